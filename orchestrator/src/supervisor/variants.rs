//! The variant ladder hook: each scheduling tick the ladder ([`crate::ladder`]) judges every
//! role's recent cycles against its budget and may step it to a lighter or heavier variant,
//! which starts a hot swap; the ladder then follows where swaps (its own or by hand) landed.

use super::Supervisor;
use super::events::SupervisorEvent;
use super::role_runtime::RoleState;
use super::swap::DEFAULT_SWAP_READY_TIMEOUT;
use crate::ladder::{LadderConfig, LadderSample, StepDirection, VariantStep};
use crate::rebind::RoleLoad;
use crate::workflow::SchedulingSpec;
use std::fs::OpenOptions;
use std::io::Write as _;

/// The variant ladder's settings of a flight's `[scheduling]` table.
pub(super) fn ladder_config(s: &SchedulingSpec) -> LadderConfig {
    LadderConfig {
        margin: s.margin,
        ..LadderConfig::default()
    }
}

impl Supervisor {
    /// One tick of the variant ladder; its steps start hot swaps.
    pub(super) fn step_variants(&mut self, roles: &[RoleLoad], events: &mut Vec<SupervisorEvent>) {
        if !self.scheduling.adapt_variants {
            return;
        }
        let samples: Vec<LadderSample> = self
            .roles
            .iter()
            .zip(roles)
            .map(|(r, load)| LadderSample {
                cycle_ms: r.last_cycle_ms,
                cycles: r.worked_cycles,
                budget_ms: r.budget_ms,
                slowdown: load.slowdown,
                ready: r.state == RoleState::Running && r.running && r.swap.is_none(),
            })
            .collect();
        let mut steps: Vec<VariantStep> = Vec::new();
        self.ladder.tick(&samples, &mut steps);
        for step in steps {
            let role = &self.roles[step.role];
            let (Some(from), Some(to)) = (role.ladder.get(step.from), role.ladder.get(step.to))
            else {
                self.ladder.failed(step.role);
                continue;
            };
            let (name, from, to) = (role.name.clone(), from.clone(), to.clone());
            // down: the running variant already misses its budget on saturated CPUs, where
            // an idle load would never finish; up: the role fits, load on idle time only
            let load_idle = step.direction == StepDirection::Up;
            match self.start_swap(&name, &to, DEFAULT_SWAP_READY_TIMEOUT, load_idle, None) {
                Ok(_) => {
                    self.variant_steps += 1;
                    self.log_variant_step(&name, &from, &to, &step);
                    events.push(SupervisorEvent::VariantStepped {
                        name,
                        from,
                        to,
                        direction: step.direction,
                        latency_ms: step.latency_ms,
                        budget_ms: step.budget_ms,
                        predicted_ms: step.predicted_ms,
                    });
                    events.append(&mut self.pending);
                }
                Err(e) => {
                    self.ladder.failed(step.role);
                    events.push(SupervisorEvent::SwapFailed {
                        name,
                        variant: to,
                        reason: format!("variant ladder: {e}"),
                        place: None,
                    });
                }
            }
        }
    }

    /// The ladder learns where swaps landed: a committed swap (by the ladder or by hand)
    /// sets the role's rung, a rolled-back one marks the ladder's target unusable.
    pub(super) fn ladder_follow_swaps(&mut self, events: &[SupervisorEvent]) {
        for e in events {
            match e {
                SupervisorEvent::SwapReady { name, variant, .. } => {
                    if let Some(i) = self.roles.iter().position(|r| &r.name == name) {
                        let rung = self.roles[i].ladder.iter().position(|v| v == variant);
                        self.ladder.landed(i, rung);
                    }
                }
                SupervisorEvent::SwapFailed { name, .. } => {
                    if let Some(i) = self.roles.iter().position(|r| &r.name == name) {
                        self.ladder.failed(i);
                    }
                }
                _ => {}
            }
        }
    }

    /// A ladder step goes into the role's log beside the swap's own lines.
    fn log_variant_step(&self, name: &str, from: &str, to: &str, step: &VariantStep) {
        let Some(role) = self.roles.iter().find(|r| r.name == name) else {
            return;
        };
        if let Ok(mut f) = OpenOptions::new().append(true).open(&role.log_path) {
            let _ = writeln!(
                f,
                "=== aeris supervisor: variant ladder {:?} `{from}` -> `{to}`: last cycle {:.1} ms, budget {:.1} ms, predicted {} ===",
                step.direction,
                step.latency_ms,
                step.budget_ms,
                step.predicted_ms
                    .map_or("unmeasured".to_string(), |p| format!("{p:.1} ms"))
            );
        }
    }
}
