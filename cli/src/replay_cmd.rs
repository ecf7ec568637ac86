//! `aeris replay`: a recorded flight replayed with live roles, decision by decision against
//! the recording, or variants compared on it (`--compare`). The replay itself lives in
//! `aeris_flight::replay`; this parses and prints.

use crate::flight_print::FlightPrinter;
use crate::run_cmd::variant_choices;
use aeris_flight::replay::{CompareRow, ReplayCycle, ReplayReport, ReplayRequest, compare, replay};
use anyhow::{Context, Result, bail};
use clap::Args;
use std::path::PathBuf;

/// Arguments of `aeris replay`.
#[derive(Debug, Args)]
pub struct ReplayArgs {
    /// The recording (`aeris run --record FILE`).
    pub file: PathBuf,
    /// Start at the first recorded cycle at or after this many seconds into the recording
    /// (the roles start fresh there: a planner at step 1).
    #[arg(long, value_name = "S")]
    pub from: Option<f64>,
    /// End this many seconds into the recording.
    #[arg(long, value_name = "S")]
    pub to: Option<f64>,
    /// Time scale: 2 replays twice as fast; the heartbeat and the deadline scale with it.
    /// `max`: on simulated time (`aeris run --clock sim`), the roles taking their turns at
    /// the recorded instants, as fast as they compute.
    #[arg(long, value_name = "X|max", default_value = "1")]
    pub speed: ReplaySpeed,
    /// Run a role with another variant than the recorded one, e.g. --variant
    /// reasoning=garbage (repeatable).
    #[arg(long, value_name = "ROLE=VARIANT")]
    pub variant: Vec<String>,
    /// Replay once per variant of ROLE and print one table: agreement with the recording
    /// and with each other, CT mean/p95, EER, tokens/s. E.g. reasoning=planner,smollm2.
    #[arg(long, value_name = "ROLE=V1,V2,..")]
    pub compare: Option<String>,
    /// Flight name of the replay (default: replay-PID; with --compare, FLIGHT-K for the K-th
    /// variant).
    #[arg(long)]
    pub flight: Option<String>,
    /// Run directory of the replay (default: $TMPDIR/aeris/FLIGHT; with --compare,
    /// DIR/VARIANT per variant); it keeps the replay's own recording, replay.mcap.
    #[arg(long, value_name = "DIR")]
    pub run_dir: Option<PathBuf>,
    /// Print the summary as one JSON object on the last line of stdout.
    #[arg(long)]
    pub json: bool,
}

/// `aeris replay --speed`: a time scale, or as fast as the roles compute.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ReplaySpeed {
    /// The recorded time scaled (2: twice as fast), on the wall clock.
    Scale(f64),
    /// Simulated time: as fast as the roles compute.
    Max,
}

impl std::str::FromStr for ReplaySpeed {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        if s == "max" {
            return Ok(ReplaySpeed::Max);
        }
        s.parse::<f64>()
            .map(ReplaySpeed::Scale)
            .map_err(|_| format!("`{s}` is neither a number nor `max`"))
    }
}

/// `aeris replay`.
pub fn run(args: ReplayArgs) -> Result<()> {
    let request = ReplayRequest {
        path: args.file.clone(),
        from_s: args.from,
        to_s: args.to,
        speed: match args.speed {
            ReplaySpeed::Scale(x) => x,
            ReplaySpeed::Max => 1.0,
        },
        clock: match args.speed {
            ReplaySpeed::Scale(_) => aeris_flight::FlightClock::Wall,
            ReplaySpeed::Max => aeris_flight::FlightClock::Sim,
        },
        variants: variant_choices(&args.variant)?,
        name: args.flight.clone(),
        run_dir: args.run_dir.clone(),
        role_executable: None,
        offload_check: Some(aeris_llm::offload_check),
    };
    let mut printer = FlightPrinter::new(true, "")?;
    if let Some(spec) = &args.compare {
        let choice: aeris_flight::VariantChoice =
            spec.parse().with_context(|| format!("--compare {spec}"))?;
        let role = choice.role.as_str();
        let variants: Vec<String> = choice
            .variant
            .split(',')
            .filter(|v| !v.is_empty())
            .map(str::to_string)
            .collect();
        if variants.is_empty() {
            bail!("--compare {spec}: no variant named");
        }
        let rows = compare(&request, role, &variants, &mut printer)
            .with_context(|| format!("replaying {}", args.file.display()))?;
        print_comparison(&rows);
        if args.json {
            println!("{}", serde_json::to_string(&rows)?);
        }
        return Ok(());
    }
    let report = replay(&request, &mut printer)
        .with_context(|| format!("replaying {}", args.file.display()))?;
    print_report(&report);
    if args.json {
        println!("{}", serde_json::to_string(&report.summary)?);
    }
    Ok(())
}

fn side(d: &Option<aeris_flight::replay::DecisionView>) -> String {
    match d {
        Some(d) => format!(
            "{:<8} s{} [{:6.1},{:6.1},{:5.1}] {:5.2} s",
            d.action, d.step, d.target[0], d.target[1], d.target[2], d.latency_s
        ),
        None => format!("{:<38}", "-"),
    }
}

fn print_cycle(c: &ReplayCycle) {
    let verdict = match (&c.recorded, &c.replayed) {
        _ if c.identical => "identical".to_string(),
        (Some(_), Some(_)) => format!("differs ({:.2} m)", c.target_delta_m.unwrap_or(0.0)),
        (Some(_), None) => "not replayed".into(),
        (None, _) => "replay only".into(),
    };
    println!(
        "{:7.2}  {} | {}  {verdict}",
        c.t_s,
        side(&c.recorded),
        side(&c.replayed)
    );
}

/// The replay's speed as the user gave it.
fn speed_text(s: &aeris_flight::replay::ReplaySummary) -> String {
    match s.clock {
        aeris_flight::FlightClock::Sim => "max (simulated time)".into(),
        aeris_flight::FlightClock::Wall => s.speed.to_string(),
    }
}

fn print_report(report: &ReplayReport) {
    let s = &report.summary;
    println!(
        "replay of {} ({:.1}-{:.1} s, speed {}): {}",
        s.recording.display(),
        s.from_s,
        s.to_s,
        speed_text(s),
        s.variants.join(" ")
    );
    println!(
        "  t (s)  {:<38} | {:<38}  same",
        "recorded: action step target CT", "replayed"
    );
    for c in &report.cycles {
        print_cycle(c);
    }
    println!(
        "  cycles: recorded {}, replayed {}, on the same frame {}, identical {} \
         (agreement {:.1}%, same action and step {:.1}%)",
        s.recorded_cycles,
        s.replayed_cycles,
        s.paired,
        s.identical,
        s.agreement * 100.0,
        s.action_agreement * 100.0
    );
    println!(
        "  CT mean {:.3} s (p95 {:.3}) recorded vs {:.3} s (p95 {:.3}) replayed; EER {:.1}% vs {:.1}%",
        s.recorded.ct_mean_s,
        s.recorded.ct_p95_s,
        s.replayed.ct_mean_s,
        s.replayed.ct_p95_s,
        s.recorded.eer * 100.0,
        s.replayed.eer * 100.0
    );
    println!(
        "  replayed messages at most {:.1} ms late; the replay's own recording: {}",
        s.late_max_ms,
        s.replay_recording.display()
    );
}

fn print_comparison(rows: &[CompareRow]) {
    let Some(first) = rows.first() else {
        return;
    };
    println!(
        "variants on {} ({:.1}-{:.1} s, speed {}; {} recorded cycles)",
        first.summary.recording.display(),
        first.summary.from_s,
        first.summary.to_s,
        speed_text(&first.summary),
        first.summary.recorded_cycles
    );
    let names: Vec<&str> = rows.iter().map(|r| r.variant.as_str()).collect();
    print!(
        "{:<22} {:>9} {:>8} {:>9} {:>7} {:>8}",
        "variant", "agree rec", "CT mean", "CT p95", "EER", "tok/s"
    );
    for n in &names {
        print!(" {:>10}", n.split('=').nth(1).unwrap_or(n));
    }
    println!();
    for r in rows {
        let s = &r.summary;
        print!(
            "{:<22} {:>8.1}% {:>7.3}s {:>8.3}s {:>6.1}% {:>8}",
            r.variant,
            s.agreement * 100.0,
            s.replayed.ct_mean_s,
            s.replayed.ct_p95_s,
            s.replayed.eer * 100.0,
            s.tokens_per_s
                .map_or_else(|| "-".to_string(), |t| format!("{t:.1}"))
        );
        for a in &r.agreement_with {
            print!(" {:>9.1}%", a * 100.0);
        }
        println!();
    }
    println!(
        "recording: CT mean {:.3} s (p95 {:.3}), EER {:.1}%",
        first.summary.recorded.ct_mean_s,
        first.summary.recorded.ct_p95_s,
        first.summary.recorded.eer * 100.0
    );
}

impl crate::command::Execute for ReplayArgs {
    fn execute(self) -> anyhow::Result<std::process::ExitCode> {
        run(self)?;
        Ok(std::process::ExitCode::SUCCESS)
    }
}
