//! `aeris bench ds`: the closed loop under a standard interference scenario, flown twice in
//! one invocation — dynamic scheduling on, then off. Partway through each flight a CPU hog
//! (busy threads pinned to the CPUs of the role with the highest latency, the heaviest)
//! lands; the figures are taken over the cycles from the hog's landing to the end.

use crate::bench_flight::FlightBenchArgs;
use crate::run_cmd::{FlightPlan, StopRule, apply_overrides, fly};
use aeris_flight::CycleTrace;
use aeris_orchestrator::supervisor::SupervisorEvent;
use aeris_orchestrator::workflow::Workflow;
use aeris_runtime::affinity::CpuSet;
use aeris_runtime::clock::monotonic_ns;
use aeris_runtime::stats::{mean_std, percentile};
use anyhow::{Context, Result, bail};
use clap::Args;
use serde::Serialize;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

/// Arguments of `aeris bench ds`.
#[derive(Debug, Args)]
pub struct DsArgs {
    /// Semantic heartbeats per flight (committed or reused cycles).
    #[arg(long, default_value_t = 40)]
    pub heartbeats: u64,
    /// Heartbeats flown before the hog lands.
    #[arg(long, default_value_t = 10)]
    pub hog_after: u64,
    /// Busy threads of the hog, all pinned to the heaviest role's CPUs.
    #[arg(long, default_value_t = 4)]
    pub hog_threads: usize,
    #[command(flatten)]
    pub flight: FlightBenchArgs,
}

/// One flight of the scenario.
#[derive(Debug, Clone, Serialize)]
pub struct DsRun {
    /// Mean cycle time over the committed cycles after the hog landed (s); `None` (JSON
    /// null) when none committed: a cycle time of 0 would read as a perfect one.
    pub ct_mean_s: Option<f64>,
    /// Its 95th percentile (s); `None` when no cycle committed.
    pub ct_p95_s: Option<f64>,
    /// Execution error rate over those cycles (reused / all).
    pub eer: f64,
    /// Automatic live moves after the hog landed.
    pub migrations: u64,
    /// From the hog's landing to the first completed automatic move (ms); `None` without one.
    pub slip_to_migrated_ms: Option<f64>,
    /// The role the hog landed on, and its CPUs then.
    pub hogged_role: String,
    /// CPUs the hog ran on.
    pub hog_cpus: String,
    /// Cycles measured (after the hog landed).
    pub cycles: usize,
    /// Every move of the flight (initial binding included), as printed.
    pub moves: Vec<String>,
}

/// `aeris bench ds --json`.
#[derive(Debug, Serialize)]
pub struct DsReport {
    /// Dynamic scheduling on.
    pub ds_on: DsRun,
    /// Dynamic scheduling off.
    pub ds_off: DsRun,
}

/// Busy threads pinned to a CPU set until dropped.
struct Hog {
    stop: Arc<AtomicBool>,
    threads: Vec<std::thread::JoinHandle<()>>,
}

impl Hog {
    fn start(cpus: &CpuSet, n: usize) -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let threads = (0..n)
            .map(|_| {
                let stop = stop.clone();
                let cpus = cpus.clone();
                std::thread::spawn(move || {
                    let _ = cpus.bind_task(0);
                    let mut x = 0u64;
                    while !stop.load(Ordering::Relaxed) {
                        for i in 0..10_000u64 {
                            x = std::hint::black_box(x.wrapping_mul(31).wrapping_add(i));
                        }
                    }
                })
            })
            .collect();
        Self { stop, threads }
    }
}

impl Drop for Hog {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

fn workflow(a: &FlightBenchArgs) -> Result<Workflow> {
    let mut w = match &a.workflow {
        Some(p) => Workflow::from_path(p).with_context(|| format!("workflow {}", p.display()))?,
        None => Workflow::builtin_models().context("built-in model workflow")?,
    };
    // the built-in model flight runs its reasoner on every CPU, where a hog on "its
    // executor" leaves nowhere to go: bind it to the perception executor instead
    if a.workflow.is_none()
        && let Some(r) = w.roles.iter_mut().find(|r| r.kind == "reasoning")
    {
        r.executor = Some("perception".into());
    }
    apply_overrides(&mut w, &a.variant, None)?;
    // the figures are dynamic scheduling's alone: the variant ladder would answer the hog
    // with a lighter reasoner in both runs
    w.scheduling.adapt_variants = false;
    Ok(w)
}

fn fly_once(a: &DsArgs, dynamic: bool) -> Result<DsRun> {
    let mut w = workflow(&a.flight)?;
    let period_s = w.timing.heartbeat_period_ms as f64 / 1000.0;
    w.mission.max_duration_s = w
        .mission
        .max_duration_s
        .max(a.heartbeats as f64 * period_s * 4.0 + 60.0);
    let tag = if dynamic { "ds-on" } else { "ds-off" };
    let flight = format!("bench-{tag}-{}", std::process::id());
    let plan = FlightPlan {
        run_dir: a
            .flight
            .run_dir
            .as_ref()
            .map(|d| d.join(tag))
            .unwrap_or_else(|| std::env::temp_dir().join("aeris").join(&flight)),
        flight,
        autopilot: None,
        stop: StopRule::Cycles(a.heartbeats),
        progress: true,
        dynamic: Some(dynamic),
    };
    let mut hog: Option<Hog> = None;
    let mut landed: Option<(u64, usize)> = None;
    let (mut hogged_role, mut hog_cpus) = (String::new(), String::new());
    let mut first_move_ns: Option<u64> = None;
    let mut migrations = 0u64;
    let mut moves = Vec::new();
    let outcome = fly(w, &plan, |sup, monitor, events| {
        for e in events {
            if let SupervisorEvent::RoleMigrated(m) = e {
                moves.push(e.to_string());
                if let Some((at, _)) = landed
                    && m.trigger.is_some()
                {
                    migrations += 1;
                    first_move_ns.get_or_insert(m.done_ns.saturating_sub(at));
                }
            }
        }
        if hog.is_none() && monitor.cycles() >= a.hog_after {
            // the heaviest role: the highest p50 latency among the roles with a budget
            let heaviest = sup
                .roles()
                .iter()
                .filter(|r| r.budget_ms().is_some() && !r.cpus().is_empty())
                .filter_map(|r| Some((r.latency_ms()?[0], r)))
                .max_by(|a, b| a.0.total_cmp(&b.0))
                .map(|(_, r)| r);
            if let Some(r) = heaviest
                && let Ok(set) = CpuSet::parse(r.cpus())
            {
                hogged_role = r.name().to_string();
                hog_cpus = set.to_string();
                eprintln!(
                    "aeris: bench ds: hog of {} threads lands on CPUs {set} (role `{}`)",
                    a.hog_threads,
                    r.name()
                );
                hog = Some(Hog::start(&set, a.hog_threads));
                landed = Some((monotonic_ns(), monitor.trace().len()));
            }
        }
        Ok(false)
    })?;
    drop(hog);
    if let Some(f) = outcome.failure {
        bail!("bench ds ({tag}): the flight ended early: {f}");
    }
    let Some((_, from)) = landed else {
        bail!("bench ds ({tag}): the hog never landed (no role had latency figures)");
    };
    let after: &[CycleTrace] = outcome.trace.get(from..).unwrap_or(&[]);
    let ct: Vec<f64> = after
        .iter()
        .filter(|c| c.committed)
        .map(|c| c.ct_s)
        .collect();
    let reused = after.iter().filter(|c| c.reused).count();
    Ok(DsRun {
        ct_mean_s: mean_std(&ct).map(|(m, _)| m),
        ct_p95_s: percentile(&ct, 95.0),
        eer: if after.is_empty() {
            0.0
        } else {
            reused as f64 / after.len() as f64
        },
        migrations,
        slip_to_migrated_ms: first_move_ns.map(|ns| ns as f64 / 1e6),
        hogged_role,
        hog_cpus,
        cycles: after.len(),
        moves,
    })
}

/// `aeris bench ds`.
pub fn ds(a: DsArgs) -> Result<()> {
    if a.heartbeats <= a.hog_after {
        bail!("--heartbeats must be more than --hog-after");
    }
    if a.hog_threads == 0 {
        bail!("--hog-threads must be at least 1");
    }
    let ds_on = fly_once(&a, true)?;
    let ds_off = fly_once(&a, false)?;
    println!(
        "dynamic scheduling under a {}-thread CPU hog landing after {} heartbeats (figures from the landing on)",
        a.hog_threads, a.hog_after
    );
    println!(
        "  {:<7} {:>10} {:>10} {:>7} {:>10} {:>16}  hogged role (CPUs)",
        "", "CT mean s", "CT p95 s", "EER %", "migrations", "slip->moved ms"
    );
    let seconds = |s: Option<f64>| s.map_or_else(|| "-".into(), |s| format!("{s:.3}"));
    for (name, r) in [("DS on", &ds_on), ("DS off", &ds_off)] {
        println!(
            "  {:<7} {:>10} {:>10} {:>7.1} {:>10} {:>16}  {} ({})",
            name,
            seconds(r.ct_mean_s),
            seconds(r.ct_p95_s),
            r.eer * 100.0,
            r.migrations,
            r.slip_to_migrated_ms
                .map(|m| format!("{m:.0}"))
                .unwrap_or_else(|| "-".into()),
            r.hogged_role,
            r.hog_cpus
        );
    }
    for m in &ds_on.moves {
        println!("  DS on: {m}");
    }
    if a.flight.json {
        println!("{}", serde_json::to_string(&DsReport { ds_on, ds_off })?);
    }
    Ok(())
}
