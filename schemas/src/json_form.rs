//! How a message reads as JSON (the recorder's JSON channels, `aeris topic`): what the
//! derived `Serialize` of a plain message cannot say by itself. Fixed text is its text;
//! a list is cut to its count; the occupancy grid's cells are base64.

use crate::{
    FixedText, HubCounts, HubReport, MAX_CUES, MAX_DETECTIONS, MAX_SUBGOALS, OccupancyGrid,
    PerceptionState,
};
use serde::ser::{Serialize, SerializeStruct, Serializer};

/// Standard base64 (RFC 4648, padded): how JSON carries bytes.
pub fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            *chunk.get(1).unwrap_or(&0),
            *chunk.get(2).unwrap_or(&0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for i in 0..4 {
            if i <= chunk.len() {
                out.push(ALPHABET[(n >> (18 - 6 * i) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

impl<const N: usize> Serialize for FixedText<N> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.as_str_lossy())
    }
}

/// Serialize the named fields of `$value` into the struct serializer `$s`.
macro_rules! fields {
    ($s:ident, $value:ident, $($field:ident),* $(,)?) => {
        $($s.serialize_field(stringify!($field), &$value.$field)?;)*
    };
}

impl Serialize for OccupancyGrid {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut out = s.serialize_struct("OccupancyGrid", 4)?;
        fields!(out, self, origin, resolution_m, status);
        out.serialize_field("cells_base64", &base64(&self.cells))?;
        out.end()
    }
}

impl Serialize for PerceptionState {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let dets = &self.detections[..(self.detection_count as usize).min(MAX_DETECTIONS)];
        let cues = &self.cues[..(self.cue_count as usize).min(MAX_CUES)];
        let relevance =
            &self.subgoal_relevance[..(self.relevance_count as usize).min(MAX_SUBGOALS)];
        let mut out = s.serialize_struct("PerceptionState", 13)?;
        fields!(
            out, self, seq, frame_seq, capture_ns, publish_ns, position, yaw, summary, occupancy,
            blocks
        );
        out.serialize_field("detections", dets)?;
        out.serialize_field("cues", cues)?;
        out.serialize_field("subgoal_relevance", relevance)?;
        out.end()
    }
}

impl Serialize for HubReport {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let attention = &self.attention[..usize::from(self.subgoals).min(MAX_SUBGOALS)];
        // the counts lie flat beside the other fields, as they always have in recordings
        let mut out = s.serialize_struct("HubReport", 16 + HubCounts::LEN)?;
        fields!(
            out,
            self,
            seq,
            cycle,
            publish_ns,
            ct_ns,
            stage_ns,
            committed,
            reused,
            clamped,
            occupancy,
            active_step,
            subgoals,
            decision_source,
            clamp_reasons,
        );
        for (name, value) in self.counts.named() {
            out.serialize_field(name, &value)?;
        }
        out.serialize_field("attention", attention)?;
        out.end()
    }
}
