//! `aeris record`: attach a recorder to a running flight, in the spirit of `ros2 bag
//! record`. The recorder is the same role `aeris run --record` starts (`aeris-record`),
//! run in this process; it stops on Ctrl-C or when the flight's supervisor is gone, and
//! finishes its file either way.

use crate::inspect::{resolve_flight, tool_bus};
use aeris_flight::recording::attach_spec;
use anyhow::{Context, Result};
use clap::Args;
use std::path::PathBuf;
use std::time::Duration;

/// Arguments of `aeris record`.
#[derive(Debug, Args)]
pub struct RecordArgs {
    /// The MCAP file to write (must not exist).
    pub file: PathBuf,
    /// Flight (default: the only one running).
    #[arg(long)]
    pub flight: Option<String>,
    /// The flight's run directory, where its supervisor wrote the role specs (default:
    /// $TMPDIR/aeris/FLIGHT, as `aeris run` uses).
    #[arg(long, value_name = "DIR")]
    pub run_dir: Option<PathBuf>,
    /// Only these topics, comma-separated (default: every topic the flight publishes).
    #[arg(long, value_name = "T,..", value_delimiter = ',')]
    pub topics: Option<Vec<String>>,
}

/// How often the watcher looks for the flight's supervisor.
const SUPERVISOR_POLL: Duration = Duration::from_millis(200);

/// `aeris record`.
pub fn run(args: RecordArgs) -> Result<()> {
    let flight = resolve_flight(args.flight)?;
    let run_dir = args
        .run_dir
        .unwrap_or_else(|| std::env::temp_dir().join("aeris").join(&flight));
    let file = std::path::absolute(&args.file)
        .with_context(|| format!("recording into {}", args.file.display()))?;
    let spec = attach_spec(&flight, &run_dir, &file, args.topics)
        .with_context(|| format!("attaching to flight `{flight}`"))?;
    let supervisor = tool_bus(&flight, "record")?
        .read_status_board()
        .with_context(|| format!("reading flight `{flight}`'s status"))?
        .supervisor_pid;
    // the flight over (its supervisor gone): stop as on Ctrl-C, so the file is finished
    std::thread::Builder::new()
        .name("flight watch".into())
        .spawn(move || {
            loop {
                std::thread::sleep(SUPERVISOR_POLL);
                // SAFETY: kill(2) with signal 0 only checks that the process exists.
                if supervisor == 0 || unsafe { libc::kill(supervisor as i32, 0) } != 0 {
                    eprintln!("aeris: the flight ended; finishing the recording");
                    // SAFETY: raise(3) with a valid signal number.
                    unsafe { libc::raise(libc::SIGTERM) };
                    return;
                }
            }
        })
        .context("starting the flight watcher")?;
    eprintln!(
        "aeris: recording flight {flight} into {} (Ctrl-C stops)",
        file.display()
    );
    crate::role_registry::run(spec).with_context(|| format!("recording flight `{flight}`"))?;
    let recording = aeris_record::read::Recording::open(&file)
        .with_context(|| format!("reading back {}", file.display()))?;
    let messages = recording.message_count("hub/report");
    println!(
        "recorded flight {flight} into {}: {} bytes, {messages} hub reports; `aeris replay {}` replays it",
        file.display(),
        std::fs::metadata(&file).map(|m| m.len()).unwrap_or(0),
        file.display()
    );
    Ok(())
}

impl crate::command::Execute for RecordArgs {
    fn execute(self) -> anyhow::Result<std::process::ExitCode> {
        run(self)?;
        Ok(std::process::ExitCode::SUCCESS)
    }
}
