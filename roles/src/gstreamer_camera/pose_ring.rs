//! The vehicle's recent poses, to place a frame at its capture time.
//!
//! A fixed ring of the last [`CAPACITY`] valid `vehicle/telemetry` samples (time of
//! publication, position, yaw): no allocation after construction. [`PoseRing::at`] answers
//! the pose at a capture time:
//! - between two samples: linear interpolation of the position, and of the yaw along the
//!   shorter arc (wrapped into [-pi, pi]);
//! - after the newest sample (the usual case for a frame captured a few ms after the last
//!   50 Hz telemetry): the newest pose, held, not extrapolated;
//! - before the oldest sample (a frame older than the ring, [`CAPACITY`] × 20 ms = 2.56 s
//!   at the controller's 50 Hz): the oldest pose, held;
//! - no sample yet: `None` (the camera then uses the mission start, yaw 0, as `sim-render`
//!   does before the first telemetry).

use aeris_geometry::wrap_pi;

/// Samples kept.
pub const CAPACITY: usize = 128;

/// One pose at one time.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PoseSample {
    /// CLOCK_MONOTONIC ns of the sample.
    pub t_ns: u64,
    /// Vehicle position `[N, E, U]` (m).
    pub position: [f32; 3],
    /// Vehicle yaw (rad).
    pub yaw: f32,
}

/// How [`PoseRing::at`] found its pose.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PoseFit {
    /// Between two samples (or exactly on one).
    Interpolated,
    /// Newer than every sample: the newest, held.
    HeldNewest,
    /// Older than every sample: the oldest, held.
    HeldOldest,
}

/// The ring of recent poses.
#[derive(Debug, Clone)]
pub struct PoseRing {
    samples: [PoseSample; CAPACITY],
    /// Index of the oldest sample.
    start: usize,
    len: usize,
}

impl Default for PoseRing {
    fn default() -> Self {
        Self {
            samples: [PoseSample::default(); CAPACITY],
            start: 0,
            len: 0,
        }
    }
}

impl PoseRing {
    /// Samples held.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether no sample arrived yet.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    fn get(&self, i: usize) -> PoseSample {
        self.samples[(self.start + i) % CAPACITY]
    }

    /// Add a sample; one not newer than the newest (a repeat or a late one) is ignored, and
    /// a full ring forgets its oldest.
    pub fn push(&mut self, s: PoseSample) {
        if self.len > 0 && s.t_ns <= self.get(self.len - 1).t_ns {
            return;
        }
        if self.len == CAPACITY {
            self.samples[self.start] = s;
            self.start = (self.start + 1) % CAPACITY;
        } else {
            self.samples[(self.start + self.len) % CAPACITY] = s;
            self.len += 1;
        }
    }

    /// The pose at `t_ns` (see the module docs); `None` before the first sample.
    pub fn at(&self, t_ns: u64) -> Option<(PoseSample, PoseFit)> {
        if self.len == 0 {
            return None;
        }
        let newest = self.get(self.len - 1);
        if t_ns >= newest.t_ns {
            let fit = if t_ns == newest.t_ns {
                PoseFit::Interpolated
            } else {
                PoseFit::HeldNewest
            };
            return Some((PoseSample { t_ns, ..newest }, fit));
        }
        let oldest = self.get(0);
        if t_ns < oldest.t_ns {
            return Some((PoseSample { t_ns, ..oldest }, PoseFit::HeldOldest));
        }
        // the last sample at or before t (binary search over the ordered ring)
        let (mut lo, mut hi) = (0, self.len - 1);
        while hi - lo > 1 {
            let mid = (lo + hi) / 2;
            if self.get(mid).t_ns <= t_ns {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let (a, b) = (self.get(lo), self.get(hi));
        let f = (t_ns - a.t_ns) as f64 / (b.t_ns - a.t_ns) as f64;
        let f = f as f32;
        let lerp = |x: f32, y: f32| x + (y - x) * f;
        Some((
            PoseSample {
                t_ns,
                position: [
                    lerp(a.position[0], b.position[0]),
                    lerp(a.position[1], b.position[1]),
                    lerp(a.position[2], b.position[2]),
                ],
                yaw: wrap_pi(a.yaw + wrap_pi(b.yaw - a.yaw) * f),
            },
            PoseFit::Interpolated,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s(t: u64, n: f32, yaw: f32) -> PoseSample {
        PoseSample {
            t_ns: t,
            position: [n, 2.0 * n, 10.0],
            yaw,
        }
    }

    #[test]
    fn interpolates_between_samples_and_holds_outside() {
        let mut r = PoseRing::default();
        assert!(r.at(5).is_none());
        r.push(s(100, 0.0, 0.0));
        r.push(s(200, 10.0, 1.0));
        r.push(s(150, 99.0, 0.0)); // late: ignored
        assert_eq!(r.len(), 2);
        let (p, fit) = r.at(150).unwrap();
        assert_eq!(fit, PoseFit::Interpolated);
        assert_eq!(p.position, [5.0, 10.0, 10.0]);
        assert!((p.yaw - 0.5).abs() < 1e-6);
        assert_eq!(r.at(250).unwrap().1, PoseFit::HeldNewest);
        assert_eq!(r.at(250).unwrap().0.position[0], 10.0);
        assert_eq!(r.at(50).unwrap().1, PoseFit::HeldOldest);
        assert_eq!(r.at(50).unwrap().0.position[0], 0.0);
    }

    #[test]
    fn yaw_takes_the_short_way_across_a_half_turn() {
        let mut r = PoseRing::default();
        r.push(s(0, 0.0, 3.0));
        r.push(s(100, 0.0, -3.0));
        let (p, _) = r.at(50).unwrap();
        assert!(p.yaw.abs() > 3.0, "{}", p.yaw);
    }

    #[test]
    fn a_full_ring_forgets_its_oldest_and_stays_ordered() {
        let mut r = PoseRing::default();
        for i in 0..(CAPACITY as u64 * 3) {
            r.push(s(i * 10, i as f32, 0.0));
        }
        assert_eq!(r.len(), CAPACITY);
        let first = CAPACITY as u64 * 2;
        assert_eq!(r.at(0).unwrap().0.position[0], first as f32);
        let (p, fit) = r.at((first + 5) * 10 + 5).unwrap();
        assert_eq!(fit, PoseFit::Interpolated);
        assert!((p.position[0] - (first as f32 + 5.5)).abs() < 1e-3);
    }
}
