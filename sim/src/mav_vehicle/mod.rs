//! A MAVLink endpoint that behaves like a PX4 multirotor in offboard mode or, with
//! [`SimFirmware::ArduPilotCopter`] ([`firmware`]), like an ArduPilot Copter in guided mode
//! (its heartbeat, mode numbers, `MAV_CMD_NAV_TAKEOFF` before position targets from the
//! ground, no offboard-loss failsafe).
//!
//! [`SimVehicle`] is system 1, component 1 (configurable) on any MAVLink connection URL
//! (`udpin:`, `udpout:`, `udpbcast:`, `tcpin:`, `tcpout:`, `serial:DEVICE:BAUD`). Around a
//! [`MultirotorModel`] it:
//! - sends HEARTBEAT at 1 Hz (`MAV_TYPE_QUADROTOR`, `MAV_AUTOPILOT_PX4`, `base_mode` with
//!   `CUSTOM_MODE_ENABLED` and `SAFETY_ARMED` when armed, `custom_mode` = PX4 main mode in
//!   bits 16..24 and sub mode in bits 24..32, see [`FlightMode`]), LOCAL_POSITION_NED and
//!   ATTITUDE at 50 Hz, EXTENDED_SYS_STATE (landed state) at 5 Hz;
//! - answers every COMMAND_LONG addressed to it with a COMMAND_ACK; it accepts
//!   `MAV_CMD_COMPONENT_ARM_DISARM` (disarming in the air only when forced with 21196),
//!   `MAV_CMD_DO_SET_MODE` (custom main mode 6 = offboard, refused unless setpoints streamed
//!   within the last 0.5 s; 3 = position; 4 with sub mode 3 = hold, 6 = land) and
//!   `MAV_CMD_NAV_LAND`; ArduPilot also `MAV_CMD_NAV_TAKEOFF` (armed in guided on the
//!   ground, to `param7` m); everything else is `MAV_RESULT_UNSUPPORTED`;
//! - flies SET_POSITION_TARGET_LOCAL_NED in `MAV_FRAME_LOCAL_NED` while in offboard,
//!   honouring `type_mask` for position, velocity, yaw and yaw rate (setpoints in other
//!   frames, with nothing usable, or with non-finite numbers are rejected and counted);
//! - like PX4, falls back to hold when the setpoint stream stops for more than 0.5 s in
//!   offboard, lands at 0.7 m/s in land mode and disarms 2 s after touching down.
//!
//! Receiving never blocks the physics: a receive thread decodes the link and feeds a bounded
//! channel that [`SimVehicle::step`] drains. The caller drives the physics with
//! [`SimVehicle::step`] (the vehicle role does, every 10 ms), or [`SimVehicle::spawn`] runs
//! it on its own thread.
//!
//! The link, its receive thread and the PX4 mode numbers come from `aeris-mavlink`, which
//! the controller role uses too.

use crate::multirotor::{
    Command, GROUND_U, MAX_STEP_S, MultirotorModel, MultirotorParams, MultirotorState,
};
use aeris_mavlink::dialect::{
    ATTITUDE_DATA, COMMAND_LONG_DATA, EXTENDED_SYS_STATE_DATA, HEARTBEAT_DATA,
    LOCAL_POSITION_NED_DATA, MavLandedState, MavMessage, MavModeFlag, MavState, MavType,
    MavVtolState, SET_POSITION_TARGET_LOCAL_NED_DATA,
};
use aeris_mavlink::{
    LINK_POLL, LinkError, LinkReceiver, LinkSigning, MavHeader, MavlinkVersion, Received,
    neu_to_ned, prepare_link,
};
use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, TryRecvError, TrySendError, sync_channel};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

pub mod firmware;
mod inbound;

pub use firmware::{ModeRequest, SimFirmware};

/// Flight mode of the simulated autopilot (a subset of PX4's).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FlightMode {
    /// Position control without stick input: holds position (the mode after boot).
    Position,
    /// Auto loiter: holds the position latched when the mode was entered.
    Hold,
    /// Offboard: flies the streamed SET_POSITION_TARGET_LOCAL_NED setpoints.
    Offboard,
    /// Auto land: descends at the latched north/east to the ground.
    Land,
}

impl FlightMode {
    /// PX4 `custom_mode` of this mode (see [`SimFirmware::custom_mode`] for the others).
    pub fn custom_mode(self) -> u32 {
        SimFirmware::Px4.custom_mode(self)
    }

    /// Small integer for counters: 1 position, 2 hold, 3 offboard, 4 land.
    pub fn index(self) -> u64 {
        match self {
            FlightMode::Position => 1,
            FlightMode::Hold => 2,
            FlightMode::Offboard => 3,
            FlightMode::Land => 4,
        }
    }
}

/// Configuration of a [`SimVehicle`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimVehicleConfig {
    /// Start position `[N, E, U]`; above 0.1 m the vehicle starts armed, holding there.
    pub start: [f32; 3],
    /// Start yaw (rad).
    pub start_yaw: f32,
    /// Kinematic limits.
    pub params: MultirotorParams,
    /// MAVLink system id.
    pub system_id: u8,
    /// MAVLink component id.
    pub component_id: u8,
    /// Offboard is refused, and left for hold, when no setpoint came within this (s).
    pub offboard_timeout_s: f32,
    /// Descent speed in land mode (m/s).
    pub land_speed: f32,
    /// Disarm this long after touching down from a flight (s).
    pub auto_disarm_s: f32,
    /// Bounds `(min, max)` in `[N, E, U]` that every received position setpoint is checked
    /// against (the vehicle still flies it, like an autopilot with its own fence would
    /// report it); counted in [`SimVehicleStats::setpoints_outside_fence`].
    pub fence: Option<([f32; 3], [f32; 3])>,
    /// The period the controller streams setpoints at (s); when set, an interval between
    /// two usable setpoints longer than two periods counts `round(interval / period) - 1`
    /// missed ticks in [`SimVehicleStats::setpoint_ticks_missed`] (the autopilot's view of
    /// the controller: jitter within two periods is not a miss).
    pub setpoint_period_s: Option<f32>,
    /// The framing the vehicle sends (it receives both): an autopilot that speaks only
    /// MAVLink 1 is `V1`.
    pub mavlink_version: MavlinkVersion,
    /// The autopilot it plays.
    pub firmware: SimFirmware,
    /// MAVLink 2 signing: signs what it sends, refuses unsigned or badly signed frames.
    pub signing: Option<LinkSigning>,
    /// Lockstep (simulated time): no receive thread; each [`SimVehicle::step`] first takes
    /// what has arrived on the link (a UDP or serial link), and a setpoint's arrival is the
    /// step's time, so a flight does not depend on when a thread ran.
    pub lockstep: bool,
}

impl Default for SimVehicleConfig {
    fn default() -> Self {
        Self {
            start: [0.0; 3],
            start_yaw: 0.0,
            params: MultirotorParams::default(),
            system_id: 1,
            component_id: 1,
            offboard_timeout_s: 0.5,
            land_speed: 0.7,
            auto_disarm_s: 2.0,
            fence: None,
            setpoint_period_s: None,
            mavlink_version: MavlinkVersion::V2,
            firmware: SimFirmware::Px4,
            signing: None,
            lockstep: false,
        }
    }
}

/// Counters of a [`SimVehicle`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SimVehicleStats {
    /// Physics steps run.
    pub steps: u64,
    /// COMMAND_LONGs received.
    pub commands: u64,
    /// COMMAND_LONGs answered with `MAV_RESULT_ACCEPTED`.
    pub commands_accepted: u64,
    /// Usable setpoints received.
    pub setpoints: u64,
    /// Setpoints rejected (frame, type mask, non-finite numbers).
    pub setpoints_rejected: u64,
    /// Messages written to the link.
    pub messages_sent: u64,
    /// Messages whose write failed.
    pub send_errors: u64,
    /// Received messages dropped because the step loop fell behind.
    pub inbox_dropped: u64,
    /// Offboard-loss failsafes (offboard -> hold).
    pub failsafes: u64,
    /// Position setpoints outside the configured fence or not finite (see
    /// [`SimVehicleConfig::fence`]); the controller must never send one.
    pub setpoints_outside_fence: u64,
    /// Controller ticks missed as seen from here (see
    /// [`SimVehicleConfig::setpoint_period_s`]; 0 without it).
    pub setpoint_ticks_missed: u64,
}

/// A snapshot of the simulated vehicle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimVehicleStatus {
    /// Kinematic state.
    pub state: MultirotorState,
    /// Flight mode.
    pub mode: FlightMode,
    /// Simulated time since start (s).
    pub time_s: f64,
    /// A link peer is known (the link is established).
    pub link_established: bool,
    /// Counters.
    pub stats: SimVehicleStats,
}

/// Why a [`SimVehicle`] could not start.
#[derive(Debug, thiserror::Error)]
pub enum SimVehicleError {
    /// The MAVLink link could not be opened.
    #[error(transparent)]
    Link(#[from] LinkError),
    /// The configuration is unusable (non-finite start, non-positive limits).
    #[error("invalid simulated vehicle configuration: {0}")]
    Config(&'static str),
    /// A thread could not be spawned.
    #[error("cannot spawn the simulated vehicle's thread: {0}")]
    Thread(std::io::Error),
}

enum Inbound {
    Command(COMMAND_LONG_DATA),
    /// With the time it arrived at the link (`None` in lockstep: the step's time).
    Setpoint(SET_POSITION_TARGET_LOCAL_NED_DATA, Option<Instant>),
}

const INBOX_CAPACITY: usize = 256;
const HEARTBEAT_PERIOD_S: f64 = 1.0;
const TELEMETRY_PERIOD_S: f64 = 0.02;
const EXT_STATE_PERIOD_S: f64 = 0.2;

/// The simulated PX4-like multirotor behind a MAVLink endpoint.
pub struct SimVehicle {
    config: SimVehicleConfig,
    receiver: LinkReceiver,
    inbox: Receiver<Inbound>,
    dropped: Arc<AtomicU64>,
    model: MultirotorModel,
    mode: FlightMode,
    time_s: f64,
    last_setpoint_s: Option<f64>,
    /// Link arrival of the last usable setpoint (s since `epoch`, or the step's time in
    /// lockstep).
    last_arrival: Option<f64>,
    /// What arrival instants are measured from.
    epoch: Instant,
    offboard_cmd: Option<Command>,
    hold_position: [f32; 3],
    hold_yaw: f32,
    /// ArduPilot: a take-off was commanded since the vehicle last stood on the ground.
    took_off: bool,
    airborne_seen: bool,
    landed_since_s: Option<f64>,
    next_heartbeat_s: f64,
    next_telemetry_s: f64,
    next_ext_state_s: f64,
    prev_roll: f32,
    prev_pitch: f32,
    roll_rate: f32,
    pitch_rate: f32,
    stats: SimVehicleStats,
}

impl core::fmt::Debug for SimVehicle {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("SimVehicle")
            .field("mode", &self.mode)
            .field("state", self.model.state())
            .finish_non_exhaustive()
    }
}

fn targets_me(target_system: u8, target_component: Option<u8>, sys: u8, comp: u8) -> bool {
    (target_system == 0 || target_system == sys)
        && target_component.is_none_or(|c| c == 0 || c == comp)
}

/// What the receive thread does with each message: commands and setpoints addressed to
/// this vehicle go to the step loop's inbox (dropped and counted when it is full).
fn inbox_handler(
    tx: SyncSender<Inbound>,
    dropped: Arc<AtomicU64>,
    sys: u8,
    comp: u8,
    lockstep: bool,
) -> impl FnMut(Received) -> ControlFlow<()> + Send + 'static {
    move |r: Received| {
        let item = match r.message {
            MavMessage::COMMAND_LONG(c)
                if targets_me(c.target_system, Some(c.target_component), sys, comp) =>
            {
                Inbound::Command(c)
            }
            MavMessage::SET_POSITION_TARGET_LOCAL_NED(s)
                if targets_me(s.target_system, None, sys, comp) =>
            {
                Inbound::Setpoint(s, (!lockstep).then(Instant::now))
            }
            _ => return ControlFlow::Continue(()),
        };
        match tx.try_send(item) {
            Ok(()) => ControlFlow::Continue(()),
            Err(TrySendError::Full(_)) => {
                dropped.fetch_add(1, Ordering::Relaxed);
                ControlFlow::Continue(())
            }
            Err(TrySendError::Disconnected(_)) => ControlFlow::Break(()),
        }
    }
}

fn norm3(v: [f32; 3]) -> f32 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

impl SimVehicle {
    /// Open `url` and start the receive thread. The physics does not run until
    /// [`SimVehicle::step`] is called.
    pub fn start(url: &str, config: SimVehicleConfig) -> Result<Self, SimVehicleError> {
        if !config.start.iter().all(|x| x.is_finite()) || !config.start_yaw.is_finite() {
            return Err(SimVehicleError::Config("start pose is not finite"));
        }
        let p = &config.params;
        let positive = [
            p.max_speed_h,
            p.max_speed_v,
            p.max_accel,
            p.max_yaw_rate,
            p.kp_position,
            p.kp_yaw,
            config.offboard_timeout_s,
            config.land_speed,
        ];
        if !positive.iter().all(|x| x.is_finite() && *x > 0.0) {
            return Err(SimVehicleError::Config(
                "limits, gains and timeouts must be finite and positive",
            ));
        }
        if config.signing.is_some() && config.mavlink_version == MavlinkVersion::V1 {
            return Err(SimVehicleError::Config("MAVLink 1 cannot be signed"));
        }
        let pending = prepare_link(url, LINK_POLL)?.with_signing(config.signing);
        let dropped = Arc::new(AtomicU64::new(0));
        let (tx, inbox) = sync_channel(INBOX_CAPACITY);
        let handler = inbox_handler(
            tx,
            dropped.clone(),
            config.system_id,
            config.component_id,
            config.lockstep,
        );
        let receiver = if config.lockstep {
            LinkReceiver::inline(pending, handler)?
        } else {
            LinkReceiver::spawn(
                "sim-vehicle-rx",
                pending,
                "aeris-sim: vehicle link failed",
                handler,
            )
            .map_err(SimVehicleError::Thread)?
        };
        let mut model = MultirotorModel::new(config.params, config.start, config.start_yaw);
        let airborne = config.start[2] > 0.1;
        let mode = if airborne {
            model.set_armed(true);
            FlightMode::Hold
        } else {
            FlightMode::Position
        };
        let state = *model.state();
        Ok(Self {
            config,
            receiver,
            inbox,
            dropped,
            model,
            mode,
            time_s: 0.0,
            last_setpoint_s: None,
            last_arrival: None,
            epoch: Instant::now(),
            offboard_cmd: None,
            hold_position: state.position,
            hold_yaw: state.yaw,
            took_off: airborne,
            airborne_seen: airborne,
            landed_since_s: None,
            next_heartbeat_s: 0.0,
            next_telemetry_s: 0.0,
            next_ext_state_s: 0.0,
            prev_roll: 0.0,
            prev_pitch: 0.0,
            roll_rate: 0.0,
            pitch_rate: 0.0,
            stats: SimVehicleStats::default(),
        })
    }

    /// Start the vehicle and run its physics on its own thread every `period`.
    pub fn spawn(
        url: &str,
        config: SimVehicleConfig,
        period: Duration,
    ) -> Result<SimVehicleRunner, SimVehicleError> {
        let mut vehicle = Self::start(url, config)?;
        let period = period.max(Duration::from_millis(1));
        let stop = Arc::new(AtomicBool::new(false));
        let status = Arc::new(Mutex::new(vehicle.status()));
        let thread = {
            let (stop, status) = (stop.clone(), status.clone());
            std::thread::Builder::new()
                .name("sim-vehicle".into())
                .spawn(move || {
                    let mut next = Instant::now();
                    let mut last = next;
                    while !stop.load(Ordering::Relaxed) {
                        let now = Instant::now();
                        vehicle.step(now.duration_since(last).as_secs_f32());
                        last = now;
                        if let Ok(mut s) = status.lock() {
                            *s = vehicle.status();
                        }
                        next += period;
                        let now = Instant::now();
                        if next > now {
                            std::thread::sleep(next - now);
                        } else {
                            next = now;
                        }
                    }
                    vehicle.shutdown();
                    vehicle.stats()
                })
                .map_err(SimVehicleError::Thread)?
        };
        Ok(SimVehicleRunner {
            stop,
            status,
            thread: Some(thread),
        })
    }

    /// The kinematic state.
    pub fn state(&self) -> &MultirotorState {
        self.model.state()
    }

    /// The flight mode.
    pub fn mode(&self) -> FlightMode {
        self.mode
    }

    /// Counters so far.
    pub fn stats(&self) -> SimVehicleStats {
        let mut s = self.stats;
        s.inbox_dropped = self.dropped.load(Ordering::Relaxed);
        s
    }

    /// A snapshot of everything.
    pub fn status(&self) -> SimVehicleStatus {
        SimVehicleStatus {
            state: *self.model.state(),
            mode: self.mode,
            time_s: self.time_s,
            link_established: self.receiver.link().is_some(),
            stats: self.stats(),
        }
    }

    /// Advance the simulation by `dt` seconds (clamped to [`MAX_STEP_S`]): handle what
    /// arrived on the link, apply failsafes, step the physics, send what is due.
    pub fn step(&mut self, dt: f32) {
        if !(dt.is_finite() && dt >= 0.0) {
            return;
        }
        let dt = dt.min(MAX_STEP_S);
        self.time_s += f64::from(dt);
        // lockstep: what arrived since the last step (a receiver with a thread has fed the
        // inbox already)
        self.receiver.pump();
        loop {
            match self.inbox.try_recv() {
                Ok(Inbound::Command(c)) => self.handle_command(&c),
                Ok(Inbound::Setpoint(s, at)) => {
                    let at_s = match at {
                        Some(at) => at.saturating_duration_since(self.epoch).as_secs_f64(),
                        None => self.time_s,
                    };
                    self.handle_setpoint(&s, at_s)
                }
                Err(TryRecvError::Empty) | Err(TryRecvError::Disconnected) => break,
            }
        }
        if self.mode == FlightMode::Offboard
            && self.config.firmware.offboard_needs_stream()
            && !self.setpoints_fresh()
        {
            self.stats.failsafes += 1;
            self.set_mode(FlightMode::Hold);
        }
        let command = self.active_command();
        self.model.step(dt, &command);
        self.update_landing();
        let s = *self.model.state();
        if dt > 0.0 {
            self.roll_rate = (s.roll - self.prev_roll) / dt;
            self.pitch_rate = (s.pitch - self.prev_pitch) / dt;
        }
        self.prev_roll = s.roll;
        self.prev_pitch = s.pitch;
        self.send_due();
        self.stats.steps += 1;
    }

    /// Stop the receive thread (also done on drop).
    pub fn shutdown(&mut self) {
        self.receiver.stop();
    }

    fn setpoints_fresh(&self) -> bool {
        self.last_setpoint_s
            .is_some_and(|t| self.time_s - t <= f64::from(self.config.offboard_timeout_s))
    }

    fn set_mode(&mut self, mode: FlightMode) {
        if mode != FlightMode::Offboard {
            let s = self.model.state();
            self.hold_position = s.position;
            self.hold_yaw = s.yaw;
        }
        self.mode = mode;
    }

    fn active_command(&self) -> Command {
        let hold = Command::hold(self.hold_position, self.hold_yaw);
        match self.mode {
            FlightMode::Position | FlightMode::Hold => hold,
            // ArduPilot: armed in guided on the ground, targets wait for a take-off
            FlightMode::Offboard
                if self.config.firmware.needs_takeoff_command() && !self.took_off =>
            {
                hold
            }
            FlightMode::Offboard => self.offboard_cmd.unwrap_or(hold),
            FlightMode::Land => Command::Position {
                position: [self.hold_position[0], self.hold_position[1], GROUND_U - 1.0],
                velocity_ff: Some([0.0, 0.0, -self.config.land_speed]),
                yaw: Some(self.hold_yaw),
                yaw_rate: None,
            },
        }
    }

    fn update_landing(&mut self) {
        let s = *self.model.state();
        if !s.armed {
            self.airborne_seen = false;
            self.landed_since_s = None;
            self.took_off = false;
            return;
        }
        if !s.landed {
            self.airborne_seen = true;
            self.landed_since_s = None;
        } else if self.airborne_seen {
            let since = *self.landed_since_s.get_or_insert(self.time_s);
            if self.time_s - since >= f64::from(self.config.auto_disarm_s) {
                self.model.set_armed(false);
                self.airborne_seen = false;
                self.landed_since_s = None;
            }
        }
    }

    fn send(&mut self, msg: &MavMessage) {
        let Some(link) = self.receiver.link() else {
            return;
        };
        if link.send_version() != self.config.mavlink_version {
            link.set_send_version(self.config.mavlink_version);
        }
        let header = MavHeader {
            system_id: self.config.system_id.into(),
            component_id: self.config.component_id,
            sequence: 0,
        };
        match link.send(&header, msg) {
            Ok(0) => {}
            Ok(_) => self.stats.messages_sent += 1,
            Err(_) => self.stats.send_errors += 1,
        }
    }

    fn send_due(&mut self) {
        let t = self.time_s;
        let time_boot_ms = (t * 1000.0) as u32;
        let s = *self.model.state();
        if t >= self.next_heartbeat_s {
            self.next_heartbeat_s = next_due(self.next_heartbeat_s, HEARTBEAT_PERIOD_S, t);
            let mut base = MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
                | MavModeFlag::MAV_MODE_FLAG_STABILIZE_ENABLED;
            base |= match self.mode {
                FlightMode::Position => MavModeFlag::MAV_MODE_FLAG_MANUAL_INPUT_ENABLED,
                FlightMode::Offboard => MavModeFlag::MAV_MODE_FLAG_GUIDED_ENABLED,
                FlightMode::Hold | FlightMode::Land => {
                    MavModeFlag::MAV_MODE_FLAG_GUIDED_ENABLED
                        | MavModeFlag::MAV_MODE_FLAG_AUTO_ENABLED
                }
            };
            if s.armed {
                base |= MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED;
            }
            self.send(&MavMessage::HEARTBEAT(HEARTBEAT_DATA {
                custom_mode: self.config.firmware.custom_mode(self.mode),
                mavtype: MavType::MAV_TYPE_QUADROTOR,
                autopilot: self.config.firmware.mav_autopilot(),
                base_mode: base,
                system_status: if s.armed {
                    MavState::MAV_STATE_ACTIVE
                } else {
                    MavState::MAV_STATE_STANDBY
                },
                mavlink_version: 3,
            }));
        }
        if t >= self.next_telemetry_s {
            self.next_telemetry_s = next_due(self.next_telemetry_s, TELEMETRY_PERIOD_S, t);
            let [x, y, z] = neu_to_ned(s.position);
            let [vx, vy, vz] = neu_to_ned(s.velocity);
            self.send(&MavMessage::LOCAL_POSITION_NED(LOCAL_POSITION_NED_DATA {
                time_boot_ms,
                x,
                y,
                z,
                vx,
                vy,
                vz,
            }));
            self.send(&MavMessage::ATTITUDE(ATTITUDE_DATA {
                time_boot_ms,
                roll: s.roll,
                pitch: s.pitch,
                yaw: s.yaw,
                rollspeed: self.roll_rate,
                pitchspeed: self.pitch_rate,
                yawspeed: s.yaw_rate,
            }));
        }
        if t >= self.next_ext_state_s {
            self.next_ext_state_s = next_due(self.next_ext_state_s, EXT_STATE_PERIOD_S, t);
            let landed_state = if s.landed {
                MavLandedState::MAV_LANDED_STATE_ON_GROUND
            } else if self.mode == FlightMode::Land {
                MavLandedState::MAV_LANDED_STATE_LANDING
            } else if s.position[2] < 1.0 && s.velocity[2] > 0.1 && norm3(s.velocity) < 10.0 {
                MavLandedState::MAV_LANDED_STATE_TAKEOFF
            } else {
                MavLandedState::MAV_LANDED_STATE_IN_AIR
            };
            self.send(&MavMessage::EXTENDED_SYS_STATE(EXTENDED_SYS_STATE_DATA {
                vtol_state: MavVtolState::MAV_VTOL_STATE_UNDEFINED,
                landed_state,
            }));
        }
    }
}

/// Next deadline of a periodic message: one period later, re-anchored when far behind.
fn next_due(prev: f64, period: f64, now: f64) -> f64 {
    let next = prev + period;
    if next <= now { now + period } else { next }
}

impl Drop for SimVehicle {
    fn drop(&mut self) {
        self.shutdown();
    }
}

/// A [`SimVehicle`] running on its own thread (see [`SimVehicle::spawn`]).
#[derive(Debug)]
pub struct SimVehicleRunner {
    stop: Arc<AtomicBool>,
    status: Arc<Mutex<SimVehicleStatus>>,
    thread: Option<JoinHandle<SimVehicleStats>>,
}

impl SimVehicleRunner {
    /// The latest snapshot (`None` if the physics thread panicked).
    pub fn status(&self) -> Option<SimVehicleStatus> {
        self.status.lock().ok().map(|s| *s)
    }

    /// Stop the physics and receive threads; the final counters.
    pub fn stop(mut self) -> SimVehicleStats {
        self.halt().unwrap_or_default()
    }

    fn halt(&mut self) -> Option<SimVehicleStats> {
        self.stop.store(true, Ordering::Relaxed);
        self.thread.take().and_then(|h| h.join().ok())
    }
}

impl Drop for SimVehicleRunner {
    fn drop(&mut self) {
        let _ = self.halt();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flight_modes_are_px4_custom_modes() {
        use aeris_mavlink::px4::{px4_main_mode, px4_sub_mode};
        assert_eq!(FlightMode::Offboard.custom_mode(), 6 << 16);
        assert_eq!(px4_main_mode(FlightMode::Offboard.custom_mode()), 6);
        assert_eq!(px4_main_mode(FlightMode::Land.custom_mode()), 4);
        assert_eq!(px4_sub_mode(FlightMode::Land.custom_mode()), 6);
        assert_eq!(px4_sub_mode(FlightMode::Hold.custom_mode()), 3);
    }

    #[test]
    fn next_due_reanchors() {
        assert_eq!(next_due(1.0, 1.0, 1.5), 2.0);
        assert_eq!(next_due(1.0, 1.0, 10.0), 11.0);
    }
}
