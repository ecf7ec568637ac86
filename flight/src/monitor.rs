//! Watching a flight from the outside: hub reports, setpoints and telemetry -> progress,
//! the per-cycle trace and the summary.

use crate::autopilot_link::{AutopilotEvent, LinkFollower};
use crate::event::FlightFailure;
use crate::telemetry::{RestartSafeCounters, controller_counters, in_the_air};
use crate::video_start::FirstDecisionOnVideo;
use aeris_runtime::MissionSpec;
use aeris_runtime::bus::{BusError, FlightBus, TypedSubscriber};
use aeris_runtime::stats::{mean_std, percentile};
use aeris_schemas::{
    ActionMode, AutopilotLinkStatus, BoundSetpoint, HubCounts, HubReport, VehicleTelemetry, topics,
};
use serde::Serialize;

/// What a finished flight reports (`aeris run --json` prints this as one line).
#[derive(Debug, Clone, Serialize)]
pub struct FlightSummary {
    /// Flight name (namespace prefix).
    pub flight: String,
    /// The vehicle ended within the acceptance radius of the goal (and landed, for a land goal).
    pub reached_goal: bool,
    /// Distance from the final position to the goal (m).
    pub final_distance_m: f64,
    /// Final position [N, E, U].
    pub final_position: [f64; 3],
    /// Time of the flight (s), on the flight's clock: wall-clock, or simulated
    /// ([`FlightSummary::clock`]).
    pub duration_s: f64,
    /// The clock the flight ran on.
    pub clock: crate::FlightClock,
    /// Wall-clock time the flight took (s): `duration_s` on the wall clock; on simulated
    /// time, how long its computation took.
    pub wall_s: f64,
    /// Semantic cycles: committed decisions plus reuses of the last valid one (over every
    /// hub process of the flight).
    pub cycles: u64,
    /// Cycles that committed a fresh decision.
    pub cycles_committed: u64,
    /// Mean cycle time (start of cycle -> commit) over committed cycles (s).
    pub ct_mean_s: f64,
    /// Standard deviation of the cycle time (s).
    pub ct_std_s: f64,
    /// 95th percentile of the cycle time (s).
    pub ct_p95_s: f64,
    /// Mean stage durations (s): perception, reasoning, routing, binding.
    pub stages_mean_s: StageMeans,
    /// Execution error rate: reuses (late, rejected or missing decisions) over cycles.
    pub eer: f64,
    /// Mean compute time of the committed cycles on this machine (s): the wall-clock work
    /// of the perception stages and the reasoner (`compute_time`), what the cycle would
    /// take on the wall clock without waiting; on simulated time too, where `ct_mean_s` is 0.
    pub ct_compute_mean_s: f64,
    /// Its 95th percentile (s).
    pub ct_compute_p95_s: f64,
    /// Cycles whose compute time exceeded the decision deadline, or without a fresh
    /// decision, over cycles: the EER this machine's compute alone would give.
    pub eer_compute: f64,
    /// What the hub did with the decisions and states it received, totalled over every hub
    /// process of the flight (flat in the JSON: `decisions_received`, ...).
    #[serde(flatten)]
    pub hub: HubCounts,
    /// Controller ticks.
    pub controller_ticks: u64,
    /// Controller ticks that missed their deadline.
    pub controller_missed_ticks: u64,
    /// Setpoints the controller refused.
    pub controller_refused_setpoints: u64,
    /// Controller ticks that held position because no fresh setpoint had arrived within
    /// the setpoint timeout.
    pub controller_hold_ticks: u64,
    /// Longest interval between two consecutive hub setpoints (by the hub's publish
    /// stamps, over consecutive sequence numbers), in ms.
    pub max_setpoint_gap_ms: f64,
    /// Median interval between consecutive hub setpoints (ms): the normal period.
    pub setpoint_period_ms: f64,
    /// Hot swaps completed during the flight.
    pub swaps_done: u64,
    /// Hot swaps refused or rolled back during the flight.
    pub swaps_failed: u64,
    /// Role restarts by the supervisor.
    pub role_restarts: u64,
    /// Live moves of roles between executors (dynamic scheduling and `aeris migrate`).
    pub migrations: u64,
    /// Steps of the variant ladder (automatic swaps to a lighter or heavier variant).
    pub variant_steps: u64,
    /// Roles found alive but silent and replaced.
    pub stalls: u64,
    /// Subgoals in the mission.
    pub subgoals_total: u64,
    /// Highest active step the hub's ATT reached (1-based).
    pub max_active_step: u64,
    /// The attention trace, compressed to the sequence of distinct active steps.
    pub attention_steps: Vec<u16>,
    /// The autopilot flown (firmware, ids, MAVLink version sent), once its HEARTBEAT
    /// was heard.
    pub autopilot: Option<String>,
    /// Times the autopilot link was lost in flight (no HEARTBEAT for the link timeout).
    pub autopilot_link_losses: u64,
    /// Commands the autopilot refused (COMMAND_ACK other than accepted / in progress).
    pub autopilot_commands_refused: u64,
    /// Committed cycles the hub gated without present occupancy (absent or stale: no depth
    /// source), keeping to the geofence and the conservative altitude (of the reports seen).
    pub commits_without_occupancy: u64,
    /// Committed decisions the gate clamped for want of occupancy (of the reports seen).
    pub no_occupancy_clamps: u64,
    /// Seconds from the capture of the first camera frame after the flight was up to the
    /// first decision taken on an S_t of it or a later frame: for a video stream that starts
    /// after the roles, how long the stack flew on telemetry alone once pictures came
    /// (`None`: no frame, or no decision on one).
    pub first_decision_on_video_s: Option<f64>,
    /// The recording, when the flight was recorded ([`crate::FlightBuilder::record`]).
    pub recording: Option<crate::RecordingSummary>,
    /// The links to other hosts as last measured (empty for a flight on one host).
    pub links: Vec<LinkSummary>,
    /// How the roles got priority over outside work: `cgroup-v2`, `cgroup-v1`, `nice` or
    /// `none` ([`aeris_orchestrator::priority`]).
    pub priority: String,
    /// The same in words: the group and its weight, the nice value, or why none.
    pub priority_detail: String,
    /// The memory the roles on the flight's host held: each role's peak, and the flight's.
    pub memory: crate::memory::MemorySummary,
    /// A flight of several vehicles: each vehicle's controller, the closest two came,
    /// collisions (`None` for one vehicle).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fleet: Option<crate::fleet::FleetSummary>,
}

/// A link to another host at the end of a flight, as its bridge measured it.
#[derive(Debug, Clone, Serialize)]
pub struct LinkSummary {
    /// The other host.
    pub host: String,
    /// Smoothed round trip (ms; `None`: never answered).
    pub rtt_ms: Option<f64>,
    /// Probes sent and answered within the link timeout.
    pub probes: u64,
    /// Probes answered.
    pub answered: u64,
    /// Probes lost over the last window (fraction).
    pub loss: f64,
    /// The other host's clock minus this host's (ms).
    pub clock_offset_ms: Option<f64>,
    /// Mean time to encode a frame for the link (ms; `None`: none encoded).
    pub frame_coding_ms: Option<f64>,
}

impl LinkSummary {
    /// The summary of `link`.
    pub fn of(link: &aeris_schemas::HostLinkStatus) -> Self {
        LinkSummary {
            host: link.host.as_str_lossy().to_string(),
            rtt_ms: link.rtt_ms(),
            probes: link.probes,
            answered: link.answered,
            loss: link.loss(),
            clock_offset_ms: (link.answered > 0).then(|| link.clock_offset_ns as f64 / 1e6),
            frame_coding_ms: (link.frame_coding_ns > 0).then(|| link.frame_coding_ns as f64 / 1e6),
        }
    }
}

/// Mean stage durations.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct StageMeans {
    /// Frame capture -> S_t published.
    pub perception: f64,
    /// S_t -> D_t published.
    pub reasoning: f64,
    /// D_t published -> received by the hub.
    pub routing: f64,
    /// Received -> bound setpoint committed.
    pub binding: f64,
}

// Indices into the hub counters.

// Indices into the controller counters.
const TICKS: usize = 0;
const MISSED: usize = 1;
const REFUSED: usize = 2;
const HOLDS: usize = 3;

/// Most cycles a flight's trace keeps (a day at the default 2 s heartbeat).
pub const MAX_TRACE_CYCLES: usize = 43_200;

/// One semantic cycle as the hub reported it, with the vehicle's pose at that moment:
/// the rows of `cycles.jsonl`, what `aeris plot timing` and `aeris plot fpv` draw.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CycleTrace {
    /// Semantic cycle number.
    pub cycle: u64,
    /// Seconds since the monitor started when the hub reported the cycle.
    pub t_s: f64,
    /// Cycle time (s), 0 when the cycle reused a decision.
    pub ct_s: f64,
    /// Stage durations (s): perception, reasoning, routing, binding.
    pub stages_s: [f64; 4],
    /// A fresh decision was committed.
    pub committed: bool,
    /// The last valid decision was reused (late, invalid or missing).
    pub reused: bool,
    /// Active instruction step (1-based).
    pub active_step: u16,
    /// Vehicle position `[N, E, U]`, when telemetry had arrived.
    pub position: Option<[f32; 3]>,
    /// Vehicle yaw (rad), when telemetry had arrived.
    pub yaw: Option<f32>,
    /// The latest setpoint the hub had bound by then: its position `[N, E, U]`...
    #[serde(default)]
    pub setpoint: Option<[f32; 3]>,
    /// ... and its mode (`goto`, `hover`, `land`, ...): what the committed decisions asked.
    #[serde(default)]
    pub setpoint_mode: Option<String>,
}

/// Subscribes to a flight's hub reports and telemetry and keeps the tallies.
pub struct FlightMonitor {
    reports: TypedSubscriber<HubReport>,
    telemetry: TypedSubscriber<VehicleTelemetry>,
    setpoints: TypedSubscriber<BoundSetpoint>,
    link: TypedSubscriber<AutopilotLinkStatus>,
    link_follower: LinkFollower,
    video_start: FirstDecisionOnVideo,
    autopilot_events: Vec<AutopilotEvent>,
    last_setpoint: Option<(u64, u64)>,
    last_bound: Option<([f32; 3], u8)>,
    setpoint_gaps_ms: Vec<f64>,
    setpoint_gap_ends_ns: Vec<u64>,
    /// `None` when the mission does not say where its goal is (the VLN setting).
    goal: Option<[f32; 3]>,
    radius: f32,
    land_goal: bool,
    subgoals: u16,
    ct_s: Vec<f64>,
    stage_sums: [f64; 4],
    hub: RestartSafeCounters<{ HubCounts::LEN }>,
    controller: RestartSafeCounters<4>,
    last_report: Option<HubReport>,
    trace: Vec<CycleTrace>,
    started_ns: u64,
    invalid_reports: u64,
    last_telemetry: Option<VehicleTelemetry>,
    attention_steps: Vec<u16>,
    airborne: bool,
    commits_without_occupancy: u64,
    no_occupancy_clamps: u64,
    fleet: Option<crate::fleet::FleetMonitor>,
}

impl FlightMonitor {
    /// Also watch every vehicle of a flight of `vehicles` (more than one): their
    /// controllers, separation and collisions; the flight has landed when all have.
    pub fn watch_fleet(&mut self, bus: &FlightBus, vehicles: u8) -> Result<(), BusError> {
        self.fleet = (vehicles > 1)
            .then(|| crate::fleet::FleetMonitor::new(bus, vehicles))
            .transpose()?;
        Ok(())
    }

    /// The fleet's watch, in a flight of several vehicles.
    pub fn fleet(&self) -> Option<&crate::fleet::FleetMonitor> {
        self.fleet.as_ref()
    }

    /// Watch the flight on `bus` flying `mission` from `started_ns` of the flight's clock.
    pub fn new(bus: &FlightBus, mission: &MissionSpec, started_ns: u64) -> Result<Self, BusError> {
        let land_goal = mission
            .subgoals
            .last()
            .and_then(|s| s.action_mode())
            .is_some_and(|a| a == ActionMode::Land);
        Ok(Self {
            reports: bus.subscriber::<topics::HubReport>()?,
            telemetry: bus.subscriber::<topics::VehicleTelemetry>()?,
            setpoints: bus.subscriber::<topics::HubSetpoint>()?,
            link: bus.subscriber::<topics::ControllerLink>()?,
            link_follower: LinkFollower::default(),
            video_start: FirstDecisionOnVideo::new(bus, started_ns)?,
            autopilot_events: Vec::new(),
            last_setpoint: None,
            last_bound: None,
            setpoint_gaps_ms: Vec::new(),
            setpoint_gap_ends_ns: Vec::new(),
            goal: mission.goal(),
            radius: mission.acceptance_radius_m,
            land_goal,
            subgoals: mission.subgoals.len() as u16,
            ct_s: Vec::new(),
            stage_sums: [0.0; 4],
            hub: RestartSafeCounters::default(),
            controller: RestartSafeCounters::default(),
            last_report: None,
            last_telemetry: None,
            attention_steps: Vec::new(),
            airborne: false,
            commits_without_occupancy: 0,
            no_occupancy_clamps: 0,
            fleet: None,
            trace: Vec::new(),
            started_ns,
            invalid_reports: 0,
        })
    }

    /// Drain new reports and telemetry.
    pub fn poll(&mut self) -> Result<(), BusError> {
        self.video_start.poll()?;
        if let Some(fleet) = &mut self.fleet {
            fleet.poll()?;
        }
        while let Some(r) = self.reports.next()? {
            if r.validate().is_err() {
                self.invalid_reports += 1;
                continue;
            }
            if r.committed == 1 {
                if r.occupancy_status() != Some(aeris_schemas::OccupancyStatus::Present) {
                    self.commits_without_occupancy += 1;
                }
                if r.clamp_reasons & aeris_schemas::clamp::NO_OCCUPANCY != 0 {
                    self.no_occupancy_clamps += 1;
                }
                self.ct_s.push(r.ct_ns as f64 * 1e-9);
                for (sum, ns) in self.stage_sums.iter_mut().zip(r.stage_ns) {
                    *sum += ns as f64 * 1e-9;
                }
            }
            self.hub.update(r.seq, r.counts.to_array());
            if self.attention_steps.last() != Some(&r.active_step) {
                self.attention_steps.push(r.active_step);
            }
            if self.trace.len() < MAX_TRACE_CYCLES {
                let t = self.last_telemetry;
                self.trace.push(CycleTrace {
                    cycle: r.cycle,
                    t_s: r.publish_ns.saturating_sub(self.started_ns) as f64 * 1e-9,
                    ct_s: r.ct_ns as f64 * 1e-9,
                    stages_s: r.stage_ns.map(|ns| ns as f64 * 1e-9),
                    committed: r.committed == 1,
                    reused: r.reused == 1,
                    active_step: r.active_step,
                    position: t.map(|t| t.position),
                    yaw: t.map(|t| t.attitude[2]),
                    setpoint: self.last_bound.map(|(p, _)| p),
                    setpoint_mode: self.last_bound.map(|(_, m)| {
                        aeris_schemas::ActionMode::from_u8(m)
                            .map_or_else(|| format!("mode {m}"), |a| a.name().to_string())
                    }),
                });
            }
            self.last_report = Some(r);
        }
        if let Some(t) = self.telemetry.latest()?
            && t.validate().is_ok()
        {
            self.controller.update(t.seq, controller_counters(&t));
            self.airborne |= in_the_air(&t);
            self.last_telemetry = Some(t);
        }
        let (follower, news) = (&mut self.link_follower, &mut self.autopilot_events);
        self.link.drain(|s| follower.update(s, news))?;
        let (last, gaps, ends, bound) = (
            &mut self.last_setpoint,
            &mut self.setpoint_gaps_ms,
            &mut self.setpoint_gap_ends_ns,
            &mut self.last_bound,
        );
        self.setpoints.drain(|sp| {
            *bound = Some((sp.position, sp.mode));
            // only consecutive numbers of one hub process measure its period; a skipped
            // number is a sample this monitor missed, not a late hub
            if let Some((seq, ns)) = *last
                && sp.seq == seq + 1
                && sp.publish_ns >= ns
            {
                gaps.push((sp.publish_ns - ns) as f64 * 1e-6);
                ends.push(sp.publish_ns);
            }
            *last = Some((sp.seq, sp.publish_ns));
        })?;
        Ok(())
    }

    /// What happened on the autopilot link since the last call.
    pub fn take_autopilot_events(&mut self) -> Vec<AutopilotEvent> {
        std::mem::take(&mut self.autopilot_events)
    }

    /// When the controller heard no autopilot within its link timeout: what it heard
    /// instead, naming the URL (the flight ends on it).
    pub fn silent_autopilot(&self) -> Option<String> {
        self.link_follower.silent()
    }

    /// Hub reports that failed validation (and were not counted).
    pub fn invalid_reports(&self) -> u64 {
        self.invalid_reports
    }

    /// The per-cycle trace so far (at most [`MAX_TRACE_CYCLES`]).
    pub fn trace(&self) -> &[CycleTrace] {
        &self.trace
    }

    /// Latest vehicle position, if any telemetry arrived.
    pub fn position(&self) -> Option<[f32; 3]> {
        self.last_telemetry.map(|t| t.position)
    }

    /// `true` when the vehicle is on the ground after having flown (the agent stopped).
    pub fn landed_after_flight(&self) -> bool {
        if let Some(fleet) = &self.fleet {
            return fleet.all_landed_after_flight();
        }
        self.airborne && self.last_telemetry.is_some_and(|t| t.landed == 1)
    }

    /// Cycle times (s) of the committed cycles so far.
    pub fn ct_samples_s(&self) -> &[f64] {
        &self.ct_s
    }

    /// Distance to the goal (m), if the position and the goal are known.
    pub fn distance_to_goal(&self) -> Option<f32> {
        Some(dist(self.position()?, self.goal?))
    }

    /// `true` when the goal is reached: within the acceptance radius (landed, for a land goal).
    pub fn reached_goal(&self) -> bool {
        match (self.last_telemetry, self.distance_to_goal()) {
            (Some(t), Some(d)) => d <= self.radius && (!self.land_goal || t.landed == 1),
            _ => false,
        }
    }

    /// Active step (1-based) and the subgoal count.
    pub fn active_step(&self) -> (u16, u16) {
        (
            self.last_report.map(|r| r.active_step).unwrap_or(0),
            self.subgoals,
        )
    }

    /// Mean cycle time so far (s).
    pub fn ct_mean_s(&self) -> f64 {
        mean_std(&self.ct_s).map(|(m, _)| m).unwrap_or(0.0)
    }

    /// Semantic cycles so far: committed decisions plus reuses of the last valid one.
    pub fn cycles(&self) -> u64 {
        let hub = self.hub_totals();
        hub.decisions_committed.saturating_add(hub.decisions_reused)
    }

    /// Execution error rate so far: reuses (a late, invalid or missing decision) over cycles.
    pub fn eer(&self) -> f64 {
        match self.cycles() {
            0 => 0.0,
            n => self.hub_totals().decisions_reused as f64 / n as f64,
        }
    }

    /// Cycles that reused the last valid decision so far: heartbeats that brought no fresh
    /// valid decision in time.
    pub fn reused(&self) -> u64 {
        self.hub_totals().decisions_reused
    }

    /// The longest interval between consecutive hub setpoints whose later one was published
    /// in `[from_ns, to_ns]` (ms; 0 when none), and the median of all intervals so far.
    pub fn setpoint_gaps_ms(&self, from_ns: u64, to_ns: u64) -> (f64, f64) {
        let max = self
            .setpoint_gap_ends_ns
            .iter()
            .zip(&self.setpoint_gaps_ms)
            .filter(|(end, _)| (from_ns..=to_ns).contains(*end))
            .map(|(_, g)| *g)
            .fold(0.0, f64::max);
        (max, percentile(&self.setpoint_gaps_ms, 50.0).unwrap_or(0.0))
    }

    /// Decisions the hub received past their deadline so far (also counted as rejected).
    pub fn late(&self) -> u64 {
        self.hub_totals().decisions_late
    }

    /// Decisions rejected so far (over every hub process of the flight).
    pub fn rejected(&self) -> u64 {
        self.hub_totals().decisions_rejected
    }

    /// Decisions received (superseded ones included) and committed so far, over every hub
    /// process of the flight.
    pub fn decisions_received_committed(&self) -> (u64, u64) {
        let hub = self.hub_totals();
        (
            hub.decisions_received + hub.decisions_superseded,
            hub.decisions_committed,
        )
    }

    /// The hub's counts so far, over every hub process of the flight.
    pub fn hub_totals(&self) -> HubCounts {
        HubCounts::from_array(core::array::from_fn(|i| self.hub.total(i)))
    }

    /// The summary of the flight so far.
    pub fn summary(&self, flight: &str, duration_s: f64, role_restarts: u64) -> FlightSummary {
        let (ct_mean, ct_std) = mean_std(&self.ct_s).unwrap_or((0.0, 0.0));
        let n = self.ct_s.len().max(1) as f64;
        let p = self.position().unwrap_or([f32::NAN; 3]);
        FlightSummary {
            flight: flight.to_string(),
            reached_goal: self.reached_goal(),
            final_distance_m: self.distance_to_goal().map(f64::from).unwrap_or(f64::NAN),
            final_position: p.map(f64::from),
            duration_s,
            clock: crate::FlightClock::Wall,
            wall_s: duration_s,
            cycles: self.cycles(),
            cycles_committed: self.hub_totals().decisions_committed,
            ct_mean_s: ct_mean,
            ct_std_s: ct_std,
            ct_p95_s: percentile(&self.ct_s, 95.0).unwrap_or(0.0),
            stages_mean_s: StageMeans {
                perception: self.stage_sums[0] / n,
                reasoning: self.stage_sums[1] / n,
                routing: self.stage_sums[2] / n,
                binding: self.stage_sums[3] / n,
            },
            eer: self.eer(),
            ct_compute_mean_s: 0.0,
            ct_compute_p95_s: 0.0,
            eer_compute: 0.0,
            hub: self.hub_totals(),
            controller_ticks: self.controller.total(TICKS),
            controller_missed_ticks: self.controller.total(MISSED),
            controller_refused_setpoints: self.controller.total(REFUSED),
            controller_hold_ticks: self.controller.total(HOLDS),
            max_setpoint_gap_ms: self.setpoint_gaps_ms.iter().copied().fold(0.0, f64::max),
            setpoint_period_ms: percentile(&self.setpoint_gaps_ms, 50.0).unwrap_or(0.0),
            swaps_done: 0,
            swaps_failed: 0,
            role_restarts,
            migrations: 0,
            variant_steps: 0,
            stalls: 0,
            subgoals_total: self.subgoals as u64,
            max_active_step: self.attention_steps.iter().copied().max().unwrap_or(0) as u64,
            attention_steps: self.attention_steps.clone(),
            autopilot: self.link_follower.autopilot(),
            autopilot_link_losses: self.link_follower.losses(),
            autopilot_commands_refused: self.link_follower.commands_refused(),
            commits_without_occupancy: self.commits_without_occupancy,
            no_occupancy_clamps: self.no_occupancy_clamps,
            first_decision_on_video_s: self.video_start.seconds(),
            recording: None,
            links: Vec::new(),
            priority: String::new(),
            priority_detail: String::new(),
            memory: Default::default(),
            fleet: self.fleet.as_ref().map(|f| f.summary()),
        }
    }
}

fn dist(a: [f32; 3], b: [f32; 3]) -> f32 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// How a flight went.
#[derive(Debug, Clone)]
pub struct FlightOutcome {
    /// The summary (`aeris run --json` prints it).
    pub summary: FlightSummary,
    /// Why it ended early, if it did.
    pub failure: Option<FlightFailure>,
    /// Cycle times (s) of every committed cycle.
    pub ct_samples_s: Vec<f64>,
    /// Compute times (s) of every committed cycle (`FlightSummary::ct_compute_mean_s`).
    pub ct_compute_samples_s: Vec<f64>,
    /// Cycles over the deadline on compute, or without a fresh decision
    /// (`FlightSummary::eer_compute`).
    pub compute_misses: u64,
    /// The per-cycle trace (what the run directory's `cycles.jsonl` holds).
    pub trace: Vec<CycleTrace>,
}
