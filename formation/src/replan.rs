//! Runtime faults feed the same loop: a vehicle lost in flight (its process killed, its
//! link silent) or stuck off its slot leaves the formation, and the rest of the program is
//! planned again for the vehicles that remain, from where they are: validated, checked,
//! flown in simulation and repaired like any program ([`plan_program`]). If nothing valid
//! comes of it, the remaining vehicles land where they are (that, too, only once checked);
//! if even that is unsafe, the outcome says so and the caller holds them.
//!
//! The rest of a program, for vehicles already in the air, starts with a take-off to the
//! formation's height (validation wants one first; from the air it is a climb or descent
//! to a common height), then the shape the formation was in or going to, then the phases
//! that were not flown yet: an interrupted `assume` is flown again, an interrupted `hold`
//! or `move` again after the formation's last shape is taken up where it is.

use crate::check::{CheckError, phase_description};
use crate::repair::{PlanOutcome, Problem, Simulation, plan_program};
use aeris_schemas::{
    FormationLimits, FormationPhase, FormationProgram, MAX_PHASES, MAX_VEHICLES, PhaseKind,
};

/// What happened to a vehicle in flight.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RuntimeFault {
    /// Vehicle `vehicle` (0-based) is gone: its process exited or its link is silent.
    Lost {
        /// The vehicle (0-based).
        vehicle: usize,
    },
    /// Vehicle `vehicle` (0-based) did not reach its slot in time.
    OffSlot {
        /// The vehicle (0-based).
        vehicle: usize,
        /// How far from its slot it was (m).
        error_m: f32,
    },
}

impl RuntimeFault {
    /// The vehicle that leaves the formation (0-based).
    pub fn vehicle(&self) -> usize {
        match *self {
            Self::Lost { vehicle } | Self::OffSlot { vehicle, .. } => vehicle,
        }
    }
}

/// A runtime fault, where it happened: what the formation role is told, and what a
/// language-model variant repairs from.
#[derive(Debug, Clone, PartialEq)]
pub struct FaultDiagnosis {
    /// The fault.
    pub fault: RuntimeFault,
    /// The phase flown when it happened (1-based).
    pub phase: usize,
    /// What that phase does.
    pub during: String,
}

impl core::fmt::Display for FaultDiagnosis {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self.fault {
            RuntimeFault::Lost { vehicle } => write!(
                f,
                "vehicle {} was lost during {} (phase {}); the others go on without it",
                vehicle + 1,
                self.during,
                self.phase
            ),
            RuntimeFault::OffSlot { vehicle, error_m } => write!(
                f,
                "vehicle {} could not reach its slot in {} (phase {}; still {error_m:.1} m \
                 off); the others go on without it",
                vehicle + 1,
                self.during,
                self.phase
            ),
        }
    }
}

/// The result of planning again after a fault.
#[derive(Debug, Clone, PartialEq)]
pub struct Replanned {
    /// What happened.
    pub diagnosis: FaultDiagnosis,
    /// The vehicles that remain, by their index in the old program (0-based); the new
    /// program's vehicle `k` is `remaining[k]`.
    pub remaining: Vec<usize>,
    /// The rest of the program as first written for them (before repairs).
    pub rest: FormationProgram,
    /// How it came out: accepted (perhaps repaired), or refused with the last problem.
    pub outcome: PlanOutcome,
    /// `true` when the rest could not be flown and the outcome is the landing where they
    /// are.
    pub landing: bool,
}

/// Why no plan could be made at all.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReplanError {
    /// The interrupted phase is not a phase of the program.
    #[error("phase {phase} is not one of the program's {count}")]
    Phase {
        /// The phase given (1-based).
        phase: usize,
        /// The program's phases.
        count: usize,
    },
    /// The faulty vehicle is not one of the program's.
    #[error("vehicle {vehicle} is not one of the program's {vehicles}")]
    Vehicle {
        /// The vehicle (1-based).
        vehicle: usize,
        /// The program's vehicles.
        vehicles: usize,
    },
    /// Fewer positions than the program's vehicles.
    #[error("{positions} positions for {vehicles} vehicles")]
    Positions {
        /// Positions given.
        positions: usize,
        /// The program's vehicles.
        vehicles: usize,
    },
    /// No vehicle would remain.
    #[error("no vehicle remains")]
    NoneLeft,
    /// The check itself failed.
    #[error("checking the new program")]
    Check(#[from] CheckError),
}

fn phase_of(kind: PhaseKind) -> FormationPhase {
    FormationPhase {
        kind: kind as u8,
        ..FormationPhase::default()
    }
}

/// The rest of `program` for `vehicles` vehicles already in the air at about `height_m`,
/// from phase `interrupted` (1-based) on (see the module); `None` when it would not fit
/// in [`MAX_PHASES`] or `interrupted` is not a phase.
pub fn rest_of_program(
    program: &FormationProgram,
    interrupted: usize,
    vehicles: usize,
    height_m: f32,
    centre: [f32; 2],
) -> Option<FormationProgram> {
    let phases = program.phases();
    let k = interrupted.checked_sub(1).filter(|k| *k < phases.len())?;
    let kind = PhaseKind::from_u8(phases[k].kind)?;
    let last_shape = phases[..=k]
        .iter()
        .rev()
        .find(|p| p.kind == PhaseKind::Assume as u8);
    let formation_height = match kind {
        PhaseKind::TakeOff => phases[k].height_m,
        // landing already: from where they are
        PhaseKind::Land => height_m,
        _ => last_shape.map_or(height_m, |s| s.height_m),
    };
    let mut out: Vec<FormationPhase> = vec![FormationPhase {
        height_m: formation_height,
        ..phase_of(PhaseKind::TakeOff)
    }];
    match kind {
        PhaseKind::TakeOff => out.extend_from_slice(&phases[k + 1..]),
        PhaseKind::Land => out.push(phase_of(PhaseKind::Land)),
        PhaseKind::Assume => out.extend_from_slice(&phases[k..]),
        PhaseKind::Hold | PhaseKind::Move => {
            let mut shape = *last_shape?;
            if kind == PhaseKind::Move {
                // taken up where the formation is, then the move flown again
                shape.centre = centre;
            }
            out.push(shape);
            out.extend_from_slice(&phases[k..]);
        }
    }
    if out.len() > MAX_PHASES {
        return None;
    }
    let mut rest = FormationProgram {
        vehicles: vehicles as u8,
        phase_count: out.len() as u8,
        ..*program
    };
    rest.phases = [FormationPhase::default(); MAX_PHASES];
    rest.phases[..out.len()].copy_from_slice(&out);
    Some(rest)
}

/// A program in flight: where it is.
#[derive(Debug, Clone, Copy)]
pub struct InFlight<'a> {
    /// The program flown.
    pub program: &'a FormationProgram,
    /// The phase flown (1-based).
    pub phase: usize,
    /// Every vehicle's position, by its index in the program.
    pub positions: &'a [[f32; 3]],
}

/// Plan again after `fault` in `flight`: the rest of the program for the vehicles that
/// remain, through [`plan_program`] with `repair`; if it is refused, their landing where
/// they are.
pub fn replan_after_fault(
    flight: &InFlight<'_>,
    fault: RuntimeFault,
    limits: &FormationLimits,
    simulation: &Simulation,
    max_repairs: usize,
    repair: impl FnMut(&FormationProgram, &Problem) -> Option<FormationProgram>,
) -> Result<Replanned, ReplanError> {
    let InFlight {
        program,
        phase: interrupted,
        positions,
    } = *flight;
    let n = program.vehicles as usize;
    let count = program.phases().len();
    if interrupted == 0 || interrupted > count {
        return Err(ReplanError::Phase {
            phase: interrupted,
            count,
        });
    }
    let lost = fault.vehicle();
    if lost >= n {
        return Err(ReplanError::Vehicle {
            vehicle: lost + 1,
            vehicles: n,
        });
    }
    if positions.len() < n {
        return Err(ReplanError::Positions {
            positions: positions.len(),
            vehicles: n,
        });
    }
    let remaining: Vec<usize> = (0..n.min(MAX_VEHICLES)).filter(|v| *v != lost).collect();
    if remaining.is_empty() {
        return Err(ReplanError::NoneLeft);
    }
    let starts: Vec<[f32; 3]> = remaining.iter().map(|v| positions[*v]).collect();
    let m = starts.len() as f32;
    let centre = [
        starts.iter().map(|p| p[0]).sum::<f32>() / m,
        starts.iter().map(|p| p[1]).sum::<f32>() / m,
    ];
    // (max/min, not clamp: limits that are not coherent must not panic here; validation
    // refuses them)
    let height = (starts.iter().map(|p| p[2]).sum::<f32>() / m)
        .max(limits.h_min)
        .min(limits.h_max);
    let diagnosis = FaultDiagnosis {
        fault,
        phase: interrupted,
        during: phase_description(&program.phases()[interrupted - 1]),
    };
    let land_here = |height: f32| {
        let mut p = FormationProgram {
            vehicles: remaining.len() as u8,
            phase_count: 2,
            ..*program
        };
        p.phases = [FormationPhase::default(); MAX_PHASES];
        p.phases[0] = FormationPhase {
            height_m: height,
            ..phase_of(PhaseKind::TakeOff)
        };
        p.phases[1] = phase_of(PhaseKind::Land);
        p
    };
    let rest = rest_of_program(program, interrupted, remaining.len(), height, centre)
        .unwrap_or_else(|| land_here(height));
    let outcome = plan_program(&rest, &starts, limits, simulation, max_repairs, repair)?;
    if matches!(outcome, PlanOutcome::Accepted { .. }) {
        return Ok(Replanned {
            diagnosis,
            remaining,
            rest,
            outcome,
            landing: false,
        });
    }
    // the rest cannot be flown: land where they are, if that is safe
    let landing = land_here(height);
    let outcome = plan_program(&landing, &starts, limits, simulation, 0, |_, _| None)?;
    Ok(Replanned {
        diagnosis,
        remaining,
        rest,
        outcome,
        landing: true,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::parse::parse_instruction;

    fn kinds(p: &FormationProgram) -> Vec<PhaseKind> {
        p.phases()
            .iter()
            .map(|ph| PhaseKind::from_u8(ph.kind).unwrap())
            .collect()
    }

    fn issue_program() -> FormationProgram {
        parse_instruction(
            "four drones take off to 5 m in a line 3 m apart, then form a V heading north, \
             hold 10 s, then a circle of radius 6 m, and land",
            &FormationLimits::default(),
        )
        .unwrap()
    }

    #[test]
    fn the_rest_starts_in_the_air_with_the_shape_it_was_in() {
        use PhaseKind::*;
        let p = issue_program();
        // during the change to the circle: the circle again, then land
        let rest = rest_of_program(&p, 5, 3, 5.0, [0.0, 0.0]).unwrap();
        assert_eq!(kinds(&rest), [TakeOff, Assume, Land]);
        assert_eq!(rest.vehicles, 3);
        assert_eq!(rest.phases[0].height_m, 5.0);
        assert_eq!(rest.phases[1], p.phases[4]);
        // during the hold: the V taken up again, the hold, the circle, land
        let rest = rest_of_program(&p, 4, 3, 5.0, [0.0, 0.0]).unwrap();
        assert_eq!(kinds(&rest), [TakeOff, Assume, Hold, Assume, Land]);
        assert_eq!(rest.phases[1], p.phases[2]);
        // during the landing: land, from the height they are at
        let rest = rest_of_program(&p, 6, 3, 3.0, [0.0, 0.0]).unwrap();
        assert_eq!(kinds(&rest), [TakeOff, Land]);
        assert_eq!(rest.phases[0].height_m, 3.0);
        assert!(rest.validate(&FormationLimits::default()).is_ok());
        assert!(rest_of_program(&p, 7, 3, 3.0, [0.0, 0.0]).is_none());
        // during a move: the shape where the formation is, then the move again
        let m = parse_instruction(
            "take off to 6 m, form a column 4 m apart heading east, move 20 m north at 3 m/s, and land",
            &FormationLimits::default(),
        )
        .unwrap();
        let rest = rest_of_program(&m, 3, 3, 6.0, [8.0, 0.5]).unwrap();
        assert_eq!(kinds(&rest), [TakeOff, Assume, Move, Land]);
        assert_eq!(rest.phases[1].centre, [8.0, 0.5]);
        assert_eq!(rest.phases[2], m.phases[2]);
    }

    #[test]
    fn bad_arguments_are_named() {
        let p = issue_program();
        let limits = FormationLimits::default();
        let at = [[0.0, 0.0, 5.0]; 4];
        let replan = |fault, phase, positions: &[[f32; 3]]| {
            replan_after_fault(
                &InFlight {
                    program: &p,
                    phase,
                    positions,
                },
                fault,
                &limits,
                &Simulation::default(),
                0,
                |_, _| None,
            )
        };
        let lost = |vehicle| RuntimeFault::Lost { vehicle };
        assert!(matches!(
            replan(lost(0), 9, &at),
            Err(ReplanError::Phase { phase: 9, count: 6 })
        ));
        assert!(matches!(
            replan(lost(4), 2, &at),
            Err(ReplanError::Vehicle { vehicle: 5, .. })
        ));
        assert!(matches!(
            replan(lost(0), 2, &at[..2]),
            Err(ReplanError::Positions { positions: 2, .. })
        ));
    }

    #[test]
    fn vehicles_left_too_close_to_fly_on_are_refused_even_their_landing() {
        let limits = FormationLimits::default();
        let p = issue_program();
        // vehicles 1 and 2 a metre apart, at 5 m; vehicle 3 lost
        let at = [
            [0.0, 0.0, 5.0],
            [0.0, 1.0, 5.0],
            [0.0, 20.0, 5.0],
            [0.0, -20.0, 5.0],
        ];
        let r = replan_after_fault(
            &InFlight {
                program: &p,
                phase: 5,
                positions: &at,
            },
            RuntimeFault::Lost { vehicle: 2 },
            &limits,
            &Simulation::default(),
            2,
            |_, _| None,
        )
        .unwrap();
        assert_eq!(r.remaining, [0, 1, 3]);
        assert!(r.landing);
        assert!(
            matches!(r.outcome, PlanOutcome::Refused { .. }),
            "{}",
            r.outcome.summary()
        );
        assert_eq!(
            r.diagnosis.to_string(),
            "vehicle 3 was lost during the change to a circle (phase 5); the others go on \
             without it"
        );
    }
}
