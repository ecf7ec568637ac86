//! The new side of a make-before-break swap ([`SwapInProgress`]) and where it runs when
//! not where the role runs now ([`Placement`], [`ReturnTo`]): what a role's runtime holds
//! while the swap step brings a replacement up.

use super::warm_up_gate::WarmUpGate;
use crate::launch::PlannedFallback;
use aeris_runtime::affinity::CpuSet;
use aeris_runtime::spec::RemoteSpec;
use aeris_schemas::RoleHeartbeat;
use std::path::PathBuf;
use std::process::Child;
use std::time::{Duration, Instant};

/// Where a role ran before its link was lost: it returns there when the link is back.
#[derive(Debug, Clone)]
pub(super) struct ReturnTo {
    /// The executor on the other host.
    pub(super) executor: String,
    /// That host, its agent and the CPUs there.
    pub(super) spec: aeris_runtime::spec::RemoteSpec,
    /// The variant it ran there.
    pub(super) variant: String,
}

/// The new side of a make-before-break swap, until its first heartbeat after warm-up.
#[derive(Debug)]
pub(super) struct SwapInProgress {
    /// The variant being brought up.
    pub(super) variant: String,
    /// Its spec (`NAME.iN.json`).
    pub(super) spec_path: PathBuf,
    /// Its log (`NAME.iN.log`).
    pub(super) log_path: PathBuf,
    /// The new process.
    pub(super) child: Child,
    /// Its pid.
    pub(super) pid: u32,
    /// Its instance number.
    pub(super) instance: u32,
    /// When the swap started.
    pub(super) started: Instant,
    /// When it is rolled back if the new process is not ready.
    pub(super) deadline: Instant,
    /// Its first working heartbeat, and when it came: it is ready.
    pub(super) ready: Option<(RoleHeartbeat, Instant)>,
    /// The replaced process completed a cycle since then (a worked heartbeat): the swap
    /// commits now, at the start of the role's next cycle ([`handover_wait`]).
    pub(super) handover: bool,
    /// How long it waits for that, at most, once ready.
    pub(super) handover_wait: Duration,
    /// Set when it runs elsewhere than the role ran (a move between hosts, a fallback).
    pub(super) placement: Option<Placement>,
    /// Set to end the swap at the next step, and why (its host's link was lost).
    pub(super) abort: Option<String>,
    /// A reasoner's new side loading idle: it runs only between the running process's
    /// decisions until it is ready.
    pub(super) gate: Option<WarmUpGate>,
}

/// Where a replacement runs when not where the role runs now: on another host (a move
/// there, `aeris migrate ROLE HOST:EXECUTOR`), or back on the flight's host (a move back, or
/// the fallback of a role whose host's link was lost).
#[derive(Debug, Clone)]
pub(super) struct Placement {
    /// Its CPUs on the flight's host (`None`: the supervisor's; always for another host,
    /// where its handle runs unbound).
    pub(super) cpus: Option<CpuSet>,
    /// Its executor's name (empty: unbound).
    pub(super) executor: String,
    /// The accelerator its model sessions run on there (its executor's), if any.
    pub(super) accelerator: Option<aeris_runtime::accelerator::Accelerator>,
    /// On another host: that host, its agent and the CPUs there (`None`: the flight's host).
    pub(super) remote: Option<RemoteSpec>,
    /// What takes over on the flight's host if the link to `remote` is lost.
    pub(super) link_fallback: Option<PlannedFallback>,
    /// Where it runs, for messages ("host `ground` (executor gs)").
    pub(super) place: String,
    /// Why it runs there (the role's new binding).
    pub(super) why: String,
    /// The role's restart policy, back in force once it runs there (a role whose link is
    /// lost is not restarted behind the link meanwhile); `None`: unchanged.
    pub(super) policy: Option<crate::restart::RestartPolicy>,
    /// A return to a host whose link came back: if it fails, the role waits to return
    /// again (after another hysteresis).
    pub(super) returning: Option<ReturnTo>,
}
