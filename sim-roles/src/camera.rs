//! The simulated FPV camera (kind `camera`, variant `sim-render`).
//!
//! Every `1 / camera.fps` it takes the vehicle pose from the newest valid
//! `vehicle/telemetry` (position, attitude yaw; the mission start and yaw 0 before any
//! telemetry), renders the mission's built-in world ([`aeris_sim::world::World`]) with
//! [`aeris_sim::render::Renderer`] straight into two loaned shared-memory samples, and sends
//! them on `camera/depth` and `camera/rgb` with the same `seq`, `capture_ns`, pose and field
//! of view in both headers. The camera sits [`CAMERA_MOUNT_HEIGHT_M`] above the vehicle's
//! position on a stabilised mount (airframe roll and pitch do not move the image); the
//! headers carry the camera's own position.
//!
//! Stages: `render`, `publish`. Heartbeat counters: [`CameraCounters`] (`rgb_frames`).

use aeris_geometry::CAMERA_MOUNT_HEIGHT_M;
use aeris_runtime::bus::{BusError, FramePublisher, TypedSubscriber};
use aeris_runtime::clock::monotonic_ns;
use aeris_runtime::{ConfigError, CycleOutcome, CycleReport, Role, RoleContext, RoleError};
use aeris_schemas::kinds;
use aeris_schemas::{CameraCounters, FrameFormat, FrameHeader, VehicleTelemetry, topics};
use aeris_sim::render::{RenderError, Renderer};
use aeris_sim::world::World;
use core::time::Duration;

/// Highest accepted frame rate (frames per second).
pub const MAX_FPS: f64 = 1000.0;

/// The camera role.
pub struct CameraRole {
    world: World,
    renderer: Renderer,
    rgb: FramePublisher,
    depth: FramePublisher,
    telemetry: TypedSubscriber<VehicleTelemetry>,
    position: [f32; 3],
    yaw: f32,
    hfov: f32,
    period: Duration,
    seq: u64,
}

impl Role for CameraRole {
    type Kind = kinds::Camera;

    fn new(ctx: &mut RoleContext<kinds::Camera>) -> Result<Self, RoleError> {
        let spec = &ctx.spec;
        let name = &spec.mission.world;
        let world = World::builtin(name).ok_or_else(|| {
            RoleError::from(ConfigError::Mission(format!(
                "names unknown world `{name}`; the built-in worlds are: {}",
                World::NAMES_HELP
            )))
        })?;
        let cam = &spec.camera;
        if !(cam.fps > 0.0 && cam.fps <= MAX_FPS) {
            return Err(ConfigError::Spec {
                field: "camera.fps",
                problem: format!("= {} is outside (0, {MAX_FPS}]", cam.fps),
            }
            .into());
        }
        let hfov = cam.hfov_deg.to_radians();
        let renderer = Renderer::new(cam.width, cam.height, hfov)
            .map_err(|e| RoleError::step("setting up the camera's renderer", e))?;
        let rgb = ctx
            .bus
            .frame_publisher::<topics::CameraRgb>(renderer.rgb_len())?;
        let depth = ctx
            .bus
            .frame_publisher::<topics::CameraDepth>(renderer.depth_len())?;
        let telemetry = ctx.bus.subscriber::<topics::VehicleTelemetry>()?;
        let start = spec.mission.start;
        if !start.iter().all(|v| v.is_finite()) {
            return Err(ConfigError::Mission("start is not finite".into()).into());
        }
        Ok(Self {
            world,
            renderer,
            rgb,
            depth,
            telemetry,
            position: start,
            yaw: 0.0,
            hfov,
            period: Duration::from_secs_f64(1.0 / cam.fps),
            seq: 0,
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
        let t0 = monotonic_ns();
        if let Some(t) = self.telemetry.latest()?
            && t.validate().is_ok()
        {
            self.position = t.position;
            self.yaw = t.attitude[2];
        }
        let p = self.position;
        let camera_position = [p[0], p[1], p[2] + CAMERA_MOUNT_HEIGHT_M];
        let cam = self.renderer.camera();
        let rgb_header = FrameHeader {
            seq: self.seq + 1,
            capture_ns: t0,
            width: cam.width,
            height: cam.height,
            camera_position,
            camera_yaw: self.yaw,
            hfov: self.hfov,
            format: FrameFormat::Rgb8 as u8,
            reserved: [0; 3],
        };
        let depth_header = FrameHeader {
            format: FrameFormat::DepthU16Mm as u8,
            ..rgb_header
        };

        let Self {
            world,
            renderer,
            rgb,
            depth,
            yaw,
            ..
        } = self;
        let mut render_ns = 0;
        let mut rendered: Result<(), RenderError> = Ok(());
        let mut depth_sent: Result<(), BusError> = Ok(());
        // both samples are loaned at once so one pass of the renderer fills both in place;
        // depth is sent first (when the inner closure returns), then rgb
        rgb.publish_with(&rgb_header, renderer.rgb_len(), |rgb_bytes| {
            depth_sent = depth.publish_with(&depth_header, renderer.depth_len(), |depth_bytes| {
                let r0 = monotonic_ns();
                rendered = renderer.render(world, camera_position, *yaw, rgb_bytes, depth_bytes);
                render_ns = monotonic_ns().saturating_sub(r0);
            });
        })?;
        depth_sent?;
        rendered.map_err(|e| RoleError::step("rendering a frame", e))?;
        self.seq += 1;
        let total = monotonic_ns().saturating_sub(t0);
        report.stage("render", render_ns);
        report.stage("publish", total.saturating_sub(render_ns));
        report.counters = CameraCounters {
            rgb_frames: self.seq,
            ..CameraCounters::default()
        }
        .to_heartbeat();
        Ok(CycleOutcome::Worked)
    }
}
