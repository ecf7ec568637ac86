//! The FPV camera: a pinhole camera on a stabilised mount [`CAMERA_MOUNT_HEIGHT_M`] above
//! the vehicle's reference point, looking along the vehicle's yaw and pitched down by
//! [`CAMERA_PITCH_RAD`] (roll and pitch of the airframe are compensated by the mount).
//! Pixels are square; pixel `(col, row)` looks through its centre `(col + 0.5, row + 0.5)`;
//! rows go downwards.
//!
//! A depth frame's z-depth `z` (distance along the optical axis) at a pixel is the point
//! `camera + z * body_to_world(pixel_ray(col, row), yaw)`.

/// Downward pitch of the camera (rad): 15 degrees.
pub const CAMERA_PITCH_RAD: f32 = 15.0 * core::f32::consts::PI / 180.0;
/// Height of the camera above the vehicle's reference point (m).
pub const CAMERA_MOUNT_HEIGHT_M: f32 = 0.25;

/// Why a [`CameraModel`] could not be built.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum CameraModelError {
    /// Width/height zero or above 4096, or a field of view / pitch out of range.
    #[error(
        "camera geometry {width}x{height}, hfov {hfov} rad, pitch {pitch} rad is invalid \
         (sides 1..=4096, 0 < hfov < pi, |pitch| < pi/2)"
    )]
    BadGeometry {
        /// Width.
        width: u32,
        /// Height.
        height: u32,
        /// Horizontal field of view (rad).
        hfov: f32,
        /// Pitch (rad).
        pitch: f32,
    },
}

/// Geometry of the pinhole camera, shared by the renderer and by whoever back-projects
/// its frames.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraModel {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Horizontal field of view (rad).
    pub hfov: f32,
    /// Downward pitch (rad, positive looks down).
    pub pitch: f32,
}

impl CameraModel {
    /// A camera with the standard pitch [`CAMERA_PITCH_RAD`].
    pub fn new(width: u32, height: u32, hfov: f32) -> Result<Self, CameraModelError> {
        Self::with_pitch(width, height, hfov, CAMERA_PITCH_RAD)
    }

    /// A camera with an explicit downward `pitch`.
    pub fn with_pitch(
        width: u32,
        height: u32,
        hfov: f32,
        pitch: f32,
    ) -> Result<Self, CameraModelError> {
        let ok = (1..=4096).contains(&width)
            && (1..=4096).contains(&height)
            && hfov.is_finite()
            && hfov > 0.0
            && hfov < core::f32::consts::PI
            && pitch.is_finite()
            && pitch.abs() < core::f32::consts::FRAC_PI_2;
        if !ok {
            return Err(CameraModelError::BadGeometry {
                width,
                height,
                hfov,
                pitch,
            });
        }
        Ok(Self {
            width,
            height,
            hfov,
            pitch,
        })
    }

    /// Focal length in pixels.
    #[inline]
    pub fn focal_px(&self) -> f32 {
        0.5 * self.width as f32 / (0.5 * self.hfov).tan()
    }

    /// Ray through the image point `(x, y)` (pixels; pixel centres at `col + 0.5`) in the
    /// level vehicle frame `[forward, right, up]`, scaled so that its component along the
    /// optical axis is 1: the point at z-depth `z` is `z * ray`.
    #[inline]
    pub fn ray_at(&self, x: f32, y: f32) -> [f32; 3] {
        let f = self.focal_px();
        let rx = (x - 0.5 * self.width as f32) / f;
        let ry = (y - 0.5 * self.height as f32) / f;
        let (s, c) = self.pitch.sin_cos();
        // optical axis F = (c, 0, -s); right R = (0, 1, 0); camera up Uc = (s, 0, c)
        [c - ry * s, rx, -s - ry * c]
    }

    /// [`CameraModel::ray_at`] through the centre of pixel `(col, row)`.
    #[inline]
    pub fn pixel_ray(&self, col: u32, row: u32) -> [f32; 3] {
        self.ray_at(col as f32 + 0.5, row as f32 + 0.5)
    }

    /// Horizontal bearing (rad, positive right) of image column `x` (pixels) relative to
    /// the camera's heading.
    #[inline]
    pub fn bearing_of_column(&self, x: f32) -> f32 {
        ((x - 0.5 * self.width as f32) / self.focal_px()).atan()
    }
}

/// Rotate a vector of the level vehicle frame `[forward, right, up]` into `[N, E, U]` for
/// a vehicle at `yaw` (0 = north, positive towards east).
#[inline]
pub fn body_to_world(v: [f32; 3], yaw: f32) -> [f32; 3] {
    let (s, c) = yaw.sin_cos();
    [v[0] * c - v[1] * s, v[0] * s + v[1] * c, v[2]]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unusable_geometry_is_refused() {
        for (w, h, hfov, pitch) in [
            (0, 10, 1.0, 0.0),
            (10, 4097, 1.0, 0.0),
            (10, 10, 3.5, 0.0),
            (10, 10, 0.0, 0.0),
            (10, 10, f32::NAN, 0.0),
            (10, 10, 1.0, 1.6),
            (10, 10, 1.0, f32::INFINITY),
        ] {
            assert!(
                matches!(
                    CameraModel::with_pitch(w, h, hfov, pitch),
                    Err(CameraModelError::BadGeometry { .. })
                ),
                "{w}x{h} hfov {hfov} pitch {pitch}"
            );
        }
        assert_eq!(
            CameraModel::new(320, 240, 1.5).unwrap().pitch,
            CAMERA_PITCH_RAD
        );
    }

    #[test]
    fn the_optical_axis_points_down_by_the_pitch_and_rotates_with_yaw() {
        let cam = CameraModel::new(320, 240, 90f32.to_radians()).unwrap();
        let axis = cam.ray_at(160.0, 120.0);
        assert!((axis[2].atan2(axis[0]) + CAMERA_PITCH_RAD).abs() < 1e-6);
        assert_eq!(axis[1], 0.0);
        // the right edge of a 90-degree camera is 45 degrees right
        assert!((cam.bearing_of_column(320.0) - 45f32.to_radians()).abs() < 1e-6);
        // facing east, forward is east
        let east = body_to_world([1.0, 0.0, 0.0], core::f32::consts::FRAC_PI_2);
        assert!(east[0].abs() < 1e-6 && (east[1] - 1.0).abs() < 1e-6);
    }
}
