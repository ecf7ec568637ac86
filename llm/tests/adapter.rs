//! Every committed LoRA adapter (`adapters/NAME/`, made by `scripts/train-reasoner.sh`)
//! means in llama.cpp what it meant in torch + peft, where it was trained: the prompt is
//! rendered to the same text by both chat templates and tokenized alike, and llama.cpp's
//! next-token logits with the adapter match the ones torch computed (`check.json`), while
//! the base alone gives other ones (the adapter is applied, not ignored).

use aeris_llm::{LanguageReasoner, ReasonerConfig};
use aeris_models::ModelStore;
use std::path::PathBuf;

mod common;

/// How far a logit of llama.cpp (Q8_0 weights, activations quantized for its dot products)
/// may be from torch's (the same weights dequantized, f32): measured at most 0.37 for the
/// committed SmolLM2 adapter, whose logits are up to 7 from the base's.
const LOGIT_TOLERANCE: f32 = 1.0;

#[derive(serde::Deserialize)]
struct Check {
    system: String,
    user: String,
    prompt_text: String,
    tokens: Vec<i32>,
    top_tokens: Vec<i32>,
    top_logits: Vec<f32>,
}

#[derive(serde::Deserialize)]
struct Checks {
    base: String,
    checks: Vec<Check>,
}

fn committed() -> Vec<(String, Checks)> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../adapters");
    let mut out = Vec::new();
    for entry in std::fs::read_dir(&dir).expect("the adapters folder") {
        let path = entry.expect("an entry").path();
        let check = path.join("check.json");
        if !check.is_file() {
            continue;
        }
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let text = std::fs::read_to_string(&check).expect("check.json");
        out.push((name, serde_json::from_str(&text).expect("a check file")));
    }
    out.sort_by(|a, b| a.0.cmp(&b.0));
    out
}

#[test]
fn every_committed_adapter_gives_llama_cpp_the_logits_torch_gave() {
    let adapters = committed();
    assert!(
        !adapters.is_empty(),
        "no committed adapter (adapters/NAME/check.json)"
    );
    let store = ModelStore::open(None).expect("model cache (run scripts/provision-models.sh)");
    for (name, checks) in adapters {
        let file = format!("adapters/{name}.gguf");
        let mut adapted = LanguageReasoner::load_adapted(
            &store,
            &checks.base,
            Some(&file),
            common::village(),
            ReasonerConfig::default(),
        )
        .unwrap_or_else(|e| panic!("{file} on {}: {e}", checks.base));
        let mut base = LanguageReasoner::load(
            &store,
            &checks.base,
            common::village(),
            ReasonerConfig::default(),
        )
        .expect("the base");
        let mut moved = 0f32;
        for (k, c) in checks.checks.iter().enumerate() {
            let text = adapted.chat(&c.system, &c.user).expect("the chat template");
            assert_eq!(
                text, c.prompt_text,
                "{name} check {k}: the templates differ"
            );
            let prompt = adapted.tokenize(&text);
            assert_eq!(
                prompt[..],
                c.tokens[..prompt.len().min(c.tokens.len())],
                "{name} check {k}: the tokenizers differ"
            );
            let ours = adapted.logits_after(&c.tokens).expect("llama.cpp's logits");
            let plain = base.logits_after(&c.tokens).expect("the base's logits");
            let best = (0..ours.len())
                .max_by(|&a, &b| ours[a].total_cmp(&ours[b]))
                .unwrap() as i32;
            assert_eq!(best, c.top_tokens[0], "{name} check {k}: the next token");
            for (&t, &logit) in c.top_tokens.iter().zip(&c.top_logits) {
                let l = ours[t as usize];
                eprintln!(
                    "{name} check {k}: token {t}: torch {logit:.3} llama.cpp {l:.3} base {:.3}",
                    plain[t as usize]
                );
                assert!(
                    (l - logit).abs() <= LOGIT_TOLERANCE,
                    "{name} check {k}: token {t}: llama.cpp {l} against torch {logit}"
                );
                moved = moved.max((l - plain[t as usize]).abs());
            }
        }
        assert!(
            moved > 4.0 * LOGIT_TOLERANCE,
            "{name}: the adapter moves no logit by more than {moved}: not applied?"
        );
    }
}
