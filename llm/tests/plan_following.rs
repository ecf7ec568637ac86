//! The language-model reasoners fly the model flight by writing the plan's decision (the
//! untuned models do not track a mission on their own; `roles::language`). This replays the
//! heartbeats of the village mission's nominal flight (takeoff, two legs, the landing) with
//! the camera lines the flight's perception wrote, and checks that SmolLM2 and Gemma 3 write
//! the plan at every one: where the drone's own numbers sit close to the answer, a small
//! model copies them instead (SmolLM2 once took off to the drone's 11 m instead of the plan's
//! 12 m and stalled below the takeoff tolerance).
//!
//! Needs the provisioned model cache (`scripts/provision-models.sh`, part of the test
//! command).

mod common;

use aeris_llm::{
    DecisionView, GEMMA3_270M, LanguageReasoner, Observation, ReasonerConfig, SMOLLM2_135M,
};
use aeris_models::ModelStore;
use aeris_schemas::{FixedText, PerceptionState};
use common::village;

fn plan(step: u16, action: &str, target: [f32; 3], yaw_deg: f32) -> DecisionView {
    DecisionView {
        step,
        action: action.into(),
        north: target[0],
        east: target[1],
        altitude: target[2],
        yaw_deg,
        speed: 5.0,
        radius: 3.0,
        confidence: 1.0,
    }
}

/// One heartbeat of the nominal flight: where the drone is, what the camera summary says
/// (empty: nothing recognised), what the planner proposes.
struct Heartbeat {
    position: [f32; 3],
    camera: &'static str,
    plan: DecisionView,
}

/// The heartbeats of a model flight of the village mission (`aeris bench cycle`), as its
/// prompts showed them.
fn nominal_flight() -> Vec<Heartbeat> {
    let mut beats = Vec::new();
    let mut at = |position, camera, plan| {
        beats.push(Heartbeat {
            position,
            camera,
            plan,
        })
    };
    let takeoff = plan(1, "takeoff", [0.0, 0.0, 12.0], 0.0);
    for up in [0.0, 4.0, 8.0, 10.0, 11.0] {
        at([0.0, 0.0, up], "", takeoff.clone());
    }
    let north = plan(2, "goto", [62.0, 0.0, 12.0], 0.0);
    for n in [0.0, 1.0, 11.0, 21.0, 31.0, 41.0, 51.0, 58.0, 61.0] {
        at([n, 0.0, 12.0], "", north.clone());
    }
    for (e, yaw) in [
        (0.0, 89.0),
        (2.0, 90.0),
        (12.0, 90.0),
        (22.0, 90.0),
        (32.0, 90.0),
    ] {
        at(
            [62.0, e, 12.0],
            "",
            plan(3, "goto", [62.0, 64.0, 12.0], yaw),
        );
    }
    at(
        [62.0, 42.0, 12.0],
        "blue water tower ahead 22 m",
        plan(3, "goto", [62.0, 64.0, 12.0], 90.0),
    );
    at(
        [62.0, 52.0, 12.0],
        "blue water tower ahead 12 m; cue: a blue water tower (0.61)",
        plan(3, "goto", [62.0, 64.0, 12.0], 90.0),
    );
    let landing = [
        (
            [60.0, 66.0, 12.0],
            "reads \"JEh\"; cue: a sign that says JEh (0.29)",
            12.0,
        ),
        ([54.0, 73.0, 12.0], "", 12.0),
        (
            [48.0, 81.0, 12.0],
            "reads \"LAKE VIE\"; cue: a sign that says LAKE VIE (0.52)",
            12.0,
        ),
        (
            [42.0, 88.0, 12.0],
            "reads \"LRKE\"; cue: a sign that says LRKE (0.34)",
            12.0,
        ),
        (
            [42.0, 88.0, 10.0],
            "reads \"LRKE\"; cue: a sign that says LRKE (0.34)",
            10.0,
        ),
        (
            [42.0, 88.0, 8.0],
            "reads \"LAKE\"; traffic light left 21 m; cue: a sign that says LAKE (0.75)",
            8.0,
        ),
        (
            [42.0, 88.0, 6.0],
            "reads \"LAKE\"; cue: a sign that says LAKE (0.75)",
            6.0,
        ),
        (
            [42.0, 88.0, 4.0],
            "reads \"LAKE VIEW\"; cue: a sign that says LAKE VIEW (0.81)",
            4.0,
        ),
        (
            [42.0, 88.0, 2.0],
            "reads \"LAKE VIEW\"; cue: a sign that says LAKE VIEW (0.81)",
            2.0,
        ),
    ];
    for (position, camera, altitude) in landing {
        at(
            position,
            camera,
            plan(4, "land", [42.0, 88.0, altitude], 130.0),
        );
    }
    beats
}

/// The plan's departures of model `file` over the nominal flight.
fn departures(file: &str) -> Vec<String> {
    let store = ModelStore::open(None).expect("model cache (run scripts/provision-models.sh)");
    let mut reasoner = LanguageReasoner::load(&store, file, village(), ReasonerConfig::default())
        .unwrap_or_else(|e| panic!("loading {file}: {e}"));
    let mut previous: Option<DecisionView> = None;
    let mut departures = Vec::new();
    let (mut new_tokens, mut seconds) = (0usize, 0.0);
    let flight = nominal_flight();
    for (i, beat) in flight.iter().enumerate() {
        let state = PerceptionState {
            summary: FixedText::from_str_truncated(beat.camera),
            ..PerceptionState::default()
        };
        let obs = Observation {
            position: beat.position,
            yaw: beat.plan.yaw_deg.to_radians(),
            landed: false,
            state: Some(&state),
            previous: previous.as_ref(),
            plan: Some(&beat.plan),
            sighted: &[],
        };
        let thought = reasoner
            .decide(&obs)
            .unwrap_or_else(|e| panic!("heartbeat {i}: {e}"));
        if thought.view != beat.plan {
            departures.push(format!(
                "heartbeat {i} at {:?}: wrote {} for the plan {}",
                beat.position,
                thought.text,
                beat.plan.to_json()
            ));
        }
        if i > 0 {
            new_tokens += thought.prompt_tokens - thought.reused_tokens;
            seconds += thought.prompt_s + thought.generate_s;
        }
        previous = Some(thought.view);
    }
    let n = (flight.len() - 1) as f64;
    eprintln!(
        "{file} over {} heartbeats: {:.1} new prompt tokens and {:.3} s a decision",
        flight.len(),
        new_tokens as f64 / n,
        seconds / n
    );
    departures
}

#[test]
fn the_language_models_write_the_plan_at_every_heartbeat_of_the_nominal_flight() {
    let smollm2 = departures(SMOLLM2_135M);
    let gemma3 = departures(GEMMA3_270M);
    assert!(
        smollm2.is_empty() && gemma3.is_empty(),
        "SmolLM2:\n{}\nGemma 3:\n{}",
        smollm2.join("\n"),
        gemma3.join("\n")
    );
}
