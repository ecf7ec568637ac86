//! # aeris-record
//!
//! The flight recorder (kind `recorder`, variant `mcap`): a role process like the others,
//! subscribed to every topic of the flight, that writes what it sees into an MCAP file.
//!
//! - Every typed message goes on two channels: `TOPIC` (message encoding `json`, schema
//!   encoding `jsonschema`, see [`codec`]) and `TOPIC/raw` (message encoding `aeris-raw`:
//!   the exact shared-memory bytes; schema named by the iceoryx2 type name, `aeris::X@sN`,
//!   with the schema version, layout hash, size and alignment as its data), so a replay can
//!   be bit-exact and refuses bytes of another layout.
//! - Frames: the header on `TOPIC` and `TOPIC/raw`; every `params.frame_every`-th frame
//!   (default [`DEFAULT_FRAME_EVERY`], 0 = none) also as a picture on `TOPIC/image`: a
//!   `foxglove.CompressedImage` (JPEG at `params.jpeg_quality`, default
//!   [`codec::DEFAULT_JPEG_QUALITY`]; depth as 16-bit PNG), or with `params.image = "raw"` a
//!   `foxglove.RawImage` (`rgb8`, or `16UC1` for depth). The writer thread encodes.
//! - The vehicle pose of every telemetry message also as a `foxglove.PoseInFrame` on
//!   `vehicle/telemetry/pose` (frame `map`, east-north-up), for Foxglove's 3D panel.
//! - With `params.frames = "exact"` (a recording for replay, [`read`]), every frame also
//!   goes on `TOPIC/frame`: its header bytes followed by its pixel bytes, exactly as in
//!   shared memory (LZ4 chunks keep that small), so `aeris replay` publishes the very
//!   frames the flight saw.
//! - The flight itself (schema version, timing, camera, mission, and the roles and
//!   executors the flight library passes as `params.roles` / `params.executors`) as the
//!   MCAP metadata record `aeris.flight` ([`read::FLIGHT_METADATA`]).
//! - Log and publish time: the message's own capture or publish stamp, CLOCK_MONOTONIC ns.
//!
//! It never slows the flight: its subscribers have bounded buffers that overwrite (no
//! publisher waits on it), its cycle only copies samples into preallocated slots, and a
//! writer thread does the JSON and the disk ([`writer`]). No free slot: the sample is
//! dropped and counted. A file that cannot be created or written (disk full): one error
//! line, status `Degraded`, recording stops, the role keeps running, the flight goes on
//! (a file-size limit, RLIMIT_FSIZE, too: SIGXFSZ is ignored, so the write fails instead).
//!
//! Files: `params.path`; when it exists already (a restarted recorder, after a crash or
//! SIGKILL), the next free `PATH.1`, `PATH.2`, ...: a restart never touches the file of an
//! earlier process, which stays readable up to its last complete chunk.
//!
//! Parameters: `path` (required), `frame_every`, `image` (`jpeg` or `raw`), `jpeg_quality`,
//! `frames` (`exact`), `roles`, `executors`, `topics` (default: every topic),
//! `period_ms` (drain period, default 10), `slots` (typed queue slots, default 4096).
//! Heartbeat counters: `[messages written, samples dropped, bytes written, failed (0/1),
//! samples received, file index (0 = PATH, n = PATH.n), 0, 0]`.

#![deny(missing_docs)]

pub mod codec;
pub mod read;
pub mod replay;
pub mod writer;

use aeris_runtime::bus::{BusError, FrameSubscriber};
use aeris_runtime::raw::{RawSubscriber, frame_subscriber, raw_subscriber};
use aeris_runtime::{CycleOutcome, CycleReport, Role, RoleContext, RoleError};
use aeris_schemas::kinds;
use aeris_schemas::{RecorderCounters, RoleStatus, topics};
use codec::{ImageFormat, Payload, PayloadCodec, bytes_of, payload_of};
use core::time::Duration;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::thread::JoinHandle;
use writer::{Counters, Queue, Slot, SlotKind, take};

/// Default: every 5th frame's pixels are recorded as an image.
pub const DEFAULT_FRAME_EVERY: u64 = 5;
/// Default number of typed queue slots.
pub const DEFAULT_SLOTS: usize = 4096;
/// Image queue slots.
pub const IMAGE_SLOTS: usize = 8;
/// Exact-frame queue slots (frames recorded for replay): a second of RGB and depth at 10
/// frames per second, and some.
pub const EXACT_SLOTS: usize = 32;

/// The file a recorder process writes: `path` when free, else the first free `path.N`.
pub fn next_free_path(path: &Path) -> (PathBuf, u64) {
    if !path.exists() {
        return (path.to_path_buf(), 0);
    }
    let mut n = 1u64;
    loop {
        let mut name = path.as_os_str().to_owned();
        name.push(format!(".{n}"));
        let candidate = PathBuf::from(name);
        if !candidate.exists() {
            return (candidate, n);
        }
        n += 1;
    }
}

/// Every file a recording at `path` has: `path`, then `path.1`, `path.2`, ... while they
/// exist (one per recorder process of the flight).
pub fn recording_files(path: &Path) -> Vec<PathBuf> {
    let mut files = Vec::new();
    if path.exists() {
        files.push(path.to_path_buf());
    }
    for n in 1.. {
        let mut name = path.as_os_str().to_owned();
        name.push(format!(".{n}"));
        let p = PathBuf::from(name);
        if !p.exists() {
            break;
        }
        files.push(p);
    }
    files
}

enum Source {
    Typed(Box<dyn RawSubscriber>),
    Frames { sub: FrameSubscriber, seen: u64 },
}

struct Input {
    payload: Payload,
    source: Source,
}

/// The recorder role (kind `recorder`, variant `mcap`).
pub struct RecorderRole {
    inputs: Vec<Input>,
    queue: Option<Queue>,
    writer: Option<JoinHandle<()>>,
    counters: Arc<Counters>,
    frame_every: u64,
    exact_frames: bool,
    period: Duration,
    dropped: u64,
    received: u64,
    file_index: u64,
}

fn subscribe(
    ctx: &RoleContext<kinds::Recorder>,
    topic: &str,
    payload: Payload,
) -> Result<Source, BusError> {
    Ok(match payload {
        Payload::Frame => Source::Frames {
            sub: frame_subscriber(ctx.bus.flight_bus(), topic)?,
            seen: 0,
        },
        _ => Source::Typed(raw_subscriber(ctx.bus.flight_bus(), topic)?),
    })
}

impl Role for RecorderRole {
    type Kind = kinds::Recorder;

    fn new(ctx: &mut RoleContext<kinds::Recorder>) -> Result<Self, RoleError> {
        let spec = &ctx.spec;
        let path = spec
            .param_str("path")
            .ok_or_else(|| RoleError::param("path", "is required"))?;
        let topic_names: Vec<String> = match spec.params.get("topics") {
            None => topics::ALL.iter().map(|t| t.to_string()).collect(),
            Some(v) => serde_json::from_value(v.clone())
                .map_err(|e| RoleError::param("topics", format!("is not a list of topics: {e}")))?,
        };
        let mut topics_in = Vec::with_capacity(topic_names.len());
        for t in topic_names {
            let payload = payload_of(&t)
                .ok_or_else(|| RoleError::param("topics", format!("names unknown topic `{t}`")))?;
            topics_in.push((t, payload));
        }
        let frame_every = match spec.params.get("frame_every") {
            None => DEFAULT_FRAME_EVERY,
            Some(v) => v.as_u64().ok_or_else(|| {
                RoleError::param(
                    "frame_every",
                    format!("= {v} is not a whole number of frames"),
                )
            })?,
        };
        let image_format = match (spec.param_str("image"), spec.params.get("jpeg_quality")) {
            (None | Some("jpeg"), None) => ImageFormat::default(),
            (None | Some("jpeg"), Some(q)) => match q.as_u64() {
                Some(q @ 1..=100) => ImageFormat::Compressed {
                    jpeg_quality: q as u8,
                },
                _ => {
                    return Err(RoleError::param(
                        "jpeg_quality",
                        format!("= {q} is not a whole number in 1..=100"),
                    ));
                }
            },
            (Some("raw"), _) => ImageFormat::Raw,
            (Some(other), _) => {
                return Err(RoleError::param(
                    "image",
                    format!("= {other:?} is neither \"jpeg\" nor \"raw\""),
                ));
            }
        };
        let exact_frames = match spec.param_str("frames") {
            None => false,
            Some("exact") => true,
            Some(other) => {
                return Err(RoleError::param(
                    "frames",
                    format!("= {other:?} is not \"exact\""),
                ));
            }
        };
        let period = Duration::from_millis(spec.param_f64("period_ms").unwrap_or(10.0) as u64)
            .max(Duration::from_millis(1));
        let slots = spec
            .param_f64("slots")
            .map_or(DEFAULT_SLOTS, |s| s.max(1.0) as usize);
        let typed_bytes = topics_in
            .iter()
            .map(|(_, p)| p.layout().0)
            .max()
            .unwrap_or(0);
        let image_bytes = spec.camera.width as usize * spec.camera.height as usize * 3;
        let mut inputs = Vec::with_capacity(topics_in.len());
        for (t, payload) in &topics_in {
            inputs.push(Input {
                payload: *payload,
                source: subscribe(ctx, t, *payload)?,
            });
        }
        // past a file-size limit (RLIMIT_FSIZE) a write fails with EFBIG instead of the
        // kernel killing the process: the recorder reports it like a full disk
        // SAFETY: signal() with a valid signal number and SIG_IGN has no preconditions.
        unsafe { libc::signal(libc::SIGXFSZ, libc::SIG_IGN) };
        let (path, file_index) = next_free_path(Path::new(path));
        let counters = Arc::new(Counters::default());
        let images = if frame_every > 0 { IMAGE_SLOTS } else { 0 };
        let exact = if exact_frames { EXACT_SLOTS } else { 0 };
        let pools = writer::Pools {
            typed: (slots, typed_bytes),
            images: (images, image_bytes),
            exact: (exact, image_bytes + size_of::<aeris_schemas::FrameHeader>()),
        };
        let flight = read::flight_metadata(spec);
        let (queue, writer) = match writer::start(
            &path,
            &topics_in,
            pools,
            image_format,
            Some(flight),
            counters.clone(),
        ) {
            Ok((q, w)) => (Some(q), Some(w)),
            Err(e) => {
                // the flight goes on without a recording: say so once, report Degraded
                tracing::warn!(
                    "recorder: {}; recording stopped, the flight goes on",
                    aeris_runtime::error_chain::chain(&e)
                );
                counters.failed.store(true, Ordering::SeqCst);
                (None, None)
            }
        };
        if queue.is_some() {
            tracing::info!("recorder: recording to {}", path.display());
        }
        Ok(Self {
            inputs,
            queue,
            writer,
            counters,
            frame_every,
            exact_frames,
            period,
            dropped: 0,
            received: 0,
            file_index,
        })
    }

    fn period(&self) -> Duration {
        self.period
    }

    fn cycle(
        &mut self,
        _ctx: &mut RoleContext<kinds::Recorder>,
        report: &mut CycleReport,
    ) -> Result<CycleOutcome, RoleError> {
        let failed = self.counters.failed.load(Ordering::SeqCst);
        let mut got = 0u64;
        let mut dropped = 0u64;
        for (index, input) in self.inputs.iter_mut().enumerate() {
            let payload = input.payload;
            match &mut input.source {
                Source::Typed(sub) => loop {
                    let mut push = |bytes: &[u8], _: &[u8], _| {
                        got += 1;
                        match self.queue.as_ref().filter(|_| !failed) {
                            Some(q) => match take(&q.free_typed) {
                                Some(slot) => enqueue_typed(q, slot, index, payload, bytes),
                                None => dropped += 1,
                            },
                            None => dropped += 1,
                        }
                    };
                    if !sub.next_raw(&mut push)? {
                        break;
                    }
                },
                Source::Frames { sub, seen } => {
                    while let Some(frame) = sub.next()? {
                        got += 1;
                        *seen += 1;
                        let Some(q) = self.queue.as_ref().filter(|_| !failed) else {
                            dropped += 1;
                            continue;
                        };
                        let header = frame.user_header();
                        match take(&q.free_typed) {
                            Some(slot) => enqueue_typed(q, slot, index, payload, bytes_of(header)),
                            None => dropped += 1,
                        }
                        if self.exact_frames {
                            match take(&q.free_exact) {
                                Some(mut slot) => {
                                    slot.topic = index;
                                    slot.kind = SlotKind::Exact;
                                    slot.stamp_ns = header.capture_ns;
                                    slot.bytes.clear();
                                    slot.bytes.extend_from_slice(bytes_of(header));
                                    slot.bytes.extend_from_slice(frame.payload());
                                    let _ = q.filled.try_send(slot);
                                }
                                None => dropped += 1,
                            }
                        }
                        if self.frame_every > 0 && (*seen - 1) % self.frame_every == 0 {
                            match take(&q.free_images) {
                                Some(mut slot) => {
                                    slot.topic = index;
                                    slot.kind = SlotKind::Image;
                                    slot.stamp_ns = header.capture_ns;
                                    slot.bytes.clear();
                                    slot.bytes.extend_from_slice(frame.payload());
                                    slot.header.clear();
                                    slot.header.extend_from_slice(bytes_of(header));
                                    let _ = q.filled.try_send(slot);
                                }
                                None => dropped += 1,
                            }
                        }
                    }
                }
            }
        }
        self.received += got;
        self.dropped += dropped;
        let failed = self.counters.failed.load(Ordering::SeqCst);
        report.counters = RecorderCounters {
            messages: self.counters.messages.load(Ordering::Relaxed),
            dropped: self.dropped,
            bytes: self.counters.bytes.load(Ordering::Relaxed),
            failed: u64::from(failed),
            received: self.received,
            file_index: self.file_index,
        }
        .to_heartbeat();
        report.status = if failed {
            RoleStatus::Degraded
        } else {
            RoleStatus::Running
        };
        Ok(if got > 0 {
            CycleOutcome::Worked
        } else {
            CycleOutcome::Idle
        })
    }

    fn shutdown(&mut self, _ctx: &mut RoleContext<kinds::Recorder>) {
        // closing the queue lets the writer write what is queued and finish the file
        self.queue = None;
        if let Some(w) = self.writer.take() {
            let _ = w.join();
        }
    }
}

/// Copy `bytes` into `slot` and queue it (the queue holds every slot: never full).
fn enqueue_typed(q: &Queue, mut slot: Slot, topic: usize, payload: Payload, bytes: &[u8]) {
    slot.topic = topic;
    slot.kind = SlotKind::Typed;
    slot.stamp_ns = payload.stamp_ns(bytes).unwrap_or(0);
    slot.bytes.clear();
    slot.bytes.extend_from_slice(bytes);
    let _ = q.filled.try_send(slot);
}
