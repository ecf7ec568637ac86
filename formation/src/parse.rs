//! The deterministic formation parser (`formation/parser`): an instruction in plain English
//! to a [`FormationProgram`], clause by clause. It is the formation role's fallback and the
//! oracle the language-model variant is tested against.
//!
//! An instruction is a sequence of clauses separated by commas, semicolons, "then" and
//! "and". Each clause is one of:
//!
//! | clause | phase | e.g. |
//! |---|---|---|
//! | take off [to H m] | `take_off` (H default [`DEFAULT_HEIGHT_M`]) | "four drones take off to 5 m" |
//! | [form / assume / fly in] a SHAPE [S m apart / of radius S m] [heading DIR] [at H m] | `assume` | "a circle of radius 6 m", "form a V heading north" |
//! | hold [for] T s / min | `hold` | "hold 10 s" |
//! | move / fly / go D m DIR [at V m/s] | `move` (V default [`DEFAULT_SPEED_MPS`]) | "move 20 m north at 3 m/s" |
//! | land | `land` | "and land" |
//!
//! SHAPE is line (abreast), column (file, trail), V (wedge, vee), circle (ring) or grid
//! (box); DIR a compass point (north, north-east, ..., or N degrees). A take-off clause may
//! also name a shape ("take off to 5 m in a line 3 m apart"): it then assumes it. "N drones"
//! anywhere says how many vehicles fly (default: all the flight has). What a clause leaves
//! out is kept from the one before (height, spacing, heading, centre); the formation's
//! centre starts at the origin. The parser does not validate: the program goes through
//! [`FormationProgram::validate`] like any other.

use aeris_schemas::{
    FormationLimits, FormationPhase, FormationProgram, MAX_PHASES, PhaseKind, ShapeKind,
};

/// Height of a take-off that names none (m).
pub const DEFAULT_HEIGHT_M: f32 = 5.0;
/// Spacing of the first shape that names none (m; at least the minimum separation).
pub const DEFAULT_SPACING_M: f32 = 3.0;
/// Speed of a move that names none (m/s).
pub const DEFAULT_SPEED_MPS: f32 = 2.0;

/// Why an instruction could not be parsed. Every variant quotes the clause.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ParseError {
    /// Nothing to parse.
    #[error("the instruction is empty")]
    Empty,
    /// A clause that is none of take off, a shape, hold, move or land.
    #[error(
        "`{0}`: not a take-off, shape, hold, move or land (see the formation section of the README)"
    )]
    Unrecognised(String),
    /// A clause that lacks a number it needs.
    #[error("`{clause}`: no {what}")]
    Missing {
        /// The clause.
        clause: String,
        /// What it lacks ("hold time", "distance", "direction").
        what: &'static str,
    },
    /// More phases than a program holds.
    #[error("more than {MAX_PHASES} phases")]
    TooManyPhases,
}

/// The words of one clause, lower case, punctuation split off ("v-shape" -> "v", "shape").
fn words(clause: &str) -> Vec<String> {
    clause
        .to_lowercase()
        .split(|c: char| !(c.is_alphanumeric() || c == '.' || c == '/'))
        .map(|w| w.trim_matches('.').to_string())
        .filter(|w| !w.is_empty())
        .collect()
}

/// The number word `w` is ("3", "2.5", "four"; "3m" -> 3).
fn number(w: &str) -> Option<f32> {
    const WORDS: [&str; 13] = [
        "zero", "one", "two", "three", "four", "five", "six", "seven", "eight", "nine", "ten",
        "eleven", "twelve",
    ];
    if let Some(n) = WORDS.iter().position(|x| *x == w) {
        return Some(n as f32);
    }
    let digits = w.trim_end_matches(|c: char| c.is_alphabetic() || c == '/');
    digits.parse::<f32>().ok().filter(|v| v.is_finite())
}

/// The first number after word index `from` (within `span` words).
fn number_after(w: &[String], from: usize, span: usize) -> Option<f32> {
    w.iter().skip(from + 1).take(span).find_map(|x| number(x))
}

/// The number just before word index `at` (skipping a unit).
fn number_before(w: &[String], at: usize) -> Option<f32> {
    (at.saturating_sub(3)..at).rev().find_map(|i| number(&w[i]))
}

fn position(w: &[String], any: &[&str]) -> Option<usize> {
    w.iter().position(|x| any.contains(&x.as_str()))
}

/// A compass direction at or after `from` as a heading (rad, 0 = north, clockwise).
fn direction(w: &[String], from: usize) -> Option<f32> {
    use core::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI};
    let named = |x: &str| {
        Some(match x {
            "north" | "northward" | "northwards" => 0.0,
            "northeast" | "north-east" => FRAC_PI_4,
            "east" | "eastward" | "eastwards" => FRAC_PI_2,
            "southeast" | "south-east" => 3.0 * FRAC_PI_4,
            "south" | "southward" | "southwards" => PI,
            "southwest" | "south-west" => -3.0 * FRAC_PI_4,
            "west" | "westward" | "westwards" => -FRAC_PI_2,
            "northwest" | "north-west" => -FRAC_PI_4,
            _ => return None,
        })
    };
    for i in from..w.len() {
        // "north east" as two words
        if let (Some(a), Some(b)) = (named(&w[i]), w.get(i + 1).and_then(|x| named(x)))
            && (a == 0.0 || a == PI)
            && b.abs() == FRAC_PI_2
        {
            return Some(if a == 0.0 {
                b / 2.0
            } else {
                b.signum() * 3.0 * FRAC_PI_4
            });
        }
        if let Some(h) = named(&w[i]) {
            return Some(h);
        }
        if w.get(i + 1).is_some_and(|x| x.starts_with("deg"))
            && let Some(d) = number(&w[i])
        {
            let r = d.to_radians();
            // to [-pi, pi]
            return Some((r + PI).rem_euclid(2.0 * PI) - PI);
        }
    }
    None
}

fn shape(w: &[String]) -> Option<(usize, ShapeKind)> {
    w.iter().enumerate().find_map(|(i, x)| {
        Some((
            i,
            match x.as_str() {
                "line" | "abreast" => ShapeKind::Line,
                "column" | "file" | "trail" => ShapeKind::Column,
                "v" | "vee" | "wedge" | "chevron" => ShapeKind::Wedge,
                "circle" | "ring" => ShapeKind::Circle,
                "grid" | "box" => ShapeKind::Grid,
                _ => return None,
            },
        ))
    })
}

/// The clauses of an instruction, in order: split at commas, semicolons, line ends and the
/// words "then", "and", "finally", "afterwards" (the language-model variant lists them for
/// its model too).
pub fn clauses(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    for part in text.split([',', ';', '\n']) {
        let mut current = Vec::new();
        for word in part.split_whitespace() {
            let lower = word.to_lowercase();
            if matches!(lower.as_str(), "then" | "and" | "finally" | "afterwards") {
                if !current.is_empty() {
                    out.push(current.join(" "));
                    current.clear();
                }
            } else {
                current.push(word);
            }
        }
        if !current.is_empty() {
            out.push(current.join(" "));
        }
    }
    out
}

/// What the clauses so far left in force.
struct Carry {
    height: f32,
    spacing: f32,
    heading: f32,
    centre: [f32; 2],
}

/// Parse `instruction` into a program for the flight whose limits are `limits` (its vehicle
/// count is the default, its minimum separation the floor of the default spacing).
pub fn parse_instruction(
    instruction: &str,
    limits: &FormationLimits,
) -> Result<FormationProgram, ParseError> {
    let clauses = clauses(instruction);
    if clauses.is_empty() {
        return Err(ParseError::Empty);
    }
    let mut program = FormationProgram {
        vehicles: limits.vehicles,
        ..FormationProgram::default()
    };
    let mut carry = Carry {
        height: DEFAULT_HEIGHT_M.max(limits.h_min),
        spacing: DEFAULT_SPACING_M.max(limits.min_separation_m),
        heading: 0.0,
        centre: [0.0, 0.0],
    };
    let mut phases: Vec<FormationPhase> = Vec::new();
    for clause in &clauses {
        let w = words(clause);
        if let Some(i) = position(&w, &["drones", "vehicles", "uavs", "quadrotors", "copters"])
            && let Some(n) = number_before(&w, i)
        {
            program.vehicles = n.clamp(0.0, 255.0) as u8;
        }
        let take_off = w
            .windows(2)
            .position(|p| p[0] == "take" && p[1] == "off")
            .or_else(|| position(&w, &["takeoff", "take-off", "launch"]));
        let land = position(&w, &["land", "landing"]);
        let hold = position(&w, &["hold", "hover", "wait", "stay"]);
        let movement = position(&w, &["move", "fly", "go", "head", "translate", "travel"]);
        let found_shape = shape(&w);
        if let Some(t) = take_off {
            // "take off to 5 m": the number after "to", before any shape
            let end = found_shape.map_or(w.len(), |(i, _)| i);
            let to = w[t..end].iter().position(|x| x == "to").map(|i| i + t);
            if let Some(h) = to.and_then(|i| number_after(&w[..end], i, 3)) {
                carry.height = h;
            }
            phases.push(FormationPhase {
                kind: PhaseKind::TakeOff as u8,
                height_m: carry.height,
                ..FormationPhase::default()
            });
        }
        if let Some((at, kind)) = found_shape {
            phases.push(assume(&w, at, kind, &mut carry));
        } else if let Some(h) = hold.filter(|_| take_off.is_none() && land.is_none()) {
            let t = number_after(&w, h, 3).ok_or_else(|| ParseError::Missing {
                clause: clause.clone(),
                what: "hold time",
            })?;
            let minutes = w.iter().any(|x| x.starts_with("min"));
            phases.push(FormationPhase {
                kind: PhaseKind::Hold as u8,
                hold_s: if minutes { t * 60.0 } else { t },
                ..FormationPhase::default()
            });
        } else if let Some(m) = movement.filter(|_| take_off.is_none() && land.is_none()) {
            phases.push(translate(&w, m, clause, &mut carry)?);
        } else if land.is_none() && take_off.is_none() {
            return Err(ParseError::Unrecognised(clause.clone()));
        }
        if land.is_some() {
            phases.push(FormationPhase {
                kind: PhaseKind::Land as u8,
                ..FormationPhase::default()
            });
        }
    }
    if phases.len() > MAX_PHASES {
        return Err(ParseError::TooManyPhases);
    }
    program.phase_count = phases.len() as u8;
    program.phases[..phases.len()].copy_from_slice(&phases);
    Ok(program)
}

/// An `assume` phase from a clause naming `kind` at word `at`.
fn assume(w: &[String], at: usize, kind: ShapeKind, carry: &mut Carry) -> FormationPhase {
    // "3 m apart", "spacing of 3 m", "3 m spacing", "radius 6 m", "6 m radius"
    let spacing = position(w, &["apart", "spaced"])
        .and_then(|i| number_before(w, i).or_else(|| number_after(w, i, 3)))
        .or_else(|| {
            position(w, &["spacing", "radius", "separation"])
                .and_then(|i| number_after(w, i, 3).or_else(|| number_before(w, i)))
        });
    if let Some(s) = spacing {
        carry.spacing = s;
    }
    if let Some(h) = position(w, &["heading", "facing", "pointing", "towards", "toward"])
        .and_then(|i| direction(w, i + 1))
    {
        carry.heading = h;
    }
    // "at 8 m" after the shape word (altitude), not "apart"'s number
    if let Some(h) = w
        .iter()
        .enumerate()
        .skip(at)
        .filter(|(_, x)| *x == "at" || *x == "altitude" || *x == "height")
        .find_map(|(i, _)| {
            let n = number_after(w, i, 2)?;
            let unit_ok = w
                .get(i + 2)
                .is_none_or(|u| u == "m" || u.starts_with("met") || u.starts_with("alt"));
            unit_ok.then_some(n)
        })
    {
        carry.height = h;
    }
    FormationPhase {
        kind: PhaseKind::Assume as u8,
        shape: kind as u8,
        height_m: carry.height,
        spacing_m: carry.spacing,
        heading_rad: carry.heading,
        centre: carry.centre,
        ..FormationPhase::default()
    }
}

/// A `move` phase from a clause whose verb is at word `at`.
fn translate(
    w: &[String],
    at: usize,
    clause: &str,
    carry: &mut Carry,
) -> Result<FormationPhase, ParseError> {
    let missing = |what| ParseError::Missing {
        clause: clause.to_string(),
        what,
    };
    let distance = number_after(w, at, 3).ok_or_else(|| missing("distance"))?;
    let heading = direction(w, at + 1).ok_or_else(|| missing("direction"))?;
    let speed = position(w, &["at", "speed"])
        .and_then(|i| {
            let n = number_after(w, i, 2)?;
            w.iter()
                .skip(i)
                .any(|u| u.contains("/s") || u.starts_with("mps") || u == "per")
                .then_some(n)
        })
        .unwrap_or(DEFAULT_SPEED_MPS);
    carry.centre = [
        carry.centre[0] + distance * heading.cos(),
        carry.centre[1] + distance * heading.sin(),
    ];
    Ok(FormationPhase {
        kind: PhaseKind::Move as u8,
        speed_mps: speed,
        centre: carry.centre,
        ..FormationPhase::default()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kinds(p: &FormationProgram) -> Vec<&'static str> {
        p.phases()
            .iter()
            .map(|x| PhaseKind::from_u8(x.kind).unwrap().name())
            .collect()
    }

    #[test]
    fn the_issue_instruction_becomes_a_valid_program() {
        let limits = FormationLimits::default();
        let p = parse_instruction(
            "four drones take off to 5 m in a line 3 m apart, then form a V heading north, \
             hold 10 s, then a circle of radius 6 m, and land",
            &limits,
        )
        .unwrap();
        assert_eq!(p.vehicles, 4);
        assert_eq!(
            kinds(&p),
            ["take_off", "assume", "assume", "hold", "assume", "land"]
        );
        let ph = p.phases();
        assert_eq!(ph[0].height_m, 5.0);
        assert_eq!(
            (ph[1].shape, ph[1].spacing_m, ph[1].height_m),
            (ShapeKind::Line as u8, 3.0, 5.0)
        );
        assert_eq!(
            (ph[2].shape, ph[2].spacing_m, ph[2].heading_rad),
            (ShapeKind::Wedge as u8, 3.0, 0.0)
        );
        assert_eq!(ph[3].hold_s, 10.0);
        assert_eq!(
            (ph[4].shape, ph[4].spacing_m),
            (ShapeKind::Circle as u8, 6.0)
        );
        assert_eq!(p.validate(&limits), Ok(()));
    }

    #[test]
    fn moves_headings_heights_and_defaults() {
        let limits = FormationLimits::default();
        let p = parse_instruction(
            "Take off; form a column 4 m apart heading east at 8 m; move 20 m north-east at \
             3 m/s; hold for 2 minutes; a grid; fly 10 m west; land",
            &limits,
        )
        .unwrap();
        assert_eq!(p.vehicles, 4, "the flight's vehicles by default");
        assert_eq!(
            kinds(&p),
            [
                "take_off", "assume", "move", "hold", "assume", "move", "land"
            ]
        );
        let ph = p.phases();
        assert_eq!(ph[0].height_m, DEFAULT_HEIGHT_M);
        let fp = core::f32::consts::FRAC_PI_2;
        assert_eq!(
            (ph[1].spacing_m, ph[1].heading_rad, ph[1].height_m),
            (4.0, fp, 8.0)
        );
        let d = 20.0 * core::f32::consts::FRAC_1_SQRT_2;
        assert!((ph[2].centre[0] - d).abs() < 1e-4 && (ph[2].centre[1] - d).abs() < 1e-4);
        assert_eq!(ph[2].speed_mps, 3.0);
        assert_eq!(ph[3].hold_s, 120.0);
        // the grid keeps the column's spacing, heading, height and the moved centre
        assert_eq!(
            (ph[4].spacing_m, ph[4].heading_rad, ph[4].height_m),
            (4.0, fp, 8.0)
        );
        assert_eq!(ph[4].centre, ph[2].centre);
        assert!((ph[5].centre[1] - (d - 10.0)).abs() < 1e-4);
        assert_eq!(ph[5].speed_mps, DEFAULT_SPEED_MPS);
        assert_eq!(p.validate(&limits), Ok(()));
    }

    #[test]
    fn what_cannot_be_parsed_is_named() {
        let limits = FormationLimits::default();
        assert_eq!(parse_instruction("  ", &limits), Err(ParseError::Empty));
        let e = parse_instruction("take off, do a barrel roll, land", &limits).unwrap_err();
        assert_eq!(e, ParseError::Unrecognised("do a barrel roll".into()));
        assert!(e.to_string().contains("`do a barrel roll`"));
        assert!(matches!(
            parse_instruction("take off, hold, land", &limits),
            Err(ParseError::Missing {
                what: "hold time",
                ..
            })
        ));
        assert!(matches!(
            parse_instruction("take off, a line, move 10 m, land", &limits),
            Err(ParseError::Missing {
                what: "direction",
                ..
            })
        ));
    }

    #[test]
    fn a_request_beyond_the_limits_parses_and_fails_validation() {
        // spacing below the minimum separation, more vehicles than the flight has: parsed as
        // said, refused by validate with the reason (the repair loop's input)
        let limits = FormationLimits::default();
        let p = parse_instruction("take off, a line 1 m apart, land", &limits).unwrap();
        assert!(
            p.validate(&limits)
                .unwrap_err()
                .to_string()
                .contains("spacing = 1")
        );
        let p = parse_instruction("six drones take off, a circle, land", &limits).unwrap();
        assert_eq!(p.vehicles, 6);
        assert!(
            p.validate(&limits)
                .unwrap_err()
                .to_string()
                .contains("6 vehicles")
        );
        // no land: parsed, refused
        let p = parse_instruction("take off, a line", &limits).unwrap();
        assert!(p.validate(&limits).is_err());
    }
}
