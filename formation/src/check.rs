//! A formation program flown before it flies: every vehicle, every transition, faster than
//! real time, against the flight's limits.
//!
//! Each phase moves the vehicles together: in a shape change every vehicle flies a
//! straight line to the slot [`assign`] gives it, all starting and arriving together (one
//! trapezoidal speed profile, scaled to the longest path, within the speed and acceleration
//! limits); take-off and landing are vertical; a move translates the whole formation. So a
//! pair's distance during a transition is a function of one parameter, and its closest
//! approach is found exactly, not sampled. What is checked: the minimum separation between
//! every pair at every instant, the geofence and altitude band of every slot, and the
//! program's duration. The first violation becomes a [`Diagnosis`]: text for a person and
//! for the formation role's repair ("vehicles 2 and 3 come within 0.8 m at t=4.2 s during
//! the change to a circle; minimum is 2.0 m").

use crate::assign::{AssignError, ClosestApproach, assign, closest_approach};
use crate::slots::slots;
use crate::trajectory::{Segment, Trajectory};
use aeris_schemas::{
    FormationError, FormationLimits, FormationProgram, MAX_VEHICLES, PhaseKind, ShapeKind,
};

/// How the vehicles fly (the built-in multirotor's defaults).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dynamics {
    /// Fastest a vehicle flies in a shape change (m/s).
    pub v_max: f32,
    /// Its largest acceleration (m/s²).
    pub a_max: f32,
    /// Climb and descent speed of take-off and landing (m/s).
    pub v_vertical: f32,
}

impl Default for Dynamics {
    /// 5 m/s, 2 m/s², 1.5 m/s vertically.
    fn default() -> Self {
        Self {
            v_max: 5.0,
            a_max: 2.0,
            v_vertical: 1.5,
        }
    }
}

/// What a check found wrong first.
#[derive(Debug, Clone, PartialEq)]
pub enum Violation {
    /// Two vehicles (1-based) closer than the minimum separation.
    TooClose {
        /// The first vehicle.
        a: usize,
        /// The second.
        b: usize,
        /// Their closest distance (m).
        distance_m: f32,
    },
    /// A slot outside the geofence.
    OutsideGeofence {
        /// The vehicle (1-based).
        vehicle: usize,
        /// Its slot `[N, E]`.
        at: [f32; 2],
    },
    /// A slot outside the altitude band.
    Altitude {
        /// The vehicle (1-based).
        vehicle: usize,
        /// Its height (m).
        height_m: f32,
    },
    /// A vehicle, flown by the vehicle model, did not reach its slot in time
    /// ([`crate::flown`]).
    OffSlot {
        /// The vehicle (1-based).
        vehicle: usize,
        /// How far from its slot it still was (m).
        error_m: f32,
        /// How long it was waited for after the phase's end (s).
        waited_s: f32,
    },
}

/// The first violation, where and when.
#[derive(Debug, Clone, PartialEq)]
pub struct Diagnosis {
    /// What.
    pub violation: Violation,
    /// The phase (1-based).
    pub phase: usize,
    /// What the phase did ("take-off", "the change to a circle", "the move", "landing").
    pub during: String,
    /// Time from the program's start (s).
    pub at_s: f32,
    /// The flight's minimum separation (m).
    pub min_separation_m: f32,
}

impl core::fmt::Display for Diagnosis {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match &self.violation {
            Violation::TooClose { a, b, distance_m } => write!(
                f,
                "vehicles {a} and {b} come within {distance_m:.1} m at t={:.1} s during {} (phase {}); minimum is {:.1} m",
                self.at_s, self.during, self.phase, self.min_separation_m
            ),
            Violation::OutsideGeofence { vehicle, at } => write!(
                f,
                "vehicle {vehicle}'s slot at N {:.1} E {:.1} is outside the geofence, in {} (phase {})",
                at[0], at[1], self.during, self.phase
            ),
            Violation::Altitude { vehicle, height_m } => write!(
                f,
                "vehicle {vehicle} would fly at {height_m:.1} m, outside the altitude band, in {} (phase {})",
                self.during, self.phase
            ),
            Violation::OffSlot {
                vehicle,
                error_m,
                waited_s,
            } => write!(
                f,
                "vehicle {vehicle} is still {error_m:.1} m from its slot {waited_s:.0} s after {} (phase {}) should have ended",
                self.during, self.phase
            ),
        }
    }
}

/// The result of flying a program in simulation.
#[derive(Debug, Clone, PartialEq)]
pub struct CheckReport {
    /// The first violation, if any: the program is accepted only without one.
    pub diagnosis: Option<Diagnosis>,
    /// The smallest distance between two vehicles over the whole program (m; up to the
    /// violation).
    pub min_separation_m: f32,
    /// How long the program takes (s; up to the violation).
    pub duration_s: f32,
    /// Each vehicle's position at the end of each phase flown.
    pub ends: Vec<[[f32; 3]; MAX_VEHICLES]>,
    /// The phases flown, as functions of time (what the formation executor flies).
    pub trajectory: Trajectory,
}

impl CheckReport {
    /// `true` when the program flew without a violation.
    pub fn accepted(&self) -> bool {
        self.diagnosis.is_none()
    }
}

/// Why a program could not be checked at all.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CheckError {
    /// It fails validation.
    #[error("the program is invalid")]
    Invalid(#[from] FormationError),
    /// Fewer starting positions than vehicles.
    #[error("{vehicles} vehicles, {starts} starting positions")]
    Starts {
        /// Vehicles of the program.
        vehicles: usize,
        /// Starting positions given.
        starts: usize,
    },
    /// Vehicles could not be assigned to slots.
    #[error("assigning vehicles to slots")]
    Assign(#[from] AssignError),
    /// The dynamics are not positive, finite numbers.
    #[error("the vehicle dynamics are not positive numbers")]
    Dynamics,
}

/// What phase `phase` of a program does, as a diagnosis says it ("take-off", "the change to
/// a circle", "the hold", "the move", "landing").
pub fn phase_description(phase: &aeris_schemas::FormationPhase) -> String {
    match PhaseKind::from_u8(phase.kind) {
        Some(PhaseKind::TakeOff) => "take-off".into(),
        Some(PhaseKind::Land) => "landing".into(),
        Some(PhaseKind::Hold) => "the hold".into(),
        Some(PhaseKind::Move) => "the move".into(),
        Some(PhaseKind::Assume) => format!(
            "the change to a {}",
            ShapeKind::from_u8(phase.shape).map_or("?", ShapeKind::name)
        ),
        None => "an unknown phase".into(),
    }
}

/// Duration of a synchronised straight transition whose longest path is `d` (m): a
/// trapezoidal profile within `v` and `a`.
fn transition_s(d: f32, v: f32, a: f32) -> f32 {
    if d <= 0.0 {
        return 0.0;
    }
    let ramp = v * v / a;
    if d >= ramp {
        d / v + v / a
    } else {
        2.0 * (d / a).sqrt()
    }
}

/// The time at which the profile of a transition of duration `t` (longest path `d`) has
/// covered share `s` of it.
fn time_at_share(s: f32, d: f32, t: f32, v: f32, a: f32) -> f32 {
    if d <= 0.0 || t <= 0.0 {
        return 0.0;
    }
    let x = s.clamp(0.0, 1.0) * d;
    let ramp = v * v / a;
    let (peak, accel_d) = if d >= ramp {
        (v, ramp / 2.0)
    } else {
        ((a * d).sqrt(), d / 2.0)
    };
    let ta = peak / a;
    if x <= accel_d {
        (2.0 * x / a).sqrt()
    } else if x <= d - accel_d {
        ta + (x - accel_d) / peak
    } else {
        t - (2.0 * (d - x) / a).sqrt()
    }
}

/// `n` vehicles on the ground in a row along east, `spacing` metres apart, centred on the
/// origin: the starting positions a plan assumes when the vehicles' own are not known.
pub fn ground_row(n: usize, spacing: f32) -> Vec<[f32; 3]> {
    let middle = (n as f32 - 1.0) / 2.0;
    (0..n)
        .map(|i| [0.0, (i as f32 - middle) * spacing, 0.0])
        .collect()
}

/// Fly `program` from the vehicles' starting positions `starts` (`[N, E, U]`, on the
/// ground) against `limits` with `dynamics`.
pub fn check_program(
    program: &FormationProgram,
    starts: &[[f32; 3]],
    limits: &FormationLimits,
    dynamics: &Dynamics,
) -> Result<CheckReport, CheckError> {
    program.validate(limits)?;
    let n = program.vehicles as usize;
    if starts.len() < n {
        return Err(CheckError::Starts {
            vehicles: n,
            starts: starts.len(),
        });
    }
    let Dynamics {
        v_max,
        a_max,
        v_vertical,
    } = *dynamics;
    if ![v_max, a_max, v_vertical]
        .iter()
        .all(|x| x.is_finite() && *x > 0.0)
    {
        return Err(CheckError::Dynamics);
    }
    let mut now = [[0.0f32; 3]; MAX_VEHICLES];
    now[..n].copy_from_slice(&starts[..n]);
    let mut report = CheckReport {
        diagnosis: None,
        min_separation_m: f32::INFINITY,
        duration_s: 0.0,
        ends: Vec::with_capacity(program.phases().len()),
        trajectory: Trajectory {
            vehicles: n,
            segments: Vec::with_capacity(program.phases().len()),
        },
    };
    // the formation's centre as flown (moves translate it)
    let mut centre: Option<[f32; 2]> = None;
    for (index, phase) in program.phases().iter().enumerate() {
        let kind = PhaseKind::from_u8(phase.kind).ok_or(FormationError::UnknownKind {
            phase: index + 1,
            kind: phase.kind,
        })?;
        let mut next = now;
        let (during, speed, vertical) = match kind {
            PhaseKind::TakeOff => {
                for p in next.iter_mut().take(n) {
                    p[2] = phase.height_m;
                }
                (phase_description(phase), v_vertical, true)
            }
            PhaseKind::Land => {
                for p in next.iter_mut().take(n) {
                    p[2] = 0.0;
                }
                (phase_description(phase), v_vertical, true)
            }
            PhaseKind::Hold => {
                report.trajectory.segments.push(Segment::stay(
                    index + 1,
                    report.duration_s,
                    phase.hold_s,
                    now,
                ));
                report.duration_s += phase.hold_s;
                report.ends.push(now);
                continue;
            }
            PhaseKind::Assume => {
                let slots = slots(phase, n).ok_or(FormationError::UnknownShape {
                    phase: index + 1,
                    shape: phase.shape,
                })?;
                let a = assign(&now[..n], &slots[..n])?;
                for (v, &s) in a.slot_of.iter().enumerate() {
                    next[v] = slots[s];
                }
                centre = Some(phase.centre);
                (phase_description(phase), v_max, false)
            }
            PhaseKind::Move => {
                let from = centre.unwrap_or(phase.centre);
                let shift = [phase.centre[0] - from[0], phase.centre[1] - from[1]];
                for p in next.iter_mut().take(n) {
                    p[0] += shift[0];
                    p[1] += shift[1];
                }
                centre = Some(phase.centre);
                (phase_description(phase), phase.speed_mps.min(v_max), false)
            }
        };
        // the slots: inside the geofence and the altitude band
        for (v, p) in next.iter().enumerate().take(n) {
            let violation = if !(limits.geofence_min[0]..=limits.geofence_max[0]).contains(&p[0])
                || !(limits.geofence_min[1]..=limits.geofence_max[1]).contains(&p[1])
            {
                Some(Violation::OutsideGeofence {
                    vehicle: v + 1,
                    at: [p[0], p[1]],
                })
            } else if !vertical && !(limits.h_min..=limits.h_max).contains(&p[2]) {
                Some(Violation::Altitude {
                    vehicle: v + 1,
                    height_m: p[2],
                })
            } else {
                None
            };
            if let Some(violation) = violation {
                report.diagnosis = Some(Diagnosis {
                    violation,
                    phase: index + 1,
                    during,
                    at_s: report.duration_s,
                    min_separation_m: limits.min_separation_m,
                });
                return Ok(report);
            }
        }
        let longest = (0..n)
            .map(|v| {
                (0..3)
                    .map(|k| (next[v][k] - now[v][k]).powi(2))
                    .sum::<f32>()
                    .sqrt()
            })
            .fold(0.0f32, f32::max);
        let duration = transition_s(longest, speed, a_max);
        if let Some(ClosestApproach {
            a,
            b,
            distance_m: d,
            share: s,
        }) = closest_approach(&now[..n], &next[..n])
        {
            report.min_separation_m = report.min_separation_m.min(d);
            if d < limits.min_separation_m {
                report.diagnosis = Some(Diagnosis {
                    violation: Violation::TooClose {
                        a: a + 1,
                        b: b + 1,
                        distance_m: d,
                    },
                    phase: index + 1,
                    during,
                    at_s: report.duration_s + time_at_share(s, longest, duration, speed, a_max),
                    min_separation_m: limits.min_separation_m,
                });
                return Ok(report);
            }
        }
        report.trajectory.segments.push(Segment {
            phase: index + 1,
            start_s: report.duration_s,
            duration_s: duration,
            from: now,
            to: next,
            longest_m: longest,
            speed_mps: speed,
            accel_mps2: a_max,
        });
        report.duration_s += duration;
        now = next;
        report.ends.push(now);
    }
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::parse::parse_instruction;

    /// Four vehicles on the ground in a row, 4 m apart, west to east.
    fn starts() -> Vec<[f32; 3]> {
        (0..4).map(|i| [0.0, -6.0 + 4.0 * i as f32, 0.0]).collect()
    }

    #[test]
    fn the_line_v_circle_program_flies_clear_of_every_limit() {
        let limits = FormationLimits::default();
        let p = parse_instruction(
            "four drones take off to 5 m in a line 3 m apart, then form a V heading north, \
             hold 10 s, then a circle of radius 6 m, and land",
            &limits,
        )
        .unwrap();
        let r = check_program(&p, &starts(), &limits, &Dynamics::default()).unwrap();
        assert!(r.accepted(), "{:?}", r.diagnosis.map(|d| d.to_string()));
        assert!(r.min_separation_m >= limits.min_separation_m, "{r:?}");
        assert_eq!(r.ends.len(), 6);
        // every vehicle at its slot of the circle, all on the ground at the end
        let circle = slots(&p.phases()[4], 4).unwrap();
        let at_circle = &r.ends[4];
        for (v, at) in at_circle[..4].iter().enumerate() {
            assert!(circle[..4].contains(at), "vehicle {v} off its slot");
        }
        assert!(r.ends[5][..4].iter().all(|p| p[2] == 0.0));
        assert!(r.duration_s > 10.0, "{}", r.duration_s);
    }

    #[test]
    fn a_circle_too_small_for_its_vehicles_is_diagnosed_with_who_when_and_where() {
        // eight vehicles on a circle of radius 2 m: neighbours 1.5 m apart
        let limits = FormationLimits {
            vehicles: 8,
            ..FormationLimits::default()
        };
        let p = parse_instruction(
            "eight drones take off to 5 m in a line 3 m apart, then a circle of radius 2 m, and land",
            &limits,
        )
        .unwrap();
        let starts: Vec<[f32; 3]> = (0..8).map(|i| [0.0, 3.0 * i as f32, 0.0]).collect();
        let r = check_program(&p, &starts, &limits, &Dynamics::default()).unwrap();
        let d = r.diagnosis.expect("a diagnosis");
        assert_eq!(d.phase, 3);
        assert_eq!(d.during, "the change to a circle");
        let Violation::TooClose { a, b, distance_m } = d.violation else {
            panic!("{d}");
        };
        assert!(a < b && b <= 8 && distance_m < 2.0, "{d}");
        let text = d.to_string();
        println!("{text}");
        assert!(
            text.starts_with(&format!("vehicles {a} and {b} come within"))
                && text.contains("during the change to a circle (phase 3); minimum is 2.0 m"),
            "{text}"
        );
        // it happened after take-off and the line
        assert!(d.at_s > 0.0, "{text}");
    }

    #[test]
    fn a_move_out_of_the_geofence_is_diagnosed() {
        let limits = FormationLimits::default();
        let p = parse_instruction("take off, a line, move 250 m north, land", &limits);
        // the move's centre is outside the geofence: validate refuses it already
        assert!(matches!(
            check_program(&p.unwrap(), &starts(), &limits, &Dynamics::default()),
            Err(CheckError::Invalid(_))
        ));
        // a centre inside, a slot outside: the check finds it
        let p = parse_instruction(
            "take off, a line 10 m apart, move 195 m east, land",
            &limits,
        )
        .unwrap();
        let r = check_program(&p, &starts(), &limits, &Dynamics::default()).unwrap();
        let d = r.diagnosis.expect("outside");
        assert!(
            matches!(d.violation, Violation::OutsideGeofence { .. }),
            "{d}"
        );
        assert_eq!(d.during, "the move");
    }

    #[test]
    fn starts_closer_than_the_minimum_are_found_at_take_off() {
        let limits = FormationLimits::default();
        let p = parse_instruction("take off, a line, land", &limits).unwrap();
        let mut s = starts();
        s[1] = [0.0, -5.0, 0.0];
        let r = check_program(&p, &s, &limits, &Dynamics::default()).unwrap();
        let d = r.diagnosis.unwrap();
        assert_eq!((d.phase, d.during.as_str()), (1, "take-off"));
        assert!(matches!(
            d.violation,
            Violation::TooClose { a: 1, b: 2, .. }
        ));
        assert!(matches!(
            check_program(&p, &s[..2], &limits, &Dynamics::default()),
            Err(CheckError::Starts {
                vehicles: 4,
                starts: 2
            })
        ));
    }

    #[test]
    fn the_profile_is_within_its_limits_and_inverts() {
        // 20 m at 5 m/s, 2 m/s²: 2.5 s up, 2.5 s down, 1.5 s cruising
        let t = transition_s(20.0, 5.0, 2.0);
        assert!((t - 6.5).abs() < 1e-5, "{t}");
        assert!((time_at_share(0.5, 20.0, t, 5.0, 2.0) - 3.25).abs() < 1e-4);
        assert_eq!(time_at_share(0.0, 20.0, t, 5.0, 2.0), 0.0);
        assert!((time_at_share(1.0, 20.0, t, 5.0, 2.0) - t).abs() < 1e-4);
        // too short to reach 5 m/s: a triangle
        let t = transition_s(2.0, 5.0, 2.0);
        assert!((t - 2.0).abs() < 1e-5, "{t}");
    }
}
