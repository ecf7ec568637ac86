//! `aeris run` (the main job) and `aeris validate`.

use crate::flight::FlightMonitor;
use aeris_orchestrator::supervisor::{Supervisor, SupervisorEvent, SupervisorOptions};
use aeris_orchestrator::workflow::Workflow;
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
    /// Flight name: the namespace prefix of every service (default: flight-<pid>).
    #[arg(long)]
    pub flight: Option<String>,
    /// Where role specs and logs go (default: $TMPDIR/aeris/<flight>).
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
            "  {:<11} {:<10} {:<15} executor {}",
            r.name,
            r.kind,
            r.variant,
            r.executor.as_deref().unwrap_or("-")
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// `aeris run`.
pub fn run(args: RunArgs) -> Result<ExitCode> {
    let mut workflow = load(args.workflow.as_deref())?;
    for v in &args.variant {
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
    }
    if let Some(s) = args.max_duration {
        if !(s > 0.0 && s.is_finite()) {
            bail!("--max-duration must be a positive number of seconds");
        }
        workflow.mission.max_duration_s = s;
    }
    workflow.validate().context("workflow")?;
    let flight = args
        .flight
        .clone()
        .unwrap_or_else(|| format!("flight-{}", std::process::id()));
    let run_dir = args
        .run_dir
        .clone()
        .unwrap_or_else(|| std::env::temp_dir().join("aeris").join(&flight));
    let aeris_exe = std::env::current_exe().context("locating the aeris binary")?;
    signals::install_termination_handlers().context("installing signal handlers")?;

    let mission = workflow.mission.clone();
    let max_duration = Duration::from_secs_f64(mission.max_duration_s);
    let mut sup = Supervisor::start(SupervisorOptions {
        workflow,
        flight: flight.clone(),
        aeris_exe,
        run_dir: run_dir.clone(),
        autopilot: args.autopilot.clone(),
    })
    .with_context(|| format!("starting flight `{flight}`"))?;
    eprintln!(
        "aeris: flight {flight}: {} roles started (logs in {})",
        sup.roles().len(),
        run_dir.join("logs").display()
    );
    eprintln!("aeris: mission: {}", mission.instruction);
    sup.wait_ready(Duration::from_secs(60))
        .context("waiting for every role's first heartbeat")?;

    let mut monitor =
        FlightMonitor::new(sup.bus(), &mission).context("subscribing to the flight")?;
    let start = Instant::now();
    let mut last_progress = Instant::now();
    let mut failure: Option<String> = None;
    let (mut swaps_done, mut swaps_failed) = (0u64, 0u64);
    loop {
        for event in sup.step().context("supervising")? {
            match &event {
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
                _ => {}
            }
            match event {
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
                _ => {}
            }
        }
        monitor.poll().context("reading flight telemetry")?;
        let (step, steps) = monitor.active_step();
        let distance = monitor.distance_to_goal();
        sup.set_progress(
            step,
            steps,
            distance.unwrap_or(-1.0),
            monitor.ct_mean_s() as f32,
        );
        if monitor.reached_goal() || failure.is_some() {
            break;
        }
        if start.elapsed() > max_duration {
            failure = Some(format!(
                "the goal was not reached within {:.0} s",
                max_duration.as_secs_f64()
            ));
            break;
        }
        if signals::termination_requested() {
            failure = Some("interrupted".into());
            break;
        }
        if last_progress.elapsed() >= Duration::from_secs(2) {
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
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let duration = start.elapsed().as_secs_f64();
    let _ = monitor.poll();
    let restarts = sup.total_restarts();
    let mut summary = monitor.summary(&flight, duration, restarts as u64);
    summary.swaps_done = swaps_done;
    summary.swaps_failed = swaps_failed;
    let report = sup.shutdown(Duration::from_secs(3));
    eprintln!("aeris: shutdown: {report}");

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
        "  controller ticks {} missed {} refused setpoints {}; role restarts {}",
        summary.controller_ticks,
        summary.controller_missed_ticks,
        summary.controller_refused_setpoints,
        summary.role_restarts
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
