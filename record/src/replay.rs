//! The replay source (kind `replay`, variant `mcap`): the camera and the vehicle of a
//! replayed flight are its recording.
//!
//! It publishes the recording's exact frames (`camera/rgb/frame`, `camera/depth/frame`)
//! and its telemetry (`vehicle/telemetry/raw`) on the live topics at their recorded times
//! (scaled by `params.speed`), while the roles under test (perception, reasoning, hub) run
//! live on them. Every stamp is moved onto this machine's clock by one offset
//! (`t' = start + (t - t0) / speed`), so the hub measures cycle times as in a live flight and the
//! replayed decisions pair with the recorded ones by the capture time of their frame.
//!
//! It starts publishing once every other role of the flight reports itself running (read
//! from the supervisor's status board; after ten seconds it names the ones it waits for),
//! so no role misses the first frames; it starts at `params.from_ns` (recording clock;
//! default: its first message) and ends before `params.to_ns`. The telemetry of
//! `params.lead_ns` before the start is published at once, so the first frame has the
//! vehicle's state at its capture. With `params.align_ns` the start is chosen so that the
//! offset between the clocks is a whole number of `align_ns` (scaled): the model roles,
//! which keep the first frame of every interval of the clock, then keep the same frames as
//! in the recording. A reader thread reads the file ahead through a bounded queue whose
//! buffers are reused: the cycle only copies bytes into shared memory, at most one frame per
//! camera topic and [`TELEMETRY_PER_CYCLE`] telemetry messages per cycle (the camera
//! topics buffer two frames: a burst would overwrite them).
//!
//! Parameters: `path` (required), `from_ns`, `to_ns`, `lead_ns`, `align_ns`, `speed`
//! (default 1).
//! Heartbeat counters: [`aeris_schemas::ReplayCounters`].

use crate::read::{ReadError, Recording};
use aeris_runtime::bus::{FramePublisher, TypedPublisher};
use aeris_runtime::clock::monotonic_ns;
use aeris_runtime::{ConfigError, CycleOutcome, CycleReport, Role, RoleContext, RoleError};
use aeris_schemas::kinds;
use aeris_schemas::{FrameHeader, ReplayCounters, RoleStatus, VehicleTelemetry, topics};
use core::time::Duration;
use std::path::PathBuf;
use std::sync::mpsc::{Receiver, SyncSender, TryRecvError};
use std::thread::JoinHandle;

/// Telemetry messages published per cycle at most.
pub const TELEMETRY_PER_CYCLE: u32 = 16;
/// After this long waiting for the other roles, the source says which it waits for.
const WAIT_NOTE_NS: u64 = 10_000_000_000;

/// The recording's channels the source publishes from.
const CHANNELS: [&str; 3] = [
    "camera/rgb/frame",
    "camera/depth/frame",
    "vehicle/telemetry/raw",
];
/// Index of the telemetry in [`CHANNELS`].
const TELEMETRY: usize = 2;
/// Messages read ahead.
const READ_AHEAD: usize = 64;
/// Cycle period.
const PERIOD: Duration = Duration::from_millis(2);
/// How often the status board is read while waiting for the other roles.
const WAIT_POLL_NS: u64 = 50_000_000;

/// One message read ahead.
struct Item {
    channel: usize,
    log_time: u64,
    bytes: Vec<u8>,
}

/// The replay source role.
pub struct ReplaySource {
    rgb: FramePublisher,
    depth: FramePublisher,
    telemetry: TypedPublisher<VehicleTelemetry>,
    items: Receiver<Item>,
    recycle: SyncSender<Vec<u8>>,
    reader: Option<JoinHandle<Result<(), ReadError>>>,
    next: Option<Item>,
    /// Recording time of the start.
    t0_rec: u64,
    /// This machine's time of the start (`None` while waiting for the roles).
    t0_wall: Option<u64>,
    next_wait_poll: u64,
    /// When the wait for the other roles began, and whether it was reported.
    waiting_since: Option<(u64, bool)>,
    align_ns: u64,
    speed: f64,
    done: bool,
    frames: u64,
    telemetry_count: u64,
    late_max_us: u64,
    failed: bool,
}

impl ReplaySource {
    /// `t` of the recording on this machine's clock (earlier than the start for the
    /// telemetry read ahead of it).
    fn wall(&self, t: u64, t0_wall: u64) -> u64 {
        let since = (t as f64 - self.t0_rec as f64) / self.speed;
        (t0_wall as f64 + since).max(0.0) as u64
    }

    /// The roles of the flight, other than this one, that are not yet built and running (a
    /// `Starting` heartbeat comes before their ports exist); `None` before the supervisor's
    /// status board is readable. Only called while waiting to start.
    fn not_running(ctx: &RoleContext<kinds::Replay>) -> Option<Vec<String>> {
        let board = ctx.bus.read_status_board().ok()?;
        let n = (board.role_count as usize).min(board.roles.len());
        if n == 0 {
            return None;
        }
        Some(
            board.roles[..n]
                .iter()
                .filter(|r| r.name.as_str() != Some(ctx.spec.name.as_str()))
                .filter(|r| {
                    !matches!(
                        RoleStatus::from_u8(r.status),
                        Some(RoleStatus::Running | RoleStatus::Degraded)
                    )
                })
                .map(|r| r.name.as_str().unwrap_or("?").to_string())
                .collect(),
        )
    }

    /// The start on this machine's clock, at or after `now`: `now`, or with `align_ns` the
    /// first instant whose scaled offset from the recording's start is a whole number of
    /// `align_ns`.
    fn start_at(&self, now: u64) -> u64 {
        if self.align_ns == 0 {
            return now;
        }
        let (a, t0, s) = (self.align_ns as f64, self.t0_rec as f64, self.speed);
        let k = ((now as f64 * s - t0) / a).ceil();
        (((t0 + k * a) / s).round() as u64).max(now)
    }

    fn publish(&mut self, item: &Item, t0_wall: u64) -> Result<(), RoleError> {
        match item.channel {
            0 | 1 => {
                let h = size_of::<FrameHeader>();
                let Some(mut header) = item
                    .bytes
                    .get(..h)
                    .and_then(crate::codec::read::<FrameHeader>)
                else {
                    return Ok(());
                };
                header.capture_ns = self.wall(header.capture_ns, t0_wall);
                let pixels = &item.bytes[h..];
                let publisher = if item.channel == 0 {
                    &self.rgb
                } else {
                    &self.depth
                };
                publisher.publish_with(&header, pixels.len(), |out| out.copy_from_slice(pixels))?;
                self.frames += 1;
            }
            _ => {
                let Some(mut t) = crate::codec::read::<VehicleTelemetry>(&item.bytes) else {
                    return Ok(());
                };
                t.stamp_ns = self.wall(t.stamp_ns, t0_wall);
                self.telemetry.publish(&t)?;
                self.telemetry_count += 1;
            }
        }
        Ok(())
    }
}

/// Read `path`'s replayed channels in `[from, to)` into `items` (and the telemetry from
/// `lead` before `from`), reusing the buffers that come back on `recycle`.
fn read_ahead(
    mut recording: Recording,
    (from, lead, to): (u64, u64, Option<u64>),
    items: SyncSender<Item>,
    recycle: Receiver<Vec<u8>>,
) -> Result<(), ReadError> {
    let early = Some(from.saturating_sub(lead));
    recording.for_each(&CHANNELS, early, to, |topic, log_time, data| {
        let Some(channel) = CHANNELS.iter().position(|c| *c == topic) else {
            return true;
        };
        if channel != TELEMETRY && log_time < from {
            return true;
        }
        let mut bytes = recycle.try_recv().unwrap_or_default();
        bytes.clear();
        bytes.extend_from_slice(data);
        // the role gone: stop reading
        items
            .send(Item {
                channel,
                log_time,
                bytes,
            })
            .is_ok()
    })
}

impl Role for ReplaySource {
    type Kind = kinds::Replay;

    fn new(ctx: &mut RoleContext<kinds::Replay>) -> Result<Self, RoleError> {
        let spec = &ctx.spec;
        let path = PathBuf::from(
            spec.param_str("path")
                .ok_or_else(|| RoleError::param("path", "is required"))?,
        );
        let speed = spec.param_f64("speed").unwrap_or(1.0);
        if !(speed.is_finite() && speed > 0.0) {
            return Err(RoleError::param(
                "speed",
                format!("= {speed} is not a positive number"),
            ));
        }
        let bound = |key: &str| spec.params.get(key).and_then(|v| v.as_u64());
        let (lead, align_ns) = (
            bound("lead_ns").unwrap_or(0),
            bound("align_ns").unwrap_or(0),
        );
        let recording =
            Recording::open(&path).map_err(|e| ConfigError::param_refused("path", e))?;
        if !recording.flight().exact_frames {
            return Err(RoleError::param(
                "path",
                format!(
                    "= {} holds no exact frames (recorded with --record-no-exact-frames)",
                    path.display()
                ),
            ));
        }
        let start = recording.time_range().map_or(0, |r| r.0);
        let t0_rec = bound("from_ns").unwrap_or(start).max(start);
        let to = bound("to_ns");
        let frame_bytes = spec.camera.width as usize * spec.camera.height as usize * 3;
        let (items_tx, items) = std::sync::mpsc::sync_channel(READ_AHEAD);
        let (recycle, recycle_rx) = std::sync::mpsc::sync_channel(READ_AHEAD + 2);
        let reader = std::thread::Builder::new()
            .name("replay reader".into())
            .spawn(move || read_ahead(recording, (t0_rec, lead, to), items_tx, recycle_rx))
            .map_err(|e| RoleError::step("starting the replay reader", e))?;
        Ok(Self {
            rgb: ctx.bus.frame_publisher::<topics::CameraRgb>(frame_bytes)?,
            depth: ctx
                .bus
                .frame_publisher::<topics::CameraDepth>(frame_bytes)?,
            telemetry: ctx.bus.publisher::<topics::VehicleTelemetry>()?,
            items,
            recycle,
            reader: Some(reader),
            next: None,
            t0_rec,
            t0_wall: None,
            next_wait_poll: 0,
            waiting_since: None,
            align_ns,
            speed,
            done: false,
            frames: 0,
            telemetry_count: 0,
            late_max_us: 0,
            failed: false,
        })
    }

    fn period(&self) -> Duration {
        PERIOD
    }

    fn cycle(
        &mut self,
        ctx: &mut RoleContext<kinds::Replay>,
        report: &mut CycleReport,
    ) -> Result<CycleOutcome, RoleError> {
        let now = monotonic_ns();
        let t0_wall = match self.t0_wall {
            Some(t) => t,
            None => {
                ReplayCounters::update(&mut report.counters, |c| {
                    c.waiting = 1;
                    c.start = self.t0_rec;
                });
                if now < self.next_wait_poll {
                    return Ok(CycleOutcome::Idle);
                }
                self.next_wait_poll = now + WAIT_POLL_NS;
                // on simulated time the flight's time first moves once every role is built,
                // so every role is up at this first turn: asking the supervisor's board, which
                // it writes on the wall clock, would make the start depend on when it did
                let up = if aeris_runtime::clock::simulated() {
                    Some(Vec::new())
                } else {
                    Self::not_running(ctx)
                };
                match up {
                    Some(waiting) if waiting.is_empty() => {
                        let t = self.start_at(now);
                        self.t0_wall = Some(t);
                        tracing::info!(
                            "replay: every role is up; replaying from {:.3} s of the recording \
                             in {:.0} ms",
                            self.t0_rec as f64 / 1e9,
                            t.saturating_sub(now) as f64 / 1e6
                        );
                        t
                    }
                    waiting => {
                        let (since, said) = *self.waiting_since.get_or_insert((now, false));
                        if !said && now.saturating_sub(since) >= WAIT_NOTE_NS {
                            self.waiting_since = Some((since, true));
                            tracing::info!(
                                "replay: still waiting for {} to run before replaying",
                                waiting.map_or_else(
                                    || "the supervisor's status board".to_string(),
                                    |w| w.join(", ")
                                )
                            );
                        }
                        return Ok(CycleOutcome::Idle);
                    }
                }
            }
        };
        let mut worked = false;
        let (mut rgb, mut depth, mut telemetry) = (0u32, 0u32, 0u32);
        while !self.done {
            let item = match self.next.take() {
                Some(item) => item,
                None => match self.items.try_recv() {
                    Ok(item) => item,
                    Err(TryRecvError::Empty) => break,
                    Err(TryRecvError::Disconnected) => {
                        self.done = true;
                        match self.reader.take().map(|r| r.join()) {
                            Some(Ok(Ok(()))) | None => {}
                            Some(Ok(Err(e))) => {
                                self.failed = true;
                                tracing::warn!(
                                    "replay: the recording ended early: {}",
                                    aeris_runtime::error_chain::chain(&e)
                                );
                            }
                            Some(Err(_)) => {
                                self.failed = true;
                                tracing::warn!(
                                    "replay: the recording's reader failed (it panicked)"
                                );
                            }
                        }
                        break;
                    }
                },
            };
            let due = self.wall(item.log_time, t0_wall);
            // one frame per camera topic per cycle: the subscribers buffer two
            let count = match item.channel {
                0 => &mut rgb,
                1 => &mut depth,
                _ => &mut telemetry,
            };
            let cap = if item.channel == TELEMETRY {
                TELEMETRY_PER_CYCLE
            } else {
                1
            };
            if due > now || *count >= cap {
                self.next = Some(item);
                break;
            }
            *count += 1;
            // the telemetry read ahead of the start is due at the start, not late
            self.late_max_us = self
                .late_max_us
                .max(now.saturating_sub(due.max(t0_wall)) / 1000);
            self.publish(&item, t0_wall)?;
            worked = true;
            let _ = self.recycle.try_send(item.bytes);
        }
        report.counters = ReplayCounters {
            frames: self.frames,
            telemetry: self.telemetry_count,
            done: u64::from(self.done),
            late_max_us: self.late_max_us,
            waiting: 0,
            offset: (self.t0_rec as i64).wrapping_sub(t0_wall as i64) as u64,
            start: self.t0_rec,
            started: 1,
        }
        .to_heartbeat();
        report.status = if self.failed {
            RoleStatus::Degraded
        } else {
            RoleStatus::Running
        };
        Ok(if worked {
            CycleOutcome::Worked
        } else {
            CycleOutcome::Idle
        })
    }
}
