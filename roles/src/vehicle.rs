//! The vehicle role (kind `vehicle`, variant `sim-multirotor`): the built-in simulated
//! multirotor behind a PX4-like MAVLink endpoint ([`aeris_sim::mav_vehicle::SimVehicle`]).
//!
//! Parameters (`params` of the [`aeris_runtime::RoleSpec`]):
//! - `listen`: MAVLink URL the vehicle serves (e.g. `udpin:127.0.0.1:14600`), default
//!   [`DEFAULT_LISTEN`]; the controller's `autopilot` URL points at it.
//!
//! The vehicle starts at `mission.start` (armed and holding when the start is in the air),
//! and every cycle (period 10 ms) steps the physics by the measured time since the last
//! cycle (at most 0.1 s per step, so a stalled process does not teleport the vehicle).
//!
//! Heartbeat [`CycleReport`]: stage `step`; counters
//! `[steps, missed, commands, setpoints, setpoints_rejected, armed, mode, messages_sent]`
//! where armed is 0/1 and mode is 1 position, 2 hold, 3 offboard, 4 land.

use aeris_runtime::clock::monotonic_ns;
use aeris_runtime::{CycleOutcome, CycleReport, Role, RoleContext, RoleError};
use aeris_sim::mav_vehicle::{SimVehicle, SimVehicleConfig};
use std::time::Duration;

/// URL served when the spec gives no `listen` parameter.
pub const DEFAULT_LISTEN: &str = "udpin:127.0.0.1:14600";

/// Physics period.
pub const VEHICLE_PERIOD: Duration = Duration::from_millis(10);

/// The simulated vehicle as a role process.
#[derive(Debug)]
pub struct VehicleRole {
    sim: SimVehicle,
    last_ns: u64,
}

impl VehicleRole {
    /// The simulated vehicle.
    pub fn sim(&self) -> &SimVehicle {
        &self.sim
    }
}

impl Role for VehicleRole {
    fn new(ctx: &mut RoleContext) -> Result<Self, RoleError> {
        let spec = &ctx.spec;
        let url = match spec.params.get("listen") {
            None => DEFAULT_LISTEN,
            Some(v) => v
                .as_str()
                .ok_or_else(|| RoleError::Config("param `listen` must be a string".into()))?,
        };
        let config = SimVehicleConfig {
            start: spec.mission.start,
            ..SimVehicleConfig::default()
        };
        let sim = SimVehicle::start(url, config)
            .map_err(|e| RoleError::Config(format!("simulated vehicle: {e}")))?;
        Ok(Self {
            sim,
            last_ns: monotonic_ns(),
        })
    }

    fn period(&self) -> Duration {
        VEHICLE_PERIOD
    }

    fn cycle(
        &mut self,
        ctx: &mut RoleContext,
        report: &mut CycleReport,
    ) -> Result<CycleOutcome, RoleError> {
        let now = monotonic_ns();
        let dt = now.saturating_sub(self.last_ns) as f64 * 1e-9;
        self.last_ns = now;
        self.sim.step(dt as f32);
        let st = self.sim.stats();
        report.stage("step", monotonic_ns().saturating_sub(now));
        report.counters = [
            st.steps,
            ctx.missed_deadlines,
            st.commands,
            st.setpoints,
            st.setpoints_rejected,
            u64::from(self.sim.state().armed),
            self.sim.mode().index(),
            st.messages_sent,
        ];
        Ok(CycleOutcome::Worked)
    }

    fn shutdown(&mut self, _ctx: &mut RoleContext) {
        self.sim.shutdown();
    }
}
