//! `aeris scene video`: the built-in scene as H.264 video, along a path or following a flight.

use aeris_sim::world::World;
use aeris_video::VideoSink;
use aeris_video::scene_video::{
    FollowConfig, FollowProgress, PathSpec, Pose, SceneCamera, follow, path_poses, render_poses,
};
use anyhow::{Context, bail};
use clap::{ArgGroup, Args};
use std::io::Write;
use std::path::PathBuf;
use std::time::Duration;

/// Arguments of `aeris scene video`.
#[derive(Debug, Args)]
#[command(
    group(ArgGroup::new("poses").required(true).args(["path", "follow"])),
    group(ArgGroup::new("output").required(true).args(["out", "udp"])),
    after_help = "Examples:\n  \
    aeris scene video village --path 0,0,12 --path 62,0,12 --out north.mp4\n  \
    aeris scene video village --follow myflight --udp 127.0.0.1:5600\n\n\
    A flight flies on the stream of --follow with a camera role of variant `gstreamer` and\n\
    params.pipeline = 'udpsrc port=5600 caps=\"application/x-rtp,media=video,clock-rate=90000,\n\
    encoding-name=H264,payload=96\" ! rtph264depay ! avdec_h264 ! appsink sync=false'."
)]
pub struct VideoArgs {
    /// Scene name (built-in: village, open; generated: open-SEED, dense-SEED).
    pub scene: String,
    /// A waypoint N,E,U (m) of the path flown; repeat for each leg's end. The camera looks
    /// along each leg (see --yaw).
    #[arg(long, value_name = "N,E,U", allow_hyphen_values = true)]
    pub path: Vec<String>,
    /// Speed along the path (m/s).
    #[arg(long, default_value_t = 5.0)]
    pub speed: f32,
    /// Seconds to stay at the last waypoint (the whole video for a single waypoint).
    #[arg(long, default_value_t = 0.0)]
    pub hold: f32,
    /// A fixed heading (degrees, 0 = north, clockwise) instead of looking along the path.
    #[arg(long, allow_hyphen_values = true)]
    pub yaw: Option<f32>,
    /// Follow the vehicle of this running flight (`aeris run --flight NAME`): render at its
    /// newest telemetry pose every frame and stream it, until the flight ends or Ctrl-C (a
    /// simulated FPV transmitter; use with --udp).
    #[arg(long, value_name = "FLIGHT", conflicts_with_all = ["path", "speed", "hold", "yaw", "out"])]
    pub follow: Option<String>,
    /// With --follow: the vehicle's position N,E,U before its first telemetry.
    #[arg(
        long,
        value_name = "N,E,U",
        default_value = "0,0,0",
        allow_hyphen_values = true
    )]
    pub start: String,
    /// With --follow: seconds to wait for the flight to start.
    #[arg(long, default_value_t = 60.0)]
    pub wait: f64,
    /// With --follow: stop after this many seconds.
    #[arg(long)]
    pub seconds: Option<f64>,
    /// Write an H.264 MP4 file (rendered as fast as possible; plays at --fps).
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// Stream H.264 as RTP (payload type 96) over UDP to HOST:PORT, in real time at --fps.
    #[arg(long, value_name = "HOST:PORT")]
    pub udp: Option<String>,
    /// Frame width (pixels).
    #[arg(long, default_value_t = 320)]
    pub width: u32,
    /// Frame height (pixels).
    #[arg(long, default_value_t = 240)]
    pub height: u32,
    /// Horizontal field of view (degrees).
    #[arg(long, default_value_t = 90.0)]
    pub hfov: f32,
    /// Frames per second.
    #[arg(long, default_value_t = 10)]
    pub fps: u32,
}

fn point(text: &str, what: &str) -> anyhow::Result<[f32; 3]> {
    let v: Vec<f32> = text
        .split(',')
        .map(|s| s.trim().parse::<f32>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("{what} `{text}` is not three numbers N,E,U"))?;
    match v[..] {
        [n, e, u] => Ok([n, e, u]),
        _ => bail!("{what} `{text}` is not three numbers N,E,U"),
    }
}

fn sink(args: &VideoArgs) -> anyhow::Result<VideoSink> {
    if let Some(path) = &args.out {
        return Ok(VideoSink::Mp4(path.clone()));
    }
    let udp = args.udp.as_deref().unwrap_or_default();
    let (host, port) = udp
        .rsplit_once(':')
        .with_context(|| format!("--udp `{udp}` is not HOST:PORT"))?;
    let port: u16 = port
        .parse()
        .with_context(|| format!("--udp `{udp}`: the port is not a number 0-65535"))?;
    Ok(VideoSink::Rtp {
        host: host.to_string(),
        port,
    })
}

/// Run `aeris scene video`.
pub fn run(args: VideoArgs) -> anyhow::Result<()> {
    let world = World::builtin(&args.scene).with_context(|| {
        format!(
            "unknown scene `{}`; scenes are: {}",
            args.scene,
            World::NAMES_HELP
        )
    })?;
    let camera = SceneCamera {
        width: args.width,
        height: args.height,
        hfov_deg: args.hfov,
        fps: args.fps,
    };
    let sink = sink(&args)?;
    let target = match &sink {
        VideoSink::Mp4(p) => p.display().to_string(),
        VideoSink::Rtp { host, port } => format!("rtp://{host}:{port}"),
    };
    let mut stderr = std::io::stderr();
    if let Some(flight) = &args.follow {
        aeris_runtime::signals::install_termination_handlers()
            .context("cannot install signal handlers")?;
        let config = FollowConfig {
            flight: flight.clone(),
            start: Pose {
                position: point(&args.start, "--start")?,
                yaw: 0.0,
            },
            wait: Duration::try_from_secs_f64(args.wait).context("--wait is not a duration")?,
            duration: args
                .seconds
                .map(Duration::try_from_secs_f64)
                .transpose()
                .context("--seconds is not a duration")?,
        };
        eprintln!(
            "following flight `{flight}`: {}x{} at {} fps to {target} (Ctrl-C stops)",
            args.width, args.height, args.fps
        );
        let report = follow(
            &world,
            &camera,
            &config,
            sink,
            &aeris_runtime::signals::termination_requested,
            &mut |p: FollowProgress| {
                let [n, e, u] = p.pose.position;
                let _ = writeln!(
                    stderr,
                    "sent {} frames ({} at the vehicle's pose); vehicle at N {n:.1} E {e:.1} U {u:.1}",
                    p.frames, p.posed_frames
                );
            },
        )
        // the error names the flight, or the stream's host, itself
        .context("following a flight")?;
        println!(
            "sent {} frames ({} at the vehicle's pose, {} late) to {target} with {}",
            report.frames, report.posed_frames, report.late_frames, report.encoder
        );
        return Ok(());
    }
    let path = PathSpec {
        waypoints: args
            .path
            .iter()
            .map(|p| point(p, "--path"))
            .collect::<anyhow::Result<_>>()?,
        speed_m_s: args.speed,
        hold_s: args.hold,
        yaw: args.yaw.map(f32::to_radians),
    };
    let poses = path_poses(&path, args.fps)?;
    // on a terminal one line redrawn; in a log a line every 100 frames and at the end
    let redraw = std::io::IsTerminal::is_terminal(&stderr);
    let report = render_poses(&world, &camera, &poses, sink, &mut |done, total| {
        if redraw && (done == total || done % 10 == 0) {
            let _ = write!(stderr, "\rrendering {target}: {done}/{total} frames");
            if done == total {
                let _ = writeln!(stderr);
            }
        } else if !redraw && (done == total || done % 100 == 0) {
            let _ = writeln!(stderr, "rendering {target}: {done}/{total} frames");
        }
    })
    // GStreamer's own message names the file or host that failed
    .context("rendering the video")?;
    println!(
        "wrote {} frames ({}x{} at {} fps, {}) to {target}",
        report.frames, args.width, args.height, args.fps, report.encoder
    );
    Ok(())
}
