//! From an episode to the mission G a flight is given, per agent.
//!
//! - **oracle** (sanity upper bound): the planner is given the reference path itself, as
//!   waypoints at its corners, each labelled with the text of the instruction step it
//!   belongs to; it ends with a landing at the goal.
//! - **aeris** (the system under evaluation): the instruction and its steps as annotated —
//!   text and action, never a waypoint; the planner grounds every step's landmark in S_t
//!   (`aeris_roles::grounding`). With a [`StepReader`] (`aeris eval --read-with`, a language
//!   model: `aeris_llm::InstructionReader`) it flies the steps the model read: an
//!   unannotated instruction (an AerialVLN file) segmented, every step with its reading
//!   (turn, landmark, relation, sign, height). Otherwise an episode without step annotation
//!   becomes two steps: take off, then the whole instruction, landing at the last place it
//!   names.
//! - **random**: the same steps (the random reasoner only flies the first, take-off, and
//!   otherwise draws AerialVLN's actions uniformly).
//!
//! Either way the flight's limits cover the scene: a geofence around every landmark and
//! the reference path, heights up to 40 m above the tallest landmark.

use crate::episode::Episode;
use aeris_runtime::MissionSpec;
use aeris_runtime::spec::{LimitsSpec, SubgoalSpec};
use aeris_schemas::MAX_SUBGOALS;
use aeris_sim::world::{Extent, World};

/// Cruise speed of evaluation flights (m/s).
pub const CRUISE_M_S: f32 = 6.0;

/// Who flies an episode.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Agent {
    /// The AERIS pipeline on the instruction alone.
    Aeris,
    /// The planner on the reference path.
    Oracle,
    /// Uniform random AerialVLN actions.
    Random,
}

impl Agent {
    /// `aeris`, `oracle` or `random`.
    pub fn as_str(self) -> &'static str {
        match self {
            Agent::Aeris => "aeris",
            Agent::Oracle => "oracle",
            Agent::Random => "random",
        }
    }

    /// The agent called `name`.
    pub fn parse(name: &str) -> Option<Agent> {
        match name {
            "aeris" => Some(Agent::Aeris),
            "oracle" => Some(Agent::Oracle),
            "random" => Some(Agent::Random),
            _ => None,
        }
    }

    /// The reasoning variant that flies for this agent.
    pub fn reasoning_variant(self) -> &'static str {
        match self {
            Agent::Aeris | Agent::Oracle => "planner",
            Agent::Random => "random",
        }
    }
}

/// Why an episode cannot be flown.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MissionError {
    /// The scene is not one of ours (e.g. an AerialVLN scene id).
    #[error(
        "episode {episode}: scene `{scene}` is not a scene this simulator has ({})",
        World::NAMES_HELP
    )]
    UnknownScene {
        /// Episode id.
        episode: String,
        /// Its scene id.
        scene: String,
    },
    /// The reference path has more corners than a mission has subgoals.
    #[error(
        "episode {episode}: the reference path needs {needed} waypoints, a mission holds {MAX_SUBGOALS}"
    )]
    TooManyWaypoints {
        /// Episode id.
        episode: String,
        /// Waypoints needed.
        needed: usize,
    },
}

/// A mission and, for each of its steps, the index of the instruction step (episode
/// subgoal) it belongs to.
#[derive(Debug, Clone, PartialEq)]
pub struct EpisodeMission {
    /// The mission.
    pub mission: MissionSpec,
    /// `step_subgoal[i]`: the episode subgoal that mission step `i` belongs to.
    pub step_subgoal: Vec<usize>,
    /// The world the episode is flown in.
    pub world: World,
}

fn f32s(p: [f64; 3]) -> [f32; 3] {
    [p[0] as f32, p[1] as f32, p[2] as f32]
}

/// Indices of the corners of a polyline: the first and last point, and every point where
/// the direction changes by more than ~1 degree or between horizontal and vertical.
pub fn corners(points: &[[f64; 3]]) -> Vec<usize> {
    let mut out = Vec::new();
    if points.is_empty() {
        return out;
    }
    out.push(0);
    let dir = |a: [f64; 3], b: [f64; 3]| {
        let d = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
        let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        (n > 1e-6).then(|| [d[0] / n, d[1] / n, d[2] / n])
    };
    for i in 1..points.len().saturating_sub(1) {
        if let (Some(a), Some(b)) = (dir(points[i - 1], points[i]), dir(points[i], points[i + 1])) {
            let cos = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
            if cos < 0.9998 {
                out.push(i);
            }
        }
    }
    if points.len() > 1 {
        out.push(points.len() - 1);
    }
    out
}

/// Reads an episode's instruction before it flies (`aeris eval --read-with`: a language
/// model segments an unannotated instruction and reads every step).
pub trait StepReader {
    /// The steps the AERIS agent flies for `episode`, each with what was read in it; `None`
    /// to fly its annotation (or the two-step fallback) as the phrase rules read it.
    fn read_steps(&mut self, episode: &Episode) -> Option<Vec<SubgoalSpec>>;
}

/// The mission for `episode` flown by `agent`; `read_steps`: the steps a language model read
/// (an annotated episode's own steps, each with its reading, or the steps it cut from an
/// unannotated instruction); ignored by the oracle, which flies the reference.
pub fn episode_mission(
    episode: &Episode,
    agent: Agent,
    read_steps: Option<&[SubgoalSpec]>,
) -> Result<EpisodeMission, MissionError> {
    let world = World::builtin(&episode.scene_id).ok_or_else(|| MissionError::UnknownScene {
        episode: episode.episode_id.clone(),
        scene: episode.scene_id.clone(),
    })?;
    let reference = episode.reference_positions();
    let goal = f32s(episode.goal());
    let start = f32s(episode.start_position);
    // texts of the instruction steps; a file without annotation has one step
    let texts: Vec<(String, [usize; 2])> = if episode.subgoals.is_empty() {
        vec![(
            episode.instruction.instruction_text.clone(),
            [0, reference.len().saturating_sub(1)],
        )]
    } else {
        episode
            .subgoals
            .iter()
            .map(|s| (s.text.clone(), s.reference_range))
            .collect()
    };
    let subgoal_of = |i: usize| {
        texts
            .iter()
            .position(|(_, r)| i >= r[0] && i <= r[1])
            .unwrap_or(texts.len() - 1)
    };
    // an empty list of read steps is no reading
    let read_steps = read_steps.filter(|r| !r.is_empty());
    let (subgoals, step_subgoal) = match agent {
        // an annotated episode's steps, each with its reading when they were read one by one
        Agent::Aeris | Agent::Random if !episode.subgoals.is_empty() => (
            match read_steps {
                Some(read) if read.len() == episode.subgoals.len() => read.to_vec(),
                _ => episode
                    .subgoals
                    .iter()
                    .map(|s| SubgoalSpec {
                        text: s.text.clone(),
                        action: s.action.clone(),
                        waypoint: None,
                        reading: None,
                    })
                    .collect(),
            },
            (0..episode.subgoals.len()).collect(),
        ),
        // the steps a model cut from the episode's one (unannotated) subgoal
        Agent::Aeris | Agent::Random if let Some(read) = read_steps => {
            (read.to_vec(), vec![0; read.len()])
        }
        Agent::Aeris | Agent::Random => (
            vec![
                SubgoalSpec {
                    text: "take off".into(),
                    action: "takeoff".into(),
                    waypoint: None,
                    reading: None,
                },
                SubgoalSpec {
                    text: episode.instruction.instruction_text.clone(),
                    action: "land".into(),
                    waypoint: None,
                    reading: None,
                },
            ],
            vec![0, 0],
        ),
        Agent::Oracle => {
            // the reference's corners: the climb's top, every turn, the top of the descent
            let idx = corners(&reference);
            let mut subgoals = Vec::new();
            let mut steps = Vec::new();
            for (k, &i) in idx.iter().enumerate().skip(1) {
                let p = f32s(reference[i]);
                let last = k + 1 == idx.len();
                let action = if last {
                    "land"
                } else if subgoals.is_empty() && p[2] > start[2] + 1.0 {
                    "takeoff"
                } else {
                    "goto"
                };
                if last && p[2] > goal[2] + 0.5 {
                    // the path ends in the air: a goto there, then land under it
                    subgoals.push(SubgoalSpec {
                        text: texts[subgoal_of(i)].0.clone(),
                        action: "goto".into(),
                        waypoint: Some(p),
                        reading: None,
                    });
                    steps.push(subgoal_of(i));
                }
                subgoals.push(SubgoalSpec {
                    text: texts[subgoal_of(i)].0.clone(),
                    action: action.into(),
                    waypoint: Some(if last { goal } else { p }),
                    reading: None,
                });
                steps.push(subgoal_of(i));
            }
            if subgoals.len() > MAX_SUBGOALS {
                return Err(MissionError::TooManyWaypoints {
                    episode: episode.episode_id.clone(),
                    needed: subgoals.len(),
                });
            }
            (subgoals, steps)
        }
    };
    let limits = scene_limits(&world, &reference, start);
    let length = crate::metrics::path_length(&reference) as f32;
    let mission = MissionSpec {
        instruction: episode.instruction.instruction_text.clone(),
        subgoals,
        world: world.name.clone(),
        start,
        cruise_speed: CRUISE_M_S,
        acceptance_radius_m: 3.0,
        // climbs and turns at lower speeds: twice the cruise time, plus a minute; a
        // grounded agent also scans and flies search legs: two minutes more
        max_duration_s: 60.0
            + 2.0 * f64::from(length / CRUISE_M_S)
            + if agent == Agent::Oracle { 0.0 } else { 120.0 },
        limits,
    };
    Ok(EpisodeMission {
        mission,
        step_subgoal,
        world,
    })
}

/// Limits covering the scene, the reference path and the start.
fn scene_limits(world: &World, reference: &[[f64; 3]], start: [f32; 3]) -> LimitsSpec {
    let mut x = Extent::around(start);
    if let Some(w) = world.extent() {
        x.union(&w);
    }
    for p in reference {
        x.include(f32s(*p));
    }
    let (lo, hi) = (x.min, x.max);
    LimitsSpec {
        h_max: hi[2] + 40.0,
        geofence_min: [lo[0] - 60.0, lo[1] - 60.0, 0.0],
        geofence_max: [hi[0] + 60.0, hi[1] + 60.0, hi[2] + 40.0],
        ..LimitsSpec::default()
    }
}
