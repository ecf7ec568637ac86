//! The built-in scene as H.264 video (feature `sim`): what `aeris scene video` does.
//!
//! Two ways to choose the poses:
//! - **a path** ([`path_poses`], [`render_poses`]): straight legs between waypoints flown at a
//!   constant speed, the camera looking along each leg (or at a fixed heading), one pose per
//!   frame at the camera rate; written to an MP4 file as fast as the renderer goes, or sent
//!   as RTP in real time (one frame every `1 / fps`);
//! - **following a flight** ([`follow`]): a simulated FPV transmitter. It joins a running
//!   flight, and every `1 / fps` renders the scene at the vehicle's newest
//!   `vehicle/telemetry` pose (the mission start before the first, like `sim-render`) and
//!   sends it. A flight whose camera is the `gstreamer` variant on that RTP stream then
//!   flies on decoded video that shows where the vehicle actually is: the loop closes
//!   through telemetry → renderer → H.264 → UDP → decoder → `camera/rgb`.
//!
//! The camera sits [`CAMERA_MOUNT_HEIGHT_M`] above the vehicle position, as in `sim-render`;
//! frames are rendered straight into the encoder's buffers.

use crate::Encoder;
use crate::encode::{EncoderConfig, EncoderStartError, FinishError, PushError, VideoSink};
use aeris_geometry::CAMERA_MOUNT_HEIGHT_M;
use aeris_runtime::FlightBus;
use aeris_runtime::bus::{BusError, flight_node_alive, list_flights};
use aeris_runtime::clock::{monotonic_ns, sleep_until_ns};
use aeris_schemas::topics;
use aeris_sim::render::{RenderError, Renderer};
use aeris_sim::world::World;
use core::time::Duration;

/// The camera that films the scene.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SceneCamera {
    /// Frame width (pixels).
    pub width: u32,
    /// Frame height (pixels).
    pub height: u32,
    /// Horizontal field of view (degrees).
    pub hfov_deg: f32,
    /// Frames per second.
    pub fps: u32,
}

/// One camera pose: the vehicle's position (the camera is mounted above it) and heading.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// Vehicle position `[N, E, U]` (m).
    pub position: [f32; 3],
    /// Heading (rad, 0 = north, clockwise).
    pub yaw: f32,
}

/// A path of straight legs.
#[derive(Debug, Clone, PartialEq)]
pub struct PathSpec {
    /// Waypoints `[N, E, U]` (m), at least one.
    pub waypoints: Vec<[f32; 3]>,
    /// Speed along the legs (m/s).
    pub speed_m_s: f32,
    /// Seconds to stay at the last waypoint (the whole video for a single waypoint).
    pub hold_s: f32,
    /// A fixed heading (rad); `None`: along each leg (a vertical leg keeps the heading of
    /// the one before, north at first).
    pub yaw: Option<f32>,
}

/// Longest video a path may make (frames), so a typo cannot fill the disk.
pub const MAX_FRAMES: usize = 1_000_000;

/// Why a path gives no poses.
#[derive(Debug, thiserror::Error)]
pub enum PathError {
    /// No waypoint.
    #[error("the path has no waypoint")]
    Empty,
    /// A coordinate, the speed, the hold or the heading is not finite, or the speed is not
    /// positive, or the hold is negative.
    #[error("the path's waypoints, speed, hold or heading are not usable numbers")]
    NotFinite,
    /// The video would have no frame, or more than [`MAX_FRAMES`].
    #[error("the path makes {0} frames; a video has 1 to {MAX_FRAMES}")]
    Frames(usize),
}

/// One pose per frame at `fps` along `path`.
pub fn path_poses(path: &PathSpec, fps: u32) -> Result<Vec<Pose>, PathError> {
    let first = *path.waypoints.first().ok_or(PathError::Empty)?;
    let finite = path.waypoints.iter().flatten().all(|v| v.is_finite())
        && path.speed_m_s.is_finite()
        && path.speed_m_s > 0.0
        && path.hold_s.is_finite()
        && path.hold_s >= 0.0
        && path.yaw.is_none_or(f32::is_finite);
    if !finite || fps == 0 {
        return Err(PathError::NotFinite);
    }
    let dist = |a: [f32; 3], b: [f32; 3]| {
        ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2) + (b[2] - a[2]).powi(2)).sqrt()
    };
    let length: f32 = path.waypoints.windows(2).map(|w| dist(w[0], w[1])).sum();
    let seconds = f64::from(length / path.speed_m_s) + f64::from(path.hold_s);
    let frames = (seconds * f64::from(fps)).ceil() as usize + 1;
    if frames > MAX_FRAMES {
        return Err(PathError::Frames(frames));
    }
    let mut poses = Vec::with_capacity(frames);
    let mut leg = 0;
    let mut leg_start_s = 0.0f32;
    let mut heading = path.yaw.unwrap_or(0.0);
    for i in 0..frames {
        let t = i as f32 / fps as f32;
        // the leg that contains t (or the last waypoint, held)
        while leg + 1 < path.waypoints.len() {
            let d = dist(path.waypoints[leg], path.waypoints[leg + 1]) / path.speed_m_s;
            if t <= leg_start_s + d {
                break;
            }
            leg_start_s += d;
            leg += 1;
        }
        let position = if leg + 1 < path.waypoints.len() {
            let (a, b) = (path.waypoints[leg], path.waypoints[leg + 1]);
            let d = dist(a, b);
            let f = if d > 0.0 {
                ((t - leg_start_s) * path.speed_m_s / d).clamp(0.0, 1.0)
            } else {
                1.0
            };
            if path.yaw.is_none() && (b[0] - a[0]).hypot(b[1] - a[1]) > 1e-3 {
                heading = (b[1] - a[1]).atan2(b[0] - a[0]);
            }
            [
                a[0] + (b[0] - a[0]) * f,
                a[1] + (b[1] - a[1]) * f,
                a[2] + (b[2] - a[2]) * f,
            ]
        } else {
            path.waypoints.last().copied().unwrap_or(first)
        };
        poses.push(Pose {
            position,
            yaw: heading,
        });
    }
    Ok(poses)
}

/// What a rendered video amounted to.
#[derive(Debug, Clone, PartialEq)]
pub struct VideoReport {
    /// Frames encoded.
    pub frames: u64,
    /// The H.264 encoder used (`x264enc` or `openh264enc`).
    pub encoder: &'static str,
    /// Frames rendered at a telemetry pose (following a flight; 0 for a path).
    pub posed_frames: u64,
    /// Frames sent after their real-time slot had passed (a stream only: the renderer was
    /// slower than the camera rate).
    pub late_frames: u64,
}

/// Why a video along a path could not be made.
#[derive(Debug, thiserror::Error)]
pub enum RenderVideoError {
    /// The renderer refused the camera.
    #[error("cannot set up the renderer")]
    Renderer(#[source] RenderError),
    /// The encoder did not start.
    #[error(transparent)]
    Encoder(#[from] EncoderStartError),
    /// A frame could not be rendered.
    #[error("cannot render frame {frame}")]
    Render {
        /// Frame number (from 0).
        frame: usize,
        /// Why.
        source: RenderError,
    },
    /// A frame could not be encoded.
    #[error("cannot encode frame {frame}")]
    Push {
        /// Frame number (from 0).
        frame: usize,
        /// Why.
        source: PushError,
    },
    /// The video could not be finished.
    #[error(transparent)]
    Finish(#[from] FinishError),
}

/// How long finishing a file may take (mp4mux writing its index).
const FINISH_TIMEOUT: Duration = Duration::from_secs(30);

fn renderer(camera: &SceneCamera) -> Result<Renderer, RenderError> {
    Renderer::new(camera.width, camera.height, camera.hfov_deg.to_radians())
}

/// Render one frame at `pose` into the encoder.
fn push_pose(
    encoder: &mut Encoder,
    renderer: &Renderer,
    world: &World,
    pose: Pose,
    depth: &mut [u8],
) -> Result<Result<(), RenderError>, PushError> {
    let p = pose.position;
    let mut rendered = Ok(());
    encoder.push_with(|rgb| {
        rendered = renderer.render(
            world,
            [p[0], p[1], p[2] + CAMERA_MOUNT_HEIGHT_M],
            pose.yaw,
            rgb,
            depth,
        );
    })?;
    Ok(rendered)
}

/// Render `world` at every pose of `poses` into `sink`; `progress(done, total)` after each
/// frame. An MP4 is written as fast as frames render (it plays at `camera.fps`); an RTP
/// stream is paced at `camera.fps` in real time.
pub fn render_poses(
    world: &World,
    camera: &SceneCamera,
    poses: &[Pose],
    sink: VideoSink,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<VideoReport, RenderVideoError> {
    let renderer = renderer(camera).map_err(RenderVideoError::Renderer)?;
    let live = matches!(sink, VideoSink::Rtp { .. });
    let mut encoder = Encoder::new(&EncoderConfig {
        width: camera.width,
        height: camera.height,
        fps: camera.fps,
        sink,
    })?;
    let mut depth = vec![0u8; renderer.depth_len()];
    let period_ns = 1_000_000_000 / u64::from(camera.fps.max(1));
    let mut next = monotonic_ns();
    let mut late = 0;
    for (frame, pose) in poses.iter().enumerate() {
        if live {
            let now = monotonic_ns();
            if now > next + period_ns {
                late += 1;
            } else {
                sleep_until_ns(next);
            }
            next += period_ns;
        }
        push_pose(&mut encoder, &renderer, world, *pose, &mut depth)
            .map_err(|source| RenderVideoError::Push { frame, source })?
            .map_err(|source| RenderVideoError::Render { frame, source })?;
        progress(frame + 1, poses.len());
    }
    let report = VideoReport {
        frames: encoder.frames(),
        encoder: encoder.encoder_name(),
        posed_frames: 0,
        late_frames: late,
    };
    encoder.finish(FINISH_TIMEOUT)?;
    Ok(report)
}

/// How to follow a flight.
#[derive(Debug, Clone, PartialEq)]
pub struct FollowConfig {
    /// The flight to join (`aeris run --flight NAME`).
    pub flight: String,
    /// The vehicle's pose before its first telemetry (the mission start).
    pub start: Pose,
    /// How long to wait for the flight to appear.
    pub wait: Duration,
    /// Stop after this long (`None`: until the flight ends or `stop` says so).
    pub duration: Option<Duration>,
}

/// Where a transmitter stands, for progress lines.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FollowProgress {
    /// Frames sent.
    pub frames: u64,
    /// Frames rendered at a telemetry pose.
    pub posed_frames: u64,
    /// The pose of the last frame.
    pub pose: Pose,
}

/// Why following a flight failed.
#[derive(Debug, thiserror::Error)]
pub enum FollowError {
    /// The flight did not appear in time.
    #[error(
        "flight `{flight}` did not start within {waited:?} (is `aeris run --flight {flight}` running?)"
    )]
    NoFlight {
        /// The flight.
        flight: String,
        /// How long it was waited for.
        waited: Duration,
    },
    /// The flight's bus could not be joined.
    #[error("cannot join flight `{flight}`")]
    Bus {
        /// The flight.
        flight: String,
        /// Why.
        source: BusError,
    },
    /// The renderer refused the camera.
    #[error("cannot set up the renderer")]
    Renderer(#[source] RenderError),
    /// The encoder did not start.
    #[error(transparent)]
    Encoder(#[from] EncoderStartError),
    /// A frame could not be rendered.
    #[error("cannot render frame {frame}")]
    Render {
        /// Frame number (from 0).
        frame: u64,
        /// Why.
        source: RenderError,
    },
    /// A frame could not be encoded.
    #[error("cannot encode frame {frame}")]
    Push {
        /// Frame number (from 0).
        frame: u64,
        /// Why.
        source: PushError,
    },
}

/// Be the FPV transmitter of a running flight (see the module docs) until the flight ends,
/// `config.duration` passes or `stop()` says so; `progress` about once a second.
pub fn follow(
    world: &World,
    camera: &SceneCamera,
    config: &FollowConfig,
    sink: VideoSink,
    stop: &dyn Fn() -> bool,
    progress: &mut dyn FnMut(FollowProgress),
) -> Result<VideoReport, FollowError> {
    let renderer = renderer(camera).map_err(FollowError::Renderer)?;
    let flight = &config.flight;
    let t0 = monotonic_ns();
    let wait_ns = u64::try_from(config.wait.as_nanos()).unwrap_or(u64::MAX);
    // join only a flight its supervisor created: never publish its manifest first
    let running =
        || flight_node_alive(flight, "supervisor") && list_flights().iter().any(|f| f == flight);
    while !running() {
        if stop() {
            return Err(FollowError::NoFlight {
                flight: flight.clone(),
                waited: Duration::from_nanos(monotonic_ns() - t0),
            });
        }
        if monotonic_ns().saturating_sub(t0) > wait_ns {
            return Err(FollowError::NoFlight {
                flight: flight.clone(),
                waited: config.wait,
            });
        }
        sleep_until_ns(monotonic_ns() + 100_000_000);
    }
    let bus_error = |source| FollowError::Bus {
        flight: flight.clone(),
        source,
    };
    let bus = FlightBus::builder(flight)
        .node_name("scene-video")
        .create()
        .map_err(bus_error)?;
    let telemetry = bus
        .subscriber::<topics::VehicleTelemetry>()
        .map_err(bus_error)?;
    let mut encoder = Encoder::new(&EncoderConfig {
        width: camera.width,
        height: camera.height,
        fps: camera.fps,
        sink,
    })?;
    let mut depth = vec![0u8; renderer.depth_len()];
    let period_ns = 1_000_000_000 / u64::from(camera.fps.max(1));
    let end = config
        .duration
        .map(|d| monotonic_ns().saturating_add(u64::try_from(d.as_nanos()).unwrap_or(u64::MAX)));
    let mut pose = config.start;
    let (mut posed, mut late) = (0, 0);
    let mut seen_telemetry = false;
    let mut next = monotonic_ns();
    let mut next_check = next;
    loop {
        let now = monotonic_ns();
        if stop() || end.is_some_and(|e| now >= e) {
            break;
        }
        if now >= next_check {
            // the flight ends with its supervisor (its manifest stays while we hold it)
            if !flight_node_alive(flight, "supervisor") {
                break;
            }
            next_check = now + 1_000_000_000;
            progress(FollowProgress {
                frames: encoder.frames(),
                posed_frames: posed,
                pose,
            });
        }
        if let Some(t) = telemetry.latest().map_err(bus_error)?
            && t.validate().is_ok()
        {
            pose = Pose {
                position: t.position,
                yaw: t.attitude[2],
            };
            seen_telemetry = true;
        }
        let frame = encoder.frames();
        push_pose(&mut encoder, &renderer, world, pose, &mut depth)
            .map_err(|source| FollowError::Push { frame, source })?
            .map_err(|source| FollowError::Render { frame, source })?;
        posed += u64::from(seen_telemetry);
        next += period_ns;
        let now = monotonic_ns();
        if now > next {
            late += 1;
            next = now;
        } else {
            sleep_until_ns(next);
        }
    }
    let report = VideoReport {
        frames: encoder.frames(),
        encoder: encoder.encoder_name(),
        posed_frames: posed,
        late_frames: late,
    };
    // a stream has nothing to finalise: a failed end of stream changes nothing sent
    let _ = encoder.finish(Duration::from_secs(2));
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_path_is_flown_at_its_speed_looking_along_each_leg() {
        let path = PathSpec {
            waypoints: vec![[0.0, 0.0, 10.0], [10.0, 0.0, 10.0], [10.0, 10.0, 10.0]],
            speed_m_s: 5.0,
            hold_s: 0.0,
            yaw: None,
        };
        let poses = path_poses(&path, 10).unwrap();
        // 20 m at 5 m/s = 4 s = 40 frame intervals: 41 frames
        assert_eq!(poses.len(), 41);
        assert_eq!(poses[0].position, [0.0, 0.0, 10.0]);
        assert!((poses[10].position[0] - 5.0).abs() < 1e-4);
        assert_eq!(poses[10].yaw, 0.0);
        assert!((poses[30].position[1] - 5.0).abs() < 1e-4);
        assert!((poses[30].yaw - core::f32::consts::FRAC_PI_2).abs() < 1e-6);
        assert_eq!(poses[40].position, [10.0, 10.0, 10.0]);
        let hover = PathSpec {
            waypoints: vec![[1.0, 2.0, 3.0]],
            speed_m_s: 1.0,
            hold_s: 2.0,
            yaw: Some(1.0),
        };
        let poses = path_poses(&hover, 5).unwrap();
        assert_eq!(poses.len(), 11);
        assert!(
            poses
                .iter()
                .all(|p| p.position == [1.0, 2.0, 3.0] && p.yaw == 1.0)
        );
        assert!(matches!(
            path_poses(
                &PathSpec {
                    waypoints: vec![],
                    ..hover.clone()
                },
                5
            ),
            Err(PathError::Empty)
        ));
        assert!(matches!(
            path_poses(
                &PathSpec {
                    speed_m_s: 0.0,
                    ..hover
                },
                5
            ),
            Err(PathError::NotFinite)
        ));
    }
}
