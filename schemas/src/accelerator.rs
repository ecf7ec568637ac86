//! Accelerators a role may be bound to: an ONNX Runtime execution provider and its device,
//! written `KIND:DEVICE` (`cuda:0`) in a workflow's `[executors.NAME] accelerator` and in a
//! role's spec.

use core::fmt;
use core::str::FromStr;

/// The kinds of accelerator a model role can use: those ONNX Runtime execution providers
/// that take a device id.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AcceleratorKind {
    /// NVIDIA GPUs through CUDA (`CUDAExecutionProvider`): Jetson boards, discrete GPUs.
    Cuda,
    /// NVIDIA GPUs through TensorRT (`TensorrtExecutionProvider`), JetPack's engine.
    TensorRt,
    /// AMD GPUs through ROCm (`ROCMExecutionProvider`).
    Rocm,
}

impl AcceleratorKind {
    /// Every kind, in the order errors list them.
    pub const ALL: [AcceleratorKind; 3] = [
        AcceleratorKind::Cuda,
        AcceleratorKind::TensorRt,
        AcceleratorKind::Rocm,
    ];

    /// Its name in a workflow (`cuda`).
    pub fn name(self) -> &'static str {
        match self {
            AcceleratorKind::Cuda => "cuda",
            AcceleratorKind::TensorRt => "tensorrt",
            AcceleratorKind::Rocm => "rocm",
        }
    }

    /// The ONNX Runtime execution provider (`CUDAExecutionProvider`).
    pub fn provider(self) -> &'static str {
        match self {
            AcceleratorKind::Cuda => "CUDAExecutionProvider",
            AcceleratorKind::TensorRt => "TensorrtExecutionProvider",
            AcceleratorKind::Rocm => "ROCMExecutionProvider",
        }
    }
}

/// One accelerator device: a kind and its device id (`cuda:0`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Accelerator {
    /// The kind.
    pub kind: AcceleratorKind,
    /// The device id (0 for the first).
    pub device: u32,
}

impl fmt::Display for Accelerator {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}", self.kind.name(), self.device)
    }
}

/// Why an accelerator's name is not one.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum AcceleratorParseError {
    /// The kind is not one of [`AcceleratorKind::ALL`].
    #[error("unknown accelerator `{0}`: use cuda, tensorrt or rocm, with a device (`cuda:0`)")]
    UnknownKind(String),
    /// The device is not a number.
    #[error("accelerator `{0}`: the device after `:` must be a number (`cuda:0`)")]
    BadDevice(String),
}

impl FromStr for Accelerator {
    type Err = AcceleratorParseError;

    /// `KIND` (device 0) or `KIND:DEVICE`.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let (kind, device) = match s.split_once(':') {
            Some((k, d)) => (
                k,
                d.parse()
                    .map_err(|_| AcceleratorParseError::BadDevice(s.to_string()))?,
            ),
            None => (s, 0),
        };
        let kind = AcceleratorKind::ALL
            .into_iter()
            .find(|k| k.name() == kind)
            .ok_or_else(|| AcceleratorParseError::UnknownKind(s.to_string()))?;
        Ok(Accelerator { kind, device })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_parse_and_print_back() {
        let a: Accelerator = "cuda:1".parse().unwrap();
        assert_eq!(a.kind, AcceleratorKind::Cuda);
        assert_eq!(a.device, 1);
        assert_eq!(a.to_string(), "cuda:1");
        assert_eq!(
            "tensorrt".parse::<Accelerator>().unwrap().to_string(),
            "tensorrt:0"
        );
        assert_eq!(
            "npu:0".parse::<Accelerator>(),
            Err(AcceleratorParseError::UnknownKind("npu:0".into()))
        );
        assert_eq!(
            "cuda:x".parse::<Accelerator>(),
            Err(AcceleratorParseError::BadDevice("cuda:x".into()))
        );
    }
}
