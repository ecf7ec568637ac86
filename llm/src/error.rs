//! Why a language model could not load, decide or write (one error for the reasoner and the
//! formation writer, which share llama.cpp's backend and decoding).

use crate::grammar::GrammarError;
use crate::view::ViewError;
use aeris_models::ModelError;
use aeris_schemas::accelerator::Accelerator;

/// Why the reasoner could not load or could not decide.
#[derive(Debug, thiserror::Error)]
pub enum LlmError {
    /// The model file is missing, corrupt or unknown (names the provisioning command).
    #[error(transparent)]
    Model(#[from] ModelError),
    /// llama.cpp's backend did not initialise.
    #[error("llama.cpp backend: {0}")]
    Backend(String),
    /// llama.cpp could not load the GGUF file.
    #[error("llama.cpp could not load {file}: {reason}")]
    Load {
        /// Cache-relative file.
        file: String,
        /// llama.cpp's error.
        reason: String,
    },
    /// llama.cpp could not load or apply a LoRA adapter to its base.
    #[error("llama.cpp could not apply the adapter {file}: {reason}")]
    Adapter {
        /// Cache-relative adapter file.
        file: String,
        /// llama.cpp's error.
        reason: String,
    },
    /// No grammar exists for the mission's limits.
    #[error("cannot build the decision grammar")]
    Grammar(#[from] GrammarError),
    /// llama.cpp rejected a generated grammar (a bug in the generator).
    #[error("llama.cpp rejected the generated grammar: {0}")]
    GrammarRejected(String),
    /// The chat template could not be applied.
    #[error("chat template: {0}")]
    Template(String),
    /// The prompt does not fit the context.
    #[error("the prompt has {tokens} tokens; the context holds {context}")]
    PromptTooLong {
        /// Prompt tokens.
        tokens: usize,
        /// Context size.
        context: usize,
    },
    /// The role is bound to an accelerator llama.cpp cannot offload to: only CUDA devices are
    /// offloaded (TensorRT and ROCm name ONNX Runtime providers).
    #[error(
        "accelerator `{0}`: llama.cpp offloads language models to CUDA devices only (`cuda:N`)"
    )]
    OffloadKind(Accelerator),
    /// The role is bound to a CUDA device, and this build's llama.cpp has no GPU offload.
    #[error(
        "accelerator `{0}`: this build's llama.cpp has no GPU offload; build aeris with \
         `--features cuda` (CUDA toolkit needed) or bind the role to a CPU executor"
    )]
    OffloadNotBuilt(Accelerator),
    /// The build offloads, but llama.cpp found no GPU device at run time.
    #[error(
        "accelerator `{0}`: llama.cpp was built with GPU offload but finds no GPU device on this \
         machine (driver missing or device not visible)"
    )]
    OffloadUnavailable(Accelerator),
    /// Evaluation failed inside llama.cpp.
    #[error("llama.cpp decode: {0}")]
    Decode(String),
    /// The grammar allowed no token of the vocabulary (a bug in the grammar generator).
    #[error("the grammar allows no token for `{field}`")]
    NoAllowedToken {
        /// JSON field being written.
        field: &'static str,
    },
    /// The output did not close within the token budget.
    #[error("no complete decision within {0} tokens")]
    Truncated(usize),
    /// No complete formation program within the token budget.
    #[error("no complete formation program within {0} tokens")]
    ProgramTruncated(usize),
    /// The output is not a formation program (cannot happen under the grammar; checked
    /// anyway).
    #[error("output {text:?} is not a formation program")]
    ProgramOutput {
        /// What the model wrote.
        text: String,
        /// Why it does not parse.
        source: serde_json::Error,
    },
    /// The output is not a decision (cannot happen under the grammar; checked anyway).
    #[error("output {text:?} is not a decision")]
    Output {
        /// What the model wrote.
        text: String,
        /// Why it does not parse.
        source: ViewError,
    },
}
