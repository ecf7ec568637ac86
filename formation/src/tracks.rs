//! A formation flight's tracks: every vehicle's position and slot over time, with the
//! phases flown. Written to a flight's run folder ([`FORMATION_TRACKS_FILE`]) by `aeris
//! formation plan --run DIR` (the program flown by the vehicle model) and by the formation
//! role of a flight of processes (the vehicles' telemetry); drawn by `aeris plot formation`.

use serde::{Deserialize, Serialize};

/// The file name of a formation flight's tracks in its run folder.
pub const FORMATION_TRACKS_FILE: &str = "formation.json";

/// A formation flight's tracks.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FormationTracks {
    /// The instruction the program came from.
    pub instruction: String,
    /// Vehicles flown.
    pub vehicles: usize,
    /// What each phase does, in order ("take-off", "the change to a wedge", ...); a flight
    /// that changed its program (a new instruction, a replan) lists every program's phases
    /// one after the other.
    pub phases: Vec<String>,
    /// Where the tracks come from ("the built-in multirotor model, 50 Hz").
    pub source: String,
    /// The track points, in time order.
    pub points: Vec<TrackSample>,
}

/// Every vehicle's position and slot at one instant.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrackSample {
    /// Time from the start (s).
    pub t_s: f32,
    /// The phase flown (1-based, into [`FormationTracks::phases`]).
    pub phase: usize,
    /// Each vehicle's position `[N, E, U]`.
    pub positions: Vec<[f32; 3]>,
    /// Each vehicle's slot `[N, E, U]` (a vehicle out of the formation: where it is).
    pub slots: Vec<[f32; 3]>,
}
