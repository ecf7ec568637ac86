//! `aeris run`: the main job.

use crate::command::Execute;
use crate::flight_print::FlightPrinter;
use aeris_flight::{Flight, Overrides, StopRule};
use aeris_orchestrator::workflow::Workflow;
use anyhow::{Context, Result};
use clap::Args;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Arguments of `aeris run`.
#[derive(Debug, Args)]
pub struct RunArgs {
    /// Workflow file (TOML). Default: the built-in default flight (workflows/default.toml).
    pub workflow: Option<PathBuf>,
    /// Fly against this external autopilot (MAVLink URL such as udpin:0.0.0.0:14540,
    /// tcpout:127.0.0.1:5760 or serial:/dev/ttyACM0:57600) instead of the built-in vehicle.
    #[arg(long, value_name = "URL")]
    pub autopilot: Option<String>,
    /// The clock the flight runs on: `wall` (real time, the only clock of a real vehicle),
    /// or `sim`: simulated time in lockstep: every role takes its turns in a fixed order,
    /// time stands still while any role works, and the flight runs as fast as the roles
    /// compute, with the same decisions on any machine. `sim` needs the built-in vehicle
    /// (or a replay), no real camera and no roles on other hosts; its roles are not
    /// hot-swapped. CT and EER are then on the flight's clock (0: work takes no simulated
    /// time); what the work took on this machine is the summary's ct_compute and
    /// eer_compute, and each role's latency, both wall-clock.
    #[arg(long, value_name = "CLOCK", default_value = "wall")]
    pub clock: aeris_flight::FlightClock,
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
    #[arg(long, value_name = "SECONDS", value_parser = positive_seconds)]
    pub max_duration: Option<f64>,
    /// Dynamic scheduling off: roles stay on their declared executors whatever their
    /// latency (stall detection and restarts stay on).
    #[arg(long)]
    pub no_ds: bool,
    /// Variant ladder off: every role keeps its declared variant whatever its latency
    /// (the workflow's `[scheduling] adapt_variants = false`).
    #[arg(long)]
    pub fixed_variants: bool,
    /// Record every topic of the flight into this MCAP file (default: RUN_DIR/flight.mcap;
    /// a restarted recorder writes FILE.1, FILE.2, ...), every frame exactly, so that
    /// `aeris replay FILE` can replay it. Its FILE is optional: give the
    /// WORKFLOW before it (`aeris run flight.toml --record`).
    #[arg(long, value_name = "FILE", num_args = 0..=1)]
    #[allow(clippy::option_option)]
    pub record: Option<Option<PathBuf>>,
    /// With --record: every Nth camera frame's pixels are recorded as an image (0: none).
    #[arg(long, value_name = "N", requires = "record")]
    pub record_frame_every: Option<u64>,
    /// With --record: the images are JPEG of this quality (1-100; depth frames as PNG), or
    /// raw pixels with 0 [default: 80].
    #[arg(long, value_name = "Q", requires = "record", value_parser = clap::value_parser!(u8).range(0..=100))]
    pub record_jpeg_quality: Option<u8>,
    /// With --record: frames only as pictures (every Nth), not every frame exactly as well:
    /// much smaller for a real camera's noisy pixels, but `aeris replay` cannot replay it.
    #[arg(long, requires = "record")]
    pub record_no_exact_frames: bool,
}

/// The file `--record` names: as given (relative to the working directory), or
/// `flight.mcap` in the run directory when none is given.
pub(crate) fn record_path(arg: Option<&Path>) -> Result<PathBuf> {
    match arg {
        None => Ok(PathBuf::from("flight.mcap")),
        Some(file) => {
            std::path::absolute(file).with_context(|| format!("--record {}", file.display()))
        }
    }
}

/// A positive, finite number of seconds (clap names the flag when it is not).
fn positive_seconds(text: &str) -> std::result::Result<f64, String> {
    match text.parse::<f64>() {
        Ok(s) if s > 0.0 && s.is_finite() => Ok(s),
        _ => Err("expected a positive number of seconds".into()),
    }
}

pub(crate) fn load(path: Option<&Path>) -> Result<Workflow> {
    match path {
        // the error names the file
        Some(p) => Ok(Workflow::from_path(p)?),
        None => Workflow::builtin_default().context("built-in default workflow"),
    }
}

/// A build without the simulator cannot run its roles: say so before anything starts,
/// instead of letting the role fail in its log.
#[cfg(not(feature = "sim"))]
fn refuse_simulator_roles(
    workflow: &Workflow,
    variants: &[aeris_flight::VariantChoice],
    external_autopilot: bool,
) -> Result<()> {
    use aeris_schemas::RoleKind;
    for role in &workflow.roles {
        if role.kind == RoleKind::Hub || (role.kind == RoleKind::Vehicle && external_autopilot) {
            continue;
        }
        let variant = variants
            .iter()
            .rev()
            .find(|v| v.role == role.name)
            .map_or(role.variant.as_str(), |v| v.variant.as_str());
        if crate::role_registry::runner(role.kind, variant).is_none() {
            anyhow::bail!(
                "role `{}` is the simulator's `{}/{variant}`, and this aeris was built without \
                 the simulator (`--no-default-features`); rebuild with the `sim` feature or fly \
                 a workflow for real hardware with --autopilot",
                role.name,
                role.kind
            );
        }
    }
    Ok(())
}

/// `aeris run`.
impl Execute for RunArgs {
    fn execute(self) -> Result<ExitCode> {
        run(self)
    }
}

fn run(args: RunArgs) -> Result<ExitCode> {
    let workflow = load(args.workflow.as_deref())?;
    // a host's link fails here, naming the host, rather than in its bridge once flying
    for h in &workflow.hosts {
        if let Some(keys) = &h.keys {
            aeris_hosts::keys::Identity::load(std::path::Path::new(keys))
                .with_context(|| format!("the keys of the link to host `{}`", h.name))?;
        }
    }
    for h in workflow.hosts.iter().filter(|h| h.insecure) {
        eprintln!(
            "aeris: INSECURE link to host `{}` ({}): plain TCP, no authentication, no encryption; \
             anyone on the network can read this flight's data there and send it decisions",
            h.name, h.endpoint
        );
    }
    let variants = variant_choices(&args.variant)?;
    #[cfg(not(feature = "sim"))]
    refuse_simulator_roles(&workflow, &variants, args.autopilot.is_some())?;
    let overrides = Overrides {
        variants,
        max_duration_s: args.max_duration,
        dynamic: args.no_ds.then_some(false),
        fixed_variants: args.fixed_variants,
    };
    let mut flight = Flight::builder(workflow)
        .autopilot(args.autopilot.clone())
        .overrides(overrides)
        .stop_when(StopRule::Goal)
        .clock(args.clock)
        .language_offload_check(aeris_llm::offload_check);
    if let Some(name) = &args.flight {
        flight = flight.name(name);
    }
    if let Some(dir) = &args.run_dir {
        flight = flight.run_dir(dir);
    }
    if let Some(file) = &args.record {
        flight = flight.record(record_path(file.as_deref())?);
        if let Some(q) = args.record_jpeg_quality {
            flight = flight.record_jpeg_quality(q);
        }
        if let Some(n) = args.record_frame_every {
            flight = flight.record_frame_every(n);
        }
        flight = flight.record_exact_frames(!args.record_no_exact_frames);
    }
    let mut printer = FlightPrinter::new(true, "")?;
    let flight = flight.start()?;
    let (outcome, _) = flight.watch(&mut printer)?;
    println!("{outcome}");
    let summary = outcome.summary;
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

/// `--variant ROLE=VARIANT` arguments (`aeris run`, `aeris replay`, the flight benchmarks).
pub(crate) fn variant_choices(args: &[String]) -> Result<Vec<aeris_flight::VariantChoice>> {
    args.iter()
        .map(|v| v.parse().context("--variant"))
        .collect()
}
