//! The decision grammar: a GBNF grammar generated from D_t's schema and the flight's limits.
//!
//! A language model decoding under this grammar can only write one JSON object, the
//! [`DecisionView`](crate::DecisionView) of a decision, whose every number lies inside the
//! range Valid(D_t) checks (the step inside `1..=L`, the waypoint inside the geofence, speed,
//! altitude, radius and confidence inside their bounds, yaw inside [-180, 180] degrees) and
//! whose action is one of the action-mode names. Ranges are encoded as digit patterns, the
//! way a regular expression encodes a numeric range, so the grammar stays small.

use aeris_schemas::{ActionMode, DecisionLimits};
use core::fmt::Write;

/// Why no grammar can be generated for a set of limits.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GrammarError {
    /// The limits are not coherent (NaN, inverted bounds, no subgoals).
    #[error("the decision limits are incoherent")]
    IncoherentLimits,
    /// A field's range holds no number the grammar can write.
    #[error("the range of `{field}` ([{min}, {max}]) holds no decimal with {decimals} digits")]
    EmptyRange {
        /// JSON field name.
        field: &'static str,
        /// Lower bound.
        min: f64,
        /// Upper bound.
        max: f64,
        /// Digits after the decimal point.
        decimals: u32,
    },
    /// A bound is too large for the grammar's integer arithmetic (|x| * 10^decimals > 10^15).
    #[error("the range of `{field}` is too large")]
    RangeTooLarge {
        /// JSON field name.
        field: &'static str,
    },
}

/// One number field of the decision view: its JSON key, bounds and written precision.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NumberField {
    /// JSON key.
    pub key: &'static str,
    /// Smallest allowed value.
    pub min: f64,
    /// Largest allowed value.
    pub max: f64,
    /// Digits after the decimal point (0: an integer).
    pub decimals: u32,
}

/// A sequence of digit classes `(lo, hi)`, one per written digit.
type DigitPattern = Vec<(u8, u8)>;

/// Digit patterns that together match exactly the decimal writings (no leading zeros) of
/// the integers in `[a, b]`.
pub(crate) fn integer_patterns(a: u64, b: u64) -> Vec<DigitPattern> {
    let mut out = Vec::new();
    if a > b {
        return out;
    }
    let digits = |x: u64| x.checked_ilog10().unwrap_or(0) + 1;
    for len in digits(a)..=digits(b) {
        let lo = if len == 1 { 0 } else { 10u64.pow(len - 1) };
        let hi = 10u64.pow(len) - 1;
        let (from, to) = (a.max(lo), b.min(hi));
        if from <= to {
            same_length(&to_digits(from, len), &to_digits(to, len), &mut out);
        }
    }
    out
}

fn to_digits(x: u64, len: u32) -> Vec<u8> {
    (0..len)
        .rev()
        .map(|i| ((x / 10u64.pow(i)) % 10) as u8)
        .collect()
}

/// Patterns for every digit string of `a.len()` digits between `a` and `b` (inclusive).
fn same_length(a: &[u8], b: &[u8], out: &mut Vec<DigitPattern>) {
    debug_assert_eq!(a.len(), b.len());
    if a.is_empty() {
        out.push(Vec::new());
        return;
    }
    let (a0, b0) = (a[0], b[0]);
    let (ra, rb) = (&a[1..], &b[1..]);
    if a0 == b0 {
        let mut tails = Vec::new();
        same_length(ra, rb, &mut tails);
        out.extend(tails.into_iter().map(|t| prefixed((a0, a0), t)));
        return;
    }
    let all_zero = ra.iter().all(|&d| d == 0);
    let all_nine = rb.iter().all(|&d| d == 9);
    let mid_lo = if all_zero { a0 } else { a0 + 1 };
    let mid_hi = if all_nine { b0 } else { b0 - 1 };
    if !all_zero {
        let mut tails = Vec::new();
        same_length(ra, &vec![9; ra.len()], &mut tails);
        out.extend(tails.into_iter().map(|t| prefixed((a0, a0), t)));
    }
    if mid_lo <= mid_hi {
        let mut p = vec![(mid_lo, mid_hi)];
        p.extend(std::iter::repeat_n((0, 9), ra.len()));
        out.push(p);
    }
    if !all_nine {
        let mut tails = Vec::new();
        same_length(&vec![0; rb.len()], rb, &mut tails);
        out.extend(tails.into_iter().map(|t| prefixed((b0, b0), t)));
    }
}

fn prefixed(head: (u8, u8), tail: DigitPattern) -> DigitPattern {
    let mut p = Vec::with_capacity(tail.len() + 1);
    p.push(head);
    p.extend(tail);
    p
}

/// Write `k / 10^decimals` with exactly `decimals` fraction digits.
fn fixed(k: i64, decimals: u32) -> String {
    let scale = 10i64.pow(decimals);
    let sign = if k < 0 { "-" } else { "" };
    let m = k.unsigned_abs();
    if decimals == 0 {
        format!("{sign}{m}")
    } else {
        format!(
            "{sign}{}.{:0width$}",
            m / scale as u64,
            m % scale as u64,
            width = decimals as usize
        )
    }
}

/// The integer bounds, in units of 10^-decimals, of the numbers the grammar may write for
/// `field`: the largest range whose written values, parsed as `f32`, stay inside the field's
/// `f32` bounds (checked by parsing, so rounding can never push a value outside).
fn scaled_bounds(field: &NumberField) -> Result<(i64, i64), GrammarError> {
    let scale = 10f64.powi(field.decimals as i32);
    let (lo, hi) = (field.min * scale, field.max * scale);
    if !(lo.abs() <= 1e15 && hi.abs() <= 1e15) {
        return Err(GrammarError::RangeTooLarge { field: field.key });
    }
    let (min32, max32) = (field.min as f32, field.max as f32);
    let mut a = lo.ceil() as i64;
    let mut b = hi.floor() as i64;
    let value = |k: i64| fixed(k, field.decimals).parse::<f32>().unwrap_or(f32::NAN);
    while a <= b && value(a).partial_cmp(&min32).is_none_or(|o| o.is_lt()) {
        a += 1;
    }
    while a <= b && value(b).partial_cmp(&max32).is_none_or(|o| o.is_gt()) {
        b -= 1;
    }
    if a > b {
        return Err(GrammarError::EmptyRange {
            field: field.key,
            min: field.min,
            max: field.max,
            decimals: field.decimals,
        });
    }
    Ok((a, b))
}

/// Write one digit pattern as GBNF, with the decimal point before the last `decimals` digits
/// (patterns shorter than `decimals + 1` digits get leading zeros: 5 -> "0.5").
fn write_pattern(out: &mut String, pattern: &[(u8, u8)], decimals: u32) {
    let mut p: Vec<(u8, u8)> = Vec::with_capacity(pattern.len() + decimals as usize + 1);
    let need = decimals as usize + 1;
    if pattern.len() < need {
        p.extend(std::iter::repeat_n((0, 0), need - pattern.len()));
    }
    p.extend_from_slice(pattern);
    let point_at = p.len() - decimals as usize;
    let mut literal = String::new();
    let flush = |out: &mut String, literal: &mut String| {
        if !literal.is_empty() {
            let _ = write!(out, "\"{literal}\" ");
            literal.clear();
        }
    };
    for (i, &(lo, hi)) in p.iter().enumerate() {
        if i == point_at && decimals > 0 {
            literal.push('.');
        }
        if lo == hi {
            literal.push((b'0' + lo) as char);
        } else {
            flush(out, &mut literal);
            let _ = write!(out, "[{}-{}] ", lo, hi);
        }
    }
    flush(out, &mut literal);
}

/// The GBNF alternatives for a number field (the right-hand side of its rule).
pub fn number_rule(field: &NumberField) -> Result<String, GrammarError> {
    let (a, b) = scaled_bounds(field)?;
    let mut alternatives = Vec::new();
    if b >= 0 {
        for p in integer_patterns(a.max(0) as u64, b as u64) {
            let mut s = String::new();
            write_pattern(&mut s, &p, field.decimals);
            alternatives.push(s.trim_end().to_string());
        }
    }
    if a < 0 {
        let (m_lo, m_hi) = ((b.min(-1)).unsigned_abs(), a.unsigned_abs());
        for p in integer_patterns(m_lo, m_hi) {
            let mut s = String::from("\"-\" ");
            write_pattern(&mut s, &p, field.decimals);
            alternatives.push(s.trim_end().to_string());
        }
    }
    Ok(alternatives
        .iter()
        .map(|a| format!("( {a} )"))
        .collect::<Vec<_>>()
        .join(" | "))
}

/// The number fields of the decision view, in the order the model writes them, with bounds
/// from `limits`.
pub fn number_fields(limits: &DecisionLimits) -> Result<[NumberField; 7], GrammarError> {
    if !limits.is_coherent() {
        return Err(GrammarError::IncoherentLimits);
    }
    let f = |x: f32| x as f64;
    let alt_min = limits.h_min.max(limits.geofence_min[2]);
    let alt_max = limits.h_max.min(limits.geofence_max[2]);
    Ok([
        NumberField {
            key: "north",
            min: f(limits.geofence_min[0]),
            max: f(limits.geofence_max[0]),
            decimals: 0,
        },
        NumberField {
            key: "east",
            min: f(limits.geofence_min[1]),
            max: f(limits.geofence_max[1]),
            decimals: 0,
        },
        NumberField {
            key: "altitude",
            min: f(alt_min),
            max: f(alt_max),
            decimals: 0,
        },
        NumberField {
            key: "yaw_deg",
            min: -180.0,
            max: 180.0,
            decimals: 0,
        },
        NumberField {
            key: "speed",
            min: 0.0,
            max: f(limits.v_max),
            decimals: 0,
        },
        NumberField {
            key: "radius",
            min: 0.0,
            max: f(limits.r_max),
            decimals: 0,
        },
        NumberField {
            key: "confidence",
            min: 0.0,
            max: 1.0,
            decimals: 1,
        },
    ])
}

/// One field of the decision as the decoder writes it: a fixed literal (the key, which the
/// decoder inserts without sampling), then a value sampled under `grammar`, which also
/// requires the character that ends the field (`,` or the closing `}`).
#[derive(Debug, Clone, PartialEq)]
pub struct FieldGrammar {
    /// JSON key.
    pub key: &'static str,
    /// The literal written before the value (`{"step":` for the first field, `"key":` after).
    pub prefix: String,
    /// GBNF (root rule `root`) of the value and its terminator.
    pub grammar: String,
    /// The terminator (`,` or `}`).
    pub terminator: char,
}

/// The decision grammar split per field, in writing order: concatenating each field's
/// prefix and a string its grammar accepts gives a string [`decision_grammar`] accepts.
pub fn field_grammars(limits: &DecisionLimits) -> Result<Vec<FieldGrammar>, GrammarError> {
    let numbers = number_fields(limits)?;
    let step = NumberField {
        key: "step",
        min: 1.0,
        max: limits.subgoals as f64,
        decimals: 0,
    };
    let mut out = Vec::with_capacity(numbers.len() + 2);
    let mut push = |key: &'static str, rule: String, first: bool, last: bool| {
        let terminator = if last { '}' } else { ',' };
        out.push(FieldGrammar {
            key,
            prefix: if first {
                format!("{{\"{key}\":")
            } else {
                format!("\"{key}\":")
            },
            grammar: format!("root ::= ( {rule} ) \"{terminator}\"\n"),
            terminator,
        });
    };
    push("step", number_rule(&step)?, true, false);
    push("action", action_rule(), false, false);
    for (i, field) in numbers.iter().enumerate() {
        push(
            field.key,
            number_rule(field)?,
            false,
            i + 1 == numbers.len(),
        );
    }
    Ok(out)
}

fn action_rule() -> String {
    ActionMode::ALL
        .iter()
        .map(|m| format!("\"\\\"{}\\\"\"", m.name()))
        .collect::<Vec<_>>()
        .join(" | ")
}

/// The GBNF grammar of one decision for the given limits (root rule `root`).
///
/// The object is `{"step":S,"action":"A","north":N,"east":E,"altitude":H,"yaw_deg":Y,
/// "speed":V,"radius":R,"confidence":C}` on one line, keys in that order, no spaces.
pub fn decision_grammar(limits: &DecisionLimits) -> Result<String, GrammarError> {
    let fields = number_fields(limits)?;
    let step = NumberField {
        key: "step",
        min: 1.0,
        max: limits.subgoals as f64,
        decimals: 0,
    };
    let mut g = String::new();
    let _ = write!(
        g,
        "root ::= \"{{\\\"step\\\":\" step \",\\\"action\\\":\" action"
    );
    for field in &fields {
        let _ = write!(g, " \",\\\"{}\\\":\" {}", field.key, rule_name(field.key));
    }
    g.push_str(" \"}\"\n");
    let _ = writeln!(g, "step ::= {}", number_rule(&step)?);
    let _ = writeln!(g, "action ::= {}", action_rule());
    for field in &fields {
        let _ = writeln!(g, "{} ::= {}", rule_name(field.key), number_rule(field)?);
    }
    Ok(g)
}

/// GBNF rule names may not contain `_`.
fn rule_name(key: &str) -> String {
    key.replace('_', "-")
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn matches(pattern: &[(u8, u8)], s: &str) -> bool {
        s.len() == pattern.len()
            && s.bytes()
                .zip(pattern)
                .all(|(c, &(lo, hi))| c >= b'0' + lo && c <= b'0' + hi)
    }

    fn covered(patterns: &[DigitPattern], x: u64) -> usize {
        let s = x.to_string();
        patterns.iter().filter(|p| matches(p, &s)).count()
    }

    #[test]
    fn small_ranges_are_exact() {
        for (a, b) in [
            (0, 0),
            (0, 9),
            (1, 4),
            (7, 123),
            (10, 99),
            (95, 1005),
            (0, 180),
        ] {
            let p = integer_patterns(a, b);
            for x in 0..1200 {
                let n = covered(&p, x);
                if (a..=b).contains(&x) {
                    assert_eq!(n, 1, "{x} in [{a}, {b}] matched {n} times");
                } else {
                    assert_eq!(n, 0, "{x} outside [{a}, {b}] matched");
                }
            }
        }
    }

    proptest! {
        #[test]
        fn every_integer_in_range_is_matched_once_and_no_other(
            a in 0u64..100_000, len in 0u64..100_000, probe in 0u64..250_000
        ) {
            let b = a + len;
            let p = integer_patterns(a, b);
            prop_assert_eq!(covered(&p, a), 1);
            prop_assert_eq!(covered(&p, b), 1);
            prop_assert_eq!(covered(&p, probe), usize::from((a..=b).contains(&probe)));
        }
    }

    #[test]
    fn decimals_get_a_point_and_leading_zero() {
        let f = NumberField {
            key: "confidence",
            min: 0.0,
            max: 1.0,
            decimals: 2,
        };
        let rule = number_rule(&f).unwrap();
        assert_eq!(
            rule,
            r#"( "0.0" [0-9] ) | ( "0." [1-9] [0-9] ) | ( "1.00" )"#
        );
    }

    #[test]
    fn bounds_never_round_outside() {
        // 0.1 is not representable: the bound must be checked on the parsed f32
        let f = NumberField {
            key: "x",
            min: -0.1f32 as f64,
            max: 12.3f32 as f64,
            decimals: 1,
        };
        let (a, b) = scaled_bounds(&f).unwrap();
        assert!(fixed(a, 1).parse::<f32>().unwrap() >= -0.1f32);
        assert!(fixed(b, 1).parse::<f32>().unwrap() <= 12.3f32);
        assert_eq!(
            (fixed(a, 1).as_str(), fixed(b, 1).as_str()),
            ("-0.1", "12.3")
        );
        let empty = NumberField {
            key: "x",
            min: 0.01,
            max: 0.09,
            decimals: 1,
        };
        assert!(matches!(
            scaled_bounds(&empty),
            Err(GrammarError::EmptyRange { .. })
        ));
    }

    #[test]
    fn incoherent_limits_give_no_grammar() {
        let limits = DecisionLimits {
            v_max: f32::NAN,
            h_min: 0.0,
            h_max: 60.0,
            r_max: 10.0,
            geofence_min: [-20.0, -40.0, 0.0],
            geofence_max: [160.0, 140.0, 60.0],
            obstacle_clearance_m: 3.0,
            subgoals: 4,
        };
        assert_eq!(
            decision_grammar(&limits),
            Err(GrammarError::IncoherentLimits)
        );
    }
}
