//! The vehicles' tracks the formation role writes to its run folder.

use aeris_formation::{FormationTracks, TrackSample, phase_description};
use aeris_schemas::FormationProgram;

/// The vehicles' tracks, kept for the run folder's `formation.json`: a sample every
/// [`TRACK_EVERY_NS`] into buffers sized for the mission's time limit at start (pushes
/// within their capacity do not allocate; a flight past it stops recording).
pub(super) struct TrackRecorder {
    pub(super) file: Option<std::path::PathBuf>,
    pub(super) instruction: String,
    /// Every program's phases, one program after the other.
    pub(super) phases: Vec<String>,
    /// Where the current program's phases start in `phases`.
    pub(super) offset: usize,
    /// `(t_s, phase)` of each sample.
    pub(super) samples: Vec<(f32, usize)>,
    /// Each sample's positions then slots, one per vehicle of the flight.
    pub(super) points: Vec<[f32; 3]>,
    pub(super) next_ns: u64,
    pub(super) start_ns: u64,
    pub(super) written: bool,
}

/// A track sample every 0.2 s.
pub(super) const TRACK_EVERY_NS: u64 = 200_000_000;

impl TrackRecorder {
    pub(super) fn new(
        file: Option<std::path::PathBuf>,
        instruction: &str,
        vehicles: usize,
        max_s: f64,
    ) -> Self {
        let samples = if file.is_some() {
            (max_s.clamp(1.0, 3600.0) / (TRACK_EVERY_NS as f64 * 1e-9)) as usize + 1
        } else {
            0
        };
        Self {
            file,
            instruction: instruction.to_string(),
            phases: Vec::new(),
            offset: 0,
            samples: Vec::with_capacity(samples),
            points: Vec::with_capacity(samples * vehicles * 2),
            next_ns: 0,
            start_ns: 0,
            written: false,
        }
    }

    /// A new program is flown from now on.
    pub(super) fn program(&mut self, program: &FormationProgram) {
        self.offset = self.phases.len();
        self.phases
            .extend(program.phases().iter().map(phase_description));
    }

    /// Write the file once (a failure is logged: the flight does not depend on it).
    pub(super) fn write(&mut self, vehicles: usize) {
        let Some(file) = self.file.as_ref().filter(|_| !self.written) else {
            return;
        };
        self.written = true;
        let points = self
            .samples
            .iter()
            .zip(self.points.chunks_exact(vehicles * 2))
            .map(|(&(t_s, phase), p)| TrackSample {
                t_s,
                phase,
                positions: p[..vehicles].to_vec(),
                slots: p[vehicles..].to_vec(),
            })
            .collect();
        let tracks = FormationTracks {
            instruction: self.instruction.clone(),
            vehicles,
            phases: self.phases.clone(),
            source: "the vehicles' telemetry in a flight of processes, every 0.2 s".into(),
            points,
        };
        let written = serde_json::to_string(&tracks)
            .map_err(std::io::Error::other)
            .and_then(|text| std::fs::write(file, text));
        match written {
            Ok(()) => tracing::info!("formation: tracks in {}", file.display()),
            Err(e) => tracing::warn!(
                "formation: cannot write the tracks to {}: {e}",
                file.display()
            ),
        }
    }
}
