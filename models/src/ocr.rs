//! Reading text (signs, billboards) with PP-OCRv4 through ONNX Runtime.
//!
//! Detection (DB): the frame is scaled so both sides are multiples of 32, normalised with
//! ImageNet statistics (channels in BGR order, as PaddleOCR trains), and the model returns a
//! text-probability map. Pixels above [`OcrReader::pixel_threshold`] form connected regions;
//! each region whose mean probability passes [`OcrReader::box_threshold`] becomes an axis-
//! aligned box, grown by the DB "unclip" offset (area x 1.6 / perimeter).
//! Recognition (SVTR/CTC): each box is cropped from the frame, resized to height 48, and the
//! per-step class probabilities are decoded greedily (collapse repeats, drop blanks) against
//! the character table stored in the model's metadata.

use crate::error::ModelError;
use crate::image::rgb8_mismatch;
use crate::onnx::{OnnxModel, SessionOptions};
use crate::store::ModelStore;

/// PP-OCRv4 detection model inside the cache.
pub const DET_MODEL: &str = "ocr/ppocrv4-det.onnx";
/// PP-OCRv4 recognition model inside the cache.
pub const REC_MODEL: &str = "ocr/ppocrv4-rec.onnx";
/// Recognition input height.
pub const REC_HEIGHT: usize = 48;
/// Narrowest recognition input (PaddleOCR pads shorter crops to it).
pub const REC_MIN_WIDTH: usize = 320;
/// Widest recognition input.
pub const REC_MAX_WIDTH: usize = 480;
/// Most text regions read per frame (largest first).
pub const MAX_REGIONS: usize = 8;

/// One piece of text read from an image.
#[derive(Debug, Clone, PartialEq)]
pub struct TextRegion {
    /// The text.
    pub text: String,
    /// Mean probability of the decoded characters, in [0, 1].
    pub score: f32,
    /// `[x, y, w, h]` in image pixels.
    pub bbox: [f32; 4],
}

/// A connected region of the probability map: bounding box in map pixels and mean score.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapRegion {
    /// `[x0, y0, x1, y1]`, inclusive.
    pub bounds: [usize; 4],
    /// Pixels in the region.
    pub pixels: usize,
    /// Mean probability over the region.
    pub mean: f32,
}

/// Connected regions (4-neighbourhood) of `prob >= threshold` in a `w` x `h` map.
/// `labels` and `stack` are scratch buffers reused between calls.
pub fn map_regions(
    prob: &[f32],
    w: usize,
    h: usize,
    threshold: f32,
    labels: &mut Vec<u32>,
    stack: &mut Vec<usize>,
    out: &mut Vec<MapRegion>,
) {
    out.clear();
    labels.clear();
    labels.resize(w * h, 0);
    if prob.len() < w * h {
        return;
    }
    let mut next = 0u32;
    for start in 0..w * h {
        if labels[start] != 0 || prob[start] < threshold {
            continue;
        }
        next += 1;
        labels[start] = next;
        stack.clear();
        stack.push(start);
        let (mut x0, mut y0, mut x1, mut y1) = (w, h, 0, 0);
        let (mut n, mut sum) = (0usize, 0.0f32);
        while let Some(i) = stack.pop() {
            let (x, y) = (i % w, i / w);
            x0 = x0.min(x);
            x1 = x1.max(x);
            y0 = y0.min(y);
            y1 = y1.max(y);
            n += 1;
            sum += prob[i];
            let mut visit = |j: usize| {
                if labels[j] == 0 && prob[j] >= threshold {
                    labels[j] = next;
                    stack.push(j);
                }
            };
            if x > 0 {
                visit(i - 1);
            }
            if x + 1 < w {
                visit(i + 1);
            }
            if y > 0 {
                visit(i - w);
            }
            if y + 1 < h {
                visit(i + w);
            }
        }
        out.push(MapRegion {
            bounds: [x0, y0, x1, y1],
            pixels: n,
            mean: sum / n as f32,
        });
    }
}

/// Greedy CTC decoding of `steps` x `classes` probabilities: per step the best class,
/// repeats collapsed, blanks (class 0) dropped. Returns the mean probability of the kept
/// characters (0 when none).
pub fn ctc_greedy(probs: &[f32], classes: usize, charset: &[String], text: &mut String) -> f32 {
    text.clear();
    if classes == 0 {
        return 0.0;
    }
    let (mut last, mut sum, mut n) = (0usize, 0.0f32, 0usize);
    for step in probs.chunks_exact(classes) {
        let (best, p) = step
            .iter()
            .enumerate()
            .fold((0, f32::MIN), |b, (i, &v)| if v > b.1 { (i, v) } else { b });
        if best != 0
            && best != last
            && let Some(c) = charset.get(best)
        {
            text.push_str(c);
            sum += p;
            n += 1;
        }
        last = best;
    }
    if n == 0 { 0.0 } else { sum / n as f32 }
}

/// The character table of a PP-OCR recognition model: blank, the `character` metadata
/// lines, then a space.
pub fn rec_charset(character_metadata: &str) -> Vec<String> {
    let mut set = vec![String::new()];
    set.extend(
        character_metadata
            .split('\n')
            .map(|s| s.trim_end_matches('\r').to_string()),
    );
    if set.last().is_some_and(String::is_empty) {
        set.pop();
    }
    set.push(" ".into());
    set
}

/// A text reader: PP-OCRv4 detection + recognition.
#[derive(Debug)]
pub struct OcrReader {
    det: OnnxModel,
    rec: OnnxModel,
    charset: Vec<String>,
    det_input: Vec<f32>,
    rec_input: Vec<f32>,
    labels: Vec<u32>,
    stack: Vec<usize>,
    regions: Vec<MapRegion>,
    /// Longest side of the detection input (the frame is scaled up or down to it).
    pub det_side: usize,
    /// Probability from which a map pixel counts as text.
    pub pixel_threshold: f32,
    /// Mean probability a region needs to be read.
    pub box_threshold: f32,
    /// Recognition score a text needs to be reported.
    pub min_score: f32,
}

fn bgr_norm(v: u8, channel: usize) -> f32 {
    // ImageNet statistics in the order PaddleOCR applies them to a BGR image
    const MEAN: [f32; 3] = [0.485, 0.456, 0.406];
    const STD: [f32; 3] = [0.229, 0.224, 0.225];
    (v as f32 / 255.0 - MEAN[channel]) / STD[channel]
}

impl OcrReader {
    /// Load both models from the cache, to run as `options` say.
    pub fn load(store: &ModelStore, options: &SessionOptions) -> Result<Self, ModelError> {
        let det = OnnxModel::load_with(store, DET_MODEL, options)?;
        let rec = OnnxModel::load_with(store, REC_MODEL, options)?;
        let characters = rec
            .metadata("character")
            .ok_or_else(|| rec.interface_error("no `character` table in the metadata"))?;
        Ok(Self {
            det,
            rec,
            charset: rec_charset(&characters),
            det_input: Vec::new(),
            rec_input: Vec::new(),
            labels: Vec::new(),
            stack: Vec::new(),
            regions: Vec::new(),
            det_side: 640,
            pixel_threshold: 0.3,
            box_threshold: 0.5,
            min_score: 0.5,
        })
    }

    /// Run detection on a blank `width` x `height` frame and recognition on a blank line:
    /// the first run of a session allocates its memory and is several times slower, so a
    /// role pays it before it reports ready, not on its first frame.
    pub fn warm_up(&mut self, width: usize, height: usize) -> Result<(), ModelError> {
        let blank = vec![0u8; width.max(1) * height.max(1) * 3];
        let mut out = Vec::new();
        self.read(&blank, width.max(1), height.max(1), &mut out)?;
        self.rec_input.clear();
        self.rec_input.resize(3 * REC_HEIGHT * REC_MIN_WIDTH, 0.0);
        self.rec.run_f32(
            &[1, 3, REC_HEIGHT, REC_MIN_WIDTH],
            &self.rec_input,
            |_, _| Ok(()),
        )
    }

    /// Number of recognition classes (blank + characters + space).
    pub fn charset_len(&self) -> usize {
        self.charset.len()
    }

    /// Read the text in packed RGB8 `rgb` (`width` x `height`) into `out`, largest region
    /// first (at most [`MAX_REGIONS`]).
    pub fn read(
        &mut self,
        rgb: &[u8],
        width: usize,
        height: usize,
        out: &mut Vec<TextRegion>,
    ) -> Result<(), ModelError> {
        out.clear();
        if width == 0 || height == 0 {
            return Err(self
                .det
                .interface_error("an empty image has no text to read"));
        }
        if let Some(reason) = rgb8_mismatch(rgb, width, height) {
            return Err(self.det.interface_error(reason));
        }
        let scale = self.det_side as f32 / width.max(height) as f32;
        let round32 = |v: f32| ((v / 32.0).round() as usize).max(1) * 32;
        let (dw, dh) = (
            round32(width as f32 * scale),
            round32(height as f32 * scale),
        );
        let plane = dw * dh;
        self.det_input.resize(3 * plane, 0.0);
        for y in 0..dh {
            let sy = ((y as f32 + 0.5) * height as f32 / dh as f32) as usize;
            for x in 0..dw {
                let sx = ((x as f32 + 0.5) * width as f32 / dw as f32) as usize;
                let p = (sy.min(height - 1) * width + sx.min(width - 1)) * 3;
                for c in 0..3 {
                    // BGR: channel c of the tensor is RGB channel 2 - c
                    self.det_input[c * plane + y * dw + x] = bgr_norm(rgb[p + 2 - c], c);
                }
            }
        }
        let (threshold, labels, stack, regions) = (
            self.pixel_threshold,
            &mut self.labels,
            &mut self.stack,
            &mut self.regions,
        );
        self.det
            .run_f32(&[1, 3, dh, dw], &self.det_input, |shape, prob| {
                if shape.len() != 4 || shape[2] as usize != dh || shape[3] as usize != dw {
                    return Err(format!(
                        "probability map {shape:?}, expected [1, 1, {dh}, {dw}]"
                    ));
                }
                map_regions(prob, dw, dh, threshold, labels, stack, regions);
                Ok(())
            })?;
        self.regions
            .retain(|r| r.mean >= self.box_threshold && r.pixels >= 6);
        self.regions.sort_by_key(|r| std::cmp::Reverse(r.pixels));
        self.regions.truncate(MAX_REGIONS);
        let (kx, ky) = (width as f32 / dw as f32, height as f32 / dh as f32);
        let regions = std::mem::take(&mut self.regions);
        for r in &regions {
            let [x0, y0, x1, y1] = r.bounds;
            let (bw, bh) = ((x1 - x0 + 1) as f32, (y1 - y0 + 1) as f32);
            let grow = bw * bh * 1.6 / (2.0 * (bw + bh));
            // plus a horizontal margin of a quarter line height, as a crop of a text line
            // with its first stroke on the edge reads worse
            let margin = grow + 0.25 * (bh + 2.0 * grow);
            let fx0 = ((x0 as f32 - margin) * kx).max(0.0);
            let fy0 = ((y0 as f32 - grow) * ky).max(0.0);
            let fx1 = ((x1 as f32 + 1.0 + margin) * kx).min(width as f32);
            let fy1 = ((y1 as f32 + 1.0 + grow) * ky).min(height as f32);
            let bbox = [fx0, fy0, fx1 - fx0, fy1 - fy0];
            if bbox[2] < 2.0 || bbox[3] < 2.0 {
                continue;
            }
            let mut text = String::new();
            let score = self.recognise(rgb, width, bbox, &mut text)?;
            let text = text.trim().to_string();
            if score >= self.min_score && !text.is_empty() {
                out.push(TextRegion { text, score, bbox });
            }
        }
        self.regions = regions;
        Ok(())
    }

    fn recognise(
        &mut self,
        rgb: &[u8],
        width: usize,
        bbox: [f32; 4],
        text: &mut String,
    ) -> Result<f32, ModelError> {
        // PaddleOCR's layout: the crop scaled to height 48 keeping its aspect ratio, then
        // padded with zeros to at least REC_MIN_WIDTH; bilinear sampling
        let text_w =
            ((bbox[2] / bbox[3] * REC_HEIGHT as f32).ceil() as usize).clamp(1, REC_MAX_WIDTH);
        let rw = text_w.max(REC_MIN_WIDTH);
        let plane = REC_HEIGHT * rw;
        self.rec_input.clear();
        self.rec_input.resize(3 * plane, 0.0);
        let height = rgb.len() / 3 / width;
        for y in 0..REC_HEIGHT {
            let fy = (bbox[1] + (y as f32 + 0.5) * bbox[3] / REC_HEIGHT as f32 - 0.5)
                .clamp(0.0, (height - 1) as f32);
            let (y0, wy) = (fy as usize, fy.fract());
            let y1 = (y0 + 1).min(height - 1);
            for x in 0..text_w {
                let fx = (bbox[0] + (x as f32 + 0.5) * bbox[2] / text_w as f32 - 0.5)
                    .clamp(0.0, (width - 1) as f32);
                let (x0, wx) = (fx as usize, fx.fract());
                let x1 = (x0 + 1).min(width - 1);
                for c in 0..3 {
                    let at = |xx: usize, yy: usize| rgb[(yy * width + xx) * 3 + 2 - c] as f32;
                    let v = (at(x0, y0) * (1.0 - wx) + at(x1, y0) * wx) * (1.0 - wy)
                        + (at(x0, y1) * (1.0 - wx) + at(x1, y1) * wx) * wy;
                    self.rec_input[c * plane + y * rw + x] = (v / 255.0 - 0.5) / 0.5;
                }
            }
        }
        let charset = &self.charset;
        self.rec
            .run_f32(&[1, 3, REC_HEIGHT, rw], &self.rec_input, |shape, probs| {
                let classes = shape.last().copied().unwrap_or(0) as usize;
                if classes != charset.len() {
                    return Err(format!(
                        "{classes} classes but a character table of {}",
                        charset.len()
                    ));
                }
                Ok(ctc_greedy(probs, classes, charset, text))
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ctc_collapses_repeats_and_drops_blanks() {
        let charset: Vec<String> = ["", "a", "b", " "].iter().map(|s| s.to_string()).collect();
        // steps: a a blank a b b
        let mut probs = Vec::new();
        for best in [1, 1, 0, 1, 2, 2] {
            let mut step = [0.1f32; 4];
            step[best] = 0.7;
            probs.extend_from_slice(&step);
        }
        let mut text = String::new();
        let score = ctc_greedy(&probs, 4, &charset, &mut text);
        assert_eq!(text, "aab");
        assert!((score - 0.7).abs() < 1e-6);
        assert_eq!(ctc_greedy(&[], 4, &charset, &mut text), 0.0);
        assert_eq!(text, "");
    }

    #[test]
    fn regions_are_connected_components() {
        #[rustfmt::skip]
        let map = [
            0.9, 0.9, 0.0, 0.0, 0.0,
            0.9, 0.0, 0.0, 0.8, 0.8,
            0.0, 0.0, 0.0, 0.8, 0.0,
        ];
        let (mut labels, mut stack, mut out) = (Vec::new(), Vec::new(), Vec::new());
        map_regions(&map, 5, 3, 0.3, &mut labels, &mut stack, &mut out);
        assert_eq!(out.len(), 2);
        assert_eq!(out[0].bounds, [0, 0, 1, 1]);
        assert_eq!(out[0].pixels, 3);
        assert_eq!(out[1].bounds, [3, 1, 4, 2]);
        assert!((out[1].mean - 0.8).abs() < 1e-6);
        // a short map is no region, not a panic
        map_regions(&map[..3], 5, 3, 0.3, &mut labels, &mut stack, &mut out);
        assert!(out.is_empty());
    }

    #[test]
    fn charset_has_blank_first_and_space_last() {
        let set = rec_charset("a\nb\n");
        assert_eq!(set, ["", "a", "b", " "]);
    }
}
