//! The one error type of model hosting.

use std::path::PathBuf;

/// The command that (re)creates the model cache; every "fix it" hint names it.
pub const PROVISION_COMMAND: &str = "scripts/provision-models.sh";

/// Why a model could not be loaded or run.
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    /// The cache folder or its manifest does not exist.
    #[error("no model cache at {root} (missing MANIFEST.sha256): run {PROVISION_COMMAND}")]
    NotProvisioned {
        /// The cache folder looked at.
        root: PathBuf,
    },
    /// The manifest cannot be read or parsed.
    #[error(
        "the model manifest {path} is unreadable or malformed ({reason}): run {PROVISION_COMMAND}"
    )]
    Manifest {
        /// The manifest's path.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// The manifest does not list the file: another cache layout or a typo in the workflow.
    #[error(
        "model `{file}` is not in the cache manifest of {root}: check the workflow's model path, or run {PROVISION_COMMAND}"
    )]
    Unknown {
        /// Path relative to the cache.
        file: String,
        /// The cache folder.
        root: PathBuf,
    },
    /// The file is listed but missing.
    #[error("model file {path} is missing: run {PROVISION_COMMAND}")]
    Missing {
        /// Its path.
        path: PathBuf,
    },
    /// The file's sha256 differs from the manifest: corrupt, truncated or replaced.
    #[error(
        "model file {path} is corrupt (sha256 {actual}, expected {expected}): run {PROVISION_COMMAND}"
    )]
    Corrupt {
        /// Its path.
        path: PathBuf,
        /// sha256 from the manifest.
        expected: String,
        /// sha256 of the file.
        actual: String,
    },
    /// An I/O error while reading a model file.
    #[error("cannot read {path}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The ONNX Runtime library could not be loaded or initialised.
    #[error("cannot start ONNX Runtime from {path}: {reason} (run {PROVISION_COMMAND})")]
    Runtime {
        /// The library path.
        path: PathBuf,
        /// What ONNX Runtime or the loader said.
        reason: String,
    },
    /// The ONNX Runtime loaded has no execution provider for the accelerator asked for.
    #[error(
        "accelerator `{accelerator}` needs ONNX Runtime's {}, which {library} does not offer (it offers: {available}); use an ONNX Runtime built with it (AERIS_ONNXRUNTIME=PATH) or bind the role to a CPU executor",
        accelerator.kind.provider()
    )]
    ProviderUnavailable {
        /// The accelerator (`cuda:0`), whose kind names the execution provider it needs.
        accelerator: aeris_schemas::accelerator::Accelerator,
        /// The ONNX Runtime library loaded.
        library: PathBuf,
        /// The providers that library offers.
        available: String,
    },
    /// The user's own ONNX Runtime library (`$AERIS_ONNXRUNTIME`) could not be loaded: it
    /// is missing, not an ONNX Runtime, or a version `ort` does not support.
    #[error("cannot start the ONNX Runtime that AERIS_ONNXRUNTIME names: {reason}")]
    OwnRuntime {
        /// The library path.
        path: PathBuf,
        /// What the loader or `ort`'s version check said (naming the library).
        reason: String,
    },
    /// ONNX Runtime refused the model file.
    #[error("cannot load model {path}: {reason}")]
    Load {
        /// The model file.
        path: PathBuf,
        /// What ONNX Runtime said.
        reason: String,
    },
    /// Running the model failed.
    #[error("model `{model}` failed to run: {reason}")]
    Inference {
        /// Model name.
        model: String,
        /// What ONNX Runtime said.
        reason: String,
    },
    /// The model's inputs or outputs are not what the caller expects.
    #[error("model `{model}` has an unexpected interface: {reason}")]
    Interface {
        /// Model name.
        model: String,
        /// What differs.
        reason: String,
    },
    /// The tokenizer could not be loaded or failed on an input.
    #[error("tokenizer {path}: {reason}")]
    Tokenizer {
        /// tokenizer.json path.
        path: PathBuf,
        /// What failed.
        reason: String,
    },
}
