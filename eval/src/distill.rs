//! Training data for the aligned reasoner (`aeris distill`): an evaluation flown on `train`
//! episodes whose reasoning role writes a training pair every heartbeat (its `distill`
//! parameter, `aeris_roles::distill`), gathered into one file with where each pair came
//! from.
//!
//! Two teachers: the planner flying (its own decisions, on the states it reaches), or a
//! language-model student flying with the aligned prompt while the planner it carries
//! labels the states the student reaches (a DAgger round). Held-out splits are refused:
//! training data never comes from the episodes a model is measured on.

use crate::agent_setup::AgentSetup;
use crate::generate::Split;
use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};

/// The pairs' file, in each episode's run folder and in the output folder.
pub const PAIRS_FILE: &str = "pairs.jsonl";

/// Why a distillation cannot run as asked.
#[derive(Debug, thiserror::Error)]
pub enum DistillError {
    /// Data asked of a held-out split.
    #[error(
        "split `{0}` is held out for measuring: training pairs come from `train` episodes only"
    )]
    HeldOutSplit(&'static str),
    /// An episode of a file is not on a `train` scene.
    #[error(
        "episode {episode} is on scene {scene}, not a train scene: training pairs come from `train` episodes only"
    )]
    HeldOutEpisode {
        /// The episode.
        episode: String,
        /// Its scene.
        scene: String,
    },
    /// The agent is no teacher: a baseline, or a language model without the aligned prompt.
    #[error(
        "agent `{0}` writes no training pairs: the teacher is the planner, or an aligned language-model student (--student)"
    )]
    NotATeacher(String),
    /// An episode's pairs could not be read or the gathered file written.
    #[error("gathering training pairs from {}", path.display())]
    Gather {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A line of an episode's pairs is not a pair (a role wrote something else).
    #[error("{}, line {line}: not a training pair", path.display())]
    BadPair {
        /// The file.
        path: PathBuf,
        /// Its 1-based line.
        line: usize,
        /// Why.
        #[source]
        source: serde_json::Error,
    },
}

/// Check that `setup` flying `split` makes training data.
pub fn check(setup: &AgentSetup, split: Split) -> Result<(), DistillError> {
    if split != Split::Train {
        return Err(DistillError::HeldOutSplit(split.as_str()));
    }
    let teacher = setup.agent == crate::mission::Agent::Aeris
        && (setup.reasoning == "planner" || setup.aligned);
    if !teacher || setup.zero_shot {
        return Err(DistillError::NotATeacher(setup.label.clone()));
    }
    Ok(())
}

/// Check that every episode of a file is on a `train` scene.
pub fn check_episodes(episodes: &[crate::episode::Episode]) -> Result<(), DistillError> {
    match episodes
        .iter()
        .find(|e| Split::of_scene(&e.scene_id) != Some(Split::Train))
    {
        Some(e) => Err(DistillError::HeldOutEpisode {
            episode: e.episode_id.clone(),
            scene: e.scene_id.clone(),
        }),
        None => Ok(()),
    }
}

/// Where an episode's pairs came from, added to each of its lines.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct PairOrigin<'a> {
    /// The episode.
    pub episode_id: &'a str,
    /// Its scene.
    pub scene_id: &'a str,
    /// Who flew (`aeris-planner`, `aeris-smollm2-aligned`).
    pub agent: &'a str,
    /// Whether the episode succeeded (stopped within the success radius): a trainer may
    /// keep only successful teachers' pairs (a failed planner episode teaches its mistakes).
    pub success: bool,
    /// A student flew and the planner labelled its states (a DAgger round): the labels are
    /// the teacher's whatever the student's episode did, so `success` does not rate them.
    pub dagger: bool,
}

/// Append every pair of `episode_pairs` (a role's file) to `out`, each with its origin;
/// the number appended. An episode whose role wrote nothing (a flight that failed to
/// start) gives 0.
pub fn gather(
    episode_pairs: &Path,
    origin: &PairOrigin<'_>,
    out: &mut impl Write,
) -> Result<usize, DistillError> {
    let gather_error = |source| DistillError::Gather {
        path: episode_pairs.to_path_buf(),
        source,
    };
    let file = match std::fs::File::open(episode_pairs) {
        Ok(f) => f,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(0),
        Err(e) => return Err(gather_error(e)),
    };
    let mut n = 0;
    let bad_pair = |line: usize, source| DistillError::BadPair {
        path: episode_pairs.to_path_buf(),
        line,
        source,
    };
    // the same fields for every line of the episode
    let origin = match serde_json::to_value(origin).map_err(|e| bad_pair(0, e))? {
        serde_json::Value::Object(o) => o,
        _ => serde_json::Map::new(),
    };
    for (i, line) in std::io::BufReader::new(file).lines().enumerate() {
        let line = line.map_err(gather_error)?;
        let mut pair: serde_json::Map<String, serde_json::Value> =
            serde_json::from_str(&line).map_err(|e| bad_pair(i + 1, e))?;
        pair.extend(origin.clone());
        let text = serde_json::to_string(&pair).map_err(|e| bad_pair(i + 1, e))?;
        writeln!(out, "{text}").map_err(gather_error)?;
        n += 1;
    }
    Ok(n)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::agent_setup::AgentOptions;

    #[test]
    fn only_teachers_on_train_make_data() {
        let planner = AgentSetup::resolve(&AgentOptions::default()).unwrap();
        assert!(check(&planner, Split::Train).is_ok());
        assert!(matches!(
            check(&planner, Split::TestUnseen),
            Err(DistillError::HeldOutSplit("test_unseen"))
        ));
        let generic = AgentSetup::resolve(&AgentOptions {
            reasoning: Some("smollm2".into()),
            ..AgentOptions::default()
        })
        .unwrap();
        assert!(matches!(
            check(&generic, Split::Train),
            Err(DistillError::NotATeacher(_))
        ));
        let student = AgentSetup::resolve(&AgentOptions {
            reasoning: Some("smollm2".into()),
            aligned: true,
            ..AgentOptions::default()
        })
        .unwrap();
        assert!(check(&student, Split::Train).is_ok());
        let oracle = AgentSetup::resolve(&AgentOptions {
            baseline: Some("oracle".into()),
            ..AgentOptions::default()
        })
        .unwrap();
        assert!(check(&oracle, Split::Train).is_err());
        assert_eq!(Split::of_scene("dense-1011"), Some(Split::Train));
        assert_eq!(Split::of_scene("open-3002"), Some(Split::TestUnseen));
        assert_eq!(Split::of_scene("village"), None);
    }

    #[test]
    fn gathers_each_line_with_its_origin_and_refuses_a_stranger() {
        let dir = std::env::temp_dir().join(format!("aeris-distill-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join(PAIRS_FILE);
        std::fs::write(
            &file,
            "{\"system\":\"s\",\"user\":\"u1\",\"target\":\"t1\"}\n{\"system\":\"s\",\"user\":\"u2\",\"target\":\"t2\"}\n",
        )
        .unwrap();
        let origin = PairOrigin {
            episode_id: "open-1-0",
            scene_id: "open-1",
            agent: "aeris-planner",
            success: true,
            dagger: false,
        };
        let mut out = Vec::new();
        assert_eq!(gather(&file, &origin, &mut out).unwrap(), 2);
        let lines: Vec<serde_json::Value> = String::from_utf8(out)
            .unwrap()
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect();
        assert_eq!(lines[1]["user"], "u2");
        assert_eq!(lines[1]["success"], true);
        assert_eq!(lines[1]["dagger"], false);
        assert_eq!(lines[1]["episode_id"], "open-1-0");
        assert_eq!(
            gather(&dir.join("absent.jsonl"), &origin, &mut Vec::new()).unwrap(),
            0
        );
        std::fs::write(&file, "not json\n").unwrap();
        let e = gather(&file, &origin, &mut Vec::new()).unwrap_err();
        assert!(matches!(e, DistillError::BadPair { line: 1, .. }), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
