//! The JSON view of a decision that a language model writes (and reads back as memory).

use aeris_schemas::{ActionMode, Decision};
use serde::{Deserialize, Serialize};

/// Why a model's text is not a decision.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ViewError {
    /// Not one JSON object of the view's shape.
    #[error("not a decision object: {0}")]
    Json(String),
    /// The action is not an action-mode name.
    #[error("unknown action `{0}`")]
    UnknownAction(String),
}

/// One decision as the model writes it: the semantic fields of D_t, the waypoint split into
/// named coordinates (its up coordinate is `altitude`) and the yaw in whole degrees.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DecisionView {
    /// Active instruction step, 1-based.
    pub step: u16,
    /// Action-mode name.
    pub action: String,
    /// Waypoint north (m).
    pub north: f32,
    /// Waypoint east (m).
    pub east: f32,
    /// Altitude h_t and the waypoint's up coordinate (m).
    pub altitude: f32,
    /// Yaw in degrees, 0 = north, 90 = east.
    pub yaw_deg: f32,
    /// Speed (m/s).
    pub speed: f32,
    /// Acceptance radius (m).
    pub radius: f32,
    /// Confidence in [0, 1].
    pub confidence: f32,
}

impl DecisionView {
    /// Parse the model's output.
    pub fn parse(text: &str) -> Result<Self, ViewError> {
        serde_json::from_str(text.trim()).map_err(|e| ViewError::Json(e.to_string()))
    }

    /// The decision's semantic fields (routing fields left at their defaults).
    pub fn to_decision(&self) -> Result<Decision, ViewError> {
        let action = ActionMode::from_name(&self.action)
            .ok_or_else(|| ViewError::UnknownAction(self.action.clone()))?;
        Ok(Decision {
            target: [self.north, self.east, self.altitude],
            yaw: (self.yaw_deg as f64).to_radians() as f32,
            speed: self.speed,
            altitude: self.altitude,
            acceptance_radius: self.radius,
            confidence: self.confidence,
            step: self.step,
            action: action as u8,
            ..Decision::default()
        })
    }

    /// The view of a decision (for the memory line of the next prompt, and a training
    /// pair's target): whole numbers, never a negative zero (the grammar writes `0`).
    pub fn from_decision(d: &Decision) -> Self {
        // adding +0.0 turns -0.0 into 0.0 and leaves every other value as it is
        let round = |x: f32| x.round() + 0.0;
        Self {
            step: d.step,
            action: ActionMode::from_u8(d.action)
                .map(ActionMode::name)
                .unwrap_or("hover")
                .to_string(),
            north: round(d.target[0]),
            east: round(d.target[1]),
            altitude: round(d.altitude),
            yaw_deg: round(d.yaw.to_degrees()),
            speed: round(d.speed),
            radius: round(d.acceptance_radius),
            confidence: (d.confidence * 10.0).round() / 10.0 + 0.0,
        }
    }

    /// The view written the way the grammar writes it (keys in order; whole numbers except
    /// the confidence, which has one decimal).
    pub fn to_json(&self) -> String {
        format!(
            "{{\"step\":{},\"action\":\"{}\",\"north\":{:.0},\"east\":{:.0},\"altitude\":{:.0},\"yaw_deg\":{:.0},\"speed\":{:.0},\"radius\":{:.0},\"confidence\":{:.1}}}",
            self.step,
            self.action,
            self.north,
            self.east,
            self.altitude,
            self.yaw_deg,
            self.speed,
            self.radius,
            self.confidence
        )
    }
}

/// Fuzzing support (the `gate_json` target in `fuzz/` and its corpus replay test), not API:
/// read `text` the way the reasoner reads a model's output ([`DecisionView::parse`], then
/// [`DecisionView::to_decision`]) and hand the decision to `admit` (the decision gate);
/// when it is admitted, its view (the memory line of the next prompt) must be written in a
/// form that parses back to the same view. Panics when that fails.
#[doc(hidden)]
pub fn fuzz_check_text(text: &str, admit: impl FnOnce(&Decision) -> bool) {
    let Ok(view) = DecisionView::parse(text) else {
        return;
    };
    let Ok(decision) = view.to_decision() else {
        return;
    };
    if admit(&decision) {
        let memory = DecisionView::from_decision(&decision);
        let json = memory.to_json();
        let back = DecisionView::parse(&json)
            .unwrap_or_else(|e| panic!("memory line {json} of {text:?} does not parse: {e}"));
        assert_eq!(back, memory, "memory line {json} of {text:?}");
        assert!(back.to_decision().is_ok(), "memory line {json}");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_through_the_written_form() {
        let v = DecisionView {
            step: 2,
            action: "goto".into(),
            north: 62.0,
            east: -4.0,
            altitude: 12.0,
            yaw_deg: 90.0,
            speed: 5.0,
            radius: 3.0,
            confidence: 0.8,
        };
        let back = DecisionView::parse(&v.to_json()).unwrap();
        assert_eq!(back, v);
        let d = back.to_decision().unwrap();
        assert_eq!(d.action, ActionMode::Goto as u8);
        assert_eq!(d.target, [62.0, -4.0, 12.0]);
        assert!((d.yaw - core::f32::consts::FRAC_PI_2).abs() < 1e-6);
        assert_eq!(DecisionView::from_decision(&d), v);
    }

    #[test]
    fn a_view_writes_no_negative_zero() {
        let d = Decision {
            target: [-0.3, -0.0, 10.0],
            yaw: -0.001,
            altitude: 10.0,
            speed: 5.0,
            acceptance_radius: 3.0,
            confidence: -0.01,
            step: 1,
            action: ActionMode::Goto as u8,
            ..Decision::default()
        };
        let json = DecisionView::from_decision(&d).to_json();
        assert!(!json.contains("-0"), "{json}");
    }

    #[test]
    fn half_turn_stays_inside_pi() {
        for deg in [180.0f32, -180.0] {
            let v = DecisionView {
                step: 1,
                action: "turn".into(),
                north: 0.0,
                east: 0.0,
                altitude: 10.0,
                yaw_deg: deg,
                speed: 0.0,
                radius: 0.0,
                confidence: 1.0,
            };
            let yaw = v.to_decision().unwrap().yaw;
            assert!(yaw.abs() <= core::f32::consts::PI, "{deg} -> {yaw}");
        }
    }

    #[test]
    fn rejects_other_shapes_and_actions() {
        assert!(matches!(
            DecisionView::parse("{\"step\":1}"),
            Err(ViewError::Json(_))
        ));
        assert!(matches!(
            DecisionView::parse("fly!"),
            Err(ViewError::Json(_))
        ));
        let mut v = DecisionView::parse(
            "{\"step\":1,\"action\":\"goto\",\"north\":0.0,\"east\":0.0,\"altitude\":1.0,\"yaw_deg\":0,\"speed\":1.0,\"radius\":1.0,\"confidence\":0.50}",
        )
        .unwrap();
        v.action = "loop".into();
        assert_eq!(
            v.to_decision(),
            Err(ViewError::UnknownAction("loop".into()))
        );
    }
}
