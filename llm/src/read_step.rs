//! Reading one step of an instruction with a language model (issue 37, item 4): the turn it
//! asks for, how it relates the vehicle to a landmark, which landmark, the text that
//! landmark carries and the height it names ([`StepReading`]), by greedy decoding under a
//! grammar made **for that step and the landmarks perception can see**
//! ([`reading_grammar`]).
//!
//! Every field is a choice: the turn and relation from their few words, the landmark from
//! perception's labels (so "the yellow board" is read as the label `yellow sign` the
//! detector gives, not matched by words), the sign text as a run of the step's own words,
//! the height as one of the numbers the step writes. The model cannot invent a place, a
//! sign or a number; the planner's phrase rules read only what the reading leaves out.

use crate::segment::{MAX_INSTRUCTION_WORDS, gbnf_literal, instruction_words};
use aeris_schemas::StepReading;
use core::fmt::Write;

/// Most tokens one reading may take: its keys, a label, a sign of a few words, a number.
pub(crate) const MAX_READING_TOKENS: usize = 96;

/// Why a step was not read.
#[derive(Debug, thiserror::Error)]
pub enum ReadStepError {
    /// The step has no words.
    #[error("the step has no words to read")]
    Empty,
    /// The step is longer than the reader takes.
    #[error("the step has {0} words; the reader takes at most {MAX_INSTRUCTION_WORDS}")]
    TooLong(usize),
    /// A landmark label cannot be written in the reading (empty, or a quote, backslash or
    /// control character in it).
    #[error("landmark label {0:?} cannot be written in a reading")]
    BadLabel(String),
    /// The model could not be loaded or run.
    #[error("reading the step with the language model")]
    Model(#[from] crate::error::LlmError),
    /// The reading did not close within the token budget.
    #[error("no complete reading within {0} tokens")]
    Truncated(usize),
    /// The output is not a reading of this step (cannot happen under the grammar; checked
    /// anyway).
    #[error("output {text:?} is not a reading of the step")]
    Output {
        /// What the model wrote.
        text: String,
        /// Why it is not one.
        source: serde_json::Error,
    },
}

/// Whether `w` (without punctuation) is written in capitals, as a sign's text is.
fn in_capitals(w: &str) -> bool {
    w.chars().any(char::is_alphabetic)
        && !w.chars().any(char::is_lowercase)
        && w.chars().all(char::is_alphanumeric)
}

/// The maximal runs of the step's [`plain_words`] that are (`capitals`) or are not written
/// in capitals.
fn runs(step: &str, capitals: bool) -> Vec<Vec<String>> {
    let mut runs: Vec<Vec<String>> = Vec::new();
    let mut run = Vec::new();
    for w in plain_words(step) {
        if in_capitals(&w) == capitals {
            run.push(w);
        } else if !run.is_empty() {
            runs.push(core::mem::take(&mut run));
        }
    }
    if !run.is_empty() {
        runs.push(run);
    }
    runs
}

/// The runs of the step's words a sign text may be: consecutive words written in capitals
/// (signs are: "the board reading CITY HALL"), without the punctuation around them
/// ("STADIUM." -> "STADIUM"). A lower-case sign text is left to the phrase rules.
pub fn sign_runs(step: &str) -> Vec<Vec<String>> {
    runs(step, true)
}

/// The runs of the step's words a place may be copied from: those not in capitals.
pub fn place_runs(step: &str) -> Vec<Vec<String>> {
    runs(step, false)
}

/// The step's words without the punctuation around them ("roof," -> "roof").
fn plain_words(step: &str) -> Vec<String> {
    instruction_words(step)
        .iter()
        .map(|w| w.trim_matches(|c: char| !c.is_alphanumeric()).to_string())
        .filter(|w| !w.is_empty())
        .collect()
}

/// Rules `{prefix}-{i}` for the runs of `words` that start at word `i` (each may go on to
/// the next word), written into `g`; returns the start rules' names.
fn span_rules(g: &mut String, prefix: &str, words: &[String]) -> Vec<String> {
    for (i, w) in words.iter().enumerate() {
        if i + 1 == words.len() {
            let _ = writeln!(g, "{prefix}-{i} ::= {}", gbnf_literal(w));
        } else {
            let _ = writeln!(
                g,
                "{prefix}-{i} ::= {} ( \" \" {prefix}-{} )?",
                gbnf_literal(w),
                i + 1
            );
        }
    }
    (0..words.len()).map(|i| format!("{prefix}-{i}")).collect()
}

/// The heights the step writes: its words that begin with a whole number ("21", "20m",
/// "15,"), each once, in order.
pub fn step_numbers(step: &str) -> Vec<u32> {
    let mut out = Vec::new();
    for w in instruction_words(step) {
        let digits: String = w.chars().take_while(char::is_ascii_digit).collect();
        let rest = &w[digits.len()..];
        // "20m", "20", "20," are heights; "2nd", "20x30" are not
        let unit_or_end = rest.is_empty()
            || rest == "m"
            || rest.starts_with(|c: char| c.is_ascii_punctuation() && c != '.')
            || rest == ".";
        if let Ok(n) = digits.parse::<u32>()
            && n > 0
            && unit_or_end
            && !out.contains(&n)
        {
            out.push(n);
        }
    }
    out
}

/// A JSON string literal of `text` as a GBNF literal (`text` holds no `"`, `\` or control
/// characters).
fn json_string_literal(text: &str) -> String {
    gbnf_literal(&format!("\\\"{text}\\\""))
}

/// The GBNF grammar (root rule `root`) of every reading of `step` with a landmark among
/// `landmarks`: `{"turn":..,"relation":..,"landmark":..,"sign":..,"height_m":..}`, the
/// landmark one of `landmarks` or null, the sign a part of one of its [`sign_runs`] or null,
/// the height one of its [`step_numbers`] or null.
pub fn reading_grammar(step: &str, landmarks: &[&str]) -> Result<String, ReadStepError> {
    let words = instruction_words(step);
    if words.is_empty() {
        return Err(ReadStepError::Empty);
    }
    if words.len() > MAX_INSTRUCTION_WORDS {
        return Err(ReadStepError::TooLong(words.len()));
    }
    if let Some(bad) = landmarks
        .iter()
        .find(|l| l.trim().is_empty() || l.chars().any(|c| c == '"' || c == '\\' || c.is_control()))
    {
        return Err(ReadStepError::BadLabel(bad.to_string()));
    }
    let mut g = String::with_capacity(1024 + 96 * words.len());
    // a place first, as the step's own words: a step that names none has no relation or
    // landmark (a step that only turns is not sent looking for one)
    g.push_str(
        "root ::= \"{\\\"turn\\\":\" turn \",\\\"place\\\":\" place \",\\\"sign\\\":\" sign \
         \",\\\"height_m\\\":\" height \"}\"\n\
         place ::= \"null,\\\"relation\\\":null,\\\"landmark\\\":null\" | \"\\\"\" place-words \
         \"\\\",\\\"relation\\\":\" relation \",\\\"landmark\\\":\" landmark\n",
    );
    let alternatives = |g: &mut String, rule: &str, options: &[String]| {
        let _ = write!(g, "{rule} ::= ");
        for (i, o) in options.iter().enumerate() {
            let _ = write!(g, "{}{o}", if i > 0 { " | " } else { "" });
        }
        g.push('\n');
    };
    let quoted =
        |xs: &[&str]| -> Vec<String> { xs.iter().map(|x| json_string_literal(x)).collect() };
    alternatives(
        &mut g,
        "turn",
        &quoted(&["none", "left", "right", "around"]),
    );
    alternatives(&mut g, "relation", &quoted(&["to", "above", "beside"]));
    let mut landmark = vec!["\"null\"".to_string()];
    landmark.extend(quoted(landmarks));
    alternatives(&mut g, "landmark", &landmark);
    // the place: a run of the step's words outside its capitals (a sign's text is its
    // own field: "the board that reads LAKE VIEW" is a board, not a lake)
    let mut starts = Vec::new();
    for (r, run) in place_runs(step).iter().enumerate() {
        starts.extend(span_rules(&mut g, &format!("p{r}"), run));
    }
    alternatives(&mut g, "place-words", &starts);
    // a sign: a run of consecutive words in capitals
    let mut sign = vec!["\"null\"".to_string()];
    for (r, run) in sign_runs(step).iter().enumerate() {
        for start in span_rules(&mut g, &format!("s{r}"), run) {
            sign.push(format!("\"\\\"\" {start} \"\\\"\""));
        }
    }
    alternatives(&mut g, "sign", &sign);
    let mut height = vec!["\"null\"".to_string()];
    height.extend(step_numbers(step).iter().map(|n| format!("\"{n}\"")));
    alternatives(&mut g, "height", &height);
    Ok(g)
}

/// What the model writes: the place the step names, in its own words, before the landmark
/// it reads it as.
#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct Read {
    turn: aeris_schemas::Turn,
    place: Option<String>,
    relation: Option<aeris_schemas::Relation>,
    landmark: Option<String>,
    sign: Option<String>,
    height_m: Option<f32>,
}

/// The label the copied `place` is read as: the model's `chosen` label when the place says a
/// word of it; else, when the place says a word of other labels, the one it says most of
/// (the longest of those); else the model's choice only when the place quotes a `sign` (a
/// "board marked FISH MARKET" is a sign whatever it is called), and no landmark otherwise
/// (the model copied words that name nothing perception labels: "right" in "hang a right").
/// Words of the sign do not count ("the board that reads LAKE VIEW" is no lake).
fn landmark_of<'a>(
    place: &str,
    chosen: Option<&str>,
    sign: Option<&str>,
    landmarks: &[&'a str],
) -> Option<&'a str> {
    let sign_words: Vec<&str> = sign.map(|s| s.split(' ').collect()).unwrap_or_default();
    let place_words: Vec<String> = place
        .split(' ')
        .filter(|w| !sign_words.contains(w))
        .map(str::to_lowercase)
        .collect();
    // label words said in the place ("roof" in "roofed", "tree" in "trees")
    let said = |label: &str| {
        label
            .split(|c: char| !c.is_alphanumeric())
            .filter(|l| l.len() > 2)
            .filter(|l| place_words.iter().any(|w| w.starts_with(&l.to_lowercase())))
            .count()
    };
    let chosen = chosen.and_then(|c| landmarks.iter().copied().find(|l| *l == c));
    if let Some(c) = chosen.filter(|c| said(c) > 0) {
        return Some(c);
    }
    let best = landmarks
        .iter()
        .copied()
        .filter(|l| said(l) > 0)
        .max_by_key(|l| (said(l), l.len()));
    best.or(chosen.filter(|_| sign.is_some()))
}

/// Whether `run` is a run of consecutive `words`.
fn run_of(words: &[String], run: &[&str]) -> bool {
    !run.is_empty()
        && words
            .windows(run.len())
            .any(|w| w.iter().map(String::as_str).eq(run.iter().copied()))
}

/// The reading the JSON text `text` writes, checked against `step` and `landmarks` as the
/// grammar allows it.
pub fn reading_from_json(
    text: &str,
    step: &str,
    landmarks: &[&str],
) -> Result<StepReading, ReadStepError> {
    let output = |source| ReadStepError::Output {
        text: text.to_string(),
        source,
    };
    let read: Read = serde_json::from_str(text).map_err(output)?;
    let place_ok = read.place.as_deref().is_none_or(|p| {
        let place: Vec<&str> = p.split(' ').collect();
        place_runs(step).iter().any(|run| run_of(run, &place))
    }) && (read.place.is_some()
        || (read.relation.is_none() && read.landmark.is_none()));
    let landmark = read.place.as_deref().and_then(|place| {
        landmark_of(
            place,
            read.landmark.as_deref(),
            read.sign.as_deref(),
            landmarks,
        )
    });
    let reading = StepReading {
        turn: read.turn,
        relation: landmark.and(read.relation),
        landmark: landmark.map(str::to_string),
        sign: read.sign.clone(),
        height_m: read.height_m,
    };
    let runs = sign_runs(step);
    let sign_ok = reading.sign.as_deref().is_none_or(|s| {
        let sign: Vec<&str> = s.split(' ').collect();
        runs.iter().any(|run| run_of(run, &sign))
    });
    let landmark_ok = read
        .landmark
        .as_deref()
        .is_none_or(|l| landmarks.contains(&l));
    let height_ok = reading
        .height_m
        .is_none_or(|h| step_numbers(step).iter().any(|&n| n as f32 == h));
    if !(place_ok && sign_ok && landmark_ok && height_ok) || reading.validate().is_err() {
        return Err(output(serde::de::Error::custom(
            "a place, landmark, sign or height the step and the labels do not hold",
        )));
    }
    Ok(reading)
}

/// What the reader is asked: the task and examples written the way people write (neither
/// in the episode generator's phrasing nor in the paraphrase set's).
pub(crate) const SYSTEM: &str = r#"You read one step of a drone pilot's instruction. Reply with JSON: "turn" is the turn the step asks for before flying ("left", "right", "around" or "none"); "place" is the place the step sends the drone to, copied from the step (null when it names none: a step that only climbs or turns); "relation" is where the drone ends up relative to that place ("to": flies up to it, "above": passes above it, "beside": lands beside, by, near or close to it); "landmark" is that place as the most specific of the listed landmarks (null when none fits); "sign" is the text in capitals written on that place (null when the step quotes none); "height_m" is the height the step names in metres (null when none).
Landmarks: tree, building, white tower, grey roof, sign, river, road
Step: Lift off and climb to about 15 m above the ground.
{"turn":"none","place":null,"relation":null,"landmark":null,"sign":null,"height_m":15}
Landmarks: tree, building, white tower, grey roof, sign, river, road
Step: after that bear round to the left and make for the tall white tower
{"turn":"left","place":"tall white tower","relation":"to","landmark":"white tower","sign":null,"height_m":null}
Landmarks: tree, building, white tower, grey roof, sign, river, road
Step: and then bank round to the right,
{"turn":"right","place":null,"relation":null,"landmark":null,"sign":null,"height_m":null}
Landmarks: tree, building, white tower, grey roof, sign, river, road
Step: go straight on across the river
{"turn":"none","place":"river","relation":"above","landmark":"river","sign":null,"height_m":null}
Landmarks: tree, building, white tower, grey roof, sign, river, road
Step: wander over to the house with the grey roof
{"turn":"none","place":"house with the grey roof","relation":"to","landmark":"grey roof","sign":null,"height_m":null}
Landmarks: tree, building, white tower, grey roof, sign, river, road
Step: then come about and put it down near the board marked FISH MARKET.
{"turn":"around","place":"board","relation":"beside","landmark":"sign","sign":"FISH MARKET","height_m":null}
Landmarks: tree, building, white tower, grey roof, sign, river, road
Step: and settle down on the ground beside the trees
{"turn":"none","place":"trees","relation":"beside","landmark":"tree","sign":null,"height_m":null}"#;

/// The user message of a reading of `step` with `landmarks` to choose from.
pub(crate) fn user_message(step: &str, landmarks: &[&str]) -> String {
    format!(
        "Landmarks: {}\nStep: {}",
        landmarks.join(", "),
        instruction_words(step).join(" ")
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use aeris_schemas::{Relation, Turn};

    const LABELS: [&str; 3] = ["yellow sign", "blue roof", "lake"];

    #[test]
    fn numbers_and_sign_runs_come_from_the_step() {
        assert_eq!(step_numbers("climb to 21 m, then 20m or 2nd 21"), [21, 20]);
        assert_eq!(
            sign_runs("Then by the \"CITY HALL\" sign, not GARAGE. or lake"),
            [vec!["CITY", "HALL"], vec!["GARAGE"]]
        );
    }

    #[test]
    fn the_grammar_offers_the_labels_runs_of_words_and_numbers() {
        let g = reading_grammar("set down by the CITY HALL board at 5 m", &LABELS).unwrap();
        assert!(
            g.contains("landmark ::= \"null\" | \"\\\"yellow sign\\\"\""),
            "{g}"
        );
        assert!(g.contains("s0-0 ::= \"CITY\" ( \" \" s0-1 )?\n"), "{g}");
        assert!(g.contains("s0-1 ::= \"HALL\"\n"), "{g}");
        assert!(g.contains("height ::= \"null\" | \"5\"\n"), "{g}");
        assert!(matches!(
            reading_grammar(" ", &LABELS),
            Err(ReadStepError::Empty)
        ));
        assert!(matches!(
            reading_grammar("go", &["a \"b\""]),
            Err(ReadStepError::BadLabel(_))
        ));
    }

    #[test]
    fn a_landmark_is_taken_only_where_the_copied_place_names_it() {
        let l = ["yellow sign", "blue water tower", "lake", "road"];
        // the model's choice, said in the place
        assert_eq!(
            landmark_of("blue tower", Some("blue water tower"), None, &l),
            Some("blue water tower")
        );
        // a sign's words do not count: the board reading LAKE VIEW is the yellow sign
        assert_eq!(
            landmark_of(
                "yellow board that reads LAKE VIEW",
                Some("lake"),
                Some("LAKE VIEW"),
                &l
            ),
            Some("yellow sign")
        );
        // nothing said, but a sign quoted: the model's word for it
        assert_eq!(
            landmark_of("board marked CAFE", Some("yellow sign"), Some("CAFE"), &l),
            Some("yellow sign")
        );
        // nothing said, nothing quoted: no landmark
        assert_eq!(landmark_of("right", Some("road"), None, &l), None);
    }

    #[test]
    fn an_output_must_read_this_step_with_these_labels() {
        let step = "hang a right and set down by the CITY HALL board";
        let ok = r#"{"turn":"right","place":"board","relation":"beside","landmark":"yellow sign","sign":"CITY HALL","height_m":null}"#;
        let r = reading_from_json(ok, step, &LABELS).unwrap();
        assert_eq!(r.turn, Turn::Right);
        assert_eq!(r.relation, Some(Relation::NextTo));
        assert_eq!(r.sign.as_deref(), Some("CITY HALL"));
        for bad in [
            r#"{"turn":"right","place":"board","relation":"to","landmark":"red roof","sign":null,"height_m":null}"#,
            r#"{"turn":"right","place":"board","relation":"to","landmark":null,"sign":"HALL CITY","height_m":null}"#,
            r#"{"turn":"right","place":null,"relation":"to","landmark":null,"sign":null,"height_m":null}"#,
            r#"{"turn":"right","place":"the board","relation":"to","landmark":null,"sign":null,"height_m":null}"#,
            r#"{"turn":"right","place":null,"relation":null,"landmark":null,"sign":null,"height_m":7}"#,
            r#"{"turn":"up","place":null,"relation":null,"landmark":null,"sign":null,"height_m":null}"#,
            "not json",
        ] {
            assert!(
                matches!(
                    reading_from_json(bad, step, &LABELS),
                    Err(ReadStepError::Output { .. })
                ),
                "{bad}"
            );
        }
    }
}
