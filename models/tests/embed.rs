//! The sentence-embedding model runs through ONNX Runtime on real text and ranks the
//! matching subgoal above unrelated ones. Needs the provisioned cache
//! (`scripts/provision-models.sh`, which `scripts/test.sh` runs first).

use aeris_models::{ModelStore, TextEmbedder, cosine};

fn embedder() -> TextEmbedder {
    let store = ModelStore::open(None).expect("model cache (run scripts/provision-models.sh)");
    TextEmbedder::load(&store, &aeris_models::SessionOptions::cpu(1))
        .expect("embedding model loads")
}

#[test]
fn matches_the_published_embedding_of_a_reference_sentence() {
    let mut e = embedder();
    let v = e.embed("This is an example sentence").unwrap();
    // sentence-transformers' all-MiniLM-L6-v2 gives 0.0677, 0.0634, 0.0488, 0.0793, 0.0374
    let published = [0.0677f32, 0.0634, 0.0488, 0.0793, 0.0374];
    for (got, want) in v.iter().zip(published) {
        assert!((got - want).abs() < 5e-4, "{:?}", &v[..5]);
    }
    let norm: f32 = v.iter().map(|x| x * x).sum::<f32>().sqrt();
    assert!((norm - 1.0).abs() < 1e-4, "normalised: {norm}");
}

#[test]
fn ranks_the_matching_subgoal_above_unrelated_ones() {
    let mut e = embedder();
    let subgoals = [
        "take off from the helipad to 12 metres",
        "fly north along the road to the red-roofed building",
        "turn right and follow the road east to the blue water tower",
        "land next to the yellow sign that says LAKE VIEW",
    ];
    let mut subgoal_vecs = Vec::new();
    e.embed_into(&subgoals, &mut subgoal_vecs).unwrap();
    for (observation, expected) in [
        ("a sign reading LAKE VIEW ahead", 3),
        ("a tall blue water tower on the right", 2),
        ("a building with a red roof straight ahead", 1),
        ("a helipad below", 0),
    ] {
        let o = e.embed(observation).unwrap();
        let scores: Vec<f32> = subgoal_vecs.iter().map(|s| cosine(&o, s)).collect();
        let best = scores
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))
            .unwrap()
            .0;
        assert_eq!(best, expected, "`{observation}` scores {scores:?}");
    }
    // batched and single embeddings agree (padding is masked out)
    let single = e.embed(subgoals[1]).unwrap();
    assert!(cosine(&single, &subgoal_vecs[1]) > 0.9999);
}
