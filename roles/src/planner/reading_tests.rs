//! The planner flying steps as a language model read them (`SubgoalSpec::reading`).

use super::geometry::horizontal;
use super::tests::vln_mission;
use super::*;
use aeris_runtime::spec::SubgoalSpec;
use aeris_schemas::StepReading;

#[test]
fn a_step_the_phrase_rules_cannot_read_flies_what_a_model_read_in_it() {
    let mut m = vln_mission();
    m.subgoals[0].text = "go up twenty one metres".into();
    m.subgoals[1].text = "hang a right and make for the house with the red roof".into();
    // the phrase rules read no turn ("hang a right") and no place ("make for")
    let rules = Planner::new(&m, &CameraSpec::default()).unwrap();
    let Some(Step { turn, target, .. }) = rules.steps[1] else {
        panic!("step 2")
    };
    assert_eq!(turn, 0.0);
    assert!(matches!(target, StepTarget::Here), "{target:?}");
    m.subgoals[0].reading = Some(StepReading {
        height_m: Some(21.0),
        ..StepReading::default()
    });
    m.subgoals[1].reading = Some(StepReading {
        turn: Turn::Right,
        relation: Some(Relation::To),
        landmark: Some("red roof".into()),
        ..StepReading::default()
    });
    // a reading without a landmark or turn leaves them to the phrase rules
    m.subgoals[2].reading = Some(StepReading::default());
    // a landing read as over a quoted sign lands next to it: a sign is read from its face
    let over_sign = StepReading {
        relation: Some(Relation::Over),
        landmark: Some("yellow sign".into()),
        sign: Some("CAFE".into()),
        ..StepReading::default()
    };
    let read = LandmarkPhrase::from_reading(&over_sign, ActionMode::Land).unwrap();
    assert_eq!(read.relation, Relation::NextTo);
    let read = LandmarkPhrase::from_reading(&over_sign, ActionMode::Goto).unwrap();
    assert_eq!(read.relation, Relation::To);
    let mut p = Planner::new(&m, &CameraSpec::default()).unwrap();
    let d = p.decide([0.0; 3], 0.0, true, None);
    assert_eq!((d.step, d.target[2]), (1, 21.0), "the height read in words");
    let Some(Step { turn, target, .. }) = p.steps[1] else {
        panic!("step 2")
    };
    assert_eq!(turn, core::f32::consts::FRAC_PI_2);
    assert!(
        matches!(target, StepTarget::Find(l) if l.description.as_str_lossy() == "red roof"
            && l.relation == Relation::To && l.sign_text.is_empty()),
        "{target:?}"
    );
    let Some(Step { target, .. }) = p.steps[2] else {
        panic!("step 3")
    };
    assert!(
        matches!(target, StepTarget::Find(l) if l.sign_text.as_str_lossy() == "HOTEL"
            && l.relation == Relation::NextTo),
        "{target:?}"
    );
}

#[test]
fn a_step_that_only_turns_turns_in_place_before_the_next_one() {
    let mut m = vln_mission();
    m.subgoals.insert(
        1,
        SubgoalSpec {
            text: "hang a right".into(),
            action: "goto".into(),
            waypoint: None,
            reading: Some(StepReading {
                turn: Turn::Right,
                ..StepReading::default()
            }),
        },
    );
    // the next step asks for no turn of its own: it searches along the turned heading
    m.subgoals[2].text = "fly to the red-roofed building".into();
    let mut p = Planner::new(&m, &CameraSpec::default()).unwrap();
    let up = [0.0, 0.0, 15.0];
    let _ = p.decide([0.0; 3], 0.0, true, None);
    let empty = PerceptionState::default();
    let east = core::f32::consts::FRAC_PI_2;
    // step 2: face east where it is
    let d = p.decide(up, 0.0, false, Some(&empty));
    assert_eq!(d.step, 2);
    assert!((d.yaw - east).abs() < 1e-3, "{}", d.yaw);
    assert!(horizontal(d.target, up) < 1e-3);
    // not turned yet: still step 2
    let d = p.decide(up, 0.3, false, Some(&empty));
    assert_eq!(d.step, 2);
    // turned: step 3 searches ahead, east
    let d = p.decide(up, east, false, Some(&empty));
    assert_eq!(d.step, 3);
    assert!((d.yaw - east).abs() < 1e-3, "{}", d.yaw);
}
