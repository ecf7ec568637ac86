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
//! - **Gate**: [`DecisionGate::admit`] against the latest vehicle position and the
//!   occupancy of the latest valid S_t, whatever its status: absent (also before the first
//!   S_t) or stale, the gate keeps to the geofence and the conservative altitude. Every
//!   report carries that status (`occupancy`), and a committed cycle's the gate's clamp
//!   reasons (`clamp_reasons`).
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
    BoundSetpoint, Decision, HubCounts, HubReport, MAX_SUBGOALS, OccupancyGrid, PerceptionState,
    StateError, all_finite,
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
    counters: HubCounts,
    position: [f32; 3],
    telemetry_seen: bool,
    /// The occupancy of the latest valid S_t (absent before the first).
    grid: OccupancyGrid,
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
            counters: HubCounts::default(),
            position: start,
            telemetry_seen: false,
            grid: OccupancyGrid::default(),
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
    /// grid (present, absent or stale: it replaces the last one) and (until telemetry
    /// arrives) its position, and run ATT.
    pub fn on_state(&mut self, state: &PerceptionState, now_ns: u64) -> Result<(), StateError> {
        self.counters.states_received += 1;
        if let Err(e) = state.validate() {
            self.counters.states_rejected += 1;
            return Err(e);
        }
        self.last_state_ns = Some(now_ns);
        self.way_check_due = true;
        self.grid = state.occupancy;
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
        // admit, keeping the clamp reasons for the report
        let admitted = self
            .gate
            .validate(d)
            .and_then(|mode| self.gate.feasible(d, mode, self.position, self.grid()))
            .and_then(|f| Ok((self.gate.bind(d, &f)?, f.reasons)));
        let (mut setpoint, reasons) = match admitted {
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
        report.clamp_reasons = reasons;
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
        HubReport {
            seq: self.report_seq,
            cycle: 0,
            publish_ns: now_ns,
            ct_ns: 0,
            stage_ns: [0; 4],
            committed: 0,
            reused: 0,
            clamped: 0,
            occupancy: self.grid.status,
            active_step: self.active_step(),
            subgoals: l as u16,
            attention,
            counts: self.counters,
            decision_source: self.sources.active().unwrap_or(0),
            clamp_reasons: 0,
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
        Some(&self.grid)
    }

    /// The occupancy the hub gates against: the latest valid S_t's (absent before one).
    pub fn occupancy(&self) -> &OccupancyGrid {
        &self.grid
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
    pub fn counters(&self) -> HubCounts {
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
mod tests;
