//! # aeris-eval
//!
//! Evaluation on aerial vision-and-language navigation (VLN) episodes (MISSION §7):
//! - [`episode`]: AerialVLN's episode JSON, with our subgoal annotation, loaded and
//!   validated with errors that name the bad field;
//! - [`generate`]: multi-step instructions with collision-free reference trajectories
//!   over the generated open and dense scenes of `aeris-sim`, in `train`, `val_unseen`
//!   and `test_unseen` splits whose scenes do not overlap;
//! - [`metrics`]: NE, SR, OSR, nDTW, SPL and ASR, exactly as the paper defines them;
//! - [`mission`]: the mission G an agent is given for an episode (oracle, random);
//! - [`plot`]: top-down maps of a scene with trajectories, as PNG;
//! - [`formation_plot`]: a formation flight's tracks and slots, one panel per phase;
//! - [`runner`]: episodes flown through the full multi-process pipeline (a supervised
//!   flight of `aeris-flight` each) and scored, per airspace (`aeris eval`).

#![deny(missing_docs)]

pub mod agent_setup;
pub mod compare;
pub mod distill;
pub mod episode;
pub mod episode_line;
pub mod formation_plot;
pub mod generate;
pub mod metrics;
pub mod mission;
pub mod plot;
pub mod runner;
pub mod shard;
pub mod table;
