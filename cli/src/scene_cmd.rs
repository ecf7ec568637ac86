//! `aeris scene ...`: a scene's landmarks, its FPV frames, video and top-down maps.

use aeris_eval::episode::load_episodes;
use aeris_eval::plot::{MapLayers, save_png, top_down};
use aeris_eval::table::ExecutedEpisode;
use aeris_sim::render::{CAMERA_MOUNT_HEIGHT_M, Renderer};
use aeris_sim::world::World;
use anyhow::{Context, bail};
use clap::{Args, Subcommand};
use std::path::{Path, PathBuf};

/// Arguments of `aeris scene`.
#[derive(Debug, Args)]
pub struct SceneArgs {
    #[command(subcommand)]
    pub command: SceneCommand,
}

/// What `aeris scene` does.
#[derive(Debug, Subcommand)]
pub enum SceneCommand {
    /// List a scene's landmarks (built-in: village, open; generated: open-SEED,
    /// dense-SEED).
    Show {
        /// Scene name.
        scene: String,
    },
    /// Render the FPV camera's RGB frame (and optionally depth) from a pose, as PNG.
    Render {
        /// Scene name.
        scene: String,
        /// Vehicle position N,E,U (m).
        #[arg(
            long,
            value_delimiter = ',',
            allow_hyphen_values = true,
            required = true
        )]
        at: Vec<f32>,
        /// Heading (degrees, 0 = north, clockwise).
        #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
        yaw: f32,
        /// Frame width (pixels).
        #[arg(long, default_value_t = 320)]
        width: u32,
        /// Frame height (pixels).
        #[arg(long, default_value_t = 240)]
        height: u32,
        /// Horizontal field of view (degrees).
        #[arg(long, default_value_t = 90.0)]
        hfov: f32,
        /// Output PNG.
        #[arg(long)]
        out: PathBuf,
        /// Also write the depth frame (grey, near = dark, 0-65 m) to this PNG.
        #[arg(long)]
        depth_out: Option<PathBuf>,
    },
    /// Render the scene as H.264 video: along a path into an MP4 file or an RTP/UDP stream,
    /// or following a running flight's vehicle (a simulated FPV transmitter for a flight
    /// whose camera is the `gstreamer` variant).
    Video(crate::scene_video_cmd::VideoArgs),
    /// Draw the scene from above, with an episode's reference path, or an evaluated
    /// episode's executed trajectory over its reference.
    Map {
        /// Scene name; with --episodes, defaults to the episode's scene.
        scene: Option<String>,
        /// Episode file to take the reference path from.
        #[arg(long)]
        episodes: Option<PathBuf>,
        /// Episode id in that file (default: the first).
        #[arg(long)]
        episode: Option<String>,
        /// episodes.jsonl of `aeris eval`: draw the episode's executed trajectory (red) over
        /// its reference (white).
        #[arg(long, value_name = "EPISODES_JSONL", conflicts_with = "episodes")]
        run: Option<PathBuf>,
        /// Output PNG.
        #[arg(long)]
        out: PathBuf,
    },
}

fn world(name: &str) -> anyhow::Result<World> {
    World::builtin(name)
        .with_context(|| format!("unknown scene `{name}`; scenes are: {}", World::NAMES_HELP))
}

/// Run `aeris scene`.
pub fn scene(args: SceneArgs) -> anyhow::Result<()> {
    match args.command {
        SceneCommand::Video(args) => crate::scene_video_cmd::run(args),
        SceneCommand::Show { scene } => {
            let w = world(&scene)?;
            println!("{}: {} landmarks", w.name, w.landmarks.len());
            for l in &w.landmarks {
                println!(
                    "  {:<40} N {:7.1}..{:7.1}  E {:7.1}..{:7.1}  top {:5.1} m{}",
                    l.name,
                    l.min[0],
                    l.max[0],
                    l.min[1],
                    l.max[1],
                    l.max[2],
                    if l.is_referable() {
                        ""
                    } else {
                        "  (not named in instructions)"
                    }
                );
            }
            for a in &w.areas {
                println!(
                    "  {:<40} N {:7.1}..{:7.1}  E {:7.1}..{:7.1}  (area)",
                    a.name, a.min[0], a.max[0], a.min[1], a.max[1]
                );
            }
            Ok(())
        }
        SceneCommand::Render {
            scene,
            at,
            yaw,
            width,
            height,
            hfov,
            out,
            depth_out,
        } => {
            let w = world(&scene)?;
            let [n, e, u] = at[..] else {
                bail!("--at takes three numbers N,E,U");
            };
            let r = Renderer::new(width, height, hfov.to_radians())?;
            let mut rgb = vec![0u8; r.rgb_len()];
            let mut depth = vec![0u8; r.depth_len()];
            r.render(
                &w,
                [n, e, u + CAMERA_MOUNT_HEIGHT_M],
                yaw.to_radians(),
                &mut rgb,
                &mut depth,
            )?;
            let img = image::RgbImage::from_raw(width, height, rgb)
                .context("frame size does not match the renderer")?;
            save_png(&img, &out)?;
            println!("wrote {}", out.display());
            if let Some(path) = depth_out {
                let grey: Vec<u8> = depth
                    .chunks_exact(2)
                    .map(|c| {
                        let mm = u16::from_le_bytes([c[0], c[1]]);
                        if mm == 0 { 255 } else { (mm / 257) as u8 }
                    })
                    .collect();
                let img = image::GrayImage::from_raw(width, height, grey)
                    .context("depth size does not match the renderer")?;
                img.save_with_format(&path, image::ImageFormat::Png)
                    .with_context(|| format!("cannot write {}", path.display()))?;
                println!("wrote {}", path.display());
            }
            Ok(())
        }
        SceneCommand::Map {
            scene,
            episodes: _,
            episode,
            run: Some(file),
            out,
        } => run_map(&file, episode.as_deref(), scene.as_deref(), &out),
        SceneCommand::Map {
            scene,
            episodes,
            episode,
            run: None,
            out,
        } => {
            let chosen = match &episodes {
                Some(file) => {
                    let list = load_episodes(file)?;
                    let e = match &episode {
                        Some(id) => list
                            .into_iter()
                            .find(|e| &e.episode_id == id)
                            .with_context(|| format!("no episode `{id}` in {}", file.display()))?,
                        None => list
                            .into_iter()
                            .next()
                            .with_context(|| format!("{} has no episodes", file.display()))?,
                    };
                    Some(e)
                }
                None => None,
            };
            let name = match (&scene, &chosen) {
                (Some(s), _) => s.clone(),
                (None, Some(e)) => e.scene_id.clone(),
                (None, None) => bail!("give a scene name or --episodes"),
            };
            let w = world(&name)?;
            let reference = chosen
                .as_ref()
                .map(|e| e.reference_positions())
                .unwrap_or_default();
            let layers = MapLayers {
                reference: &reference,
                executed: &[],
                goal: chosen.as_ref().map(|e| e.goal()),
            };
            save_png(&top_down(&w, &layers)?, &out)?;
            if let Some(e) = &chosen {
                println!("{}: {}", e.episode_id, e.instruction.instruction_text);
            }
            println!("wrote {}", out.display());
            Ok(())
        }
    }
}

/// The top-down map of one evaluated episode of `file` (episodes.jsonl of `aeris eval`):
/// its executed path over its reference, in its scene (or `scene`), written to `out`.
pub fn run_map(
    file: &Path,
    episode: Option<&str>,
    scene: Option<&str>,
    out: &Path,
) -> anyhow::Result<()> {
    let r = ExecutedEpisode::read(file, episode)?;
    let w = world(scene.unwrap_or(&r.scene_id))?;
    let layers = MapLayers {
        reference: &r.reference,
        executed: &r.positions,
        goal: Some(r.goal),
    };
    save_png(&top_down(&w, &layers)?, out)?;
    println!("{}: executed (red) over reference (white)", r.episode_id);
    println!("wrote {}", out.display());
    Ok(())
}

impl crate::command::Execute for SceneArgs {
    fn execute(self) -> anyhow::Result<std::process::ExitCode> {
        scene(self)?;
        Ok(std::process::ExitCode::SUCCESS)
    }
}
