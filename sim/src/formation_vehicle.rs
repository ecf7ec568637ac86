//! The built-in multirotor as the vehicle model of a formation program's simulated flight
//! ([`aeris_formation::flown`]): each vehicle tracks its slot as the controller's offboard
//! setpoint (position with velocity feed-forward), within the multirotor's speed and
//! acceleration limits.

use crate::multirotor::{Command, MultirotorModel, MultirotorParams};
use aeris_formation::{FlownConfig, Simulation, Slot, VehicleModel};

impl VehicleModel for MultirotorModel {
    fn step(&mut self, dt: f32, slot: &Slot) {
        let moving = slot.velocity.iter().any(|v| v.abs() > 1e-3);
        MultirotorModel::step(
            self,
            dt,
            &Command::Position {
                position: slot.position,
                velocity_ff: moving.then_some(slot.velocity),
                yaw: None,
                yaw_rate: None,
            },
        );
    }

    fn position(&self) -> [f32; 3] {
        self.state().position
    }
}

/// The built-in multirotor (default parameters), armed, at rest at `start`.
pub fn multirotor(start: [f32; 3]) -> Box<dyn VehicleModel> {
    let mut m = MultirotorModel::new(MultirotorParams::default(), start, 0.0);
    m.set_armed(true);
    Box::new(m)
}

/// A program's simulation with the built-in multirotor: the exact check of the
/// transitions, then the vehicles flying them at 50 Hz.
pub fn multirotor_simulation() -> Simulation {
    Simulation {
        flight: Some(FlownConfig::new(multirotor)),
        ..Simulation::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use aeris_formation::{
        Dynamics, ExecutorState, check_program, fly_trajectory, parse_instruction, slots,
    };
    use aeris_schemas::{FormationLimits, PhaseKind};

    fn distance(a: [f32; 3], b: [f32; 3]) -> f32 {
        ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
    }

    fn starts() -> Vec<[f32; 3]> {
        (0..4).map(|i| [0.0, -6.0 + 4.0 * i as f32, 0.0]).collect()
    }

    /// The issue's program (line, V, hold, circle, land) for four vehicles from [`starts`],
    /// and its exact check.
    fn issue_program_checked(
        limits: &FormationLimits,
    ) -> (
        aeris_schemas::FormationProgram,
        aeris_formation::CheckReport,
    ) {
        let program = parse_instruction(
            "four drones take off to 5 m in a line 3 m apart, then form a V heading north, \
             hold 10 s, then a circle of radius 6 m, and land",
            limits,
        )
        .unwrap();
        let checked = check_program(&program, &starts(), limits, &Dynamics::default()).unwrap();
        (program, checked)
    }

    #[test]
    fn four_vehicles_fly_line_v_circle_and_land_reaching_every_slot_apart() {
        let limits = FormationLimits::default();
        let (program, checked) = issue_program_checked(&limits);
        assert!(checked.accepted());
        let config = FlownConfig::new(multirotor);
        let flown = fly_trajectory(&checked.trajectory, &starts(), &config).unwrap();
        assert_eq!(
            flown.end,
            ExecutorState::Done,
            "{:?}",
            flown.settled_after_s
        );
        // every phase settled: every vehicle within tolerance of every slot
        assert_eq!(flown.settled_after_s.len(), program.phases().len());
        let closest = flown.closest.unwrap();
        assert!(
            closest.distance_m >= limits.min_separation_m,
            "vehicles {} and {} came within {:.2} m at {:.1} s",
            closest.a,
            closest.b,
            closest.distance_m,
            closest.at_s
        );
        // the tracks pass through each shape's slots, and end on the ground
        for (index, phase) in program.phases().iter().enumerate() {
            if phase.kind != PhaseKind::Assume as u8 {
                continue;
            }
            let want = slots(phase, 4).unwrap();
            let end = &checked.ends[index];
            for (v, slot) in end.iter().enumerate().take(4) {
                assert!(want[..4].contains(slot));
                let reached = flown.tracks.iter().any(|p| {
                    p.phase == index + 1
                        && distance(p.positions[v], *slot) <= config.tolerance.distance_m
                });
                assert!(
                    reached,
                    "vehicle {} never at its slot of phase {}",
                    v + 1,
                    index + 1
                );
            }
        }
        let last = flown.tracks.last().unwrap();
        assert!(last.positions[..4].iter().all(|p| p[2] < 0.5), "{last:?}");
        // slower than planned only by the waits for the vehicles
        let waited: f32 = flown.settled_after_s.iter().sum();
        assert!(flown.duration_s <= checked.duration_s + waited + 0.1);
    }

    /// A multirotor capped at 2 m/s, where the plan assumes 5.
    fn slow(start: [f32; 3]) -> Box<dyn VehicleModel> {
        let params = MultirotorParams {
            max_speed_h: 2.0,
            ..MultirotorParams::default()
        };
        let mut m = MultirotorModel::new(params, start, 0.0);
        m.set_armed(true);
        Box::new(m)
    }

    #[test]
    fn vehicles_too_slow_for_the_plan_lag_and_are_waited_for() {
        let limits = FormationLimits::default();
        let program = parse_instruction(
            "four drones take off to 5 m in a line 3 m apart, then a circle of radius 8 m, and land",
            &limits,
        )
        .unwrap();
        let checked = check_program(&program, &starts(), &limits, &Dynamics::default()).unwrap();
        let flown =
            fly_trajectory(&checked.trajectory, &starts(), &FlownConfig::new(slow)).unwrap();
        assert_eq!(flown.end, ExecutorState::Done);
        assert!(
            flown.max_tracking_error_m > 1.0,
            "{}",
            flown.max_tracking_error_m
        );
        assert!(flown.settled_after_s.iter().any(|s| *s > 0.5));
    }

    #[test]
    fn the_plan_loop_flies_what_it_accepts_with_the_multirotor() {
        let limits = FormationLimits::default();
        let program =
            parse_instruction("take off to 5 m, a line 1 m apart, land", &limits).unwrap();
        let out = aeris_formation::plan_program(
            &program,
            &starts(),
            &limits,
            &multirotor_simulation(),
            3,
            |p, problem| aeris_formation::repair_by_rule(p, problem, &limits),
        )
        .unwrap();
        let aeris_formation::PlanOutcome::Accepted { flown, .. } = &out else {
            panic!("{}", out.summary());
        };
        let flown = flown.as_ref().expect("flown by the multirotor");
        assert_eq!(flown.end, ExecutorState::Done);
        assert!(flown.closest.unwrap().distance_m >= limits.min_separation_m);
    }

    #[test]
    fn a_vehicle_lost_mid_formation_leaves_the_others_to_re_form_and_land() {
        use aeris_formation::{InFlight, PlanOutcome, RuntimeFault, replan_after_fault};
        let limits = FormationLimits::default();
        let (program, checked) = issue_program_checked(&limits);
        // flown until halfway through the change to the circle (phase 5)
        let circle = checked.trajectory.segments[4];
        assert_eq!(circle.phase, 5);
        let config = FlownConfig {
            stop_after_s: Some(circle.start_s + circle.duration_s / 2.0),
            ..FlownConfig::new(multirotor)
        };
        let before = fly_trajectory(&checked.trajectory, &starts(), &config).unwrap();
        assert_eq!(before.end, ExecutorState::Flying { segment: 4 });
        let at = before.tracks.last().unwrap().positions;
        // vehicle 3 is lost there: the other three take up the circle and land
        let r = replan_after_fault(
            &InFlight {
                program: &program,
                phase: 5,
                positions: &at[..4],
            },
            RuntimeFault::Lost { vehicle: 2 },
            &limits,
            &multirotor_simulation(),
            3,
            |p, problem| aeris_formation::repair_by_rule(p, problem, &limits),
        )
        .unwrap();
        assert_eq!(r.remaining, [0, 1, 3]);
        assert!(!r.landing);
        let PlanOutcome::Accepted {
            program: rest,
            report,
            flown,
            repaired,
        } = &r.outcome
        else {
            panic!("{}", r.outcome.summary());
        };
        assert_eq!(rest.vehicles, 3);
        // the circle asked for, now of three (wider only if a repair had to widen it)
        let circle = rest.phases[1];
        assert_eq!(circle.shape, program.phases[4].shape, "{repaired:?}");
        assert!(circle.spacing_m >= 6.0, "{repaired:?}");
        let flown = flown.as_ref().unwrap();
        assert_eq!(flown.end, ExecutorState::Done);
        assert!(flown.closest.unwrap().distance_m >= limits.min_separation_m);
        for (v, p) in report.ends[1].iter().take(3).enumerate() {
            let d = (p[0].powi(2) + p[1].powi(2)).sqrt();
            assert!(
                (d - circle.spacing_m).abs() < 1e-3,
                "vehicle {v} {d} m from the centre"
            );
        }
    }
}
