//! The controller role: ports, the receive thread, and the cycle that runs the lease, the
//! tracker and the autopilot sequencer and writes what they decide (see the module
//! documentation of [`crate::controller`]).

use super::autopilot_state::AutopilotState;
use super::lease::{LEASE_LISTEN_PERIODS, LEASE_SILENCE_PERIODS, LeaseArbiter, LeaseChange};
use super::link_watch::{LinkLedger, link_state, term_heartbeat};
use super::messages::{
    Target, command_long, companion_header, companion_heartbeat, position_target_message,
    takeoff_params, three_params,
};
use super::sequencer::{AutopilotSequencer, AutopilotStatus, FlightIntent};
use super::signing_params::signing_from_spec;
use super::tracker::{Tracker, TrackerConfig};
use aeris_mavlink::dialect::{MavCmd, MavMessage};
use aeris_mavlink::{
    Autopilot, LINK_POLL, LinkReceiver, MavHeader, MavlinkVersion, Received, ned_to_neu,
    prepare_link,
};
use aeris_runtime::bus::{TypedPublisher, TypedSubscriber};
use aeris_runtime::clock::monotonic_ns;
use aeris_runtime::role::try_sched_fifo;
use aeris_runtime::{
    ConfigError, CycleOutcome, CycleReport, Role, RoleContext, RoleError, RoleSpec,
};
use aeris_schemas::kinds;
use aeris_schemas::{
    ActionMode, AutopilotLinkStatus, BoundSetpoint, ControllerCounters, ControllerLease, FixedText,
    LEASE_LINK_HEARD, LinkState, VehicleTelemetry, topics,
};
use std::ops::ControlFlow;
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// Autopilot URL used when the spec gives none.
pub const DEFAULT_AUTOPILOT: &str = "udpout:127.0.0.1:14600";
/// Polls of the autopilot lease per control period.
pub const POLLS_PER_TICK: u32 = 4;
/// `params.link_timeout_ms` when the spec gives none: no autopilot HEARTBEAT this long
/// after the start is a silent link; none this long after the last is a lost one.
pub const DEFAULT_LINK_TIMEOUT_MS: u64 = 5_000;

/// What the receive thread keeps for the cycle: the autopilot's state and the ledger of
/// everything heard.
#[derive(Debug, Clone, Copy, Default)]
struct Heard {
    state: AutopilotState,
    ledger: LinkLedger,
}

/// Which MAVLink framing the controller sends (`params.mavlink`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MavlinkFraming {
    /// MAVLink 2, unless the autopilot's heartbeats arrive in MAVLink 1 (the default).
    Auto,
    /// Always MAVLink 1.
    V1,
    /// Always MAVLink 2.
    V2,
}

impl MavlinkFraming {
    /// The framing of `spec`'s `params.mavlink`: `1`, `2` or `"auto"` (the default).
    pub fn from_spec(spec: &RoleSpec) -> Result<Self, RoleError> {
        match spec.params.get("mavlink") {
            None => Ok(Self::Auto),
            Some(v) if v.as_u64() == Some(1) => Ok(Self::V1),
            Some(v) if v.as_u64() == Some(2) => Ok(Self::V2),
            Some(v) if v.as_str() == Some("auto") => Ok(Self::Auto),
            Some(v) => Err(RoleError::param(
                "mavlink",
                format!("= {v}: use 1, 2 or \"auto\""),
            )),
        }
    }

    /// MAVLink 1 frames are refused (the workflow said `mavlink = 2`).
    pub fn v2_only(self) -> bool {
        self == Self::V2
    }

    /// The version to send once the autopilot's heartbeat framing is `heard`.
    pub fn send_version(self, heard: Option<MavlinkVersion>) -> MavlinkVersion {
        match (self, heard) {
            (Self::V1, _) | (Self::Auto, Some(MavlinkVersion::V1)) => MavlinkVersion::V1,
            _ => MavlinkVersion::V2,
        }
    }
}

/// The 50 Hz MAVLink controller role.
pub struct ControllerRole {
    /// The autopilot link and its receive thread (which applies what arrives to `shared`).
    receiver: LinkReceiver,
    shared: Arc<Mutex<Heard>>,
    /// The last autopilot state copied out of `shared` (used when the lock is busy).
    ap_cache: AutopilotState,
    /// The last ledger copied out of `shared`.
    ledger: LinkLedger,
    /// Whom commands and setpoints are addressed to (broadcast until the autopilot's
    /// heartbeat named it).
    target: Target,
    link_out: TypedPublisher<AutopilotLinkStatus>,
    link_seq: u64,
    link_timeout_ns: u64,
    link_state: LinkState,
    link_losses: u64,
    /// When this process last took the autopilot lease (`None`: never held it).
    term_start_ns: Option<u64>,
    /// The lease this process took over said the flight's autopilot had been heard.
    heard_before_term: bool,
    url: FixedText<{ aeris_schemas::LINK_URL_MAX }>,
    setpoints: TypedSubscriber<BoundSetpoint>,
    telemetry: TypedPublisher<VehicleTelemetry>,
    /// The holder's telemetry, read while standing by.
    telemetry_in: TypedSubscriber<VehicleTelemetry>,
    lease_out: TypedPublisher<ControllerLease>,
    lease_in: TypedSubscriber<ControllerLease>,
    arbiter: LeaseArbiter,
    /// What the holder last reported (the standby's view of the vehicle).
    standby_ap: AutopilotState,
    tracker: Tracker,
    sequencer: AutopilotSequencer,
    period: Duration,
    period_ns: u64,
    next_tick_ns: u64,
    /// Control ticks run and skipped in the current term of the lease.
    ticks: u64,
    missed_ticks: u64,
    /// The tracker's hold ticks when this process last took the lease.
    hold_ticks_base: u64,
    /// Setpoints sent in the current term.
    term_sent: u64,
    start_ns: u64,
    sent: u64,
    send_errors: u64,
    commands_sent: u64,
    telemetry_seq: u64,
    header: MavHeader,
    framing: MavlinkFraming,
}

impl core::fmt::Debug for ControllerRole {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("ControllerRole")
            .field("sent", &self.sent)
            .field("refused", &self.tracker.refused())
            .finish_non_exhaustive()
    }
}

impl ControllerRole {
    /// MAVLink messages of the last run written successfully (setpoints only).
    pub fn setpoints_sent(&self) -> u64 {
        self.sent
    }

    /// Writes to the autopilot link that failed.
    pub fn send_errors(&self) -> u64 {
        self.send_errors
    }

    /// The tracker (setpoint gate and reference).
    pub fn tracker(&self) -> &Tracker {
        &self.tracker
    }

    /// The heartbeat counters (see the module documentation).
    fn counters(&self) -> [u64; 8] {
        ControllerCounters {
            ticks: self.ticks,
            missed_ticks: self.missed_ticks,
            refused_setpoints: self.tracker.refused(),
            hold_ticks: self.tracker.hold_ticks() - self.hold_ticks_base,
            sent: self.sent,
            lease_held: u64::from(self.arbiter.is_active()),
            takeovers: self.arbiter.takeovers(),
            lease_epoch: self.arbiter.epoch(),
        }
        .to_heartbeat()
    }

    fn send(&mut self, msg: &MavMessage) -> bool {
        let Some(link) = self.receiver.link() else {
            return false;
        };
        // the framing follows the autopilot's (an atomic load, a store when it changes)
        let version = self.framing.send_version(self.ap_cache.heartbeat_version);
        if link.send_version() != version {
            link.set_send_version(version);
            tracing::info!("aeris controller: sending MAVLink {version:?} to the autopilot");
        }
        match link.send(&self.header, msg) {
            Ok(n) => n > 0,
            Err(_) => {
                self.send_errors += 1;
                false
            }
        }
    }

    fn command(&mut self, command: MavCmd, params: [f32; 7], confirmation: u8) {
        if self.send(&command_long(command, params, confirmation, self.target)) {
            self.commands_sent += 1;
        }
    }

    /// Take in what the receive thread heard: the autopilot it bound to names the target
    /// and the firmware; the link's state is published (by the lease holder).
    fn watch_link(&mut self, now_ns: u64, name: &str) -> Result<(), RoleError> {
        if let Some(id) = self.ledger.bound {
            let target = Target {
                system_id: id.system_id,
                component_id: id.component_id,
            };
            if target != self.target {
                self.target = target;
                self.sequencer.set_autopilot(id.autopilot);
                tracing::info!(
                    "aeris controller `{name}`: flying {} at system {} component {}",
                    id.autopilot.name(),
                    id.system_id,
                    id.component_id
                );
            }
        }
        // Only the holder's link is judged: an autopilot answers whoever sends to it, so a
        // standby's own link may hear nothing until it takes over. The clock starts when
        // this process took the lease, and a heartbeat heard before that counts from then.
        let Some(term_start) = self.term_start_ns.filter(|_| self.arbiter.is_active()) else {
            return Ok(());
        };
        let state = link_state(
            now_ns,
            term_start,
            term_heartbeat(
                self.ap_cache.last_heartbeat_ns,
                term_start,
                self.heard_before_term,
            ),
            self.link_timeout_ns,
        );
        if state != self.link_state {
            if state == LinkState::Lost {
                self.link_losses += 1;
            }
            tracing::info!(
                "aeris controller `{name}`: autopilot link {} ({})",
                state.name(),
                self.url.as_str_lossy()
            );
            self.link_state = state;
        }
        self.link_seq += 1;
        let link = self.receiver.link();
        let (unsigned_refused, bad_signature_refused) =
            link.map_or((0, 0), |l| l.signing_refused());
        let status = AutopilotLinkStatus {
            seq: self.link_seq,
            lease_epoch: self.arbiter.epoch(),
            unsigned_refused,
            bad_signature_refused,
            crc_failures: link.map_or(0, |l| l.crc_failures()),
            signing: u8::from(link.is_some_and(|l| l.is_signed())),
            stamp_ns: now_ns,
            losses: self.link_losses,
            timeout_ms: (self.link_timeout_ns / 1_000_000).min(u64::from(u32::MAX)) as u32,
            state: state as u8,
            send_version: match link.map(|l| l.send_version()) {
                Some(MavlinkVersion::V1) => 1,
                _ => 2,
            },
            url: self.url,
            ..self.ledger.status
        };
        self.link_out.publish(&status)?;
        Ok(())
    }
}

impl Role for ControllerRole {
    type Kind = kinds::Controller;

    fn new(ctx: &mut RoleContext<kinds::Controller>) -> Result<Self, RoleError> {
        let spec = &ctx.spec;
        let rate = spec.timing.control_rate_hz;
        if !(rate.is_finite() && rate > 0.0 && rate <= 1000.0) {
            return Err(ConfigError::Spec {
                field: "timing.control_rate_hz",
                problem: format!("= {rate} must be in (0, 1000]"),
            }
            .into());
        }
        let url = match spec.params.get("autopilot") {
            None => DEFAULT_AUTOPILOT.to_string(),
            Some(v) => v
                .as_str()
                .ok_or_else(|| RoleError::param("autopilot", "must be a string"))?
                .to_string(),
        };
        let realtime = spec.param_bool("realtime", true)?;
        let standby = spec.param_bool("standby", false)?;
        let framing = MavlinkFraming::from_spec(spec)?;
        let link_timeout_ms = match spec.params.get("link_timeout_ms") {
            None => DEFAULT_LINK_TIMEOUT_MS,
            Some(v) => v.as_u64().filter(|&ms| ms > 0).ok_or_else(|| {
                RoleError::param(
                    "link_timeout_ms",
                    format!("= {v}: use a whole number of milliseconds above 0"),
                )
            })?,
        };
        let tracker = Tracker::new(TrackerConfig::from_spec(spec));
        let setpoints = ctx.bus.subscriber::<topics::HubSetpoint>()?;
        let telemetry = ctx.bus.publisher::<topics::VehicleTelemetry>()?;
        let telemetry_in = ctx.bus.subscriber::<topics::VehicleTelemetry>()?;
        let lease_out = ctx.bus.publisher::<topics::ControllerLease>()?;
        let lease_in = ctx.bus.subscriber::<topics::ControllerLease>()?;
        let link_out = ctx.bus.publisher::<topics::ControllerLink>()?;
        let signing = signing_from_spec(spec)?;
        if signing.is_some() && framing == MavlinkFraming::V1 {
            return Err(RoleError::param(
                "signing_key_file",
                "is set with `mavlink` = 1: MAVLink 1 cannot be signed",
            ));
        }
        let pending = prepare_link(&url, LINK_POLL)
            .map_err(|e| RoleError::step("preparing the autopilot link", e))?
            .with_signing(signing);
        let shared = Arc::new(Mutex::new(Heard::default()));
        let v2_only = framing.v2_only();
        // Spawned before switching to SCHED_FIFO so the receive thread keeps the normal policy.
        let receiver = {
            let shared = shared.clone();
            let on_message = move |r: Received| {
                let now = monotonic_ns();
                if let Ok(mut heard) = shared.lock() {
                    let Heard { state, ledger } = &mut *heard;
                    // only the autopilot the ledger bound to is believed
                    if let Some(autopilot) = ledger.accept(&r, v2_only) {
                        state.apply(&r.message, now, autopilot);
                        if matches!(r.message, MavMessage::HEARTBEAT(_)) {
                            state.heartbeat_version = r.version;
                        }
                    }
                }
                ControlFlow::Continue(())
            };
            if aeris_runtime::clock::simulated() {
                // on simulated time the link is read on the controller's own turns
                LinkReceiver::inline(pending, on_message)
                    .map_err(|e| RoleError::step("opening the autopilot link", e))?
            } else {
                LinkReceiver::spawn(
                    "controller-rx",
                    pending,
                    "aeris controller: autopilot link failed",
                    on_message,
                )
                .map_err(|e| RoleError::step("spawning the receive thread", e))?
            }
        };
        if realtime && !try_sched_fifo(50) {
            tracing::warn!(
                "aeris controller `{}`: SCHED_FIFO not permitted, running with the normal scheduler",
                spec.name
            );
        }
        let now = monotonic_ns();
        let period = Duration::from_secs_f64(1.0 / rate);
        let period_ns = (period.as_nanos() as u64).max(1);
        Ok(Self {
            receiver,
            shared,
            ap_cache: AutopilotState::default(),
            ledger: LinkLedger::default(),
            target: Target::BROADCAST,
            link_out,
            link_seq: 0,
            link_timeout_ns: link_timeout_ms.saturating_mul(1_000_000),
            link_state: LinkState::Waiting,
            link_losses: 0,
            term_start_ns: None,
            heard_before_term: false,
            url: FixedText::from_str_truncated(&url),
            setpoints,
            telemetry,
            telemetry_in,
            lease_out,
            lease_in,
            arbiter: LeaseArbiter::new(
                std::process::id(),
                !standby,
                now,
                period_ns.saturating_mul(LEASE_SILENCE_PERIODS),
                // a standby listens twice as long, so that at a flight's start the primary
                // claims first
                period_ns.saturating_mul(LEASE_LISTEN_PERIODS * if standby { 2 } else { 1 }),
            ),
            standby_ap: AutopilotState::default(),
            tracker,
            // PX4 until the autopilot's heartbeat says otherwise
            sequencer: AutopilotSequencer::new(Autopilot::Px4, now),
            period,
            period_ns,
            next_tick_ns: now,
            ticks: 0,
            missed_ticks: 0,
            hold_ticks_base: 0,
            term_sent: 0,
            start_ns: now,
            sent: 0,
            send_errors: 0,
            commands_sent: 0,
            telemetry_seq: 0,
            header: companion_header(),
            framing,
        })
    }

    fn period(&self) -> Duration {
        self.period / POLLS_PER_TICK
    }

    fn cycle(
        &mut self,
        ctx: &mut RoleContext<kinds::Controller>,
        report: &mut CycleReport,
    ) -> Result<CycleOutcome, RoleError> {
        // inline (simulated time): what the autopilot sent since the last turn
        self.receiver.pump();
        // lease: who may write to the autopilot
        let t0 = monotonic_ns();
        let arbiter = &mut self.arbiter;
        self.lease_in.drain(|l| arbiter.observe(l, t0))?;
        let standby_ap = &mut self.standby_ap;
        let holding = self.arbiter.is_active();
        self.telemetry_in.drain(|t| {
            if !holding && t.validate().is_ok() {
                *standby_ap = AutopilotState::from_telemetry(t);
            }
        })?;
        let change = self.arbiter.decide(t0);
        let active = self.arbiter.is_active();
        if change == LeaseChange::TookOver {
            // fly from this poll on (the holder's last tick was the silence window or more ago), from
            // the reference the holder last published
            self.next_tick_ns = t0;
            self.term_start_ns = Some(t0);
            let before = self.arbiter.highest_seen();
            if let Some(l) = before {
                self.tracker.adopt(l);
            }
            self.heard_before_term = before.is_some_and(|l| l.flags & LEASE_LINK_HEARD != 0);
            self.hold_ticks_base = self.tracker.hold_ticks();
            self.term_sent = 0;
            // a new term publishes like a new process: sequence and counters from zero
            self.telemetry_seq = 0;
            self.ticks = 0;
            self.missed_ticks = 0;
            tracing::info!(
                "aeris controller `{}`: took the autopilot lease (epoch {})",
                ctx.spec.name,
                self.arbiter.epoch()
            );
        } else if change == LeaseChange::SteppedDown {
            tracing::info!(
                "aeris controller `{}`: another controller holds the autopilot lease, standing by",
                ctx.spec.name
            );
        }
        if active {
            let mut lease = self.arbiter.lease(t0, self.term_sent);
            self.tracker.write_handover(&mut lease);
            if self.heard_before_term || self.ap_cache.last_heartbeat_ns.is_some() {
                lease.flags |= LEASE_LINK_HEARD;
            }
            self.lease_out.publish(&lease)?;
        }
        if t0 < self.next_tick_ns {
            return Ok(CycleOutcome::Idle);
        }
        self.next_tick_ns += self.period_ns;
        if t0 > self.next_tick_ns {
            // a control tick was skipped: count it and re-anchor instead of bursting
            let late = t0 - self.next_tick_ns;
            if active {
                self.missed_ticks += late / self.period_ns + 1;
            }
            self.next_tick_ns = t0 + self.period_ns - late % self.period_ns;
        }

        // read
        let tracker = &mut self.tracker;
        self.setpoints.drain(|sp| {
            let _ = tracker.offer(sp, t0);
        })?;
        // Never block the real-time tick on the receive thread (std mutexes have no
        // priority inheritance): when the lock is busy, fly on the previous copy.
        if let Ok(heard) = self.shared.try_lock() {
            self.ap_cache = heard.state;
            self.ledger = heard.ledger;
        }
        self.watch_link(t0, &ctx.spec.name)?;
        let t1 = monotonic_ns();
        if !active {
            // a standby keeps the setpoints and the holder's view, and writes nothing; its
            // tracker takes the holder's reference when it takes over
            report.stage("read", t1 - t0);
            report.counters = self.counters();
            return Ok(CycleOutcome::Worked);
        }
        let ap = self
            .ap_cache
            .or_else(&self.standby_ap, self.term_start_ns.unwrap_or(0));

        // track
        let view = ap.vehicle_view(self.tracker.config().floor());
        let landed = view.landed;
        let cmd = self.tracker.tick(t1, &view);
        let t2 = monotonic_ns();
        self.ticks += 1;

        // send
        let time_boot_ms = ((t2.saturating_sub(self.start_ns)) / 1_000_000) as u32;
        if self.send(&position_target_message(&cmd, time_boot_ms, self.target)) {
            self.sent += 1;
            self.term_sent += 1;
            self.sequencer.setpoint_sent(t2);
        }
        let link_up = ap.link_up(t2);
        let status = AutopilotStatus {
            link_up,
            armed: ap.armed,
            offboard: ap.offboard,
            landing_mode: ap.landing_mode,
            landed,
        };
        let active = self.tracker.active(t2).map(|(sp, _)| *sp);
        // a firmware that lands by itself is handed the landing once over the landing point
        // (its land mode descends where the vehicle is)
        let over_landing_point = active.zip(view.position).is_some_and(|(sp, p)| {
            let (dn, de) = (sp.position[0] - p[0], sp.position[1] - p[1]);
            (dn * dn + de * de).sqrt() <= sp.acceptance_radius.clamp(0.5, 2.0)
        });
        let intent = FlightIntent {
            wants_flight: self.tracker.wants_flight(t2, landed),
            landing: cmd.mode == Some(ActionMode::Land) && over_landing_point,
            // a take-off climbs from where the vehicle stands to the setpoint's height
            takeoff_height_m: active.map_or(0.0, |sp| {
                sp.position[2]
                    - view
                        .position
                        .map_or(self.tracker.config().floor(), |p| p[2])
            }),
        };
        // no command goes out before the autopilot's heartbeat named its ids and firmware
        let requests = self.sequencer.step(
            t2,
            AutopilotStatus {
                link_up: link_up && self.ledger.bound.is_some(),
                ..status
            },
            intent,
        );
        if requests.heartbeat {
            self.send(&companion_heartbeat());
        }
        if let Some(params) = requests.set_mode {
            self.command(
                MavCmd::MAV_CMD_DO_SET_MODE,
                three_params(params),
                requests.confirmation,
            );
        }
        if requests.arm {
            self.command(
                MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
                three_params([1.0, 0.0, 0.0]),
                requests.confirmation,
            );
        }
        if let Some(height) = requests.takeoff_m {
            self.command(
                MavCmd::MAV_CMD_NAV_TAKEOFF,
                takeoff_params(height),
                requests.confirmation,
            );
        }
        // Telemetry carries what the autopilot reported; nothing is published before its
        // first LOCAL_POSITION_NED (a made-up position would be taken as real downstream).
        let Some(position_ned) = ap.position_ned else {
            report.stage("read", t1 - t0);
            report.stage("track", t2 - t1);
            report.counters = self.counters();
            return Ok(CycleOutcome::Worked);
        };
        let attitude = ap.attitude.unwrap_or([0.0; 3]);
        self.telemetry_seq += 1;
        let telemetry = VehicleTelemetry {
            seq: self.telemetry_seq,
            stamp_ns: t2,
            autopilot_time_ms: ap.time_boot_ms,
            armed: u8::from(ap.armed),
            offboard: u8::from(ap.offboard),
            link_up: u8::from(link_up),
            landed: u8::from(landed),
            position: ned_to_neu(position_ned),
            velocity: ned_to_neu(ap.velocity_ned),
            attitude,
            controller_ticks: self.ticks,
            controller_missed_ticks: self.missed_ticks,
            setpoints_refused: self.tracker.refused(),
            hold_ticks: self.tracker.hold_ticks() - self.hold_ticks_base,
        };
        self.telemetry.publish(&telemetry)?;
        let t3 = monotonic_ns();

        report.stage("read", t1 - t0);
        report.stage("track", t2 - t1);
        report.stage("send", t3 - t2);
        report.counters = self.counters();
        Ok(CycleOutcome::Worked)
    }

    fn shutdown(&mut self, _ctx: &mut RoleContext<kinds::Controller>) {
        self.receiver.stop();
    }
}
