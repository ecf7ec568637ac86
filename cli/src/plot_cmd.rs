//! `aeris plot`: the pictures of a flight or an evaluated episode.
//!
//! Every flight's run folder holds `cycles.jsonl` (one line per semantic cycle: stage
//! timings, commit or reuse, active step, vehicle pose) and `roles/*.json` (the specs the
//! supervisor wrote, mission included). `aeris eval` records each episode's run folder in
//! episodes.jsonl (`run_dir`).

use aeris_eval::plot::{TimingBar, fpv_strip, save_png, timing_chart};
use aeris_flight::CycleTrace;
use aeris_runtime::RoleSpec;
use aeris_sim::render::{CAMERA_MOUNT_HEIGHT_M, Renderer};
use aeris_sim::world::World;
use anyhow::{Context, Result, bail};
use clap::{Args, Subcommand};
use std::io::BufRead;
use std::path::{Path, PathBuf};

/// Arguments of `aeris plot`.
#[derive(Debug, Args)]
pub struct PlotArgs {
    #[command(subcommand)]
    command: PlotCommand,
}

#[derive(Debug, Subcommand)]
enum PlotCommand {
    /// The heartbeat timing trace of a flight: per-cycle stacked bars (perception,
    /// reasoning, routing, binding), commit marks, reused cycles, the deadline line.
    Timing {
        /// The flight's run folder (holds cycles.jsonl and roles/).
        #[arg(long)]
        run: PathBuf,
        /// Output PNG.
        #[arg(long, default_value = "timing.png")]
        out: PathBuf,
    },
    /// A strip of FPV frames along a flight, each captioned with the active instruction
    /// step (rendered again from the recorded poses in the flight's scene).
    Fpv {
        /// The flight's run folder (holds cycles.jsonl and roles/).
        #[arg(long)]
        run: PathBuf,
        /// Frames in the strip, evenly spaced over the flight's cycles.
        #[arg(long, default_value_t = 6)]
        frames: usize,
        /// Output PNG.
        #[arg(long, default_value = "fpv.png")]
        out: PathBuf,
    },
    /// The top-down map of an evaluated episode: executed path over the reference, the
    /// scene's landmarks, the goal and its success circle.
    Map {
        /// episodes.jsonl of `aeris eval`.
        #[arg(long, value_name = "EPISODES_JSONL")]
        run: PathBuf,
        /// Episode id (default: the first line).
        #[arg(long)]
        episode: Option<String>,
        /// Output PNG.
        #[arg(long, default_value = "map.png")]
        out: PathBuf,
    },
    /// A formation flight: one top-down panel per phase, each vehicle's track in its colour
    /// and the slots the phase ends on (`formation.json` of the run folder, written by
    /// `aeris formation plan --run DIR`).
    Formation {
        /// The run folder (holds formation.json).
        #[arg(long)]
        run: PathBuf,
        /// Output PNG.
        #[arg(long, default_value = "formation.png")]
        out: PathBuf,
    },
}

/// Run `aeris plot`.
pub fn run(args: PlotArgs) -> Result<()> {
    match args.command {
        PlotCommand::Formation { run, out } => {
            use aeris_eval::formation_plot::{
                FORMATION_TRACKS_FILE, FormationTracks, formation_chart,
            };
            let path = run.join(FORMATION_TRACKS_FILE);
            let text = std::fs::read_to_string(&path)
                .with_context(|| format!("reading {}", path.display()))?;
            let tracks: FormationTracks = serde_json::from_str(&text).with_context(|| {
                format!("{} is not a formation flight's tracks", path.display())
            })?;
            save_png(&formation_chart(&tracks)?, &out)?;
            println!(
                "{} vehicles, {} phases, {:.1} s ({})",
                tracks.vehicles,
                tracks.phases.len(),
                tracks.points.last().map_or(0.0, |p| p.t_s),
                tracks.source
            );
            println!("wrote {}", out.display());
            Ok(())
        }
        PlotCommand::Timing { run, out } => {
            let trace = read_trace(&run)?;
            let spec = read_spec(&run)?;
            let deadline_s = spec.timing.decision_deadline_ms as f64 * 1e-3;
            let bars: Vec<TimingBar> = trace
                .iter()
                .map(|c| TimingBar {
                    stages_s: c.stages_s,
                    committed: c.committed,
                    reused: c.reused,
                })
                .collect();
            save_png(&timing_chart(&bars, deadline_s)?, &out)?;
            let committed = trace.iter().filter(|c| c.committed).count();
            let reused = trace.iter().filter(|c| c.reused).count();
            println!(
                "{} cycles: {committed} committed, {reused} reused; deadline {deadline_s:.1} s",
                trace.len()
            );
            println!("wrote {}", out.display());
            Ok(())
        }
        PlotCommand::Fpv { run, frames, out } => {
            if frames == 0 || frames > 24 {
                bail!("--frames must be 1..=24");
            }
            let trace = read_trace(&run)?;
            let spec = read_spec(&run)?;
            let mission = &spec.mission;
            let world = World::builtin(&mission.world).with_context(|| {
                format!(
                    "the flight's scene `{}` is not one this simulator has",
                    mission.world
                )
            })?;
            let posed: Vec<&CycleTrace> = trace
                .iter()
                .filter(|c| c.position.is_some() && c.yaw.is_some())
                .collect();
            if posed.is_empty() {
                bail!("{} has no cycle with a vehicle pose", run.display());
            }
            let cam = &spec.camera;
            let renderer = Renderer::new(cam.width, cam.height, cam.hfov_deg.to_radians())?;
            let mut rgb = vec![0u8; renderer.rgb_len()];
            let mut depth = vec![0u8; renderer.depth_len()];
            let n = frames.min(posed.len());
            let mut strip = Vec::with_capacity(n);
            for k in 0..n {
                let c = posed[if n == 1 {
                    0
                } else {
                    k * (posed.len() - 1) / (n - 1)
                }];
                let (Some(p), Some(yaw)) = (c.position, c.yaw) else {
                    continue;
                };
                renderer.render(
                    &world,
                    [p[0], p[1], p[2] + CAMERA_MOUNT_HEIGHT_M],
                    yaw,
                    &mut rgb,
                    &mut depth,
                )?;
                let img = image::RgbImage::from_raw(cam.width, cam.height, rgb.clone())
                    .context("frame size does not match the renderer")?;
                let step = usize::from(c.active_step);
                let text = step
                    .checked_sub(1)
                    .and_then(|i| mission.subgoals.get(i))
                    .map(|s| s.text.as_str())
                    .unwrap_or("waiting for the first decision");
                let caption = format!("T {:.0} S  STEP {step}  {}", c.t_s, text.to_uppercase());
                strip.push((img, caption));
            }
            save_png(&fpv_strip(&strip)?, &out)?;
            println!("{n} frames of {} cycles with a pose", posed.len());
            println!("wrote {}", out.display());
            Ok(())
        }
        PlotCommand::Map { run, episode, out } => {
            crate::scene_cmd::run_map(&run, episode.as_deref(), None, &out)
        }
    }
}

/// The rows of `run/cycles.jsonl`.
fn read_trace(run: &Path) -> Result<Vec<CycleTrace>> {
    let path = run.join("cycles.jsonl");
    let file = std::fs::File::open(&path).with_context(|| {
        format!(
            "cannot open {} (a flight's run folder holds it once the flight has ended)",
            path.display()
        )
    })?;
    let mut out = Vec::new();
    for (i, line) in std::io::BufReader::new(file).lines().enumerate() {
        let line = line.with_context(|| format!("reading {}", path.display()))?;
        if line.trim().is_empty() {
            continue;
        }
        out.push(
            serde_json::from_str(&line)
                .with_context(|| format!("{} line {}", path.display(), i + 1))?,
        );
    }
    if out.is_empty() {
        bail!("{} has no cycles", path.display());
    }
    Ok(out)
}

/// The hub's role spec in `run/roles/` (mission, timing and camera of the flight).
fn read_spec(run: &Path) -> Result<RoleSpec> {
    let dir = run.join("roles");
    let entries = std::fs::read_dir(&dir)
        .with_context(|| format!("cannot list {} (not a flight's run folder?)", dir.display()))?;
    let mut files: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "json"))
        .collect();
    files.sort();
    let hub = files
        .iter()
        .find(|p| p.file_stem().is_some_and(|s| s == "hub"))
        .or(files.first())
        .with_context(|| format!("no role spec in {}", dir.display()))?;
    RoleSpec::load(hub).with_context(|| format!("reading {}", hub.display()))
}

impl crate::command::Execute for PlotArgs {
    fn execute(self) -> anyhow::Result<std::process::ExitCode> {
        run(self)?;
        Ok(std::process::ExitCode::SUCCESS)
    }
}
