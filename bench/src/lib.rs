//! Benchmarks: IPC ping-pong, gate cost, controller jitter, model costs, flights.
//!
//! - [`ipc`]: two-process round trips of 64 B to 6 MB payloads over iceoryx2 zero-copy
//!   publish-subscribe (busy-poll and event wake-up) and over a Unix domain socket that copies.
//! - [`camera`]: glass-to-shared-memory latency and dropped frames of the `gstreamer` camera
//!   role on live `videotestsrc` streams.
//! - [`gate`]: cost per decision of the hub's validate + clamp + bind.
//! - [`control`]: wake-up lateness of a loop on absolute CLOCK_MONOTONIC deadlines at the
//!   control rate, alone and with a CPU hog on every core, under SCHED_FIFO where permitted.
//! - [`models`]: load time, latency and memory of every model a role hosts, each in a
//!   process of its own.
//! - [`flights`]: benchmarks that fly the pipeline end to end as supervised flights
//!   (`aeris-flight`): cycle time and EER, hot swaps, the fault table, dynamic scheduling
//!   under a CPU hog.
//! - [`formation`]: formation programs from the benchmark instructions by every variant:
//!   time to write, valid as written, accepted, repaired or refused.
//! - [`hosts`]: the default flight with roles on a second host (network namespaces): CT
//!   across the link vs local, frames across, moves there and back, a link cut.
//!
//! - [`machine`]: the machine a figure came from (CPU, flags, cores, build profile, steal
//!   time over the run, a calibration figure), carried in every report's JSON.
//!
//! Every benchmark returns a report struct (serde `Serialize`); printing is the caller's job.

#![deny(missing_docs)]

pub mod camera;
pub mod control;
pub mod error;
pub mod flights;
pub mod formation;
pub mod gate;
pub mod hosts;
pub mod ipc;
pub mod machine;
pub mod models;

pub use control::{ControlConfig, ControlReport, ControlRow, Scenario, Sched, SchedChoice};
pub use error::BenchError;
pub use gate::{GateReport, GateRow};
pub use ipc::{IpcConfig, IpcReport, IpcRow, PongSpec, Transport, Wake};
pub use models::{MODEL_CASES, ModelCase, ModelRow, ModelsReport};

/// Nanoseconds to microseconds, rounded to 0.01 µs (keeps reports readable).
pub(crate) fn ns_to_us(ns: f64) -> f64 {
    (ns / 10.0).round() / 100.0
}

/// p50, p99 and max of `samples_ns` in µs (all 0 when empty).
pub(crate) fn summary_us(samples_ns: &[f64]) -> (f64, f64, f64) {
    let p = |q| aeris_runtime::stats::percentile(samples_ns, q).map_or(0.0, ns_to_us);
    (p(50.0), p(99.0), p(100.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn summary_is_nearest_rank_in_us() {
        let ns: Vec<f64> = (1..=100).map(|i| i as f64 * 1000.0).collect();
        assert_eq!(summary_us(&ns), (50.0, 99.0, 100.0));
        assert_eq!(summary_us(&[]), (0.0, 0.0, 0.0));
        assert_eq!(ns_to_us(1234.5), 1.23);
    }
}
