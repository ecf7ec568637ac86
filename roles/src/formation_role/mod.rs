//! The formation role (kind `formation`): the ground station of a flight of several
//! vehicles. It runs for the whole flight, outside every vehicle's scope.
//!
//! At start it writes a formation program for the mission's instruction (variant `parser`,
//! the deterministic parser, or a GGUF model under the program grammar: `qwen-coder`,
//! `smollm2`, `gemma3`), validates it, checks it in simulation (every transition's
//! separation, the geofence, the altitude band, the time) and repairs it, at most
//! `max_repairs` times; a program that stays unsafe is refused and nothing flies (the role
//! stops with the diagnosis). Then, every control period, it reads every vehicle's
//! `v{K}/vehicle/telemetry`, steps the [`FormationExecutor`] (a phase in time; at its end,
//! a wait until every vehicle is within tolerance of its slot) and publishes each vehicle's
//! slot on `v{K}/hub/setpoint`, which that vehicle's controller tracks; the land phase is
//! sent as a landing. It finishes when every vehicle has landed.
//!
//! **Runtime faults feed the same loop.** A vehicle whose telemetry stops, or whose
//! controller has no autopilot, for `lost_after_ms` is lost; one the executor waited for past
//! its settle timeout is off its slot. Either leaves the formation: the rest of the program
//! is planned again for the vehicles that remain, from where they are
//! ([`replan_after_fault`]: the same check and repair), or their landing where they are; the
//! lost vehicle's controller gets no more setpoints and holds. That path allocates (it is a
//! new plan); the control period's does not.
//!
//! **Reshaped on demand.** A new instruction on `formation/say` (`aeris formation say`) is
//! written for the vehicles in the formation, planned from where they are through the same
//! check and repair, and flown at once without landing; refused, the formation flies on.
//! The answer goes to `formation/reply`.
//!
//! Parameters: `vehicles` and `starts` (set by the launch plan from `[flight] vehicles`),
//! `min_separation_m` (2), `max_repairs` (3), `lost_after_ms` (1000), `model`, `threads` (1),
//! `models_dir` for the model variants.
//!
//! Every program flies only once the hub's program gate admits it
//! ([`aeris_hub::program_gate`]: valid under the flight's limits), and every slot goes to a
//! controller only as the setpoint the gate binds it to (one the controller would refuse is
//! not sent).
//!
//! Heartbeat counters: [`aeris_schemas::FormationCounters`].

mod tracks;
mod writer;

use crate::vision::open_store;
use aeris_formation::{
    Dynamics, ExecutorState, FormationExecutor, InFlight, ParserWriter, PlanOutcome, ProgramWriter,
    RuntimeFault, Simulation, Slot, Tolerance, Trajectory, phase_description, plan_instruction,
    plan_program, replan_after_fault,
};
use aeris_hub::program_gate::ProgramGate;
use aeris_runtime::bus::{TypedPublisher, TypedSubscriber};
use aeris_runtime::clock::monotonic_ns;
use aeris_runtime::{ConfigError, CycleOutcome, CycleReport, Role, RoleContext, RoleError};
use aeris_schemas::kinds;
use aeris_schemas::{
    BoundSetpoint, FormationCommand, FormationCounters, FormationPhase, FormationProgram,
    FormationReply, MAX_PHASES, MAX_VEHICLES, PhaseKind, SayOutcome, VehicleTelemetry, topics,
};
use std::time::Duration;
use tracks::{TRACK_EVERY_NS, TrackRecorder};
use writer::Writer;

/// One vehicle as the formation role sees it.
struct VehicleLink {
    /// Its number in the flight (1-based): its scope `v{K}`.
    number: u8,
    setpoints: TypedPublisher<BoundSetpoint>,
    telemetry: TypedSubscriber<VehicleTelemetry>,
    /// Newest telemetry, and when it arrived (ns).
    last: Option<(VehicleTelemetry, u64)>,
    /// Since when its controller has reported no autopilot (ns).
    silent_since: Option<u64>,
    /// Has been in the air.
    flew: bool,
    /// Left the formation (lost or off its slot).
    left: bool,
}

/// The program being flown and its vehicles.
struct Flying {
    program: FormationProgram,
    executor: FormationExecutor,
    /// The program's vehicle `k` is `links[members[k]]`.
    members: Vec<usize>,
}

/// The formation role.
pub struct FormationRole {
    writer: Writer,
    say: TypedSubscriber<FormationCommand>,
    reply: TypedPublisher<FormationReply>,
    links: Vec<VehicleLink>,
    flying: Flying,
    gate: ProgramGate,
    max_repairs: usize,
    lost_after_ns: u64,
    period: Duration,
    started: bool,
    last_tick_ns: u64,
    seq: u64,
    slots: [Slot; MAX_VEHICLES],
    positions: [[f32; 3]; MAX_VEHICLES],
    counters: FormationCounters,
    min_separation_m: f32,
    done: bool,
    /// Phases of the program flown whose settling was logged.
    settled_logged: usize,
    tracks: TrackRecorder,
}

/// `take-off, the change to a line, ...`.
fn describe_phases(program: &FormationProgram) -> String {
    program
        .phases()
        .iter()
        .map(phase_description)
        .collect::<Vec<_>>()
        .join(", ")
}

/// Write and plan the program with `writer`; the accepted program and its trajectory, or
/// the refusal as an error.
fn plan(
    writer: &mut Writer,
    instruction: &str,
    starts: &[[f32; 3]],
    gate: &ProgramGate,
    max_repairs: usize,
) -> Result<(FormationProgram, Trajectory), RoleError> {
    let planned = plan_instruction(
        writer,
        instruction,
        starts,
        gate.limits(),
        &Simulation::default(),
        max_repairs,
    )
    .map_err(|e| RoleError::step("planning the formation", e))?;
    tracing::info!(
        "formation: {} (written in {:.0} ms, checked in {:.1} ms)",
        planned.outcome.summary(),
        planned.write_time.as_secs_f64() * 1e3,
        planned.plan_time.as_secs_f64() * 1e3
    );
    match planned.outcome {
        PlanOutcome::Accepted {
            program, report, ..
        } => {
            gate.admit(&program)
                .map_err(|e| RoleError::step("the hub's program gate refused the program", e))?;
            for (i, phase) in program.phases().iter().enumerate() {
                tracing::info!("formation: phase {}: {}", i + 1, phase_description(phase));
            }
            Ok((*program, report.trajectory))
        }
        PlanOutcome::Refused { problem, .. } => Err(RoleError::step(
            "the formation program was refused, nothing flies",
            problem,
        )),
    }
}

impl Role for FormationRole {
    type Kind = kinds::Formation;

    fn new(ctx: &mut RoleContext<kinds::Formation>) -> Result<Self, RoleError> {
        let spec = &ctx.spec;
        let vehicles = spec
            .param_f64("vehicles")
            .filter(|v| (1.0..=MAX_VEHICLES as f64).contains(v))
            .ok_or_else(|| {
                RoleError::param("vehicles", "must be 1..=8 (the launch plan sets it)")
            })? as u8;
        let starts: Vec<[f32; 3]> = spec
            .params
            .get("starts")
            .and_then(|v| serde_json::from_value(v.clone()).ok())
            .filter(|s: &Vec<[f32; 3]>| s.len() == vehicles as usize)
            .ok_or_else(|| RoleError::param("starts", "must list one [N, E, U] per vehicle"))?;
        let min_separation_m = spec.param_f64("min_separation_m").unwrap_or(2.0) as f32;
        let max_repairs = spec
            .param_f64("max_repairs")
            .unwrap_or(3.0)
            .clamp(0.0, 10.0) as usize;
        let lost_after_ms = spec.param_f64("lost_after_ms").unwrap_or(1000.0).max(100.0);
        let gate =
            ProgramGate::for_flight(&spec.mission.decision_limits(), vehicles, min_separation_m)
                .map_err(|e| ConfigError::refused("the formation's program gate", e))?;
        let instruction = spec.mission.instruction.clone();
        let mut writer = match spec.variant.as_str() {
            "parser" => Writer::Parser(ParserWriter),
            variant => {
                let file = spec
                    .param_str("model")
                    .or(aeris_llm::variant_model(variant))
                    .ok_or_else(|| ConfigError::NoModel(variant.to_string()))?
                    .to_string();
                let threads = spec.param_f64("threads").unwrap_or(1.0).clamp(1.0, 64.0) as i32;
                let store = open_store(ctx)?;
                let model = aeris_llm::FormationWriter::load(&store, variant, &file, threads)
                    .map_err(|e| {
                        RoleError::step(format!("loading formation/{variant} from {file}"), e)
                    })?;
                Writer::Model(Box::new(model))
            }
        };
        // how long the writing took: wall-clock time, on simulated time too
        let planning = aeris_runtime::clock::wall_ns();
        let (program, trajectory) = plan(&mut writer, &instruction, &starts, &gate, max_repairs)?;
        let program_ms = aeris_runtime::clock::wall_ns().saturating_sub(planning) / 1_000_000;
        let mut tracks = TrackRecorder::new(
            spec.param_str("tracks_file").map(std::path::PathBuf::from),
            &instruction,
            usize::from(vehicles),
            spec.mission.max_duration_s,
        );
        tracks.program(&program);
        let say = ctx.bus.subscriber::<topics::FormationSay>()?;
        let reply = ctx.bus.publisher::<topics::FormationReply>()?;
        // vehicle K's scope; a flight of one vehicle has no vehicle scopes
        let scope = |k: u8| (vehicles > 1).then_some(k);
        let mut links = Vec::with_capacity(vehicles as usize);
        for k in 1..=vehicles {
            links.push(VehicleLink {
                number: k,
                setpoints: ctx.bus.publisher_in::<topics::HubSetpoint>(scope(k))?,
                telemetry: ctx
                    .bus
                    .subscriber_in::<topics::VehicleTelemetry>(scope(k))?,
                last: None,
                silent_since: None,
                flew: false,
                left: false,
            });
        }
        let rate = ctx.spec.timing.control_rate_hz;
        let period = Duration::from_secs_f64(if rate.is_finite() && rate > 0.0 {
            1.0 / rate
        } else {
            0.02
        });
        // a program for fewer vehicles than the flight has flies the first ones; the rest
        // stay where they are, on the ground
        let flying = program.vehicles.min(vehicles);
        if flying < vehicles {
            tracing::info!(
                "formation: the program flies {flying} of the flight's {vehicles} vehicles; \
                 vehicles {}..{vehicles} stay on the ground",
                flying + 1
            );
        }
        let counters = FormationCounters {
            vehicles: u64::from(flying),
            program_ms,
            ..FormationCounters::default()
        };
        Ok(Self {
            writer,
            say,
            reply,
            links,
            flying: Flying {
                program,
                executor: FormationExecutor::new(trajectory, Tolerance::default()),
                members: (0..flying as usize).collect(),
            },
            gate,
            max_repairs,
            lost_after_ns: (lost_after_ms * 1e6) as u64,
            period,
            started: false,
            last_tick_ns: 0,
            seq: 0,
            slots: [Slot::default(); MAX_VEHICLES],
            positions: [[0.0; 3]; MAX_VEHICLES],
            counters,
            min_separation_m: f32::INFINITY,
            done: false,
            settled_logged: 0,
            tracks,
        })
    }

    fn period(&self) -> Duration {
        self.period
    }

    fn cycle(
        &mut self,
        _ctx: &mut RoleContext<kinds::Formation>,
        report: &mut CycleReport,
    ) -> Result<CycleOutcome, RoleError> {
        let now = monotonic_ns();
        self.read_telemetry(now)?;
        if !self.started {
            // every vehicle of the program heard from, and its controller bound to its
            // autopilot
            let members = &self.flying.members;
            if !members
                .iter()
                .all(|&m| self.links[m].last.is_some_and(|(t, _)| t.link_up == 1))
            {
                report.counters = self.counters.to_heartbeat();
                return Ok(CycleOutcome::Idle);
            }
            tracing::info!(
                "formation: every vehicle's controller reports its autopilot; flying {} phases",
                self.flying.program.phases().len()
            );
            self.started = true;
            self.last_tick_ns = now;
            self.tracks.start_ns = now;
        }
        if let Some(fault) = self.fault(now) {
            self.replan(fault, now);
        }
        if let Some(command) = self.say.latest()? {
            self.reshape(&command, now)?;
        }
        let dt = now.saturating_sub(self.last_tick_ns) as f32 * 1e-9;
        self.last_tick_ns = now;
        for (k, &member) in self.flying.members.iter().enumerate() {
            if let Some((t, _)) = self.links[member].last {
                self.positions[k] = t.position;
            }
        }
        let n = self.flying.members.len();
        let state = self
            .flying
            .executor
            .tick(dt, &self.positions[..n], &mut self.slots);
        let segment = match state {
            ExecutorState::Flying { segment }
            | ExecutorState::Settling { segment, .. }
            | ExecutorState::Stuck { segment, .. } => segment,
            ExecutorState::Done => self
                .flying
                .executor
                .trajectory()
                .segments
                .len()
                .saturating_sub(1),
        };
        let phase = self
            .flying
            .executor
            .trajectory()
            .segments
            .get(segment)
            .map_or(0, |s| s.phase);
        let landing = self
            .flying
            .program
            .phases()
            .get(phase.saturating_sub(1))
            .is_some_and(|p| p.kind == PhaseKind::Land as u8);
        self.publish(now, phase, landing)?;
        self.record(now, phase);
        self.counters.phase = phase as u64;
        self.counters.state = match state {
            ExecutorState::Flying { .. } => 1,
            ExecutorState::Settling { .. } => 2,
            ExecutorState::Done => 3,
            ExecutorState::Stuck { .. } => 4,
        };
        let settled = self.flying.executor.settled_after_s();
        if settled.len() > self.settled_logged {
            // a phase just ended with every vehicle at its slot
            let segments = &self.flying.executor.trajectory().segments;
            for (i, wait) in settled.iter().enumerate().skip(self.settled_logged) {
                let phase = segments.get(i).map_or(0, |s| s.phase);
                tracing::info!(
                    "formation: phase {phase}: every vehicle within {} m of its slot {wait:.2} s after the phase's end",
                    Tolerance::default().distance_m
                );
            }
            self.settled_logged = settled.len();
        }
        let settle_ms = settled.iter().fold(0.0f32, |a, b| a.max(*b)) * 1e3;
        self.counters.longest_settle_ms = self.counters.longest_settle_ms.max(settle_ms as u64);
        report.counters = self.counters.to_heartbeat();
        let all_landed =
            self.flying.members.iter().all(|&m| {
                self.links[m].flew && self.links[m].last.is_some_and(|(t, _)| t.landed == 1)
            });
        if state == ExecutorState::Done && all_landed && !self.done {
            self.done = true;
            tracing::info!(
                "formation: every vehicle landed; closest two {:.2} m apart",
                self.min_separation_m
            );
            self.tracks.write(self.links.len());
            return Ok(CycleOutcome::Finished);
        }
        Ok(CycleOutcome::Worked)
    }

    fn shutdown(&mut self, _ctx: &mut RoleContext<kinds::Formation>) {
        self.tracks.write(self.links.len());
    }
}

impl FormationRole {
    /// Keep a track sample when one is due (no allocation: see [`TrackRecorder`]).
    fn record(&mut self, now: u64, phase: usize) {
        let t = &mut self.tracks;
        if t.file.is_none() || now < t.next_ns || t.samples.len() == t.samples.capacity() {
            return;
        }
        t.next_ns = now + TRACK_EVERY_NS;
        t.samples.push((
            now.saturating_sub(t.start_ns) as f32 * 1e-9,
            t.offset + phase.max(1),
        ));
        let position = |l: &VehicleLink| l.last.map_or([0.0; 3], |(tel, _)| tel.position);
        for l in &self.links {
            t.points.push(position(l));
        }
        for (i, l) in self.links.iter().enumerate() {
            let slot = self
                .flying
                .members
                .iter()
                .position(|&m| m == i)
                .map_or_else(|| position(l), |k| self.slots[k].position);
            t.points.push(slot);
        }
    }

    /// Take every vehicle's newest telemetry; the closest pair so far.
    fn read_telemetry(&mut self, now: u64) -> Result<(), RoleError> {
        for link in &mut self.links {
            if let Some(t) = link.telemetry.latest()? {
                link.last = Some((t, now));
                link.flew |= t.landed == 0 && t.armed == 1;
                link.silent_since = match (t.link_up, link.silent_since) {
                    (1, _) => None,
                    (_, Some(since)) => Some(since),
                    (_, None) => Some(now),
                };
            }
        }
        for (i, a) in self.links.iter().enumerate() {
            for b in &self.links[i + 1..] {
                if let (Some((ta, _)), Some((tb, _))) = (a.last, b.last)
                    && !a.left
                    && !b.left
                {
                    let d = (0..3)
                        .map(|j| (ta.position[j] - tb.position[j]).powi(2))
                        .sum::<f32>()
                        .sqrt();
                    self.min_separation_m = self.min_separation_m.min(d);
                }
            }
        }
        Ok(())
    }

    /// The first vehicle of the formation that is lost or stuck, if any.
    fn fault(&self, now: u64) -> Option<RuntimeFault> {
        for (k, &member) in self.flying.members.iter().enumerate() {
            let link = &self.links[member];
            let stale = link
                .last
                .is_none_or(|(_, at)| now.saturating_sub(at) > self.lost_after_ns);
            let silent = link
                .silent_since
                .is_some_and(|since| now.saturating_sub(since) > self.lost_after_ns);
            if stale || silent {
                return Some(RuntimeFault::Lost { vehicle: k });
            }
        }
        match self.flying.executor.state() {
            ExecutorState::Stuck {
                vehicle, error_m, ..
            } => Some(RuntimeFault::OffSlot { vehicle, error_m }),
            _ => None,
        }
    }

    /// Plan the rest of the program without the faulty vehicle (see the module).
    fn replan(&mut self, fault: RuntimeFault, now: u64) {
        let lost = self.flying.members[fault.vehicle()];
        self.links[lost].left = true;
        self.counters.vehicles_left += 1;
        let n = self.flying.members.len();
        let phase = self.counters.phase.max(1) as usize;
        let positions: Vec<[f32; 3]> = self.positions[..n].to_vec();
        let flight = InFlight {
            program: &self.flying.program,
            phase,
            positions: &positions,
        };
        let remaining_members = |remaining: &[usize]| -> Vec<usize> {
            remaining.iter().map(|&k| self.flying.members[k]).collect()
        };
        let limits = *self.gate.limits();
        match replan_after_fault(
            &flight,
            fault,
            &limits,
            &Simulation {
                dynamics: Dynamics::default(),
                flight: None,
            },
            self.max_repairs,
            |_, _| None,
        ) {
            Ok(replanned) => {
                // (the diagnosis numbers vehicles in the program flown, 1-based)
                tracing::info!(
                    "formation: {} (the flight's vehicle {})",
                    replanned.diagnosis,
                    self.links[lost].number
                );
                let members = remaining_members(&replanned.remaining);
                match replanned.outcome {
                    PlanOutcome::Accepted {
                        program, report, ..
                    } if self.gate.admit(&program).is_ok() => {
                        tracing::info!(
                            "formation: {} for the {} that remain ({})",
                            if replanned.landing {
                                "landing where they are"
                            } else {
                                "the rest of the program replanned"
                            },
                            members.len(),
                            describe_phases(&program)
                        );
                        self.fly(*program, report.trajectory, members, now);
                    }
                    outcome => {
                        // not even a landing is safe (or the gate refused it): hold where
                        // they are
                        tracing::warn!(
                            "formation: no safe plan for the {} that remain ({}); holding",
                            members.len(),
                            outcome.summary()
                        );
                        self.hold(members, now);
                    }
                }
            }
            Err(e) => {
                tracing::warn!(
                    "formation: vehicle {} left the formation; no plan for the rest ({}); holding",
                    self.links[lost].number,
                    aeris_runtime::error_chain::chain(&e)
                );
                let members: Vec<usize> = self
                    .flying
                    .members
                    .iter()
                    .copied()
                    .filter(|m| *m != lost)
                    .collect();
                self.hold(members, now);
            }
        }
    }

    /// A new instruction in flight (`aeris formation say`): written for the vehicles of the
    /// formation, a take-off to their height put first when it has none (from the air it is
    /// a climb or descent to one height), planned from where they are through the same
    /// check and repair, and flown at once; refused, the formation flies on as before. The
    /// answer goes to `formation/reply`. A language model writes for seconds, during which
    /// the controllers hold their positions (no fresh setpoints).
    fn reshape(&mut self, command: &FormationCommand, now: u64) -> Result<(), RoleError> {
        let text = command.text.as_str_lossy();
        tracing::info!("formation: new instruction {}: {text:?}", command.id);
        let (outcome, answer) = match self.plan_in_flight(text) {
            Ok((written, outcome)) => {
                let shown = match &outcome {
                    PlanOutcome::Accepted { program, .. } => **program,
                    PlanOutcome::Refused { .. } => written,
                };
                let answer = format!("{}: {}", outcome.summary(), describe_phases(&shown));
                let said = match outcome {
                    PlanOutcome::Accepted { program, .. } if self.gate.admit(&program).is_err() => {
                        SayOutcome::Refused
                    }
                    PlanOutcome::Accepted {
                        program,
                        report,
                        repaired,
                        ..
                    } => {
                        let members = std::mem::take(&mut self.flying.members);
                        self.fly(*program, report.trajectory, members, now);
                        if repaired.is_empty() {
                            SayOutcome::Accepted
                        } else {
                            SayOutcome::Repaired
                        }
                    }
                    PlanOutcome::Refused { .. } => SayOutcome::Refused,
                };
                (said, answer)
            }
            Err(why) => (SayOutcome::Refused, format!("refused: {why}")),
        };
        tracing::info!("formation: instruction {}: {answer}", command.id);
        let mut reply = FormationReply {
            id: command.id,
            outcome: outcome as u8,
            ..FormationReply::default()
        };
        reply.text.set(&answer);
        self.reply.publish(&reply)?;
        Ok(())
    }

    /// Write and plan `text` for the formation in the air (see [`Self::reshape`]).
    fn plan_in_flight(&mut self, text: &str) -> Result<(FormationProgram, PlanOutcome), String> {
        let n = self.flying.members.len();
        let limits = *self.gate.with_vehicles(n as u8).limits();
        let mut program = self.writer.write(text, &limits).map_err(|e| {
            format!(
                "no program was written: {}",
                aeris_runtime::error_chain::chain(&e)
            )
        })?;
        if usize::from(program.vehicles) != n {
            return Err(format!(
                "the instruction is for {} vehicles; {n} fly in the formation",
                program.vehicles
            ));
        }
        let starts: Vec<[f32; 3]> = self.positions[..n].to_vec();
        let height = (starts.iter().map(|p| p[2]).sum::<f32>() / n.max(1) as f32)
            .max(limits.h_min)
            .min(limits.h_max);
        let first = program.phases().first().map(|p| p.kind);
        if first != Some(PhaseKind::TakeOff as u8) {
            let count = usize::from(program.phase_count);
            if count >= MAX_PHASES {
                return Err(format!(
                    "{count} phases and a take-off do not fit in {MAX_PHASES}"
                ));
            }
            program.phases.copy_within(0..count, 1);
            program.phases[0] = FormationPhase {
                kind: PhaseKind::TakeOff as u8,
                height_m: height,
                ..FormationPhase::default()
            };
            program.phase_count += 1;
        }
        let writer = &mut self.writer;
        let outcome = plan_program(
            &program,
            &starts,
            &limits,
            &Simulation::default(),
            self.max_repairs,
            |p, problem| writer.repair(text, p, problem, &limits),
        )
        .map_err(|e| {
            format!(
                "the check could not run: {}",
                aeris_runtime::error_chain::chain(&e)
            )
        })?;
        Ok((program, outcome))
    }

    /// Keep `members` where they are: an empty trajectory whose slots are their positions.
    fn hold(&mut self, members: Vec<usize>, now: u64) {
        let mut at = [[0.0f32; 3]; MAX_VEHICLES];
        for (k, &m) in members.iter().enumerate() {
            if let Some((t, _)) = self.links[m].last {
                at[k] = t.position;
            }
        }
        let trajectory = Trajectory {
            vehicles: members.len(),
            segments: vec![aeris_formation::Segment::stay(1, 0.0, f32::INFINITY, at)],
        };
        self.fly(self.flying.program, trajectory, members, now);
    }

    /// From now on fly `trajectory` (of `program`) with `members`.
    fn fly(
        &mut self,
        program: FormationProgram,
        trajectory: Trajectory,
        members: Vec<usize>,
        now: u64,
    ) {
        self.counters.vehicles = members.len() as u64;
        self.settled_logged = 0;
        if program != self.flying.program {
            self.tracks.program(&program);
        }
        self.flying = Flying {
            program,
            executor: FormationExecutor::new(trajectory, Tolerance::default()),
            members,
        };
        self.last_tick_ns = now;
    }

    /// Each vehicle of the formation its slot, bound by the hub's program gate; a slot the
    /// gate refuses is not sent (that controller holds) and counted.
    fn publish(&mut self, now: u64, phase: usize, landing: bool) -> Result<(), RoleError> {
        let phase = phase.min(u16::MAX as usize) as u16;
        for (k, &member) in self.flying.members.iter().enumerate() {
            self.seq += 1;
            match self
                .gate
                .bind_slot(self.slots[k].position, phase, landing, self.seq, now)
            {
                Ok(sp) => {
                    self.links[member].setpoints.publish(&sp)?;
                    self.counters.setpoints += 1;
                }
                Err(_) => self.counters.refused_slots += 1,
            }
        }
        Ok(())
    }
}
