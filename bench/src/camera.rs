//! Glass-to-shared-memory latency of the `gstreamer` camera role.
//!
//! Per row (a frame size), this process starts the real camera role
//! (`aeris role --spec`, variant `gstreamer`, its own flight) on
//! `videotestsrc is-live=true pattern=ball ! video/x-raw,width=W,height=H,framerate=F/1 ! appsink sync=false`
//! at the camera size `W`×`H` (so the role's converters pass the frames through), subscribes to
//! `camera/rgb` and, for every frame after the warm-up, records `receive time − capture_ns`:
//! from the buffer's capture time (its PTS on the pipeline clock, CLOCK_MONOTONIC) to the frame
//! being readable in shared memory by another process. The subscriber polls every
//! [`POLL`] (so the figures include up to that much of its own wake-up), the role its
//! appsink every `poll_ms` (default 2 ms).
//!
//! Dropped frames: a live `videotestsrc` stamps frame `n` at `n / F`, so a gap of `k / F`
//! between two consecutive received frames means `k − 1` frames were lost somewhere between
//! the source and the subscriber (the appsink keeps only the newest buffer; the frame service
//! keeps two per subscriber).

use crate::error::BenchError;
use crate::summary_us;
use aeris_runtime::FlightBus;
use aeris_runtime::clock::{monotonic_ns, sleep_until_ns};
use aeris_schemas::topics;
use serde::Serialize;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};

/// How often the subscriber looks for a frame.
pub const POLL: core::time::Duration = core::time::Duration::from_micros(100);

/// How long a row waits for the camera's first frame.
const FIRST_FRAME_TIMEOUT_NS: u64 = 20_000_000_000;

/// What to measure.
#[derive(Debug, Clone)]
pub struct CameraConfig {
    /// The `aeris` executable (its hidden `role` command runs the camera).
    pub exe: PathBuf,
    /// Frame sizes, one row each.
    pub sizes: Vec<(u32, u32)>,
    /// Source frame rate.
    pub fps: u32,
    /// Measured seconds per row.
    pub seconds: f64,
    /// Frames skipped at the start of each row (pipeline start-up).
    pub warmup_frames: u64,
    /// Folder for the role's spec and log.
    pub work_dir: PathBuf,
}

/// One row: one frame size.
#[derive(Debug, Clone, Serialize)]
pub struct CameraRow {
    /// Frame width.
    pub width: u32,
    /// Frame height.
    pub height: u32,
    /// Source frame rate.
    pub fps: u32,
    /// Frames received and measured.
    pub frames: u64,
    /// Frames the source made that never reached the subscriber (capture-time gaps).
    pub dropped: u64,
    /// Latency p50 (µs).
    pub p50_us: f64,
    /// Latency p99 (µs).
    pub p99_us: f64,
    /// Latency max (µs).
    pub max_us: f64,
}

/// The benchmark's figures.
#[derive(Debug, Clone, Serialize)]
pub struct CameraReport {
    /// Rows, one per frame size.
    pub rows: Vec<CameraRow>,
}

/// Kills and reaps the role when dropped.
struct RoleProcess(Child);

impl Drop for RoleProcess {
    fn drop(&mut self) {
        // SIGTERM first: the role stops its pipeline and leaves its services cleanly
        // SAFETY: kill(2) on our own child's pid.
        unsafe { libc::kill(self.0.id() as libc::pid_t, libc::SIGTERM) };
        let deadline = monotonic_ns() + 5_000_000_000;
        while monotonic_ns() < deadline {
            if let Ok(Some(_)) = self.0.try_wait() {
                return;
            }
            sleep_until_ns(monotonic_ns() + 10_000_000);
        }
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn io(what: impl Into<String>) -> impl FnOnce(std::io::Error) -> BenchError {
    let what = what.into();
    move |source| BenchError::Io { what, source }
}

/// Run every row.
pub fn run(config: &CameraConfig) -> Result<CameraReport, BenchError> {
    let seconds_ok = config.seconds.is_finite() && config.seconds > 0.0;
    if config.fps == 0 || !seconds_ok || config.sizes.is_empty() {
        return Err(BenchError::Config(
            "the camera bench needs a rate, a duration and at least one size".into(),
        ));
    }
    std::fs::create_dir_all(&config.work_dir)
        .map_err(io(format!("cannot create {}", config.work_dir.display())))?;
    let rows = config
        .sizes
        .iter()
        .map(|&(w, h)| row(config, w, h))
        .collect::<Result<_, _>>()?;
    Ok(CameraReport { rows })
}

fn row(config: &CameraConfig, width: u32, height: u32) -> Result<CameraRow, BenchError> {
    let fps = config.fps;
    let flight = format!("bench-camera-{}-{width}x{height}", std::process::id());
    let bus = FlightBus::builder(&flight).node_name("bench").create()?;
    let rgb = bus.frame_subscriber::<topics::CameraRgb>()?;
    let pipeline = format!(
        "videotestsrc is-live=true pattern=ball ! video/x-raw,width={width},height={height},framerate={fps}/1 ! appsink sync=false"
    );
    let spec = serde_json::json!({
        "flight": flight,
        "name": "camera",
        "kind": "camera",
        "variant": "gstreamer",
        "camera": { "width": width, "height": height, "fps": fps, "hfov_deg": 90.0 },
        "mission": {
            "instruction": "hover",
            "subgoals": [{ "text": "take off", "action": "takeoff" }, { "text": "land", "action": "land" }],
        },
        "params": { "pipeline": pipeline },
    });
    let spec_path = config.work_dir.join(format!("{flight}.json"));
    std::fs::write(&spec_path, spec.to_string())
        .map_err(io(format!("cannot write {}", spec_path.display())))?;
    let log_path = config.work_dir.join(format!("{flight}.log"));
    let log = std::fs::File::create(&log_path)
        .map_err(io(format!("cannot create {}", log_path.display())))?;
    let child = Command::new(&config.exe)
        .args(["role", "--spec"])
        .arg(&spec_path)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(log)
        .spawn()
        .map_err(io(format!("cannot start {}", config.exe.display())))?;
    let mut role = RoleProcess(child);

    let poll_ns = POLL.as_nanos() as u64;
    let frame_ns = 1e9 / f64::from(fps);
    let mut latencies = Vec::new();
    let (mut seen, mut dropped) = (0u64, 0u64);
    let mut last_capture: Option<u64> = None;
    let started = monotonic_ns();
    let mut end: Option<u64> = None;
    loop {
        let now = monotonic_ns();
        if end.is_some_and(|e| now >= e) {
            break;
        }
        if end.is_none() && now.saturating_sub(started) > FIRST_FRAME_TIMEOUT_NS {
            return Err(BenchError::Timeout {
                what: format!(
                    "waiting for the camera's frames (role log: {})",
                    log_path.display()
                ),
                timeout_ms: FIRST_FRAME_TIMEOUT_NS / 1_000_000,
            });
        }
        if let Ok(Some(status)) = role.0.try_wait() {
            return Err(BenchError::Pong(format!(
                "the camera role exited ({status}); its log: {}",
                log_path.display()
            )));
        }
        while let Some(frame) = rgb.next()? {
            let received = monotonic_ns();
            let header = *frame.user_header();
            seen += 1;
            if seen <= config.warmup_frames {
                last_capture = Some(header.capture_ns);
                if seen == config.warmup_frames.max(1) && end.is_none() {
                    end = Some(received + (config.seconds * 1e9) as u64);
                }
                continue;
            }
            if end.is_none() {
                end = Some(received + (config.seconds * 1e9) as u64);
            }
            latencies.push(received.saturating_sub(header.capture_ns) as f64);
            if let Some(prev) = last_capture {
                let gap = header.capture_ns.saturating_sub(prev) as f64 / frame_ns;
                dropped += (gap.round() as u64).saturating_sub(1);
            }
            last_capture = Some(header.capture_ns);
        }
        sleep_until_ns(monotonic_ns() + poll_ns);
    }
    drop(role);
    let (p50_us, p99_us, max_us) = summary_us(&latencies);
    Ok(CameraRow {
        width,
        height,
        fps,
        frames: latencies.len() as u64,
        dropped,
        p50_us,
        p99_us,
        max_us,
    })
}
