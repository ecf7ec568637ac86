//! What the language-model tests share: the village mission (the model flight's,
//! `workflows/models.toml`) as the reasoner reads it.

use aeris_llm::{MissionBrief, StepBrief};
use aeris_schemas::{ActionMode, DecisionLimits};

/// The model flight's mission.
pub fn village() -> MissionBrief {
    let step = |text: &str, action, waypoint| StepBrief {
        text: text.into(),
        action,
        waypoint: Some(waypoint),
    };
    MissionBrief {
        instruction: "Take off from the helipad to 12 metres, fly north along the road to the \
red-roofed building, then turn right and follow the road east to the blue water tower, and \
land next to the yellow sign that says LAKE VIEW."
            .into(),
        steps: vec![
            step(
                "take off from the helipad to 12 metres",
                ActionMode::Takeoff,
                [0.0, 0.0, 12.0],
            ),
            step(
                "fly north along the road to the red-roofed building",
                ActionMode::Goto,
                [62.0, 0.0, 12.0],
            ),
            step(
                "turn right and follow the road east to the blue water tower",
                ActionMode::Goto,
                [62.0, 64.0, 12.0],
            ),
            step(
                "land next to the yellow sign that says LAKE VIEW",
                ActionMode::Land,
                [42.0, 88.0, 0.0],
            ),
        ],
        limits: DecisionLimits {
            v_max: 8.0,
            h_min: 0.0,
            h_max: 60.0,
            r_max: 10.0,
            geofence_min: [-20.0, -40.0, 0.0],
            geofence_max: [160.0, 140.0, 60.0],
            obstacle_clearance_m: 3.0,
            subgoals: 4,
        },
        cruise_speed: 5.0,
        acceptance_radius: 3.0,
    }
}
