//! A real camera through GStreamer (kind `camera`, variant `gstreamer`).
//!
//! Parameters:
//! - `pipeline` (required): a GStreamer pipeline (`gst-launch-1.0` syntax) ending in an
//!   `appsink`, e.g. `v4l2src ! appsink sync=false`, or the H.264 RTP stream of
//!   `aeris scene video --follow`:
//!   `udpsrc port=5600 caps="application/x-rtp,media=video,clock-rate=90000,encoding-name=H264,payload=96" ! rtph264depay ! avdec_h264 ! appsink sync=false`.
//!   Frames are converted and scaled to RGB at the workflow's `[camera]` size
//!   (see [`aeris_video::capture`] for the rule);
//! - `depth_pipeline` (optional): the same for a depth camera, GRAY16_LE millimetres, published
//!   on `camera/depth`. Without it no depth is published at all (nothing made up);
//! - `stall_ms` (default 1000): no frame for this long is a stall;
//! - `poll_ms` (default 2): the cycle period. Each cycle takes the newest frame without
//!   waiting, so a frame waits at most one period in the appsink (the role's heartbeat latency
//!   stays the cost of copying and publishing, not of waiting for the camera).
//!
//! Each RGB frame is published on `camera/rgb` (the service of `sim-render`, same
//! [`FrameHeader`] semantics): `seq` from 1, `capture_ns` = the buffer's capture time on
//! CLOCK_MONOTONIC (its PTS through the pipeline clock), the pose = the vehicle's pose
//! interpolated from `vehicle/telemetry` at that time ([`pose_ring`]; the mission start, yaw 0
//! before the first telemetry) with the camera [`CAMERA_MOUNT_HEIGHT_M`] above it, the
//! workflow's field of view. The frame is copied once, from GStreamer's buffer into the
//! loaned shared-memory sample. With `depth_pipeline`, the newest depth frame at that moment
//! (waiting at most one camera period for one) goes out on `camera/depth` with the same header
//! (format aside), so consumers pair the two by `seq` as they do `sim-render`'s; an RGB frame
//! with no depth frame ready has no depth partner.
//!
//! Failures never end the role: an error or end of stream of either pipeline is logged with
//! GStreamer's text, the pipeline is stopped and restarted after a back-off (250 ms, doubling
//! up to 8 s, back to 250 ms after the next frame); a stall (no frame for `stall_ms`) is
//! logged and waited out (a live source resumes by itself). While a pipeline is down or
//! stalled the heartbeat says `degraded`; frames are published again as soon as they come.
//!
//! Heartbeat counters: [`CameraCounters`]. Stages: `publish`, `depth`.

pub mod pose_ring;

use aeris_geometry::CAMERA_MOUNT_HEIGHT_M;
use aeris_runtime::bus::{FramePublisher, TypedSubscriber};
use aeris_runtime::clock::monotonic_ns;
use aeris_runtime::error_chain::chain;
use aeris_runtime::{
    ConfigError, CycleOutcome, CycleReport, Role, RoleContext, RoleError, RoleSpec,
};
use aeris_schemas::kinds;
use aeris_schemas::{
    CameraCounters, FrameFormat, FrameHeader, RoleStatus, VehicleTelemetry, topics,
};
use aeris_video::capture::{Capture, CaptureConfig, CaptureEvent, CapturedFrame, PixelFormat};
use core::time::Duration;
use pose_ring::{PoseFit, PoseRing, PoseSample};

/// Default stall time (ms).
pub const DEFAULT_STALL_MS: f64 = 1000.0;
/// Default cycle period (ms).
pub const DEFAULT_POLL_MS: f64 = 2.0;
/// First restart back-off.
pub const RESTART_BACKOFF_MIN: Duration = Duration::from_millis(250);
/// Longest restart back-off.
pub const RESTART_BACKOFF_MAX: Duration = Duration::from_secs(8);

/// One pipeline and its restart state.
struct Source {
    /// `pipeline` or `depth_pipeline` (for log lines).
    param: &'static str,
    capture: Capture,
    /// When to start it again (CLOCK_MONOTONIC ns), while it is down.
    restart_at: Option<u64>,
    backoff_ns: u64,
    stalled: bool,
}

impl Source {
    fn new(
        spec: &RoleSpec,
        param: &'static str,
        format: PixelFormat,
    ) -> Result<Option<Self>, RoleError> {
        let Some(value) = spec.params.get(param) else {
            return Ok(None);
        };
        let pipeline = value
            .as_str()
            .ok_or_else(|| RoleError::param(param, format!("must be a string, got {value}")))?;
        let stall_ms = match spec.params.get("stall_ms") {
            None => DEFAULT_STALL_MS,
            Some(v) => v
                .as_f64()
                .filter(|ms| ms.is_finite() && *ms > 0.0)
                .ok_or_else(|| {
                    RoleError::param("stall_ms", format!("must be a positive number, got {v}"))
                })?,
        };
        let config = CaptureConfig {
            pipeline: pipeline.to_string(),
            format,
            width: spec.camera.width,
            height: spec.camera.height,
            stall: Duration::from_secs_f64(stall_ms / 1000.0),
        };
        let capture = Capture::new(&config).map_err(|e| ConfigError::param_refused(param, e))?;
        Ok(Some(Source {
            param,
            capture,
            restart_at: None,
            backoff_ns: duration_ns(RESTART_BACKOFF_MIN),
            stalled: false,
        }))
    }

    /// Log the pipeline's events, count them, schedule restarts, and restart when due;
    /// `true` while the pipeline is down or stalled.
    fn tend(&mut self, now: u64, counters: &mut CameraCounters) -> bool {
        while let Some(event) = self.capture.poll_event() {
            match &event {
                CaptureEvent::Error(text) => {
                    counters.errors += 1;
                    tracing::warn!("camera: `{}` failed: {text}", self.param);
                    self.schedule_restart(now);
                }
                CaptureEvent::Eos => {
                    counters.ends_of_stream += 1;
                    tracing::info!("camera: `{}` reached the end of its stream", self.param);
                    self.schedule_restart(now);
                }
                CaptureEvent::Stalled { silent_ms } => {
                    counters.stalls += 1;
                    self.stalled = true;
                    tracing::info!(
                        "camera: `{}` stalled: no frame for {silent_ms} ms",
                        self.param
                    );
                }
                CaptureEvent::Resumed { after_ms } => {
                    self.stalled = false;
                    tracing::info!("camera: `{}` resumed after {after_ms} ms", self.param);
                }
            }
        }
        if let Some(at) = self.restart_at
            && now >= at
        {
            counters.restarts += 1;
            match self.capture.start() {
                Ok(()) => {
                    self.restart_at = None;
                    self.stalled = false;
                    tracing::info!("camera: `{}` restarted", self.param);
                }
                Err(e) => {
                    tracing::warn!("camera: `{}` restart failed: {}", self.param, chain(&e));
                    self.schedule_restart(now);
                }
            }
        }
        self.restart_at.is_some() || self.stalled
    }

    fn schedule_restart(&mut self, now: u64) {
        self.capture.stop();
        self.stalled = false;
        self.restart_at = Some(now.saturating_add(self.backoff_ns));
        tracing::info!(
            "camera: restarting `{}` in {} ms",
            self.param,
            self.backoff_ns / 1_000_000
        );
        self.backoff_ns = (self.backoff_ns * 2).min(duration_ns(RESTART_BACKOFF_MAX));
    }

    /// The newest frame, if one is ready (waiting at most `wait`).
    fn pull(&mut self, wait: Duration) -> Option<CapturedFrame> {
        let frame = self.capture.pull(wait)?;
        self.backoff_ns = duration_ns(RESTART_BACKOFF_MIN);
        Some(frame)
    }
}

fn duration_ns(d: Duration) -> u64 {
    u64::try_from(d.as_nanos()).unwrap_or(u64::MAX)
}

/// The GStreamer camera role.
pub struct GstreamerCameraRole {
    rgb_source: Source,
    depth_source: Option<Source>,
    rgb: FramePublisher,
    depth: Option<FramePublisher>,
    telemetry: TypedSubscriber<VehicleTelemetry>,
    poses: PoseRing,
    start: [f32; 3],
    width: u32,
    height: u32,
    hfov: f32,
    period: Duration,
    frame_period: Duration,
    seq: u64,
    counters: CameraCounters,
}

impl GstreamerCameraRole {
    /// Take in every telemetry sample that arrived (allocation-free).
    fn take_telemetry(&mut self) -> Result<(), RoleError> {
        let poses = &mut self.poses;
        self.telemetry.drain(|t| {
            if t.validate().is_ok() {
                poses.push(PoseSample {
                    t_ns: t.stamp_ns,
                    position: t.position,
                    yaw: t.attitude[2],
                });
            }
        })?;
        Ok(())
    }
}

impl Role for GstreamerCameraRole {
    type Kind = kinds::Camera;

    fn new(ctx: &mut RoleContext<kinds::Camera>) -> Result<Self, RoleError> {
        let spec = &ctx.spec;
        let cam = &spec.camera;
        if !(cam.fps.is_finite() && cam.fps > 0.0) {
            return Err(ConfigError::Spec {
                field: "camera.fps",
                problem: format!("= {} is not positive", cam.fps),
            }
            .into());
        }
        let poll_ms = match spec.params.get("poll_ms") {
            None => DEFAULT_POLL_MS,
            Some(v) => v
                .as_f64()
                .filter(|ms| ms.is_finite() && *ms > 0.0 && *ms <= 1000.0)
                .ok_or_else(|| {
                    RoleError::param("poll_ms", format!("must be in (0, 1000], got {v}"))
                })?,
        };
        let mut rgb_source =
            Source::new(spec, "pipeline", PixelFormat::Rgb8)?.ok_or_else(|| {
                RoleError::param(
                    "pipeline",
                    "is missing: the gstreamer camera needs a GStreamer pipeline ending in \
                 `appsink`, e.g. `videotestsrc is-live=true ! appsink sync=false`",
                )
            })?;
        let mut depth_source = Source::new(spec, "depth_pipeline", PixelFormat::Gray16Le)?;
        let start = spec.mission.start;
        if !start.iter().all(|v| v.is_finite()) {
            return Err(ConfigError::Mission("start is not finite".into()).into());
        }
        let rgb = ctx
            .bus
            .frame_publisher::<topics::CameraRgb>(rgb_source.capture.frame_len())?;
        let depth = match &depth_source {
            Some(d) => Some(
                ctx.bus
                    .frame_publisher::<topics::CameraDepth>(d.capture.frame_len())?,
            ),
            None => None,
        };
        let telemetry = ctx.bus.subscriber::<topics::VehicleTelemetry>()?;
        rgb_source
            .capture
            .start()
            .map_err(|e| RoleError::step("starting camera param `pipeline`", e))?;
        if let Some(d) = &mut depth_source {
            d.capture
                .start()
                .map_err(|e| RoleError::step("starting camera param `depth_pipeline`", e))?;
        }
        Ok(Self {
            rgb_source,
            depth_source,
            rgb,
            depth,
            telemetry,
            poses: PoseRing::default(),
            start,
            width: cam.width,
            height: cam.height,
            hfov: cam.hfov_deg.to_radians(),
            period: Duration::from_secs_f64(poll_ms / 1000.0),
            frame_period: Duration::from_secs_f64(1.0 / cam.fps),
            seq: 0,
            counters: CameraCounters::default(),
        })
    }

    fn period(&self) -> Duration {
        self.period
    }

    fn cycle(
        &mut self,
        _ctx: &mut RoleContext<kinds::Camera>,
        report: &mut CycleReport,
    ) -> Result<CycleOutcome, RoleError> {
        let now = monotonic_ns();
        self.take_telemetry()?;
        let mut degraded = self.rgb_source.tend(now, &mut self.counters);
        if let Some(d) = &mut self.depth_source {
            degraded |= d.tend(now, &mut self.counters);
        }
        report.status = if degraded {
            RoleStatus::Degraded
        } else {
            RoleStatus::Running
        };
        report.counters = self.counters.to_heartbeat();
        let Some(frame) = self.rgb_source.pull(Duration::ZERO) else {
            return Ok(CycleOutcome::Idle);
        };
        let t0 = monotonic_ns();
        if let Err(e) = frame.check() {
            tracing::warn!("camera: frame dropped: {}", chain(&e));
            return Ok(CycleOutcome::Idle);
        }
        // telemetry up to now, so a capture just before this cycle falls inside the ring
        self.take_telemetry()?;
        if !frame.pts_mapped {
            self.counters.stamped_on_arrival += 1;
        }
        let (position, yaw) = match self.poses.at(frame.capture_ns) {
            Some((p, fit)) => {
                if fit != PoseFit::Interpolated {
                    self.counters.held_pose += 1;
                }
                (p.position, p.yaw)
            }
            None => {
                self.counters.held_pose += 1;
                (self.start, 0.0)
            }
        };
        let header = FrameHeader {
            seq: self.seq + 1,
            capture_ns: frame.capture_ns,
            width: self.width,
            height: self.height,
            camera_position: [
                position[0],
                position[1],
                position[2] + CAMERA_MOUNT_HEIGHT_M,
            ],
            camera_yaw: yaw,
            hfov: self.hfov,
            format: FrameFormat::Rgb8 as u8,
            reserved: [0; 3],
        };
        let mut copied = Ok(());
        let len = self.rgb_source.capture.frame_len();
        self.rgb
            .publish_with(&header, len, |dst| copied = frame.copy_to(dst))?;
        // checked above; a failure here left a zeroed frame, which is logged
        if let Err(e) = copied {
            tracing::warn!("camera: frame {} not copied: {}", header.seq, chain(&e));
        }
        drop(frame);
        self.seq += 1;
        self.counters.rgb_frames = self.seq;
        let t1 = monotonic_ns();
        report.stage("publish", t1.saturating_sub(t0));
        if let (Some(source), Some(publisher)) = (&mut self.depth_source, &self.depth)
            && let Some(depth) = source.pull(self.frame_period)
            && depth.check().is_ok()
        {
            let header = FrameHeader {
                format: FrameFormat::DepthU16Mm as u8,
                ..header
            };
            let mut copied = Ok(());
            publisher.publish_with(&header, source.capture.frame_len(), |dst| {
                copied = depth.copy_to(dst)
            })?;
            if let Err(e) = copied {
                tracing::info!(
                    "camera: depth frame {} not copied: {}",
                    header.seq,
                    chain(&e)
                );
            }
            self.counters.depth_frames += 1;
        }
        report.stage("depth", monotonic_ns().saturating_sub(t1));
        report.counters = self.counters.to_heartbeat();
        Ok(CycleOutcome::Worked)
    }

    fn shutdown(&mut self, _ctx: &mut RoleContext<kinds::Camera>) {
        self.rgb_source.capture.stop();
        if let Some(d) = &mut self.depth_source {
            d.capture.stop();
        }
    }
}
