//! The `openai` backend: any OpenAI-compatible server (vLLM, llama.cpp's `llama-server`,
//! Ollama, hosted APIs behind a local proxy) through `POST {base}/v1/chat/completions`.
//!
//! - The request carries the query's system and user prompts, then each image as a
//!   `data:image/png;base64,…` URL in object form, preceded by a text line naming its view
//!   and age; deficit regions are painted black with a 2 px red outline first (the paper's
//!   cue), unless `mark_deficits` is off.
//! - `response_format` is `json_schema` with the nested `json_schema.schema` form and
//!   `strict: true`; `temperature` 0 by default.
//! - The API key is read once from the environment variable named by `api_key_env` and sent
//!   as `Authorization: Bearer …`; it is never logged or printed (`Debug` redacts it). No
//!   variable set: no header (local servers).
//! - One connection per call, plain HTTP (`http://` URLs only: put hosted HTTPS APIs behind a
//!   local forwarding proxy). The whole call — connect, send, wait, read — is bounded by
//!   `timeout_ms`; the reply body by 4 MiB.
//! - The answer is `choices[0].message.content`; an error status, a reply that is not a chat
//!   completion, a refusal, or `finish_reason: "length"` is a [`BackendError`]. The content
//!   itself is validated by the controller like every other backend's answer.

use std::fmt;
use std::time::Duration;

use bytes::Bytes;
use fogline_io::http::PostError;
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};
use tokio::runtime::Runtime;

use super::{Backend, BackendError, Query};
use crate::RcoError;
use crate::observation::View;

/// The path appended to the base URL.
pub const COMPLETIONS_PATH: &str = "/v1/chat/completions";
/// The largest reply body read, bytes.
pub const MAX_REPLY_BYTES: usize = 4 << 20;

/// Settings of the `openai` backend.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct OpenAiParams {
    /// The server, `http://host:port` (a path prefix is allowed; a trailing `/v1` is
    /// dropped).
    pub base_url: String,
    /// The model name sent in every request.
    pub model: String,
    /// The environment variable holding the API key (empty: none).
    pub api_key_env: String,
    /// The limit of one call, ms.
    pub timeout_ms: u64,
    /// `max_tokens` of every request.
    pub max_tokens: u32,
    /// `temperature` of every request.
    pub temperature: f64,
    /// Send the frames (off: text only).
    pub send_images: bool,
    /// Paint the deficit regions black with a red outline before sending.
    pub mark_deficits: bool,
}

impl Default for OpenAiParams {
    fn default() -> Self {
        Self {
            base_url: "http://127.0.0.1:8000".into(),
            model: "Qwen/Qwen2-VL-2B-Instruct".into(),
            api_key_env: "OPENAI_API_KEY".into(),
            timeout_ms: 20_000,
            max_tokens: 512,
            temperature: 0.0,
            send_images: true,
            mark_deficits: true,
        }
    }
}

/// A blocking client of an OpenAI-compatible chat completions endpoint.
pub struct OpenAiBackend {
    params: OpenAiParams,
    authority: String,
    path: String,
    api_key: Option<String>,
    runtime: Runtime,
}

impl fmt::Debug for OpenAiBackend {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("OpenAiBackend")
            .field("params", &self.params)
            .field("api_key", &self.api_key.as_ref().map(|_| "<redacted>"))
            .finish_non_exhaustive()
    }
}

impl OpenAiParams {
    /// The base URL, checked (`http://host[:port][/prefix]`): a malformed one is an error
    /// before any call is made.
    pub fn parsed_url(&self) -> Result<fogline_io::http::BaseUrl, RcoError> {
        let url = self.base_url.trim();
        fogline_io::http::BaseUrl::parse(url)
            .map_err(|e| RcoError::Backend(format!("base URL {url:?}: {e}")))
    }
}

impl OpenAiBackend {
    /// A client for `params.base_url` (nothing is connected until the first call). Reads the
    /// API key from the environment now.
    pub fn new(params: OpenAiParams) -> Result<Self, RcoError> {
        let base = params.parsed_url()?;
        let prefix = base
            .prefix
            .strip_suffix("/v1")
            .unwrap_or(&base.prefix)
            .to_string();
        let authority = base.authority;
        if params.timeout_ms == 0 {
            return Err(RcoError::Backend("timeout_ms must be >= 1".into()));
        }
        if params.model.trim().is_empty() {
            return Err(RcoError::Backend("the model name is empty".into()));
        }
        if !params.temperature.is_finite() || params.temperature < 0.0 {
            return Err(RcoError::Backend(
                "temperature must be finite and >= 0".into(),
            ));
        }
        let api_key = if params.api_key_env.is_empty() {
            None
        } else {
            std::env::var(&params.api_key_env)
                .ok()
                .filter(|k| !k.trim().is_empty())
        };
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .map_err(|e| RcoError::Backend(format!("cannot start the client runtime: {e}")))?;
        Ok(Self {
            path: format!("{prefix}{COMPLETIONS_PATH}"),
            authority,
            params,
            api_key,
            runtime,
        })
    }

    /// The settings.
    pub fn params(&self) -> &OpenAiParams {
        &self.params
    }

    /// Whether an API key was found in the environment.
    pub fn has_api_key(&self) -> bool {
        self.api_key.is_some()
    }

    /// The JSON request body of `query`.
    pub fn request_body(&self, query: &Query<'_>) -> Result<Value, BackendError> {
        let mut content = vec![json!({"type": "text", "text": query.user})];
        if self.params.send_images {
            for img in &query.images {
                let png = png_of(img.view, self.params.mark_deficits)
                    .map_err(|e| BackendError::Protocol(format!("cannot encode a frame: {e}")))?;
                content.push(json!({
                    "type": "text",
                    "text": format!("Image: {} camera, {} tick(s) ago.", img.camera.short(), img.ticks_ago),
                }));
                content.push(json!({
                    "type": "image_url",
                    "image_url": {"url": fogline_io::data_url(&png, fogline_io::ImageFormat::Png)},
                }));
            }
        }
        Ok(json!({
            "model": self.params.model,
            "messages": [
                {"role": "system", "content": query.system},
                {"role": "user", "content": content},
            ],
            "temperature": self.params.temperature,
            "max_tokens": self.params.max_tokens,
            "response_format": {
                "type": "json_schema",
                "json_schema": {"name": query.schema_name, "strict": true, "schema": query.schema},
            },
        }))
    }

    async fn post(&self, body: Vec<u8>) -> Result<(u16, Bytes), BackendError> {
        fogline_io::http::post_json(
            &self.authority,
            &self.path,
            body,
            self.api_key.as_deref(),
            MAX_REPLY_BYTES,
        )
        .await
        .map_err(|e| match e {
            // It answered, with something that is not a usable reply.
            PostError::NotHttp(_) | PostError::Body(_) | PostError::TooLarge(_) => {
                BackendError::Protocol(e.to_string())
            }
            PostError::Connect(_)
            | PostError::Connection(_)
            | PostError::Timeout(_)
            | PostError::Request(_) => BackendError::Unavailable {
                url: self.params.base_url.clone(),
                reason: e.to_string(),
            },
        })
    }
}

/// The start of a reply body, for error messages (printable ASCII, at most 200 characters).
fn excerpt(body: &[u8]) -> String {
    String::from_utf8_lossy(body)
        .chars()
        .filter(|c| c.is_ascii_graphic() || *c == ' ')
        .take(200)
        .collect()
}

/// The content of a chat completion reply.
pub fn completion_content(body: &[u8]) -> Result<String, BackendError> {
    let v: Value = serde_json::from_slice(body)
        .map_err(|e| BackendError::Protocol(format!("not JSON ({e}): {}", excerpt(body))))?;
    let choice = v
        .get("choices")
        .and_then(|c| c.get(0))
        .ok_or_else(|| BackendError::Protocol("no choices[0]".into()))?;
    if choice.get("finish_reason").and_then(Value::as_str) == Some("length") {
        return Err(BackendError::Truncated);
    }
    let msg = choice
        .get("message")
        .ok_or_else(|| BackendError::Protocol("no choices[0].message".into()))?;
    match msg.get("content") {
        Some(Value::String(s)) => Ok(s.clone()),
        _ => match msg.get("refusal").and_then(Value::as_str) {
            Some(r) => Err(BackendError::Refused(excerpt(r.as_bytes()))),
            None => Err(BackendError::Protocol(
                "choices[0].message.content is not a string".into(),
            )),
        },
    }
}

/// The pixel rectangle `[x0, x1) × [y0, y1)` of a box (edges rounded, clipped).
fn pixel_rect(b: &crate::observation::PixelBox, w: u32, h: u32) -> (usize, usize, usize, usize) {
    let c = b.clipped(w, h);
    let r = |v: f64| v.round().max(0.0) as usize;
    (r(c.x_px), r(c.y_px), r(c.x_end_px()), r(c.y_end_px()))
}

/// The view's frame as PNG, its deficits painted black with a 2 px red outline when `mark`.
pub fn png_of(view: &View, mark: bool) -> Result<Vec<u8>, String> {
    let rgb = view.rgb.as_deref().ok_or("the view has no pixels")?;
    let (w, h) = (view.width, view.height);
    let mut px = rgb.to_vec();
    if mark {
        let stride = w as usize * 3;
        for d in &view.deficits {
            let (x0, y0, x1, y1) = pixel_rect(d, w, h);
            for y in y0..y1 {
                for x in x0..x1 {
                    let edge = x < x0 + 2 || x + 2 >= x1 || y < y0 + 2 || y + 2 >= y1;
                    let i = y * stride + x * 3;
                    let c = if edge { [255, 0, 0] } else { [0, 0, 0] };
                    px[i..i + 3].copy_from_slice(&c);
                }
            }
        }
    }
    fogline_io::encode(&px, w, h, fogline_io::ImageFormat::Png)
}

impl Backend for OpenAiBackend {
    fn describe(&self) -> String {
        format!(
            "openai-compatible model {} at {}",
            self.params.model, self.params.base_url
        )
    }

    fn answer(&mut self, query: &Query<'_>) -> Result<String, BackendError> {
        let body = serde_json::to_vec(&self.request_body(query)?)
            .map_err(|e| BackendError::Protocol(format!("cannot serialise the request: {e}")))?;
        let limit = Duration::from_millis(self.params.timeout_ms);
        let (status, reply) = self
            .runtime
            .block_on(async { tokio::time::timeout(limit, self.post(body)).await })
            .map_err(|_| BackendError::Timeout {
                timeout_ms: self.params.timeout_ms,
            })??;
        if !(200..300).contains(&status) {
            return Err(BackendError::Status {
                status,
                body: excerpt(&reply),
            });
        }
        completion_content(&reply)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn urls() {
        let p = |u: &str| OpenAiParams {
            base_url: u.into(),
            api_key_env: String::new(),
            ..OpenAiParams::default()
        };
        let b = OpenAiBackend::new(p("http://127.0.0.1:8000/v1")).unwrap();
        assert_eq!(b.path, "/v1/chat/completions");
        assert_eq!(b.authority, "127.0.0.1:8000");
        let b = OpenAiBackend::new(p("http://llm.local/proxy/")).unwrap();
        assert_eq!(b.path, "/proxy/v1/chat/completions");
        assert_eq!(b.authority, "llm.local:80");
        assert!(OpenAiBackend::new(p("https://api.example.invalid")).is_err());
    }

    #[test]
    fn replies() {
        let ok = br#"{"choices":[{"message":{"content":"{}"},"finish_reason":"stop"}]}"#;
        assert_eq!(completion_content(ok).unwrap(), "{}");
        let cut = br#"{"choices":[{"message":{"content":"{"},"finish_reason":"length"}]}"#;
        assert_eq!(completion_content(cut), Err(BackendError::Truncated));
        let refused = br#"{"choices":[{"message":{"content":null,"refusal":"no"}}]}"#;
        assert!(matches!(
            completion_content(refused),
            Err(BackendError::Refused(_))
        ));
        assert!(completion_content(b"<html>").is_err());
        assert!(completion_content(br#"{"choices":[]}"#).is_err());
    }
}
