//! Sentence embeddings: all-MiniLM-L6-v2 through ONNX Runtime, WordPiece via `tokenizers`.

use crate::error::ModelError;
use crate::onnx::{OnnxModel, SessionOptions};
use crate::store::ModelStore;
use ort::value::TensorRef;
use std::path::PathBuf;
use tokenizers::Tokenizer;

/// Dimension of an embedding.
pub const EMBEDDING_DIM: usize = 384;
/// Longest input in tokens (longer texts are truncated).
pub const MAX_TOKENS: usize = 128;
/// Model file inside the cache.
pub const MODEL_FILE: &str = "embed/minilm-l6-v2.onnx";
/// Tokenizer file inside the cache.
pub const TOKENIZER_FILE: &str = "embed/tokenizer.json";

/// An L2-normalised sentence embedding.
pub type Embedding = [f32; EMBEDDING_DIM];

/// Cosine similarity of two normalised embeddings (their dot product).
pub fn cosine(a: &Embedding, b: &Embedding) -> f32 {
    a.iter().zip(b.iter()).map(|(x, y)| x * y).sum()
}

/// Turns text into [`Embedding`]s.
pub struct TextEmbedder {
    model: OnnxModel,
    tokenizer: Tokenizer,
    tokenizer_path: PathBuf,
    ids: Vec<i64>,
    mask: Vec<i64>,
}

impl std::fmt::Debug for TextEmbedder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TextEmbedder")
            .field("model", &self.model)
            .finish()
    }
}

impl TextEmbedder {
    /// Load the model and tokenizer from the cache, the model to run as `options` say.
    pub fn load(store: &ModelStore, options: &SessionOptions) -> Result<Self, ModelError> {
        let model = OnnxModel::load_with(store, MODEL_FILE, options)?;
        let tokenizer_path = store.verified(TOKENIZER_FILE)?;
        let tk_err = |reason: String| ModelError::Tokenizer {
            path: tokenizer_path.clone(),
            reason,
        };
        let mut tokenizer =
            Tokenizer::from_file(&tokenizer_path).map_err(|e| tk_err(e.to_string()))?;
        tokenizer.with_padding(None);
        tokenizer
            .with_truncation(Some(tokenizers::TruncationParams {
                max_length: MAX_TOKENS,
                ..Default::default()
            }))
            .map_err(|e| tk_err(e.to_string()))?;
        Ok(Self {
            model,
            tokenizer,
            tokenizer_path,
            ids: Vec::with_capacity(MAX_TOKENS * 16),
            mask: Vec::with_capacity(MAX_TOKENS * 16),
        })
    }

    /// Embed each of `texts` into `out` (resized to `texts.len()`), one batch.
    pub fn embed_into(
        &mut self,
        texts: &[&str],
        out: &mut Vec<Embedding>,
    ) -> Result<(), ModelError> {
        out.clear();
        if texts.is_empty() {
            return Ok(());
        }
        let encodings = self
            .tokenizer
            .encode_batch(texts.to_vec(), true)
            .map_err(|e| ModelError::Tokenizer {
                path: self.tokenizer_path.clone(),
                reason: e.to_string(),
            })?;
        let width = encodings
            .iter()
            .map(|e| e.get_ids().len())
            .max()
            .unwrap_or(0)
            .max(1);
        self.ids.clear();
        self.mask.clear();
        for e in &encodings {
            let n = e.get_ids().len();
            self.ids.extend(e.get_ids().iter().map(|&v| i64::from(v)));
            self.ids.extend(std::iter::repeat_n(0, width - n));
            self.mask.extend(std::iter::repeat_n(1, n));
            self.mask.extend(std::iter::repeat_n(0, width - n));
        }
        let shape = [texts.len(), width];
        let ids = TensorRef::from_array_view((shape, self.ids.as_slice()))
            .map_err(|e| self.model.inference_error(e))?;
        let mask = TensorRef::from_array_view((shape, self.mask.as_slice()))
            .map_err(|e| self.model.inference_error(e))?;
        let outputs = self
            .model
            .session()
            .run(ort::inputs!["input_ids" => ids, "attention_mask" => mask])
            .map_err(|e| ModelError::Inference {
                model: MODEL_FILE.into(),
                reason: e.to_string(),
            })?;
        let value = outputs
            .get("sentence_embedding")
            .ok_or_else(|| ModelError::Interface {
                model: MODEL_FILE.into(),
                reason: "no `sentence_embedding` output".into(),
            })?;
        let (shape, data) =
            value
                .try_extract_tensor::<f32>()
                .map_err(|e| ModelError::Interface {
                    model: MODEL_FILE.into(),
                    reason: e.to_string(),
                })?;
        if shape.len() != 2
            || shape[0] as usize != texts.len()
            || shape[1] as usize != EMBEDDING_DIM
        {
            return Err(ModelError::Interface {
                model: MODEL_FILE.into(),
                reason: format!(
                    "output shape {shape:?}, expected [{}, {EMBEDDING_DIM}]",
                    texts.len()
                ),
            });
        }
        for row in data.chunks_exact(EMBEDDING_DIM) {
            let mut e = [0.0; EMBEDDING_DIM];
            e.copy_from_slice(row);
            out.push(e);
        }
        Ok(())
    }

    /// Embed one text.
    pub fn embed(&mut self, text: &str) -> Result<Embedding, ModelError> {
        let mut out = Vec::with_capacity(1);
        self.embed_into(&[text], &mut out)?;
        out.pop().ok_or_else(|| ModelError::Interface {
            model: MODEL_FILE.into(),
            reason: "no embedding returned".into(),
        })
    }
}
