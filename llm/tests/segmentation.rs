//! An instruction without subgoal annotation, written the way AerialVLN's annotators write
//! (lower case, one run-on sentence, no step numbers), segmented by a provisioned model under
//! its per-instruction grammar: the steps are the instruction's words in order, and their
//! actions read as the instruction does (a take-off first, a landing last, movement between).

use aeris_llm::segment::instruction_words;
use aeris_llm::{QWEN25_CODER_05B, Segmenter};
use aeris_models::ModelStore;

/// In AerialVLN's style; not a sentence our episode generator can write.
const UNANNOTATED: &str = "go up to roughly the height of the trees and move ahead till you \
reach the grey building, now swing left and keep going along the road past the small lake and \
when you see a blue tower descend and touch down right beside it";

#[test]
fn an_unannotated_instruction_is_segmented_by_the_model_into_its_steps() {
    let store = ModelStore::open(None).expect("model cache (run scripts/provision-models.sh)");
    let mut segmenter = Segmenter::load(&store, QWEN25_CODER_05B, 2).expect("the segmenter");
    let steps = segmenter.segment(UNANNOTATED).expect("a segmentation");
    eprintln!("{steps:#?}\n{:?}", segmenter.last_stats());
    let words: Vec<String> = steps
        .iter()
        .flat_map(|s| s.text.split(' ').map(str::to_string))
        .collect();
    assert_eq!(
        words,
        instruction_words(UNANNOTATED),
        "every word, in order"
    );
    assert!(steps.len() >= 3, "{steps:?}");
    assert_eq!(steps[0].action, "takeoff", "{steps:?}");
    assert_eq!(steps[steps.len() - 1].action, "land", "{steps:?}");
    assert!(
        steps[1..steps.len() - 1].iter().all(|s| s.action == "goto"),
        "{steps:?}"
    );
}
