//! The formation role's language-model variant: an instruction and an API context (the phase
//! types and their fields, the vehicles, the limits) become a [`FormationProgram`] by greedy
//! decoding under a grammar of the program's JSON form ([`program_grammar`]).
//!
//! The grammar fixes the structure: the phase kinds and their fields, take-off first and
//! land last, no hold or move before a shape, at most [`MAX_PHASES`] phases. Its number
//! ranges are the format's, not the flight's limits: a model asked for "1 m apart" writes
//! 1.0, which validation and the simulation then refuse or repair, where a grammar bounded
//! at the 2 m minimum would make it write 10.0-19.9 from its first digit on. The output
//! goes through [`FormationProgram::validate`] and the simulation like the parser's.

use crate::decode::{
    BATCH, GenerateStop, chat_prompt, eval_tokens, generate_under_grammar, load_cpu_model,
    reuse_prefix,
};
use crate::error::LlmError;
use crate::grammar::{GrammarError, NumberField, number_rule};
use aeris_formation::{Problem, ProgramWriter, clauses};
use aeris_models::ModelStore;
use aeris_schemas::{
    FormationLimits, FormationPhase, FormationProgram, MAX_PHASES, MAX_VEHICLES, PhaseKind,
    ShapeKind,
};
use core::fmt::Write;
use llama_cpp_2::context::LlamaContext;
use llama_cpp_2::llama_batch::LlamaBatch;
use llama_cpp_2::model::LlamaModel;
use llama_cpp_2::sampling::LlamaSampler;
use llama_cpp_2::token::LlamaToken;
use serde::Deserialize;
use std::time::Instant;

/// Most tokens one program may take (16 phases of about 30 tokens fit).
pub const MAX_PROGRAM_TOKENS: usize = 600;

/// Context length (the API context, a repair's program and problem, and the output).
const CONTEXT_TOKENS: u32 = 2048;

/// The number fields of the program's JSON form and their format bounds.
const fn field(key: &'static str, min: f64, max: f64, decimals: u32) -> NumberField {
    NumberField {
        key,
        min,
        max,
        decimals,
    }
}
const VEHICLES: NumberField = field("vehicles", 1.0, MAX_VEHICLES as f64, 0);
const HEIGHT: NumberField = field("height", 0.0, 999.9, 1);
const SPACING: NumberField = field("spacing", 0.0, 99.9, 1);
const HEADING: NumberField = field("heading", -180.0, 180.0, 0);
const COORDINATE: NumberField = field("coordinate", -999.9, 999.9, 1);
const SECONDS: NumberField = field("seconds", 0.0, 999.0, 0);
const SPEED: NumberField = field("speed", 0.0, 99.9, 1);

/// The GBNF grammar of a formation program's JSON form (root rule `root`), on one line,
/// keys in a fixed order:
///
/// `{"vehicles":4,"phases":[{"do":"take_off","height":5.0},{"do":"assume","shape":"line",
/// "spacing":3.0,"heading":0,"height":5.0,"north":0.0,"east":0.0},{"do":"hold","seconds":10},
/// {"do":"move","north":20.0,"east":0.0,"speed":2.0},{"do":"land"}]}`
pub fn program_grammar() -> Result<String, GrammarError> {
    let mut g = String::new();
    // take-off, then optionally a shape and what follows it, then land: at most MAX_PHASES
    let _ = writeln!(
        g,
        r#"root ::= "{{\"vehicles\":" vehicles ",\"phases\":[" take-off ( "," assume ( "," middle ){{0,{}}} )? "," land "]}}""#,
        MAX_PHASES - 3
    );
    g.push_str(
        r#"take-off ::= "{\"do\":\"take_off\",\"height\":" height "}"
assume ::= "{\"do\":\"assume\",\"shape\":" shape ",\"spacing\":" spacing ",\"heading\":" heading ",\"height\":" height ",\"north\":" coordinate ",\"east\":" coordinate "}"
hold ::= "{\"do\":\"hold\",\"seconds\":" seconds "}"
move ::= "{\"do\":\"move\",\"north\":" coordinate ",\"east\":" coordinate ",\"speed\":" speed "}"
land ::= "{\"do\":\"land\"}"
middle ::= assume | hold | move
shape ::= "\"line\"" | "\"column\"" | "\"wedge\"" | "\"circle\"" | "\"grid\""
"#,
    );
    for f in [
        &VEHICLES,
        &HEIGHT,
        &SPACING,
        &HEADING,
        &COORDINATE,
        &SECONDS,
        &SPEED,
    ] {
        let _ = writeln!(g, "{} ::= {}", f.key, number_rule(f)?);
    }
    Ok(g)
}

/// One phase as the model writes it.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(tag = "do", rename_all = "snake_case", deny_unknown_fields)]
enum PhaseView {
    TakeOff {
        height: f32,
    },
    Assume {
        shape: ShapeName,
        spacing: f32,
        heading: f32,
        height: f32,
        north: f32,
        east: f32,
    },
    Hold {
        seconds: f32,
    },
    Move {
        north: f32,
        east: f32,
        speed: f32,
    },
    Land,
}

/// The shapes the model may name (explicit offsets are the parser's and a user's).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(rename_all = "snake_case")]
enum ShapeName {
    Line,
    Column,
    Wedge,
    Circle,
    Grid,
}

/// A program as the model writes it.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
struct ProgramView {
    vehicles: u8,
    phases: Vec<PhaseView>,
}

/// Why a JSON text is no program (beyond what serde finds).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0} phases: a program has at most {MAX_PHASES}")]
struct TooManyPhases(usize);

/// The program the JSON form `text` writes (not validated).
pub fn program_from_json(text: &str) -> Result<FormationProgram, serde_json::Error> {
    let view: ProgramView = serde_json::from_str(text)?;
    if view.phases.len() > MAX_PHASES {
        return Err(serde::de::Error::custom(TooManyPhases(view.phases.len())));
    }
    let mut program = FormationProgram {
        vehicles: view.vehicles,
        phase_count: view.phases.len() as u8,
        ..FormationProgram::default()
    };
    for (slot, phase) in program.phases.iter_mut().zip(&view.phases) {
        *slot = match *phase {
            PhaseView::TakeOff { height } => FormationPhase {
                kind: PhaseKind::TakeOff as u8,
                height_m: height,
                ..FormationPhase::default()
            },
            PhaseView::Assume {
                shape,
                spacing,
                heading,
                height,
                north,
                east,
            } => FormationPhase {
                kind: PhaseKind::Assume as u8,
                shape: match shape {
                    ShapeName::Line => ShapeKind::Line,
                    ShapeName::Column => ShapeKind::Column,
                    ShapeName::Wedge => ShapeKind::Wedge,
                    ShapeName::Circle => ShapeKind::Circle,
                    ShapeName::Grid => ShapeKind::Grid,
                } as u8,
                spacing_m: spacing,
                heading_rad: heading.to_radians(),
                height_m: height,
                centre: [north, east],
                ..FormationPhase::default()
            },
            PhaseView::Hold { seconds } => FormationPhase {
                kind: PhaseKind::Hold as u8,
                hold_s: seconds,
                ..FormationPhase::default()
            },
            PhaseView::Move { north, east, speed } => FormationPhase {
                kind: PhaseKind::Move as u8,
                centre: [north, east],
                speed_mps: speed,
                ..FormationPhase::default()
            },
            PhaseView::Land => FormationPhase {
                kind: PhaseKind::Land as u8,
                ..FormationPhase::default()
            },
        };
    }
    Ok(program)
}

/// `program` in the JSON form the model writes (numbers as the grammar writes them); `None`
/// for what that form cannot say (explicit offsets, unknown kinds).
pub fn program_to_json(program: &FormationProgram) -> Option<String> {
    let mut s = format!("{{\"vehicles\":{},\"phases\":[", program.vehicles);
    for (i, p) in program.phases().iter().enumerate() {
        if i > 0 {
            s.push(',');
        }
        let _ = match PhaseKind::from_u8(p.kind)? {
            PhaseKind::TakeOff => write!(s, r#"{{"do":"take_off","height":{:.1}}}"#, p.height_m),
            PhaseKind::Assume => {
                let shape = ShapeKind::from_u8(p.shape).filter(|s| *s != ShapeKind::Offsets)?;
                write!(
                    s,
                    r#"{{"do":"assume","shape":"{}","spacing":{:.1},"heading":{:.0},"height":{:.1},"north":{:.1},"east":{:.1}}}"#,
                    shape.name(),
                    p.spacing_m,
                    p.heading_rad.to_degrees(),
                    p.height_m,
                    p.centre[0],
                    p.centre[1]
                )
            }
            PhaseKind::Hold => write!(s, r#"{{"do":"hold","seconds":{:.0}}}"#, p.hold_s),
            PhaseKind::Move => write!(
                s,
                r#"{{"do":"move","north":{:.1},"east":{:.1},"speed":{:.1}}}"#,
                p.centre[0], p.centre[1], p.speed_mps
            ),
            PhaseKind::Land => write!(s, r#"{{"do":"land"}}"#),
        };
    }
    s.push_str("]}");
    Some(s)
}

/// The API context: what a program is, its phases and fields, one example.
const SYSTEM: &str = r#"You write formation programs for a swarm of drones. Reply with one JSON object and nothing else:
{"vehicles":N,"phases":[PHASE,...]}
vehicles: how many drones the instruction names; if it names none, all the flight has.
The phases, in the order the instruction gives them:
{"do":"take_off","height":H} always first: every drone climbs to H m.
{"do":"assume","shape":S,"spacing":D,"heading":A,"height":H,"north":X,"east":Y} the drones form shape S: "line" (side by side), "column" (one behind the other), "wedge" (a V), "circle" or "grid"; D m between neighbours (for a circle D is its radius); facing A degrees (0 north, 90 east, 180 south, -90 west); at H m; centred X m north and Y m east of the start.
{"do":"hold","seconds":T} keep the formation for T seconds.
{"do":"move","north":X,"east":Y,"speed":V} move the whole formation until its centre is X m north and Y m east of the start, at V m/s.
{"do":"land"} always last.
Every shape the instruction names is an assume phase of its own. A value the instruction does not give is kept from the phase before; the first heading is 0 and the first centre 0.0, 0.0.
Example 1, a flight of 4 drones. Instruction: three drones take off to 7 m, form a wedge 4 m apart heading south, hold 20 s, then a grid 5 m apart, and land
{"vehicles":3,"phases":[{"do":"take_off","height":7.0},{"do":"assume","shape":"wedge","spacing":4.0,"heading":180,"height":7.0,"north":0.0,"east":0.0},{"do":"hold","seconds":20},{"do":"assume","shape":"grid","spacing":5.0,"heading":180,"height":7.0,"north":0.0,"east":0.0},{"do":"land"}]}
Example 2, a flight of 4 drones. Instruction: take off to 3 m in a column 2.5 m apart, move 12 m west at 1.5 m/s, then a circle of radius 4 m heading east, and land
{"vehicles":4,"phases":[{"do":"take_off","height":3.0},{"do":"assume","shape":"column","spacing":2.5,"heading":0,"height":3.0,"north":0.0,"east":0.0},{"do":"move","north":0.0,"east":-12.0,"speed":1.5},{"do":"assume","shape":"circle","spacing":4.0,"heading":90,"height":3.0,"north":0.0,"east":-12.0},{"do":"land"}]}"#;

/// The user message: the flight, the instruction, and for a repair the program and its
/// problem.
fn user_message(
    instruction: &str,
    limits: &FormationLimits,
    repair: Option<(&str, &Problem)>,
) -> String {
    let mut m = format!(
        "The flight has {} drones: \"vehicles\" is {} unless the instruction says how many \
         drones. Heights {:.0} to {:.0} m; drones at least {:.1} m apart; speed at most {:.0} \
         m/s.\nInstruction: {}",
        limits.vehicles,
        limits.vehicles,
        limits.h_min,
        limits.h_max,
        limits.min_separation_m,
        limits.v_max,
        crate::prompt::sanitize(instruction, 600),
    );
    // the clauses one per line: a small model maps each to its phase(s) instead of
    // re-reading one long sentence
    m.push_str("\nIts parts, in order:");
    for (i, clause) in clauses(instruction).iter().take(MAX_PHASES).enumerate() {
        let _ = write!(m, "\n{}. {}", i + 1, crate::prompt::sanitize(clause, 200));
    }
    if let Some((program, problem)) = repair {
        let _ = write!(
            m,
            "\nYour program was:\n{program}\nIt cannot fly: {problem}.\nWrite the corrected program."
        );
    }
    m
}

/// What one program cost.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct WriteStats {
    /// Tokens in the prompt.
    pub prompt_tokens: usize,
    /// Prompt tokens whose KV entries were reused from the previous program.
    pub reused_tokens: usize,
    /// Tokens generated.
    pub generated_tokens: usize,
    /// Seconds evaluating the prompt.
    pub prompt_s: f64,
    /// Seconds generating.
    pub generate_s: f64,
}

/// The language-model formation variant: a GGUF model in llama.cpp writing programs under
/// [`program_grammar`].
pub struct FormationWriter {
    // Field order matters: the context borrows the model and must drop first.
    ctx: LlamaContext<'static>,
    model: &'static LlamaModel,
    grammar: LlamaSampler,
    batch: LlamaBatch<'static>,
    cached: Vec<LlamaToken>,
    variant: String,
    last: WriteStats,
    generated_total: usize,
    load_s: f64,
}

impl FormationWriter {
    /// Load `file` (cache-relative, hash-checked) as variant `variant`, evaluating on
    /// `threads` CPU threads.
    pub fn load(
        store: &ModelStore,
        variant: &str,
        file: &str,
        threads: i32,
    ) -> Result<Self, LlmError> {
        let started = Instant::now();
        let grammar_text = program_grammar()?;
        let (model, ctx) = load_cpu_model(store, file, threads, CONTEXT_TOKENS)?;
        let grammar = LlamaSampler::grammar(model, &grammar_text, "root")
            .map_err(|e| LlmError::GrammarRejected(e.to_string()))?;
        Ok(Self {
            ctx,
            model,
            grammar,
            batch: LlamaBatch::new(BATCH, 1),
            cached: Vec::new(),
            variant: variant.to_string(),
            last: WriteStats::default(),
            generated_total: 0,
            load_s: started.elapsed().as_secs_f64(),
        })
    }

    /// Seconds the load took.
    pub fn load_s(&self) -> f64 {
        self.load_s
    }

    /// What the last program cost.
    pub fn last_stats(&self) -> WriteStats {
        self.last
    }

    /// Tokens generated since the model was loaded.
    pub fn tokens_generated(&self) -> usize {
        self.generated_total
    }

    /// The program's JSON text for `instruction` (a repair when `repair` holds the program
    /// and its problem): greedy decoding under the grammar.
    pub fn write_json(
        &mut self,
        instruction: &str,
        limits: &FormationLimits,
        repair: Option<(&str, &Problem)>,
    ) -> Result<String, LlmError> {
        let prompt = chat_prompt(
            self.model,
            SYSTEM,
            user_message(instruction, limits, repair),
        )?;
        let tokens = self.model.vocab().tokenize(prompt.as_bytes(), false, true);
        let context = self.ctx.n_ctx() as usize;
        if tokens.len() + MAX_PROGRAM_TOKENS >= context {
            return Err(LlmError::PromptTooLong {
                tokens: tokens.len(),
                context,
            });
        }
        let t0 = Instant::now();
        let reused = reuse_prefix(&mut self.ctx, &self.cached, &tokens);
        eval_tokens(&mut self.ctx, &mut self.batch, &tokens[reused..], reused)?;
        self.cached.clear();
        self.cached.extend_from_slice(&tokens);
        let prompt_s = t0.elapsed().as_secs_f64();
        let t1 = Instant::now();
        self.grammar.reset();
        // "]}" ends the program and appears nowhere else in it
        let (bytes, generated, outcome) = generate_under_grammar(
            &mut self.ctx,
            &mut self.batch,
            self.model,
            &mut self.grammar,
            tokens.len(),
            MAX_PROGRAM_TOKENS,
            b"]}",
        );
        let outcome = outcome.map_err(|stop| match stop {
            GenerateStop::Truncated(n) => LlmError::ProgramTruncated(n),
            GenerateStop::NoAllowedToken => LlmError::NoAllowedToken { field: "program" },
            GenerateStop::Decode(e) => e,
        });
        // the next prompt shares only the prompt's tokens
        let _ = self
            .ctx
            .clear_kv_cache_seq(Some(0), Some(tokens.len() as u32), None);
        self.last = WriteStats {
            prompt_tokens: tokens.len(),
            reused_tokens: reused,
            generated_tokens: generated,
            prompt_s,
            generate_s: t1.elapsed().as_secs_f64(),
        };
        self.generated_total += generated;
        outcome?;
        Ok(String::from_utf8_lossy(&bytes).into_owned())
    }

    fn program(&mut self, text: String) -> Result<FormationProgram, LlmError> {
        program_from_json(&text).map_err(|source| LlmError::ProgramOutput { text, source })
    }
}

impl ProgramWriter for FormationWriter {
    type Error = LlmError;

    fn name(&self) -> &str {
        &self.variant
    }

    fn write(
        &mut self,
        instruction: &str,
        limits: &FormationLimits,
    ) -> Result<FormationProgram, LlmError> {
        let text = self.write_json(instruction, limits, None)?;
        self.program(text)
    }

    /// The model rewrites the program from its JSON form and the problem's text; `None`
    /// when it cannot (a form the model cannot read, or no program came out).
    fn repair(
        &mut self,
        instruction: &str,
        program: &FormationProgram,
        problem: &Problem,
        limits: &FormationLimits,
    ) -> Option<FormationProgram> {
        let before = program_to_json(program)?;
        let text = self
            .write_json(instruction, limits, Some((&before, problem)))
            .ok()?;
        self.program(text).ok()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use aeris_formation::parse_instruction;

    #[test]
    fn the_json_form_round_trips_the_parsers_programs() {
        let limits = FormationLimits::default();
        for text in [
            "four drones take off to 5 m in a line 3 m apart, then form a V heading north, \
             hold 10 s, then a circle of radius 6 m, and land",
            "three drones take off to 8 m, a column 4 m apart heading east, move 20 m north \
             at 3 m/s, a grid, hold 5 s, land",
        ] {
            let program = parse_instruction(text, &limits).unwrap();
            let json = program_to_json(&program).unwrap();
            let back = program_from_json(&json).unwrap();
            assert_eq!(back.vehicles, program.vehicles);
            assert_eq!(back.phase_count, program.phase_count);
            for (a, b) in back.phases().iter().zip(program.phases()) {
                assert_eq!((a.kind, a.shape), (b.kind, b.shape));
                for (x, y) in [
                    (a.height_m, b.height_m),
                    (a.spacing_m, b.spacing_m),
                    (a.heading_rad, b.heading_rad),
                    (a.hold_s, b.hold_s),
                    (a.speed_mps, b.speed_mps),
                    (a.centre[0], b.centre[0]),
                    (a.centre[1], b.centre[1]),
                ] {
                    assert!((x - y).abs() < 0.05, "{json}: {x} vs {y}");
                }
            }
            back.validate(&limits).unwrap();
        }
    }

    #[test]
    fn a_text_that_is_no_program_is_refused_by_serde() {
        for bad in [
            r#"{"vehicles":4,"phases":[{"do":"jump"}]}"#,
            r#"{"vehicles":4,"phases":[{"do":"hold","seconds":1,"extra":2}]}"#,
            r#"{"vehicles":4}"#,
            r#"{"vehicles":400,"phases":[]}"#,
        ] {
            assert!(program_from_json(bad).is_err(), "{bad}");
        }
        let many = format!(
            r#"{{"vehicles":4,"phases":[{}]}}"#,
            vec![r#"{"do":"land"}"#; MAX_PHASES + 1].join(",")
        );
        let e = program_from_json(&many).unwrap_err().to_string();
        assert!(e.contains("17 phases"), "{e}");
    }

    #[test]
    fn the_grammar_has_every_rule_it_names() {
        let g = program_grammar().unwrap();
        for rule in [
            "root",
            "take-off",
            "assume",
            "hold",
            "move",
            "land",
            "middle",
            "shape",
            "vehicles",
            "height",
            "spacing",
            "heading",
            "coordinate",
            "seconds",
            "speed",
        ] {
            assert!(
                g.contains(&format!("\n{rule} ::= ")) || g.starts_with(&format!("{rule} ::= ")),
                "{rule}"
            );
        }
        assert!(g.contains(&format!("{{0,{}}}", MAX_PHASES - 3)));
    }
}
