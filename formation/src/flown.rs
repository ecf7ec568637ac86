//! A checked program flown by a vehicle model, faster than real time: every vehicle tracks
//! the slot the [`FormationExecutor`] gives it at the controllers' rate (position and
//! velocity feed-forward, as the controller's offboard setpoints), with the model's own
//! speed and acceleration limits (the built-in multirotor's: `aeris_sim::formation_vehicle`,
//! where the tests of this module live, since this crate must not depend on the simulator). Where [`check_program`](crate::check_program)
//! proves the straight-line transitions apart, this measures what vehicles that lag their
//! slots do: the smallest distance between two of them, how long each phase takes to
//! settle, how far a vehicle falls behind; and records the tracks for a plot.

use crate::check::{Diagnosis, Violation, phase_description};
use crate::trajectory::{ExecutorState, FormationExecutor, Slot, Tolerance, Trajectory, distance};
use aeris_schemas::{FormationLimits, FormationProgram, MAX_VEHICLES};

/// A vehicle that flies toward the slot it is given (the built-in multirotor is one:
/// `aeris_sim::formation_vehicle`). This crate holds no vehicle model, so that what
/// depends on it (the on-board roles among them) builds without the simulator.
pub trait VehicleModel {
    /// Fly toward `slot` (position, velocity feed-forward) for `dt` seconds.
    fn step(&mut self, dt: f32, slot: &Slot);
    /// Where it is, `[N, E, U]`.
    fn position(&self) -> [f32; 3];
}

/// Makes a vehicle, armed, at rest at a starting position.
pub type VehicleFactory = fn(start: [f32; 3]) -> Box<dyn VehicleModel>;

/// How the program is flown.
#[derive(Debug, Clone, Copy)]
pub struct FlownConfig {
    /// The vehicles' model.
    pub vehicle: VehicleFactory,
    /// Setpoints per second (the controllers' rate).
    pub rate_hz: f32,
    /// When a vehicle is at its slot, and how long it may take.
    pub tolerance: Tolerance,
    /// Seconds between two recorded track points.
    pub track_every_s: f32,
    /// Stop this many seconds into the flight, wherever it is (`None`: fly to the end).
    pub stop_after_s: Option<f32>,
}

impl FlownConfig {
    /// `vehicle`, 50 Hz, the default tolerance, a track point every 0.1 s.
    pub fn new(vehicle: VehicleFactory) -> Self {
        Self {
            vehicle,
            rate_hz: 50.0,
            tolerance: Tolerance::default(),
            track_every_s: 0.1,
            stop_after_s: None,
        }
    }
}

/// Every vehicle's position and slot at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackPoint {
    /// Time from the start (s).
    pub t_s: f32,
    /// The phase flown (1-based).
    pub phase: usize,
    /// Each vehicle's position `[N, E, U]`.
    pub positions: [[f32; 3]; MAX_VEHICLES],
    /// Each vehicle's slot.
    pub slots: [[f32; 3]; MAX_VEHICLES],
}

/// The closest two vehicles came.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Closest {
    /// The first vehicle (1-based).
    pub a: usize,
    /// The second (1-based).
    pub b: usize,
    /// Their distance (m).
    pub distance_m: f32,
    /// When (s).
    pub at_s: f32,
    /// In which phase (1-based).
    pub phase: usize,
}

/// What flying the program showed.
#[derive(Debug, Clone, PartialEq)]
pub struct FlownReport {
    /// How it ended: [`ExecutorState::Done`], [`ExecutorState::Stuck`] naming the vehicle,
    /// or where it was when stopped ([`FlownConfig::stop_after_s`]).
    pub end: ExecutorState,
    /// How long it took (s).
    pub duration_s: f32,
    /// The closest two vehicles came (`None` for a single vehicle).
    pub closest: Option<Closest>,
    /// For each phase, how long after its planned end every vehicle was at its slot (s).
    pub settled_after_s: Vec<f32>,
    /// The furthest any vehicle was from its slot while flying (m).
    pub max_tracking_error_m: f32,
    /// Every vehicle's position and slot, every `track_every_s`.
    pub tracks: Vec<TrackPoint>,
}

/// Fly `trajectory` from `starts` (on the ground, armed) until it ends or a vehicle is
/// stuck. `None` when fewer starts than vehicles are given or the rate is not positive.
pub fn fly_trajectory(
    trajectory: &Trajectory,
    starts: &[[f32; 3]],
    config: &FlownConfig,
) -> Option<FlownReport> {
    let n = trajectory.vehicles;
    if starts.len() < n || !(config.rate_hz.is_finite() && config.rate_hz > 0.0) {
        return None;
    }
    let dt = 1.0 / config.rate_hz;
    let mut vehicles: Vec<Box<dyn VehicleModel>> =
        starts[..n].iter().map(|p| (config.vehicle)(*p)).collect();
    let mut executor = FormationExecutor::new(trajectory.clone(), config.tolerance);
    let mut positions = [[0.0f32; 3]; MAX_VEHICLES];
    let mut slots = [Slot::default(); MAX_VEHICLES];
    let mut report = FlownReport {
        end: executor.state(),
        duration_s: 0.0,
        closest: None,
        settled_after_s: Vec::new(),
        max_tracking_error_m: 0.0,
        tracks: Vec::new(),
    };
    // every phase on time, every settle timed out: the longest it may take
    let bound_s = trajectory.duration_s()
        + config.tolerance.settle_timeout_s * (trajectory.segments.len() + 1) as f32;
    let mut next_track = 0.0f32;
    let mut t = 0.0f32;
    loop {
        for (p, m) in positions.iter_mut().zip(&vehicles) {
            *p = m.position();
        }
        let state = executor.tick(dt, &positions[..n], &mut slots);
        let segment = match state {
            ExecutorState::Flying { segment }
            | ExecutorState::Settling { segment, .. }
            | ExecutorState::Stuck { segment, .. } => segment,
            ExecutorState::Done => trajectory.segments.len().saturating_sub(1),
        };
        let phase = trajectory.segments.get(segment).map_or(0, |s| s.phase);
        if matches!(state, ExecutorState::Flying { .. }) {
            for v in 0..n {
                report.max_tracking_error_m = report
                    .max_tracking_error_m
                    .max(distance(positions[v], slots[v].position));
            }
        }
        for a in 0..n {
            for b in a + 1..n {
                let d = distance(positions[a], positions[b]);
                if report.closest.is_none_or(|c| d < c.distance_m) {
                    report.closest = Some(Closest {
                        a: a + 1,
                        b: b + 1,
                        distance_m: d,
                        at_s: t,
                        phase,
                    });
                }
            }
        }
        let ending = matches!(state, ExecutorState::Done | ExecutorState::Stuck { .. })
            || config.stop_after_s.is_some_and(|s| t >= s);
        if t >= next_track || ending {
            let mut point = TrackPoint {
                t_s: t,
                phase,
                positions,
                slots: [[0.0; 3]; MAX_VEHICLES],
            };
            for (s, slot) in point.slots.iter_mut().zip(&slots) {
                *s = slot.position;
            }
            report.tracks.push(point);
            next_track += config.track_every_s.max(dt);
        }
        if ending || t > bound_s {
            report.end = state;
            break;
        }
        for (m, slot) in vehicles.iter_mut().zip(&slots) {
            m.step(dt, slot);
        }
        t += dt;
    }
    report.duration_s = t;
    report.settled_after_s = executor.settled_after_s().to_vec();
    Some(report)
}

/// What flying showed wrong first, as a [`Diagnosis`] of `program` under `limits`: two
/// vehicles closer than the minimum separation, or a vehicle stuck off its slot; `None`
/// when it flew clear.
pub fn flown_diagnosis(
    flown: &FlownReport,
    program: &FormationProgram,
    limits: &FormationLimits,
) -> Option<Diagnosis> {
    let describe = |phase: usize| {
        program
            .phases()
            .get(phase.wrapping_sub(1))
            .map_or_else(String::new, phase_description)
    };
    if let Some(c) = flown.closest
        && c.distance_m < limits.min_separation_m
    {
        return Some(Diagnosis {
            violation: Violation::TooClose {
                a: c.a,
                b: c.b,
                distance_m: c.distance_m,
            },
            phase: c.phase,
            during: format!("{} as the vehicles flew it", describe(c.phase)),
            at_s: c.at_s,
            min_separation_m: limits.min_separation_m,
        });
    }
    if let ExecutorState::Stuck {
        segment,
        vehicle,
        error_m,
        waited_s,
    } = flown.end
    {
        let phase = segment + 1;
        return Some(Diagnosis {
            violation: Violation::OffSlot {
                vehicle: vehicle + 1,
                error_m,
                waited_s,
            },
            phase,
            during: describe(phase),
            at_s: flown.duration_s,
            min_separation_m: limits.min_separation_m,
        });
    }
    None
}
