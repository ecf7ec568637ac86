//! The vehicle role (kind `vehicle`, variant `sim-multirotor`): the built-in simulated
//! multirotor behind a PX4- or ArduPilot-like MAVLink endpoint ([`aeris_sim::mav_vehicle::SimVehicle`]).
//!
//! Parameters (`params` of the [`aeris_runtime::RoleSpec`]):
//! - `listen`: MAVLink URL the vehicle serves (e.g. `udpin:127.0.0.1:14600`), default
//!   [`DEFAULT_LISTEN`]; the controller's `autopilot` URL points at it.
//! - `state_file`: where the vehicle checkpoints its pose every 100 ms; a restarted vehicle
//!   resumes from a checkpoint younger than [`CHECKPOINT_MAX_AGE`] instead of teleporting
//!   back to the start (the supervisor sets it to `<run dir>/<role>.state`).
//! - `mavlink`: the framing the vehicle sends, `1` or `2` (default); it receives both, so
//!   it can play an autopilot that speaks only MAVLink 1.
//! - `autopilot`: the firmware it plays, `"px4"` (default: offboard) or `"ardupilot"`
//!   (Copter: guided, take-off command, land mode); see
//!   [`aeris_sim::mav_vehicle::SimFirmware`].
//! - `signing_key_file`, `signing_link_id`: MAVLink 2 signing, as the controller's
//!   ([`aeris_roles::controller::signing_params`]);
//! - `system_id`: its MAVLink system id, 1..=255 (default 1); the controller learns it
//!   from the heartbeat.
//!
//! Every received position setpoint is checked against the mission's geofence and altitude
//! band at the MAVLink boundary (an independent check of the controller and the hub); the
//! vehicle still flies it, but counts it.
//!
//! The vehicle starts at `mission.start` (armed and holding when the start is in the air),
//! and every cycle (period 10 ms) steps the physics by the measured time since the last
//! cycle (at most 0.1 s per step, so a stalled process does not teleport the vehicle).
//!
//! Heartbeat [`CycleReport`]: stage `step`; counters [`VehicleCounters`],
//! where armed is 0/1, mode is 1 position, 2 hold, 3 offboard, 4 land, and
//! setpoint_ticks_missed counts the controller ticks (at the workflow's control rate) whose
//! setpoint never reached the vehicle: an interval between two setpoints longer than two
//! control periods counts `round(interval / period) - 1` (see
//! [`aeris_sim::mav_vehicle::SimVehicleStats::setpoint_ticks_missed`]).

use aeris_mavlink::MavlinkVersion;
use aeris_runtime::clock::monotonic_ns;
use aeris_runtime::{CycleOutcome, CycleReport, Role, RoleContext, RoleError};
use aeris_schemas::VehicleCounters;
use aeris_schemas::kinds;
use aeris_sim::mav_vehicle::{SimFirmware, SimVehicle, SimVehicleConfig};
use std::fs::File;
use std::os::unix::fs::FileExt;
use std::time::Duration;

/// URL served when the spec gives no `listen` parameter.
pub const DEFAULT_LISTEN: &str = "udpin:127.0.0.1:14600";

/// Physics period.
pub const VEHICLE_PERIOD: Duration = Duration::from_millis(10);

/// A checkpoint older than this is ignored at start (the flight it belonged to is over).
pub const CHECKPOINT_MAX_AGE: Duration = Duration::from_secs(10);

/// Cycles between checkpoints (10 ms period -> every 100 ms).
const CHECKPOINT_EVERY: u64 = 10;

const CHECKPOINT_MAGIC: u32 = 0xAE51_5701;
const CHECKPOINT_LEN: usize = 32;

/// The pose a restarted vehicle resumes from: `[magic, stamp_ns, n, e, u, yaw, checksum]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Checkpoint {
    /// CLOCK_MONOTONIC ns when written.
    pub stamp_ns: u64,
    /// Position `[N, E, U]`.
    pub position: [f32; 3],
    /// Yaw (rad).
    pub yaw: f32,
}

fn checksum(bytes: &[u8]) -> u32 {
    bytes.iter().fold(0x811C_9DC5u32, |h, b| {
        (h ^ u32::from(*b)).wrapping_mul(0x0100_0193)
    })
}

impl Checkpoint {
    /// Fixed-size little-endian encoding with a checksum (a torn write fails to decode).
    pub fn encode(&self) -> [u8; CHECKPOINT_LEN] {
        let mut b = [0u8; CHECKPOINT_LEN];
        b[0..4].copy_from_slice(&CHECKPOINT_MAGIC.to_le_bytes());
        b[4..12].copy_from_slice(&self.stamp_ns.to_le_bytes());
        for (i, v) in self
            .position
            .iter()
            .chain(core::iter::once(&self.yaw))
            .enumerate()
        {
            b[12 + 4 * i..16 + 4 * i].copy_from_slice(&v.to_le_bytes());
        }
        let c = checksum(&b[..28]);
        b[28..32].copy_from_slice(&c.to_le_bytes());
        b
    }

    /// Decode; `None` for a wrong magic, a bad checksum or non-finite numbers.
    pub fn decode(b: &[u8]) -> Option<Self> {
        let b: &[u8; CHECKPOINT_LEN] = b.get(..CHECKPOINT_LEN)?.try_into().ok()?;
        let word = |i: usize| [b[i], b[i + 1], b[i + 2], b[i + 3]];
        if u32::from_le_bytes(word(0)) != CHECKPOINT_MAGIC
            || u32::from_le_bytes(word(28)) != checksum(&b[..28])
        {
            return None;
        }
        let mut stamp = [0u8; 8];
        stamp.copy_from_slice(&b[4..12]);
        let f = |i: usize| f32::from_le_bytes(word(12 + 4 * i));
        let c = Checkpoint {
            stamp_ns: u64::from_le_bytes(stamp),
            position: [f(0), f(1), f(2)],
            yaw: f(3),
        };
        (c.position.iter().all(|v| v.is_finite()) && c.yaw.is_finite()).then_some(c)
    }
}

/// The simulated vehicle as a role process.
#[derive(Debug)]
pub struct VehicleRole {
    sim: SimVehicle,
    last_ns: u64,
    checkpoint: Option<File>,
    resumed: bool,
}

impl VehicleRole {
    /// The simulated vehicle.
    pub fn sim(&self) -> &SimVehicle {
        &self.sim
    }

    /// `true` when this process resumed from a checkpoint.
    pub fn resumed(&self) -> bool {
        self.resumed
    }
}

impl Role for VehicleRole {
    type Kind = kinds::Vehicle;

    fn new(ctx: &mut RoleContext<kinds::Vehicle>) -> Result<Self, RoleError> {
        let spec = &ctx.spec;
        let url = match spec.params.get("listen") {
            None => DEFAULT_LISTEN,
            Some(v) => v
                .as_str()
                .ok_or_else(|| RoleError::param("listen", "must be a string"))?,
        };
        let limits = &spec.mission.limits;
        let mut fence_max = limits.geofence_max;
        fence_max[2] = fence_max[2].min(limits.h_max);
        let mavlink_version = match spec.params.get("mavlink") {
            None => MavlinkVersion::V2,
            Some(v) if v.as_u64() == Some(2) => MavlinkVersion::V2,
            Some(v) if v.as_u64() == Some(1) => MavlinkVersion::V1,
            Some(v) => {
                return Err(RoleError::param(
                    "mavlink",
                    format!("= {v}: the vehicle speaks MAVLink 1 or 2"),
                ));
            }
        };
        let firmware = match spec.params.get("autopilot") {
            None => SimFirmware::Px4,
            Some(v) => v.as_str().and_then(SimFirmware::from_name).ok_or_else(|| {
                RoleError::param(
                    "autopilot",
                    format!("= {v}: the vehicle plays \"px4\" or \"ardupilot\""),
                )
            })?,
        };
        let system_id = match spec.params.get("system_id") {
            None => 1,
            Some(v) => v
                .as_u64()
                .and_then(|id| u8::try_from(id).ok())
                .filter(|&id| id > 0)
                .ok_or_else(|| RoleError::param("system_id", format!("= {v}: use 1..=255")))?,
        };
        let signing = aeris_roles::controller::signing_from_spec(spec)?;
        let mut config = SimVehicleConfig {
            mavlink_version,
            firmware,
            signing,
            system_id,
            start: spec.mission.start,
            fence: Some((limits.geofence_min, fence_max)),
            setpoint_period_s: (spec.timing.control_rate_hz > 0.0)
                .then(|| (1.0 / spec.timing.control_rate_hz) as f32),
            // on simulated time the link is read on the vehicle's own turns
            lockstep: aeris_runtime::clock::simulated(),
            ..SimVehicleConfig::default()
        };
        let state_file = match spec.params.get("state_file") {
            None => None,
            Some(v) => Some(
                v.as_str()
                    .ok_or_else(|| RoleError::param("state_file", "must be a string"))?
                    .to_string(),
            ),
        };
        let mut resumed = false;
        if let Some(path) = &state_file
            && let Ok(bytes) = std::fs::read(path)
            && let Some(c) = Checkpoint::decode(&bytes)
            && monotonic_ns().saturating_sub(c.stamp_ns) <= CHECKPOINT_MAX_AGE.as_nanos() as u64
        {
            config.start = c.position;
            config.start_yaw = c.yaw;
            resumed = true;
            tracing::info!("vehicle: resumed from checkpoint at {:?}", c.position);
        }
        let checkpoint = match &state_file {
            Some(path) => Some(
                std::fs::OpenOptions::new()
                    .create(true)
                    .write(true)
                    .truncate(false)
                    .open(path)
                    .map_err(|e| RoleError::step(format!("cannot open state_file {path}"), e))?,
            ),
            None => None,
        };
        let sim = SimVehicle::start(url, config)
            .map_err(|e| RoleError::step("starting the simulated vehicle", e))?;
        Ok(Self {
            sim,
            last_ns: monotonic_ns(),
            checkpoint,
            resumed,
        })
    }

    fn period(&self) -> Duration {
        VEHICLE_PERIOD
    }

    fn cycle(
        &mut self,
        ctx: &mut RoleContext<kinds::Vehicle>,
        report: &mut CycleReport,
    ) -> Result<CycleOutcome, RoleError> {
        let now = monotonic_ns();
        let dt = now.saturating_sub(self.last_ns) as f64 * 1e-9;
        self.last_ns = now;
        self.sim.step(dt as f32);
        let st = self.sim.stats();
        report.stage("step", monotonic_ns().saturating_sub(now));
        if let Some(file) = &self.checkpoint
            && ctx.cycles.is_multiple_of(CHECKPOINT_EVERY)
        {
            let state = self.sim.state();
            let c = Checkpoint {
                stamp_ns: now,
                position: state.position,
                yaw: state.yaw,
            };
            // One 32-byte positional write: no allocation; a torn write fails its checksum.
            if let Err(e) = file.write_all_at(&c.encode(), 0) {
                return Err(RoleError::step("writing the vehicle checkpoint", e));
            }
        }
        report.counters = VehicleCounters {
            setpoints: st.setpoints,
            outside_fence: st.setpoints_outside_fence,
            steps: st.steps,
            missed_deadlines: ctx.missed_deadlines,
            setpoint_ticks_missed: st.setpoint_ticks_missed,
            rejected: st.setpoints_rejected,
            armed: u64::from(self.sim.state().armed),
            mode: self.sim.mode().index(),
        }
        .to_heartbeat();
        Ok(CycleOutcome::Worked)
    }

    fn shutdown(&mut self, _ctx: &mut RoleContext<kinds::Vehicle>) {
        self.sim.shutdown();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn checkpoints_round_trip_and_torn_ones_are_refused() {
        let c = Checkpoint {
            stamp_ns: 123_456_789,
            position: [1.5, -2.0, 12.0],
            yaw: 0.25,
        };
        let mut b = c.encode();
        assert_eq!(Checkpoint::decode(&b), Some(c));
        b[13] ^= 0x40;
        assert_eq!(Checkpoint::decode(&b), None);
        assert_eq!(Checkpoint::decode(&b[..10]), None);
    }
}
