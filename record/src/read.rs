//! Reading a recording back: the flight it holds ([`RecordedFlight`], from the MCAP
//! metadata record [`FLIGHT_METADATA`]) and its messages in log-time order, through the
//! file's index (a recording must have been closed: a recorder killed mid-flight leaves no
//! index, and its file is for Foxglove, not for replay).
//!
//! A recording made by another schema version, or with another payload layout, is refused
//! with an error naming both: its raw bytes would be read as something they are not.

use aeris_runtime::spec::{CameraSpec, TimingSpec};
use aeris_runtime::{MissionSpec, RoleSpec};
use aeris_schemas::{SCHEMA_LAYOUT_HASH, SCHEMA_VERSION, ZeroCopySend};
use mcap::sans_io::indexed_reader::{IndexedReadEvent, IndexedReader, IndexedReaderOptions};
use mcap::sans_io::summary_reader::{SummaryReadEvent, SummaryReader};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

/// Name of the MCAP metadata record that describes the recorded flight.
pub const FLIGHT_METADATA: &str = "aeris.flight";
/// Key of [`FLIGHT_METADATA`] holding the [`RecordedFlight`] as JSON.
const FLIGHT_KEY: &str = "flight.json";

/// A role of the recorded flight, as the flight library declared it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecordedRole {
    /// Instance name.
    pub name: String,
    /// Kind.
    pub kind: String,
    /// Variant it ran.
    pub variant: String,
    /// Variants it could be swapped to.
    #[serde(default)]
    pub variants: Vec<String>,
    /// Executor it was declared on.
    #[serde(default)]
    pub executor: Option<String>,
    /// Its parameters.
    #[serde(default)]
    pub params: serde_json::Map<String, serde_json::Value>,
}

/// The flight a recording holds: what a replay needs to run the same roles on it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecordedFlight {
    /// Flight name.
    pub flight: String,
    /// Schema version of the recorded payloads.
    pub schema_version: u32,
    /// Layout hash of the recorded payloads (`0x` and 16 hex digits).
    pub layout_hash: String,
    /// Flight timing.
    pub timing: TimingSpec,
    /// Camera geometry.
    pub camera: CameraSpec,
    /// The mission.
    pub mission: MissionSpec,
    /// The flight's roles (the recorder's `params.roles`).
    #[serde(default)]
    pub roles: Vec<RecordedRole>,
    /// The flight's executor names (the recorder's `params.executors`).
    #[serde(default)]
    pub executors: Vec<String>,
    /// Every frame is recorded exactly (`TOPIC/frame`): the recording can be replayed.
    #[serde(default)]
    pub exact_frames: bool,
}

/// The [`FLIGHT_METADATA`] record a recorder with `spec` writes.
pub fn flight_metadata(spec: &RoleSpec) -> BTreeMap<String, String> {
    let list = |key: &str| spec.params.get(key).cloned().unwrap_or_default();
    let flight = RecordedFlight {
        flight: spec.flight.clone(),
        schema_version: SCHEMA_VERSION,
        layout_hash: layout_hash(),
        timing: spec.timing.clone(),
        camera: spec.camera.clone(),
        mission: spec.mission.clone(),
        roles: serde_json::from_value(list("roles")).unwrap_or_default(),
        executors: serde_json::from_value(list("executors")).unwrap_or_default(),
        exact_frames: spec.param_str("frames") == Some("exact"),
    };
    let mut m = BTreeMap::new();
    m.insert("flight".into(), flight.flight.clone());
    m.insert("schema_version".into(), SCHEMA_VERSION.to_string());
    m.insert("layout_hash".into(), flight.layout_hash.clone());
    m.insert(
        FLIGHT_KEY.into(),
        serde_json::to_string(&flight).unwrap_or_default(),
    );
    m
}

fn layout_hash() -> String {
    format!("{SCHEMA_LAYOUT_HASH:#018x}")
}

/// Why a recording cannot be read back.
#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    /// The file could not be opened or read.
    #[error("reading {}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The file is not a well-formed MCAP file.
    #[error("{} is not a readable MCAP recording", path.display())]
    Mcap {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: mcap::McapError,
    },
    /// The file has no summary: its recorder did not close it.
    #[error(
        "{} has no index: its recorder did not close it (killed, or the disk filled); Foxglove \
         still opens it, a replay cannot",
        path.display()
    )]
    NotClosed {
        /// The file.
        path: PathBuf,
    },
    /// The file has no [`FLIGHT_METADATA`] record.
    #[error("{} holds no `{FLIGHT_METADATA}` record: it was not recorded by aeris `run --record`", path.display())]
    NoFlight {
        /// The file.
        path: PathBuf,
    },
    /// The [`FLIGHT_METADATA`] record does not parse.
    #[error("the `{FLIGHT_METADATA}` record of {} is not a flight", path.display())]
    BadFlight {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: serde_json::Error,
    },
    /// Recorded by another schema version.
    #[error(
        "{} was recorded with schema version s{recorded}; this aeris reads s{ours}: replay it \
         with the aeris that recorded it",
        path.display()
    )]
    SchemaVersion {
        /// The file.
        path: PathBuf,
        /// The recording's version.
        recorded: u32,
        /// This build's.
        ours: u32,
    },
    /// Same version number, other payload layout (a build of another commit).
    #[error(
        "{} was recorded with payload layout {recorded}; this aeris has {ours} (same schema \
         version s{version}, other build)",
        path.display()
    )]
    LayoutHash {
        /// The file.
        path: PathBuf,
        /// The recording's layout hash.
        recorded: String,
        /// This build's.
        ours: String,
        /// The schema version both have.
        version: u32,
    },
    /// A raw message is not the size of its payload type.
    #[error("a message on {topic} in {} has {len} bytes, not the {want} of its type", path.display())]
    BadMessage {
        /// The file.
        path: PathBuf,
        /// Its channel.
        topic: String,
        /// Its length.
        len: usize,
        /// The payload's size.
        want: usize,
    },
}

/// A closed recording, opened for reading.
pub struct Recording {
    path: PathBuf,
    file: File,
    summary: mcap::Summary,
    flight: RecordedFlight,
}

impl std::fmt::Debug for Recording {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Recording")
            .field("path", &self.path)
            .field("flight", &self.flight.flight)
            .finish_non_exhaustive()
    }
}

impl Recording {
    /// Open the recording at `path`: read its index and its flight, and refuse it when
    /// another schema version or payload layout recorded it.
    pub fn open(path: &Path) -> Result<Self, ReadError> {
        let io = |source| ReadError::Io {
            path: path.to_path_buf(),
            source,
        };
        let bad = |source| ReadError::Mcap {
            path: path.to_path_buf(),
            source,
        };
        let mut file = File::open(path).map_err(io)?;
        // a closed MCAP file ends with the magic; one cut short (its writer killed) does not
        let mut tail = [0u8; 8];
        let closed = file.seek(SeekFrom::End(-8)).is_ok()
            && file.read_exact(&mut tail).is_ok()
            && tail == *mcap::MAGIC;
        if !closed {
            return Err(ReadError::NotClosed {
                path: path.to_path_buf(),
            });
        }
        file.seek(SeekFrom::Start(0)).map_err(io)?;
        let mut reader = SummaryReader::new();
        while let Some(event) = reader.next_event() {
            match event.map_err(bad)? {
                SummaryReadEvent::ReadRequest(need) => {
                    let n = file.read(reader.insert(need)).map_err(io)?;
                    reader.notify_read(n);
                }
                SummaryReadEvent::SeekRequest(to) => {
                    reader.notify_seeked(file.seek(to).map_err(io)?);
                }
            }
        }
        let summary = reader.finish().ok_or_else(|| ReadError::NotClosed {
            path: path.to_path_buf(),
        })?;
        let index = summary
            .metadata_indexes
            .iter()
            .find(|m| m.name == FLIGHT_METADATA)
            .ok_or_else(|| ReadError::NoFlight {
                path: path.to_path_buf(),
            })?;
        let mut record = vec![0u8; index.length as usize];
        file.seek(SeekFrom::Start(index.offset)).map_err(io)?;
        file.read_exact(&mut record).map_err(io)?;
        // opcode (1 byte) and length (8 bytes) precede the record's body
        let metadata = match record.split_first() {
            Some((&op, rest)) if rest.len() >= 8 => {
                match mcap::parse_record(op, &rest[8..]).map_err(bad)? {
                    mcap::records::Record::Metadata(m) => m.metadata,
                    _ => BTreeMap::new(),
                }
            }
            _ => BTreeMap::new(),
        };
        let recorded_version = metadata
            .get("schema_version")
            .and_then(|v| v.parse::<u32>().ok());
        if let Some(v) = recorded_version
            && v != SCHEMA_VERSION
        {
            return Err(ReadError::SchemaVersion {
                path: path.to_path_buf(),
                recorded: v,
                ours: SCHEMA_VERSION,
            });
        }
        let json = metadata
            .get(FLIGHT_KEY)
            .ok_or_else(|| ReadError::NoFlight {
                path: path.to_path_buf(),
            })?;
        let flight: RecordedFlight =
            serde_json::from_str(json).map_err(|source| ReadError::BadFlight {
                path: path.to_path_buf(),
                source,
            })?;
        check_schema(path, flight.schema_version, &flight.layout_hash)?;
        Ok(Self {
            path: path.to_path_buf(),
            file,
            summary,
            flight,
        })
    }

    /// The recorded flight.
    pub fn flight(&self) -> &RecordedFlight {
        &self.flight
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Log times of the first and the last message (CLOCK_MONOTONIC ns of the recording
    /// machine).
    pub fn time_range(&self) -> Option<(u64, u64)> {
        self.summary
            .stats
            .as_ref()
            .map(|s| (s.message_start_time, s.message_end_time))
    }

    /// Number of messages on channel `topic`.
    pub fn message_count(&self, topic: &str) -> u64 {
        let Some(stats) = &self.summary.stats else {
            return 0;
        };
        self.summary
            .channels
            .iter()
            .filter(|(_, c)| c.topic == topic)
            .map(|(id, _)| stats.channel_message_counts.get(id).copied().unwrap_or(0))
            .sum()
    }

    /// Call `f(topic, log_time, data)` for every message on `topics` with a log time in
    /// `[from_ns, to_ns)`, in log-time order; `f` returns `false` to stop early.
    pub fn for_each(
        &mut self,
        topics: &[&str],
        from_ns: Option<u64>,
        to_ns: Option<u64>,
        mut f: impl FnMut(&str, u64, &[u8]) -> bool,
    ) -> Result<(), ReadError> {
        let path = self.path.clone();
        let io = |source| ReadError::Io {
            path: path.clone(),
            source,
        };
        let bad = |source| ReadError::Mcap {
            path: path.clone(),
            source,
        };
        let mut options = IndexedReaderOptions::new()
            .include_topics(topics.iter().map(|t| t.to_string()))
            .with_order(mcap::sans_io::indexed_reader::ReadOrder::LogTime);
        if let Some(t) = from_ns {
            options = options.starting_at(t);
        }
        if let Some(t) = to_ns {
            options = options.ending_before(t);
        }
        let mut reader = IndexedReader::new_with_options(&self.summary, options).map_err(bad)?;
        let mut buffer = Vec::new();
        while let Some(event) = reader.next_event() {
            match event.map_err(bad)? {
                IndexedReadEvent::ReadChunkRequest { offset, length } => {
                    self.file.seek(SeekFrom::Start(offset)).map_err(io)?;
                    buffer.resize(length, 0);
                    self.file.read_exact(&mut buffer).map_err(io)?;
                    reader
                        .insert_chunk_record_data(offset, &buffer)
                        .map_err(bad)?;
                }
                IndexedReadEvent::Message { header, data } => {
                    let topic = self
                        .summary
                        .channels
                        .get(&header.channel_id)
                        .map_or("", |c| c.topic.as_str());
                    if !f(topic, header.log_time, data) {
                        return Ok(());
                    }
                }
            }
        }
        Ok(())
    }

    /// Every message of `TOPIC/raw` as a `T`, in log-time order.
    pub fn typed<T: ZeroCopySend + Copy>(&mut self, topic: &str) -> Result<Vec<T>, ReadError> {
        let raw = format!("{topic}/raw");
        let mut out = Vec::new();
        let mut wrong = None;
        self.for_each(
            &[raw.as_str()],
            None,
            None,
            |_, _, data| match crate::codec::read::<T>(data) {
                Some(v) => {
                    out.push(v);
                    true
                }
                None => {
                    wrong = Some(data.len());
                    false
                }
            },
        )?;
        match wrong {
            Some(len) => Err(ReadError::BadMessage {
                path: self.path.clone(),
                topic: raw,
                len,
                want: size_of::<T>(),
            }),
            None => Ok(out),
        }
    }
}

/// Refuse a recording whose schema version or payload layout is not this build's.
pub fn check_schema(path: &Path, version: u32, layout: &str) -> Result<(), ReadError> {
    if version != SCHEMA_VERSION {
        return Err(ReadError::SchemaVersion {
            path: path.to_path_buf(),
            recorded: version,
            ours: SCHEMA_VERSION,
        });
    }
    if layout != layout_hash() {
        return Err(ReadError::LayoutHash {
            path: path.to_path_buf(),
            recorded: layout.to_string(),
            ours: layout_hash(),
            version,
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn another_schema_version_or_layout_is_refused_naming_both() {
        let p = Path::new("old.mcap");
        let e = check_schema(p, SCHEMA_VERSION - 1, &layout_hash()).unwrap_err();
        let text = e.to_string();
        assert!(
            text.contains(&format!("s{}", SCHEMA_VERSION - 1))
                && text.contains(&format!("s{SCHEMA_VERSION}")),
            "{text}"
        );
        let e = check_schema(p, SCHEMA_VERSION, "0x0000000000000001").unwrap_err();
        assert!(e.to_string().contains("0x0000000000000001"), "{e}");
        check_schema(p, SCHEMA_VERSION, &layout_hash()).unwrap();
    }

    /// An MCAP file at `path` with `metadata` as its `aeris.flight` record (none: no
    /// record), closed or cut before its summary.
    fn write(path: &Path, metadata: Option<BTreeMap<String, String>>, close: bool) {
        let file = std::io::BufWriter::new(File::create(path).unwrap());
        let mut out = mcap::WriteOptions::new()
            .compression(Some(mcap::Compression::Lz4))
            .create(file)
            .unwrap();
        if let Some(metadata) = metadata {
            out.write_metadata(&mcap::records::Metadata {
                name: FLIGHT_METADATA.into(),
                metadata,
            })
            .unwrap();
        }
        if close {
            out.finish().unwrap();
        } else {
            out.flush().unwrap();
            std::mem::forget(out);
        }
    }

    #[test]
    fn a_recording_opens_only_when_closed_described_and_of_this_schema() {
        let dir = tempfile::tempdir().unwrap();
        let spec = RoleSpec {
            flight: "f".into(),
            name: "recorder".into(),
            kind: aeris_schemas::RoleKind::Recorder,
            variant: "mcap".into(),
            cpus: String::new(),
            timing: TimingSpec::default(),
            camera: CameraSpec::default(),
            mission: MissionSpec {
                instruction: "land".into(),
                subgoals: Vec::new(),
                world: "village".into(),
                start: [0.0; 3],
                cruise_speed: 5.0,
                acceptance_radius_m: 2.0,
                max_duration_s: 60.0,
                limits: aeris_schemas::DecisionLimits::default(),
            },
            params: Default::default(),
            instance: 0,
            remote: None,
            heartbeat_pid: None,
            flight_clock_offset_ns: 0,
            clock: Default::default(),
            accelerator: None,
            vehicle: None,
        };
        let ours = flight_metadata(&spec);
        let good = dir.path().join("good.mcap");
        write(&good, Some(ours.clone()), true);
        let rec = Recording::open(&good).unwrap();
        assert_eq!(rec.flight().flight, "f");
        assert_eq!(rec.flight().schema_version, SCHEMA_VERSION);

        let mut older = ours.clone();
        older.insert("schema_version".into(), (SCHEMA_VERSION - 1).to_string());
        let old = dir.path().join("old.mcap");
        write(&old, Some(older), true);
        let e = Recording::open(&old).unwrap_err();
        assert!(
            matches!(e, ReadError::SchemaVersion { recorded, ours, .. }
                if recorded == SCHEMA_VERSION - 1 && ours == SCHEMA_VERSION),
            "{e}"
        );

        let bare = dir.path().join("bare.mcap");
        write(&bare, None, true);
        assert!(matches!(
            Recording::open(&bare),
            Err(ReadError::NoFlight { .. })
        ));

        let cut = dir.path().join("cut.mcap");
        write(&cut, Some(ours), false);
        let e = Recording::open(&cut).unwrap_err();
        assert!(matches!(e, ReadError::NotClosed { .. }), "{e}");

        let missing = dir.path().join("missing.mcap");
        assert!(matches!(
            Recording::open(&missing),
            Err(ReadError::Io { .. })
        ));
    }
}
