//! The BERT encoder of all-MiniLM-L6-v2 in f32, one sentence at a time (no padding, so no
//! attention mask is needed):
//!
//! - embeddings: word + position + token type 0, then LayerNorm;
//! - each layer: Q, K, V projections, per head `softmax(Q Kᵀ / √d_head) V`, output
//!   projection + residual + LayerNorm, then `GELU(x W₁ + b₁) W₂ + b₂` + residual + LayerNorm
//!   (GELU the exact `x Φ(x) = x (1 + erf(x / √2)) / 2` of `hidden_act = "gelu"`).
//!
//! Matrix products go through ndarray (matrixmultiply's kernels, AVX/FMA when the CPU has
//! them); LayerNorm statistics and the pooled norm accumulate in f64. Cost per sentence of
//! n tokens: about `L (4 h² + 2 h i) n + L h n²` multiply-adds (L layers, hidden h,
//! intermediate i) — 10.6 M per token for all-MiniLM-L6-v2.

use std::path::Path;

use ndarray::{Array1, Array2, ArrayView2, Axis, s};
use safetensors::{Dtype, SafeTensors};
use serde::Deserialize;

use crate::error::EmbedError;

/// The fields of `config.json` the encoder reads.
#[derive(Debug, Clone, Deserialize)]
pub struct BertConfig {
    /// Vocabulary size.
    pub vocab_size: usize,
    /// Hidden size h.
    pub hidden_size: usize,
    /// Layers L.
    pub num_hidden_layers: usize,
    /// Attention heads.
    pub num_attention_heads: usize,
    /// Feed-forward size i.
    pub intermediate_size: usize,
    /// Activation (only `gelu` is supported).
    pub hidden_act: String,
    /// Position embeddings: the longest input.
    pub max_position_embeddings: usize,
    /// Token types.
    pub type_vocab_size: usize,
    /// LayerNorm's ε.
    pub layer_norm_eps: f64,
    /// Only `absolute` is supported.
    #[serde(default = "absolute")]
    pub position_embedding_type: String,
}

fn absolute() -> String {
    "absolute".into()
}

impl BertConfig {
    fn validate(&self, path: &Path) -> Result<(), EmbedError> {
        let bad = |reason: String| {
            Err(EmbedError::Format {
                path: path.to_path_buf(),
                reason,
            })
        };
        if self.hidden_act != "gelu" {
            return bad(format!(
                "hidden_act {:?}: only \"gelu\" is supported",
                self.hidden_act
            ));
        }
        if self.position_embedding_type != "absolute" {
            return bad(format!(
                "position_embedding_type {:?}: only \"absolute\" is supported",
                self.position_embedding_type
            ));
        }
        if self.num_attention_heads == 0
            || self.hidden_size == 0
            || !self.hidden_size.is_multiple_of(self.num_attention_heads)
        {
            return bad(format!(
                "hidden_size {} is not a positive multiple of num_attention_heads {}",
                self.hidden_size, self.num_attention_heads
            ));
        }
        if self.type_vocab_size == 0 || self.max_position_embeddings < 2 {
            return bad("type_vocab_size and max_position_embeddings must be positive".into());
        }
        if !(self.layer_norm_eps > 0.0 && self.layer_norm_eps.is_finite()) {
            return bad(format!("layer_norm_eps {}", self.layer_norm_eps));
        }
        Ok(())
    }
}

/// A dense layer: `y = x wᵀ + b`, the weight kept transposed (`[in, out]`).
#[derive(Debug, Clone)]
struct Linear {
    w_t: Array2<f32>,
    b: Array1<f32>,
}

impl Linear {
    fn apply(&self, x: &ArrayView2<'_, f32>) -> Array2<f32> {
        let mut y = x.dot(&self.w_t);
        y += &self.b;
        y
    }
}

#[derive(Debug, Clone)]
struct LayerNorm {
    g: Vec<f32>,
    b: Vec<f32>,
    eps: f64,
}

impl LayerNorm {
    fn apply(&self, x: &mut Array2<f32>) {
        let (g, b) = (&self.g, &self.b);
        for mut row in x.rows_mut() {
            let n = row.len() as f64;
            let mean = row.iter().map(|&v| v as f64).sum::<f64>() / n;
            let var = row
                .iter()
                .map(|&v| {
                    let d = v as f64 - mean;
                    d * d
                })
                .sum::<f64>()
                / n;
            let inv = 1.0 / (var + self.eps).sqrt();
            for (j, v) in row.iter_mut().enumerate() {
                *v = (((*v as f64 - mean) * inv) as f32) * g[j] + b[j];
            }
        }
    }
}

#[derive(Debug, Clone)]
struct Layer {
    /// Query, key and value projections side by side (`[h, 3h]`).
    qkv: Linear,
    o: Linear,
    ln_attention: LayerNorm,
    up: Linear,
    down: Linear,
    ln_output: LayerNorm,
}

/// The encoder's weights.
#[derive(Clone)]
pub struct Bert {
    config: BertConfig,
    word: Array2<f32>,
    position: Array2<f32>,
    token_type: Array2<f32>,
    ln_embeddings: LayerNorm,
    layers: Vec<Layer>,
}

/// The configuration only (the weights are 90 MB).
impl std::fmt::Debug for Bert {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Bert")
            .field("config", &self.config)
            .finish_non_exhaustive()
    }
}

/// Reads the named tensors of a safetensors file as f32 arrays of the expected shapes.
struct Weights<'a> {
    path: &'a Path,
    st: SafeTensors<'a>,
    prefix: &'static str,
}

impl Weights<'_> {
    fn err(&self, reason: String) -> EmbedError {
        EmbedError::Format {
            path: self.path.to_path_buf(),
            reason,
        }
    }

    fn tensor(&self, name: &str, shape: &[usize]) -> Result<Vec<f32>, EmbedError> {
        let full = format!("{}{name}", self.prefix);
        let view = self
            .st
            .tensor(&full)
            .map_err(|e| self.err(format!("tensor {full}: {e}")))?;
        if view.dtype() != Dtype::F32 {
            return Err(self.err(format!(
                "tensor {full}: dtype {:?}, expected F32",
                view.dtype()
            )));
        }
        if view.shape() != shape {
            return Err(self.err(format!(
                "tensor {full}: shape {:?}, expected {shape:?}",
                view.shape()
            )));
        }
        Ok(view
            .data()
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect())
    }

    fn matrix(&self, name: &str, rows: usize, cols: usize) -> Result<Array2<f32>, EmbedError> {
        let v = self.tensor(name, &[rows, cols])?;
        Array2::from_shape_vec((rows, cols), v).map_err(|e| self.err(format!("{name}: {e}")))
    }

    fn vector(&self, name: &str, len: usize) -> Result<Array1<f32>, EmbedError> {
        Ok(Array1::from(self.tensor(name, &[len])?))
    }

    fn linear(&self, name: &str, n_in: usize, n_out: usize) -> Result<Linear, EmbedError> {
        let w = self.matrix(&format!("{name}.weight"), n_out, n_in)?;
        Ok(Linear {
            w_t: w.t().as_standard_layout().into_owned(),
            b: self.vector(&format!("{name}.bias"), n_out)?,
        })
    }

    fn layer_norm(&self, name: &str, n: usize, eps: f64) -> Result<LayerNorm, EmbedError> {
        Ok(LayerNorm {
            g: self.tensor(&format!("{name}.weight"), &[n])?,
            b: self.tensor(&format!("{name}.bias"), &[n])?,
            eps,
        })
    }
}

impl Bert {
    /// Loads the encoder from `config.json` and `model.safetensors` (tensor names of
    /// Hugging Face's `BertModel`, with or without the `bert.` prefix; f32 only).
    pub fn load(config_path: &Path, weights_path: &Path) -> Result<Self, EmbedError> {
        let text = std::fs::read_to_string(config_path).map_err(|source| EmbedError::Io {
            path: config_path.to_path_buf(),
            source,
        })?;
        let config: BertConfig = serde_json::from_str(&text).map_err(|e| EmbedError::Format {
            path: config_path.to_path_buf(),
            reason: format!("not a BERT config.json: {e}"),
        })?;
        config.validate(config_path)?;
        let bytes = std::fs::read(weights_path).map_err(|source| EmbedError::Io {
            path: weights_path.to_path_buf(),
            source,
        })?;
        let st = SafeTensors::deserialize(&bytes).map_err(|e| EmbedError::Format {
            path: weights_path.to_path_buf(),
            reason: format!("not a safetensors file: {e}"),
        })?;
        let prefix = if st.tensor("embeddings.word_embeddings.weight").is_ok() {
            ""
        } else {
            "bert."
        };
        let w = Weights {
            path: weights_path,
            st,
            prefix,
        };
        let c = &config;
        let (h, i) = (c.hidden_size, c.intermediate_size);
        let eps = c.layer_norm_eps;
        let layers = (0..c.num_hidden_layers)
            .map(|l| {
                let p = format!("encoder.layer.{l}");
                let (q, k, v) = (
                    w.linear(&format!("{p}.attention.self.query"), h, h)?,
                    w.linear(&format!("{p}.attention.self.key"), h, h)?,
                    w.linear(&format!("{p}.attention.self.value"), h, h)?,
                );
                Ok(Layer {
                    qkv: Linear {
                        w_t: ndarray::concatenate(
                            Axis(1),
                            &[q.w_t.view(), k.w_t.view(), v.w_t.view()],
                        )
                        .map_err(|e| w.err(format!("{p}: {e}")))?,
                        b: ndarray::concatenate(Axis(0), &[q.b.view(), k.b.view(), v.b.view()])
                            .map_err(|e| w.err(format!("{p}: {e}")))?,
                    },
                    o: w.linear(&format!("{p}.attention.output.dense"), h, h)?,
                    ln_attention: w.layer_norm(
                        &format!("{p}.attention.output.LayerNorm"),
                        h,
                        eps,
                    )?,
                    up: w.linear(&format!("{p}.intermediate.dense"), h, i)?,
                    down: w.linear(&format!("{p}.output.dense"), i, h)?,
                    ln_output: w.layer_norm(&format!("{p}.output.LayerNorm"), h, eps)?,
                })
            })
            .collect::<Result<Vec<_>, EmbedError>>()?;
        Ok(Self {
            word: w.matrix("embeddings.word_embeddings.weight", c.vocab_size, h)?,
            position: w.matrix(
                "embeddings.position_embeddings.weight",
                c.max_position_embeddings,
                h,
            )?,
            token_type: w.matrix(
                "embeddings.token_type_embeddings.weight",
                c.type_vocab_size,
                h,
            )?,
            ln_embeddings: w.layer_norm("embeddings.LayerNorm", h, eps)?,
            layers,
            config,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &BertConfig {
        &self.config
    }

    /// The last hidden state `[n, h]` of `ids` (at most `max_position_embeddings` of them,
    /// each below `vocab_size`; the tokenizer guarantees both).
    pub fn forward(&self, ids: &[u32]) -> Array2<f32> {
        self.forward_batch(&[ids]).remove(0)
    }

    /// The last hidden states of several sequences at once. The dense layers run on the
    /// tokens of all of them stacked (one matrix product per layer and weight, so the
    /// weights are streamed once per batch, not once per sentence); attention stays within
    /// each sequence. Each row's result is the same as [`forward`](Self::forward)'s.
    pub fn forward_batch(&self, seqs: &[&[u32]]) -> Vec<Array2<f32>> {
        let c = &self.config;
        let h = c.hidden_size;
        let lens: Vec<usize> = seqs
            .iter()
            .map(|ids| ids.len().min(c.max_position_embeddings))
            .collect();
        let total: usize = lens.iter().sum();
        let mut x = Array2::<f32>::zeros((total, h));
        let mut row0 = 0;
        for (ids, &n) in seqs.iter().zip(&lens) {
            for t in 0..n {
                let mut row = x.row_mut(row0 + t);
                let id = (ids[t] as usize).min(c.vocab_size - 1);
                row.assign(&self.word.row(id));
                row += &self.position.row(t);
                row += &self.token_type.row(0);
            }
            row0 += n;
        }
        self.ln_embeddings.apply(&mut x);
        let heads = c.num_attention_heads;
        let d = h / heads;
        let scale = 1.0 / (d as f32).sqrt();
        for layer in &self.layers {
            // Q, K and V in one product: columns [0, h), [h, 2h), [2h, 3h).
            let qkv = layer.qkv.apply(&x.view());
            let mut context = Array2::<f32>::zeros((total, h));
            let mut row0 = 0;
            for &n in &lens {
                let rows = row0..row0 + n;
                row0 += n;
                for head in 0..heads {
                    let col = head * d;
                    let q = qkv.slice(s![rows.clone(), col..col + d]);
                    let k = qkv.slice(s![rows.clone(), h + col..h + col + d]);
                    let v = qkv.slice(s![rows.clone(), 2 * h + col..2 * h + col + d]);
                    let mut scores = q.dot(&k.t());
                    for mut row in scores.rows_mut() {
                        let max = row.iter().copied().fold(f32::NEG_INFINITY, f32::max);
                        let mut sum = 0.0f32;
                        for s in row.iter_mut() {
                            *s = ((*s - max) * scale).exp();
                            sum += *s;
                        }
                        row /= sum;
                    }
                    context
                        .slice_mut(s![rows.clone(), col..col + d])
                        .assign(&scores.dot(&v));
                }
            }
            let mut a = layer.o.apply(&context.view());
            a += &x;
            layer.ln_attention.apply(&mut a);
            let mut up = layer.up.apply(&a.view());
            up.mapv_inplace(gelu);
            let mut out = layer.down.apply(&up.view());
            out += &a;
            layer.ln_output.apply(&mut out);
            x = out;
        }
        let mut out = Vec::with_capacity(lens.len());
        let mut row0 = 0;
        for &n in &lens {
            out.push(x.slice(s![row0..row0 + n, ..]).to_owned());
            row0 += n;
        }
        out
    }

    /// Mean of the last hidden state over the tokens, L2-normalised (sentence-transformers'
    /// `Pooling(mean)` then `Normalize`): the sentence embedding.
    pub fn embed_ids(&self, ids: &[u32]) -> Vec<f32> {
        pool(&self.forward(ids))
    }

    /// [`embed_ids`](Self::embed_ids) of several sequences, run as one batch.
    pub fn embed_ids_batch(&self, seqs: &[&[u32]]) -> Vec<Vec<f32>> {
        self.forward_batch(seqs).iter().map(pool).collect()
    }
}

/// Mean over the rows, L2-normalised (norm floored at 1e-12, as `F.normalize`).
fn pool(hidden: &Array2<f32>) -> Vec<f32> {
    let n = hidden.nrows().max(1) as f64;
    let mean: Vec<f64> = hidden
        .sum_axis(Axis(0))
        .iter()
        .map(|&v| v as f64 / n)
        .collect();
    let norm = mean.iter().map(|v| v * v).sum::<f64>().sqrt().max(1e-12);
    mean.iter().map(|v| (v / norm) as f32).collect()
}

/// The exact GELU, `x Φ(x)`.
fn gelu(x: f32) -> f32 {
    0.5 * x * (1.0 + libm::erff(x * std::f32::consts::FRAC_1_SQRT_2))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gelu_matches_its_definition() {
        // Φ(1) = 0.841344746…, Φ(−2) = 0.022750131…
        assert!((gelu(1.0) - 0.841_344_7).abs() < 1e-6);
        assert!((gelu(-2.0) + 2.0 * 0.022_750_13).abs() < 1e-6);
        assert_eq!(gelu(0.0), 0.0);
    }

    #[test]
    fn layer_norm_centres_and_scales_each_row() {
        let ln = LayerNorm {
            g: vec![1.0, 1.0, 2.0],
            b: vec![0.0, 0.0, 1.0],
            eps: 1e-12,
        };
        let mut x = Array2::from_shape_vec((1, 3), vec![1.0f32, 2.0, 3.0]).unwrap_or_default();
        ln.apply(&mut x);
        let s = (2.0f32 / 3.0).sqrt();
        let want = [-1.0 / s, 0.0, 2.0 / s + 1.0];
        for (a, b) in x.iter().zip(want) {
            assert!((a - b).abs() < 1e-6, "{a} vs {b}");
        }
    }
}
