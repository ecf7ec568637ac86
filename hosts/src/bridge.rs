//! The bridge role (kind `bridge`, variant `zenoh`): carries the topics that cross between
//! its host and one other, between iceoryx2 here and zenoh there. The supervisor adds two
//! per other host (`bridge-to-HOST` on the flight's host, `bridge-on-HOST` there) and tells
//! each what to send and receive; the rest of the flight does not know it exists.
//!
//! - **Exact bytes.** A message crosses as the bytes of its `#[repr(C)]` payload (a frame as
//!   its header's bytes, then its pixels), with an attachment: the schema stamp (version and
//!   layout hash), the bridge's own sequence number of the topic, the header length and the
//!   frame coding. The receiving bridge publishes those bytes into its own shared memory, so
//!   what a role reads is bit for bit what was published on the other host; the hub's
//!   sequence checks on decisions work across hosts as on one. The one exception is an RGB
//!   frame's pixels: by default they cross as JPEG ([`crate::frames`]; `frames = "raw"`
//!   sends them exact), decoded back into shared memory on the other host; the header and
//!   depth frames stay exact.
//! - **Schema checked per message.** A message stamped with another schema is refused,
//!   counted, and named once in the log ([`SchemaMismatch`]); nothing of it is published.
//! - **QoS.** Each topic keeps its iceoryx2 QoS on both hosts (history, buffer). On zenoh
//!   every message is reliable and ordered per topic; frames are sent at data priority,
//!   everything else at interactive priority without batching (`express`). Congestion
//!   drops instead of blocking: a slow or cut link never stalls the bridge, so a role
//!   reachable only over the link never blocks the flight.
//! - **No echo.** A topic carried both ways (the heartbeat of two hosts) is not sent back:
//!   samples the bridge itself published are skipped by their publisher id.
//! - **Frames only where they are read.** The bridges of a host carry the topics of every
//!   role that may run there (a role can be moved there during the flight), but a frame
//!   (hundreds of KB) crosses only while a role on the receiving host reads it: the
//!   receiving bridge subscribes to it on zenoh only while its topic has a reader there, and
//!   the sending bridge copies a frame out of shared memory only while zenoh reports a
//!   matching subscriber. Every other topic is small and always carried, so a role that
//!   starts on the other host finds the latest sample in its history.
//!
//! Parameters: `connect` (the other host's agent endpoint), `keys` (this host's identity
//! directory for the mutual-TLS link; none: a plain `tcp/` link), `export` and `import` (topic
//! lists), `peer` (who is at the other end, for messages), `frame_bytes` (the first frame
//! publisher's size), `link_timeout_ms` (zenoh's lease), `frames` (`jpeg`, the default, or
//! `raw`) and `jpeg_quality` (85).
//!
//! The bridge on the flight's host (`probe` names the other host) also measures the link:
//! it asks the other host's agent for its `info` every 250 ms and publishes the round
//! trip, the loss, the clock offset, the other host's load and the cost of encoding a frame
//! on `hosts/link` ([`crate::probe`]). The encoding cost is that of the frames sent: none is
//! encoded only to measure it (on the vehicle, CPU is what the flight lacks; a debug build
//! takes 15 ms a frame), so until a frame has crossed it is unknown (0).
//!
//! When it stops it prints what crossed, per topic (`bridge: sent `camera/rgb`: N messages,
//! B bytes`), and the CPU time its process used (`bridge: used S s of CPU over W s`).
//!
//! Heartbeat counters: [`BridgeCounters`]. Status `Degraded` while no peer is connected or
//! after a refusal.
//!
//! Unlike the other roles the bridge allocates per message: zenoh takes each message as an
//! owned buffer.

use crate::frames::{CODING_JPEG, CODING_RAW, DEFAULT_JPEG_QUALITY, FrameCoding, decode};
use crate::probe::LinkProbe;
use crate::protocol::{SchemaStamp, check_schema, data_key};
use crate::session::{LinkSecurity, Reach, SessionError, open_client};
use aeris_runtime::clock::monotonic_ns;
use aeris_runtime::raw::{
    Payload, RawPublisher, RawSubscriber, payload_of, raw_publisher, raw_subscriber, read,
};
use aeris_runtime::{ConfigError, CycleOutcome, CycleReport, Role, RoleContext, RoleError};
use aeris_schemas::RoleStatus;
use aeris_schemas::kinds;
use aeris_schemas::{BridgeCounters, FrameHeader};
use core::time::Duration;
use iceoryx2::identifiers::UniquePublisherId;
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::Receiver;
use zenoh::bytes::ZBytes;
use zenoh::handlers::FifoChannelHandler;
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::qos::{CongestionControl, Priority};
use zenoh::sample::Sample;
use zenoh::{Session, Wait};

pub use crate::protocol::SchemaMismatch;

/// The pause between tries to reach the other host while it does not answer.
const OPEN_RETRY: Duration = Duration::from_secs(1);

/// How often the bridge moves what is waiting.
const PERIOD: Duration = Duration::from_millis(1);

/// Messages of one topic moved per cycle at most (a burst is spread over cycles).
const BURST: usize = 64;

/// How often a working bridge reports a worked cycle (its heartbeat, not each message).
const REPORT_NS: u64 = 100_000_000;

/// Attachment: schema stamp (12 bytes), sequence number (8), header length (4), frame
/// coding (1: [`CODING_RAW`] or [`CODING_JPEG`]; absent means raw).
const ATTACHMENT_LEN: usize = 25;

fn attachment(seq: u64, header_len: usize, coding: u8) -> [u8; ATTACHMENT_LEN] {
    let mut a = [0u8; ATTACHMENT_LEN];
    a[..12].copy_from_slice(&SchemaStamp::current().to_bytes());
    a[12..20].copy_from_slice(&seq.to_le_bytes());
    a[20..24].copy_from_slice(&(header_len as u32).to_le_bytes());
    a[24] = coding;
    a
}

/// One topic sent to the other host.
struct Export {
    topic: String,
    payload: Payload,
    sub: Box<dyn RawSubscriber>,
    /// Its zenoh publisher (`None` until the other host is first reached).
    publisher: Option<Publisher<'static>>,
    seq: u64,
    /// Messages and bytes sent.
    sent: (u64, u64),
    /// Bytes before coding, and nanoseconds spent encoding.
    raw_bytes: u64,
    encode_ns: u64,
    /// A subscriber on the other host wants it (frames: checked every [`REPORT_NS`];
    /// every other topic is always sent).
    wanted: bool,
}

/// One topic received from the other host.
struct Import {
    topic: String,
    payload: Payload,
    /// Its zenoh subscriber (frames: only while the topic has a reader on this host).
    sub: Option<Subscriber<FifoChannelHandler<Sample>>>,
    publisher: Box<dyn RawPublisher>,
    /// This bridge also subscribes to the topic here (it sends it the other way too).
    exported: bool,
    /// Messages and bytes received and published here.
    received: (u64, u64),
    /// Nanoseconds spent decoding.
    decode_ns: u64,
}

/// The bridge role.
pub struct BridgeRole {
    flight: String,
    /// How frames are sent.
    frames: FrameCoding,
    /// Decoded pixels of the frame being received (reused).
    pixels: Vec<u8>,
    /// The zenoh session (`None` until the other host is first reached).
    session: Option<Session>,
    /// The session being opened in the background while the other host does not answer.
    opening: Option<Receiver<Session>>,
    /// Tells that background opener to give up (the bridge stopped).
    stop_opening: Arc<AtomicBool>,
    exports: Vec<Export>,
    imports: Vec<Import>,
    /// Publisher ids of this bridge's own imports (never exported back).
    own: Vec<UniquePublisherId>,
    peer: String,
    counters: BridgeCounters,
    refused_logged: bool,
    connected: bool,
    last_report_ns: u64,
    link_checked_ns: u64,
    /// The link's measurement (the bridge on the flight's host only).
    probe: Option<LinkProbe>,
    /// When it started (for its CPU share, printed when it stops).
    started_ns: u64,
}

fn topics_param(ctx: &RoleContext<kinds::Bridge>, key: &str) -> Result<Vec<String>, RoleError> {
    let Some(v) = ctx.spec.params.get(key) else {
        return Ok(Vec::new());
    };
    let list: Vec<String> = serde_json::from_value(v.clone())
        .map_err(|e| RoleError::param(key, format!("is not a list of topics: {e}")))?;
    for t in &list {
        if payload_of(t).is_none() {
            return Err(RoleError::param(
                key,
                format!("names `{t}`, which is not a topic"),
            ));
        }
    }
    Ok(list)
}

impl Role for BridgeRole {
    type Kind = kinds::Bridge;

    fn new(ctx: &mut RoleContext<kinds::Bridge>) -> Result<Self, RoleError> {
        let connect = ctx
            .spec
            .param_str("connect")
            .ok_or_else(|| RoleError::param("connect", "is required"))?
            .to_string();
        // the link's identity (`keys`, this host's); none: a plain TCP link, which the
        // endpoint must then say (`tcp/`)
        let security = LinkSecurity::from_keys(ctx.spec.param_str("keys").map(Path::new))
            .map_err(|e| ConfigError::param_refused("keys", e))?;
        let export = topics_param(ctx, "export")?;
        let import = topics_param(ctx, "import")?;
        let peer = ctx
            .spec
            .param_str("peer")
            .unwrap_or("the other host")
            .to_string();
        let frame_bytes = ctx
            .spec
            .params
            .get("frame_bytes")
            .and_then(|v| v.as_u64())
            .unwrap_or(320 * 240 * 3) as usize;
        let lease = Duration::from_millis(
            ctx.spec
                .params
                .get("link_timeout_ms")
                .and_then(|v| v.as_u64())
                .unwrap_or(1000),
        );
        let frames = FrameCoding::parse(
            ctx.spec.param_str("frames").unwrap_or("jpeg"),
            ctx.spec
                .params
                .get("jpeg_quality")
                .and_then(|v| v.as_u64())
                .unwrap_or(DEFAULT_JPEG_QUALITY as u64),
        )
        .map_err(|e| ConfigError::param_refused("frames", e))?;
        let flight = ctx.spec.flight.clone();
        let probe = match ctx.spec.param_str("probe") {
            Some(host) => Some(LinkProbe::new(&ctx.bus, host, lease)?),
            None => None,
        };
        let mut imports = Vec::with_capacity(import.len());
        let mut own = Vec::with_capacity(import.len());
        for t in import {
            let payload = payload_of(&t).unwrap_or(Payload::Heartbeat);
            let publisher = raw_publisher(ctx.bus.flight_bus(), &t, frame_bytes)?;
            own.push(publisher.id());
            // subscribed on zenoh once the session is open ([`BridgeRole::attach`]); frames
            // once a reader appears here too ([`BridgeRole::follow_readers`])
            imports.push(Import {
                received: (0, 0),
                decode_ns: 0,
                exported: export.contains(&t),
                topic: t,
                payload,
                sub: None,
                publisher,
            });
        }
        let mut exports = Vec::with_capacity(export.len());
        for t in export {
            let payload = payload_of(&t).unwrap_or(Payload::Heartbeat);
            let sub = raw_subscriber(ctx.bus.flight_bus(), &t)?;
            exports.push(Export {
                topic: t,
                payload,
                sub,
                publisher: None,
                seq: 0,
                sent: (0, 0),
                raw_bytes: 0,
                encode_ns: 0,
                wanted: payload != Payload::Frame,
            });
        }
        println!(
            "bridge to {peer} at {connect}: sends [{}], receives [{}]",
            exports
                .iter()
                .map(|e| e.topic.as_str())
                .collect::<Vec<_>>()
                .join(", "),
            imports
                .iter()
                .map(|i| i.topic.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        );
        let counters = BridgeCounters {
            topics: (exports.len() + imports.len()) as u64,
            ..BridgeCounters::default()
        };
        let mut bridge = BridgeRole {
            flight,
            frames,
            pixels: Vec::new(),
            session: None,
            opening: None,
            stop_opening: Arc::new(AtomicBool::new(false)),
            exports,
            imports,
            own,
            peer,
            counters,
            refused_logged: false,
            connected: false,
            last_report_ns: 0,
            link_checked_ns: 0,
            probe,
            started_ns: monotonic_ns(),
        };
        match open_client(&connect, Reach::Eventually, lease, &security) {
            Ok(session) => bridge.attach(session)?,
            Err(e @ (SessionError::Endpoint { .. } | SessionError::Security { .. })) => {
                return Err(ConfigError::param_refused("connect", e).into());
            }
            Err(e) => {
                // the other host does not answer yet: the bridge runs without it (the
                // flight never waits for a link) and keeps trying in the background
                tracing::warn!(
                    "bridge: {} not reachable yet ({e}); trying every second",
                    bridge.peer
                );
                bridge.opening = Some(open_in_background(
                    connect,
                    lease,
                    security,
                    bridge.stop_opening.clone(),
                ));
            }
        }
        Ok(bridge)
    }

    fn period(&self) -> Duration {
        PERIOD
    }

    fn cycle(
        &mut self,
        _ctx: &mut RoleContext<kinds::Bridge>,
        report: &mut CycleReport,
    ) -> Result<CycleOutcome, RoleError> {
        let t0 = monotonic_ns();
        let mut moved = 0u64;
        if let Some(session) = self.opening.as_ref().and_then(|rx| rx.try_recv().ok()) {
            self.opening = None;
            self.attach(session)?;
        }
        for ex in &mut self.exports {
            for _ in 0..BURST {
                // the message as zenoh takes it: one owned copy out of shared memory (a
                // frame encoded straight into it)
                let mut sent: Option<(Vec<u8>, usize, usize, u8)> = None;
                let mut failed = None;
                let own = &self.own;
                let (wanted, frames, is_frame) = (
                    ex.wanted && ex.publisher.is_some(),
                    self.frames,
                    ex.payload == Payload::Frame,
                );
                let mut encode_ns = 0u64;
                let got = ex.sub.next_raw(&mut |bytes, pixels, from| {
                    if !wanted || own.contains(&from) {
                        return;
                    }
                    // a JPEG frame is a few percent of its pixels: reserve accordingly
                    let room = match frames {
                        FrameCoding::Jpeg { .. } if is_frame => pixels.len() / 8,
                        _ => pixels.len(),
                    };
                    let mut message = Vec::with_capacity(bytes.len() + room);
                    message.extend_from_slice(bytes);
                    let coding = match read::<FrameHeader>(bytes).filter(|_| is_frame) {
                        Some(header) => {
                            let t = monotonic_ns();
                            let coded = frames.encode(&header, pixels, &mut message);
                            encode_ns = monotonic_ns().saturating_sub(t);
                            match coded {
                                Ok(c) => c,
                                Err(e) => {
                                    failed = Some(e);
                                    return;
                                }
                            }
                        }
                        None => {
                            message.extend_from_slice(pixels);
                            CODING_RAW
                        }
                    };
                    sent = Some((message, bytes.len(), bytes.len() + pixels.len(), coding));
                })?;
                if !got {
                    break;
                }
                if let Some(e) = failed {
                    self.counters.dropped += 1;
                    if !self.refused_logged {
                        tracing::warn!("bridge: cannot send `{}`: {e}", ex.topic);
                        self.refused_logged = true;
                    }
                    continue;
                }
                let Some((message, header_len, raw_len, coding)) = sent else {
                    continue;
                };
                if coding == CODING_JPEG {
                    ex.encode_ns += encode_ns;
                    if let Some(p) = self.probe.as_mut() {
                        p.frame_coded(encode_ns);
                    }
                }
                let Some(publisher) = ex.publisher.as_ref() else {
                    continue;
                };
                ex.seq += 1;
                let len = message.len() as u64;
                let put = publisher
                    .put(ZBytes::from(message))
                    .attachment(ZBytes::from(
                        attachment(ex.seq, header_len, coding).to_vec(),
                    ))
                    .wait();
                match put {
                    Ok(()) => {
                        self.counters.sent += 1;
                        self.counters.bytes_sent += len;
                        ex.sent.0 += 1;
                        ex.sent.1 += len;
                        ex.raw_bytes += raw_len as u64;
                        moved += 1;
                    }
                    Err(_) => self.counters.dropped += 1,
                }
            }
        }
        for im in &mut self.imports {
            let Some(sub) = im.sub.as_ref() else {
                continue;
            };
            for _ in 0..BURST {
                let Ok(Some(sample)) = sub.try_recv() else {
                    break;
                };
                let bytes = sample.payload().to_bytes();
                let att = sample.attachment().map(|a| a.to_bytes());
                let stamp = att.as_deref().and_then(SchemaStamp::from_bytes);
                let header_len = att
                    .as_deref()
                    .and_then(|a| a.get(20..24))
                    .and_then(|b| b.try_into().ok())
                    .map(|b| u32::from_le_bytes(b) as usize);
                let (Some(stamp), Some(header_len)) = (stamp, header_len) else {
                    self.counters.refused += 1;
                    continue;
                };
                if let Err(e) = check_schema(&format!("the bridge of {}", self.peer), stamp) {
                    self.counters.refused += 1;
                    if !self.refused_logged {
                        tracing::warn!("bridge: refused `{}`: {e}", im.topic);
                        self.refused_logged = true;
                    }
                    continue;
                }
                let Some((header, pixels)) = bytes.split_at_checked(header_len) else {
                    self.counters.refused += 1;
                    continue;
                };
                let coding = att.as_deref().and_then(|a| a.get(24)).copied();
                let pixels = match (im.payload, read::<FrameHeader>(header)) {
                    (Payload::Frame, Some(h)) if coding.is_some_and(|c| c != CODING_RAW) => {
                        let t = monotonic_ns();
                        let decoded =
                            decode(coding.unwrap_or(CODING_RAW), &h, pixels, &mut self.pixels);
                        im.decode_ns += monotonic_ns().saturating_sub(t);
                        if let Err(e) = decoded {
                            self.counters.refused += 1;
                            if !self.refused_logged {
                                tracing::warn!("bridge: refused `{}`: {e}", im.topic);
                                self.refused_logged = true;
                            }
                            continue;
                        }
                        &self.pixels[..]
                    }
                    (Payload::Frame, _) => pixels,
                    _ => &[],
                };
                match im.publisher.publish_raw(header, pixels) {
                    Ok(()) => {
                        self.counters.received += 1;
                        self.counters.bytes_received += bytes.len() as u64;
                        im.received.0 += 1;
                        im.received.1 += bytes.len() as u64;
                        moved += 1;
                    }
                    Err(_) => self.counters.dropped += 1,
                }
            }
        }
        let now = monotonic_ns();
        if now.saturating_sub(self.link_checked_ns) >= REPORT_NS {
            self.link_checked_ns = now;
            self.check_link();
            self.follow_readers();
        }
        let connected = self.connected;
        if let Some(p) = self.probe.as_mut() {
            p.step(self.session.as_ref(), connected, now);
        }
        self.counters.connected = connected as u64;
        report.counters = self.counters.to_heartbeat();
        report.status = if connected && !self.refused_logged {
            RoleStatus::Running
        } else {
            RoleStatus::Degraded
        };
        if moved > 0 && now.saturating_sub(self.last_report_ns) >= REPORT_NS {
            self.last_report_ns = now;
            report.stage("bridge", now.saturating_sub(t0));
            return Ok(CycleOutcome::Worked);
        }
        Ok(CycleOutcome::Idle)
    }
}

/// Open the session to `connect` on a thread of its own, trying every second until it
/// opens or `stop` is set; the session arrives on the returned channel.
fn open_in_background(
    connect: String,
    lease: Duration,
    security: LinkSecurity,
    stop: Arc<AtomicBool>,
) -> Receiver<Session> {
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        while !stop.load(Ordering::Relaxed) {
            match open_client(&connect, Reach::Eventually, lease, &security) {
                Ok(session) => {
                    let _ = tx.send(session);
                    return;
                }
                Err(_) => std::thread::sleep(OPEN_RETRY),
            }
        }
    });
    rx
}

impl BridgeRole {
    /// Declare every topic on the newly opened `session`: a publisher per exported topic,
    /// a subscriber per imported one (frames: once read here).
    fn attach(&mut self, session: Session) -> Result<(), RoleError> {
        let declare = |what: String| {
            move |e: zenoh::Error| RoleError::step(format!("declaring {what} on zenoh"), e)
        };
        for im in self
            .imports
            .iter_mut()
            .filter(|i| i.payload != Payload::Frame)
        {
            im.sub = Some(
                session
                    .declare_subscriber(data_key(&self.flight, &im.topic))
                    .wait()
                    .map_err(declare(format!("the subscriber of `{}`", im.topic)))?,
            );
        }
        for ex in &mut self.exports {
            let (priority, express) = match ex.payload {
                Payload::Frame => (Priority::Data, false),
                _ => (Priority::InteractiveHigh, true),
            };
            ex.publisher = Some(
                session
                    .declare_publisher(data_key(&self.flight, &ex.topic))
                    .congestion_control(CongestionControl::Drop)
                    .priority(priority)
                    .express(express)
                    .wait()
                    .map_err(declare(format!("the publisher of `{}`", ex.topic)))?,
            );
        }
        self.session = Some(session);
        Ok(())
    }

    /// Frames cross only where they are read: subscribe to an imported frame topic on
    /// zenoh while it has a reader on this host (besides this bridge), and send an
    /// exported one while zenoh has a subscriber for it on the other host.
    fn follow_readers(&mut self) {
        for im in self
            .imports
            .iter_mut()
            .filter(|i| i.payload == Payload::Frame)
        {
            let ours = usize::from(im.exported);
            let read_here = im.publisher.subscribers().is_some_and(|n| n > ours);
            if read_here == im.sub.is_some() {
                continue;
            }
            if !read_here {
                im.sub = None;
                println!(
                    "bridge: `{}` has no reader here: not receiving it",
                    im.topic
                );
                continue;
            }
            let Some(session) = self.session.as_ref() else {
                continue;
            };
            match session
                .declare_subscriber(data_key(&self.flight, &im.topic))
                .wait()
            {
                Ok(sub) => {
                    im.sub = Some(sub);
                    println!("bridge: `{}` is read here: receiving it", im.topic);
                }
                Err(e) => {
                    self.counters.dropped += 1;
                    tracing::warn!("bridge: cannot subscribe to `{}` on zenoh: {e}", im.topic);
                }
            }
        }
        for ex in self
            .exports
            .iter_mut()
            .filter(|e| e.payload == Payload::Frame)
        {
            ex.wanted = ex
                .publisher
                .as_ref()
                .is_some_and(|p| p.matching_status().wait().is_ok_and(|m| m.matching()));
        }
    }

    /// Whether the other host's router is connected; a change is logged.
    fn check_link(&mut self) {
        let connected = self
            .session
            .as_ref()
            .is_some_and(|s| s.info().routers_zid().wait().next().is_some());
        if connected != self.connected {
            self.connected = connected;
            if connected {
                println!("bridge: connected to {}", self.peer);
            } else {
                tracing::warn!("bridge: no link to {}", self.peer);
            }
        }
    }
}

impl Drop for BridgeRole {
    /// What crossed, per topic, for the log (`aeris bench hosts` reads it).
    fn drop(&mut self) {
        self.stop_opening.store(true, Ordering::Relaxed);
        let per_message = |ns: u64, n: u64| ns as f64 / 1e6 / n.max(1) as f64;
        for ex in &self.exports {
            print!(
                "bridge: sent `{}`: {} messages, {} bytes",
                ex.topic, ex.sent.0, ex.sent.1
            );
            if ex.raw_bytes != ex.sent.1 {
                print!(
                    " ({} bytes before coding; encoding {:.2} ms per message)",
                    ex.raw_bytes,
                    per_message(ex.encode_ns, ex.sent.0)
                );
            }
            println!();
        }
        for im in &self.imports {
            print!(
                "bridge: received `{}`: {} messages, {} bytes",
                im.topic, im.received.0, im.received.1
            );
            if im.decode_ns > 0 {
                print!(
                    " (decoding {:.2} ms per message)",
                    per_message(im.decode_ns, im.received.0)
                );
            }
            println!();
        }
        let cpu_s = process_cpu_s();
        let wall_s = monotonic_ns().saturating_sub(self.started_ns) as f64 / 1e9;
        println!(
            "bridge: used {:.2} s of CPU over {:.1} s ({:.1}% of one core, its link's TLS or TCP included)",
            cpu_s,
            wall_s,
            100.0 * cpu_s / wall_s.max(1e-9)
        );
    }
}

/// CPU time this process used so far (user and system, every thread; s).
fn process_cpu_s() -> f64 {
    // SAFETY: a zeroed rusage is a valid out-parameter; getrusage fills it.
    let mut u: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: `u` is alive and of the type getrusage writes.
    if unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut u) } != 0 {
        return 0.0;
    }
    let t = |tv: libc::timeval| tv.tv_sec as f64 + tv.tv_usec as f64 / 1e6;
    t(u.ru_utime) + t(u.ru_stime)
}
