//! Controller period jitter: how late a loop on absolute CLOCK_MONOTONIC deadlines wakes up.
//!
//! The loop runs like [`aeris_runtime::RoleHost`]: `next += period`, sleep until `next`
//! (`clock_nanosleep(TIMER_ABSTIME)`), and re-anchor without bursting when a deadline already
//! passed (counted as missed). Each wake-up records `actual wake - deadline`. It runs on its
//! own thread (so a SCHED_FIFO grant never leaks to the caller), alone and with a CPU hog: one
//! busy-looping SCHED_OTHER thread pinned to every CPU this process may use.

use crate::error::BenchError;
use crate::summary_us;
use aeris_runtime::affinity::CpuSet;
use aeris_runtime::clock::{monotonic_ns, sleep_until_ns};
use aeris_runtime::role::try_sched_fifo;
use serde::{Deserialize, Serialize};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;

/// What else runs while the loop is measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Scenario {
    /// Nothing but the usual background.
    Alone,
    /// A busy-looping thread on every CPU.
    Hog,
}

impl Scenario {
    /// The name used in reports.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Alone => "alone",
            Self::Hog => "hog",
        }
    }
}

/// The scheduling policy the loop actually ran under.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Sched {
    /// SCHED_FIFO (granted).
    Fifo,
    /// SCHED_OTHER (the default, or SCHED_FIFO was refused).
    Other,
}

impl Sched {
    /// The name used in reports.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Fifo => "fifo",
            Self::Other => "other",
        }
    }
}

/// Which policies to measure per scenario.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SchedChoice {
    /// One row: SCHED_FIFO where permitted, else SCHED_OTHER.
    Auto,
    /// One row under SCHED_OTHER.
    Other,
    /// A SCHED_OTHER row, then a SCHED_FIFO row where permitted.
    Both,
}

/// What to measure.
#[derive(Debug, Clone, PartialEq)]
pub struct ControlConfig {
    /// Seconds per row.
    pub seconds: f64,
    /// Loop rate (the controller runs at 50 Hz).
    pub rate_hz: f64,
    /// SCHED_FIFO priority asked for (1..=99).
    pub fifo_priority: i32,
    /// Which policies to measure.
    pub sched: SchedChoice,
    /// Scenarios, in order.
    pub scenarios: Vec<Scenario>,
}

impl Default for ControlConfig {
    /// 5 s per row at 50 Hz, FIFO priority 80 where permitted, alone then with the hog.
    fn default() -> Self {
        Self {
            seconds: 5.0,
            rate_hz: 50.0,
            fifo_priority: 80,
            sched: SchedChoice::Auto,
            scenarios: vec![Scenario::Alone, Scenario::Hog],
        }
    }
}

/// One measured row.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ControlRow {
    /// `alone` or `hog`.
    pub scenario: Scenario,
    /// The policy the loop ran under: `fifo` or `other`.
    pub sched: Sched,
    /// Wake-ups measured.
    pub ticks: u64,
    /// Deadlines that had already passed when the loop woke (skipped, not burst).
    pub missed: u64,
    /// Median wake-up lateness, µs.
    pub p50_us: f64,
    /// 99th percentile wake-up lateness, µs.
    pub p99_us: f64,
    /// Worst wake-up lateness, µs.
    pub max_us: f64,
}

/// The result of [`run`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ControlReport {
    /// One row per scenario and policy.
    pub rows: Vec<ControlRow>,
    /// Loop rate.
    pub rate_hz: f64,
    /// Seconds per row.
    pub seconds: f64,
    /// Hog threads in the `hog` scenario (one per usable CPU).
    pub hog_threads: usize,
    /// Whether SCHED_FIFO was granted when asked for (`false` when never asked).
    pub fifo_granted: bool,
}

/// What one measuring thread saw.
struct LoopResult {
    granted: bool,
    lateness_ns: Vec<f64>,
    ticks: u64,
    missed: u64,
}

/// The deadline loop itself (on the calling thread).
fn deadline_loop(period_ns: u64, total_ns: u64) -> LoopResult {
    let expected = (total_ns / period_ns.max(1)) as usize + 2;
    let mut lateness_ns = Vec::with_capacity(expected);
    let (mut ticks, mut missed) = (0u64, 0u64);
    let start = monotonic_ns();
    let end = start.saturating_add(total_ns);
    let mut next = start + period_ns;
    while next <= end {
        sleep_until_ns(next);
        let now = monotonic_ns();
        if now < next {
            continue; // a signal cut the sleep short: sleep again
        }
        lateness_ns.push((now - next) as f64);
        ticks += 1;
        next += period_ns;
        if now > next {
            // As RoleHost: count the passed deadlines and re-anchor instead of bursting.
            let behind = now - next;
            missed += behind / period_ns + 1;
            next = now + period_ns - behind % period_ns;
        }
    }
    LoopResult {
        granted: false,
        lateness_ns,
        ticks,
        missed,
    }
}

/// Run the loop on a fresh thread, under SCHED_FIFO at `fifo` priority when given and permitted.
fn measure(period_ns: u64, total_ns: u64, fifo: Option<i32>) -> Result<LoopResult, BenchError> {
    let handle = std::thread::Builder::new()
        .name("aeris-bench-ctl".into())
        .spawn(move || {
            let granted = fifo.is_some_and(try_sched_fifo);
            LoopResult {
                granted,
                ..deadline_loop(period_ns, total_ns)
            }
        })
        .map_err(|e| BenchError::Thread(format!("cannot start the control loop: {e}")))?;
    handle
        .join()
        .map_err(|_| BenchError::Thread("the control loop panicked".into()))
}

/// Busy-looping threads, one pinned to each CPU; stopped and joined on drop.
struct Hog {
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<u64>>,
}

impl Hog {
    fn start(cpus: &[usize]) -> Result<Self, BenchError> {
        let mut hog = Self {
            stop: Arc::new(AtomicBool::new(false)),
            threads: Vec::with_capacity(cpus.len()),
        };
        for &cpu in cpus {
            let stop = Arc::clone(&hog.stop);
            let set = CpuSet::parse(&cpu.to_string()).ok();
            let t = std::thread::Builder::new()
                .name(format!("aeris-hog-{cpu}"))
                .spawn(move || {
                    if let Some(set) = set {
                        let _ = set.bind_task(0);
                    }
                    let mut x = 0x9E37_79B9_7F4A_7C15u64;
                    while !stop.load(Ordering::Relaxed) {
                        for _ in 0..1024 {
                            x = core::hint::black_box(
                                x.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1),
                            );
                        }
                    }
                    x
                })
                .map_err(|e| BenchError::Thread(format!("cannot start a hog thread: {e}")))?;
            hog.threads.push(t);
        }
        Ok(hog)
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

/// Measure every scenario of `cfg`; `progress` sees each row as soon as it is measured.
pub fn run(
    cfg: &ControlConfig,
    mut progress: impl FnMut(&ControlRow),
) -> Result<ControlReport, BenchError> {
    if !(cfg.rate_hz.is_finite() && cfg.rate_hz > 0.0 && cfg.rate_hz <= 100_000.0) {
        return Err(BenchError::Config(format!(
            "rate {} Hz is not in (0, 100000]",
            cfg.rate_hz
        )));
    }
    if !(cfg.seconds.is_finite() && cfg.seconds > 0.0 && cfg.seconds <= 86_400.0) {
        return Err(BenchError::Config(format!(
            "{} s is not a usable duration",
            cfg.seconds
        )));
    }
    if !(1..=99).contains(&cfg.fifo_priority) {
        return Err(BenchError::Config(format!(
            "SCHED_FIFO priority {} is not in 1..=99",
            cfg.fifo_priority
        )));
    }
    let period_ns = ((1e9 / cfg.rate_hz).round() as u64).max(1);
    let total_ns = (cfg.seconds * 1e9).round() as u64;
    let cpus = CpuSet::of_task(0)
        .map(|s| s.cpus().to_vec())
        .unwrap_or_else(|_| CpuSet::available().cpus().to_vec());
    let fifo = Some(cfg.fifo_priority);
    let policies: &[Option<i32>] = match cfg.sched {
        SchedChoice::Auto => &[fifo],
        SchedChoice::Other => &[None],
        SchedChoice::Both => &[None, fifo],
    };

    let mut rows = Vec::new();
    let mut fifo_granted = false;
    for &scenario in &cfg.scenarios {
        let hog = match scenario {
            Scenario::Alone => None,
            Scenario::Hog => {
                let hog = Hog::start(&cpus)?;
                // let the hog reach every CPU before measuring
                std::thread::sleep(core::time::Duration::from_millis(200));
                Some(hog)
            }
        };
        for &policy in policies {
            let r = measure(period_ns, total_ns, policy)?;
            fifo_granted |= r.granted;
            if policy.is_some() && !r.granted && cfg.sched == SchedChoice::Both {
                continue; // the SCHED_OTHER row of this scenario is already there
            }
            let (p50_us, p99_us, max_us) = summary_us(&r.lateness_ns);
            let row = ControlRow {
                scenario,
                sched: if r.granted { Sched::Fifo } else { Sched::Other },
                ticks: r.ticks,
                missed: r.missed,
                p50_us,
                p99_us,
                max_us,
            };
            progress(&row);
            rows.push(row);
        }
        drop(hog);
    }
    Ok(ControlReport {
        rows,
        rate_hz: cfg.rate_hz,
        seconds: cfg.seconds,
        hog_threads: cpus.len(),
        fifo_granted,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn short_run_counts_ticks_and_reports_rows() {
        let cfg = ControlConfig {
            seconds: 0.1,
            rate_hz: 200.0,
            sched: SchedChoice::Other,
            ..ControlConfig::default()
        };
        let mut seen = 0;
        let report = run(&cfg, |_| seen += 1).unwrap();
        assert_eq!(report.rows.len(), 2);
        assert_eq!(seen, 2);
        assert_eq!(report.rows[0].scenario, Scenario::Alone);
        assert_eq!(report.rows[1].scenario, Scenario::Hog);
        for row in &report.rows {
            assert_eq!(row.sched, Sched::Other);
            assert!(row.ticks + row.missed >= 15, "{row:?}");
            assert!(row.p50_us <= row.p99_us && row.p99_us <= row.max_us);
        }
        let json = serde_json::to_value(&report).unwrap();
        assert_eq!(json["rows"][1]["scenario"], "hog");
        assert_eq!(json["rows"][0]["sched"], "other");
    }

    #[test]
    fn rejects_bad_settings() {
        for cfg in [
            ControlConfig {
                rate_hz: 0.0,
                ..ControlConfig::default()
            },
            ControlConfig {
                seconds: f64::NAN,
                ..ControlConfig::default()
            },
            ControlConfig {
                fifo_priority: 0,
                ..ControlConfig::default()
            },
        ] {
            assert!(matches!(run(&cfg, |_| {}), Err(BenchError::Config(_))));
        }
    }
}
