//! The oracle's mission follows the reference path: at most 16 steps, straight legs between
//! its waypoints that stay clear of obstacles, ending with a landing at the goal. The AERIS
//! agent's mission carries the instruction's steps and no coordinates at all.

use aeris_eval::generate::{AirspaceFilter, Split, generate_split};
use aeris_eval::mission::{Agent, corners, episode_mission};
use aeris_runtime::spec::SubgoalSpec;

#[test]
fn oracle_missions_fly_the_reference_corners_clear_of_obstacles() {
    for split in Split::ALL {
        let eps = generate_split(split, AirspaceFilter::Full, 16, &mut |_, _| {}).unwrap();
        for e in &eps {
            let m = episode_mission(e, Agent::Oracle, None).unwrap();
            let steps = &m.mission.subgoals;
            assert!(steps.len() <= 16, "{}", e.episode_id);
            assert_eq!(steps[0].action, "takeoff", "{}", e.episode_id);
            assert_eq!(steps.last().unwrap().action, "land");
            let goal = e.goal();
            assert_eq!(
                steps.last().unwrap().waypoint,
                Some([goal[0] as f32, goal[1] as f32, goal[2] as f32])
            );
            assert_eq!(m.step_subgoal.len(), steps.len());
            assert!(m.step_subgoal.windows(2).all(|w| w[0] <= w[1]));
            assert_eq!(*m.step_subgoal.last().unwrap(), e.subgoals.len() - 1);
            // straight legs from the start through every waypoint are clear by 2 m
            let mut at = m.mission.start;
            for s in steps {
                let w = s.waypoint.expect("the oracle knows every waypoint");
                let len =
                    ((w[0] - at[0]).powi(2) + (w[1] - at[1]).powi(2) + (w[2] - at[2]).powi(2))
                        .sqrt();
                let n = (len / 0.25).ceil().max(1.0) as usize;
                for i in 0..=n {
                    let t = i as f32 / n as f32;
                    let p = [
                        at[0] + (w[0] - at[0]) * t,
                        at[1] + (w[1] - at[1]) * t,
                        at[2] + (w[2] - at[2]) * t,
                    ];
                    assert!(!m.world.collides(p, 2.0), "{}: {p:?}", e.episode_id);
                }
                at = w;
            }
            // the geofence holds the whole reference
            let l = &m.mission.limits;
            for p in e.reference_positions() {
                let inside = |v: f64, a: usize| {
                    v as f32 > l.geofence_min[a] && (v as f32) < l.geofence_max[a]
                };
                assert!(
                    inside(p[0], 0) && inside(p[1], 1),
                    "{}: {p:?}",
                    e.episode_id
                );
            }
        }
    }
}

#[test]
fn the_aeris_mission_names_places_and_gives_no_coordinates() {
    let eps = generate_split(Split::ValUnseen, AirspaceFilter::Full, 4, &mut |_, _| {}).unwrap();
    for e in &eps {
        for agent in [Agent::Aeris, Agent::Random] {
            let m = episode_mission(e, agent, None).unwrap();
            let texts: Vec<&str> = m.mission.subgoals.iter().map(|s| s.text.as_str()).collect();
            let annotated: Vec<&str> = e.subgoals.iter().map(|s| s.text.as_str()).collect();
            assert_eq!(texts, annotated, "{}", e.episode_id);
            assert!(m.mission.subgoals.iter().all(|s| s.waypoint.is_none()));
            assert_eq!(m.mission.goal(), None);
            m.mission.validate().unwrap();
        }
    }
    // an AerialVLN file without step annotation: take off, then the whole instruction
    let mut bare = eps[0].clone();
    bare.subgoals.clear();
    let m = episode_mission(&bare, Agent::Aeris, None).unwrap();
    let actions: Vec<&str> = m
        .mission
        .subgoals
        .iter()
        .map(|s| s.action.as_str())
        .collect();
    assert_eq!(actions, ["takeoff", "land"]);
    assert_eq!(
        m.mission.subgoals[1].text,
        bare.instruction.instruction_text
    );
    // the steps a model cut from the instruction fly instead, all within the episode's one
    // subgoal
    let read: Vec<SubgoalSpec> = [
        ("rise up", "takeoff"),
        ("head north", "goto"),
        ("set down", "land"),
    ]
    .into_iter()
    .map(|(text, action)| SubgoalSpec {
        text: text.into(),
        action: action.into(),
        waypoint: None,
        reading: None,
    })
    .collect();
    let m = episode_mission(&bare, Agent::Aeris, Some(&read)).unwrap();
    assert_eq!(m.mission.subgoals, read);
    assert_eq!(m.step_subgoal, [0, 0, 0]);
    m.mission.validate().unwrap();
    // an annotated episode flies its steps with what was read in each, one by one; read
    // steps that are not its steps are not flown
    let steps_read: Vec<SubgoalSpec> = eps[0]
        .subgoals
        .iter()
        .map(|s| SubgoalSpec {
            text: s.text.clone(),
            action: s.action.clone(),
            waypoint: None,
            reading: Some(aeris_schemas::StepReading {
                turn: aeris_schemas::Turn::Left,
                ..Default::default()
            }),
        })
        .collect();
    let annotated = episode_mission(&eps[0], Agent::Aeris, Some(&steps_read)).unwrap();
    assert_eq!(annotated.mission.subgoals, steps_read);
    assert_eq!(
        annotated.step_subgoal,
        (0..steps_read.len()).collect::<Vec<_>>()
    );
    let annotated = episode_mission(&eps[0], Agent::Aeris, Some(&read[..1])).unwrap();
    assert_eq!(annotated.mission.subgoals.len(), eps[0].subgoals.len());
    assert!(
        annotated
            .mission
            .subgoals
            .iter()
            .all(|s| s.reading.is_none())
    );
}

#[test]
fn corners_keep_the_ends_and_every_turn() {
    let p = [
        [0.0, 0.0, 0.0],
        [0.0, 0.0, 2.0],
        [0.0, 0.0, 4.0],
        [5.0, 0.0, 4.0],
        [10.0, 0.0, 4.0],
        [10.0, 5.0, 4.0],
        [10.0, 5.0, 2.0],
        [10.0, 5.0, 0.0],
    ];
    assert_eq!(corners(&p), vec![0, 2, 4, 5, 7]);
    assert_eq!(corners(&p[..1]), vec![0]);
    assert!(corners(&[]).is_empty());
}
