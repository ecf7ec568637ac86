//! The text a language model emits, read the way the reasoner reads it
//! (`DecisionView::parse`, then `to_decision`), then through the decision gate. Checks:
//! `aeris_llm::view::fuzz_check_text` (the memory line of an admitted decision parses back)
//! and `aeris_hub::testing::fuzz_check_model_decision` (the gate's promises).

#![no_main]

use aeris_hub::DecisionGate;
use aeris_hub::testing::fuzz_check_model_decision;
use aeris_llm::view::fuzz_check_text;
use libfuzzer_sys::fuzz_target;
use std::sync::LazyLock;

static GATE: LazyLock<DecisionGate> = LazyLock::new(aeris_fuzz::default_gate);

fuzz_target!(|data: &[u8]| {
    // the reasoner decodes the model's bytes lossily: any bytes are some text
    let text = String::from_utf8_lossy(data);
    fuzz_check_text(&text, |d| fuzz_check_model_decision(&GATE, d).is_some());
});
