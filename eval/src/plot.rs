//! The evaluation's pictures, as PNG:
//! - [`top_down`]: a scene's landmarks with a reference and an executed trajectory;
//! - [`timing_chart`]: the heartbeat timing trace of a flight, one stacked bar per semantic
//!   cycle (perception, reasoning, routing, binding), a commit mark over every cycle that
//!   committed a fresh decision and a red cross under every cycle that reused the last one,
//!   and the deadline as a dashed line;
//! - [`fpv_strip`]: FPV frames side by side, each captioned with the instruction step that
//!   was active.
//!
//! Captions use the renderer's 5x7 font (letters, digits; other characters are blank).
//!
//! North is up, east to the right. Landmarks are drawn in their roof colours (ground
//! patches in their own), areas as outlines; the reference path is white, the executed
//! path red, the start a black square, the goal a black cross inside its 20 m success
//! circle.

use aeris_sim::world::{Extent, LandmarkKind, World};
use image::{Rgb, RgbImage};
use imageproc::drawing::{
    draw_cross_mut, draw_filled_rect_mut, draw_hollow_circle_mut, draw_hollow_rect_mut,
    draw_line_segment_mut,
};
use imageproc::rect::Rect;
use std::path::{Path, PathBuf};

/// Pixels per metre of the maps.
pub const PIXELS_PER_M: f32 = 2.0;
/// Colour of the reference path.
pub const REFERENCE: [u8; 3] = [255, 255, 255];
/// Colour of the executed path.
pub const EXECUTED: [u8; 3] = [230, 20, 20];
const GRASS: [u8; 3] = [150, 186, 120];
const INK: [u8; 3] = [0, 0, 0];

/// Why a picture could not be made.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// The picture would be empty or larger than 8192 pixels a side.
    #[error("the map would be {width}x{height} pixels (1..=8192 a side)")]
    Size {
        /// Width.
        width: u32,
        /// Height.
        height: u32,
    },
    /// There is nothing to draw.
    #[error("nothing to draw: {0}")]
    Empty(&'static str),
    /// Writing the PNG failed.
    #[error("cannot write {path}")]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        source: image::ImageError,
    },
}

/// What a map shows besides the scene.
#[derive(Debug, Clone, Default)]
pub struct MapLayers<'a> {
    /// Reference positions `[N, E, U]`.
    pub reference: &'a [[f64; 3]],
    /// Executed positions `[N, E, U]`.
    pub executed: &'a [[f64; 3]],
    /// The goal, with its success circle.
    pub goal: Option<[f64; 3]>,
}

/// The top-down map of `world` with `layers`, covering every landmark and path with a
/// 20 m margin.
pub fn top_down(world: &World, layers: &MapLayers<'_>) -> Result<RgbImage, PlotError> {
    let mut x = world.extent();
    let points = layers
        .reference
        .iter()
        .chain(layers.executed)
        .chain(&layers.goal);
    for p in points {
        let p = [p[0] as f32, p[1] as f32, p[2] as f32];
        match &mut x {
            Some(x) => x.include(p),
            None => x = Some(Extent::around(p)),
        }
    }
    let x = x.unwrap_or(Extent {
        min: [-50.0, -50.0, 0.0],
        max: [50.0, 50.0, 0.0],
    });
    let (lo, hi) = ([x.min[0], x.min[1]], [x.max[0], x.max[1]]);
    let margin = 20.0;
    let (lo, hi) = (
        [lo[0] - margin, lo[1] - margin],
        [hi[0] + margin, hi[1] + margin],
    );
    let width = ((hi[1] - lo[1]) * PIXELS_PER_M).ceil() as u32;
    let height = ((hi[0] - lo[0]) * PIXELS_PER_M).ceil() as u32;
    if !(1..=8192).contains(&width) || !(1..=8192).contains(&height) {
        return Err(PlotError::Size { width, height });
    }
    // pixel of (n, e): x grows east, y grows south
    let px = |n: f32, e: f32| ((e - lo[1]) * PIXELS_PER_M, (hi[0] - n) * PIXELS_PER_M);
    let mut img = RgbImage::from_pixel(width, height, Rgb(GRASS));
    // ground patches first, then obstacles by height so tall ones are on top
    let mut order: Vec<usize> = (0..world.landmarks.len()).collect();
    order.sort_by(|&a, &b| {
        let (la, lb) = (&world.landmarks[a], &world.landmarks[b]);
        (la.is_obstacle(), la.max[2])
            .partial_cmp(&(lb.is_obstacle(), lb.max[2]))
            .unwrap_or(core::cmp::Ordering::Equal)
    });
    for i in order {
        let l = &world.landmarks[i];
        let (x0, y0) = px(l.max[0], l.min[1]);
        let (x1, y1) = px(l.min[0], l.max[1]);
        let rect = Rect::at(x0.floor() as i32, y0.floor() as i32).of_size(
            ((x1 - x0).ceil() as u32).max(1),
            ((y1 - y0).ceil() as u32).max(1),
        );
        draw_filled_rect_mut(&mut img, rect, Rgb(l.roof));
        if l.is_obstacle() && !matches!(l.kind, LandmarkKind::Tree) {
            draw_hollow_rect_mut(&mut img, rect, Rgb(INK));
        }
    }
    for a in &world.areas {
        let (x0, y0) = px(a.max[0], a.min[1]);
        let (x1, y1) = px(a.min[0], a.max[1]);
        let rect = Rect::at(x0 as i32, y0 as i32)
            .of_size(((x1 - x0) as u32).max(1), ((y1 - y0) as u32).max(1));
        draw_hollow_rect_mut(&mut img, rect, Rgb([20, 70, 20]));
    }
    let polyline = |img: &mut RgbImage, pts: &[[f64; 3]], colour: [u8; 3]| {
        for w in pts.windows(2) {
            let a = px(w[0][0] as f32, w[0][1] as f32);
            let b = px(w[1][0] as f32, w[1][1] as f32);
            // three pixels wide
            for (dx, dy) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)] {
                draw_line_segment_mut(img, (a.0 + dx, a.1 + dy), (b.0 + dx, b.1 + dy), Rgb(colour));
            }
        }
    };
    polyline(&mut img, layers.reference, REFERENCE);
    polyline(&mut img, layers.executed, EXECUTED);
    let start = layers.reference.first().or(layers.executed.first());
    if let Some(s) = start {
        let (x, y) = px(s[0] as f32, s[1] as f32);
        draw_filled_rect_mut(
            &mut img,
            Rect::at(x as i32 - 4, y as i32 - 4).of_size(9, 9),
            Rgb(INK),
        );
    }
    if let Some(g) = layers.goal {
        let (x, y) = px(g[0] as f32, g[1] as f32);
        let r = (crate::metrics::SUCCESS_RADIUS_M as f32 * PIXELS_PER_M) as i32;
        draw_hollow_circle_mut(&mut img, (x as i32, y as i32), r, Rgb(INK));
        draw_cross_mut(&mut img, Rgb(INK), x as i32, y as i32);
    }
    Ok(img)
}

/// Colours of the timing stages: perception, reasoning, routing, binding.
pub const STAGE_COLOURS: [[u8; 3]; 4] = [
    [60, 110, 220],
    [240, 150, 30],
    [40, 170, 80],
    [150, 70, 190],
];
/// Names of the timing stages, in [`STAGE_COLOURS`]' order.
pub const STAGE_NAMES: [&str; 4] = ["perception", "reasoning", "routing", "binding"];
const DEADLINE: [u8; 3] = [220, 30, 30];
const PAPER: [u8; 3] = [255, 255, 255];

/// Draw `text` with its top-left corner at `(x, y)`, each font pixel `scale` pixels wide.
pub fn draw_text(img: &mut RgbImage, x: i32, y: i32, text: &str, scale: u32, colour: [u8; 3]) {
    let s = scale.max(1) as i32;
    for (k, b) in text.bytes().enumerate() {
        let mut rows = aeris_sim::render::glyph(b);
        match b {
            b'.' => rows[6] = 0b00100,
            b'-' => rows[3] = 0b01110,
            b':' => (rows[2], rows[5]) = (0b00100, 0b00100),
            _ => {}
        }
        for (gy, bits) in rows.iter().enumerate() {
            for gx in 0..5 {
                if bits & (0b10000 >> gx) == 0 {
                    continue;
                }
                let (px, py) = (x + (k as i32 * 6 + gx) * s, y + gy as i32 * s);
                if px >= 0 && py >= 0 {
                    draw_filled_rect_mut(
                        img,
                        Rect::at(px, py).of_size(s as u32, s as u32),
                        Rgb(colour),
                    );
                }
            }
        }
    }
}

/// Width in pixels of `text` drawn at `scale`.
pub fn text_width(text: &str, scale: u32) -> u32 {
    (text.len() as u32 * 6).saturating_sub(1) * scale.max(1)
}

/// One semantic cycle of a timing chart.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TimingBar {
    /// Stage durations (s): perception, reasoning, routing, binding.
    pub stages_s: [f64; 4],
    /// A fresh decision was committed.
    pub committed: bool,
    /// The last valid decision was reused.
    pub reused: bool,
}

/// The heartbeat timing chart of `bars` (oldest first) with the deadline at `deadline_s`.
pub fn timing_chart(bars: &[TimingBar], deadline_s: f64) -> Result<RgbImage, PlotError> {
    const PLOT_H: u32 = 240;
    const LEFT: u32 = 56;
    const TOP: u32 = 40;
    const BOTTOM: u32 = 40;
    let bar_w: u32 = match bars.len() {
        0..=60 => 10,
        61..=150 => 5,
        151..=400 => 2,
        _ => 1,
    };
    let width = LEFT + 16 + (bars.len() as u32).max(1) * bar_w;
    let width = width.max(560);
    let height = TOP + PLOT_H + BOTTOM;
    if width > 8192 {
        return Err(PlotError::Size { width, height });
    }
    let total = |b: &TimingBar| b.stages_s.iter().map(|v| v.max(0.0)).sum::<f64>();
    let top_s = bars
        .iter()
        .map(total)
        .fold(deadline_s.max(0.1) * 1.25, f64::max);
    let mut img = RgbImage::from_pixel(width, height, Rgb(PAPER));
    let y_of = |t: f64| TOP as f32 + PLOT_H as f32 * (1.0 - (t / top_s) as f32);
    // axis and ticks every 0.5 s
    draw_line_segment_mut(
        &mut img,
        (LEFT as f32 - 1.0, TOP as f32),
        (LEFT as f32 - 1.0, (TOP + PLOT_H) as f32),
        Rgb(INK),
    );
    draw_line_segment_mut(
        &mut img,
        (LEFT as f32 - 1.0, (TOP + PLOT_H) as f32),
        (width as f32 - 8.0, (TOP + PLOT_H) as f32),
        Rgb(INK),
    );
    let mut tick = 0.0;
    while tick <= top_s {
        let y = y_of(tick);
        draw_line_segment_mut(
            &mut img,
            (LEFT as f32 - 5.0, y),
            (LEFT as f32 - 1.0, y),
            Rgb(INK),
        );
        let label = format!("{tick:.1}");
        draw_text(
            &mut img,
            LEFT as i32 - 8 - text_width(&label, 1) as i32,
            y as i32 - 3,
            &label,
            1,
            INK,
        );
        tick += 0.5;
    }
    draw_text(&mut img, 4, TOP as i32 - 14, "S", 1, INK);
    for (i, b) in bars.iter().enumerate() {
        let x = (LEFT + i as u32 * bar_w) as i32;
        let mut t = 0.0;
        for (k, v) in b.stages_s.iter().enumerate() {
            let v = v.max(0.0);
            let (y0, y1) = (y_of(t + v), y_of(t));
            let h = (y1 - y0).round() as u32;
            if h > 0 {
                draw_filled_rect_mut(
                    &mut img,
                    Rect::at(x, y0.round() as i32)
                        .of_size(bar_w.saturating_sub(u32::from(bar_w > 2)).max(1), h),
                    Rgb(STAGE_COLOURS[k]),
                );
            }
            t += v;
        }
        let cx = x + bar_w as i32 / 2;
        if b.committed {
            // commit mark: a small black tick over the bar
            let y = y_of(t) as i32 - 6;
            draw_filled_rect_mut(&mut img, Rect::at(cx - 1, y).of_size(3, 4), Rgb(INK));
        }
        if b.reused {
            draw_cross_mut(&mut img, Rgb(DEADLINE), cx, (TOP + PLOT_H + 6) as i32);
        }
    }
    // the deadline, dashed
    let yd = y_of(deadline_s);
    let mut x = LEFT as f32;
    while x < width as f32 - 8.0 {
        draw_line_segment_mut(
            &mut img,
            (x, yd),
            ((x + 6.0).min(width as f32 - 8.0), yd),
            Rgb(DEADLINE),
        );
        draw_line_segment_mut(
            &mut img,
            (x, yd + 1.0),
            ((x + 6.0).min(width as f32 - 8.0), yd + 1.0),
            Rgb(DEADLINE),
        );
        x += 10.0;
    }
    // legend
    let mut lx = LEFT as i32;
    for (name, colour) in STAGE_NAMES.iter().zip(STAGE_COLOURS) {
        draw_filled_rect_mut(&mut img, Rect::at(lx, 12).of_size(10, 10), Rgb(colour));
        draw_text(&mut img, lx + 14, 13, name, 1, INK);
        lx += 14 + text_width(name, 1) as i32 + 16;
    }
    draw_line_segment_mut(
        &mut img,
        (lx as f32, 17.0),
        (lx as f32 + 12.0, 17.0),
        Rgb(DEADLINE),
    );
    draw_text(&mut img, lx + 16, 13, "deadline", 1, INK);
    let caption = format!("{} cycles  x reused", bars.len());
    draw_text(
        &mut img,
        LEFT as i32,
        (TOP + PLOT_H + 20) as i32,
        &caption,
        1,
        INK,
    );
    Ok(img)
}

/// Frames side by side (all of one size), each with its caption under it (wrapped to the
/// frame's width, at most three lines).
pub fn fpv_strip(frames: &[(RgbImage, String)]) -> Result<RgbImage, PlotError> {
    let (fw, fh) = frames.first().map_or((0, 0), |(f, _)| f.dimensions());
    const GAP: u32 = 4;
    const CAPTION_H: u32 = 3 * 10 + 8;
    let n = frames.len() as u32;
    let width = n * fw + (n + 1) * GAP;
    let height = fh + CAPTION_H + 2 * GAP;
    if fw == 0 || !(1..=8192).contains(&width) || height > 8192 {
        return Err(PlotError::Size { width, height });
    }
    let mut img = RgbImage::from_pixel(width, height, Rgb(PAPER));
    let per_line = ((fw / 6).max(1)) as usize;
    for (k, (frame, caption)) in frames.iter().enumerate() {
        if frame.dimensions() != (fw, fh) {
            return Err(PlotError::Size {
                width: frame.width(),
                height: frame.height(),
            });
        }
        let x0 = GAP + k as u32 * (fw + GAP);
        image::imageops::replace(&mut img, frame, i64::from(x0), i64::from(GAP));
        let mut line = String::new();
        let mut y = (GAP + fh + 6) as i32;
        let mut lines = 0;
        for word in caption.split_whitespace() {
            if !line.is_empty() && line.len() + 1 + word.len() > per_line {
                draw_text(&mut img, x0 as i32, y, &line, 1, INK);
                y += 10;
                lines += 1;
                line.clear();
                if lines == 3 {
                    break;
                }
            }
            if !line.is_empty() {
                line.push(' ');
            }
            line.push_str(word);
        }
        if lines < 3 && !line.is_empty() {
            draw_text(&mut img, x0 as i32, y, &line, 1, INK);
        }
    }
    Ok(img)
}

/// Write `img` as PNG to `path`.
pub fn save_png(img: &RgbImage, path: &Path) -> Result<(), PlotError> {
    img.save_with_format(path, image::ImageFormat::Png)
        .map_err(|source| PlotError::Write {
            path: path.to_path_buf(),
            source,
        })
}
