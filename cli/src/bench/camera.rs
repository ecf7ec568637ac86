//! `aeris bench camera`: glass-to-shared-memory latency of the `gstreamer` camera role.

use aeris_bench::camera::{self, CameraConfig};
use anyhow::{Context, bail};
use clap::Args;

/// Arguments of `aeris bench camera`.
#[derive(Debug, Args)]
pub struct CameraArgs {
    /// Frame sizes WxH, one row each.
    #[arg(long, value_delimiter = ',', default_value = "640x480,1280x720")]
    pub sizes: Vec<String>,
    /// Source frame rate (frames per second).
    #[arg(long, default_value_t = 30)]
    pub fps: u32,
    /// Measured seconds per row.
    #[arg(long, default_value_t = 10.0)]
    pub seconds: f64,
    /// Frames skipped at the start of each row.
    #[arg(long, default_value_t = 10)]
    pub warmup: u64,
    /// Print one JSON object on the last line of stdout.
    #[arg(long)]
    pub json: bool,
}

fn size(text: &str) -> anyhow::Result<(u32, u32)> {
    let parsed = text
        .split_once('x')
        .and_then(|(w, h)| Some((w.parse().ok()?, h.parse().ok()?)));
    match parsed {
        Some((w, h)) if w > 0 && h > 0 => Ok((w, h)),
        _ => bail!("--sizes: `{text}` is not WIDTHxHEIGHT"),
    }
}

/// Run `aeris bench camera`.
pub fn run(a: CameraArgs) -> anyhow::Result<()> {
    iceoryx2::prelude::set_log_level(iceoryx2::prelude::LogLevel::Error);
    let exe = std::env::current_exe().context("cannot find this executable to start the camera")?;
    let work_dir = std::env::temp_dir().join(format!("aeris-bench-camera-{}", std::process::id()));
    let config = CameraConfig {
        exe,
        sizes: a
            .sizes
            .iter()
            .map(|s| size(s))
            .collect::<anyhow::Result<_>>()?,
        fps: a.fps,
        seconds: a.seconds,
        warmup_frames: a.warmup,
        work_dir: work_dir.clone(),
    };
    println!(
        "camera glass-to-shared-memory latency (videotestsrc is-live=true -> gstreamer camera role \
         -> camera/rgb subscriber), {} s per row after {} warm-up frames",
        a.seconds, a.warmup
    );
    println!(
        "{:>10} {:>4} {:>7} {:>8} {:>10} {:>10} {:>10}",
        "size", "fps", "frames", "dropped", "p50_us", "p99_us", "max_us"
    );
    let report = camera::run(&config);
    let _ = std::fs::remove_dir_all(&work_dir);
    let report = report.context("camera bench failed")?;
    for r in &report.rows {
        println!(
            "{:>10} {:>4} {:>7} {:>8} {:>10.1} {:>10.1} {:>10.1}",
            format!("{}x{}", r.width, r.height),
            r.fps,
            r.frames,
            r.dropped,
            r.p50_us,
            r.p99_us,
            r.max_us
        );
    }
    if a.json {
        crate::bench::json::print(&report)?;
    }
    Ok(())
}
