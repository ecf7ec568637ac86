//! Episodes in AerialVLN's JSON format, plus our subgoal annotation.
//!
//! A file is `{"episodes": [ ... ]}` (a bare list is accepted too). Each episode has
//! AerialVLN's fields (MISSION §7): `episode_id`, `trajectory_id`, `scene_id`,
//! `start_position` `[x,y,z]`, `start_rotation` `[w,x,y,z]`, `goals[0].position`,
//! `reference_path` (one pose per step, the first three numbers the position) and
//! `instruction.instruction_text`. Ids may be strings or numbers (AerialVLN uses both).
//! Fields we do not use (`actions`, `instruction_tokens`, ...) are ignored.
//!
//! Ours, optional, so real AerialVLN files load unchanged: `airspace` (`open`/`dense`) and
//! `subgoals` — the instruction's segmentation, each with its text, action, waypoint, the
//! landmark it names and the `reference_range` `[first, last]` of reference poses it
//! covers. Generated scenes use `[N, E, U]` metres; metrics are distances, so they hold in
//! any right-handed or left-handed metric frame.

use serde::{Deserialize, Deserializer, Serialize};
use std::path::{Path, PathBuf};

/// One episode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Episode {
    /// Unique id of the episode.
    #[serde(deserialize_with = "id_string")]
    pub episode_id: String,
    /// Id of the reference trajectory.
    #[serde(deserialize_with = "id_string")]
    pub trajectory_id: String,
    /// Scene the episode is flown in (ours: a generated scene name such as `dense-203`).
    #[serde(deserialize_with = "id_string")]
    pub scene_id: String,
    /// Start position `[x, y, z]`.
    pub start_position: [f64; 3],
    /// Start orientation as a quaternion `[w, x, y, z]`.
    pub start_rotation: [f64; 4],
    /// Goals; the first is the episode's goal.
    pub goals: Vec<Goal>,
    /// Reference poses, one per step; the first three numbers of each are the position.
    pub reference_path: Vec<Vec<f64>>,
    /// The instruction.
    pub instruction: Instruction,
    /// Kind of airspace (ours).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub airspace: Option<String>,
    /// The instruction's subgoals (ours).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub subgoals: Vec<SubgoalAnnotation>,
}

/// A goal of an episode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Goal {
    /// Position `[x, y, z]`.
    pub position: [f64; 3],
    /// Success radius the dataset states, if any (metrics use 20 m regardless).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radius: Option<f64>,
}

/// The instruction of an episode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Instruction {
    /// The natural-language instruction.
    pub instruction_text: String,
}

/// One subgoal of the instruction (our annotation).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SubgoalAnnotation {
    /// The instruction's words for this step.
    pub text: String,
    /// Action of the step: `takeoff`, `goto` or `land`.
    pub action: String,
    /// Where the step ends `[x, y, z]`.
    pub waypoint: [f64; 3],
    /// The landmark the step names, if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub landmark: Option<String>,
    /// First and last index of the reference poses this step covers.
    pub reference_range: [usize; 2],
}

/// Accept a string or an integer id.
fn id_string<'de, D: Deserializer<'de>>(d: D) -> Result<String, D::Error> {
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum Id {
        Text(String),
        Int(i64),
    }
    match Id::deserialize(d)? {
        Id::Text(s) => Ok(s),
        Id::Int(n) => Ok(n.to_string()),
    }
}

impl Episode {
    /// The goal position (`goals[0].position`); validated episodes always have one.
    pub fn goal(&self) -> [f64; 3] {
        self.goals
            .first()
            .map_or(self.start_position, |g| g.position)
    }

    /// The reference positions (first three numbers of each pose).
    pub fn reference_positions(&self) -> Vec<[f64; 3]> {
        self.reference_path
            .iter()
            .filter(|p| p.len() >= 3)
            .map(|p| [p[0], p[1], p[2]])
            .collect()
    }

    /// Check what the format cannot express: a goal, a non-empty reference path of poses
    /// with at least three numbers, finite numbers, a non-empty instruction, subgoal ranges
    /// inside the reference path. `index` is the episode's place in its file, for the path
    /// in the error.
    pub fn validate(&self, index: usize) -> Result<(), EpisodeError> {
        let at = |field: String| format!("episodes[{index}].{field}");
        let bad = |field: String, problem: &str| EpisodeError::Invalid {
            field: at(field),
            problem: problem.to_string(),
        };
        let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
        if self.episode_id.is_empty() {
            return Err(bad("episode_id".into(), "is empty"));
        }
        if !finite(&self.start_position) {
            return Err(bad("start_position".into(), "has a non-finite number"));
        }
        let q = self.start_rotation;
        let norm = (q.iter().map(|x| x * x).sum::<f64>()).sqrt();
        if !finite(&q) || !(0.5..=1.5).contains(&norm) {
            return Err(bad(
                "start_rotation".into(),
                "is not a unit quaternion [w, x, y, z]",
            ));
        }
        if self.goals.is_empty() {
            return Err(bad("goals".into(), "is empty: an episode needs a goal"));
        }
        for (k, g) in self.goals.iter().enumerate() {
            if !finite(&g.position) {
                return Err(bad(
                    format!("goals[{k}].position"),
                    "has a non-finite number",
                ));
            }
        }
        if self.reference_path.is_empty() {
            return Err(bad("reference_path".into(), "is empty"));
        }
        for (k, p) in self.reference_path.iter().enumerate() {
            if p.len() < 3 {
                return Err(bad(
                    format!("reference_path[{k}]"),
                    "has fewer than 3 numbers (a pose starts with x, y, z)",
                ));
            }
            if !finite(p) {
                return Err(bad(
                    format!("reference_path[{k}]"),
                    "has a non-finite number",
                ));
            }
        }
        if self.instruction.instruction_text.trim().is_empty() {
            return Err(bad("instruction.instruction_text".into(), "is empty"));
        }
        if let Some(a) = &self.airspace
            && aeris_sim::scene_gen::Airspace::parse(a).is_none()
        {
            return Err(bad("airspace".into(), "is neither `open` nor `dense`"));
        }
        let len = self.reference_path.len();
        for (k, s) in self.subgoals.iter().enumerate() {
            if !matches!(s.action.as_str(), "takeoff" | "goto" | "land") {
                return Err(bad(
                    format!("subgoals[{k}].action"),
                    "is not one of takeoff, goto, land",
                ));
            }
            if !finite(&s.waypoint) {
                return Err(bad(
                    format!("subgoals[{k}].waypoint"),
                    "has a non-finite number",
                ));
            }
            let [a, b] = s.reference_range;
            if a > b || b >= len {
                return Err(bad(
                    format!("subgoals[{k}].reference_range"),
                    "is not [first, last] inside reference_path",
                ));
            }
        }
        Ok(())
    }
}

/// The top level of an episode file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EpisodeFile {
    /// The episodes.
    pub episodes: Vec<Episode>,
}

/// Why episodes could not be read.
#[derive(Debug, thiserror::Error)]
pub enum EpisodeError {
    /// The file could not be read.
    #[error("cannot read episode file {path}")]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The file could not be written.
    #[error("cannot write episode file {path}")]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The text is not valid JSON, or a field has the wrong type or is missing.
    #[error("{field}: {problem}")]
    Format {
        /// JSON path of the bad field, e.g. `episodes[3].goals[0].position`.
        field: String,
        /// What is wrong, from the JSON parser.
        problem: String,
    },
    /// A field holds a value no episode can have.
    #[error("{field} {problem}")]
    Invalid {
        /// JSON path of the bad field.
        field: String,
        /// What is wrong.
        problem: String,
    },
    /// A file's content is not valid episodes.
    #[error("episode file {path} is invalid")]
    Content {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        source: Box<EpisodeError>,
    },
    /// Two episodes share an id.
    #[error("episodes[{index}].episode_id `{id}` is used twice")]
    DuplicateId {
        /// Index of the second episode with the id.
        index: usize,
        /// The id.
        id: String,
    },
}

impl EpisodeError {
    /// The JSON path of the bad field, when the error is about one.
    pub fn field(&self) -> Option<&str> {
        match self {
            EpisodeError::Format { field, .. } | EpisodeError::Invalid { field, .. } => Some(field),
            EpisodeError::Content { source, .. } => source.field(),
            _ => None,
        }
    }
}

/// Episodes from JSON text (`{"episodes": [...]}` or a bare list), validated.
pub fn parse_episodes(text: &str) -> Result<Vec<Episode>, EpisodeError> {
    // try the wrapped form first so its errors carry the `episodes[..]` path
    let wrapped = text.trim_start().starts_with('{');
    let episodes = if wrapped {
        let mut de = serde_json::Deserializer::from_str(text);
        let file: EpisodeFile =
            serde_path_to_error::deserialize(&mut de).map_err(|e| EpisodeError::Format {
                field: path_or_top(e.path().to_string()),
                problem: e.inner().to_string(),
            })?;
        file.episodes
    } else {
        let mut de = serde_json::Deserializer::from_str(text);
        let list: Vec<Episode> =
            serde_path_to_error::deserialize(&mut de).map_err(|e| EpisodeError::Format {
                field: path_or_top(format!("episodes{}", e.path())),
                problem: e.inner().to_string(),
            })?;
        list
    };
    let mut seen = std::collections::HashSet::new();
    for (i, e) in episodes.iter().enumerate() {
        e.validate(i)?;
        if !seen.insert(e.episode_id.as_str()) {
            return Err(EpisodeError::DuplicateId {
                index: i,
                id: e.episode_id.clone(),
            });
        }
    }
    Ok(episodes)
}

fn path_or_top(p: String) -> String {
    if p.is_empty() || p == "." || p == "episodes." {
        "(top level)".into()
    } else {
        p
    }
}

/// Episodes from a file (see [`parse_episodes`]).
pub fn load_episodes(path: &Path) -> Result<Vec<Episode>, EpisodeError> {
    let text = std::fs::read_to_string(path).map_err(|source| EpisodeError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    parse_episodes(&text).map_err(|e| EpisodeError::Content {
        path: path.to_path_buf(),
        source: Box::new(e),
    })
}

/// Write `episodes` as `{"episodes": [...]}` (pretty-printed) to `path`.
pub fn save_episodes(path: &Path, episodes: &[Episode]) -> Result<(), EpisodeError> {
    #[derive(Serialize)]
    struct Out<'a> {
        episodes: &'a [Episode],
    }
    let text =
        serde_json::to_string_pretty(&Out { episodes }).map_err(|e| EpisodeError::Write {
            path: path.to_path_buf(),
            source: std::io::Error::other(e),
        })?;
    std::fs::write(path, text + "\n").map_err(|source| EpisodeError::Write {
        path: path.to_path_buf(),
        source,
    })
}
