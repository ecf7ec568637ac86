//! Every `aeris bench` JSON report carries the machine that measured it
//! ([`aeris_bench::machine`]): read when the benchmark starts, stamped when it prints.

use aeris_bench::machine::{MachineRun, stamped};
use serde::Serialize;
use std::sync::OnceLock;

static RUN: OnceLock<MachineRun> = OnceLock::new();

/// Read the machine now: call when a benchmark starts (its steal time counts from here).
pub fn start() {
    RUN.get_or_init(MachineRun::start);
}

/// Print `report` as one JSON line with `"machine"` added.
pub fn print<T: Serialize>(report: &T) -> anyhow::Result<()> {
    let run = RUN.get_or_init(MachineRun::start);
    println!("{}", stamped(report, run)?);
    Ok(())
}
