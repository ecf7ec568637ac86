//! The gate for formation programs: what the hub's decision gate is to D_t, for the
//! programs a formation role flies and the slots it sends each vehicle.
//!
//! - [`ProgramGate::for_flight`]: the flight's limits (the same [`DecisionLimits`] every
//!   D_t is gated against: altitude band, speed, geofence) as a formation's, for its
//!   vehicles and minimum separation;
//! - [`ProgramGate::admit`]: a program flies only when valid under them (deterministic,
//!   [`FormationProgram::validate`]); whether its vehicles keep apart is the simulation's
//!   check, which runs on the same limits;
//! - [`ProgramGate::bind_slot`]: one vehicle's slot bound to a [`BoundSetpoint`] for its
//!   controller (a goto to the slot at the flight's top speed, or a landing over it) and
//!   checked as the controller will check it, so nothing is sent that a controller would
//!   refuse: an unfit slot is not sent, and that controller holds.
//!
//! Pure functions; [`ProgramGate::bind_slot`] does not allocate.

use aeris_schemas::{
    ActionMode, BoundSetpoint, DecisionLimits, FormationError, FormationLimits, FormationProgram,
    SetpointError,
};

/// The flight's limits, as a formation's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProgramGate {
    decision: DecisionLimits,
    formation: FormationLimits,
}

/// Why a flight has no room for a formation.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error(
    "the flight's limits leave no room for a formation of {vehicles} vehicles {min_separation_m} m apart \
     (altitude {h_min}-{h_max} m, speed {v_max} m/s)"
)]
pub struct NoRoom {
    /// The vehicles.
    pub vehicles: u8,
    /// The separation asked for (m).
    pub min_separation_m: f32,
    /// The band's bottom, as a formation's (m).
    pub h_min: f32,
    /// Its top (m).
    pub h_max: f32,
    /// The top speed (m/s).
    pub v_max: f32,
}

impl ProgramGate {
    /// The gate of a flight with `decision` limits for `vehicles` vehicles never closer than
    /// `min_separation_m`: the formation defaults ([`FormationLimits::default`]) narrowed to
    /// the flight's band, speed and geofence.
    pub fn for_flight(
        decision: &DecisionLimits,
        vehicles: u8,
        min_separation_m: f32,
    ) -> Result<Self, NoRoom> {
        let d = FormationLimits::default();
        let formation = FormationLimits {
            vehicles,
            h_min: decision.h_min.max(decision.geofence_min[2]).max(d.h_min),
            h_max: decision.h_max.min(decision.geofence_max[2]).min(d.h_max),
            min_separation_m,
            v_max: decision.v_max.min(d.v_max),
            geofence_min: [decision.geofence_min[0], decision.geofence_min[1]],
            geofence_max: [decision.geofence_max[0], decision.geofence_max[1]],
            ..d
        };
        if !formation.is_coherent() {
            return Err(NoRoom {
                vehicles,
                min_separation_m,
                h_min: formation.h_min,
                h_max: formation.h_max,
                v_max: formation.v_max,
            });
        }
        Ok(Self {
            decision: *decision,
            formation,
        })
    }

    /// The formation limits programs are validated and checked against.
    pub fn limits(&self) -> &FormationLimits {
        &self.formation
    }

    /// The same for `vehicles` vehicles (a formation that lost some).
    pub fn with_vehicles(&self, vehicles: u8) -> Self {
        Self {
            formation: FormationLimits {
                vehicles,
                ..self.formation
            },
            ..*self
        }
    }

    /// Admit `program`: valid under the flight's limits.
    pub fn admit(&self, program: &FormationProgram) -> Result<(), FormationError> {
        program.validate(&self.formation)
    }

    /// Vehicle's slot `position` (`[N, E, U]`) in phase `phase` (1-based), bound to the
    /// setpoint its controller flies: a goto to the slot at the flight's top speed, or, in
    /// a landing phase, a landing over it. Checked as the controller checks it.
    pub fn bind_slot(
        &self,
        position: [f32; 3],
        phase: u16,
        landing: bool,
        seq: u64,
        now_ns: u64,
    ) -> Result<BoundSetpoint, SetpointError> {
        let mode = if landing {
            ActionMode::Land
        } else {
            ActionMode::Goto
        };
        let sp = BoundSetpoint {
            seq,
            decision_seq: u64::from(phase),
            publish_ns: now_ns,
            position,
            yaw: 0.0,
            speed: self.formation.v_max,
            acceptance_radius: 0.5,
            active_step: phase,
            mode: mode as u8,
            ..BoundSetpoint::default()
        };
        sp.validate(&self.decision)?;
        Ok(sp)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gate() -> ProgramGate {
        ProgramGate::for_flight(&DecisionLimits::default(), 4, 2.0).unwrap()
    }

    #[test]
    fn the_flights_band_speed_and_fence_bound_the_formation() {
        let decision = DecisionLimits {
            h_max: 30.0,
            v_max: 5.0,
            ..DecisionLimits::default()
        };
        let g = ProgramGate::for_flight(&decision, 3, 2.5).unwrap();
        let l = g.limits();
        assert_eq!(
            (l.vehicles, l.h_max, l.v_max, l.min_separation_m),
            (3, 30.0, 5.0, 2.5)
        );
        assert_eq!(
            l.geofence_min,
            [decision.geofence_min[0], decision.geofence_min[1]]
        );
        // no band left above the formation's lowest height
        let flat = DecisionLimits {
            h_max: 1.0,
            ..DecisionLimits::default()
        };
        assert!(ProgramGate::for_flight(&flat, 3, 2.0).is_err());
        assert!(ProgramGate::for_flight(&DecisionLimits::default(), 0, 2.0).is_err());
    }

    #[test]
    fn a_slot_outside_the_fence_or_not_finite_is_not_bound() {
        let g = gate();
        let inside = g.bind_slot([1.0, 2.0, 5.0], 2, false, 7, 100).unwrap();
        assert_eq!(inside.mode, ActionMode::Goto as u8);
        assert_eq!((inside.seq, inside.active_step), (7, 2));
        let land = g.bind_slot([1.0, 2.0, 0.0], 6, true, 8, 100).unwrap();
        assert_eq!(land.mode, ActionMode::Land as u8);
        let far = DecisionLimits::default().geofence_max[0] + 10.0;
        assert!(g.bind_slot([far, 0.0, 5.0], 2, false, 9, 100).is_err());
        assert!(g.bind_slot([f32::NAN, 0.0, 5.0], 2, false, 9, 100).is_err());
    }
}
