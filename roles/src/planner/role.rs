//! The planner as a reasoning process (kind `reasoning`, variant `planner`).
//!
//! [`PlannerRole`] turns the mission's subgoals into decisions D_t through exactly the path a
//! language model's decisions take (`reasoning/decision` -> hub gate -> controller): it
//! decides once per heartbeat on the first fresh S_t, or on the telemetry alone when no S_t
//! came for a heartbeat and a half, polling every 50 ms ([`ReasonerIo`]).
//!
//! Parameter `distill` (a file path): every decision is also written there as a training
//! pair for the aligned reasoner ([`crate::distill`]).
//!
//! Heartbeat stages: `read`, `plan`, `publish`. Heartbeat counters:
//! [`aeris_schemas::PlannerCounters`]. The role's log says when the planner loses occupancy (and
//! keeps to the geofence and the conservative altitude) and when it gets it back.

use super::Planner;
use crate::distill::{DistillWriter, StudentView};
use crate::reasoner_io::{POLL, ReasonerIo};
use aeris_llm::DecisionView;
use aeris_runtime::clock::monotonic_ns;
use aeris_runtime::{
    ConfigError, CycleOutcome, CycleReport, Role, RoleContext, RoleError, RoleSpec,
};
use aeris_schemas::kinds;
use aeris_schemas::{Decision, OccupancyStatus, PlannerCounters};
use core::time::Duration;

/// The planner of the mission in `spec`, seen through its camera (every reasoning role
/// keeps one: the planner variants decide with it, the language roles show its plan).
pub fn mission_planner(spec: &RoleSpec) -> Result<Planner, RoleError> {
    Planner::new(&spec.mission, &spec.camera).ok_or_else(|| {
        ConfigError::Mission("names an unknown action, or the camera is invalid".into()).into()
    })
}

/// The planner with the reasoning role's I/O: what the planner, garbage and random
/// variants share.
pub(crate) struct PlannerReasoner {
    pub(crate) planner: Planner,
    pub(crate) io: ReasonerIo,
    /// What the log last said: blind or not, and the occupancy status (`None`: nothing
    /// said yet).
    blind_announced: Option<(bool, Option<OccupancyStatus>)>,
    /// Training pairs of the planner's decisions, in the aligned prompt (parameter
    /// `distill`, the planner variant only).
    distill: Option<(StudentView, DistillWriter)>,
}

impl PlannerReasoner {
    /// The mission's planner, resumed where the hub has the flight, and the role's ports.
    pub(crate) fn new(ctx: &mut RoleContext<kinds::Reasoning>) -> Result<Self, RoleError> {
        let mut planner = mission_planner(&ctx.spec)?;
        // a plan takes microseconds: a first S_t is taken up to the deadline's age
        let io = ReasonerIo::new(ctx, &mut planner, Duration::ZERO)?;
        Ok(Self {
            planner,
            io,
            blind_announced: None,
            distill: None,
        })
    }

    /// Read inputs and, when a decision is due, make it (stamped, not yet published).
    pub(crate) fn think(
        &mut self,
        report: &mut CycleReport,
    ) -> Result<Option<Decision>, RoleError> {
        let Some(due) = self.io.poll()? else {
            return Ok(None);
        };
        let reasoning_start = monotonic_ns();
        let before = self.planner.rejections().0;
        let was_blind = self.blind_announced;
        let state = self.io.state(&due);
        let mut d = self
            .planner
            .decide(due.position, due.yaw, due.landed, state);
        if let Some((view, writer)) = &mut self.distill {
            let sighted = view.sighted(state);
            writer.write(view.brief(), &view.observation(&due, state, &sighted), &d)?;
            view.decided(DecisionView::from_decision(&d));
        }
        let now = (self.planner.blind(), self.planner.occupancy());
        if Some(now) != was_blind {
            self.blind_announced = Some(now);
            // rare (when the depth source goes or comes back): a line in the role's log
            match self.planner.occupancy() {
                _ if self.planner.blind() => tracing::warn!(
                    "reasoning: step {}: occupancy {}: unknown space is not free; planning \
                     inside the geofence at the conservative altitude",
                    d.step,
                    self.planner
                        .occupancy()
                        .map_or("not seen yet (no S_t)", |s| s.name())
                ),
                _ => tracing::info!(
                    "reasoning: step {}: occupancy present: planning over the grid",
                    d.step
                ),
            }
        }
        if let (n, Some((p, read))) = self.planner.rejections()
            && n > before
        {
            // rare (a few per flight): worth a line in the role's log
            tracing::warn!(
                "reasoning: step {}: the sign at [{:.0}, {:.0}] reads \"{read}\", not the one \
                 the instruction quotes; searching on",
                d.step,
                p[0],
                p[1]
            );
        }
        self.io.stamp(&mut d, &due, reasoning_start);
        report.stage("read", reasoning_start - due.poll_ns);
        report.stage("plan", monotonic_ns() - reasoning_start);
        Ok(Some(d))
    }

    /// Publish `d` (see [`ReasonerIo::publish`]) and report the subgoal in progress.
    pub(crate) fn send(
        &mut self,
        d: &mut Decision,
        report: &mut CycleReport,
    ) -> Result<(), RoleError> {
        self.io.publish(d, report)?;
        let mut c = PlannerCounters::from_heartbeat(&report.counters);
        c.decisions = self.io.published();
        c.subgoal = self.planner.current() as u64;
        c.blind_decisions = self.planner.blind_decisions();
        report.counters = c.to_heartbeat();
        Ok(())
    }
}

/// The deterministic planner variant of the reasoning role.
pub struct PlannerRole {
    reasoner: PlannerReasoner,
}

impl Role for PlannerRole {
    type Kind = kinds::Reasoning;

    fn new(ctx: &mut RoleContext<kinds::Reasoning>) -> Result<Self, RoleError> {
        let mut reasoner = PlannerReasoner::new(ctx)?;
        if let Some(writer) = DistillWriter::from_spec(&ctx.spec)? {
            reasoner.distill = Some((StudentView::new(&ctx.spec)?, writer));
        }
        Ok(Self { reasoner })
    }

    fn period(&self) -> Duration {
        POLL
    }

    fn cycle(
        &mut self,
        _ctx: &mut RoleContext<kinds::Reasoning>,
        report: &mut CycleReport,
    ) -> Result<CycleOutcome, RoleError> {
        let Some(mut d) = self.reasoner.think(report)? else {
            return Ok(CycleOutcome::Idle);
        };
        self.reasoner.send(&mut d, report)?;
        Ok(CycleOutcome::Worked)
    }
}
