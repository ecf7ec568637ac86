//! `aeris run` (the main job) and `aeris validate`.

use aeris_flight::{FlightMonitor, FlightSummary};
use aeris_orchestrator::executors::{
    AcceleratorInfo, ExecutorOrigin, ExecutorRegistry, accelerators_from,
};
use aeris_orchestrator::plan_launch;
use aeris_orchestrator::supervisor::{Supervisor, SupervisorEvent, SupervisorOptions};
use aeris_orchestrator::workflow::Workflow;
use aeris_runtime::affinity::CpuSet;
use aeris_runtime::signals;
use anyhow::{Context, Result, bail};
use clap::Args;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};

/// Arguments of `aeris run`.
#[derive(Debug, Args)]
pub struct RunArgs {
    /// Workflow file (TOML). Default: the built-in default flight (workflows/default.toml).
    pub workflow: Option<PathBuf>,
    /// Fly against this external autopilot (MAVLink URL such as udpin:0.0.0.0:14540,
    /// tcpout:127.0.0.1:5760 or serial:/dev/ttyACM0:57600) instead of the built-in vehicle.
    #[arg(long, value_name = "URL")]
    pub autopilot: Option<String>,
    /// Print the summary as one JSON object on the last line of stdout.
    #[arg(long)]
    pub json: bool,
    /// Flight name: the namespace prefix of every service (default: flight-PID).
    #[arg(long)]
    pub flight: Option<String>,
    /// Where role specs and logs go (default: $TMPDIR/aeris/FLIGHT).
    #[arg(long, value_name = "DIR")]
    pub run_dir: Option<PathBuf>,
    /// Run a role with another variant of its kind (see `aeris roles`), e.g.
    /// --variant reasoning=garbage (repeatable).
    #[arg(long, value_name = "ROLE=VARIANT")]
    pub variant: Vec<String>,
    /// Give up after this many seconds of flight, counted once every role is up
    /// (default: the mission's max_duration_s).
    #[arg(long, value_name = "SECONDS")]
    pub max_duration: Option<f64>,
    /// Dynamic scheduling off: roles stay on their declared executors whatever their
    /// latency (stall detection and restarts stay on).
    #[arg(long)]
    pub no_ds: bool,
    /// Variant ladder off: every role keeps its declared variant whatever its latency
    /// (the workflow's `[scheduling] adapt_variants = false`).
    #[arg(long)]
    pub fixed_variants: bool,
}

fn load(path: Option<&Path>) -> Result<Workflow> {
    match path {
        Some(p) => Workflow::from_path(p).with_context(|| format!("workflow {}", p.display())),
        None => Workflow::builtin_default().context("built-in default workflow"),
    }
}

/// `aeris validate WORKFLOW`.
pub fn validate(path: &Path) -> Result<ExitCode> {
    let w = load(Some(path))?;
    println!(
        "{}: ok — {} roles, {} subgoals",
        path.display(),
        w.roles.len(),
        w.mission.subgoals.len()
    );
    for r in &w.roles {
        println!(
            "  {:<18} {:<10} {:<15} executor {}",
            r.name,
            r.kind,
            r.variant,
            r.executor.as_deref().unwrap_or("-")
        );
    }
    // the executor registry a flight of it would start with
    let online = CpuSet::of_task(0).unwrap_or_else(|_| CpuSet::available());
    let plan =
        plan_launch(&w, "validate", None, &online, || Ok(0)).context("resolving the executors")?;
    let mut registry = ExecutorRegistry::discover(&plan.executors, &online);
    if let Some((providers, accelerators)) = onnx_accelerators() {
        registry.set_accelerators(providers, accelerators);
    }
    println!("executors:");
    for e in registry.executors() {
        let origin = match e.origin {
            ExecutorOrigin::Declared => "declared",
            ExecutorOrigin::Discovered => "discovered",
        };
        println!("  {:<18} CPUs {:<8} {origin}", e.name, e.cpus.to_string());
    }
    println!("{}", accelerator_line(&registry));
    Ok(ExitCode::SUCCESS)
}

/// What the provisioned ONNX Runtime reports: its execution providers and the accelerator
/// devices they found; `None` when no runtime is provisioned (the flight needs none unless
/// it runs model roles).
pub fn onnx_accelerators() -> Option<(Vec<String>, Vec<AcceleratorInfo>)> {
    let store = aeris_models::ModelStore::open(None).ok()?;
    let report = aeris_models::execution_providers(&store).ok()?;
    let devices: Vec<(String, String, String, u32)> = report
        .devices
        .iter()
        .map(|d| {
            (
                d.provider.clone(),
                d.kind.as_str().to_string(),
                d.vendor.clone(),
                d.device_id,
            )
        })
        .collect();
    Some((report.providers, accelerators_from(&devices)))
}

/// One line on the registry's accelerators, for logs.
pub fn accelerator_line(registry: &ExecutorRegistry) -> String {
    let Some(providers) = registry.providers() else {
        return "accelerators: unknown (no provisioned ONNX Runtime to ask)".into();
    };
    let providers = providers
        .iter()
        .map(|p| p.strip_suffix("ExecutionProvider").unwrap_or(p))
        .collect::<Vec<_>>()
        .join(", ");
    if registry.accelerators().is_empty() {
        return format!("accelerators: none (ONNX Runtime providers: {providers})");
    }
    let list = registry
        .accelerators()
        .iter()
        .map(|a| format!("{} ({} {} via {})", a.name, a.vendor, a.kind, a.provider))
        .collect::<Vec<_>>()
        .join(", ");
    format!("accelerators: {list} (ONNX Runtime providers: {providers})")
}

/// Apply `--variant ROLE=VARIANT` overrides and `--max-duration` to a workflow.
pub fn apply_overrides(
    workflow: &mut Workflow,
    variants: &[String],
    max_duration: Option<f64>,
) -> Result<()> {
    for v in variants {
        let Some((role, variant)) = v.split_once('=') else {
            bail!("--variant expects ROLE=VARIANT, got `{v}`");
        };
        let decl = workflow
            .roles
            .iter_mut()
            .find(|r| r.name == role)
            .with_context(|| format!("--variant: the workflow has no role `{role}`"))?;
        decl.variant = variant.to_string();
        if !decl.variants.iter().any(|x| x == variant) {
            decl.variants.push(variant.to_string());
        }
        // a variant chosen by hand off the role's ladder: the role keeps it
        if !decl.ladder.iter().any(|x| x == variant) {
            decl.ladder.clear();
        }
    }
    if let Some(s) = max_duration {
        if !(s > 0.0 && s.is_finite()) {
            bail!("--max-duration must be a positive number of seconds");
        }
        workflow.mission.max_duration_s = s;
    }
    workflow.validate().context("workflow")
}

/// When [`fly`] ends the flight (besides a failure or Ctrl-C).
// the benchmarks that used `Cycles` and `Hook` fly through aeris-flight now; `run` and
// `eval` follow in the next commit, and this goes
#[allow(dead_code)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StopRule {
    /// When the vehicle reached the goal (the main job).
    Goal,
    /// After this many semantic cycles (benchmarks: heartbeats, goal or not).
    Cycles(u64),
    /// When the vehicle is on the ground after having flown, wherever that is (VLN
    /// episodes: the agent stopped).
    Landed,
    /// Only when the step hook says so (benchmarks that inject faults and then fly on).
    Hook,
}

/// What a flight needs besides its workflow.
#[derive(Debug, Clone)]
pub struct FlightPlan {
    /// Flight name (namespace prefix).
    pub flight: String,
    /// Specs and logs.
    pub run_dir: PathBuf,
    /// External autopilot URL.
    pub autopilot: Option<String>,
    /// When to end.
    pub stop: StopRule,
    /// Print progress to stderr every 2 s.
    pub progress: bool,
    /// Dynamic scheduling: `Some(false)` turns the workflow's `[scheduling] dynamic` off,
    /// `Some(true)` on, `None` keeps it.
    pub dynamic: Option<bool>,
}

/// How a flight went.
#[allow(dead_code)]
pub struct FlightOutcome {
    /// The summary.
    pub summary: FlightSummary,
    /// Why it ended early, if it did.
    pub failure: Option<String>,
    /// Cycle times (s) of every committed cycle.
    pub ct_samples_s: Vec<f64>,
    /// The per-cycle trace (what `cycles.jsonl` holds).
    pub trace: Vec<aeris_flight::CycleTrace>,
}

/// Fly `workflow`: start the supervisor, wait for every role, then supervise until the
/// stop rule, a failure, the mission's time limit or Ctrl-C; `each_step` sees the
/// supervisor, the monitor and the step's events (benchmarks trigger swaps from it) and
/// returns `true` to end the flight.
pub fn fly(
    workflow: Workflow,
    plan: &FlightPlan,
    mut each_step: impl FnMut(&mut Supervisor, &FlightMonitor, &[SupervisorEvent]) -> Result<bool>,
) -> Result<FlightOutcome> {
    let flight = plan.flight.clone();
    let aeris_exe = std::env::current_exe().context("locating the aeris binary")?;
    signals::install_termination_handlers().context("installing signal handlers")?;

    let mission = workflow.mission.clone();
    let max_duration = Duration::from_secs_f64(mission.max_duration_s);
    let mut sup = Supervisor::start(SupervisorOptions {
        workflow,
        flight: flight.clone(),
        aeris_exe,
        run_dir: plan.run_dir.clone(),
        autopilot: plan.autopilot.clone(),
    })
    .with_context(|| format!("starting flight `{flight}`"))?;
    eprintln!(
        "aeris: flight {flight}: {} roles started (logs in {})",
        sup.roles().len(),
        plan.run_dir.join("logs").display()
    );
    eprintln!("aeris: mission: {}", mission.instruction);
    if let Some(on) = plan.dynamic {
        sup.set_dynamic(on);
    }
    if let Some((providers, accelerators)) = onnx_accelerators() {
        sup.set_accelerators(providers, accelerators);
    }
    eprintln!("aeris: {}", accelerator_line(sup.registry()));
    sup.wait_ready(Duration::from_secs(60))
        .context("waiting for every role's first heartbeat")?;

    let mut monitor =
        FlightMonitor::new(sup.bus(), &mission).context("subscribing to the flight")?;
    let start = Instant::now();
    let mut last_progress = Instant::now();
    let mut failure: Option<String> = None;
    let (mut swaps_done, mut swaps_failed) = (0u64, 0u64);
    loop {
        let events = sup.step().context("supervising")?;
        for event in &events {
            match event {
                SupervisorEvent::SwapStarted { .. } | SupervisorEvent::SwapReady { .. } => {
                    eprintln!("aeris: {event}");
                }
                SupervisorEvent::SwapDone { .. } => {
                    swaps_done += 1;
                    eprintln!("aeris: {event}");
                }
                SupervisorEvent::SwapFailed { .. } => {
                    swaps_failed += 1;
                    eprintln!("aeris: {event}");
                }
                SupervisorEvent::RoleGaveUp { name } => {
                    failure = Some(format!("role `{name}` exhausted its restart budget"));
                }
                SupervisorEvent::RoleRestarted {
                    name,
                    pid,
                    restarts,
                } => {
                    eprintln!("aeris: restarted {name} (pid {pid}, restart #{restarts})");
                }
                SupervisorEvent::RoleExited { name, status } => {
                    eprintln!("aeris: role {name} exited: {status}");
                }
                SupervisorEvent::RoleMigrated(_)
                | SupervisorEvent::MigrationFailed { .. }
                | SupervisorEvent::RoleStalled { .. }
                | SupervisorEvent::ServiceLost { .. }
                | SupervisorEvent::VariantStepped { .. }
                | SupervisorEvent::BindingProbed { .. }
                | SupervisorEvent::InitialBinding { .. } => eprintln!("aeris: {event}"),
                _ => {}
            }
        }
        monitor.poll().context("reading flight telemetry")?;
        let hook_done = each_step(&mut sup, &monitor, &events)?;
        let (step, steps) = monitor.active_step();
        let distance = monitor.distance_to_goal();
        sup.set_progress(
            step,
            steps,
            distance.unwrap_or(-1.0),
            monitor.ct_mean_s() as f32,
        );
        let done = match plan.stop {
            StopRule::Goal => monitor.reached_goal(),
            StopRule::Cycles(n) => monitor.cycles() >= n,
            StopRule::Landed => monitor.landed_after_flight(),
            StopRule::Hook => false,
        };
        if done || hook_done || failure.is_some() {
            break;
        }
        if start.elapsed() > max_duration {
            failure = Some(match plan.stop {
                StopRule::Goal => format!(
                    "the goal was not reached within {:.0} s",
                    max_duration.as_secs_f64()
                ),
                StopRule::Cycles(n) => format!(
                    "{n} cycles did not complete within {:.0} s",
                    max_duration.as_secs_f64()
                ),
                StopRule::Landed => format!(
                    "the vehicle did not land within {:.0} s",
                    max_duration.as_secs_f64()
                ),
                StopRule::Hook => format!(
                    "the benchmark did not finish within {:.0} s",
                    max_duration.as_secs_f64()
                ),
            });
            break;
        }
        if signals::termination_requested() {
            failure = Some("interrupted".into());
            break;
        }
        if plan.progress && last_progress.elapsed() >= Duration::from_secs(2) {
            last_progress = Instant::now();
            let text = usize::from(step)
                .checked_sub(1)
                .and_then(|i| mission.subgoals.get(i))
                .map(|s| s.text.as_str())
                .unwrap_or("waiting for the first decision");
            let pos = monitor.position().unwrap_or([f32::NAN; 3]);
            eprintln!(
                "[{:6.1} s] step {step}/{steps} \"{text}\"  distance to goal {}  alt {:.1} m  CT {:.3} s  EER {:.1}%  rejected {}  restarts {}",
                start.elapsed().as_secs_f64(),
                distance
                    .map(|d| format!("{d:.1} m"))
                    .unwrap_or_else(|| "?".into()),
                pos[2],
                monitor.ct_mean_s(),
                monitor.eer() * 100.0,
                monitor.rejected(),
                sup.total_restarts(),
            );
            if monitor.invalid_reports() > 0 {
                eprintln!(
                    "aeris: {} hub reports failed validation and were not counted",
                    monitor.invalid_reports()
                );
            }
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let duration = start.elapsed().as_secs_f64();
    let _ = monitor.poll();
    let restarts = sup.total_restarts();
    let mut summary = monitor.summary(&flight, duration, restarts as u64);
    summary.migrations = u64::from(sup.total_migrations());
    summary.variant_steps = u64::from(sup.total_variant_steps());
    summary.stalls = sup.roles().iter().map(|r| u64::from(r.stalls())).sum();
    summary.swaps_done = swaps_done;
    summary.swaps_failed = swaps_failed;
    let report = sup.shutdown(Duration::from_secs(3));
    eprintln!("aeris: shutdown: {report}");
    let trace_path = plan.run_dir.join("cycles.jsonl");
    write_trace(&trace_path, monitor.trace())
        .with_context(|| format!("writing {}", trace_path.display()))?;
    let ct_samples_s = monitor.ct_samples_s().to_vec();
    Ok(FlightOutcome {
        summary,
        failure,
        ct_samples_s,
        trace: monitor.trace().to_vec(),
    })
}

/// Write a flight's cycle trace, one JSON object per line.
fn write_trace(path: &std::path::Path, trace: &[aeris_flight::CycleTrace]) -> Result<()> {
    use std::io::Write;
    let mut out = std::io::BufWriter::new(std::fs::File::create(path)?);
    for c in trace {
        serde_json::to_writer(&mut out, c)?;
        out.write_all(b"\n")?;
    }
    out.flush()?;
    Ok(())
}

/// `aeris run`.
pub fn run(args: RunArgs) -> Result<ExitCode> {
    let mut workflow = load(args.workflow.as_deref())?;
    apply_overrides(&mut workflow, &args.variant, args.max_duration)?;
    if args.fixed_variants {
        workflow.scheduling.adapt_variants = false;
    }
    let flight = args
        .flight
        .clone()
        .unwrap_or_else(|| format!("flight-{}", std::process::id()));
    let run_dir = args
        .run_dir
        .clone()
        .unwrap_or_else(|| std::env::temp_dir().join("aeris").join(&flight));
    let plan = FlightPlan {
        flight: flight.clone(),
        run_dir,
        autopilot: args.autopilot.clone(),
        stop: StopRule::Goal,
        progress: true,
        dynamic: args.no_ds.then_some(false),
    };
    let FlightOutcome {
        summary, failure, ..
    } = fly(workflow, &plan, |_, _, _| Ok(false))?;

    println!(
        "flight {flight}: {}",
        if summary.reached_goal {
            "goal reached"
        } else {
            "goal NOT reached"
        }
    );
    if let Some(f) = &failure {
        println!("  reason: {f}");
    }
    println!(
        "  final distance to goal {:.2} m after {:.1} s; subgoals reached by ATT {}/{}",
        summary.final_distance_m,
        summary.duration_s,
        summary.max_active_step,
        summary.subgoals_total
    );
    println!(
        "  cycles {} (committed {}), CT mean {:.3} s (std {:.3}, p95 {:.3}); stages: perception {:.3} reasoning {:.3} routing {:.4} binding {:.4} s",
        summary.cycles,
        summary.cycles_committed,
        summary.ct_mean_s,
        summary.ct_std_s,
        summary.ct_p95_s,
        summary.stages_mean_s.perception,
        summary.stages_mean_s.reasoning,
        summary.stages_mean_s.routing,
        summary.stages_mean_s.binding
    );
    println!(
        "  EER {:.2}%; decisions received {} rejected {} late {} reused {}; sequence gaps {} reorders {}",
        summary.eer * 100.0,
        summary.decisions_received,
        summary.decisions_rejected,
        summary.decisions_late,
        summary.decisions_reused,
        summary.sequence_gaps,
        summary.sequence_reorders
    );
    println!(
        "  controller ticks {} missed {} refused setpoints {}; role restarts {}, stalls {}, live migrations {}",
        summary.controller_ticks,
        summary.controller_missed_ticks,
        summary.controller_refused_setpoints,
        summary.role_restarts,
        summary.stalls,
        summary.migrations
    );
    if args.json {
        println!(
            "{}",
            serde_json::to_string(&summary).context("serialising the summary")?
        );
    }
    Ok(if summary.reached_goal {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(2)
    })
}
