//! Segmenting an instruction into steps with a language model (issue 37, item 4): an
//! instruction that comes without subgoal annotation (AerialVLN's own files carry none) is
//! split into steps, each with its action, by greedy decoding under a grammar made **for
//! that instruction** ([`segment_grammar`]).
//!
//! The grammar writes the instruction's words, in order, each exactly once; the model
//! chooses only where one step ends and the next begins, and each step's action
//! (`takeoff`, `goto`, `land`). So the model cannot drop, invent or reorder a word: its
//! output is always a segmentation of the instruction, and the planner reads each step as
//! it reads an annotated one. The phrase rules (the hub's `segment_instruction`, which
//! splits on sentence ends and "then") stay the fallback where no model is loaded.

use crate::error::LlmError;
use aeris_schemas::MAX_SUBGOALS;
use core::fmt::Write;
use serde::Deserialize;

/// Most words of an instruction the segmenter takes (AerialVLN's longest are ~200).
pub const MAX_INSTRUCTION_WORDS: usize = 256;

/// Most tokens one segmentation may take: its words (a few tokens each at most) and the
/// JSON around each step.
pub(crate) const MAX_SEGMENTATION_TOKENS: usize = 3 * MAX_INSTRUCTION_WORDS + 24 * MAX_SUBGOALS;

/// A step's action, as the decision grammar names them.
const ACTIONS: [&str; 3] = ["takeoff", "goto", "land"];

/// Why an instruction was not segmented.
#[derive(Debug, thiserror::Error)]
pub enum SegmentError {
    /// The instruction has no words.
    #[error("the instruction has no words to segment")]
    Empty,
    /// The instruction is longer than the segmenter takes.
    #[error("the instruction has {0} words; the segmenter takes at most {MAX_INSTRUCTION_WORDS}")]
    TooLong(usize),
    /// The model could not be loaded or run.
    #[error("segmenting with the language model")]
    Model(#[from] LlmError),
    /// The segmentation did not close within the token budget.
    #[error("no complete segmentation within {0} tokens")]
    Truncated(usize),
    /// The model wrote more steps than a mission holds.
    #[error("the model wrote {0} steps; a mission holds at most {MAX_SUBGOALS}")]
    TooManySteps(usize),
    /// The output is not a segmentation (cannot happen under the grammar; checked anyway).
    #[error("output {text:?} is not a segmentation")]
    Output {
        /// What the model wrote.
        text: String,
        /// Why it does not parse.
        source: serde_json::Error,
    },
}

/// One step of a segmented instruction.
#[derive(Debug, Clone, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Segment {
    /// The step's words, as the instruction writes them.
    pub text: String,
    /// `takeoff`, `goto` or `land`.
    pub action: String,
}

/// The instruction's words as the grammar and the output write them: split on white space,
/// control characters dropped, `"` and `\` left out (they cannot be written inside the
/// output's JSON strings as the words themselves); words left empty are skipped.
pub fn instruction_words(instruction: &str) -> Vec<String> {
    instruction
        .split_whitespace()
        .map(|w| {
            w.chars()
                .filter(|c| !c.is_control() && *c != '"' && *c != '\\')
                .collect::<String>()
        })
        .filter(|w| !w.is_empty())
        .collect()
}

/// The GBNF grammar (root rule `root`) of every segmentation of `words`: a JSON list of
/// steps `{"text":"...","action":"..."}` whose texts, joined by spaces, are `words` in
/// order. Between two words the model either writes a space or closes the step, names its
/// action and opens the next; after the last word it names the last step's action.
pub fn segment_grammar(words: &[String]) -> Result<String, SegmentError> {
    if words.is_empty() {
        return Err(SegmentError::Empty);
    }
    if words.len() > MAX_INSTRUCTION_WORDS {
        return Err(SegmentError::TooLong(words.len()));
    }
    let mut g = String::with_capacity(64 * words.len());
    g.push_str("root ::= \"[{\\\"text\\\":\\\"\" w0\n");
    g.push_str("action ::= ");
    for (i, a) in ACTIONS.iter().enumerate() {
        let _ = write!(g, "{}\"\\\"{a}\\\"\"", if i > 0 { " | " } else { "" });
    }
    g.push('\n');
    g.push_str("next ::= \"\\\",\\\"action\\\":\" action \"},{\\\"text\\\":\\\"\"\n");
    for (i, w) in words.iter().enumerate() {
        let literal = gbnf_literal(w);
        if i + 1 == words.len() {
            let _ = writeln!(
                g,
                "w{i} ::= {literal} \"\\\",\\\"action\\\":\" action \"}}]\""
            );
        } else {
            let _ = writeln!(g, "w{i} ::= {literal} ( \" \" | next ) w{}", i + 1);
        }
    }
    Ok(g)
}

/// `word` as a GBNF string literal (it holds no `"`, `\` or control characters).
pub(crate) fn gbnf_literal(word: &str) -> String {
    format!("\"{word}\"")
}

/// The segmentation the JSON text `text` writes, checked against `words`.
pub fn segments_from_json(text: &str, words: &[String]) -> Result<Vec<Segment>, SegmentError> {
    let output = |source| SegmentError::Output {
        text: text.to_string(),
        source,
    };
    let segments: Vec<Segment> = serde_json::from_str(text).map_err(output)?;
    let written: Vec<&str> = segments.iter().flat_map(|s| s.text.split(' ')).collect();
    if written != words
        || segments
            .iter()
            .any(|s| !ACTIONS.contains(&s.action.as_str()))
    {
        return Err(output(serde::de::Error::custom(
            "not the instruction's words in order, or an unknown action",
        )));
    }
    if segments.len() > MAX_SUBGOALS {
        return Err(SegmentError::TooManySteps(segments.len()));
    }
    Ok(segments)
}

/// What the segmenter is asked: the task and two instructions written the way people write
/// them (neither in the episode generator's phrasing).
pub(crate) const SYSTEM: &str = r#"You split a drone pilot's instruction into its steps, in order, copying its words. A step is one thing the drone does: take off (action "takeoff"), go somewhere or turn towards something (action "goto"), or land (action "land"). Reply with a JSON list of steps, each {"text":"the step's words","action":"takeoff|goto|land"}.
Instruction: Lift off and climb to about 15 m. Head over to the lake on your left, after that go past the red building and put it down by the white tower.
[{"text":"Lift off and climb to about 15 m.","action":"takeoff"},{"text":"Head over to the lake on your left,","action":"goto"},{"text":"after that go past the red building","action":"goto"},{"text":"and put it down by the white tower.","action":"land"}]
Instruction: go up a little and swing right, follow the road until the bridge then come down next to the sign that reads PARK
[{"text":"go up a little","action":"takeoff"},{"text":"and swing right, follow the road until the bridge","action":"goto"},{"text":"then come down next to the sign that reads PARK","action":"land"}]"#;

#[cfg(test)]
mod tests {
    use super::*;

    fn words(s: &str) -> Vec<String> {
        instruction_words(s)
    }

    #[test]
    fn words_keep_punctuation_and_lose_what_json_cannot_hold() {
        assert_eq!(
            words("  go to the \"red\" roof,\tthen\nland\\ "),
            ["go", "to", "the", "red", "roof,", "then", "land"]
        );
        assert!(words(" \" ").is_empty());
    }

    #[test]
    fn the_grammar_chains_the_words_and_refuses_what_it_cannot_hold() {
        let g = segment_grammar(&words("take off, land")).unwrap();
        assert!(g.contains("w0 ::= \"take\" ( \" \" | next ) w1\n"), "{g}");
        assert!(g.contains("w2 ::= \"land\" \"\\\",\\\"action\\\":\" action \"}]\"\n"));
        assert!(matches!(segment_grammar(&[]), Err(SegmentError::Empty)));
        let long = vec!["w".to_string(); MAX_INSTRUCTION_WORDS + 1];
        assert!(matches!(
            segment_grammar(&long),
            Err(SegmentError::TooLong(n)) if n == MAX_INSTRUCTION_WORDS + 1
        ));
    }

    #[test]
    fn an_output_must_be_the_instructions_words_in_order() {
        let w = words("take off, then land");
        let ok =
            r#"[{"text":"take off,","action":"takeoff"},{"text":"then land","action":"land"}]"#;
        let s = segments_from_json(ok, &w).unwrap();
        assert_eq!(s.len(), 2);
        assert_eq!(s[1].action, "land");
        for bad in [
            r#"[{"text":"take off, land","action":"takeoff"}]"#,
            r#"[{"text":"take off, then land","action":"hover"}]"#,
            r#"[{"text":"take off, then land"}]"#,
            "not json",
        ] {
            assert!(
                matches!(
                    segments_from_json(bad, &w),
                    Err(SegmentError::Output { .. })
                ),
                "{bad}"
            );
        }
    }
}
