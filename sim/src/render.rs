//! A CPU ray-caster that renders FPV RGB8 and depth frames of a [`World`].
//!
//! Camera model: [`aeris_geometry::camera`] (re-exported here: [`CameraModel`],
//! [`CAMERA_MOUNT_HEIGHT_M`], [`CAMERA_PITCH_RAD`], [`body_to_world`]), shared with the
//! consumers of the frames: a pinhole camera on a stabilised mount above the vehicle's
//! reference point, looking along the vehicle's yaw and pitched down.
//!
//! Depth frames hold, per pixel, the **z-depth** (distance along the optical axis, like
//! RGB-D cameras) in millimetres as little-endian `u16`. 0 means no return: sky, or a
//! surface farther than [`MAX_DEPTH_M`] along the axis. A point is recovered as
//! `camera + z * world_ray` with [`CameraModel::pixel_ray`] rotated by
//! [`body_to_world`].
//!
//! Shading is flat per face ([`face_shade`]), so every rendered colour is a palette colour
//! times one of [`FACE_SHADES`] (rounded): perception can segment exactly. Buildings show
//! their roof colour on a band of [`ROOF_BAND_M`] at the top of their walls (eaves), so a
//! roof colour is visible from below the roof.

use crate::world::{GROUND, LandmarkKind, World, palette};
pub use aeris_geometry::camera::{
    CAMERA_MOUNT_HEIGHT_M, CAMERA_PITCH_RAD, CameraModel, CameraModelError, body_to_world,
};

/// Largest z-depth a depth frame can hold (m); farther surfaces read 0 (no return).
pub const MAX_DEPTH_M: f32 = 65.535;
/// Rays are traced this far (m); beyond, grass (looking down) or sky is drawn.
pub const MAX_RANGE_M: f32 = 2000.0;
/// Height (m) of the band under a building's roof that shows the roof colour.
pub const ROOF_BAND_M: f32 = 2.0;
/// Sky colour at the horizon.
pub const SKY_HORIZON: [u8; 3] = [206, 222, 240];
/// Sky colour at the zenith.
pub const SKY_ZENITH: [u8; 3] = [112, 160, 226];
/// Brightness factor of faces by outward normal: up, down, north, south, east, west.
pub const FACE_SHADES: [f32; 6] = [1.0, 0.55, 0.62, 0.92, 0.8, 0.7];

/// Brightness factor of a face with the axis-aligned outward `normal` (sun high in the
/// south-east).
#[inline]
pub fn face_shade(normal: [f32; 3]) -> f32 {
    if normal[2] > 0.5 {
        FACE_SHADES[0]
    } else if normal[2] < -0.5 {
        FACE_SHADES[1]
    } else if normal[0] > 0.5 {
        FACE_SHADES[2]
    } else if normal[0] < -0.5 {
        FACE_SHADES[3]
    } else if normal[1] > 0.5 {
        FACE_SHADES[4]
    } else {
        FACE_SHADES[5]
    }
}

/// `colour * shade`, rounded; how the renderer shades every surface.
#[inline]
pub fn shaded(colour: [u8; 3], shade: f32) -> [u8; 3] {
    let s = |c: u8| (c as f32 * shade + 0.5).clamp(0.0, 255.0) as u8;
    [s(colour[0]), s(colour[1]), s(colour[2])]
}

/// Why a renderer could not be built or could not render.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum RenderError {
    /// The camera model is unusable.
    #[error(transparent)]
    Camera(#[from] CameraModelError),
    /// An output buffer has the wrong length.
    #[error("{which} buffer is {actual} bytes, expected {expected}")]
    BufferSize {
        /// "rgb" or "depth".
        which: &'static str,
        /// Expected bytes.
        expected: usize,
        /// Actual bytes.
        actual: usize,
    },
    /// The camera position or yaw is not finite.
    #[error("camera pose is not finite")]
    BadPose,
}

/// Renders frames of a world; all per-pixel rays are computed once here.
#[derive(Debug, Clone)]
pub struct Renderer {
    camera: CameraModel,
    /// Unit ray per pixel in the level vehicle frame, and 1 / |ray| of the axis-scaled
    /// ray (turns a distance along the unit ray into z-depth).
    rays: Vec<[f32; 4]>,
}

impl Renderer {
    /// A renderer for `width` x `height` frames with horizontal field of view `hfov_rad`
    /// and the standard pitch [`CAMERA_PITCH_RAD`].
    pub fn new(width: u32, height: u32, hfov_rad: f32) -> Result<Self, RenderError> {
        Self::with_camera(CameraModel::new(width, height, hfov_rad)?)
    }

    /// A renderer for an explicit camera model.
    pub fn with_camera(camera: CameraModel) -> Result<Self, RenderError> {
        let mut rays = Vec::with_capacity(camera.width as usize * camera.height as usize);
        for row in 0..camera.height {
            for col in 0..camera.width {
                let r = camera.pixel_ray(col, row);
                let n = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
                rays.push([r[0] / n, r[1] / n, r[2] / n, 1.0 / n]);
            }
        }
        Ok(Self { camera, rays })
    }

    /// The camera model.
    pub fn camera(&self) -> &CameraModel {
        &self.camera
    }

    /// Bytes of an RGB8 frame.
    pub fn rgb_len(&self) -> usize {
        self.rays.len() * 3
    }

    /// Bytes of a depth frame.
    pub fn depth_len(&self) -> usize {
        self.rays.len() * 2
    }

    /// Render `world` from the camera at `position` `[N, E, U]` (the camera itself, mount
    /// height included) looking along `yaw` into `rgb` (RGB8) and `depth_mm` (u16 LE mm).
    /// Never allocates.
    pub fn render(
        &self,
        world: &World,
        position: [f32; 3],
        yaw: f32,
        rgb: &mut [u8],
        depth_mm: &mut [u8],
    ) -> Result<(), RenderError> {
        if rgb.len() != self.rgb_len() {
            return Err(RenderError::BufferSize {
                which: "rgb",
                expected: self.rgb_len(),
                actual: rgb.len(),
            });
        }
        if depth_mm.len() != self.depth_len() {
            return Err(RenderError::BufferSize {
                which: "depth",
                expected: self.depth_len(),
                actual: depth_mm.len(),
            });
        }
        if !position.iter().all(|v| v.is_finite()) || !yaw.is_finite() {
            return Err(RenderError::BadPose);
        }
        let (s, c) = yaw.sin_cos();
        for ((ray, px), dpx) in self
            .rays
            .iter()
            .zip(rgb.chunks_exact_mut(3))
            .zip(depth_mm.chunks_exact_mut(2))
        {
            let dir = [ray[0] * c - ray[1] * s, ray[0] * s + ray[1] * c, ray[2]];
            let (colour, z) = match world.raycast(position, dir, MAX_RANGE_M) {
                Some(hit) => (
                    surface_colour(world, &hit, position, dir),
                    hit.distance * ray[3],
                ),
                // the ground plane goes on beyond the traced range
                None if dir[2] < 0.0 => (palette::GRASS, 0.0),
                None => (sky(dir[2]), 0.0),
            };
            px.copy_from_slice(&colour);
            let mm = (z * 1000.0).round();
            let d = if z <= 0.0 || mm > u16::MAX as f32 {
                0
            } else {
                (mm as u16).max(1)
            };
            dpx.copy_from_slice(&d.to_le_bytes());
        }
        Ok(())
    }
}

#[inline]
fn sky(up: f32) -> [u8; 3] {
    let t = up.clamp(0.0, 1.0).sqrt();
    let mix = |a: u8, b: u8| (a as f32 + (b as f32 - a as f32) * t + 0.5) as u8;
    [
        mix(SKY_HORIZON[0], SKY_ZENITH[0]),
        mix(SKY_HORIZON[1], SKY_ZENITH[1]),
        mix(SKY_HORIZON[2], SKY_ZENITH[2]),
    ]
}

#[inline]
fn surface_colour(
    world: &World,
    hit: &crate::world::Hit,
    origin: [f32; 3],
    dir: [f32; 3],
) -> [u8; 3] {
    let shade = face_shade(hit.normal);
    if hit.landmark == GROUND {
        return shaded(palette::GRASS, shade);
    }
    let Some(l) = world.landmarks.get(hit.landmark) else {
        return shaded(palette::GRASS, shade);
    };
    if hit.roof {
        return shaded(l.roof, shade);
    }
    let p = [
        origin[0] + dir[0] * hit.distance,
        origin[1] + dir[1] * hit.distance,
        origin[2] + dir[2] * hit.distance,
    ];
    match &l.kind {
        LandmarkKind::Building if p[2] > l.max[2] - ROOF_BAND_M => shaded(l.roof, shade),
        LandmarkKind::Sign { text } if sign_text_at(l, text, hit.normal, p) => {
            shaded(palette::SIGN_TEXT, shade)
        }
        _ => shaded(l.wall, shade),
    }
}

/// `true` when the point `p` on the face with `normal` of the sign box `l` is lettering.
/// Text is painted on the two large vertical faces, readable from in front of each.
fn sign_text_at(l: &crate::world::Landmark, text: &str, normal: [f32; 3], p: [f32; 3]) -> bool {
    let thin_north = (l.max[0] - l.min[0]) <= (l.max[1] - l.min[1]);
    // s: metres from the face's left edge as seen by a viewer facing it
    let (s, width) = if thin_north {
        let w = l.max[1] - l.min[1];
        if normal[0] > 0.5 {
            (l.max[1] - p[1], w)
        } else if normal[0] < -0.5 {
            (p[1] - l.min[1], w)
        } else {
            return false;
        }
    } else {
        let w = l.max[0] - l.min[0];
        if normal[1] > 0.5 {
            (p[0] - l.min[0], w)
        } else if normal[1] < -0.5 {
            (l.max[0] - p[0], w)
        } else {
            return false;
        }
    };
    let height = l.max[2] - l.min[2];
    let t = l.max[2] - p[2];
    let n = text.len();
    if n == 0 {
        return false;
    }
    let cols = (6 * n - 1) as f32;
    let cell = (width / (cols + 2.0)).min(height / 9.0);
    if cell <= 0.0 {
        return false;
    }
    let x0 = 0.5 * (width - cols * cell);
    let y0 = 0.5 * (height - 7.0 * cell);
    let gx = ((s - x0) / cell).floor();
    let gy = ((t - y0) / cell).floor();
    if gx < 0.0 || gy < 0.0 || gx >= cols || gy >= 7.0 {
        return false;
    }
    let (gx, gy) = (gx as usize, gy as usize);
    let (ch, col) = (gx / 6, gx % 6);
    if col == 5 {
        return false;
    }
    let Some(&b) = text.as_bytes().get(ch) else {
        return false;
    };
    glyph(b)[gy] & (0b10000 >> col) != 0
}

/// 5x7 bitmap of an ASCII letter or digit (rows top to bottom, bit 4 = leftmost column);
/// blank for anything else. Signs and plot captions share it.
pub fn glyph(b: u8) -> [u8; 7] {
    const LETTERS: [[u8; 7]; 26] = [
        [0x0E, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11], // A
        [0x1E, 0x11, 0x11, 0x1E, 0x11, 0x11, 0x1E], // B
        [0x0E, 0x11, 0x10, 0x10, 0x10, 0x11, 0x0E], // C
        [0x1C, 0x12, 0x11, 0x11, 0x11, 0x12, 0x1C], // D
        [0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x1F], // E
        [0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x10], // F
        [0x0E, 0x11, 0x10, 0x17, 0x11, 0x11, 0x0F], // G
        [0x11, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11], // H
        [0x0E, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E], // I
        [0x07, 0x02, 0x02, 0x02, 0x02, 0x12, 0x0C], // J
        [0x11, 0x12, 0x14, 0x18, 0x14, 0x12, 0x11], // K
        [0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x1F], // L
        [0x11, 0x1B, 0x15, 0x15, 0x11, 0x11, 0x11], // M
        [0x11, 0x11, 0x19, 0x15, 0x13, 0x11, 0x11], // N
        [0x0E, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E], // O
        [0x1E, 0x11, 0x11, 0x1E, 0x10, 0x10, 0x10], // P
        [0x0E, 0x11, 0x11, 0x11, 0x15, 0x12, 0x0D], // Q
        [0x1E, 0x11, 0x11, 0x1E, 0x14, 0x12, 0x11], // R
        [0x0F, 0x10, 0x10, 0x0E, 0x01, 0x01, 0x1E], // S
        [0x1F, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04], // T
        [0x11, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E], // U
        [0x11, 0x11, 0x11, 0x11, 0x11, 0x0A, 0x04], // V
        [0x11, 0x11, 0x11, 0x15, 0x15, 0x15, 0x0A], // W
        [0x11, 0x11, 0x0A, 0x04, 0x0A, 0x11, 0x11], // X
        [0x11, 0x11, 0x0A, 0x04, 0x04, 0x04, 0x04], // Y
        [0x1F, 0x01, 0x02, 0x04, 0x08, 0x10, 0x1F], // Z
    ];
    const DIGITS: [[u8; 7]; 10] = [
        [0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E], // 0
        [0x04, 0x0C, 0x04, 0x04, 0x04, 0x04, 0x0E], // 1
        [0x0E, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1F], // 2
        [0x1F, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0E], // 3
        [0x02, 0x06, 0x0A, 0x12, 0x1F, 0x02, 0x02], // 4
        [0x1F, 0x10, 0x1E, 0x01, 0x01, 0x11, 0x0E], // 5
        [0x06, 0x08, 0x10, 0x1E, 0x11, 0x11, 0x0E], // 6
        [0x1F, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08], // 7
        [0x0E, 0x11, 0x11, 0x0E, 0x11, 0x11, 0x0E], // 8
        [0x0E, 0x11, 0x11, 0x0F, 0x01, 0x02, 0x0C], // 9
    ];
    match b {
        b'A'..=b'Z' => LETTERS[(b - b'A') as usize],
        b'a'..=b'z' => LETTERS[(b - b'a') as usize],
        b'0'..=b'9' => DIGITS[(b - b'0') as usize],
        _ => [0; 7],
    }
}

/// A binary PPM (P6) image of an RGB8 frame, for snapshots and debugging.
pub fn ppm_bytes(width: u32, height: u32, rgb: &[u8]) -> Result<Vec<u8>, RenderError> {
    let expected = width as usize * height as usize * 3;
    if rgb.len() != expected {
        return Err(RenderError::BufferSize {
            which: "rgb",
            expected,
            actual: rgb.len(),
        });
    }
    let mut out = format!("P6\n{width} {height}\n255\n").into_bytes();
    out.extend_from_slice(rgb);
    Ok(out)
}
