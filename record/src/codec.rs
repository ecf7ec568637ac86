//! What the recorder knows of each topic: its payload type, the payload's exact bytes, the
//! JSON a reader sees, the JSON Schema of that JSON (inferred from the converter's own
//! output, so the two cannot disagree) and the message's log time.

use aeris_schemas::topics::Stamped;
use aeris_schemas::{
    FrameHeader, MAX_CUES, MAX_DETECTIONS, MAX_SUBGOALS, PerceptionState, SCHEMA_LAYOUT_HASH,
    SCHEMA_VERSION, VehicleTelemetry, with_payload_type,
};
use serde_json::{Map, Value, json};

pub use aeris_runtime::raw::{Payload, bytes_of, payload_of, read};
pub use aeris_schemas::json_form::base64;

/// What the recorder adds to a [`Payload`]: its JSON, the JSON's schema, the raw channel's
/// schema, its stamp and (for telemetry) its pose.
pub trait PayloadCodec {
    /// The JSON channel's schema name (`aeris.Decision`).
    fn json_schema_name(self) -> String;
    /// The raw channel's schema data: what a replay checks before trusting the bytes.
    fn raw_schema(self) -> Value;
    /// CLOCK_MONOTONIC ns the message was captured or published, by its own stamp.
    fn stamp_ns(self, bytes: &[u8]) -> Option<u64>;
    /// The vehicle pose of a telemetry message in `bytes` as a `foxglove.PoseInFrame`
    /// ([`pose_in_frame_json`]); `None` for other payloads or another length.
    fn to_pose_json(self, bytes: &[u8]) -> Option<Value>;
    /// The payload in `bytes` as JSON; `None` when the length is not the payload's.
    fn to_json(self, bytes: &[u8]) -> Option<Value>;
    /// The JSON Schema of [`PayloadCodec::to_json`]'s output, inferred from a full example
    /// (every variable-length list at its longest), so the schema and the encoder agree.
    fn json_schema(self) -> Value;
}

impl PayloadCodec for Payload {
    /// The JSON channel's schema name (`aeris.Decision`).
    fn json_schema_name(self) -> String {
        let bare = self.type_name().split('@').next().unwrap_or_default();
        bare.replace("::", ".")
    }

    /// The raw channel's schema data: what a replay checks before trusting the bytes.
    fn raw_schema(self) -> Value {
        let (size, align) = self.layout();
        json!({
            "type_name": self.type_name(),
            "schema_version": SCHEMA_VERSION,
            "layout_hash": format!("{SCHEMA_LAYOUT_HASH:#018x}"),
            "size": size,
            "align": align,
        })
    }

    /// CLOCK_MONOTONIC ns the message was captured or published, by its own stamp.
    fn stamp_ns(self, bytes: &[u8]) -> Option<u64> {
        with_payload_type!(self, T => Some(read::<T>(bytes)?.stamp_ns()))
    }

    /// The vehicle pose of a telemetry message in `bytes` as a `foxglove.PoseInFrame`
    /// ([`pose_in_frame_json`]); `None` for other payloads or another length.
    fn to_pose_json(self, bytes: &[u8]) -> Option<Value> {
        match self {
            Payload::Telemetry => Some(pose_in_frame_json(&read(bytes)?)),
            _ => None,
        }
    }

    /// The payload in `bytes` as JSON (its type's `Serialize`); `None` when the length is
    /// not the payload's.
    fn to_json(self, bytes: &[u8]) -> Option<Value> {
        with_payload_type!(self, T => serde_json::to_value(read::<T>(bytes)?).ok())
    }

    /// The JSON Schema of [`PayloadCodec::to_json`]'s output, inferred from a full example
    /// (every variable-length list at its longest), so the schema and the encoder agree.
    fn json_schema(self) -> Value {
        let example = match self {
            Payload::State => serde_json::to_value(PerceptionState {
                detection_count: MAX_DETECTIONS as u32,
                cue_count: MAX_CUES as u32,
                relevance_count: MAX_SUBGOALS as u32,
                ..PerceptionState::default()
            }),
            other => with_payload_type!(other, T => serde_json::to_value(T::default())),
        };
        document_schema(&self.json_schema_name(), &example.unwrap_or(Value::Null))
    }
}

/// A JSON Schema document (draft 2020-12) titled `title` for values shaped like `example`.
pub fn document_schema(title: &str, example: &Value) -> Value {
    let mut schema = infer_schema(example);
    if let Value::Object(m) = &mut schema {
        m.insert(
            "$schema".into(),
            "https://json-schema.org/draft/2020-12/schema".into(),
        );
        m.insert("title".into(), title.into());
    }
    schema
}

/// The JSON Schema of values shaped like `v`.
fn infer_schema(v: &Value) -> Value {
    match v {
        Value::Null => json!({"type": "null"}),
        Value::Bool(_) => json!({"type": "boolean"}),
        Value::Number(n) if n.is_f64() => json!({"type": "number"}),
        Value::Number(_) => json!({"type": "integer"}),
        Value::String(_) => json!({"type": "string"}),
        Value::Array(items) => match items.first() {
            Some(first) => json!({"type": "array", "items": infer_schema(first)}),
            None => json!({"type": "array"}),
        },
        Value::Object(fields) => {
            let properties: Map<String, Value> = fields
                .iter()
                .map(|(k, v)| (k.clone(), infer_schema(v)))
                .collect();
            let required: Vec<&String> = fields.keys().collect();
            json!({"type": "object", "properties": properties, "required": required})
        }
    }
}

/// A `foxglove.RawImage` (JSON encoding) of one frame: `rgb8` or `16UC1` (depth, mm).
pub fn raw_image_json(frame_id: &str, header: &FrameHeader, pixels: &[u8]) -> Value {
    let depth = header.format == aeris_schemas::FrameFormat::DepthU16Mm as u8;
    let (encoding, bpp) = if depth { ("16UC1", 2) } else { ("rgb8", 3) };
    json!({
        "timestamp": {
            "sec": header.capture_ns / 1_000_000_000,
            "nsec": header.capture_ns % 1_000_000_000,
        },
        "frame_id": frame_id,
        "width": header.width,
        "height": header.height,
        "encoding": encoding,
        "step": header.width * bpp,
        "data": base64(pixels),
    })
}

/// The JSON Schema of [`raw_image_json`].
pub fn raw_image_schema() -> Value {
    let h = FrameHeader {
        width: 1,
        height: 1,
        ..FrameHeader::default()
    };
    document_schema("foxglove.RawImage", &raw_image_json("camera", &h, &[0; 3]))
}

/// How a frame's pixels go onto its topic's image channel (`TOPIC/image`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImageFormat {
    /// `foxglove.CompressedImage`: RGB frames as JPEG at `jpeg_quality` (1..=100), depth
    /// frames as 16-bit grey PNG (lossless: JPEG has no 16-bit depth).
    Compressed {
        /// JPEG quality, 1..=100.
        jpeg_quality: u8,
    },
    /// `foxglove.RawImage`: the pixels as they are (`rgb8`, `16UC1`).
    Raw,
}

/// JPEG quality of recorded frames unless the recorder's `params.jpeg_quality` says.
pub const DEFAULT_JPEG_QUALITY: u8 = 80;

impl Default for ImageFormat {
    fn default() -> Self {
        ImageFormat::Compressed {
            jpeg_quality: DEFAULT_JPEG_QUALITY,
        }
    }
}

impl ImageFormat {
    /// The Foxglove schema name of the image channel.
    pub fn schema_name(self) -> &'static str {
        match self {
            ImageFormat::Compressed { .. } => "foxglove.CompressedImage",
            ImageFormat::Raw => "foxglove.RawImage",
        }
    }

    /// The JSON Schema of the image channel.
    pub fn schema(self) -> Value {
        match self {
            ImageFormat::Compressed { .. } => compressed_image_schema(),
            ImageFormat::Raw => raw_image_schema(),
        }
    }
}

/// A `foxglove.CompressedImage` (JSON encoding) of one encoded frame (`format`: `jpeg` or
/// `png`).
pub fn compressed_image_json(
    frame_id: &str,
    header: &FrameHeader,
    format: &str,
    data: &[u8],
) -> Value {
    json!({
        "timestamp": {
            "sec": header.capture_ns / 1_000_000_000,
            "nsec": header.capture_ns % 1_000_000_000,
        },
        "frame_id": frame_id,
        "format": format,
        "data": base64(data),
    })
}

/// The JSON Schema of [`compressed_image_json`].
pub fn compressed_image_schema() -> Value {
    document_schema(
        "foxglove.CompressedImage",
        &compressed_image_json("camera", &FrameHeader::default(), "jpeg", &[0; 3]),
    )
}

/// Why a frame could not be encoded.
#[derive(Debug, thiserror::Error)]
pub enum EncodeError {
    /// The pixels are not one frame of the header's size and format.
    #[error("{got} bytes of pixels for a {width}x{height} frame of format {format}")]
    Size {
        /// Bytes given.
        got: usize,
        /// Frame width.
        width: u32,
        /// Frame height.
        height: u32,
        /// The header's format byte.
        format: u8,
    },
    /// The encoder failed.
    #[error("encoding the frame")]
    Encoder(#[source] image::ImageError),
}

/// Encode one frame's `pixels` into `out` (cleared first): RGB as JPEG at `jpeg_quality`,
/// depth (little-endian u16 millimetres) as 16-bit grey PNG. Returns the format name.
pub fn encode_frame(
    header: &FrameHeader,
    pixels: &[u8],
    jpeg_quality: u8,
    out: &mut Vec<u8>,
) -> Result<&'static str, EncodeError> {
    use image::ImageEncoder;
    out.clear();
    let (w, h) = (header.width, header.height);
    let depth = header.format == aeris_schemas::FrameFormat::DepthU16Mm as u8;
    let bpp = if depth { 2 } else { 3 };
    if pixels.len() != w as usize * h as usize * bpp {
        return Err(EncodeError::Size {
            got: pixels.len(),
            width: w,
            height: h,
            format: header.format,
        });
    }
    if depth {
        // the PNG encoder takes 16-bit samples in native byte order and ours are
        // little-endian: as they are on a little-endian machine, swapped (a copy) elsewhere
        let native: std::borrow::Cow<[u8]> = if cfg!(target_endian = "little") {
            std::borrow::Cow::Borrowed(pixels)
        } else {
            pixels
                .chunks_exact(2)
                .flat_map(|b| u16::from_le_bytes([b[0], b[1]]).to_ne_bytes())
                .collect()
        };
        image::codecs::png::PngEncoder::new(&mut *out)
            .write_image(&native, w, h, image::ExtendedColorType::L16)
            .map_err(EncodeError::Encoder)?;
        Ok("png")
    } else {
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut *out, jpeg_quality.clamp(1, 100))
            .write_image(pixels, w, h, image::ExtendedColorType::Rgb8)
            .map_err(EncodeError::Encoder)?;
        Ok("jpeg")
    }
}

/// The frame Foxglove draws the vehicle in: east-north-up metres from the mission origin
/// (x east, y north, z up, as ROS REP 103's `map`).
pub const POSE_FRAME_ID: &str = "map";

/// The vehicle's pose as a `foxglove.PoseInFrame` (JSON) in [`POSE_FRAME_ID`]: our
/// `[N, E, U]` becomes `x = E, y = N, z = U`, and the yaw (0 north, clockwise) a rotation
/// about z of `pi/2 - yaw` (counter-clockwise from east), so the 3D panel draws the
/// trajectory and heading.
pub fn pose_in_frame_json(t: &VehicleTelemetry) -> Value {
    let [n, e, u] = t.position.map(f64::from);
    let heading = core::f64::consts::FRAC_PI_2 - f64::from(t.attitude[2]);
    let (sin, cos) = (heading / 2.0).sin_cos();
    json!({
        "timestamp": {
            "sec": t.stamp_ns / 1_000_000_000,
            "nsec": t.stamp_ns % 1_000_000_000,
        },
        "frame_id": POSE_FRAME_ID,
        "pose": {
            "position": {"x": e, "y": n, "z": u},
            "orientation": {"x": 0.0, "y": 0.0, "z": sin, "w": cos},
        },
    })
}

/// The JSON Schema of [`pose_in_frame_json`].
pub fn pose_in_frame_schema() -> Value {
    document_schema(
        "foxglove.PoseInFrame",
        &pose_in_frame_json(&VehicleTelemetry::default()),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use aeris_schemas::{Decision, topics};

    #[test]
    fn every_topic_has_a_payload_and_its_json_round_trips_the_bytes() {
        for topic in topics::ALL {
            let p = payload_of(topic).unwrap_or_else(|| panic!("{topic} has no payload"));
            let (size, _) = p.layout();
            let zeros = vec![0u8; size];
            assert!(p.to_json(&zeros).is_some(), "{topic}");
            assert!(
                p.to_json(&zeros[1..]).is_none(),
                "{topic}: a short payload is refused"
            );
            assert!(p.type_name().ends_with(&format!("@s{SCHEMA_VERSION}")));
            let schema = p.json_schema();
            assert_eq!(schema["type"], "object", "{topic}");
        }
    }

    #[test]
    fn the_state_schema_describes_its_lists_items() {
        let s = Payload::State.json_schema();
        assert_eq!(s["properties"]["detections"]["items"]["type"], "object");
        assert_eq!(s["properties"]["seq"]["type"], "integer");
        assert_eq!(s["properties"]["yaw"]["type"], "number");
    }

    #[test]
    fn base64_matches_rfc_4648() {
        assert_eq!(base64(b""), "");
        assert_eq!(base64(b"f"), "Zg==");
        assert_eq!(base64(b"fo"), "Zm8=");
        assert_eq!(base64(b"foo"), "Zm9v");
        assert_eq!(base64(b"foobar"), "Zm9vYmFy");
    }

    #[test]
    fn stamps_come_from_the_payload() {
        let d = Decision {
            publish_ns: 42,
            ..Decision::default()
        };
        assert_eq!(Payload::Decision.stamp_ns(bytes_of(&d)), Some(42));
    }
}
