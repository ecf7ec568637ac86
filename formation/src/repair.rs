//! Validated in simulation, repaired on failure: the loop a formation program goes through
//! before anything flies.
//!
//! [`plan_program`] validates the program, checks its transitions exactly
//! ([`check_program`]) and flies them with the vehicle model ([`fly_trajectory`]);
//! a [`Problem`] (invalid, or unsafe with its [`Diagnosis`]) goes to a repairer with the
//! program, at most `max_repairs` times. The result is accepted as asked, accepted after k
//! repairs, or refused with the last problem: never flown unsafely.
//!
//! [`repair_by_rule`] is the deterministic repairer (the parser variant's): it widens a
//! shape whose vehicles come too close, lifts a height into the band, pulls a move back
//! inside the geofence, and gives up on what it cannot mend (too many vehicles, vehicles
//! too close on the ground). The language-model variant repairs from the problem's text.

use crate::assign::closest_approach;
use crate::check::{CheckError, CheckReport, Diagnosis, Dynamics, Violation, check_program};
use crate::flown::{FlownConfig, FlownReport, flown_diagnosis, fly_trajectory};
use crate::slots::slots;
use aeris_schemas::{
    FormationError, FormationLimits, FormationProgram, MAX_PHASES, MAX_VEHICLES, PhaseKind,
    ShapeKind,
};

/// What is wrong with a program.
#[derive(Debug, Clone, PartialEq)]
pub enum Problem {
    /// It fails validation.
    Invalid(FormationError),
    /// It flies into a violation.
    Unsafe(Diagnosis),
}

impl core::fmt::Display for Problem {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Invalid(e) => write!(f, "invalid: {e}"),
            Self::Unsafe(d) => write!(f, "unsafe: {d}"),
        }
    }
}

impl std::error::Error for Problem {}

/// How a program came out of [`plan_program`].
#[derive(Debug, Clone, PartialEq)]
pub enum PlanOutcome {
    /// Flies as it is (after `repairs` repairs; 0: as asked), with its simulation.
    Accepted {
        /// The program to fly.
        program: Box<FormationProgram>,
        /// Its check: the transitions as planned, and their trajectory.
        report: CheckReport,
        /// Its flight by the vehicle model (`None` when none was given).
        flown: Option<Box<FlownReport>>,
        /// The problems repaired on the way, in order.
        repaired: Vec<Problem>,
    },
    /// No program to fly: the last problem, and those repaired before it.
    Refused {
        /// Why the last program could not fly.
        problem: Problem,
        /// The problems repaired before, in order.
        repaired: Vec<Problem>,
    },
}

impl PlanOutcome {
    /// One line for a person: accepted, repaired after k attempts (the problems are in
    /// `repaired`), or refused and why.
    pub fn summary(&self) -> String {
        match self {
            Self::Accepted { repaired, .. } if repaired.is_empty() => "accepted".into(),
            Self::Accepted { repaired, .. } => format!(
                "repaired after {} attempt{}",
                repaired.len(),
                if repaired.len() == 1 { "" } else { "s" },
            ),
            Self::Refused { problem, .. } => format!("refused: {problem}"),
        }
    }
}

/// How a program is simulated before it flies: its transitions checked exactly against
/// kinematic limits, then (when a vehicle model is given) flown by that model.
#[derive(Debug, Clone, Copy, Default)]
pub struct Simulation {
    /// The limits the exact check of the transitions plans with.
    pub dynamics: Dynamics,
    /// The vehicle model that then flies the planned trajectory; `None`: the exact check
    /// alone (a build without the simulator).
    pub flight: Option<FlownConfig>,
}

/// Validate `program`, fly it in simulation from `starts`, and hand each problem to
/// `repair` (with the program), at most `max_repairs` times. A repair that returns `None`
/// gives up: the program is refused with that problem.
pub fn plan_program(
    program: &FormationProgram,
    starts: &[[f32; 3]],
    limits: &FormationLimits,
    simulation: &Simulation,
    max_repairs: usize,
    mut repair: impl FnMut(&FormationProgram, &Problem) -> Option<FormationProgram>,
) -> Result<PlanOutcome, CheckError> {
    let mut program = *program;
    let mut repaired = Vec::new();
    loop {
        let problem = match check_program(&program, starts, limits, &simulation.dynamics) {
            Ok(report) => match report.diagnosis.clone() {
                None => {
                    let flown = match &simulation.flight {
                        Some(config) => Some(
                            fly_trajectory(&report.trajectory, starts, config)
                                .ok_or(CheckError::Dynamics)?,
                        ),
                        None => None,
                    };
                    match flown
                        .as_ref()
                        .and_then(|f| flown_diagnosis(f, &program, limits))
                    {
                        None => {
                            return Ok(PlanOutcome::Accepted {
                                program: Box::new(program),
                                report,
                                flown: flown.map(Box::new),
                                repaired,
                            });
                        }
                        Some(d) => Problem::Unsafe(d),
                    }
                }
                Some(d) => Problem::Unsafe(d),
            },
            Err(CheckError::Invalid(e)) => Problem::Invalid(e),
            Err(other) => return Err(other),
        };
        if repaired.len() >= max_repairs {
            return Ok(PlanOutcome::Refused { problem, repaired });
        }
        match repair(&program, &problem) {
            Some(next) if next != program => {
                program = next;
                repaired.push(problem);
            }
            _ => return Ok(PlanOutcome::Refused { problem, repaired }),
        }
    }
}

/// The nearest two slots of an `assume` phase for `n` vehicles (m).
fn nearest_slots(program: &FormationProgram, phase: usize) -> Option<f32> {
    let n = (program.vehicles as usize).min(MAX_VEHICLES);
    let s = slots(&program.phases[phase], n)?;
    closest_approach(&s[..n], &s[..n]).map(|c| c.distance_m)
}

/// The deterministic repair of `problem` in `program` under `limits` (see the module);
/// `None` when it cannot be mended.
pub fn repair_by_rule(
    program: &FormationProgram,
    problem: &Problem,
    limits: &FormationLimits,
) -> Option<FormationProgram> {
    let mut p = *program;
    match problem {
        Problem::Invalid(FormationError::OutOfRange {
            phase,
            field,
            min,
            max,
            ..
        }) => {
            let ph = p.phases.get_mut(phase.checked_sub(1)?)?;
            let slot = match *field {
                "height" => &mut ph.height_m,
                "spacing" => &mut ph.spacing_m,
                "hold" => &mut ph.hold_s,
                "speed" => &mut ph.speed_mps,
                "centre.n" => &mut ph.centre[0],
                "centre.e" => &mut ph.centre[1],
                _ => return None,
            };
            *slot = slot.clamp(*min, *max);
            Some(p)
        }
        Problem::Invalid(FormationError::LastNotLand(_))
            if (p.phase_count as usize) < MAX_PHASES =>
        {
            let i = p.phase_count as usize;
            p.phases[i] = aeris_schemas::FormationPhase {
                kind: PhaseKind::Land as u8,
                ..Default::default()
            };
            p.phase_count += 1;
            Some(p)
        }
        Problem::Invalid(_) => None,
        Problem::Unsafe(d) => {
            let index = d.phase.checked_sub(1)?;
            let kind = PhaseKind::from_u8(p.phases.get(index)?.kind)?;
            match (&d.violation, kind) {
                (Violation::TooClose { .. }, PhaseKind::Assume) => {
                    // widen the shape until its nearest slots are sqrt(2) times the minimum
                    // apart: straight synchronised transitions then keep the minimum (CAPT)
                    let want = limits.min_separation_m * core::f32::consts::SQRT_2 * 1.01;
                    let nearest = nearest_slots(&p, index)?;
                    let ph = &mut p.phases[index];
                    if ph.shape == ShapeKind::Offsets as u8 || nearest <= 0.0 {
                        return None;
                    }
                    let wider = ph.spacing_m * (want / nearest).max(1.05);
                    if wider > limits.max_spacing_m {
                        return None;
                    }
                    ph.spacing_m = wider;
                    Some(p)
                }
                (Violation::Altitude { .. }, _) => {
                    let ph = &mut p.phases[index];
                    ph.height_m = ph.height_m.clamp(limits.h_min, limits.h_max);
                    Some(p)
                }
                (Violation::OutsideGeofence { at, .. }, PhaseKind::Move) => {
                    // pull the move's centre back by how far the slot is outside
                    let ph = &mut p.phases[index];
                    for (k, c) in ph.centre.iter_mut().enumerate() {
                        let over = (at[k] - limits.geofence_max[k]).max(0.0)
                            - (limits.geofence_min[k] - at[k]).max(0.0);
                        *c -= over * 1.01;
                    }
                    Some(p)
                }
                // vehicles too close on the ground, a shape off the geofence: not mendable
                // by rule
                _ => None,
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::parse::parse_instruction;

    fn plan(text: &str, limits: &FormationLimits, starts: &[[f32; 3]]) -> PlanOutcome {
        let p = parse_instruction(text, limits).unwrap();
        plan_program(
            &p,
            starts,
            limits,
            &Simulation::default(),
            3,
            |p, problem| repair_by_rule(p, problem, limits),
        )
        .unwrap()
    }

    fn row(n: usize) -> Vec<[f32; 3]> {
        (0..n).map(|i| [0.0, 4.0 * i as f32, 0.0]).collect()
    }

    #[test]
    fn a_sound_program_is_accepted_as_asked() {
        let limits = FormationLimits::default();
        let out = plan(
            "four drones take off to 5 m in a line 3 m apart, then form a V heading north, \
             hold 10 s, then a circle of radius 6 m, and land",
            &limits,
            &row(4),
        );
        assert_eq!(out.summary(), "accepted");
    }

    #[test]
    fn spacing_below_the_minimum_is_repaired_and_then_flies_clear() {
        let limits = FormationLimits::default();
        let out = plan("take off to 5 m, a line 1 m apart, land", &limits, &row(4));
        let PlanOutcome::Accepted {
            program,
            report,
            repaired,
            ..
        } = &out
        else {
            panic!("{}", out.summary());
        };
        assert!(!repaired.is_empty());
        assert!(
            out.summary().starts_with("repaired after"),
            "{}",
            out.summary()
        );
        assert!(program.phases[1].spacing_m >= limits.min_separation_m);
        assert!(report.min_separation_m >= limits.min_separation_m);
        // eight on a circle of radius 2 m (neighbours 1.5 m apart): widened until it flies
        let limits8 = FormationLimits {
            vehicles: 8,
            ..limits
        };
        let out = plan(
            "eight drones take off, a circle of radius 2 m, land",
            &limits8,
            &row(8),
        );
        let PlanOutcome::Accepted {
            program,
            report,
            repaired,
            ..
        } = &out
        else {
            panic!("{}", out.summary());
        };
        assert!(matches!(repaired[0], Problem::Unsafe(_)), "{repaired:?}");
        assert!(program.phases[1].spacing_m > 2.0);
        assert!(
            report.min_separation_m >= limits.min_separation_m,
            "{report:?}"
        );
    }

    #[test]
    fn what_cannot_be_mended_is_refused_with_the_diagnosis() {
        let limits = FormationLimits::default();
        // more vehicles than the flight has
        let out = plan("six drones take off, a circle, land", &limits, &row(6));
        assert!(
            matches!(
                &out,
                PlanOutcome::Refused {
                    problem: Problem::Invalid(FormationError::Vehicles { .. }),
                    ..
                }
            ),
            "{}",
            out.summary()
        );
        assert!(out.summary().contains("6 vehicles"), "{}", out.summary());
        // vehicles too close on the ground: never flown
        let mut starts = row(4);
        starts[1] = [0.0, 1.0, 0.0];
        let out = plan("take off, a line 3 m apart, land", &limits, &starts);
        assert!(
            out.summary()
                .starts_with("refused: unsafe: vehicles 1 and 2 come within 1.0 m"),
            "{}",
            out.summary()
        );
        // a repairer that keeps failing is stopped after max_repairs
        let p = parse_instruction("take off, a line 1 m apart, land", &limits).unwrap();
        let mut calls = 0;
        let out = plan_program(&p, &row(4), &limits, &Simulation::default(), 2, |p, _| {
            calls += 1;
            let mut q = *p;
            q.phases[1].spacing_m = 1.0 - 0.1 * calls as f32;
            Some(q)
        })
        .unwrap();
        assert_eq!(calls, 2);
        assert!(matches!(out, PlanOutcome::Refused { ref repaired, .. } if repaired.len() == 2));
    }
}
