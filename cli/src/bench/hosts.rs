//! `aeris bench hosts`: roles on a second host, measured ([`aeris_bench::hosts`]).

use anyhow::{Context, Result, bail};
use clap::Args;

/// Arguments of `aeris bench hosts`.
#[derive(Debug, Args)]
pub struct HostsArgs {
    /// Link delays (ms, each way, tc netem) of the flights across the link; 0 is the bare
    /// link. A delay this kernel cannot emulate (no sch_netem) is reported as skipped.
    #[arg(long, value_delimiter = ',', default_value = "0,20,100")]
    pub delays: Vec<u32>,
    /// Packet loss (%, each way) of one more flight across the link (0: none).
    #[arg(long, default_value_t = 1.0)]
    pub loss: f64,
    /// Busy processes started outside the flight (unpinned, normal priority) for the run.
    #[arg(long, value_name = "N", default_value_t = 0)]
    pub outside_load: usize,
    /// Instead: what mutual TLS costs beside plain TCP (the same flights on each link: the
    /// link's round trip, the decision's and the frame's paths, the bridges' CPU, the time
    /// from a restored link to the link and the reasoner back).
    #[arg(long)]
    pub tls: bool,
    /// Print one JSON object on the last line of stdout.
    #[arg(long)]
    pub json: bool,
}

/// `aeris bench hosts`.
pub fn run(a: HostsArgs) -> Result<()> {
    if !(0.0..=100.0).contains(&a.loss) {
        bail!("--loss must be a percentage from 0 to 100, got {}", a.loss);
    }
    let work = tempfile_dir()?;
    if a.tls {
        let config = aeris_bench::hosts::HostsBenchConfig {
            aeris: std::env::current_exe().context("cannot find the aeris executable")?,
            delays_ms: Vec::new(),
            loss_percent: 0.0,
            outside_load: a.outside_load,
            work_dir: work.clone(),
        };
        let report = aeris_bench::hosts::compare_links(&config, &mut |line| {
            eprintln!("bench hosts --tls: {line}")
        });
        let _ = std::fs::remove_dir_all(&work);
        return print_links(&report.context("bench hosts --tls failed")?, a.json);
    }
    let config = aeris_bench::hosts::HostsBenchConfig {
        aeris: std::env::current_exe().context("cannot find the aeris executable")?,
        delays_ms: a.delays.clone(),
        loss_percent: a.loss,
        outside_load: a.outside_load,
        work_dir: work.clone(),
    };
    let report = aeris_bench::hosts::run(&config, &mut |line| eprintln!("bench hosts: {line}"));
    let _ = std::fs::remove_dir_all(&work);
    let report = report.context("bench hosts failed")?;
    println!(
        "roles on a second host (network namespaces on this machine), {} busy processes outside the flight",
        report.outside_load
    );
    println!(
        "  {:<26} {:>6} {:>6} {:>5} {:>8} {:>8} {:>6} {:>7} {:>7} {:>10} {:>9} {:>8} {:>9} {:>8}",
        "roles there",
        "delay",
        "loss",
        "goal",
        "CT mean",
        "CT p95",
        "EER",
        "missed",
        "frames",
        "bytes/fr",
        "frames/s",
        "RTT ms",
        "link loss",
        "enc ms"
    );
    for r in &report.rows {
        let there = if r.roles_there.is_empty() {
            "none (all on board)".to_string()
        } else {
            r.roles_there.join(",")
        };
        if let Some(why) = &r.skipped {
            println!(
                "  {there:<26} {:>4}ms {:>5}% skipped: {why}",
                r.delay_ms, r.loss_percent
            );
            continue;
        }
        let f = |v: Option<f64>, p: usize, unit: &str| {
            v.map_or_else(|| "-".to_string(), |x| format!("{x:.p$}{unit}"))
        };
        let n = |v: Option<u64>| v.map_or_else(|| "-".to_string(), |x| x.to_string());
        println!(
            "  {there:<26} {:>4}ms {:>5}% {:>5} {:>8} {:>8} {:>6} {:>7} {:>7} {:>10} {:>9} {:>8} {:>9} {:>8}",
            r.delay_ms,
            r.loss_percent,
            r.reached_goal.map_or("-", |g| if g { "yes" } else { "no" }),
            f(r.ct_mean_s, 3, "s"),
            f(r.ct_p95_s, 3, "s"),
            f(r.eer.map(|e| e * 100.0), 1, "%"),
            n(r.controller_missed_ticks),
            n(r.frames_across),
            f(r.bytes_per_frame, 0, ""),
            f(r.frames_per_s, 1, ""),
            f(r.link_rtt_ms, 3, ""),
            f(r.link_loss.map(|l| l * 100.0), 0, "%"),
            f(r.frame_coding_ms, 2, ""),
        );
    }
    let m = &report.moves;
    println!(
        "  reasoner moved to the ground host: ready {} ms, done {} ms; back: ready {} ms, done {} ms; decisions reused over the flight {}, missed ticks {}, goal {}",
        m.there_ready_ms,
        m.there_done_ms,
        m.back_ready_ms,
        m.back_done_ms,
        m.decisions_reused,
        m.controller_missed_ticks,
        m.reached_goal
    );
    let c = &report.cut;
    println!(
        "  link cut: loss noticed after {} ms, on-board fallback ready after {} ms; restored: reasoner back on the ground host after {} ms (5 s hysteresis included); decisions reused {}, missed ticks {}, goal {}",
        c.loss_noticed_ms,
        c.fallback_ready_ms,
        c.returned_ms,
        c.decisions_reused,
        c.controller_missed_ticks,
        c.reached_goal
    );
    let p = &report.placement;
    match &p.skipped {
        Some(why) => println!("  placement: skipped: {why}"),
        None => {
            let ms = |v: Option<u64>| v.map_or_else(|| "-".to_string(), |x| format!("{x} ms"));
            let moved = if p.moved_before_hog {
                "moved to the ground before the hog landed".to_string()
            } else {
                format!(
                    "a hog of {} threads on the vehicle's CPUs: moved to the ground after {}, ready {}, done {}",
                    p.hog_threads,
                    ms(p.moved_after_ms),
                    ms(p.ready_after_ms),
                    ms(p.done_after_ms)
                )
            };
            println!(
                "  placement (vehicle CPUs {}, ground CPUs {}): detector {} of its {:.0} ms budget on board; {moved}; missed ticks {}, goal {}",
                p.vehicle_cpus,
                p.ground_cpus,
                p.latency_before_ms
                    .map_or_else(|| "?".to_string(), |l| format!("{l:.1} ms")),
                p.budget_ms,
                p.controller_missed_ticks
                    .map_or_else(|| "-".to_string(), |x| x.to_string()),
                p.reached_goal.map_or("-", |g| if g { "yes" } else { "no" })
            );
            match &p.why {
                Some(why) => println!("    {why}"),
                // no move: what the flight said of the detector
                None => {
                    for line in &p.detector_lines {
                        println!("    {line}");
                    }
                }
            }
        }
    }
    if a.json {
        crate::bench::json::print(&report)?;
    }
    Ok(())
}

/// The TLS-beside-TCP table.
fn print_links(report: &aeris_bench::hosts::SecurityReport, json: bool) -> Result<()> {
    println!(
        "the link to a second host (network namespaces on this machine), reasoner and perception there, {} busy processes outside the flight",
        report.outside_load
    );
    println!(
        "  {:<5} {:>5} {:>8} {:>8} {:>8} {:>11} {:>12} {:>8} {:>9} {:>10} {:>10} {:>11} {:>13}",
        "link",
        "goal",
        "RTT ms",
        "CT mean",
        "CT p95",
        "D_t path ms",
        "frame->S_t ms",
        "enc ms",
        "bytes/fr",
        "bridge CPU",
        "ground CPU",
        "link back ms",
        "reasoner back"
    );
    let f = |v: Option<f64>, p: usize| v.map_or_else(|| "-".to_string(), |x| format!("{x:.p$}"));
    for r in &report.rows {
        println!(
            "  {:<5} {:>5} {:>8} {:>8} {:>8} {:>11} {:>12} {:>8} {:>9} {:>9}% {:>9}% {:>11} {:>10} ms",
            match r.link {
                aeris_bench::hosts::LinkKind::Tls => "tls",
                aeris_bench::hosts::LinkKind::Tcp => "tcp",
            },
            if r.reached_goal { "yes" } else { "no" },
            f(r.rtt_ms, 3),
            f(r.ct_mean_s, 3),
            f(r.ct_p95_s, 3),
            f(r.decision_path_ms, 2),
            f(r.frame_to_state_ms, 1),
            f(r.frame_coding_ms, 2),
            f(r.bytes_per_frame, 0),
            f(r.bridge_cpu_vehicle_pct, 1),
            f(r.bridge_cpu_ground_pct, 1),
            r.restored_to_link_ms,
            r.restored_to_reasoner_ms,
        );
    }
    println!(
        "  the link alone (loopback, through a router; round trip, each way client → router → client):"
    );
    for r in &report.rows {
        for p in &r.ping {
            println!(
                "  {:<5} {:>6} B: p50 {:>7.1} us  p95 {:>7.1} us  mean {:>7.1} us  ({} round trips)",
                match r.link {
                    aeris_bench::hosts::LinkKind::Tls => "tls",
                    aeris_bench::hosts::LinkKind::Tcp => "tcp",
                },
                p.bytes,
                p.p50_us,
                p.p95_us,
                p.mean_us,
                p.round_trips
            );
        }
    }
    if json {
        crate::bench::json::print(report)?;
    }
    Ok(())
}

/// A fresh directory for the flights' run directories.
fn tempfile_dir() -> Result<std::path::PathBuf> {
    let dir = std::env::temp_dir().join(format!("aeris-bench-hosts-{}", std::process::id()));
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    Ok(dir)
}
