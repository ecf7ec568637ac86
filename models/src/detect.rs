//! Object detection through ONNX Runtime: YOLO output layouts, decoded and NMS'd in Rust.
//!
//! Two layouts are decoded:
//! - [`DetectorLayout::Yolov5`]: `[1, N, 5 + C]` rows of `(cx, cy, w, h, objectness, C class
//!   probabilities)` — YOLOv3/v5/v7 exports, and our converted Darknet yolov3-tiny (COCO);
//! - [`DetectorLayout::Yolov8`]: `[1, 4 + C, N]` columns of `(cx, cy, w, h, C class scores)`
//!   without objectness — YOLOv8/YOLO11 exports (e.g. nudenet's `320n.onnx`).
//!
//! RT-DETR and PP-YOLOE (the paper's other pool members) have no weights on the registries
//! this project can reach; their layouts are not guessed at.

use crate::error::ModelError;
use crate::image::{Letterbox, letterbox_chw, rgb8_mismatch};
use crate::onnx::{OnnxModel, SessionOptions};
use crate::store::ModelStore;

/// The COCO detector inside the cache (converted Darknet yolov3-tiny).
pub const COCO_DETECTOR: &str = "detect/yolov3-tiny.onnx";
/// A YOLOv8-layout detector inside the cache (nudenet 320n, 18 classes).
pub const YOLOV8_DETECTOR: &str = "detect/nudenet-320n.onnx";

/// How a detector's output tensor is laid out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DetectorLayout {
    /// `[1, N, 5 + C]`: box, objectness, class probabilities.
    Yolov5,
    /// `[1, 4 + C, N]`: box, class scores (no objectness).
    Yolov8,
}

/// One detection in image pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct DetectedBox {
    /// Class index.
    pub class_id: usize,
    /// Score in [0, 1] (objectness x class probability for YOLOv5 layouts).
    pub score: f32,
    /// `[x, y, w, h]`: top-left corner and size in image pixels.
    pub bbox: [f32; 4],
}

/// Intersection over union of two `[x, y, w, h]` boxes.
pub fn iou(a: [f32; 4], b: [f32; 4]) -> f32 {
    let x0 = a[0].max(b[0]);
    let y0 = a[1].max(b[1]);
    let x1 = (a[0] + a[2]).min(b[0] + b[2]);
    let y1 = (a[1] + a[3]).min(b[1] + b[3]);
    let inter = (x1 - x0).max(0.0) * (y1 - y0).max(0.0);
    let union = a[2] * a[3] + b[2] * b[3] - inter;
    if union > 0.0 { inter / union } else { 0.0 }
}

/// Class-wise non-maximum suppression in place: sorts `boxes` by score (best first) and
/// drops every box overlapping a better one of its class by more than `iou_threshold`.
pub fn non_max_suppression(boxes: &mut Vec<DetectedBox>, iou_threshold: f32) {
    boxes.sort_by(|a, b| b.score.total_cmp(&a.score));
    let mut kept = 0;
    for i in 0..boxes.len() {
        let suppressed = (0..kept).any(|k| {
            boxes[k].class_id == boxes[i].class_id
                && iou(boxes[k].bbox, boxes[i].bbox) > iou_threshold
        });
        if !suppressed {
            boxes.swap(kept, i);
            kept += 1;
        }
    }
    boxes.truncate(kept);
}

/// Decode a raw output tensor of `shape` into candidate boxes (input pixels) above
/// `min_score`, appended to `out`.
pub fn decode(
    layout: DetectorLayout,
    shape: &[i64],
    data: &[f32],
    min_score: f32,
    out: &mut Vec<DetectedBox>,
) -> Result<usize, String> {
    let dims: Vec<usize> = shape.iter().map(|&d| d.max(0) as usize).collect();
    if dims.len() != 3 || dims[0] != 1 || dims.iter().product::<usize>() != data.len() {
        return Err(format!(
            "output shape {shape:?} is not [1, a, b] over {} values",
            data.len()
        ));
    }
    let before = out.len();
    let to_corner = |cx: f32, cy: f32, w: f32, h: f32| [cx - w / 2.0, cy - h / 2.0, w, h];
    match layout {
        DetectorLayout::Yolov5 => {
            let (n, stride) = (dims[1], dims[2]);
            if stride < 6 {
                return Err(format!("YOLOv5 rows of {stride} values; need 5 + classes"));
            }
            for row in data.chunks_exact(stride).take(n) {
                let obj = row[4];
                if obj.is_nan() || obj < min_score {
                    continue;
                }
                let (class_id, p) =
                    row[5..]
                        .iter()
                        .enumerate()
                        .fold(
                            (0, f32::MIN),
                            |best, (i, &v)| if v > best.1 { (i, v) } else { best },
                        );
                let score = obj * p;
                if score >= min_score && row[..4].iter().all(|v| v.is_finite()) {
                    out.push(DetectedBox {
                        class_id,
                        score,
                        bbox: to_corner(row[0], row[1], row[2], row[3]),
                    });
                }
            }
        }
        DetectorLayout::Yolov8 => {
            let (rows, n) = (dims[1], dims[2]);
            if rows < 5 {
                return Err(format!("YOLOv8 columns of {rows} values; need 4 + classes"));
            }
            for i in 0..n {
                let at = |r: usize| data[r * n + i];
                let (class_id, score) = (4..rows)
                    .map(|r| (r - 4, at(r)))
                    .fold((0, f32::MIN), |best, c| if c.1 > best.1 { c } else { best });
                let b = [at(0), at(1), at(2), at(3)];
                if score >= min_score && b.iter().all(|v| v.is_finite()) {
                    out.push(DetectedBox {
                        class_id,
                        score,
                        bbox: to_corner(b[0], b[1], b[2], b[3]),
                    });
                }
            }
        }
    }
    Ok(out.len() - before)
}

/// Parse class names from model metadata: `a,b,c` or a Python dict `{0: 'a', 1: 'b'}`.
pub fn parse_class_names(text: &str) -> Vec<String> {
    let t = text.trim();
    if let Some(inner) = t.strip_prefix('{').and_then(|r| r.strip_suffix('}')) {
        let mut names: Vec<(usize, String)> = inner
            .split(',')
            .filter_map(|pair| {
                let (k, v) = pair.split_once(':')?;
                let v = v.trim().trim_matches(|c| c == '\'' || c == '"');
                Some((k.trim().parse().ok()?, v.to_string()))
            })
            .collect();
        names.sort_by_key(|(k, _)| *k);
        names.into_iter().map(|(_, v)| v).collect()
    } else {
        t.split(',')
            .map(|s| s.trim().to_string())
            .filter(|s| !s.is_empty())
            .collect()
    }
}

/// A YOLO-family detector.
#[derive(Debug)]
pub struct Detector {
    model: OnnxModel,
    layout: DetectorLayout,
    names: Vec<String>,
    side: usize,
    input: Vec<f32>,
    /// Boxes below this score are dropped before NMS.
    pub min_score: f32,
    /// IoU above which NMS suppresses a box.
    pub iou_threshold: f32,
}

impl Detector {
    /// Load `file` from the cache. The layout comes from the model's `layout` metadata
    /// (`yolov5`) or, without it, is taken as YOLOv8 (the Ultralytics export format); the
    /// input side from the model's fixed input shape or its `imgsz` metadata.
    pub fn load(
        store: &ModelStore,
        file: &str,
        options: &SessionOptions,
    ) -> Result<Self, ModelError> {
        let model = OnnxModel::load_with(store, file, options)?;
        let layout = match model.metadata("layout").as_deref() {
            Some("yolov5") => DetectorLayout::Yolov5,
            Some("yolov8") | None => DetectorLayout::Yolov8,
            Some(other) => return Err(model.interface_error(format!("unknown layout `{other}`"))),
        };
        let names = model
            .metadata("names")
            .map(|n| parse_class_names(&n))
            .unwrap_or_default();
        if names.is_empty() {
            return Err(model.interface_error("no class names in the model's metadata"));
        }
        let side = Self::input_side(&model).ok_or_else(|| {
            model.interface_error("cannot tell the input size (fixed shape or `imgsz`)")
        })?;
        Ok(Self {
            model,
            layout,
            names,
            side,
            input: vec![0.0; 3 * side * side],
            min_score: 0.25,
            iou_threshold: 0.45,
        })
    }

    fn input_side(model: &OnnxModel) -> Option<usize> {
        let m = model
            .metadata("input_size")
            .or_else(|| model.metadata("imgsz"))?;
        m.split(|c: char| !c.is_ascii_digit())
            .find(|s| !s.is_empty())?
            .parse()
            .ok()
    }

    /// Run the model once on a blank frame: its first run allocates the session's memory
    /// and is several times slower, so a role pays it before it reports ready.
    pub fn warm_up(&mut self) -> Result<(), ModelError> {
        let side = self.side;
        let blank = vec![0u8; side * side * 3];
        let mut out = Vec::new();
        self.detect(&blank, side, side, &mut out)
    }

    /// The output layout.
    pub fn layout(&self) -> DetectorLayout {
        self.layout
    }

    /// Class names, indexed by `class_id`.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// Side of the square network input.
    pub fn input_side_px(&self) -> usize {
        self.side
    }

    /// Detect objects in packed RGB8 `rgb` (`width` x `height`); `out` receives the boxes
    /// in image pixels after NMS, best first.
    pub fn detect(
        &mut self,
        rgb: &[u8],
        width: usize,
        height: usize,
        out: &mut Vec<DetectedBox>,
    ) -> Result<(), ModelError> {
        out.clear();
        if let Some(reason) = rgb8_mismatch(rgb, width, height) {
            return Err(self.model.interface_error(reason));
        }
        let lb: Letterbox = letterbox_chw(rgb, width, height, self.side, &mut self.input);
        let side = self.side;
        let (layout, min_score) = (self.layout, self.min_score);
        self.model
            .run_f32(&[1, 3, side, side], &self.input, |shape, data| {
                decode(layout, shape, data, min_score, out)
            })?;
        non_max_suppression(out, self.iou_threshold);
        for b in out.iter_mut() {
            let m = lb.to_image(b.bbox);
            let x0 = m[0].clamp(0.0, width as f32);
            let y0 = m[1].clamp(0.0, height as f32);
            let x1 = (m[0] + m[2]).clamp(0.0, width as f32);
            let y1 = (m[1] + m[3]).clamp(0.0, height as f32);
            b.bbox = [x0, y0, x1 - x0, y1 - y0];
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn b(class_id: usize, score: f32, bbox: [f32; 4]) -> DetectedBox {
        DetectedBox {
            class_id,
            score,
            bbox,
        }
    }

    #[test]
    fn iou_of_known_boxes() {
        assert_eq!(iou([0.0, 0.0, 2.0, 2.0], [0.0, 0.0, 2.0, 2.0]), 1.0);
        assert_eq!(iou([0.0, 0.0, 2.0, 2.0], [2.0, 2.0, 2.0, 2.0]), 0.0);
        assert!((iou([0.0, 0.0, 2.0, 2.0], [1.0, 0.0, 2.0, 2.0]) - 1.0 / 3.0).abs() < 1e-6);
        assert_eq!(iou([0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0]), 0.0);
    }

    #[test]
    fn nms_keeps_the_best_of_overlapping_boxes_per_class() {
        let mut boxes = vec![
            b(0, 0.6, [0.0, 0.0, 10.0, 10.0]),
            b(0, 0.9, [1.0, 1.0, 10.0, 10.0]),
            b(1, 0.5, [1.0, 1.0, 10.0, 10.0]), // other class: kept
            b(0, 0.4, [50.0, 50.0, 10.0, 10.0]), // far away: kept
        ];
        non_max_suppression(&mut boxes, 0.45);
        let kept: Vec<(usize, f32)> = boxes.iter().map(|d| (d.class_id, d.score)).collect();
        assert_eq!(kept, vec![(0, 0.9), (1, 0.5), (0, 0.4)]);
    }

    #[test]
    fn decodes_both_layouts() {
        // YOLOv5: 2 rows of (cx, cy, w, h, obj, c0, c1)
        let v5 = [
            50.0, 50.0, 20.0, 10.0, 0.9, 0.1, 0.8, 1.0, 1.0, 1.0, 1.0, 0.1, 0.9, 0.1,
        ];
        let mut out = Vec::new();
        assert_eq!(
            decode(DetectorLayout::Yolov5, &[1, 2, 7], &v5, 0.25, &mut out),
            Ok(1)
        );
        assert_eq!(out[0].class_id, 1);
        assert!((out[0].score - 0.72).abs() < 1e-6);
        assert_eq!(out[0].bbox, [40.0, 45.0, 20.0, 10.0]);
        // YOLOv8: 3 columns, rows (cx, cy, w, h, c0, c1)
        let v8 = [
            10.0, 20.0, 30.0, // cx
            10.0, 20.0, 30.0, // cy
            4.0, 4.0, 4.0, // w
            2.0, 2.0, 2.0, // h
            0.1, 0.7, 0.2, // c0
            0.3, 0.1, 0.9, // c1
        ];
        out.clear();
        assert_eq!(
            decode(DetectorLayout::Yolov8, &[1, 6, 3], &v8, 0.5, &mut out),
            Ok(2)
        );
        assert_eq!((out[0].class_id, out[0].bbox), (0, [18.0, 19.0, 4.0, 2.0]));
        assert_eq!(out[1].class_id, 1);
        // shapes that do not match the data are errors, not panics
        assert!(decode(DetectorLayout::Yolov8, &[1, 6, 4], &v8, 0.5, &mut out).is_err());
        assert!(decode(DetectorLayout::Yolov5, &[1, 3, 4], &v5[..12], 0.5, &mut out).is_err());
        let nan = [f32::NAN; 7];
        assert_eq!(
            decode(DetectorLayout::Yolov5, &[1, 1, 7], &nan, 0.25, &mut out),
            Ok(0)
        );
    }

    #[test]
    fn parses_both_name_formats() {
        assert_eq!(
            parse_class_names("person,bicycle, car"),
            ["person", "bicycle", "car"]
        );
        assert_eq!(parse_class_names("{1: 'b', 0: 'a'}"), ["a", "b"]);
    }
}
