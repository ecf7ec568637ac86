//! Two-process IPC ping-pong: iceoryx2 zero-copy publish-subscribe against a Unix domain socket.
//!
//! The ping (this process) spawns a pong process per row (`pong_exe pong_args... --spec JSON`,
//! which must call [`run_pong`]), waits for its `ready` line, then runs warm-up and measured
//! round trips. Each ping stamps a sequence number and its CLOCK_MONOTONIC send time into the
//! first 16 bytes and a check byte into the last byte of the payload; the pong checks the
//! bytes and sends a payload of the same size back with the same stamp; the ping checks the
//! echo and records `now - stamp` as the round-trip time.
//!
//! - **iceoryx2**: the ping loans a slice from shared memory, writes only the stamp (no other
//!   byte is written or copied, which is the point of zero copy), sends; the pong receives the
//!   sample in place, loans a reply of the same length, stamps and sends it. Wake-up either by
//!   spinning on `receive` (`busy`) or by an iceoryx2 event service per direction: notify after
//!   send, wait on the listener before receiving (`event`).
//! - **uds**: a `SOCK_STREAM` Unix socket; the ping writes the whole payload, the pong reads it
//!   fully and writes it fully back. `event` = blocking reads and writes (the kernel wakes the
//!   reader); `busy` = non-blocking socket polled in a spin loop.
//!
//! With two or more CPUs, the ping's thread and the pong are pinned to different CPUs. The pong
//! dies with its parent (`PR_SET_PDEATHSIG`) and exits on a stop message or end of stream.

use crate::error::BenchError;
use crate::summary_us;
use aeris_runtime::FlightBus;
use aeris_runtime::affinity::CpuSet;
use aeris_runtime::bus::Ipc;
use aeris_runtime::clock::monotonic_ns;
use core::mem::MaybeUninit;
use core::time::Duration;
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::{AllocationStrategy, ServiceName};
use iceoryx2::sample::Sample;
use serde::{Deserialize, Serialize};
use std::io::{Read, Write};
use std::os::fd::AsRawFd;
use std::os::linux::net::SocketAddrExt;
use std::os::unix::net::{SocketAddr, UnixListener, UnixStream};
use std::path::PathBuf;
use std::process::{Child, ChildStdout, Command, Stdio};

/// The default payloads: a small message, a VGA RGB frame, a 1080p RGB frame.
pub const DEFAULT_PAYLOADS: [usize; 3] = [64, 640 * 480 * 3, 1920 * 1080 * 3];

/// Bytes a payload needs at least: sequence number, timestamp, check byte.
pub const MIN_PAYLOAD: usize = 17;

/// The sequence number that tells the pong to exit.
const STOP_SEQ: u64 = u64::MAX;

/// How long the ping waits for one echo before giving up.
const REPLY_TIMEOUT_NS: u64 = 5_000_000_000;

/// How long the ping waits for the pong's `ready` line.
const READY_TIMEOUT_MS: u64 = 15_000;

/// How long the pong waits between checks that its parent is still there.
const PONG_IDLE_NS: u64 = 1_000_000_000;

/// The line the pong prints on stdout once its ports exist.
const READY_LINE: &str = "ready";

/// How the bytes cross the process boundary.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Transport {
    /// iceoryx2 zero-copy publish-subscribe of `[u8]` slices.
    Iceoryx2,
    /// A Unix domain stream socket (the bytes are copied through the kernel).
    Uds,
}

impl Transport {
    /// The name used in reports.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Iceoryx2 => "iceoryx2",
            Self::Uds => "uds",
        }
    }
}

/// How the receiver learns that something arrived.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Wake {
    /// Spin on a non-blocking receive.
    Busy,
    /// Sleep until woken (iceoryx2 event service; blocking socket read).
    Event,
}

impl Wake {
    /// The name used in reports.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Busy => "busy",
            Self::Event => "event",
        }
    }
}

/// What to measure and how to start the pong.
#[derive(Debug, Clone)]
pub struct IpcConfig {
    /// Measured round trips per row.
    pub iterations: usize,
    /// Round trips before measuring (not reported).
    pub warmup: usize,
    /// Payload sizes in bytes (each at least [`MIN_PAYLOAD`]).
    pub payloads: Vec<usize>,
    /// (transport, wake-up) pairs; one row per pair and payload.
    pub cases: Vec<(Transport, Wake)>,
    /// The executable that runs the pong (usually `std::env::current_exe()`).
    pub pong_exe: PathBuf,
    /// Arguments before `--spec JSON` (e.g. `["bench", "ipc-pong"]`).
    pub pong_args: Vec<String>,
    /// Pin ping and pong to different CPUs when two or more are available.
    pub pin: bool,
}

impl IpcConfig {
    /// Every transport and wake-up mode.
    pub const ALL_CASES: [(Transport, Wake); 4] = [
        (Transport::Iceoryx2, Wake::Busy),
        (Transport::Iceoryx2, Wake::Event),
        (Transport::Uds, Wake::Busy),
        (Transport::Uds, Wake::Event),
    ];

    /// The defaults (2000 iterations after 200 warm-up round trips, [`DEFAULT_PAYLOADS`],
    /// [`IpcConfig::ALL_CASES`], pinned) with the pong started as `pong_exe pong_args...`.
    pub fn new(pong_exe: PathBuf, pong_args: Vec<String>) -> Self {
        Self {
            iterations: 2000,
            warmup: 200,
            payloads: DEFAULT_PAYLOADS.to_vec(),
            cases: Self::ALL_CASES.to_vec(),
            pong_exe,
            pong_args,
            pin: true,
        }
    }
}

/// One measured row: round-trip times of one transport, wake-up mode and payload size.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct IpcRow {
    /// `iceoryx2` or `uds`.
    pub transport: Transport,
    /// `busy` or `event`.
    pub wake: Wake,
    /// Bytes each way.
    pub payload_bytes: usize,
    /// Median round trip, µs.
    pub p50_us: f64,
    /// 99th percentile round trip, µs.
    pub p99_us: f64,
    /// Slowest round trip, µs.
    pub max_us: f64,
}

/// The result of [`run`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct IpcReport {
    /// One row per case and payload.
    pub rows: Vec<IpcRow>,
    /// Measured round trips per row.
    pub iterations: usize,
    /// Warm-up round trips per row.
    pub warmup: usize,
    /// CPU the ping ran on (when pinned).
    pub ping_cpu: Option<usize>,
    /// CPU the pong ran on (when pinned).
    pub pong_cpu: Option<usize>,
}

/// What the pong process is told (as JSON after `--spec`).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct PongSpec {
    /// Transport of this row.
    pub transport: Transport,
    /// Wake-up mode of this row.
    pub wake: Wake,
    /// Payload size of this row.
    pub payload_bytes: usize,
    /// Flight namespace of the iceoryx2 services.
    pub flight: String,
    /// Row index (part of every service and socket name).
    pub row: usize,
    /// Abstract Unix socket name (uds only).
    pub socket: String,
    /// CPU to pin the pong to.
    pub cpu: Option<usize>,
    /// The ping's pid: the pong exits when its parent is another process.
    pub parent_pid: u32,
}

impl PongSpec {
    /// Parse the JSON the ping passes after `--spec`.
    pub fn from_json(text: &str) -> Result<Self, BenchError> {
        Ok(serde_json::from_str(text)?)
    }

    /// The JSON passed after `--spec`.
    pub fn to_json(&self) -> Result<String, BenchError> {
        Ok(serde_json::to_string(self)?)
    }
}

// ---------------------------------------------------------------------------------------------
// The stamp in every payload.

#[derive(Debug, Clone, Copy)]
struct Stamp {
    seq: u64,
    sent_ns: u64,
    tail_ok: bool,
}

fn tail_byte(seq: u64) -> u8 {
    (seq as u8) ^ 0xA5
}

fn stamp_bytes(seq: u64, sent_ns: u64) -> impl Iterator<Item = u8> {
    seq.to_le_bytes().into_iter().chain(sent_ns.to_le_bytes())
}

/// Write the stamp into an initialised buffer (only the first 16 and the last byte).
fn write_stamp(buf: &mut [u8], seq: u64, sent_ns: u64) {
    for (dst, b) in buf.iter_mut().zip(stamp_bytes(seq, sent_ns)) {
        *dst = b;
    }
    if let Some(last) = buf.last_mut() {
        *last = tail_byte(seq);
    }
}

/// Write the stamp into loaned shared memory (only the first 16 and the last byte).
fn write_stamp_uninit(buf: &mut [MaybeUninit<u8>], seq: u64, sent_ns: u64) {
    for (dst, b) in buf.iter_mut().zip(stamp_bytes(seq, sent_ns)) {
        dst.write(b);
    }
    if let Some(last) = buf.last_mut() {
        last.write(tail_byte(seq));
    }
}

fn read_stamp(buf: &[u8]) -> Option<Stamp> {
    if buf.len() < MIN_PAYLOAD {
        return None;
    }
    let seq = u64::from_le_bytes(*buf.first_chunk::<8>()?);
    let sent_ns = u64::from_le_bytes(*buf.get(8..)?.first_chunk::<8>()?);
    Some(Stamp {
        seq,
        sent_ns,
        tail_ok: buf.last() == Some(&tail_byte(seq)),
    })
}

/// Check an echo against what was sent.
fn check_echo(buf: &[u8], seq: u64, sent_ns: u64) -> Result<(), BenchError> {
    match read_stamp(buf) {
        Some(s) if s.seq == seq && s.sent_ns == sent_ns && s.tail_ok => Ok(()),
        Some(s) => Err(BenchError::Corrupt {
            expected_seq: seq,
            got_seq: s.seq,
            stamp_ok: s.sent_ns == sent_ns,
            tail_ok: s.tail_ok,
        }),
        None => Err(BenchError::Corrupt {
            expected_seq: seq,
            got_seq: 0,
            stamp_ok: false,
            tail_ok: false,
        }),
    }
}

// ---------------------------------------------------------------------------------------------
// iceoryx2 ports of one row.

type SlicePublisher = Publisher<Ipc, [u8], ()>;
type SliceSubscriber = Subscriber<Ipc, [u8], ()>;
type SliceSample = Sample<Ipc, [u8], ()>;

/// Which end of the ping-pong a process is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Side {
    Ping,
    Pong,
}

impl Side {
    /// (outgoing direction, incoming direction).
    fn directions(self) -> (&'static str, &'static str) {
        match self {
            Self::Ping => ("ping", "pong"),
            Self::Pong => ("pong", "ping"),
        }
    }
}

struct IoxPorts {
    publisher: SlicePublisher,
    subscriber: SliceSubscriber,
    notifier: Option<Notifier<Ipc>>,
    listener: Option<Listener<Ipc>>,
    out_service: String,
    in_service: String,
    /// Yield the CPU while spinning (ping and pong share one CPU).
    yield_while_spinning: bool,
}

fn iox_err(what: &'static str, service: &str, reason: impl core::fmt::Debug) -> BenchError {
    BenchError::Iceoryx {
        what,
        service: service.to_string(),
        reason: format!("{reason:?}"),
    }
}

fn iox_service_name(name: &str) -> Result<ServiceName, BenchError> {
    ServiceName::new(name).map_err(|e| iox_err("name", name, e))
}

fn row_topic(row: usize, direction: &str) -> String {
    format!("bench/r{row}/{direction}")
}

impl IoxPorts {
    /// Open (or create) the four services of `row` and this side's ports on them.
    fn open(
        bus: &FlightBus,
        row: usize,
        payload: usize,
        side: Side,
        wake: Wake,
        yield_while_spinning: bool,
    ) -> Result<Self, BenchError> {
        let (out_dir, in_dir) = side.directions();
        let out_service = bus.service_name(&row_topic(row, out_dir));
        let in_service = bus.service_name(&row_topic(row, in_dir));
        let publisher = Self::slice_service(bus, &out_service)?
            .publisher_builder()
            .initial_max_slice_len(payload)
            .allocation_strategy(AllocationStrategy::Static)
            .max_loaned_samples(1)
            .create()
            .map_err(|e| iox_err("create publisher", &out_service, e))?;
        let subscriber = Self::slice_service(bus, &in_service)?
            .subscriber_builder()
            .create()
            .map_err(|e| iox_err("create subscriber", &in_service, e))?;
        let (notifier, listener) = match wake {
            Wake::Busy => (None, None),
            Wake::Event => {
                let out_ev = format!("{out_service}-event");
                let in_ev = format!("{in_service}-event");
                let notifier = Self::event_service(bus, &out_ev)?
                    .notifier_builder()
                    .create()
                    .map_err(|e| iox_err("create notifier", &out_ev, e))?;
                let listener = Self::event_service(bus, &in_ev)?
                    .listener_builder()
                    .create()
                    .map_err(|e| iox_err("create listener", &in_ev, e))?;
                (Some(notifier), Some(listener))
            }
        };
        Ok(Self {
            publisher,
            subscriber,
            notifier,
            listener,
            out_service,
            in_service,
            yield_while_spinning,
        })
    }

    fn slice_service(
        bus: &FlightBus,
        name: &str,
    ) -> Result<
        iceoryx2::service::port_factory::publish_subscribe::PortFactory<Ipc, [u8], ()>,
        BenchError,
    > {
        bus.node()
            .service_builder(&iox_service_name(name)?)
            .publish_subscribe::<[u8]>()
            .history_size(0)
            .subscriber_max_buffer_size(2)
            .subscriber_max_borrowed_samples(2)
            .max_publishers(1)
            .max_subscribers(1)
            .max_nodes(4)
            .enable_safe_overflow(true)
            .open_or_create()
            .map_err(|e| iox_err("open service", name, e))
    }

    fn event_service(
        bus: &FlightBus,
        name: &str,
    ) -> Result<iceoryx2::service::port_factory::event::PortFactory<Ipc>, BenchError> {
        bus.node()
            .service_builder(&iox_service_name(name)?)
            .event()
            .max_notifiers(1)
            .max_listeners(1)
            .max_nodes(4)
            .open_or_create()
            .map_err(|e| iox_err("open event service", name, e))
    }

    /// Loan `len` bytes, stamp them, send, and notify (event mode). Only the stamp is written.
    fn send(&self, len: usize, seq: u64, sent_ns: u64) -> Result<(), BenchError> {
        let mut sample = self
            .publisher
            .loan_slice_uninit(len)
            .map_err(|e| iox_err("loan", &self.out_service, e))?;
        write_stamp_uninit(sample.payload_mut(), seq, sent_ns);
        // SAFETY: the slice lies in the publisher's data segment, a shared-memory mapping whose
        // pages the kernel zero-filled when the segment was created and which afterwards only
        // ever holds bytes earlier samples wrote: every byte has a defined value. The benchmark
        // writes the stamp and leaves the rest as it was (a zero-copy sender fills only what it
        // produces); nobody interprets the other bytes.
        let sample = unsafe { sample.assume_init() };
        sample
            .send()
            .map_err(|e| iox_err("send", &self.out_service, e))?;
        if let Some(n) = &self.notifier {
            n.notify()
                .map_err(|e| iox_err("notify", &self.out_service, e))?;
        }
        Ok(())
    }

    /// The next sample, waiting at most `timeout_ns` (spinning or on the listener).
    fn receive(&self, timeout_ns: u64) -> Result<Option<SliceSample>, BenchError> {
        let deadline = monotonic_ns().saturating_add(timeout_ns);
        let mut spins = 0u32;
        loop {
            if let Some(s) = self
                .subscriber
                .receive()
                .map_err(|e| iox_err("receive", &self.in_service, e))?
            {
                return Ok(Some(s));
            }
            match &self.listener {
                Some(listener) => {
                    let now = monotonic_ns();
                    if now >= deadline {
                        return Ok(None);
                    }
                    listener
                        .timed_wait(|_| {}, Duration::from_nanos(deadline - now))
                        .map_err(|e| iox_err("wait", &self.in_service, e))?;
                }
                None => {
                    spins = spins.wrapping_add(1);
                    if self.yield_while_spinning {
                        std::thread::yield_now();
                    } else {
                        core::hint::spin_loop();
                    }
                    if spins.is_multiple_of(1024) && monotonic_ns() >= deadline {
                        return Ok(None);
                    }
                }
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Unix-socket transfers.

/// Deadline handling of a socket transfer: the ping gives up, the pong waits for ever.
#[derive(Debug, Clone, Copy)]
struct SockWait {
    busy: bool,
    deadline_ns: Option<u64>,
}

fn would_block(e: &std::io::Error) -> bool {
    matches!(
        e.kind(),
        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
    )
}

impl SockWait {
    /// `Ok(())` to retry after a would-block, or the error to return.
    fn on_would_block(&self, what: &str) -> Result<(), BenchError> {
        let expired = self.deadline_ns.is_some_and(|d| monotonic_ns() >= d);
        if !self.busy || expired {
            return Err(BenchError::Timeout {
                what: what.to_string(),
                timeout_ms: REPLY_TIMEOUT_NS / 1_000_000,
            });
        }
        core::hint::spin_loop();
        Ok(())
    }
}

fn send_all(mut sock: &UnixStream, mut buf: &[u8], wait: SockWait) -> Result<(), BenchError> {
    while !buf.is_empty() {
        match sock.write(buf) {
            Ok(0) => {
                return Err(BenchError::io(
                    "socket write",
                    std::io::ErrorKind::WriteZero.into(),
                ));
            }
            Ok(n) => buf = buf.get(n..).unwrap_or(&[]),
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) if would_block(&e) => wait.on_would_block("writing to the socket")?,
            Err(e) => return Err(BenchError::io("socket write", e)),
        }
    }
    Ok(())
}

/// Fill `buf` from the socket; `Ok(false)` on end of stream before the first byte.
fn recv_exact(mut sock: &UnixStream, buf: &mut [u8], wait: SockWait) -> Result<bool, BenchError> {
    let mut got = 0;
    while got < buf.len() {
        let rest = buf.get_mut(got..).unwrap_or(&mut []);
        match sock.read(rest) {
            Ok(0) if got == 0 => return Ok(false),
            Ok(0) => {
                return Err(BenchError::io(
                    "socket read",
                    std::io::ErrorKind::UnexpectedEof.into(),
                ));
            }
            Ok(n) => got += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) if would_block(&e) => wait.on_would_block("reading from the socket")?,
            Err(e) => return Err(BenchError::io("socket read", e)),
        }
    }
    Ok(true)
}

fn socket_addr(name: &str) -> Result<SocketAddr, BenchError> {
    SocketAddr::from_abstract_name(name.as_bytes())
        .map_err(|e| BenchError::io(format!("socket name `{name}`"), e))
}

fn configure_stream(
    sock: &UnixStream,
    wake: Wake,
    timeout: Option<Duration>,
) -> Result<(), BenchError> {
    let r = match wake {
        Wake::Busy => sock.set_nonblocking(true),
        Wake::Event => sock
            .set_nonblocking(false)
            .and_then(|()| sock.set_read_timeout(timeout))
            .and_then(|()| sock.set_write_timeout(timeout)),
    };
    r.map_err(|e| BenchError::io("configuring the socket", e))
}

// ---------------------------------------------------------------------------------------------
// The pong process.

struct PongProcess {
    child: Option<Child>,
    stdout: Option<ChildStdout>,
}

impl PongProcess {
    fn spawn(cfg: &IpcConfig, spec: &PongSpec) -> Result<Self, BenchError> {
        let child = Command::new(&cfg.pong_exe)
            .args(&cfg.pong_args)
            .arg("--spec")
            .arg(spec.to_json()?)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .map_err(|e| BenchError::io(format!("starting {}", cfg.pong_exe.display()), e))?;
        let mut p = Self {
            child: Some(child),
            stdout: None,
        };
        p.stdout = p.child.as_mut().and_then(|c| c.stdout.take());
        Ok(p)
    }

    fn exit_text(&mut self) -> String {
        match self.child.as_mut().map(|c| c.try_wait()) {
            Some(Ok(Some(status))) => format!("exited ({status})"),
            _ => "closed its output".into(),
        }
    }

    /// Wait for the `ready` line.
    fn wait_ready(&mut self) -> Result<(), BenchError> {
        let Some(out) = self.stdout.as_mut() else {
            return Err(BenchError::Pong("no stdout pipe".into()));
        };
        let deadline = monotonic_ns() + READY_TIMEOUT_MS * 1_000_000;
        let mut line = Vec::new();
        let mut chunk = [0u8; 64];
        while !line.contains(&b'\n') {
            let now = monotonic_ns();
            if now >= deadline {
                return Err(BenchError::Timeout {
                    what: "waiting for the pong to be ready".into(),
                    timeout_ms: READY_TIMEOUT_MS,
                });
            }
            let mut pfd = libc::pollfd {
                fd: out.as_raw_fd(),
                events: libc::POLLIN,
                revents: 0,
            };
            let ms = ((deadline - now) / 1_000_000).clamp(1, i32::MAX as u64) as i32;
            // SAFETY: `pfd` is one valid pollfd.
            let rc = unsafe { libc::poll(&mut pfd, 1, ms) };
            if rc < 0 {
                let e = std::io::Error::last_os_error();
                if e.kind() == std::io::ErrorKind::Interrupted {
                    continue;
                }
                return Err(BenchError::io("poll on the pong's stdout", e));
            }
            if rc == 0 {
                continue;
            }
            match out.read(&mut chunk) {
                Ok(0) => {
                    // give a dying child a moment so its exit status is known
                    std::thread::sleep(Duration::from_millis(50));
                    let why = self.exit_text();
                    return Err(BenchError::Pong(format!("{why} before it was ready")));
                }
                Ok(n) => line.extend_from_slice(chunk.get(..n).unwrap_or(&[])),
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(BenchError::io("reading the pong's stdout", e)),
            }
        }
        let text = String::from_utf8_lossy(&line);
        if text.trim() == READY_LINE {
            Ok(())
        } else {
            Err(BenchError::Pong(format!(
                "said `{}` instead of `{READY_LINE}`",
                text.trim()
            )))
        }
    }

    /// Wait (briefly) for the pong to exit after the stop message; kill it if it does not.
    fn finish(mut self) -> Result<(), BenchError> {
        let Some(mut child) = self.child.take() else {
            return Ok(());
        };
        let deadline = monotonic_ns() + 5_000_000_000;
        loop {
            match child.try_wait() {
                Ok(Some(status)) if status.success() => return Ok(()),
                Ok(Some(status)) => {
                    return Err(BenchError::Pong(format!("exited with {status}")));
                }
                Ok(None) if monotonic_ns() < deadline => {
                    std::thread::sleep(Duration::from_millis(2))
                }
                Ok(None) => {
                    let _ = child.kill();
                    let _ = child.wait();
                    return Err(BenchError::Pong(
                        "did not exit on the stop message (killed)".into(),
                    ));
                }
                Err(e) => return Err(BenchError::io("waiting for the pong", e)),
            }
        }
    }
}

impl Drop for PongProcess {
    fn drop(&mut self) {
        if let Some(mut child) = self.child.take() {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

/// Restores the calling thread's CPU affinity when dropped.
struct AffinityGuard(Option<CpuSet>);

impl Drop for AffinityGuard {
    fn drop(&mut self) {
        if let Some(set) = &self.0 {
            let _ = set.bind_task(0);
        }
    }
}

fn single_cpu(cpu: usize) -> Result<CpuSet, BenchError> {
    CpuSet::parse(&cpu.to_string()).map_err(|e| BenchError::Config(e.to_string()))
}

// ---------------------------------------------------------------------------------------------
// The ping side.

/// Run every row of `cfg`; `progress` sees each row as soon as it is measured.
pub fn run(cfg: &IpcConfig, mut progress: impl FnMut(&IpcRow)) -> Result<IpcReport, BenchError> {
    if cfg.iterations == 0 {
        return Err(BenchError::Config("iterations must be at least 1".into()));
    }
    if let Some(p) = cfg.payloads.iter().find(|p| **p < MIN_PAYLOAD) {
        return Err(BenchError::Config(format!(
            "payload of {p} bytes is below the minimum of {MIN_PAYLOAD}"
        )));
    }
    let pid = std::process::id();
    let flight = format!("bench-ipc-{pid}");

    let original = CpuSet::of_task(0).map_err(|e| BenchError::io("reading CPU affinity", e))?;
    let mut guard = AffinityGuard(None);
    let (ping_cpu, pong_cpu) = match original.cpus() {
        [a, b, ..] if cfg.pin => {
            single_cpu(*a)?
                .bind_task(0)
                .map_err(|e| BenchError::io(format!("pinning the ping to CPU {a}"), e))?;
            guard.0 = Some(original.clone());
            (Some(*a), Some(*b))
        }
        _ => (None, None),
    };
    let shared_cpu = original.cpus().len() < 2;

    let needs_bus = cfg.cases.iter().any(|(t, _)| *t == Transport::Iceoryx2);
    let bus = if needs_bus {
        Some(
            FlightBus::builder(&flight)
                .node_name("ping")
                .join_manifest(false)
                .create()?,
        )
    } else {
        None
    };

    let mut rows = Vec::new();
    let mut row_index = 0;
    for &(transport, wake) in &cfg.cases {
        for &payload in &cfg.payloads {
            let spec = PongSpec {
                transport,
                wake,
                payload_bytes: payload,
                flight: flight.clone(),
                row: row_index,
                socket: format!("aeris-bench-ipc-{pid}-{row_index}"),
                cpu: pong_cpu,
                parent_pid: pid,
            };
            row_index += 1;
            let samples = match (transport, &bus) {
                (Transport::Iceoryx2, Some(bus)) => ping_iceoryx2(cfg, &spec, bus, shared_cpu)?,
                (Transport::Iceoryx2, None) => {
                    return Err(BenchError::Config("no iceoryx2 node".into()));
                }
                (Transport::Uds, _) => ping_uds(cfg, &spec)?,
            };
            let (p50_us, p99_us, max_us) = summary_us(&samples);
            let row = IpcRow {
                transport,
                wake,
                payload_bytes: payload,
                p50_us,
                p99_us,
                max_us,
            };
            progress(&row);
            rows.push(row);
        }
    }
    drop(bus);
    drop(guard);
    Ok(IpcReport {
        rows,
        iterations: cfg.iterations,
        warmup: cfg.warmup,
        ping_cpu,
        pong_cpu,
    })
}

fn ping_iceoryx2(
    cfg: &IpcConfig,
    spec: &PongSpec,
    bus: &FlightBus,
    shared_cpu: bool,
) -> Result<Vec<f64>, BenchError> {
    let ports = IoxPorts::open(
        bus,
        spec.row,
        spec.payload_bytes,
        Side::Ping,
        spec.wake,
        shared_cpu,
    )?;
    let mut pong = PongProcess::spawn(cfg, spec)?;
    pong.wait_ready()?;
    let mut samples = Vec::with_capacity(cfg.iterations);
    for i in 0..cfg.warmup + cfg.iterations {
        let seq = i as u64 + 1;
        let sent = monotonic_ns();
        ports.send(spec.payload_bytes, seq, sent)?;
        let Some(reply) = ports.receive(REPLY_TIMEOUT_NS)? else {
            return Err(BenchError::Timeout {
                what: format!("waiting for echo {seq} on `{}`", ports.in_service),
                timeout_ms: REPLY_TIMEOUT_NS / 1_000_000,
            });
        };
        let now = monotonic_ns();
        check_echo(reply.payload(), seq, sent)?;
        drop(reply);
        if i >= cfg.warmup {
            samples.push(now.saturating_sub(sent) as f64);
        }
    }
    ports.send(spec.payload_bytes, STOP_SEQ, monotonic_ns())?;
    pong.finish()?;
    Ok(samples)
}

fn ping_uds(cfg: &IpcConfig, spec: &PongSpec) -> Result<Vec<f64>, BenchError> {
    let addr = socket_addr(&spec.socket)?;
    let listener = UnixListener::bind_addr(&addr)
        .map_err(|e| BenchError::io(format!("binding socket `{}`", spec.socket), e))?;
    let mut pong = PongProcess::spawn(cfg, spec)?;
    pong.wait_ready()?;
    // The pong connected before it said ready: the connection waits in the backlog.
    let (sock, _) = listener
        .accept()
        .map_err(|e| BenchError::io("accepting the pong's connection", e))?;
    configure_stream(
        &sock,
        spec.wake,
        Some(Duration::from_nanos(REPLY_TIMEOUT_NS)),
    )?;
    let len = spec.payload_bytes;
    let mut out = vec![0x5Au8; len];
    let mut back = vec![0u8; len];
    let mut samples = Vec::with_capacity(cfg.iterations);
    for i in 0..cfg.warmup + cfg.iterations {
        let seq = i as u64 + 1;
        let sent = monotonic_ns();
        let wait = SockWait {
            busy: spec.wake == Wake::Busy,
            deadline_ns: Some(sent + REPLY_TIMEOUT_NS),
        };
        write_stamp(&mut out, seq, sent);
        send_all(&sock, &out, wait)?;
        if !recv_exact(&sock, &mut back, wait)? {
            return Err(BenchError::Pong("closed the socket".into()));
        }
        let now = monotonic_ns();
        check_echo(&back, seq, sent)?;
        if i >= cfg.warmup {
            samples.push(now.saturating_sub(sent) as f64);
        }
    }
    let wait = SockWait {
        busy: spec.wake == Wake::Busy,
        deadline_ns: Some(monotonic_ns() + REPLY_TIMEOUT_NS),
    };
    write_stamp(&mut out, STOP_SEQ, monotonic_ns());
    send_all(&sock, &out, wait)?;
    pong.finish()?;
    Ok(samples)
}

// ---------------------------------------------------------------------------------------------
// The pong side.

fn parent_gone(parent_pid: u32) -> bool {
    std::os::unix::process::parent_id() != parent_pid
}

/// Run the pong of one row in this process: die with the parent, pin, open the ports, print
/// `ready` on stdout, then echo until the stop message (or the end of the stream). Lowers
/// iceoryx2's log level of this process to errors.
pub fn run_pong(spec: &PongSpec) -> Result<(), BenchError> {
    // This process only echoes: keep iceoryx2's start-up notices (e.g. "no config file")
    // out of the ping's output; errors still show.
    iceoryx2::prelude::set_log_level(iceoryx2::prelude::LogLevel::Error);
    // SAFETY: prctl(PR_SET_PDEATHSIG) only sets a flag of the calling process.
    let rc = unsafe {
        libc::prctl(
            libc::PR_SET_PDEATHSIG,
            libc::SIGKILL as libc::c_ulong,
            0,
            0,
            0,
        )
    };
    if rc != 0 {
        return Err(BenchError::last_os("prctl(PR_SET_PDEATHSIG)"));
    }
    if parent_gone(spec.parent_pid) {
        return Err(BenchError::Pong(format!(
            "parent {} is already gone",
            spec.parent_pid
        )));
    }
    if let Some(cpu) = spec.cpu {
        single_cpu(cpu)?
            .bind_task(0)
            .map_err(|e| BenchError::io(format!("pinning the pong to CPU {cpu}"), e))?;
    }
    match spec.transport {
        Transport::Iceoryx2 => pong_iceoryx2(spec),
        Transport::Uds => pong_uds(spec),
    }
}

fn say_ready() -> Result<(), BenchError> {
    let mut out = std::io::stdout().lock();
    writeln!(out, "{READY_LINE}")
        .and_then(|()| out.flush())
        .map_err(|e| BenchError::io("writing `ready`", e))
}

fn pong_iceoryx2(spec: &PongSpec) -> Result<(), BenchError> {
    let bus = FlightBus::builder(&spec.flight)
        .node_name(&format!("pong{}", spec.row))
        .join_manifest(false)
        .create()?;
    let ports = IoxPorts::open(
        &bus,
        spec.row,
        spec.payload_bytes,
        Side::Pong,
        spec.wake,
        spec.cpu.is_none(),
    )?;
    say_ready()?;
    loop {
        let Some(sample) = ports.receive(PONG_IDLE_NS)? else {
            if parent_gone(spec.parent_pid) {
                return Ok(());
            }
            continue;
        };
        let stamp = match read_stamp(sample.payload()) {
            Some(s) if s.tail_ok => s,
            other => {
                return Err(BenchError::Corrupt {
                    expected_seq: other.map_or(0, |s| s.seq),
                    got_seq: other.map_or(0, |s| s.seq),
                    stamp_ok: true,
                    tail_ok: false,
                });
            }
        };
        if stamp.seq == STOP_SEQ {
            return Ok(());
        }
        let len = sample.payload().len();
        drop(sample);
        ports.send(len, stamp.seq, stamp.sent_ns)?;
    }
}

fn pong_uds(spec: &PongSpec) -> Result<(), BenchError> {
    let addr = socket_addr(&spec.socket)?;
    let sock = UnixStream::connect_addr(&addr)
        .map_err(|e| BenchError::io(format!("connecting to socket `{}`", spec.socket), e))?;
    configure_stream(&sock, spec.wake, None)?;
    let mut buf = vec![0u8; spec.payload_bytes];
    say_ready()?;
    let wait = SockWait {
        busy: spec.wake == Wake::Busy,
        deadline_ns: None,
    };
    loop {
        if !recv_exact(&sock, &mut buf, wait)? {
            return Ok(()); // the ping closed the socket
        }
        let stamp = match read_stamp(&buf) {
            Some(s) if s.tail_ok => s,
            other => {
                return Err(BenchError::Corrupt {
                    expected_seq: other.map_or(0, |s| s.seq),
                    got_seq: other.map_or(0, |s| s.seq),
                    stamp_ok: true,
                    tail_ok: false,
                });
            }
        };
        if stamp.seq == STOP_SEQ {
            return Ok(());
        }
        send_all(&sock, &buf, wait)?;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stamps_round_trip_and_detect_damage() {
        let mut buf = vec![0u8; 64];
        write_stamp(&mut buf, 7, 123_456);
        assert!(check_echo(&buf, 7, 123_456).is_ok());
        assert!(check_echo(&buf, 8, 123_456).is_err());
        assert!(check_echo(&buf, 7, 1).is_err());
        buf[63] ^= 1;
        assert!(matches!(
            check_echo(&buf, 7, 123_456),
            Err(BenchError::Corrupt { tail_ok: false, .. })
        ));
        assert!(read_stamp(&buf[..16]).is_none());

        let mut raw = vec![MaybeUninit::new(0u8); 32];
        write_stamp_uninit(&mut raw, 9, 99);
        let bytes: Vec<u8> = raw.iter().map(|b| unsafe { b.assume_init() }).collect();
        assert!(check_echo(&bytes, 9, 99).is_ok());
    }

    #[test]
    fn pong_spec_is_json() {
        let spec = PongSpec {
            transport: Transport::Iceoryx2,
            wake: Wake::Event,
            payload_bytes: 64,
            flight: "bench-ipc-1".into(),
            row: 3,
            socket: "s".into(),
            cpu: Some(1),
            parent_pid: 42,
        };
        let json = spec.to_json().unwrap();
        assert!(json.contains("\"iceoryx2\"") && json.contains("\"event\""));
        assert_eq!(PongSpec::from_json(&json).unwrap(), spec);
        assert!(PongSpec::from_json("{").is_err());
    }

    #[test]
    fn rejects_payloads_too_small_for_the_stamp() {
        let mut cfg = IpcConfig::new("/nonexistent".into(), vec![]);
        cfg.payloads = vec![8];
        assert!(matches!(run(&cfg, |_| {}), Err(BenchError::Config(_))));
    }
}
