//! The planner grounded in real rendered frames: test_unseen episodes flown in one process,
//! the sim's renderer and the geometric perception feeding [`Planner::decide`] once per
//! heartbeat, and a point-mass vehicle following its decisions.
//!
//! The full multi-process pipeline flies these episodes in `aeris eval`
//! (tests/tests/flights/vln_eval.rs runs one); this test pins the planner's own behaviour on them
//! without processes, so a grounding regression shows here as a named failure: the dense
//! episode's "land next to the blue-roofed building" once came down onto the roof.
//!
//! `PLANNER_TRACE=1` prints every decision with the scene summary it was made on.

use aeris_eval::episode::Episode;
use aeris_eval::generate::{AirspaceFilter, Split, generate_split};
use aeris_eval::mission::{Agent, episode_mission};
use aeris_roles::planner::Planner;
use aeris_runtime::spec::CameraSpec;
use aeris_schemas::{ActionMode, FrameFormat, FrameHeader, PerceptionState};
use aeris_sim::render::{CAMERA_MOUNT_HEIGHT_M, Renderer};
use aeris_sim_roles::perception::{InstructionWords, Segmenter};

/// Seconds per heartbeat (one frame and one decision each).
const HEARTBEAT_S: f32 = 2.0;
/// Integration step of the point mass (s).
const DT: f32 = 0.1;
/// Vertical speed of the point mass (m/s).
const CLIMB: f32 = 2.0;
/// The evaluation's collision radius (m).
const COLLISION_RADIUS_M: f32 = 0.3;

/// How a flight ended.
struct Flight {
    landed_at: Option<[f32; 3]>,
    collided_at: Option<[f32; 3]>,
    steps_done: usize,
}

fn episode(split: Split, episode_id: &str) -> Episode {
    let airspace = if episode_id.contains("dense") {
        AirspaceFilter::Dense
    } else {
        AirspaceFilter::Open
    };
    let episodes = generate_split(split, airspace, 8, &mut |_, _| {}).unwrap();
    episodes
        .into_iter()
        .find(|e| e.episode_id == episode_id)
        .expect("the episode is generated")
}

fn fly(episode: &Episode) -> (Flight, [f32; 3]) {
    let m = episode_mission(episode, Agent::Aeris, None).unwrap();
    let g = episode.goal();
    let goal = [g[0] as f32, g[1] as f32, g[2] as f32];
    let camera = CameraSpec::default();
    let mut planner = Planner::new(&m.mission, &camera).unwrap();
    let words = InstructionWords::from_mission(&m.mission);
    let hfov = camera.hfov_deg.to_radians();
    let renderer = Renderer::new(camera.width, camera.height, hfov).unwrap();
    let mut segmenter = Segmenter::new();
    let (mut rgb, mut depth) = (vec![0; renderer.rgb_len()], vec![0; renderer.depth_len()]);
    let mut state = PerceptionState::default();
    let (mut p, mut yaw, mut landed) = (m.mission.start, 0.0f32, true);
    let beats = (m.mission.max_duration_s as f32 / HEARTBEAT_S) as usize;
    for beat in 0..beats {
        let cam = [p[0], p[1], p[2] + CAMERA_MOUNT_HEIGHT_M];
        renderer
            .render(&m.world, cam, yaw, &mut rgb, &mut depth)
            .unwrap();
        let header = FrameHeader {
            seq: beat as u64 + 1,
            capture_ns: beat as u64 * 2_000_000_000,
            width: camera.width,
            height: camera.height,
            camera_position: cam,
            camera_yaw: yaw,
            hfov,
            format: FrameFormat::Rgb8 as u8,
            reserved: [0; 3],
        };
        segmenter
            .perceive(&rgb, &depth, &header, &words, &mut state, &mut |_, _| {})
            .unwrap();
        let d = planner.decide(p, yaw, landed, Some(&state));
        if std::env::var_os("PLANNER_TRACE").is_some() {
            eprintln!(
                "beat {beat} step {} at [{:.0}, {:.0}, {:.0}] -> {:?} [{:.0}, {:.0}, {:.0}] | {}",
                d.step,
                p[0],
                p[1],
                p[2],
                ActionMode::from_u8(d.action),
                d.target[0],
                d.target[1],
                d.altitude,
                state.summary.as_str_lossy()
            );
        }
        let action = ActionMode::from_u8(d.action).unwrap();
        yaw = d.yaw;
        let (target, height) = ([d.target[0], d.target[1]], d.altitude);
        let mut t = 0.0;
        while t < HEARTBEAT_S {
            t += DT;
            let (dn, de) = (target[0] - p[0], target[1] - p[1]);
            let dist = dn.hypot(de);
            let step = (d.speed * DT).min(dist);
            if dist > 1e-3 {
                p[0] += dn / dist * step;
                p[1] += de / dist * step;
            }
            // a landing comes down once over its touchdown point, as the gate binds it
            let u = if action == ActionMode::Land && dist <= 1.0 {
                0.0
            } else {
                height
            };
            p[2] += (u - p[2]).clamp(-CLIMB * DT, CLIMB * DT);
            landed = p[2] <= 0.05;
            if landed {
                p[2] = 0.0;
            }
            // as the evaluation judges it: the ground is not an obstacle
            if m.world.collides(p, COLLISION_RADIUS_M) {
                let flight = Flight {
                    landed_at: None,
                    collided_at: Some(p),
                    steps_done: planner.current(),
                };
                return (flight, goal);
            }
            if landed && action == ActionMode::Land {
                let flight = Flight {
                    landed_at: Some(p),
                    collided_at: None,
                    steps_done: planner.current() + 1,
                };
                return (flight, goal);
            }
        }
    }
    let flight = Flight {
        landed_at: None,
        collided_at: None,
        steps_done: planner.current(),
    };
    (flight, goal)
}

#[test]
fn lands_next_to_the_blue_roofed_building_in_the_dense_episode_not_on_it() {
    let id = "test_unseen-dense-3000-0";
    let (flight, goal) = fly(&episode(Split::TestUnseen, id));
    assert_eq!(flight.collided_at, None, "{id}: collided");
    let at = flight
        .landed_at
        .unwrap_or_else(|| panic!("{id}: never landed ({} steps)", flight.steps_done));
    let ne =
        ((at[0] - goal[0]).powi(2) + (at[1] - goal[1]).powi(2) + (at[2] - goal[2]).powi(2)).sqrt();
    assert!(
        ne <= 20.0,
        "{id}: landed at {at:?}, {ne:.1} m from the goal {goal:?}"
    );
    assert_eq!(flight.steps_done, 3, "{id}");
}

/// Horizontal distance (m) from `p` to the box of the landmark `name` of `episode`'s world.
fn distance_to(episode: &Episode, name: &str, p: [f32; 3]) -> f32 {
    let world = aeris_sim::world::World::builtin(&episode.scene_id).unwrap();
    let l = world
        .landmarks
        .iter()
        .find(|l| l.name == name)
        .expect("the landmark is in the scene");
    l.horizontal_distance(p[0], p[1])
}

/// Geometric perception reads no sign texts, so which sign a step names is a guess here
/// (`aeris eval` reads them with PP-OCR); the landing beside the building is not.
#[test]
fn lands_beside_the_blue_roofed_building_in_the_open_episode() {
    let e = episode(Split::TestUnseen, "test_unseen-open-3000-0");
    let (flight, _) = fly(&e);
    assert_eq!(flight.collided_at, None, "collided");
    let at = flight.landed_at.expect("landed");
    let gap = distance_to(&e, "blue-roofed building", at);
    assert!(
        (3.0..=14.0).contains(&gap),
        "landed at {at:?}, {gap:.1} m from the building"
    );
}

/// Every episode of two splits: the planner never touches an obstacle, and it lands.
#[test]
fn never_collides_and_always_lands_on_the_unseen_splits() {
    let mut failures = Vec::new();
    for split in [Split::ValUnseen, Split::TestUnseen] {
        for e in generate_split(split, AirspaceFilter::Full, 8, &mut |_, _| {}).unwrap() {
            let (flight, goal) = fly(&e);
            if let Some(p) = flight.collided_at {
                failures.push(format!("{}: collided at {p:?}", e.episode_id));
            } else if flight.landed_at.is_none() {
                failures.push(format!("{}: never landed", e.episode_id));
            }
            eprintln!(
                "{}: landed at {:?}, goal {goal:?}, {} steps",
                e.episode_id, flight.landed_at, flight.steps_done
            );
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
