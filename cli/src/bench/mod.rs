//! `aeris bench ...`: run the benchmarks of `aeris-bench` and print their figures.

pub mod camera;
pub mod ds;
pub mod faults;
pub mod flight;
pub mod formation;
pub mod hosts;
pub mod json;
pub mod models;

use aeris_bench::control::{self, ControlConfig, ControlReport, SchedChoice};
use aeris_bench::ipc::{self, IpcConfig, IpcReport, PongSpec, Transport, Wake};
use anyhow::Context;
use clap::{Args, Subcommand, ValueEnum};

/// Arguments of `aeris bench`.
#[derive(Debug, Args)]
pub struct BenchArgs {
    #[command(subcommand)]
    pub command: BenchCommand,
}

/// The benchmarks.
#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// Two-process round trips: iceoryx2 zero copy (busy-poll, event) against a Unix socket.
    Ipc(IpcArgs),
    /// Glass-to-shared-memory latency of the `gstreamer` camera role (buffer capture time to
    /// frame readable on `camera/rgb`), p50/p99, and dropped frames, on live videotestsrc
    /// streams (640x480 and 1280x720).
    Camera(crate::bench::camera::CameraArgs),
    /// Cost per decision of the hub's gate: validate + clamp + bind (median, p99).
    Gate(GateArgs),
    /// Controller period jitter on absolute deadlines, alone and with a CPU hog on every core.
    Control(ControlArgs),
    /// Every model a role hosts: load time, latency p50/p95, memory (a process per model).
    Models(crate::bench::models::ModelsArgs),
    /// The model flight end to end: cycle time per stage (mean, std, p95) and EER over N
    /// heartbeats.
    Cycle(crate::bench::flight::CycleArgs),
    /// Hot swaps during the model flight: missed heartbeats and setpoint gaps per swap.
    Swap(crate::bench::flight::SwapArgs),
    /// Dynamic scheduling with the variant ladder, alone, and off, under a CPU hog landing
    /// on the heaviest role's CPUs: CT, EER, live migrations, ladder steps, time from the
    /// hog's landing to the completed move.
    Ds(crate::bench::ds::DsArgs),
    /// Fault injection over one default flight: SIGKILL and SIGSTOP of every role, a
    /// garbage reasoner, a shared-memory service removed; detection and recovery times,
    /// missed controller ticks, lost decisions, invalid setpoints per fault.
    Faults(crate::bench::faults::FaultsArgs),
    /// What recording costs: the default (and --models the model) flight without and with
    /// the recorder: controller missed ticks, CT, EER, recorder CPU, MB per minute.
    Record(crate::bench::flight::RecordArgs),
    /// Roles on a second host (two network namespaces on this machine; needs root): CT of
    /// the default flight with the reasoner and perception there vs on board, per link
    /// delay (netem), frames across; the reasoner moved there and back; a link cut.
    Hosts(crate::bench::hosts::HostsArgs),
    /// Formation programs from the benchmark instructions by every variant (parser,
    /// language models): time to write, valid as written, accepted, repaired or refused,
    /// the parser's phases or not, closest approach in simulation.
    Formation(crate::bench::formation::FormationArgs),
    /// One model of `bench models` (started by it).
    #[command(name = "model-probe", hide = true)]
    ModelProbe(crate::bench::models::ModelProbeArgs),
    /// The second process of `bench ipc` (started by it).
    #[command(name = "ipc-pong", hide = true)]
    IpcPong(IpcPongArgs),
}

/// Arguments of `aeris bench gate`.
#[derive(Debug, Args)]
pub struct GateArgs {
    /// Timed calls per mix.
    #[arg(long, default_value_t = 200_000)]
    pub calls: usize,
    /// Print one JSON object on the last line of stdout.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `aeris bench ipc`.
#[derive(Debug, Args)]
pub struct IpcArgs {
    /// Measured round trips per row.
    #[arg(long, default_value_t = 2000)]
    pub iterations: usize,
    /// Warm-up round trips per row (not reported).
    #[arg(long, default_value_t = 200)]
    pub warmup: usize,
    /// Payload sizes in bytes (default: 64, 640x480x3, 1920x1080x3).
    #[arg(long, value_delimiter = ',')]
    pub payloads: Vec<usize>,
    /// Only these transports (default: all).
    #[arg(long, value_enum, value_delimiter = ',')]
    pub transport: Vec<TransportArg>,
    /// Only these wake-up modes (default: all).
    #[arg(long, value_enum, value_delimiter = ',')]
    pub wake: Vec<WakeArg>,
    /// Do not pin ping and pong to different CPUs.
    #[arg(long)]
    pub no_pin: bool,
    /// Print one JSON object on the last line of stdout.
    #[arg(long)]
    pub json: bool,
}

/// A transport on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum TransportArg {
    /// iceoryx2 zero copy.
    Iceoryx2,
    /// Unix domain socket.
    Uds,
}

/// A wake-up mode on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum WakeArg {
    /// Spin on receive.
    Busy,
    /// Sleep until woken.
    Event,
}

/// Arguments of the hidden `aeris bench ipc-pong`.
#[derive(Debug, Args)]
pub struct IpcPongArgs {
    /// The row's pong spec (JSON), written by `bench ipc`.
    #[arg(long)]
    pub spec: String,
}

/// Arguments of `aeris bench control`.
#[derive(Debug, Args)]
pub struct ControlArgs {
    /// Seconds per row.
    #[arg(long, default_value_t = 5.0)]
    pub seconds: f64,
    /// Loop rate in Hz.
    #[arg(long, default_value_t = 50.0)]
    pub rate_hz: f64,
    /// Scheduling: `auto` (SCHED_FIFO where permitted), `other`, or `both` (one row each).
    #[arg(long, value_enum, default_value_t = SchedArg::Auto)]
    pub sched: SchedArg,
    /// SCHED_FIFO priority.
    #[arg(long, default_value_t = 80)]
    pub fifo_priority: i32,
    /// Print one JSON object on the last line of stdout.
    #[arg(long)]
    pub json: bool,
}

/// Scheduling choice on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SchedArg {
    /// SCHED_FIFO where permitted, else SCHED_OTHER.
    Auto,
    /// SCHED_OTHER only.
    Other,
    /// Both, one row each.
    Both,
}

/// Run `aeris bench ...`.
pub fn run(args: BenchArgs) -> anyhow::Result<()> {
    // the internal children of a benchmark print for their parent, not for a reader
    if !matches!(
        args.command,
        BenchCommand::ModelProbe(_) | BenchCommand::IpcPong(_)
    ) {
        crate::bench::json::start();
    }
    match args.command {
        BenchCommand::Ipc(a) => run_ipc(a),
        BenchCommand::Gate(a) => run_gate(a),
        BenchCommand::Camera(a) => crate::bench::camera::run(a),
        BenchCommand::Control(a) => run_control(a),
        BenchCommand::Models(a) => crate::bench::models::run(a),
        BenchCommand::Cycle(a) => crate::bench::flight::cycle(a),
        BenchCommand::Swap(a) => crate::bench::flight::swap(a),
        BenchCommand::Ds(a) => crate::bench::ds::ds(a),
        BenchCommand::Faults(a) => crate::bench::faults::faults(a),
        BenchCommand::Record(a) => crate::bench::flight::record(a),
        BenchCommand::Hosts(a) => crate::bench::hosts::run(a),
        BenchCommand::Formation(a) => crate::bench::formation::run(a),
        BenchCommand::ModelProbe(a) => crate::bench::models::probe(a),
        BenchCommand::IpcPong(a) => {
            let spec = PongSpec::from_json(&a.spec).context("bench ipc-pong: bad --spec")?;
            ipc::run_pong(&spec).context("bench ipc-pong failed")
        }
    }
}

fn run_ipc(a: IpcArgs) -> anyhow::Result<()> {
    // iceoryx2's start-up notices (e.g. "no config file") would interleave with the table.
    iceoryx2::prelude::set_log_level(iceoryx2::prelude::LogLevel::Error);
    let exe = std::env::current_exe().context("cannot find this executable to start the pong")?;
    let mut cfg = IpcConfig::new(exe, vec!["bench".into(), "ipc-pong".into()]);
    cfg.iterations = a.iterations;
    cfg.warmup = a.warmup;
    cfg.pin = !a.no_pin;
    if !a.payloads.is_empty() {
        cfg.payloads = a.payloads;
    }
    cfg.cases.retain(|(t, w)| {
        let t_ok = a.transport.is_empty()
            || a.transport.iter().any(|x| {
                matches!(
                    (x, t),
                    (TransportArg::Iceoryx2, Transport::Iceoryx2)
                        | (TransportArg::Uds, Transport::Uds)
                )
            });
        let w_ok = a.wake.is_empty()
            || a.wake.iter().any(|x| {
                matches!(
                    (x, w),
                    (WakeArg::Busy, Wake::Busy) | (WakeArg::Event, Wake::Event)
                )
            });
        t_ok && w_ok
    });
    anyhow::ensure!(
        !cfg.cases.is_empty(),
        "no transport/wake-up combination selected"
    );

    println!(
        "IPC round trip, {} iterations after {} warm-up per row",
        cfg.iterations, cfg.warmup
    );
    println!(
        "{:<9} {:<6} {:>14} {:>11} {:>11} {:>11}",
        "transport", "wake", "payload_bytes", "p50_us", "p99_us", "max_us"
    );
    let report = ipc::run(&cfg, |r| {
        println!(
            "{:<9} {:<6} {:>14} {:>11.2} {:>11.2} {:>11.2}",
            r.transport.as_str(),
            r.wake.as_str(),
            r.payload_bytes,
            r.p50_us,
            r.p99_us,
            r.max_us
        );
    })
    .context("bench ipc failed")?;
    print_ipc_footer(&report);
    if a.json {
        crate::bench::json::print(&report)?;
    }
    Ok(())
}

fn print_ipc_footer(report: &IpcReport) {
    match (report.ping_cpu, report.pong_cpu) {
        (Some(a), Some(b)) => println!("ping on CPU {a}, pong on CPU {b}"),
        _ => println!("ping and pong not pinned"),
    }
    for wake in [Wake::Busy, Wake::Event] {
        for iox in report
            .rows
            .iter()
            .filter(|r| r.transport == Transport::Iceoryx2 && r.wake == wake)
        {
            let uds = report.rows.iter().find(|r| {
                r.transport == Transport::Uds
                    && r.wake == wake
                    && r.payload_bytes == iox.payload_bytes
            });
            if let Some(uds) = uds
                && iox.p50_us > 0.0
            {
                println!(
                    "uds/iceoryx2 p50 ({}, {} B): {:.1}x",
                    wake.as_str(),
                    iox.payload_bytes,
                    uds.p50_us / iox.p50_us
                );
            }
        }
    }
}

fn run_gate(a: GateArgs) -> anyhow::Result<()> {
    let report = aeris_bench::gate::run(a.calls).context("bench gate failed")?;
    println!(
        "decision gate: DecisionGate::admit (validate + clamp + bind), {} calls per mix",
        a.calls
    );
    println!(
        "{:<10} {:>9} {:>10} {:>10} {:>10}",
        "mix", "admitted", "median_ns", "median_us", "p99_us"
    );
    for r in &report.rows {
        println!(
            "{:<10} {:>9} {:>10.0} {:>10.3} {:>10.3}",
            r.mix, r.admitted, r.median_ns, r.median_us, r.p99_us
        );
    }
    println!(
        "(each figure includes one clock read pair: {:.0} ns median)",
        report.clock_overhead_ns
    );
    if a.json {
        crate::bench::json::print(&report)?;
    }
    Ok(())
}

fn run_control(a: ControlArgs) -> anyhow::Result<()> {
    let cfg = ControlConfig {
        seconds: a.seconds,
        rate_hz: a.rate_hz,
        fifo_priority: a.fifo_priority,
        sched: match a.sched {
            SchedArg::Auto => SchedChoice::Auto,
            SchedArg::Other => SchedChoice::Other,
            SchedArg::Both => SchedChoice::Both,
        },
        ..ControlConfig::default()
    };
    println!(
        "control loop at {} Hz, {} s per row, wake-up lateness",
        cfg.rate_hz, cfg.seconds
    );
    println!(
        "{:<8} {:<6} {:>7} {:>7} {:>10} {:>10} {:>10}",
        "scenario", "sched", "ticks", "missed", "p50_us", "p99_us", "max_us"
    );
    let report: ControlReport = control::run(&cfg, |r| {
        println!(
            "{:<8} {:<6} {:>7} {:>7} {:>10.2} {:>10.2} {:>10.2}",
            r.scenario.as_str(),
            r.sched.as_str(),
            r.ticks,
            r.missed,
            r.p50_us,
            r.p99_us,
            r.max_us
        );
    })
    .context("bench control failed")?;
    println!(
        "hog: {} busy threads; SCHED_FIFO {}",
        report.hog_threads,
        if report.fifo_granted {
            "granted"
        } else if cfg.sched == SchedChoice::Other {
            "not asked for"
        } else {
            "refused (ran SCHED_OTHER)"
        }
    );
    if a.json {
        crate::bench::json::print(&report)?;
    }
    Ok(())
}

impl crate::command::Execute for BenchArgs {
    fn execute(self) -> anyhow::Result<std::process::ExitCode> {
        run(self)?;
        Ok(std::process::ExitCode::SUCCESS)
    }
}
