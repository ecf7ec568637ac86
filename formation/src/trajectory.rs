//! A checked program's slots as functions of time, and the executor that flies them.
//!
//! [`check_program`](crate::check_program) turns a program into [`Segment`]s: in each, every
//! vehicle flies a straight line from where the last one left it to its slot, all together
//! on one trapezoidal speed profile (a hold is a segment that stays). [`Trajectory`] samples
//! them, position and velocity, without allocating. [`FormationExecutor`] is what a
//! formation's ground station runs at the controllers' rate: it follows the segments in
//! time, and between two of them waits until every vehicle is within tolerance of its slot
//! (a vehicle that cannot hold its slot stops the program instead of dragging the others
//! on: the executor reports it, and its caller repairs or lands).

use aeris_schemas::MAX_VEHICLES;

/// One phase of a program, flown: every vehicle from `from` to `to` in `duration_s`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Segment {
    /// The phase of the program (1-based).
    pub phase: usize,
    /// When it starts, from the program's start (s), had every phase ended on time.
    pub start_s: f32,
    /// How long it takes (s).
    pub duration_s: f32,
    /// Where each vehicle starts it (`[N, E, U]`; the first `vehicles`).
    pub from: [[f32; 3]; MAX_VEHICLES],
    /// Its slot at the end.
    pub to: [[f32; 3]; MAX_VEHICLES],
    /// The longest vehicle's path (m): the profile's length.
    pub longest_m: f32,
    /// The profile's top speed (m/s).
    pub speed_mps: f32,
    /// The profile's acceleration (m/s²).
    pub accel_mps2: f32,
}

impl Segment {
    /// A segment in which every vehicle stays at `at` for `duration_s` (a hold).
    pub fn stay(phase: usize, start_s: f32, duration_s: f32, at: [[f32; 3]; MAX_VEHICLES]) -> Self {
        Self {
            phase,
            start_s,
            duration_s,
            from: at,
            to: at,
            longest_m: 0.0,
            speed_mps: 0.0,
            accel_mps2: 0.0,
        }
    }

    /// The share of every path covered `t` seconds into the segment, and its rate (1/s).
    pub fn share_at(&self, t: f32) -> (f32, f32) {
        let (d, v, a, total) = (
            self.longest_m,
            self.speed_mps,
            self.accel_mps2,
            self.duration_s,
        );
        if d <= 0.0 || v <= 0.0 || a <= 0.0 || total <= 0.0 {
            return (1.0, 0.0);
        }
        let t = t.clamp(0.0, total);
        let peak = if d >= v * v / a { v } else { (a * d).sqrt() };
        let ramp_s = peak / a;
        let (x, speed) = if t <= ramp_s {
            (0.5 * a * t * t, a * t)
        } else if t <= total - ramp_s {
            (0.5 * a * ramp_s * ramp_s + peak * (t - ramp_s), peak)
        } else {
            let left = total - t;
            (d - 0.5 * a * left * left, a * left)
        };
        ((x / d).clamp(0.0, 1.0), speed / d)
    }

    /// Vehicle `v`'s slot and slot velocity `t` seconds into the segment.
    pub fn slot_at(&self, v: usize, t: f32) -> Slot {
        self.slot_on(v, self.share_at(t))
    }

    /// The first `n` vehicles' slots `t` seconds into the segment, written to `out` (the
    /// profile is evaluated once for all of them).
    pub fn slots_at(&self, t: f32, n: usize, out: &mut [Slot; MAX_VEHICLES]) {
        let share = self.share_at(t);
        for (v, slot) in out.iter_mut().enumerate().take(n) {
            *slot = self.slot_on(v, share);
        }
    }

    /// Vehicle `v`'s slot at `(share, rate)` of the profile.
    fn slot_on(&self, v: usize, (s, rate): (f32, f32)) -> Slot {
        let (from, to) = (self.from[v], self.to[v]);
        let mut slot = Slot::default();
        for k in 0..3 {
            let delta = to[k] - from[k];
            slot.position[k] = from[k] + s * delta;
            slot.velocity[k] = rate * delta;
        }
        slot
    }
}

/// Where a vehicle should be, and how fast that place moves.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Slot {
    /// `[N, E, U]` (m).
    pub position: [f32; 3],
    /// `[N, E, U]` (m/s): the controller's velocity feed-forward.
    pub velocity: [f32; 3],
}

/// A checked program's segments, in order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Trajectory {
    /// Vehicles it flies.
    pub vehicles: usize,
    /// Its segments, one per phase, in order.
    pub segments: Vec<Segment>,
}

impl Trajectory {
    /// How long it takes when every phase ends on time (s).
    pub fn duration_s(&self) -> f32 {
        self.segments
            .last()
            .map_or(0.0, |s| s.start_s + s.duration_s)
    }

    /// Every vehicle's slot `t` seconds from the start, had every phase ended on time:
    /// the first `vehicles` entries of `out` are written.
    pub fn sample(&self, t: f32, out: &mut [Slot; MAX_VEHICLES]) {
        let Some(seg) = self
            .segments
            .iter()
            .rev()
            .find(|s| s.start_s <= t)
            .or(self.segments.first())
        else {
            return;
        };
        seg.slots_at(t - seg.start_s, self.vehicles, out);
    }
}

/// What the executor is doing after a tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ExecutorState {
    /// Flying segment `segment` (0-based) of the trajectory.
    Flying {
        /// The segment.
        segment: usize,
    },
    /// Segment `segment` has ended; waiting for every vehicle to reach its slot.
    Settling {
        /// The segment.
        segment: usize,
        /// How long it has waited (s).
        waited_s: f32,
    },
    /// Every segment flown and every vehicle at its last slot.
    Done,
    /// A vehicle did not reach its slot within the settle timeout: the program stops
    /// there (the slots stay where the segment ended).
    Stuck {
        /// The segment.
        segment: usize,
        /// The vehicle furthest from its slot (0-based).
        vehicle: usize,
        /// Its distance from the slot (m).
        error_m: f32,
        /// How long it was waited for (s).
        waited_s: f32,
    },
}

/// How close is "at its slot", and how long a vehicle may take to get there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tolerance {
    /// Distance from the slot within which a vehicle is at it (m).
    pub distance_m: f32,
    /// How long, after a segment's end, the executor waits for every vehicle (s).
    pub settle_timeout_s: f32,
}

impl Default for Tolerance {
    /// 0.5 m, 15 s.
    fn default() -> Self {
        Self {
            distance_m: 0.5,
            settle_timeout_s: 15.0,
        }
    }
}

/// Flies a [`Trajectory`] tick by tick from the vehicles' measured positions: time runs
/// within a segment; between segments it waits for every vehicle to be at its slot.
#[derive(Debug, Clone, PartialEq)]
pub struct FormationExecutor {
    trajectory: Trajectory,
    tolerance: Tolerance,
    state: ExecutorState,
    /// Time into the current segment (s).
    clock_s: f32,
    /// How long each segment's settling took (s), once it settled.
    settled_after_s: Vec<f32>,
}

impl FormationExecutor {
    /// An executor at the start of `trajectory`.
    pub fn new(trajectory: Trajectory, tolerance: Tolerance) -> Self {
        let state = if trajectory.segments.is_empty() {
            ExecutorState::Done
        } else {
            ExecutorState::Flying { segment: 0 }
        };
        let settled_after_s = Vec::with_capacity(trajectory.segments.len());
        Self {
            trajectory,
            tolerance,
            state,
            clock_s: 0.0,
            settled_after_s,
        }
    }

    /// The trajectory it flies.
    pub fn trajectory(&self) -> &Trajectory {
        &self.trajectory
    }

    /// Where it is.
    pub fn state(&self) -> ExecutorState {
        self.state
    }

    /// For each segment settled so far, how long after its end every vehicle was at its
    /// slot (s).
    pub fn settled_after_s(&self) -> &[f32] {
        &self.settled_after_s
    }

    /// Advance by `dt` seconds, given each vehicle's position (the first `vehicles` of
    /// `positions`), and write each vehicle's slot to `out`. Allocation-free.
    pub fn tick(
        &mut self,
        dt: f32,
        positions: &[[f32; 3]],
        out: &mut [Slot; MAX_VEHICLES],
    ) -> ExecutorState {
        let n = self.trajectory.vehicles.min(positions.len());
        let dt = if dt.is_finite() { dt.max(0.0) } else { 0.0 };
        match self.state {
            ExecutorState::Flying { segment } => {
                self.clock_s += dt;
                let seg = &self.trajectory.segments[segment];
                if self.clock_s >= seg.duration_s {
                    self.state = ExecutorState::Settling {
                        segment,
                        waited_s: self.clock_s - seg.duration_s,
                    };
                }
            }
            ExecutorState::Settling { segment, waited_s } => {
                self.state = ExecutorState::Settling {
                    segment,
                    waited_s: waited_s + dt,
                };
            }
            ExecutorState::Done | ExecutorState::Stuck { .. } => {}
        }
        if let ExecutorState::Settling { segment, waited_s } = self.state {
            let seg = &self.trajectory.segments[segment];
            let (vehicle, error_m) = (0..n)
                .map(|v| (v, distance(positions[v], seg.to[v])))
                .fold((0, 0.0f32), |a, b| if b.1 > a.1 { b } else { a });
            if error_m <= self.tolerance.distance_m {
                self.settled_after_s.push(waited_s);
                self.clock_s = 0.0;
                self.state = if segment + 1 < self.trajectory.segments.len() {
                    ExecutorState::Flying {
                        segment: segment + 1,
                    }
                } else {
                    ExecutorState::Done
                };
            } else if waited_s > self.tolerance.settle_timeout_s {
                self.state = ExecutorState::Stuck {
                    segment,
                    vehicle,
                    error_m,
                    waited_s,
                };
            }
        }
        let (segment, t) = match self.state {
            ExecutorState::Flying { segment } => (segment, self.clock_s),
            ExecutorState::Settling { segment, .. } | ExecutorState::Stuck { segment, .. } => {
                (segment, f32::INFINITY)
            }
            ExecutorState::Done => (
                self.trajectory.segments.len().saturating_sub(1),
                f32::INFINITY,
            ),
        };
        if let Some(seg) = self.trajectory.segments.get(segment) {
            seg.slots_at(t, n, out);
        }
        self.state
    }
}

/// The distance between two points `[N, E, U]` (m).
pub(crate) fn distance(a: [f32; 3], b: [f32; 3]) -> f32 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(from: [f32; 3], to: [f32; 3]) -> Segment {
        let mut f = [[0.0; 3]; MAX_VEHICLES];
        let mut t = [[0.0; 3]; MAX_VEHICLES];
        f[0] = from;
        t[0] = to;
        Segment {
            phase: 1,
            start_s: 0.0,
            // 20 m at 5 m/s, 2 m/s²
            duration_s: 6.5,
            from: f,
            to: t,
            longest_m: 20.0,
            speed_mps: 5.0,
            accel_mps2: 2.0,
        }
    }

    #[test]
    fn a_segment_starts_and_ends_at_rest_and_never_exceeds_its_speed() {
        let s = line([0.0; 3], [20.0, 0.0, 0.0]);
        assert_eq!(s.slot_at(0, 0.0).position, [0.0; 3]);
        assert_eq!(s.slot_at(0, 0.0).velocity, [0.0; 3]);
        let end = s.slot_at(0, 6.5);
        assert!((end.position[0] - 20.0).abs() < 1e-4, "{end:?}");
        assert!(end.velocity[0].abs() < 1e-4, "{end:?}");
        let mut last = 0.0;
        for k in 0..=65 {
            let slot = s.slot_at(0, k as f32 * 0.1);
            assert!(slot.velocity[0] <= 5.0 + 1e-4, "{slot:?}");
            assert!(slot.position[0] >= last - 1e-5, "it goes back at {k}");
            last = slot.position[0];
        }
        // halfway in time is halfway in distance (a symmetric profile)
        assert!((s.slot_at(0, 3.25).position[0] - 10.0).abs() < 1e-3);
    }

    #[test]
    fn the_executor_waits_at_a_segment_end_for_a_vehicle_that_lags() {
        let mut seg = line([0.0; 3], [20.0, 0.0, 0.0]);
        seg.from[1] = [0.0, 5.0, 0.0];
        seg.to[1] = [20.0, 5.0, 0.0];
        let traj = Trajectory {
            vehicles: 2,
            segments: vec![seg, Segment::stay(2, 6.5, 1.0, seg.to)],
        };
        let mut x = FormationExecutor::new(traj, Tolerance::default());
        let mut out = [Slot::default(); MAX_VEHICLES];
        // vehicle 1 follows its slot, vehicle 2 stays behind
        let mut pos = [[0.0, 0.0, 0.0], [0.0, 5.0, 0.0]];
        for _ in 0..70 {
            x.tick(0.1, &pos, &mut out);
            pos[0] = out[0].position;
        }
        assert!(matches!(
            x.state(),
            ExecutorState::Settling { segment: 0, .. }
        ));
        // the slots stay at the segment's end while it waits
        assert_eq!(out[1].position, [20.0, 5.0, 0.0]);
        pos[1] = [19.8, 5.0, 0.0];
        assert_eq!(
            x.tick(0.1, &pos, &mut out),
            ExecutorState::Flying { segment: 1 }
        );
        assert_eq!(x.settled_after_s().len(), 1);
        for _ in 0..11 {
            x.tick(0.1, &pos, &mut out);
        }
        assert_eq!(x.state(), ExecutorState::Done);
    }

    #[test]
    fn a_vehicle_that_never_arrives_stops_the_program_naming_it() {
        let mut seg = line([0.0; 3], [20.0, 0.0, 0.0]);
        seg.from[1] = [0.0, 5.0, 0.0];
        seg.to[1] = [20.0, 5.0, 0.0];
        let traj = Trajectory {
            vehicles: 2,
            segments: vec![seg],
        };
        let mut x = FormationExecutor::new(traj, Tolerance::default());
        let mut out = [Slot::default(); MAX_VEHICLES];
        let pos = [[20.0, 0.0, 0.0], [3.0, 5.0, 0.0]];
        let mut state = x.state();
        for _ in 0..300 {
            state = x.tick(0.1, &pos, &mut out);
        }
        let ExecutorState::Stuck {
            segment: 0,
            vehicle: 1,
            error_m,
            ..
        } = state
        else {
            panic!("{state:?}");
        };
        assert!((error_m - 17.0).abs() < 1e-4, "{error_m}");
    }
}
