//! How frames cross between hosts: RGB frames as JPEG (the bridge's `frames = "jpeg"`, the
//! default: a 320x240 frame is 230 KB raw, a few tens of KB as JPEG) or raw; depth frames
//! always raw (JPEG would change their values). The coding used travels in the message's
//! attachment, so the receiving bridge decodes what it was sent whatever it sends itself.

use aeris_schemas::{FrameFormat, FrameHeader};
use image::ImageDecoder as _;
use image::codecs::jpeg::{JpegDecoder, JpegEncoder};

/// The attachment byte of a raw frame (and of every other message).
pub const CODING_RAW: u8 = 0;
/// The attachment byte of a JPEG frame.
pub const CODING_JPEG: u8 = 1;

/// How a bridge sends frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameCoding {
    /// Exact bytes.
    Raw,
    /// RGB frames as JPEG of this quality (1-100); depth raw.
    Jpeg {
        /// JPEG quality.
        quality: u8,
    },
}

/// Default JPEG quality of frames between hosts.
pub const DEFAULT_JPEG_QUALITY: u8 = 85;

/// Why a frame could not be encoded or decoded.
#[derive(Debug, thiserror::Error)]
pub enum FrameCodingError {
    /// The coding's name is neither `jpeg` nor `raw`, or the quality is outside 1-100.
    #[error("frames = `{name}` (quality {quality}): use `jpeg` (quality 1-100) or `raw`")]
    Unknown {
        /// The name given.
        name: String,
        /// The quality given.
        quality: u64,
    },
    /// The JPEG encoder or decoder failed.
    #[error("JPEG {what} of a {width}x{height} frame failed")]
    Jpeg {
        /// `encoding` or `decoding`.
        what: &'static str,
        /// Frame width.
        width: u32,
        /// Frame height.
        height: u32,
        /// The codec's reason.
        #[source]
        source: image::ImageError,
    },
    /// A decoded frame is not what its header says.
    #[error("a JPEG frame decodes to {got_width}x{got_height}, its header says {width}x{height}")]
    Size {
        /// Width in the header.
        width: u32,
        /// Height in the header.
        height: u32,
        /// Width decoded.
        got_width: u32,
        /// Height decoded.
        got_height: u32,
    },
    /// An RGB frame's pixels are not as long as its header says.
    #[error("a {width}x{height} RGB frame has {got} bytes of pixels, not {expected}")]
    Length {
        /// Frame width.
        width: u32,
        /// Frame height.
        height: u32,
        /// Bytes the header implies.
        expected: usize,
        /// Bytes it has.
        got: usize,
    },
    /// A JPEG frame decodes to another colour type than RGB.
    #[error("a JPEG frame decodes to {0:?}, not 8-bit RGB")]
    Colour(image::ColorType),
    /// The attachment names a coding this build does not know.
    #[error("unknown frame coding {0}")]
    UnknownCoding(u8),
}

impl FrameCoding {
    /// The coding named `name` (`jpeg` or `raw`) at `quality`.
    pub fn parse(name: &str, quality: u64) -> Result<Self, FrameCodingError> {
        match (name, quality) {
            ("raw", _) => Ok(FrameCoding::Raw),
            ("jpeg", 1..=100) => Ok(FrameCoding::Jpeg {
                quality: quality as u8,
            }),
            _ => Err(FrameCodingError::Unknown {
                name: name.to_string(),
                quality,
            }),
        }
    }

    /// Append the frame `header` describes (its `pixels`) to `out` as this coding sends it;
    /// returns the coding used (depth and other formats go raw).
    pub fn encode(
        self,
        header: &FrameHeader,
        pixels: &[u8],
        out: &mut Vec<u8>,
    ) -> Result<u8, FrameCodingError> {
        match self {
            FrameCoding::Jpeg { quality }
                if FrameFormat::from_u8(header.format) == Some(FrameFormat::Rgb8) =>
            {
                // the encoder asserts the length: check it here
                let expected = header.width as usize * header.height as usize * 3;
                if pixels.len() != expected {
                    return Err(FrameCodingError::Length {
                        width: header.width,
                        height: header.height,
                        expected,
                        got: pixels.len(),
                    });
                }
                JpegEncoder::new_with_quality(&mut *out, quality)
                    .encode(
                        pixels,
                        header.width,
                        header.height,
                        image::ExtendedColorType::Rgb8,
                    )
                    .map_err(|source| FrameCodingError::Jpeg {
                        what: "encoding",
                        width: header.width,
                        height: header.height,
                        source,
                    })?;
                Ok(CODING_JPEG)
            }
            _ => {
                out.extend_from_slice(pixels);
                Ok(CODING_RAW)
            }
        }
    }
}

/// The pixels of a frame sent as `coding` (`bytes`, after its header), into `out`
/// (cleared); a raw frame is copied.
pub fn decode(
    coding: u8,
    header: &FrameHeader,
    bytes: &[u8],
    out: &mut Vec<u8>,
) -> Result<(), FrameCodingError> {
    out.clear();
    match coding {
        CODING_RAW => {
            out.extend_from_slice(bytes);
            Ok(())
        }
        CODING_JPEG => {
            let jpeg = |source| FrameCodingError::Jpeg {
                what: "decoding",
                width: header.width,
                height: header.height,
                source,
            };
            let decoder = JpegDecoder::new(std::io::Cursor::new(bytes)).map_err(jpeg)?;
            let (w, h) = decoder.dimensions();
            if decoder.color_type() != image::ColorType::Rgb8 {
                return Err(FrameCodingError::Colour(decoder.color_type()));
            }
            if (w, h) != (header.width, header.height) {
                return Err(FrameCodingError::Size {
                    width: header.width,
                    height: header.height,
                    got_width: w,
                    got_height: h,
                });
            }
            out.resize(decoder.total_bytes() as usize, 0);
            decoder.read_image(out).map_err(jpeg)
        }
        other => Err(FrameCodingError::UnknownCoding(other)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header(format: FrameFormat, w: u32, h: u32) -> FrameHeader {
        FrameHeader {
            width: w,
            height: h,
            format: format as u8,
            ..FrameHeader::default()
        }
    }

    #[test]
    fn an_rgb_frame_crosses_as_jpeg_close_to_its_pixels_and_depth_stays_exact() {
        let (w, h) = (64u32, 48u32);
        // a smooth picture: JPEG keeps it within a few levels
        let pixels: Vec<u8> = (0..w * h)
            .flat_map(|i| {
                let (x, y) = (i % w, i / w);
                [(x * 4) as u8, (y * 5) as u8, 128]
            })
            .collect();
        let rgb = header(FrameFormat::Rgb8, w, h);
        let coding = FrameCoding::parse("jpeg", 85).unwrap();
        let mut sent = Vec::new();
        assert_eq!(
            coding.encode(&rgb, &pixels, &mut sent).unwrap(),
            CODING_JPEG
        );
        assert!(sent.len() < pixels.len() / 4, "{} bytes", sent.len());
        let mut got = Vec::new();
        decode(CODING_JPEG, &rgb, &sent, &mut got).unwrap();
        assert_eq!(got.len(), pixels.len());
        let worst = got
            .iter()
            .zip(&pixels)
            .map(|(a, b)| a.abs_diff(*b))
            .max()
            .unwrap();
        assert!(worst <= 24, "worst difference {worst}");
        // depth: raw, exact
        let depth = header(FrameFormat::DepthU16Mm, w, h);
        let mm: Vec<u8> = (0..w * h * 2).map(|i| i as u8).collect();
        let mut sent = Vec::new();
        assert_eq!(coding.encode(&depth, &mm, &mut sent).unwrap(), CODING_RAW);
        decode(CODING_RAW, &depth, &sent, &mut got).unwrap();
        assert_eq!(got, mm);
        // a JPEG of another size than its header says is refused
        let mut sent = Vec::new();
        coding.encode(&rgb, &pixels, &mut sent).unwrap();
        let e = decode(
            CODING_JPEG,
            &header(FrameFormat::Rgb8, 32, 48),
            &sent,
            &mut got,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("decodes to 64x48, its header says 32x48"), "{e}");
        // pixels shorter than the header says: refused, not a panic in the encoder
        let e = coding
            .encode(&rgb, &pixels[..10], &mut Vec::new())
            .unwrap_err()
            .to_string();
        assert!(e.contains("has 10 bytes of pixels, not 9216"), "{e}");
        assert!(FrameCoding::parse("h264", 85).is_err());
        assert!(FrameCoding::parse("jpeg", 0).is_err());
        assert_eq!(FrameCoding::parse("raw", 0).unwrap(), FrameCoding::Raw);
    }
}
