//! # aeris-hub
//!
//! The communication hub (MISSION §4): ordered delivery, the decision gate, the heartbeat
//! deadline with last-valid reuse, and ATT (attention-subgoal alignment).
//!
//! The decision logic is pure and deterministic, so it can be tested and fuzzed on its own;
//! it depends on `aeris-schemas` only (build with `--no-default-features` to leave out the
//! role shell and with it the runtime and iceoryx2):
//! - [`gate`]: [`gate::DecisionGate`] validates D_t, makes it feasible against the geofence,
//!   the altitude band and the occupancy grid (clamp or reject), and binds it to a
//!   [`aeris_schemas::BoundSetpoint`];
//! - [`ordering`]: [`ordering::SequenceTracker`] (gaps, reorders, duplicates, restarts);
//! - [`program_gate`]: [`program_gate::ProgramGate`], the gate of formation programs and of
//!   the slots a formation role sends each vehicle's controller;
//! - [`att`]: instruction segmentation, the pluggable [`att::AttentionScorer`], the lexical
//!   scorer and the [`att::Attention`] state machine with its trace;
//! - [`core`]: [`core::HubCore`], the state machine that ties them together;
//! - [`role`] (feature `role`, on by default): [`role::HubRole`], the thin process shell that
//!   feeds it messages and the clock, and turns the flight's spec into the core's types;
//! - [`testing`]: the gate's promises as checks, shared by the fuzz targets and the corpus
//!   replay tests.

#![deny(missing_docs)]

pub mod att;
pub mod core;
pub mod gate;
pub mod ordering;
pub mod program_gate;
#[cfg(feature = "role")]
pub mod role;
pub mod testing;

pub use crate::core::{DecisionVerdict, HubConfig, HubCore, RejectReason, TickOutput};
pub use att::{
    Attention, AttentionError, AttentionPrior, AttentionResult, AttentionScorer, EMBEDDING_GAIN,
    EmbeddingScorer, LexicalScorer, segment_instruction,
};
pub use gate::{DecisionGate, Feasible, GateConfigError, GateError, OVER_MARGIN_M};
pub use ordering::{SeqVerdict, SequenceTracker, SourceSelector, SourceVerdict};
#[cfg(feature = "role")]
pub use role::HubRole;
