//! The header of a camera frame; the frame bytes travel as the sample's slice payload.

use crate::all_finite;
use iceoryx2_bb_derive_macros::ZeroCopySend;
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;

/// Largest accepted frame side in pixels.
pub const MAX_FRAME_SIDE: u32 = 4096;

/// Pixel format of a frame's bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum FrameFormat {
    /// 8-bit RGB, row-major, 3 bytes per pixel.
    Rgb8 = 1,
    /// Depth in millimetres, little-endian u16 per pixel (0 = no return).
    DepthU16Mm = 2,
}

impl FrameFormat {
    /// Bytes per pixel.
    pub fn bytes_per_pixel(self) -> usize {
        match self {
            FrameFormat::Rgb8 => 3,
            FrameFormat::DepthU16Mm => 2,
        }
    }

    /// Decode a wire byte.
    pub fn from_u8(v: u8) -> Option<Self> {
        match v {
            1 => Some(FrameFormat::Rgb8),
            2 => Some(FrameFormat::DepthU16Mm),
            _ => None,
        }
    }
}

/// User header of a frame sample (`camera/rgb`, `camera/depth`).
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("aeris::FrameHeader@s8")]
#[repr(C)]
pub struct FrameHeader {
    /// Frame sequence number (monotone per camera, from 1).
    pub seq: u64,
    /// CLOCK_MONOTONIC ns at capture.
    pub capture_ns: u64,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Camera position at capture `[N, E, U]`.
    pub camera_position: [f32; 3],
    /// Camera yaw at capture (rad, 0 = north, clockwise positive).
    pub camera_yaw: f32,
    /// Horizontal field of view (rad).
    pub hfov: f32,
    /// Pixel format as [`FrameFormat`] wire byte.
    pub format: u8,
    /// Reserved, zero.
    #[cfg_attr(feature = "serde", serde(skip))]
    pub reserved: [u8; 3],
}

impl Default for FrameHeader {
    fn default() -> Self {
        Self {
            seq: 0,
            capture_ns: 0,
            width: 0,
            height: 0,
            camera_position: [0.0; 3],
            camera_yaw: 0.0,
            hfov: 1.2,
            format: FrameFormat::Rgb8 as u8,
            reserved: [0; 3],
        }
    }
}

/// Why a frame is unusable.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum FrameError {
    /// The format byte is unknown.
    #[error("unknown frame format {0}")]
    UnknownFormat(u8),
    /// Width or height is zero or above [`MAX_FRAME_SIDE`].
    #[error("frame size {width}x{height} is outside 1..={MAX_FRAME_SIDE}")]
    BadSize {
        /// Width.
        width: u32,
        /// Height.
        height: u32,
    },
    /// The payload length does not match width * height * bytes per pixel.
    #[error("payload is {actual} bytes, header says {expected}")]
    LengthMismatch {
        /// Expected bytes.
        expected: usize,
        /// Actual bytes.
        actual: usize,
    },
    /// Pose or field of view is not finite or out of range.
    #[error("camera pose or field of view is not finite or out of range")]
    BadPose,
}

impl FrameHeader {
    /// Payload bytes this header describes, if the header is well formed.
    pub fn expected_len(&self) -> Result<usize, FrameError> {
        let format =
            FrameFormat::from_u8(self.format).ok_or(FrameError::UnknownFormat(self.format))?;
        if self.width == 0
            || self.height == 0
            || self.width > MAX_FRAME_SIDE
            || self.height > MAX_FRAME_SIDE
        {
            return Err(FrameError::BadSize {
                width: self.width,
                height: self.height,
            });
        }
        Ok(self.width as usize * self.height as usize * format.bytes_per_pixel())
    }

    /// Validate the header against the payload it came with.
    pub fn validate(&self, payload_len: usize) -> Result<FrameFormat, FrameError> {
        let expected = self.expected_len()?;
        if expected != payload_len {
            return Err(FrameError::LengthMismatch {
                expected,
                actual: payload_len,
            });
        }
        let pose_ok = all_finite(&self.camera_position)
            && self.camera_yaw.is_finite()
            && self.hfov > 0.0
            && self.hfov < core::f32::consts::PI;
        if !pose_ok {
            return Err(FrameError::BadPose);
        }
        // expected_len already decoded the format
        FrameFormat::from_u8(self.format).ok_or(FrameError::UnknownFormat(self.format))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn validates_length_and_format() {
        let h = FrameHeader {
            width: 4,
            height: 2,
            ..FrameHeader::default()
        };
        assert_eq!(h.validate(24), Ok(FrameFormat::Rgb8));
        assert!(matches!(
            h.validate(23),
            Err(FrameError::LengthMismatch { .. })
        ));
        let d = FrameHeader {
            format: FrameFormat::DepthU16Mm as u8,
            ..h
        };
        assert_eq!(d.validate(16), Ok(FrameFormat::DepthU16Mm));
        let bad = FrameHeader { format: 9, ..h };
        assert_eq!(bad.validate(24), Err(FrameError::UnknownFormat(9)));
        let zero = FrameHeader { width: 0, ..h };
        assert!(matches!(zero.validate(0), Err(FrameError::BadSize { .. })));
        let nan = FrameHeader {
            camera_yaw: f32::NAN,
            ..h
        };
        assert_eq!(nan.validate(24), Err(FrameError::BadPose));
    }
}
