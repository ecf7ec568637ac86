//! The `aeris` command line.

mod agent_cmd;
mod bench;
mod command;
#[cfg(feature = "sim")]
mod distill_cmd;
#[cfg(feature = "sim")]
mod episodes_cmd;
#[cfg(feature = "sim")]
mod eval_cmd;
mod flight_print;
mod formation_cmd;
#[cfg(feature = "sim")]
mod formation_fly;
mod inspect;
mod keys_cmd;
mod migrate_cmd;
#[cfg(feature = "sim")]
mod plot_cmd;
mod record_cmd;
mod replay_cmd;
mod role_cmd;
mod role_registry;
mod roles_cmd;
mod run_cmd;
#[cfg(feature = "sim")]
mod scene_cmd;
#[cfg(feature = "sim")]
mod scene_video_cmd;
mod status_cmd;
mod swap_cmd;
mod topic_cmd;
mod validate_cmd;

use clap::{Parser, Subcommand};
use command::Execute;
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
    Status(status_cmd::StatusArgs),
    /// Inspect the topics of a running flight (like `ros2 topic`).
    Topic(topic_cmd::TopicArgs),
    /// Replace a running role by another variant of its pool, make-before-break: the new
    /// process loads and warms up beside the old one; once it is ready it takes over right
    /// after the old one's next completed cycle, then the old one stops. A variant that
    /// fails to come up is rolled back and the old one keeps running.
    Swap(swap_cmd::SwapArgs),
    /// Move a running role to another executor, CPU list or host. On the flight's host the
    /// move is live: every thread is re-bound, the pid stays, nothing restarts. To another
    /// host (`HOST:EXECUTOR`) and back it is make-before-break: the role starts there, takes
    /// over once ready, right after the old process's next completed cycle, and the old
    /// process stops. Onto or off an accelerator
    /// executor (`accelerator = "cuda:0"`) it is make-before-break too: the model role
    /// restarts with the other execution provider, refused if ONNX Runtime lacks it. Later
    /// restarts start there.
    Migrate(migrate_cmd::MigrateArgs),
    /// Check a workflow file and print what it would start.
    Validate(validate_cmd::ValidateArgs),
    /// List the role kinds and variants this build can run.
    Roles(roles_cmd::RolesArgs),
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
    Keys(keys_cmd::KeysArgs),
    /// Run a benchmark (IPC, camera, gate, control, models, flights: cycle, swap, ds, faults, record, hosts, formation) and print its figures.
    Bench(bench::BenchArgs),
    #[cfg(feature = "sim")]
    /// Fly VLN episodes through the full pipeline and score them (NE, SR, OSR, nDTW, SPL,
    /// ASR, CT, EER), per airspace; writes OUT/episodes.jsonl.
    Eval(eval_cmd::EvalArgs),
    #[cfg(feature = "sim")]
    /// Write training pairs for the aligned reasoner: fly `train` episodes with a teacher
    /// (the planner, or a language-model student the planner labels: DAgger) and write,
    /// for every decision, what the aligned model reads and the teacher's decision;
    /// writes OUT/pairs.jsonl.
    Distill(distill_cmd::DistillArgs),
    #[cfg(feature = "sim")]
    /// Generate and check VLN episodes (AerialVLN JSON format, train/val_unseen/test_unseen).
    Episodes(episodes_cmd::EpisodesArgs),
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
    Formation(formation_cmd::FormationArgs),
    /// Run one role in this process (the supervisor starts roles this way).
    #[command(hide = true)]
    Role(role_cmd::RoleArgs),
}

impl Command {
    /// Commands that read and print, and hold no socket of a flight.
    fn only_prints(&self) -> bool {
        match self {
            Command::Status(_)
            | Command::Topic(_)
            | Command::Validate(_)
            | Command::Roles(_)
            | Command::Keys(_) => true,
            #[cfg(feature = "sim")]
            Command::Episodes(_) => true,
            _ => false,
        }
    }
}

fn main() -> ExitCode {
    // iceoryx2 is configured explicitly (aeris_runtime::bus::iceoryx_config), so it has no
    // config-file warning to print; what fails on the bus comes back as a BusError naming
    // the service, so its own log keeps to errors unless IOX2_LOG_LEVEL asks for more.
    iceoryx2::prelude::set_log_level_from_env_or(iceoryx2::prelude::LogLevel::Error);
    // the libraries' messages, one plain line each on stderr (RUST_LOG filters)
    aeris_runtime::log::init_stderr();
    let cli = Cli::parse();
    if cli.command.only_prints() {
        // a reader that goes away (`aeris status | head`) ends the command as it ends
        // other Unix tools, instead of a panic in println!. Only for commands that just
        // print: a flight, an agent or a role keeps EPIPE as an error on its sockets.
        // SAFETY: signal(2) with a valid signal and disposition, before any thread starts.
        unsafe { libc::signal(libc::SIGPIPE, libc::SIG_DFL) };
    }
    let result = match cli.command {
        Command::Run(args) => args.execute(),
        Command::Status(args) => args.execute(),
        Command::Topic(args) => args.execute(),
        Command::Swap(args) => args.execute(),
        Command::Migrate(args) => args.execute(),
        Command::Validate(args) => args.execute(),
        Command::Roles(args) => args.execute(),
        Command::Replay(args) => args.execute(),
        Command::Record(args) => args.execute(),
        Command::Agent(args) => args.execute(),
        Command::Keys(args) => args.execute(),
        Command::Bench(args) => args.execute(),
        #[cfg(feature = "sim")]
        Command::Eval(args) => args.execute(),
        #[cfg(feature = "sim")]
        Command::Distill(args) => args.execute(),
        #[cfg(feature = "sim")]
        Command::Episodes(args) => args.execute(),
        #[cfg(feature = "sim")]
        Command::Scene(args) => args.execute(),
        #[cfg(feature = "sim")]
        Command::Plot(args) => args.execute(),
        Command::Formation(args) => args.execute(),
        Command::Role(args) => args.execute(),
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
            // a handle that could not reach its host, lost it while the role ran, or whose role
            // its host stopped for not hearing the handle: the
            // supervisor counts the link as lost either way (not a crash to restart)
            let unreachable = e.chain().any(|c| {
                matches!(
                    c.downcast_ref::<aeris_hosts::handle::HandleError>(),
                    Some(
                        aeris_hosts::handle::HandleError::Unreachable { .. }
                            | aeris_hosts::handle::HandleError::LinkLost { .. }
                            | aeris_hosts::handle::HandleError::StoppedThere { .. }
                    )
                )
            });
            ExitCode::from(if schema {
                role_cmd::EXIT_SCHEMA_MISMATCH
            } else if unreachable {
                aeris_orchestrator::restart::EXIT_HOST_UNREACHABLE as u8
            } else {
                1
            })
        }
    }
}
