//! The text reader reads a sign: the village's LAKE VIEW sign rendered by the built-in
//! renderer from 10 m in front of it, read back through PP-OCRv4 in ONNX Runtime.

use aeris_models::{ModelStore, OcrReader};
use aeris_sim::render::Renderer;
use aeris_sim::world::World;

#[test]
fn reads_the_lake_view_sign_in_a_rendered_frame() {
    let store = ModelStore::open(None).expect("model cache (run scripts/provision-models.sh)");
    let mut ocr = OcrReader::load(&store, &aeris_models::SessionOptions::cpu(1)).unwrap();
    assert_eq!(ocr.charset_len(), 6625);
    let (w, h) = (640u32, 480u32);
    let renderer = Renderer::new(w, h, 60f32.to_radians()).unwrap();
    let world = World::builtin("village").unwrap();
    let mut rgb = vec![0u8; renderer.rgb_len()];
    let mut depth = vec![0u8; renderer.depth_len()];
    // north of the sign (N 34..35, E 84..92, U 2..6), facing south at its height
    renderer
        .render(
            &world,
            [44.0, 88.0, 5.0],
            std::f32::consts::PI,
            &mut rgb,
            &mut depth,
        )
        .unwrap();
    let mut texts = Vec::new();
    ocr.read(&rgb, w as usize, h as usize, &mut texts).unwrap();
    // Two lines of text are found on the board, left to right as painted. "LAKE" reads
    // exactly; the renderer's 5x7 bitmap V is read as U or T by PP-OCRv4 (rapidocr's own
    // Python pipeline reads the same frame the same way), so the second word is only
    // checked for its last three letters until signs carry a real font.
    assert_eq!(texts.len(), 2, "read {texts:?}");
    texts.sort_by(|a, b| a.bbox[0].total_cmp(&b.bbox[0]));
    assert_eq!(texts[0].text, "LAKE", "read {texts:?}");
    assert!(texts[0].score > 0.9, "read {texts:?}");
    assert!(texts[1].text.ends_with("IEW"), "read {texts:?}");
    assert!(texts[0].bbox[0] + texts[0].bbox[2] <= texts[1].bbox[0] + 1.0);

    // a frame without text reads nothing
    renderer
        .render(&world, [0.0, 0.0, 30.0], 0.0, &mut rgb, &mut depth)
        .unwrap();
    ocr.read(&rgb, w as usize, h as usize, &mut texts).unwrap();
    assert!(
        texts
            .iter()
            .all(|t| !t.text.to_uppercase().contains("LAKE")),
        "{texts:?}"
    );
    // a wrong-sized buffer is an error, not a panic
    assert!(
        ocr.read(&rgb[..99], w as usize, h as usize, &mut texts)
            .is_err()
    );
}

/// The billboards of generated scenes (the VLN evaluation's subgoal markers) read back
/// through the OCR model as an approaching vehicle sees them: from the open side of the
/// board, camera at 4 m, at 12, 16, .., 28 m. PP-OCRv4 misreads some letters of the
/// renderer's 5x7 bitmap font at some distances (S as E, U as L), so a sign counts as read
/// when one of the approach frames reads it exactly, as a vehicle flying in would.
#[test]
fn reads_the_billboards_of_generated_scenes() {
    use aeris_sim::world::LandmarkKind;
    let store = ModelStore::open(None).expect("model cache (run scripts/provision-models.sh)");
    let mut ocr = OcrReader::load(&store, &aeris_models::SessionOptions::cpu(1)).unwrap();
    let (w, h) = (640u32, 480u32);
    let renderer = Renderer::new(w, h, 60f32.to_radians()).unwrap();
    let mut rgb = vec![0u8; renderer.rgb_len()];
    let mut depth = vec![0u8; renderer.depth_len()];
    let mut texts = Vec::new();
    let mut read = 0;
    for scene in ["open-2000", "dense-2000"] {
        let world = World::builtin(scene).unwrap();
        for sign in &world.landmarks {
            let LandmarkKind::Sign { text } = &sign.kind else {
                continue;
            };
            // the renderer's 5x7 V reads as U or T (see above): those signs are skipped
            if text.contains('V') {
                continue;
            }
            let c = sign.centre();
            // which side of the board is in the open: the one a ray reaches it from
            let clear = |dn: f32| {
                let p = [c[0] + dn, c[1], 4.0];
                let unit = [-dn.signum(), 0.0, 0.0];
                world
                    .raycast(p, unit, dn.abs())
                    .is_some_and(|hit| world.landmarks[hit.landmark].name == sign.name)
            };
            let side = if clear(28.0) {
                1.0
            } else if clear(-28.0) {
                -1.0
            } else {
                panic!("{scene}: {} is hidden from both sides", sign.name)
            };
            let yaw = if side > 0.0 {
                std::f32::consts::PI
            } else {
                0.0
            };
            let mut reads = Vec::new();
            for d in [12.0f32, 16.0, 20.0, 24.0, 28.0] {
                let cam = [c[0] + side * d, c[1], 4.0];
                renderer
                    .render(&world, cam, yaw, &mut rgb, &mut depth)
                    .unwrap();
                ocr.read(&rgb, w as usize, h as usize, &mut texts).unwrap();
                let seen: String = texts
                    .iter()
                    .map(|t| t.text.to_uppercase().replace(' ', ""))
                    .collect();
                reads.push(seen);
            }
            assert!(
                reads.iter().any(|r| r.contains(&text.replace(' ', ""))),
                "{scene}: {} read as {reads:?}",
                sign.name
            );
            read += 1;
        }
    }
    assert!(read >= 4, "only {read} signs checked");
}
