//! The recorder's queue and its writer thread.
//!
//! The role's drain loop never waits on the disk: it takes a preallocated [`Slot`] from a
//! free list, copies a sample into it and hands it to the writer thread; with no free slot
//! the sample is dropped and counted. The writer thread turns slots into MCAP messages
//! (JSON and raw bytes), gives the slots back, and ends every chunk at least every
//! [`FLUSH_EVERY`] so a killed recorder leaves a file readable up to its last chunk.

use crate::codec::{
    ImageFormat, Payload, PayloadCodec, compressed_image_json, encode_frame, pose_in_frame_schema,
    raw_image_json,
};
use mcap::records::MessageHeader;
use serde_json::Value;
use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Longest time a written message waits in an open chunk.
pub const FLUSH_EVERY: Duration = Duration::from_millis(250);
/// Chunk size (bytes): small, so chunks end often even without [`FLUSH_EVERY`].
pub const CHUNK_SIZE: u64 = 64 * 1024;

/// What a slot holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SlotKind {
    /// A typed payload (or a frame header): JSON and raw channels.
    Typed,
    /// A frame's pixels, with its header in `header`: the image channel.
    Image,
    /// A frame's header bytes followed by its pixel bytes, exactly as in shared memory:
    /// the `TOPIC/frame` channel a replay publishes from.
    Exact,
}

/// One queued sample; its buffer is allocated once and reused.
#[derive(Debug)]
pub struct Slot {
    /// Index of the topic in the recorder's topic list.
    pub topic: usize,
    /// What it holds.
    pub kind: SlotKind,
    /// Log time (CLOCK_MONOTONIC ns).
    pub stamp_ns: u64,
    /// The payload bytes (pixels, for an image).
    pub bytes: Vec<u8>,
    /// The frame header bytes, for an image.
    pub header: Vec<u8>,
}

impl Slot {
    fn with_capacity(bytes: usize, header: usize) -> Self {
        Self {
            topic: 0,
            kind: SlotKind::Typed,
            stamp_ns: 0,
            bytes: Vec::with_capacity(bytes),
            header: Vec::with_capacity(header),
        }
    }
}

/// Counters the writer thread and the role share (the role's heartbeat reports them).
#[derive(Debug, Default)]
pub struct Counters {
    /// MCAP messages written.
    pub messages: AtomicU64,
    /// Bytes of message data written.
    pub bytes: AtomicU64,
    /// The writer failed: recording stopped (the flight goes on).
    pub failed: AtomicBool,
}

/// Why a recording cannot be written.
#[derive(Debug, thiserror::Error)]
pub enum WriteError {
    /// The file could not be created.
    #[error("creating {}", path.display())]
    Create {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The MCAP writer failed (a full or vanished disk).
    #[error("writing {}", path.display())]
    Mcap {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: mcap::McapError,
    },
}

/// One topic's channels in the file.
struct Channels {
    payload: Payload,
    json: u16,
    raw: u16,
    image: Option<u16>,
    /// `TOPIC/pose` (`foxglove.PoseInFrame`), for the telemetry.
    pose: Option<u16>,
    /// `TOPIC/frame` (header and pixels, exact), for frames when recorded for replay.
    exact: Option<u16>,
    sequence: u32,
}

/// The pools of free slots and the queue to the writer.
pub struct Queue {
    /// Free typed slots.
    pub free_typed: Receiver<Slot>,
    /// Free image slots.
    pub free_images: Receiver<Slot>,
    /// Free exact-frame slots (none unless frames are recorded for replay).
    pub free_exact: Receiver<Slot>,
    /// Filled slots to the writer (never full: it holds every slot there is).
    pub filled: SyncSender<Slot>,
}

/// The slot pools of a recording: how many slots of how many bytes each.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Pools {
    /// Typed messages (and frame headers).
    pub typed: (usize, usize),
    /// Frames as pictures (`TOPIC/image`).
    pub images: (usize, usize),
    /// Frames exact (`TOPIC/frame`); 0 slots: the channel is not written.
    pub exact: (usize, usize),
}

/// Start the writer thread on a new MCAP file at `path` recording `topics` (each with its
/// payload); every slot of `pools` is allocated now. `flight` (if any) is written first as
/// the MCAP metadata record `aeris.flight` ([`crate::read::FLIGHT_METADATA`]).
pub fn start(
    path: &Path,
    topics: &[(String, Payload)],
    pools: Pools,
    image_format: ImageFormat,
    flight: Option<BTreeMap<String, String>>,
    counters: Arc<Counters>,
) -> Result<(Queue, JoinHandle<()>), WriteError> {
    let Pools {
        typed,
        images,
        exact,
    } = pools;
    let file = File::create(path).map_err(|source| WriteError::Create {
        path: path.to_path_buf(),
        source,
    })?;
    let mcap_err = |source| WriteError::Mcap {
        path: path.to_path_buf(),
        source,
    };
    let mut out = mcap::WriteOptions::new()
        .compression(Some(mcap::Compression::Lz4))
        .chunk_size(Some(CHUNK_SIZE))
        .profile("")
        .library(concat!("aeris-record ", env!("CARGO_PKG_VERSION")))
        .create(BufWriter::new(file))
        .map_err(mcap_err)?;
    if let Some(metadata) = flight {
        out.write_metadata(&mcap::records::Metadata {
            name: crate::read::FLIGHT_METADATA.into(),
            metadata,
        })
        .map_err(mcap_err)?;
    }
    let mut channels = Vec::with_capacity(topics.len());
    let none = BTreeMap::new();
    let image_schema = image_format.schema().to_string();
    for (topic, payload) in topics {
        let json_schema = payload.json_schema().to_string();
        let sid = out
            .add_schema(
                &payload.json_schema_name(),
                "jsonschema",
                json_schema.as_bytes(),
            )
            .map_err(mcap_err)?;
        let json = out
            .add_channel(sid, topic, "json", &none)
            .map_err(mcap_err)?;
        let raw_schema = payload.raw_schema().to_string();
        let rid = out
            .add_schema(payload.type_name(), "aeris-layout", raw_schema.as_bytes())
            .map_err(mcap_err)?;
        let raw = out
            .add_channel(rid, &format!("{topic}/raw"), "aeris-raw", &none)
            .map_err(mcap_err)?;
        // a JSON side channel `{topic}/{suffix}` with its own schema
        let mut side = |suffix: &str, name: &str, schema: &str| {
            let id = out
                .add_schema(name, "jsonschema", schema.as_bytes())
                .map_err(mcap_err)?;
            out.add_channel(id, &format!("{topic}/{suffix}"), "json", &none)
                .map_err(mcap_err)
        };
        let image = match payload {
            Payload::Frame => Some(side("image", image_format.schema_name(), &image_schema)?),
            _ => None,
        };
        let pose = match payload {
            Payload::Telemetry => Some(side(
                "pose",
                "foxglove.PoseInFrame",
                &pose_in_frame_schema().to_string(),
            )?),
            _ => None,
        };
        let exact_channel = match payload {
            Payload::Frame if exact.0 > 0 => {
                let id = out
                    .add_schema(
                        &format!("{}+pixels", payload.type_name()),
                        "aeris-layout",
                        raw_schema.as_bytes(),
                    )
                    .map_err(mcap_err)?;
                Some(
                    out.add_channel(id, &format!("{topic}/frame"), "aeris-raw", &none)
                        .map_err(mcap_err)?,
                )
            }
            _ => None,
        };
        channels.push(Channels {
            payload: *payload,
            json,
            raw,
            image,
            pose,
            exact: exact_channel,
            sequence: 0,
        });
    }
    out.flush().map_err(mcap_err)?;

    let (free_typed_tx, free_typed) = std::sync::mpsc::sync_channel(typed.0);
    let (free_images_tx, free_images) = std::sync::mpsc::sync_channel(images.0);
    let (free_exact_tx, free_exact) = std::sync::mpsc::sync_channel(exact.0);
    let (filled, filled_rx) = std::sync::mpsc::sync_channel(typed.0 + images.0 + exact.0);
    for _ in 0..typed.0 {
        let _ = free_typed_tx.send(Slot::with_capacity(typed.1, 0));
    }
    for _ in 0..images.0 {
        let _ = free_images_tx.send(Slot::with_capacity(images.1, typed.1));
    }
    for _ in 0..exact.0 {
        let _ = free_exact_tx.send(Slot::with_capacity(exact.1, 0));
    }
    let mut thread = WriterThread {
        path: path.to_path_buf(),
        out,
        channels,
        topics: topics.iter().map(|(t, _)| t.clone()).collect(),
        counters,
        free_typed: free_typed_tx,
        free_images: free_images_tx,
        free_exact: free_exact_tx,
        image_format,
        encoded: Vec::with_capacity(images.1),
        encode_failed: false,
    };
    let handle = std::thread::Builder::new()
        .name("recorder writer".into())
        .spawn(move || thread.run(filled_rx))
        .map_err(|source| WriteError::Create {
            path: path.to_path_buf(),
            source,
        })?;
    Ok((
        Queue {
            free_typed,
            free_images,
            free_exact,
            filled,
        },
        handle,
    ))
}

struct WriterThread {
    path: PathBuf,
    out: mcap::Writer<BufWriter<File>>,
    channels: Vec<Channels>,
    topics: Vec<String>,
    counters: Arc<Counters>,
    free_typed: SyncSender<Slot>,
    free_images: SyncSender<Slot>,
    free_exact: SyncSender<Slot>,
    image_format: ImageFormat,
    /// The encoded picture, reused.
    encoded: Vec<u8>,
    /// An encoder failure was reported (once).
    encode_failed: bool,
}

impl WriterThread {
    /// Write until every sender is gone (the role stopped), then finish the file; on the
    /// first failure say so once, mark the counters failed and stop writing.
    fn run(&mut self, filled: Receiver<Slot>) {
        let mut last_flush = Instant::now();
        let result = loop {
            let slot = match filled.recv_timeout(FLUSH_EVERY) {
                Ok(slot) => Some(slot),
                Err(RecvTimeoutError::Timeout) => None,
                Err(RecvTimeoutError::Disconnected) => break self.out.finish().map(|_| ()),
            };
            if let Some(slot) = slot {
                let written = self.write(&slot);
                let pool = self.pool(slot.kind);
                // the role may be gone already: a slot with nowhere to go is just freed
                let _ = pool.try_send(slot);
                if let Err(e) = written {
                    break Err(e);
                }
            }
            if last_flush.elapsed() >= FLUSH_EVERY {
                last_flush = Instant::now();
                if let Err(e) = self.out.flush() {
                    break Err(e);
                }
            }
        };
        if let Err(source) = result {
            self.counters.failed.store(true, Ordering::SeqCst);
            let e = WriteError::Mcap {
                path: self.path.clone(),
                source,
            };
            tracing::warn!(
                "recorder: {}; recording stopped, the flight goes on",
                aeris_runtime::error_chain::chain(&e)
            );
            // keep returning slots so the role's drain loop sees a steady state, not a leak
            while let Ok(slot) = filled.recv() {
                let _ = self.pool(slot.kind).try_send(slot);
            }
        }
    }

    /// The free list a slot of `kind` goes back to.
    fn pool(&self, kind: SlotKind) -> &SyncSender<Slot> {
        match kind {
            SlotKind::Typed => &self.free_typed,
            SlotKind::Image => &self.free_images,
            SlotKind::Exact => &self.free_exact,
        }
    }

    fn write(&mut self, slot: &Slot) -> Result<(), mcap::McapError> {
        let ch = &mut self.channels[slot.topic];
        let mut put = |out: &mut mcap::Writer<BufWriter<File>>, channel_id, data: &[u8]| {
            ch.sequence = ch.sequence.wrapping_add(1);
            let header = MessageHeader {
                channel_id,
                sequence: ch.sequence,
                log_time: slot.stamp_ns,
                publish_time: slot.stamp_ns,
            };
            out.write_to_known_channel(&header, data)?;
            self.counters.messages.fetch_add(1, Ordering::Relaxed);
            self.counters
                .bytes
                .fetch_add(data.len() as u64, Ordering::Relaxed);
            Ok::<(), mcap::McapError>(())
        };
        match slot.kind {
            SlotKind::Typed => {
                let json = ch.payload.to_json(&slot.bytes).unwrap_or(Value::Null);
                let text = json.to_string();
                let (json_id, raw_id) = (ch.json, ch.raw);
                put(&mut self.out, json_id, text.as_bytes())?;
                put(&mut self.out, raw_id, &slot.bytes)?;
                if let (Some(pose_id), Some(pose)) = (ch.pose, ch.payload.to_pose_json(&slot.bytes))
                {
                    put(&mut self.out, pose_id, pose.to_string().as_bytes())?;
                }
            }
            SlotKind::Exact => {
                if let Some(id) = ch.exact {
                    put(&mut self.out, id, &slot.bytes)?;
                }
            }
            SlotKind::Image => {
                let Some(image_id) = ch.image else {
                    return Ok(());
                };
                let Some(header) = read_header(&slot.header) else {
                    return Ok(());
                };
                let frame_id = &self.topics[slot.topic];
                let image = match self.image_format {
                    ImageFormat::Raw => raw_image_json(frame_id, &header, &slot.bytes),
                    ImageFormat::Compressed { jpeg_quality } => {
                        match encode_frame(&header, &slot.bytes, jpeg_quality, &mut self.encoded) {
                            Ok(format) => {
                                compressed_image_json(frame_id, &header, format, &self.encoded)
                            }
                            Err(e) => {
                                // the frame's header and raw bytes are recorded; its picture
                                // is not (said once)
                                if !self.encode_failed {
                                    self.encode_failed = true;
                                    tracing::warn!(
                                        "recorder: a frame of {frame_id} was not recorded as \
                                         an image: {}",
                                        aeris_runtime::error_chain::chain(&e)
                                    );
                                }
                                return Ok(());
                            }
                        }
                    }
                };
                put(&mut self.out, image_id, image.to_string().as_bytes())?;
            }
        }
        Ok(())
    }
}

fn read_header(bytes: &[u8]) -> Option<aeris_schemas::FrameHeader> {
    (bytes.len() == size_of::<aeris_schemas::FrameHeader>())
        // SAFETY: the length is that of the header, a plain `#[repr(C)]` type of integers
        // and floats; the read is unaligned-safe.
        .then(|| unsafe {
            core::ptr::read_unaligned(bytes.as_ptr().cast::<aeris_schemas::FrameHeader>())
        })
}

/// A free slot of `pool`, if any (none: the sample is dropped).
pub fn take(pool: &Receiver<Slot>) -> Option<Slot> {
    pool.try_recv().ok()
}
