//! Which vehicle takes which slot.
//!
//! The assignment minimises the sum of **squared** distances from the vehicles to their
//! slots (the Hungarian method, `pathfinding`'s Kuhn-Munkres). With every vehicle flying
//! a straight line to its slot, all starting and arriving together, that choice keeps any
//! two vehicles at least `d / sqrt(2)` apart throughout, when they start and end at least
//! `d` apart (Turpin, Michael, Kumar: "CAPT: Concurrent assignment and planning of
//! trajectories for multiple robots", IJRR 2014): paths that could be uncrossed are never
//! crossed. Minimising plain distances does not give that bound.

use pathfinding::kuhn_munkres::kuhn_munkres_min;
use pathfinding::matrix::Matrix;

/// Squared distances are compared in units of 1 cm² (integers for the Hungarian method).
const SCALE: f64 = 1e4;

/// Why vehicles could not be assigned to slots.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum AssignError {
    /// More vehicles than slots.
    #[error("{vehicles} vehicles for {slots} slots")]
    TooFewSlots {
        /// Vehicles to place.
        vehicles: usize,
        /// Slots for them.
        slots: usize,
    },
    /// A position that is NaN or infinite (vehicle or slot `index`).
    #[error("{what} {index} is not at a finite position")]
    NonFinite {
        /// `vehicle` or `slot`.
        what: &'static str,
        /// Its index (0-based).
        index: usize,
    },
    /// Positions so far apart that their squared distances overflow the assignment's
    /// integer weights (over ~10^5 km).
    #[error("positions too far apart to assign")]
    TooFar,
}

/// Vehicles to slots: `slot_of[v]` is vehicle `v`'s slot.
#[derive(Debug, Clone, PartialEq)]
pub struct Assignment {
    /// The slot of each vehicle.
    pub slot_of: Vec<usize>,
    /// The sum of squared distances it minimised (m²).
    pub cost_m2: f64,
}

/// Assign each vehicle at `vehicles` (`[N, E, U]`) one of `slots`, minimising the sum of
/// squared distances (see the module).
pub fn assign(vehicles: &[[f32; 3]], slots: &[[f32; 3]]) -> Result<Assignment, AssignError> {
    if vehicles.len() > slots.len() {
        return Err(AssignError::TooFewSlots {
            vehicles: vehicles.len(),
            slots: slots.len(),
        });
    }
    for (what, points) in [("vehicle", vehicles), ("slot", slots)] {
        if let Some(index) = points.iter().position(|p| p.iter().any(|c| !c.is_finite())) {
            return Err(AssignError::NonFinite { what, index });
        }
    }
    if vehicles.is_empty() {
        return Ok(Assignment {
            slot_of: Vec::new(),
            cost_m2: 0.0,
        });
    }
    // every weight, and their sum, must fit an i64
    let limit = (i64::MAX / (vehicles.len() as i64 + 1)) as f64;
    let mut weights = Vec::with_capacity(vehicles.len() * slots.len());
    for v in vehicles {
        for s in slots {
            let w = squared(*v, *s) * SCALE;
            if w > limit {
                return Err(AssignError::TooFar);
            }
            weights.push(w.round() as i64);
        }
    }
    let matrix =
        Matrix::from_vec(vehicles.len(), slots.len(), weights).map_err(|_| AssignError::TooFar)?;
    let (_, slot_of) = kuhn_munkres_min(&matrix);
    let cost_m2 = vehicles
        .iter()
        .zip(&slot_of)
        .map(|(v, &s)| squared(*v, slots[s]))
        .sum();
    Ok(Assignment { slot_of, cost_m2 })
}

fn squared(a: [f32; 3], b: [f32; 3]) -> f64 {
    (0..3)
        .map(|i| (f64::from(a[i]) - f64::from(b[i])).powi(2))
        .sum()
}

/// The closest two vehicles come while flying straight from `from[v]` to `to[v]`, all
/// starting and arriving together: which pair (0-based), how close (m), and at what share
/// of the transition (0..=1). Exact: the pair's relative position is linear in the share.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClosestApproach {
    /// The first vehicle of the pair.
    pub a: usize,
    /// The second (`a < b`).
    pub b: usize,
    /// Their distance then (m).
    pub distance_m: f32,
    /// When, as the share of the transition flown.
    pub share: f32,
}

/// The [`ClosestApproach`] of the vehicles moving from `from` to `to` together; `None`
/// with fewer than two vehicles.
pub fn closest_approach(from: &[[f32; 3]], to: &[[f32; 3]]) -> Option<ClosestApproach> {
    let n = from.len().min(to.len());
    let mut best: Option<ClosestApproach> = None;
    for i in 0..n {
        for j in i + 1..n {
            // relative position p(s) = p0 + s * dp, s in [0, 1]
            let p0: [f32; 3] = core::array::from_fn(|k| from[i][k] - from[j][k]);
            let dp: [f32; 3] = core::array::from_fn(|k| (to[i][k] - to[j][k]) - p0[k]);
            let dd: f32 = dp.iter().map(|d| d * d).sum();
            let share = if dd > 0.0 {
                (-(0..3).map(|k| p0[k] * dp[k]).sum::<f32>() / dd).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let distance_m = (0..3)
                .map(|k| (p0[k] + share * dp[k]).powi(2))
                .sum::<f32>()
                .sqrt();
            if best.is_none_or(|b| distance_m < b.distance_m) {
                best = Some(ClosestApproach {
                    a: i,
                    b: j,
                    distance_m,
                    share,
                });
            }
        }
    }
    best
}

/// The smallest distance between any two vehicles flying straight from `from[v]` to
/// `to[v]`, all starting and arriving together (infinite with fewer than two).
pub fn min_separation_along(from: &[[f32; 3]], to: &[[f32; 3]]) -> f64 {
    closest_approach(from, to).map_or(f64::INFINITY, |c| f64::from(c.distance_m))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Whether the horizontal segments a0-a1 and b0-b1 cross.
    fn cross(a0: [f32; 3], a1: [f32; 3], b0: [f32; 3], b1: [f32; 3]) -> bool {
        let orient = |p: [f32; 3], q: [f32; 3], r: [f32; 3]| {
            (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0])
        };
        let (d1, d2) = (orient(b0, b1, a0), orient(b0, b1, a1));
        let (d3, d4) = (orient(a0, a1, b0), orient(a0, a1, b1));
        d1 * d2 < 0.0 && d3 * d4 < 0.0
    }

    fn crossings(from: &[[f32; 3]], to: &[[f32; 3]], slot_of: &[usize]) -> usize {
        let mut n = 0;
        for i in 0..from.len() {
            for j in i + 1..from.len() {
                if cross(from[i], to[slot_of[i]], from[j], to[slot_of[j]]) {
                    n += 1;
                }
            }
        }
        n
    }

    #[test]
    fn paths_never_cross_where_crossing_is_avoidable() {
        // a line west to east, slots of a line 10 m north listed east to west: taking the
        // slots in their order crosses every pair, the assignment none
        let from: Vec<[f32; 3]> = (0..4).map(|i| [0.0, 3.0 * i as f32, 5.0]).collect();
        let to: Vec<[f32; 3]> = (0..4).map(|i| [10.0, 9.0 - 3.0 * i as f32, 5.0]).collect();
        assert_eq!(crossings(&from, &to, &[0, 1, 2, 3]), 6);
        let a = assign(&from, &to).unwrap();
        assert_eq!(a.slot_of, [3, 2, 1, 0]);
        assert_eq!(crossings(&from, &to, &a.slot_of), 0);
        assert!((a.cost_m2 - 400.0).abs() < 1e-6);
        // a line into a circle around its middle, and a circle turned a quarter: no path
        // crosses another, and nobody comes closer than the starts' 3 m / sqrt(2)
        let circle: Vec<[f32; 3]> = (0..4)
            .map(|i| {
                let a = core::f32::consts::TAU * i as f32 / 4.0 + 0.3;
                [6.0 * a.cos(), 4.5 + 6.0 * a.sin(), 5.0]
            })
            .collect();
        let a = assign(&from, &circle).unwrap();
        assert_eq!(crossings(&from, &circle, &a.slot_of), 0);
        let to: Vec<[f32; 3]> = a.slot_of.iter().map(|&s| circle[s]).collect();
        assert!(min_separation_along(&from, &to) >= 3.0 / 2f64.sqrt());
    }

    #[test]
    fn errors_name_what_cannot_be_assigned() {
        let p = [[0.0, 0.0, 0.0]; 3];
        assert_eq!(
            assign(&p, &p[..2]),
            Err(AssignError::TooFewSlots {
                vehicles: 3,
                slots: 2
            })
        );
        let mut bad = p;
        bad[1][2] = f32::NAN;
        assert_eq!(
            assign(&p, &bad),
            Err(AssignError::NonFinite {
                what: "slot",
                index: 1
            })
        );
        assert_eq!(
            assign(&[[0.0, 0.0, 0.0]], &[[1e30, 0.0, 0.0]]),
            Err(AssignError::TooFar)
        );
        // fewer vehicles than slots: each gets its own
        let a = assign(&p[..1], &[[5.0, 0.0, 0.0], [0.5, 0.0, 0.0]]).unwrap();
        assert_eq!(a.slot_of, [1]);
        assert_eq!(assign(&[], &p).unwrap().slot_of, Vec::<usize>::new());
    }

    /// `n` points at least `d` apart in a 40 m square (rejection sampling from `seeds`).
    fn spread(seeds: &[(f32, f32)], d: f32) -> Vec<[f32; 3]> {
        let mut out: Vec<[f32; 3]> = Vec::new();
        for &(n, e) in seeds {
            let p = [n, e, 5.0];
            if out
                .iter()
                .all(|q| ((q[0] - n).powi(2) + (q[1] - e).powi(2)).sqrt() >= d)
            {
                out.push(p);
            }
        }
        out
    }

    proptest! {
        /// CAPT's bound: starts and slots at least 3 m apart, every vehicle flying straight
        /// and synchronised to its assigned slot: no two closer than 3 / sqrt(2) m.
        #[test]
        fn synchronised_straight_transitions_keep_the_capt_bound(
            a in proptest::collection::vec((0.0f32..40.0, 0.0f32..40.0), 8..40),
            b in proptest::collection::vec((0.0f32..40.0, 0.0f32..40.0), 8..40),
        ) {
            let from = spread(&a, 3.0);
            let slots = spread(&b, 3.0);
            let n = from.len().min(slots.len()).min(8);
            let (from, slots) = (&from[..n], &slots[..n]);
            let assignment = assign(from, slots).unwrap();
            let to: Vec<[f32; 3]> = assignment.slot_of.iter().map(|&s| slots[s]).collect();
            prop_assert!(min_separation_along(from, &to) >= 3.0 / 2f64.sqrt() - 1e-3);
        }
    }
}
