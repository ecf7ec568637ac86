//! What was read in one step of an instruction (issue 37, item 4): the turn it asks for, how
//! it relates the vehicle to a landmark, which landmark (as perception labels it), the text
//! that landmark carries, and the height it names.
//!
//! A language model writes it under a grammar (`aeris-llm`'s instruction reader); the
//! mission carries it beside the step's text (the runtime's `SubgoalSpec::reading`), and the
//! planner flies what it says, reading only what it leaves out from the text by its phrase
//! rules.

/// Most bytes of a reading's landmark or sign text.
pub const READING_TEXT_MAX: usize = 64;

/// The heading change a step asks for before it flies.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum Turn {
    /// No turn: the step flies on from the heading it starts with.
    #[default]
    None,
    /// A quarter turn left.
    Left,
    /// A quarter turn right.
    Right,
    /// A half turn.
    Around,
}

impl Turn {
    /// The heading change (rad, positive right).
    pub fn radians(self) -> f32 {
        match self {
            Turn::None => 0.0,
            Turn::Left => -core::f32::consts::FRAC_PI_2,
            Turn::Right => core::f32::consts::FRAC_PI_2,
            Turn::Around => core::f32::consts::PI,
        }
    }
}

/// How a step relates the vehicle to its landmark.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum Relation {
    /// "fly to X": stop short of it.
    To,
    /// "fly over X": pass above it (`above` in a reading).
    #[cfg_attr(feature = "serde", serde(rename = "above"))]
    Over,
    /// "land next to X": land short of it (`beside` in a reading).
    #[cfg_attr(feature = "serde", serde(rename = "beside"))]
    NextTo,
}

/// One step as read.
#[derive(Debug, Clone, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct StepReading {
    /// The turn it asks for.
    pub turn: Turn,
    /// How it relates the vehicle to its landmark; `None` when it names no place.
    pub relation: Option<Relation>,
    /// The landmark, as perception labels it ("yellow sign").
    pub landmark: Option<String>,
    /// The text the landmark carries, as the step quotes it ("CITY HALL").
    pub sign: Option<String>,
    /// The height it names (m above the start).
    pub height_m: Option<f32>,
}

/// Why a reading is unusable.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StepReadingError {
    /// A landmark or sign text is empty, too long or holds control characters.
    #[error(
        "its {field} text {text:?} is empty, longer than {READING_TEXT_MAX} bytes or holds control characters"
    )]
    BadText {
        /// `landmark` or `sign`.
        field: &'static str,
        /// The text.
        text: String,
    },
    /// The height is not a finite positive number.
    #[error("its height {0} m is not a finite positive number")]
    BadHeight(f32),
}

impl StepReading {
    /// Check the texts and the height.
    pub fn validate(&self) -> Result<(), StepReadingError> {
        for (field, text) in [("landmark", &self.landmark), ("sign", &self.sign)] {
            if let Some(t) = text
                && (t.trim().is_empty()
                    || t.len() > READING_TEXT_MAX
                    || t.chars().any(char::is_control))
            {
                return Err(StepReadingError::BadText {
                    field,
                    text: t.clone(),
                });
            }
        }
        match self.height_m {
            Some(h) if !(h.is_finite() && h > 0.0) => Err(StepReadingError::BadHeight(h)),
            _ => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_reading_with_a_bad_text_or_height_is_refused() {
        let ok = StepReading {
            turn: Turn::Right,
            relation: Some(Relation::NextTo),
            landmark: Some("yellow sign".into()),
            sign: Some("CITY HALL".into()),
            height_m: None,
        };
        assert_eq!(ok.validate(), Ok(()));
        let mut bad = ok.clone();
        bad.sign = Some(" ".into());
        assert!(matches!(
            bad.validate(),
            Err(StepReadingError::BadText { field: "sign", .. })
        ));
        let mut bad = ok.clone();
        bad.landmark = Some("x".repeat(READING_TEXT_MAX + 1));
        assert!(bad.validate().is_err());
        let mut bad = ok;
        bad.height_m = Some(f32::NAN);
        assert!(matches!(
            bad.validate(),
            Err(StepReadingError::BadHeight(_))
        ));
        assert_eq!(Turn::Left.radians(), -core::f32::consts::FRAC_PI_2);
    }
}
