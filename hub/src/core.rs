//! The hub's pure state machine: ordered delivery, deadline, gate, last-valid reuse, ATT.
//!
//! [`HubCore`] never reads a clock or touches a transport: the role feeds it messages and
//! the time, which makes every rule testable with constructed inputs.
//!
//! # Rules
//! - **Source**: decisions carry their reasoner's instance number. The hub follows the
//!   newest live instance ([`SourceSelector`]): a newer one (hot swap, restart) takes over
//!   with its first decision that passes the deadline and the gate (the sequence check
//!   starts over for it); until then its rejected decisions count as rejections but do not
//!   cost the running reasoner its slot. An older instance's decisions are ignored (counted
//!   as superseded, not as rejections) unless the newer one has been silent for a whole
//!   slot (`heartbeat_period + decision_deadline`).
//! - **Order**: a decision whose sequence number is older than or equal to the last one is
//!   rejected (see [`SequenceTracker`]; a `1` with a cycle start newer than any seen is a
//!   restarted reasoner and resynchronises).
//! - **Deadline**: a decision received more than `decision_deadline` after its
//!   `cycle_start_ns` is late: rejected (counted as late and rejected). A `cycle_start_ns` in
//!   the future is rejected too (it would defeat the deadline).
//! - **Gate**: [`DecisionGate::admit`] against the latest vehicle position and occupancy.
//! - **Reuse (EER accounting)**: after a commit of cycle k (started at `s`), the next
//!   semantic cycle is due by `s + heartbeat_period + decision_deadline`; each later
//!   heartbeat period is one more slot. A slot that closes without a fresh commit counts one
//!   reuse of the last valid decision and emits a report with `reused = 1`. A rejected or
//!   late decision counts its slot's reuse at once (at most one per slot, so a burst of
//!   garbage counts once). Nothing is reused before the first valid decision.
//! - **Setpoint**: a decision is gated once, when it is committed; every tick re-publishes
//!   the setpoint it was bound to then (in-place actions stay anchored where they were
//!   committed, a goto keeps the clamp it got), with a fresh sequence number, time, active
//!   step and `reused` flag. A new S_t whose occupancy shows the way from the vehicle to that
//!   setpoint blocked ([`DecisionGate::check_way`]) turns it into a hold where the vehicle
//!   was when that happened (mode hover), latched while the vehicle drifts, until a later
//!   S_t shows the way clear again or a fresh decision commits. `reused = 1` once its slot
//!   closed without a fresh decision. No setpoint before the first valid decision.
//! - **ATT** runs on every valid state; its active step annotates every setpoint and report.
//!   With `no_att`, the active step is the reasoner's declared step.

use crate::att::{Attention, AttentionResult};
use crate::gate::{DecisionGate, GateError};
use crate::ordering::{SeqVerdict, SequenceTracker, SourceSelector, SourceVerdict};
use aeris_schemas::{
    BoundSetpoint, Decision, HubReport, MAX_SUBGOALS, OccupancyGrid, PerceptionState, StateError,
    all_finite,
};

/// Timing and mode of the hub.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HubConfig {
    /// Semantic heartbeat period (ns, >= 1).
    pub heartbeat_period_ns: u64,
    /// A decision received later than this after its cycle start is late (ns).
    pub decision_deadline_ns: u64,
    /// No-ATT ablation: the active step is the reasoner's declared step.
    pub no_att: bool,
}

/// The hub's counters (also carried by every [`HubReport`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct HubCounters {
    /// Decisions received.
    pub decisions_received: u64,
    /// Decisions committed.
    pub decisions_committed: u64,
    /// Decisions rejected (invalid, infeasible, out of order, late, future timestamp).
    pub decisions_rejected: u64,
    /// Decisions received after the deadline (also in `decisions_rejected`).
    pub decisions_late: u64,
    /// Cycles that reused the last valid decision.
    pub decisions_reused: u64,
    /// Sequence gaps detected.
    pub sequence_gaps: u64,
    /// Out-of-order or duplicate decisions.
    pub sequence_reorders: u64,
    /// States received.
    pub states_received: u64,
    /// States rejected by validation.
    pub states_rejected: u64,
    /// Decisions of an older reasoning instance ignored while a newer one was live.
    pub decisions_superseded: u64,
    /// Switches to another reasoning instance.
    pub source_switches: u64,
}

/// Why a decision was rejected.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum RejectReason {
    /// The gate refused it (invalid, infeasible).
    #[error("gate: {0}")]
    Gate(GateError),
    /// Its sequence number is older than or equal to the last one (or 0).
    #[error("sequence number {seq} is out of order ({verdict:?})")]
    Sequence {
        /// The sequence number received.
        seq: u64,
        /// How it was classified.
        verdict: SeqVerdict,
    },
    /// Its cycle start lies in the future of its receive time.
    #[error("cycle start {cycle_start_ns} ns is after its receive time {receive_ns} ns")]
    FutureTimestamp {
        /// The decision's cycle start.
        cycle_start_ns: u64,
        /// When the hub received it.
        receive_ns: u64,
    },
}

/// What the hub did with one decision.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DecisionVerdict {
    /// Admitted: the setpoint it binds to now (not yet published: `seq` 0) and the cycle's
    /// report (to publish).
    Committed {
        /// The bound setpoint.
        setpoint: BoundSetpoint,
        /// The committed cycle's report.
        report: HubReport,
    },
    /// Rejected; the last valid decision stays in force. `report` is the reuse report when
    /// this rejection was the first of its slot (publish it).
    Rejected {
        /// Why.
        reason: RejectReason,
        /// Reuse report, if this rejection counted a reuse.
        report: Option<HubReport>,
    },
    /// From an older reasoning instance while a newer one is live: ignored, not a
    /// rejection (it never had a slot).
    Superseded {
        /// The instance that sent it.
        source: u32,
        /// The instance the hub follows.
        active: u32,
    },
    /// Past the deadline; rejected like [`DecisionVerdict::Rejected`].
    Late {
        /// Receive time minus cycle start (ns).
        age_ns: u64,
        /// Reuse report, if this rejection counted a reuse.
        report: Option<HubReport>,
    },
}

/// What one tick produces.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TickOutput {
    /// The setpoint to publish this tick (none before the first valid decision).
    pub setpoint: Option<BoundSetpoint>,
    /// A reuse report, when a slot closed without a fresh decision.
    pub report: Option<HubReport>,
}

/// Why a [`HubCore`] could not be built.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum HubCoreError {
    /// The gate's subgoal count and ATT's differ.
    #[error("the gate has {gate} subgoals but attention has {attention}")]
    SubgoalMismatch {
        /// Subgoals in the gate's limits.
        gate: usize,
        /// Subgoals ATT scores.
        attention: usize,
    },
    /// The start position is not finite.
    #[error("the start position is not finite")]
    BadStart,
}

/// The last valid decision and the setpoint the gate bound it to when it was committed.
#[derive(Debug, Clone, Copy, PartialEq)]
struct LastValid {
    decision: Decision,
    /// As the gate bound it (`seq`, `publish_ns`, `active_step` and `reused` are set anew
    /// every time it is published).
    bound: BoundSetpoint,
}

/// The hub's pure state machine.
#[derive(Debug)]
pub struct HubCore {
    gate: DecisionGate,
    attention: Attention,
    config: HubConfig,
    subgoals: usize,
    sources: SourceSelector,
    sequence: SequenceTracker,
    counters: HubCounters,
    position: [f32; 3],
    telemetry_seen: bool,
    grid: OccupancyGrid,
    grid_present: bool,
    att: AttentionResult,
    last: Option<LastValid>,
    hold: Option<[f32; 3]>,
    /// A valid S_t arrived since the committed setpoint's way was last checked.
    way_check_due: bool,
    slot_deadline_ns: u64,
    slot_accounted: bool,
    reuse_active: bool,
    reuses_since_commit: u64,
    setpoint_seq: u64,
    report_seq: u64,
    last_state_ns: Option<u64>,
}

impl HubCore {
    /// A hub with `gate`, `attention` (same subgoal count) and `config`; the vehicle is
    /// assumed at `start` until telemetry or a state says otherwise.
    pub fn new(
        gate: DecisionGate,
        attention: Attention,
        config: HubConfig,
        start: [f32; 3],
    ) -> Result<Self, HubCoreError> {
        let subgoals = gate.limits().subgoals as usize;
        if attention.subgoals() != subgoals {
            return Err(HubCoreError::SubgoalMismatch {
                gate: subgoals,
                attention: attention.subgoals(),
            });
        }
        if !all_finite(&start) {
            return Err(HubCoreError::BadStart);
        }
        let config = HubConfig {
            heartbeat_period_ns: config.heartbeat_period_ns.max(1),
            ..config
        };
        Ok(Self {
            gate,
            attention,
            config,
            subgoals,
            sources: SourceSelector::new(
                config
                    .heartbeat_period_ns
                    .saturating_add(config.decision_deadline_ns),
            ),
            sequence: SequenceTracker::new(),
            counters: HubCounters::default(),
            position: start,
            telemetry_seen: false,
            grid: OccupancyGrid::default(),
            grid_present: false,
            att: AttentionResult::one_hot(0, subgoals),
            last: None,
            hold: None,
            way_check_due: false,
            slot_deadline_ns: 0,
            slot_accounted: false,
            reuse_active: false,
            reuses_since_commit: 0,
            setpoint_seq: 0,
            report_seq: 0,
            last_state_ns: None,
        })
    }

    /// A new state S_t received at `now_ns`: validate (count a reject), keep its occupancy
    /// grid and (until telemetry arrives) its position, and run ATT.
    pub fn on_state(&mut self, state: &PerceptionState, now_ns: u64) -> Result<(), StateError> {
        self.counters.states_received += 1;
        if let Err(e) = state.validate() {
            self.counters.states_rejected += 1;
            return Err(e);
        }
        self.last_state_ns = Some(now_ns);
        self.way_check_due = true;
        self.grid_present = state.occupancy.is_present();
        if self.grid_present {
            self.grid = state.occupancy;
        }
        if !self.telemetry_seen {
            self.position = state.position;
        }
        if !self.config.no_att {
            let declared = self.last.map(|l| l.decision.step);
            self.att = self.attention.update(state, declared);
        }
        Ok(())
    }

    /// The latest vehicle position `[N, E, U]` from telemetry; `false` (ignored) when not
    /// finite.
    pub fn on_telemetry(&mut self, position: [f32; 3]) -> bool {
        if !all_finite(&position) {
            return false;
        }
        self.position = position;
        self.telemetry_seen = true;
        true
    }

    /// A decision received at `now_ns` (also its commit time: binding time 0). See
    /// [`HubCore::on_decision_timed`].
    pub fn on_decision(&mut self, d: &Decision, now_ns: u64) -> DecisionVerdict {
        self.on_decision_timed(d, now_ns, || now_ns)
    }

    /// A decision received at `receive_ns`: order, deadline, gate, then commit.
    /// `commit_clock` is called once, after the gate admitted it, to stamp the commit (the
    /// role passes the monotonic clock).
    pub fn on_decision_timed(
        &mut self,
        d: &Decision,
        receive_ns: u64,
        commit_clock: impl FnOnce() -> u64,
    ) -> DecisionVerdict {
        self.counters.decisions_received += 1;
        let candidate = match self.sources.classify(d.source, receive_ns) {
            SourceVerdict::Superseded { active } => {
                self.sources.supersede();
                self.counters.decisions_superseded = self.sources.superseded();
                return DecisionVerdict::Superseded {
                    source: d.source,
                    active,
                };
            }
            // another instance: judged on its own numbering, adopted only if committed
            SourceVerdict::Switched { .. } => true,
            SourceVerdict::First | SourceVerdict::Active => {
                self.sources.adopt(d.source, receive_ns);
                false
            }
        };
        if !candidate {
            let verdict = self.sequence.observe(d.seq, d.cycle_start_ns);
            self.counters.sequence_gaps = self.sequence.gaps();
            self.counters.sequence_reorders = self.sequence.reorders();
            if !verdict.accepted() {
                return self.reject(
                    RejectReason::Sequence {
                        seq: d.seq,
                        verdict,
                    },
                    receive_ns,
                );
            }
        }
        if d.cycle_start_ns > receive_ns {
            return self.reject_from(
                candidate,
                RejectReason::FutureTimestamp {
                    cycle_start_ns: d.cycle_start_ns,
                    receive_ns,
                },
                receive_ns,
            );
        }
        let age_ns = receive_ns - d.cycle_start_ns;
        if age_ns > self.config.decision_deadline_ns {
            self.counters.decisions_late += 1;
            self.counters.decisions_rejected += 1;
            // a candidate's late decision does not cost the running reasoner its slot
            let report = if candidate {
                None
            } else {
                self.account_reuse(receive_ns)
            };
            return DecisionVerdict::Late { age_ns, report };
        }
        let mut setpoint = match self.gate.admit(d, self.position, self.grid()) {
            Ok(s) => s,
            Err(e) => return self.reject_from(candidate, RejectReason::Gate(e), receive_ns),
        };
        if candidate {
            // the newer instance takes over with this decision; its numbering starts here
            self.sources.adopt(d.source, receive_ns);
            self.counters.source_switches = self.sources.switches();
            self.sequence.resync();
            self.sequence.observe(d.seq, d.cycle_start_ns);
        }
        let commit_ns = commit_clock().max(receive_ns);
        self.last = Some(LastValid {
            decision: *d,
            bound: setpoint,
        });
        self.hold = None;
        // the gate just admitted it against the latest position and occupancy
        self.way_check_due = false;
        self.reuse_active = false;
        self.reuses_since_commit = 0;
        let next = d
            .cycle_start_ns
            .saturating_add(self.config.heartbeat_period_ns)
            .saturating_add(self.config.decision_deadline_ns);
        self.slot_deadline_ns = self.slot_deadline_ns.max(next);
        self.slot_accounted = false;
        self.counters.decisions_committed += 1;
        setpoint.active_step = self.active_step();
        setpoint.publish_ns = commit_ns;
        let mut report = self.base_report(commit_ns);
        report.cycle = d.cycle;
        report.committed = 1;
        report.clamped = setpoint.clamped;
        report.ct_ns = commit_ns.saturating_sub(d.cycle_start_ns);
        report.stage_ns = [
            d.state_stamp_ns.saturating_sub(d.cycle_start_ns),
            d.publish_ns.saturating_sub(d.state_stamp_ns),
            receive_ns.saturating_sub(d.publish_ns),
            commit_ns.saturating_sub(receive_ns),
        ];
        DecisionVerdict::Committed { setpoint, report }
    }

    /// One tick at `now_ns`: close reuse slots that ended, and produce this tick's setpoint.
    pub fn on_tick(&mut self, now_ns: u64) -> TickOutput {
        let mut report = None;
        if self.last.is_some() && now_ns > self.slot_deadline_ns {
            let period = self.config.heartbeat_period_ns;
            let closed = (now_ns - self.slot_deadline_ns - 1) / period + 1;
            let fresh = closed - u64::from(self.slot_accounted);
            self.slot_deadline_ns = self
                .slot_deadline_ns
                .saturating_add(closed.saturating_mul(period));
            self.slot_accounted = false;
            if fresh > 0 {
                self.count_reuses(fresh);
                report = Some(self.reuse_report(now_ns));
            }
        }
        TickOutput {
            setpoint: self.current_setpoint(now_ns),
            report,
        }
    }

    /// Reject a decision of the active instance (`candidate` false: its slot counts a
    /// reuse) or of a candidate instance (not adopted; the active one keeps its slot).
    fn reject_from(
        &mut self,
        candidate: bool,
        reason: RejectReason,
        now_ns: u64,
    ) -> DecisionVerdict {
        if !candidate {
            return self.reject(reason, now_ns);
        }
        self.counters.decisions_rejected += 1;
        DecisionVerdict::Rejected {
            reason,
            report: None,
        }
    }

    fn reject(&mut self, reason: RejectReason, now_ns: u64) -> DecisionVerdict {
        self.counters.decisions_rejected += 1;
        let report = self.account_reuse(now_ns);
        DecisionVerdict::Rejected { reason, report }
    }

    /// Count the current slot's reuse, once, when there is a decision to reuse.
    fn account_reuse(&mut self, now_ns: u64) -> Option<HubReport> {
        if self.last.is_none() || self.slot_accounted {
            return None;
        }
        self.slot_accounted = true;
        self.count_reuses(1);
        Some(self.reuse_report(now_ns))
    }

    fn count_reuses(&mut self, n: u64) {
        self.counters.decisions_reused = self.counters.decisions_reused.saturating_add(n);
        self.reuses_since_commit = self.reuses_since_commit.saturating_add(n);
        self.reuse_active = true;
    }

    fn reuse_report(&mut self, now_ns: u64) -> HubReport {
        let mut r = self.base_report(now_ns);
        r.cycle = self
            .last
            .map_or(0, |l| l.decision.cycle)
            .saturating_add(self.reuses_since_commit);
        r.reused = 1;
        r
    }

    fn base_report(&mut self, now_ns: u64) -> HubReport {
        self.report_seq += 1;
        let att = self.attention_now();
        let l = self.subgoals.min(MAX_SUBGOALS);
        let mut attention = [0.0; MAX_SUBGOALS];
        attention[..l].copy_from_slice(&att.alpha[..l]);
        let c = &self.counters;
        HubReport {
            seq: self.report_seq,
            cycle: 0,
            publish_ns: now_ns,
            ct_ns: 0,
            stage_ns: [0; 4],
            committed: 0,
            reused: 0,
            clamped: 0,
            reserved: 0,
            active_step: self.active_step(),
            subgoals: l as u16,
            attention,
            decisions_received: c.decisions_received,
            decisions_committed: c.decisions_committed,
            decisions_rejected: c.decisions_rejected,
            decisions_late: c.decisions_late,
            decisions_reused: c.decisions_reused,
            sequence_gaps: c.sequence_gaps,
            sequence_reorders: c.sequence_reorders,
            states_received: c.states_received,
            states_rejected: c.states_rejected,
            decisions_superseded: c.decisions_superseded,
            source_switches: c.source_switches,
            decision_source: self.sources.active().unwrap_or(0),
            reserved2: 0,
        }
    }

    /// The committed setpoint, or a hold when a newer S_t showed its way blocked.
    fn current_setpoint(&mut self, now_ns: u64) -> Option<BoundSetpoint> {
        let last = self.last?;
        if self.way_check_due {
            self.way_check_due = false;
            match self.gate.check_way(&last.bound, self.position, self.grid()) {
                Ok(()) => self.hold = None,
                Err(_) => {
                    self.hold.get_or_insert(self.position);
                }
            }
        }
        let mut sp = match self.hold {
            None => last.bound,
            Some(here) => self.gate.hold(&last.decision, here).ok()?,
        };
        self.setpoint_seq += 1;
        sp.seq = self.setpoint_seq;
        sp.publish_ns = now_ns;
        sp.active_step = self.active_step();
        sp.reused = u8::from(self.reuse_active);
        Some(sp)
    }

    fn grid(&self) -> Option<&OccupancyGrid> {
        self.grid_present.then_some(&self.grid)
    }

    /// The attention now: ATT's last result, or all on the declared step with `no_att`.
    pub fn attention_now(&self) -> AttentionResult {
        if self.config.no_att {
            let declared = self.last.map_or(1, |l| l.decision.step as usize);
            AttentionResult::one_hot(declared.saturating_sub(1), self.subgoals)
        } else {
            self.att
        }
    }

    /// Active step i* (1-based) that annotates outgoing messages.
    pub fn active_step(&self) -> u16 {
        let l = self.subgoals.clamp(1, MAX_SUBGOALS);
        (self.attention_now().active.min(l - 1) + 1) as u16
    }

    /// The counters so far.
    pub fn counters(&self) -> HubCounters {
        self.counters
    }

    /// The reasoning instance the hub follows, if any decision arrived.
    pub fn decision_source(&self) -> Option<u32> {
        self.sources.active()
    }

    /// The sequence tracker of incoming decisions.
    pub fn sequence(&self) -> &SequenceTracker {
        &self.sequence
    }

    /// ATT (its trace included).
    pub fn attention(&self) -> &Attention {
        &self.attention
    }

    /// The decision gate.
    pub fn gate(&self) -> &DecisionGate {
        &self.gate
    }

    /// The last valid decision, if any.
    pub fn last_valid(&self) -> Option<&Decision> {
        self.last.as_ref().map(|l| &l.decision)
    }

    /// The vehicle position the hub binds against.
    pub fn position(&self) -> [f32; 3] {
        self.position
    }

    /// `true` when the current setpoint is bound from a reused decision.
    pub fn reusing(&self) -> bool {
        self.reuse_active
    }

    /// When the last valid state arrived.
    pub fn last_state_ns(&self) -> Option<u64> {
        self.last_state_ns
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::att::{AttentionPrior, LexicalScorer};
    use aeris_schemas::{ActionMode, DecisionLimits, OCCUPANCY_CELLS};

    const S: u64 = 1_000_000_000;
    const TEXTS: [&str; 3] = [
        "take off from the helipad",
        "fly to the red tower",
        "land on the blue roof",
    ];

    fn limits() -> DecisionLimits {
        DecisionLimits {
            v_max: 8.0,
            h_min: 0.0,
            h_max: 60.0,
            r_max: 10.0,
            geofence_min: [-100.0, -100.0, 0.0],
            geofence_max: [100.0, 100.0, 60.0],
            obstacle_clearance_m: 3.0,
            subgoals: 3,
        }
    }

    fn hub_with(no_att: bool) -> HubCore {
        let attention = Attention::new(
            Box::new(LexicalScorer::new(&TEXTS)),
            3,
            0.5,
            AttentionPrior::default(),
            64,
        )
        .unwrap();
        HubCore::new(
            DecisionGate::new(limits()).unwrap(),
            attention,
            HubConfig {
                heartbeat_period_ns: 2 * S,
                decision_deadline_ns: 2 * S,
                no_att,
            },
            [0.0; 3],
        )
        .unwrap()
    }

    fn hub() -> HubCore {
        hub_with(false)
    }

    /// A valid goto of cycle `cycle` with sequence `seq`, started at `start_ns`.
    fn goto(seq: u64, cycle: u64, start_ns: u64, target: [f32; 3]) -> Decision {
        Decision {
            seq,
            cycle,
            cycle_start_ns: start_ns,
            state_stamp_ns: start_ns,
            reasoning_start_ns: start_ns,
            publish_ns: start_ns,
            target,
            yaw: 0.5,
            speed: 4.0,
            altitude: target[2],
            acceptance_radius: 2.0,
            confidence: 0.9,
            step: 2,
            action: ActionMode::Goto as u8,
            reserved: 0,
            source: 0,
        }
    }

    fn state(summary: &str) -> PerceptionState {
        let mut s = PerceptionState::default();
        s.summary.set(summary);
        s
    }

    /// A grid of 1 m cells centred on the origin, free but for a wall `top` m high across
    /// it at N in `[north, north + 1)`.
    fn wall_north(north: i32, top: u8) -> OccupancyGrid {
        let mut g = OccupancyGrid {
            origin: [0.0, 0.0],
            resolution_m: 1.0,
            cells: [0; OCCUPANCY_CELLS],
        };
        let row = (north + 32) as usize;
        g.cells[row * 64..(row + 1) * 64].fill(top);
        g
    }

    fn committed(v: DecisionVerdict) -> (BoundSetpoint, HubReport) {
        match v {
            DecisionVerdict::Committed { setpoint, report } => (setpoint, report),
            other => panic!("expected a commit, got {other:?}"),
        }
    }

    #[test]
    fn a_swapped_in_reasoner_takes_over_with_its_first_timely_decision_and_costs_no_slot() {
        let mut h = hub();
        let from = |source: u32, seq: u64, start: u64| Decision {
            source,
            ..goto(seq, seq, start, [10.0, 0.0, 10.0])
        };
        // the old instance 3 has been deciding every heartbeat
        for k in 1..=5u64 {
            committed(h.on_decision(&from(3, 40 + k, 2 * k * S), 2 * k * S + 1));
        }
        // a candidate's first decision arrives late (it was still warming up): rejected,
        // but it neither takes over nor costs the running reasoner its slot
        let v = h.on_decision(&from(7, 1, 8 * S), 11 * S);
        assert!(
            matches!(v, DecisionVerdict::Late { report: None, .. }),
            "{v:?}"
        );
        assert_eq!(h.decision_source(), Some(3));
        assert_eq!(h.counters().decisions_reused, 0);
        // its next one is in time: it takes over, its own numbering (1, 2) accepted
        let (_, r) = committed(h.on_decision(&from(7, 2, 12 * S), 12 * S + 1));
        assert_eq!((r.decision_source, r.source_switches), (7, 1));
        // the old one, not stopped yet, is ignored without costing a slot
        let v = h.on_decision(&from(3, 46, 12 * S + 5), 12 * S + 6);
        assert_eq!(
            v,
            DecisionVerdict::Superseded {
                source: 3,
                active: 7
            }
        );
        committed(h.on_decision(&from(7, 3, 14 * S), 14 * S + 1));
        let c = h.counters();
        assert_eq!(
            (
                c.decisions_committed,
                c.decisions_rejected,
                c.decisions_reused,
                c.decisions_superseded,
                c.sequence_reorders
            ),
            (7, 1, 0, 1, 0)
        );
        // the new one falls silent (rolled back, died): after a whole slot the old
        // instance's next decision is taken again
        committed(h.on_decision(&from(3, 47, 19 * S), 19 * S + 1));
        assert_eq!(h.decision_source(), Some(3));
        assert_eq!(h.counters().source_switches, 2);
    }

    #[test]
    fn no_setpoint_before_the_first_valid_decision() {
        let mut h = hub();
        assert_eq!(h.on_tick(S), TickOutput::default());
        let mut bad = goto(1, 1, S, [10.0, 0.0, 10.0]);
        bad.speed = f32::NAN;
        let v = h.on_decision(&bad, S + 1);
        assert!(matches!(
            v,
            DecisionVerdict::Rejected {
                reason: RejectReason::Gate(GateError::Invalid(_)),
                report: None
            }
        ));
        assert_eq!(h.on_tick(100 * S), TickOutput::default());
        let c = h.counters();
        assert_eq!(
            (
                c.decisions_received,
                c.decisions_rejected,
                c.decisions_reused
            ),
            (1, 1, 0)
        );
    }

    #[test]
    fn a_garbage_decision_leaves_the_last_valid_one_in_force() {
        let mut h = hub();
        h.on_telemetry([1.0, 1.0, 10.0]);
        let good = goto(1, 1, S, [30.0, 10.0, 12.0]);
        let (fresh, report) = committed(h.on_decision(&good, S + S / 2));
        assert_eq!((report.committed, report.reused, report.cycle), (1, 0, 1));
        let before = h.on_tick(S + S / 2 + 1).setpoint.unwrap();
        assert_eq!(before.reused, 0);
        assert_eq!(before.position, fresh.position);

        let mut garbage = goto(2, 2, 2 * S, [30.0, 10.0, 12.0]);
        garbage.target[0] = f32::INFINITY;
        garbage.action = 0xEE;
        match h.on_decision(&garbage, 2 * S + 1) {
            DecisionVerdict::Rejected {
                report: Some(r), ..
            } => {
                assert_eq!((r.reused, r.committed, r.decisions_reused), (1, 0, 1));
                assert_eq!(r.validate(), Ok(()));
            }
            other => panic!("{other:?}"),
        }
        let after = h.on_tick(2 * S + 2).setpoint.unwrap();
        let expected = h.gate().admit(&good, [1.0, 1.0, 10.0], None).unwrap();
        assert_eq!(after.position, expected.position);
        assert_eq!(
            (after.decision_seq, after.mode),
            (1, ActionMode::Goto as u8)
        );
        assert_eq!((after.reused, after.seq), (1, before.seq + 1));
        // a second garbage decision in the same slot: rejected, but no second reuse
        let mut again = garbage;
        again.seq = 3;
        assert!(matches!(
            h.on_decision(&again, 2 * S + 3),
            DecisionVerdict::Rejected { report: None, .. }
        ));
        let c = h.counters();
        assert_eq!((c.decisions_rejected, c.decisions_reused), (2, 1));
    }

    #[test]
    fn late_and_future_decisions_are_rejected() {
        let mut h = hub();
        let (first, _) = committed(h.on_decision(&goto(1, 1, 10 * S, [20.0, 0.0, 10.0]), 11 * S));
        // 2.5 s after its cycle start: late
        let late = goto(2, 2, 12 * S, [-20.0, 0.0, 10.0]);
        match h.on_decision(&late, 14 * S + S / 2) {
            DecisionVerdict::Late { age_ns, report } => {
                assert_eq!(age_ns, 2 * S + S / 2);
                assert_eq!(report.map(|r| r.decisions_late), Some(1));
            }
            other => panic!("{other:?}"),
        }
        // exactly at the deadline is on time
        let on_time = goto(3, 3, 13 * S, [-20.0, 0.0, 10.0]);
        let (sp, _) = committed(h.on_decision(&on_time, 15 * S));
        assert_ne!(sp.position, first.position);
        let future = goto(4, 4, 20 * S, [5.0, 0.0, 10.0]);
        assert!(matches!(
            h.on_decision(&future, 16 * S),
            DecisionVerdict::Rejected {
                reason: RejectReason::FutureTimestamp { .. },
                ..
            }
        ));
        let tick = h.on_tick(16 * S).setpoint.unwrap();
        assert_eq!((tick.decision_seq, tick.position), (3, sp.position));
        let c = h.counters();
        assert_eq!(
            (
                c.decisions_late,
                c.decisions_rejected,
                c.decisions_committed
            ),
            (1, 2, 2)
        );
    }

    #[test]
    fn each_missed_heartbeat_counts_one_reuse() {
        let mut h = hub();
        committed(h.on_decision(&goto(1, 7, 0, [20.0, 0.0, 10.0]), S));
        // the next cycle is due by 0 + 2 s period + 2 s deadline
        let t = h.on_tick(4 * S);
        assert_eq!((t.report, t.setpoint.unwrap().reused), (None, 0));
        let t = h.on_tick(4 * S + 1);
        let r = t.report.unwrap();
        assert_eq!((r.reused, r.cycle, r.decisions_reused), (1, 8, 1));
        assert_eq!(t.setpoint.unwrap().reused, 1);
        assert_eq!(h.on_tick(5 * S).report, None);
        let r = h.on_tick(6 * S + 1).report.unwrap();
        assert_eq!((r.cycle, r.decisions_reused), (9, 2));
        // a stall over three more periods: three reuses, one report
        let r = h.on_tick(12 * S + 1).report.unwrap();
        assert_eq!(r.decisions_reused, 5);
        assert_eq!(h.on_tick(12 * S + 2).report, None);
        // a fresh decision ends the reuse
        let (_, r) = committed(h.on_decision(&goto(2, 13, 12 * S, [0.0, 20.0, 10.0]), 13 * S));
        assert_eq!((r.committed, r.reused, r.decisions_reused), (1, 0, 5));
        assert_eq!(h.on_tick(13 * S).setpoint.unwrap().reused, 0);
        assert_eq!(h.counters().decisions_reused, 5);
    }

    #[test]
    fn a_rejection_counts_its_slot_once() {
        let mut h = hub();
        committed(h.on_decision(&goto(1, 1, 0, [20.0, 0.0, 10.0]), S));
        let mut bad = goto(2, 2, 2 * S, [20.0, 0.0, 10.0]);
        bad.step = 99;
        assert!(matches!(
            h.on_decision(&bad, 3 * S),
            DecisionVerdict::Rejected {
                report: Some(_),
                ..
            }
        ));
        // the slot that the rejection already counted closes without a second reuse
        assert_eq!(h.on_tick(4 * S + 1).report, None);
        assert_eq!(h.counters().decisions_reused, 1);
        // the next one does count
        assert!(h.on_tick(6 * S + 1).report.is_some());
        assert_eq!(h.counters().decisions_reused, 2);
    }

    #[test]
    fn stages_and_cycle_time_of_a_commit() {
        let mut h = hub();
        let mut d = goto(1, 4, 1_000, [10.0, 0.0, 10.0]);
        d.state_stamp_ns = 1_500;
        d.reasoning_start_ns = 1_600;
        d.publish_ns = 1_800;
        let (sp, r) = committed(h.on_decision_timed(&d, 2_000, || 2_100));
        assert_eq!(r.stage_ns, [500, 300, 200, 100]);
        assert_eq!((r.ct_ns, r.cycle, r.publish_ns), (1_100, 4, 2_100));
        assert_eq!(sp.publish_ns, 2_100);
        assert_eq!(r.stage_ns.iter().sum::<u64>(), r.ct_ns);
    }

    #[test]
    fn gaps_and_reorders_are_counted_and_reorders_rejected() {
        let mut h = hub();
        let t = 10 * S;
        for seq in [1, 2, 5] {
            committed(h.on_decision(&goto(seq, seq, t, [10.0, 0.0, 10.0]), t + seq));
        }
        for seq in [4, 5, 0] {
            assert!(matches!(
                h.on_decision(&goto(seq, seq, t, [10.0, 0.0, 10.0]), t + 9),
                DecisionVerdict::Rejected {
                    reason: RejectReason::Sequence { .. },
                    ..
                }
            ));
        }
        let c = h.counters();
        assert_eq!((c.sequence_gaps, c.sequence_reorders), (1, 3));
        assert_eq!((c.decisions_received, c.decisions_rejected), (6, 3));
        assert_eq!(h.last_valid().map(|d| d.seq), Some(5));
        assert_eq!(h.sequence().missing(), 2);
        // a restarted reasoner starts over at 1, with a newer cycle start: accepted
        committed(h.on_decision(&goto(1, 1, t + S, [10.0, 0.0, 10.0]), t + S));
        assert_eq!(h.sequence().restarts(), 1);
        committed(h.on_decision(&goto(2, 2, t + S, [10.0, 0.0, 10.0]), t + S));
    }

    #[test]
    fn an_infeasible_decision_becomes_a_latched_hold() {
        let mut h = hub();
        h.on_telemetry([0.0, 0.0, 10.0]);
        committed(h.on_decision(&goto(1, 1, S, [30.0, 0.0, 10.0]), S));
        assert_eq!(h.on_tick(S).setpoint.unwrap().position, [30.0, 0.0, 10.0]);
        // a wall appears 2 m ahead: pulling back leaves no motion
        let mut s = state("a wall");
        s.position = [0.0, 0.0, 10.0];
        s.occupancy = wall_north(2, 40);
        h.on_state(&s, S).unwrap();
        h.on_telemetry([0.4, 0.1, 10.2]);
        let sp = h.on_tick(S + 1).setpoint.unwrap();
        assert_eq!(
            (sp.mode, sp.position),
            (ActionMode::Hover as u8, [0.4, 0.1, 10.2])
        );
        assert_eq!(sp.validate(&limits()), Ok(ActionMode::Hover));
        // the hold stays where it was latched while the vehicle drifts
        h.on_telemetry([0.9, -0.3, 10.0]);
        assert_eq!(
            h.on_tick(S + 2).setpoint.unwrap().position,
            [0.4, 0.1, 10.2]
        );
        // the wall is gone: the decision is flown again
        s.occupancy.cells = [0; OCCUPANCY_CELLS];
        h.on_state(&s, S).unwrap();
        let sp = h.on_tick(S + 3).setpoint.unwrap();
        assert_eq!(
            (sp.mode, sp.position),
            (ActionMode::Goto as u8, [30.0, 0.0, 10.0])
        );
    }

    /// The setpoint a decision was committed to is the one flown: the vehicle moving (with
    /// or without a new S_t whose grid leaves its way clear) does not make the hub run the
    /// gate again and bind it elsewhere, though a fresh admission would.
    #[test]
    fn a_decision_is_gated_once_and_its_setpoint_kept_while_the_vehicle_moves() {
        let mut h = hub();
        h.on_telemetry([0.0, 0.0, 10.0]);
        // a wall 20 m high across the way at N in [10, 11)
        let mut s = state("a wall ahead");
        s.occupancy = wall_north(10, 20);
        h.on_state(&s, S).unwrap();
        let d = goto(1, 1, S, [25.0, 0.0, 10.0]);
        let (committed, _) = self::committed(h.on_decision(&d, S));
        // pulled back 3 m before the wall
        assert_eq!(
            (committed.position, committed.clamped),
            ([7.0, 0.0, 10.0], 1)
        );
        let first = h.on_tick(S + 1).setpoint.unwrap();
        assert_eq!((first.position, first.clamped), (committed.position, 1));
        // the vehicle moves east: from there the gate would pull the goal back elsewhere
        let moved = [2.0, 6.0, 10.0];
        h.on_telemetry(moved);
        let again = h.gate().admit(&d, moved, Some(&s.occupancy)).unwrap();
        assert_ne!(again.position, committed.position);
        let sp = h.on_tick(S + 2).setpoint.unwrap();
        assert_eq!(
            (sp.position, sp.mode, sp.clamped, sp.decision_seq),
            (committed.position, ActionMode::Goto as u8, 1, 1)
        );
        assert_eq!(sp.seq, first.seq + 1);
        // a new S_t with the same wall: the way to the committed setpoint is still clear
        h.on_state(&s, S + 3).unwrap();
        let sp = h.on_tick(S + 4).setpoint.unwrap();
        assert_eq!(
            (sp.position, sp.mode),
            (committed.position, ActionMode::Goto as u8)
        );
    }

    #[test]
    fn in_place_actions_stay_anchored() {
        let mut h = hub();
        h.on_telemetry([1.0, 2.0, 0.0]);
        let mut d = goto(1, 1, S, [1.0, 2.0, 10.0]);
        d.action = ActionMode::Takeoff as u8;
        d.step = 1;
        committed(h.on_decision(&d, S));
        h.on_telemetry([3.0, 4.0, 5.0]);
        assert_eq!(h.on_tick(S).setpoint.unwrap().position, [1.0, 2.0, 10.0]);
    }

    #[test]
    fn bad_states_and_telemetry_are_ignored() {
        let mut h = hub();
        let mut s = state("x");
        s.cue_count = 99;
        assert!(h.on_state(&s, S).is_err());
        assert!(!h.on_telemetry([f32::NAN, 0.0, 0.0]));
        assert_eq!(h.position(), [0.0; 3]);
        let c = h.counters();
        assert_eq!((c.states_received, c.states_rejected), (1, 1));
        // before telemetry, a state's position is used
        let mut s = state("x");
        s.position = [5.0, 6.0, 7.0];
        h.on_state(&s, S).unwrap();
        assert_eq!(h.position(), [5.0, 6.0, 7.0]);
        h.on_telemetry([1.0, 1.0, 1.0]);
        h.on_state(&s, S).unwrap();
        assert_eq!(h.position(), [1.0, 1.0, 1.0]);
    }

    #[test]
    fn att_alpha_sums_to_one_and_follows_progress() {
        let mut h = hub();
        let scenes = [
            ("helipad below, taking off", 1),
            ("open field", 1),
            ("a red tower ahead", 2),
            ("red tower close, trees", 2),
            ("a blue roof below", 3),
            // evidence for an earlier subgoal does not move ATT back
            ("a red tower behind, helipad", 3),
            ("blue roof", 3),
        ];
        let mut steps = Vec::new();
        for (i, (text, want)) in scenes.iter().enumerate() {
            h.on_state(&state(text), i as u64).unwrap();
            let a = h.attention_now();
            let sum: f32 = a.alpha[..3].iter().sum();
            assert!((sum - 1.0).abs() < 1e-5, "{sum}");
            assert!(a.alpha[3..].iter().all(|v| *v == 0.0));
            assert_eq!(h.active_step(), *want, "after {text:?}");
            steps.push(h.active_step());
        }
        let trace: Vec<usize> = h.attention().trace().map(|e| e.active).collect();
        assert_eq!(trace, vec![0, 0, 1, 1, 2, 2, 2]);
        // reports carry the attention and the active step
        let (sp, r) = committed(h.on_decision(&goto(1, 1, S, [10.0, 0.0, 10.0]), S));
        assert_eq!((sp.active_step, r.active_step, r.subgoals), (3, 3, 3));
        assert_eq!(r.validate(), Ok(()));
        assert!((r.alpha().iter().sum::<f32>() - 1.0).abs() < 1e-5);
    }

    #[test]
    fn declared_step_pulls_att_forward_and_no_att_follows_it() {
        let mut h = hub();
        let mut d = goto(1, 1, S, [10.0, 0.0, 10.0]);
        d.step = 2;
        committed(h.on_decision(&d, S));
        h.on_state(&state("nothing in particular"), S).unwrap();
        assert_eq!(h.active_step(), 2);

        let mut h = hub_with(true);
        assert_eq!(h.active_step(), 1);
        d.step = 3;
        committed(h.on_decision(&d, S));
        h.on_state(&state("helipad"), S).unwrap();
        assert_eq!(h.active_step(), 3);
        let a = h.attention_now();
        assert_eq!(&a.alpha[..3], &[0.0, 0.0, 1.0]);
        assert_eq!(h.attention().updates(), 0);
    }
}
