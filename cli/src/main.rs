//! The `aeris` command line.

mod agent_cmd;
mod bench;
#[cfg(feature = "sim")]
mod eval_cmd;
mod flight_print;
mod formation_cmd;
#[cfg(feature = "sim")]
mod formation_fly;
mod inspect;
mod keys_cmd;
#[cfg(feature = "sim")]
mod plot_cmd;
mod record_cmd;
mod replay_cmd;
mod role_registry;
mod run_cmd;
#[cfg(feature = "sim")]
mod scene_cmd;
#[cfg(feature = "sim")]
mod scene_video_cmd;

use aeris_schemas::RoleKind;
use anyhow::Context;
use clap::{Parser, Subcommand};
use std::path::PathBuf;
use std::process::ExitCode;

/// AERIS-rs: fly a drone from natural-language instructions, every role its own process,
/// frames and state over iceoryx2 shared memory, setpoints over MAVLink.
#[derive(Debug, Parser)]
#[command(name = "aeris", version, propagate_version = true)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Fly a mission: with no WORKFLOW, the built-in default mission in the built-in sim.
    Run(run_cmd::RunArgs),
    /// Show every role of a running flight: pid, CPU set, variant, heartbeat age, latency, restarts, memory.
    Status {
        /// Flight to show (default: the only one running).
        #[arg(long)]
        flight: Option<String>,
        /// Print one JSON object instead of a table.
        #[arg(long)]
        json: bool,
    },
    /// Inspect the topics of a running flight (like `ros2 topic`).
    Topic {
        #[command(subcommand)]
        command: TopicCommand,
    },
    /// Replace a running role by another variant of its pool, make-before-break: the new
    /// process loads and warms up beside the old one; once it is ready it takes over right
    /// after the old one's next completed cycle, then the old one stops. A variant that
    /// fails to come up is rolled back and the old one keeps running.
    Swap {
        /// Role name (see `aeris status`).
        role: String,
        /// Variant from the role's pool (the workflow's `variants`).
        variant: String,
        /// Flight (default: the only one running).
        #[arg(long)]
        flight: Option<String>,
        /// Seconds the new process may take to load, warm up and send its first heartbeat
        /// before the swap is rolled back (default: 90).
        #[arg(long, value_name = "SECONDS")]
        timeout: Option<f64>,
        /// Print one JSON object instead of progress lines.
        #[arg(long)]
        json: bool,
    },
    /// Move a running role to another executor, CPU list or host. On the flight's host the
    /// move is live: every thread is re-bound, the pid stays, nothing restarts. To another
    /// host (`HOST:EXECUTOR`) and back it is make-before-break: the role starts there, takes
    /// over once ready, right after the old process's next completed cycle, and the old
    /// process stops. Onto or off an accelerator
    /// executor (`accelerator = "cuda:0"`) it is make-before-break too: the model role
    /// restarts with the other execution provider, refused if ONNX Runtime lacks it. Later
    /// restarts start there.
    Migrate {
        /// Role name (see `aeris status`).
        role: String,
        /// An executor of the workflow, `cpuN` for one CPU, a CPU list such as `0-1`, or
        /// `HOST:EXECUTOR` for an executor on another host (`[hosts]` of the workflow).
        target: String,
        /// Flight (default: the only one running).
        #[arg(long)]
        flight: Option<String>,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// Check a workflow file and print what it would start.
    Validate {
        /// Workflow file (TOML).
        workflow: PathBuf,
    },
    /// List the role kinds and variants this build can run.
    Roles,
    /// Replay a recorded flight (`aeris run --record`): its frames and
    /// telemetry at their recorded times, perception, reasoning and the hub live, every
    /// decision set beside the recorded one; or compare variants on it (--compare).
    Replay(replay_cmd::ReplayArgs),
    /// Record a running flight into an MCAP file (like `ros2 bag record`), every frame
    /// exact, until Ctrl-C or the flight's end.
    Record(record_cmd::RecordArgs),
    /// Run roles on this host for flights whose supervisor runs on another (a daemon: one on
    /// every host a workflow's `[hosts.NAME]` names), until Ctrl-C.
    Agent(agent_cmd::AgentArgs),
    /// The flight's identities: a certificate authority and a certificate per host, which
    /// the links between hosts authenticate with (mutual TLS) and the agents' access rules
    /// name.
    Keys {
        #[command(subcommand)]
        command: keys_cmd::KeysCommand,
    },
    /// Run a benchmark (IPC, camera, gate, control, models, flights: cycle, swap, ds, faults, record, hosts, formation) and print its figures.
    Bench(bench::BenchArgs),
    #[cfg(feature = "sim")]
    /// Fly VLN episodes through the full pipeline and score them (NE, SR, OSR, nDTW, SPL,
    /// ASR, CT, EER), per airspace; writes OUT/episodes.jsonl.
    Eval(eval_cmd::EvalArgs),
    #[cfg(feature = "sim")]
    /// Generate and check VLN episodes (AerialVLN JSON format, train/val_unseen/test_unseen).
    Episodes(scene_cmd::EpisodesArgs),
    #[cfg(feature = "sim")]
    /// Look at a scene: its landmarks, an FPV frame from a pose, a video along a path or of a
    /// flight, a top-down map.
    Scene(scene_cmd::SceneArgs),
    #[cfg(feature = "sim")]
    /// Pictures of a flight or an evaluated episode: heartbeat timing trace, FPV strip
    /// with the active step, top-down map.
    Plot(plot_cmd::PlotArgs),
    /// Multi-UAV formations: plan a formation program from an instruction (parsed, flown
    /// in simulation, repaired on failure), or fly one with several built-in vehicles.
    Formation {
        #[command(subcommand)]
        command: formation_cmd::FormationCommand,
    },
    /// Run one role in this process (the supervisor starts roles this way).
    #[command(hide = true)]
    Role {
        /// Role spec (JSON) written by the supervisor.
        #[arg(long)]
        spec: PathBuf,
        /// Instance number the supervisor gave this process (overrides the spec's).
        #[arg(long)]
        instance: Option<u32>,
    },
}

#[derive(Debug, Subcommand)]
enum TopicCommand {
    /// List the services of running flights with their message types.
    List {
        /// Only this flight.
        #[arg(long)]
        flight: Option<String>,
    },
    /// Print the messages published on a topic.
    Echo {
        /// Topic, e.g. hub/setpoint (see `aeris topic list`).
        topic: String,
        /// Flight (default: the only one running).
        #[arg(long)]
        flight: Option<String>,
        /// Stop after this many messages.
        #[arg(long, short = 'n')]
        count: Option<u64>,
        /// Stop after this many seconds.
        #[arg(long, default_value_t = 10.0)]
        seconds: f64,
    },
    /// Measure the publication rate of a topic.
    Hz {
        /// Topic, e.g. vehicle/telemetry.
        topic: String,
        /// Flight (default: the only one running).
        #[arg(long)]
        flight: Option<String>,
        /// Measure for this many seconds.
        #[arg(long, default_value_t = 5.0)]
        seconds: f64,
    },
}

/// Exit code of a role that refused to join a flight of another schema (the supervisor
/// never restarts a role that exits with it).
const EXIT_SCHEMA_MISMATCH: u8 = aeris_orchestrator::restart::EXIT_SCHEMA_MISMATCH as u8;

fn run_role(spec: PathBuf, instance: Option<u32>) -> anyhow::Result<ExitCode> {
    let mut spec = aeris_runtime::RoleSpec::load(&spec)?;
    if let Some(n) = instance {
        spec.instance = n;
    }
    let name = spec.name.clone();
    // a role on another host stamps in the flight's host's clock
    aeris_runtime::clock::set_flight_clock_offset_ns(spec.flight_clock_offset_ns);
    if spec.remote.is_some() {
        // on another host: this process is the role's handle there
        let exit = aeris_hosts::handle::run_remote(spec)
            .with_context(|| format!("role `{name}` on its host"))?;
        return Ok(ExitCode::from(exit.exit_code()));
    }
    let result = role_registry::run(spec);
    result.with_context(|| format!("role `{name}` failed"))?;
    Ok(ExitCode::SUCCESS)
}

/// The catalog's kinds with the variants this build runs (a build without the simulator
/// runs none of the simulator's).
fn roles() -> anyhow::Result<ExitCode> {
    for kind in RoleKind::ALL {
        let info = kind.info();
        let variants: Vec<&str> = info
            .variants
            .iter()
            .copied()
            .filter(|v| role_registry::runner(kind, v).is_some())
            .collect();
        if variants.is_empty() {
            continue;
        }
        println!(
            "{:<11} variants: {:<24} {}",
            kind.name(),
            variants.join(", "),
            info.summary
        );
    }
    Ok(ExitCode::SUCCESS)
}

fn main() -> ExitCode {
    // iceoryx2 is configured explicitly (aeris_runtime::bus::iceoryx_config), so it has no
    // config-file warning to print; what fails on the bus comes back as a BusError naming
    // the service, so its own log keeps to errors unless IOX2_LOG_LEVEL asks for more.
    iceoryx2::prelude::set_log_level_from_env_or(iceoryx2::prelude::LogLevel::Error);
    // the libraries' messages, one plain line each on stderr (RUST_LOG filters)
    aeris_runtime::log::init_stderr();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Run(args) => run_cmd::run(args),
        Command::Status { flight, json } => {
            inspect::status(flight, json).map(|_| ExitCode::SUCCESS)
        }
        Command::Topic { command } => match command {
            TopicCommand::List { flight } => inspect::topic_list(flight),
            TopicCommand::Echo {
                topic,
                flight,
                count,
                seconds,
            } => inspect::topic_echo(flight, &topic, count, seconds),
            TopicCommand::Hz {
                topic,
                flight,
                seconds,
            } => inspect::topic_hz(flight, &topic, seconds),
        }
        .map(|_| ExitCode::SUCCESS),
        Command::Swap {
            role,
            variant,
            flight,
            timeout,
            json,
        } => inspect::swap(flight, &role, &variant, timeout, json).map(|_| ExitCode::SUCCESS),
        Command::Migrate {
            role,
            target,
            flight,
            json,
        } => inspect::migrate(flight, &role, &target, json).map(|_| ExitCode::SUCCESS),
        Command::Validate { workflow } => run_cmd::validate(&workflow),
        Command::Roles => roles(),
        Command::Replay(args) => replay_cmd::run(args).map(|_| ExitCode::SUCCESS),
        Command::Record(args) => record_cmd::run(args).map(|_| ExitCode::SUCCESS),
        Command::Agent(args) => agent_cmd::run(args).map(|_| ExitCode::SUCCESS),
        Command::Keys { command } => keys_cmd::run(command).map(|_| ExitCode::SUCCESS),
        Command::Bench(args) => bench::run(args).map(|_| ExitCode::SUCCESS),
        #[cfg(feature = "sim")]
        Command::Eval(args) => eval_cmd::run(args).map(|_| ExitCode::SUCCESS),
        #[cfg(feature = "sim")]
        Command::Episodes(args) => scene_cmd::episodes(args).map(|_| ExitCode::SUCCESS),
        #[cfg(feature = "sim")]
        Command::Scene(args) => scene_cmd::scene(args).map(|_| ExitCode::SUCCESS),
        #[cfg(feature = "sim")]
        Command::Plot(args) => plot_cmd::run(args).map(|_| ExitCode::SUCCESS),
        Command::Formation { command } => formation_cmd::run(command),
        Command::Role { spec, instance } => run_role(spec, instance),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("aeris: error: {e:#}");
            let schema = e.chain().any(|c| {
                matches!(
                    c.downcast_ref::<aeris_runtime::RoleError>(),
                    Some(aeris_runtime::RoleError::Bus(
                        aeris_runtime::BusError::Manifest { .. }
                            | aeris_runtime::BusError::IncompatibleSchema { .. }
                    ))
                ) || matches!(
                    c.downcast_ref::<aeris_runtime::BusError>(),
                    Some(
                        aeris_runtime::BusError::Manifest { .. }
                            | aeris_runtime::BusError::IncompatibleSchema { .. }
                    )
                ) || matches!(
                    c.downcast_ref::<aeris_hosts::handle::HandleError>(),
                    Some(aeris_hosts::handle::HandleError::Schema { .. })
                )
            });
            // a handle that could not reach its host, or lost it while the role ran: the
            // supervisor counts the link as lost either way (not a crash to restart)
            let unreachable = e.chain().any(|c| {
                matches!(
                    c.downcast_ref::<aeris_hosts::handle::HandleError>(),
                    Some(
                        aeris_hosts::handle::HandleError::Unreachable { .. }
                            | aeris_hosts::handle::HandleError::LinkLost { .. }
                    )
                )
            });
            ExitCode::from(if schema {
                EXIT_SCHEMA_MISMATCH
            } else if unreachable {
                aeris_orchestrator::restart::EXIT_HOST_UNREACHABLE as u8
            } else {
                1
            })
        }
    }
}
