//! Top-down maps: a scene's landmarks with a reference and an executed trajectory, as PNG.
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
    /// Writing the PNG failed.
    #[error("cannot write {path}: {source}")]
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

/// Write `img` as PNG to `path`.
pub fn save_png(img: &RgbImage, path: &Path) -> Result<(), PlotError> {
    img.save_with_format(path, image::ImageFormat::Png)
        .map_err(|source| PlotError::Write {
            path: path.to_path_buf(),
            source,
        })
}
