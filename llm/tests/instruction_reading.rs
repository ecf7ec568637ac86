//! The instruction reader on a provisioned model: an instruction without subgoal annotation,
//! written the way AerialVLN's annotators write (lower case, one run-on sentence, no step
//! numbers), segmented under its per-instruction grammar (the steps are the instruction's
//! words in order, and their actions read as the instruction does: a take-off first, a
//! landing last, movement between); steps in people's wording read as turns, places, signs
//! and heights.

use aeris_llm::segment::instruction_words;
use aeris_llm::{InstructionReader, QWEN25_CODER_05B};
use aeris_models::ModelStore;
use aeris_schemas::{Relation, Turn};

/// In AerialVLN's style; not a sentence our episode generator can write.
const UNANNOTATED: &str = "go up to roughly the height of the trees and move ahead till you \
reach the grey building, now swing left and keep going along the road past the small lake and \
when you see a blue tower descend and touch down right beside it";

/// One test, one model load: as two tests, two readers' llama.cpp thread pools spun against
/// each other on the same two cores (60 s in the suite on a 2-core Xeon; 17 s as one).
#[test]
fn the_reader_segments_an_unannotated_instruction_and_reads_steps_written_the_way_people_write() {
    let store = ModelStore::open(None).expect("model cache (run scripts/provision-models.sh)");
    let mut reader = InstructionReader::load(&store, QWEN25_CODER_05B, 2).expect("the reader");
    segments_an_unannotated_instruction_into_its_steps(&mut reader);
    reads_steps_written_the_way_people_write(&mut reader);
}

/// The segmentation keeps every word in order, takes off first, lands last and moves
/// between.
fn segments_an_unannotated_instruction_into_its_steps(reader: &mut InstructionReader) {
    let steps = reader.segment(UNANNOTATED).expect("a segmentation");
    eprintln!("{steps:#?}\n{:?}", reader.last_stats());
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

/// A detector's labels (the kinds of the simulator's perception, and some it does not give).
const LABELS: [&str; 11] = [
    "car",
    "blue water tower",
    "road",
    "green roof",
    "yellow sign",
    "helipad",
    "building",
    "red roof",
    "lake",
    "tree",
    "bridge",
];

/// Steps in the way people write them (neither the episode generator's wording, nor the
/// reader's examples, nor the paraphrase set's): each is read as a turn, a place, a sign or a
/// height, as its words say.
fn reads_steps_written_the_way_people_write(reader: &mut InstructionReader) {
    let mut read = |step: &str| {
        let r = reader
            .read_step(step, &LABELS)
            .unwrap_or_else(|e| panic!("{step:?}: {e:?}"));
        eprintln!("{step:?}\n  {r:?}\n  {:?}", reader.last_stats());
        r
    };
    let r = read("rise to about 18 metres off the pad");
    assert_eq!((r.height_m, r.turn), (Some(18.0), Turn::None), "{r:?}");
    let r = read("then swing around");
    assert_eq!(
        (r.turn, r.landmark.as_deref()),
        (Turn::Around, None),
        "{r:?}"
    );
    let r = read("now swing left and keep going along the road past the small lake");
    assert_eq!(r.turn, Turn::Left, "{r:?}");
    let r = read("then veer right towards the building with the green roof");
    assert_eq!(
        (r.turn, r.landmark.as_deref(), r.sign.as_deref()),
        (Turn::Right, Some("green roof"), None),
        "{r:?}"
    );
    let r = read("when you see the blue tower drop down right beside it");
    assert_eq!(
        (r.relation, r.landmark.as_deref()),
        (Some(Relation::NextTo), Some("blue water tower")),
        "{r:?}"
    );
    let r = read("and touch down close to the yellow board reading TOWN HALL");
    assert_eq!(
        (r.landmark.as_deref(), r.sign.as_deref(), r.height_m),
        (Some("yellow sign"), Some("TOWN HALL"), None),
        "{r:?}"
    );
}
