//! The `openai` backend: any OpenAI-compatible server (vLLM, llama.cpp's `llama-server`,
//! llama-cpp-python, Ollama, hosted APIs) through `POST {base}/v1/chat/completions`.
//!
//! - The request carries the query's system and user prompts, then each image as a
//!   `data:image/png;base64,…` URL in object form, preceded by a text line naming its view
//!   and age; deficit regions are painted black with a 2 px red outline first (the paper's
//!   cue), unless `mark_deficits` is off. A query without images sends the user prompt as a
//!   plain string (some text-only chat templates drop a list of parts).
//! - Structured output is negotiated ([`StructuredOutput`]): first `response_format`
//!   `json_schema` (the nested `json_schema.schema` form, `strict: true`); a server that
//!   refuses it (HTTP 400, 422 or 500 whose body names `response_format`, `json_schema`,
//!   `json_object` or `'text'`) is asked again at once with `{"type": "json_object",
//!   "schema": …}`, and one that refuses that too with no `response_format` at all. Without
//!   `json_schema` the schema is written into the system prompt too, restated for grammar
//!   servers (`prompt::grammar_schema`: patterns on free strings, small integer ranges as
//!   enums), so that they write only what the answer check accepts. The mode the server took
//!   is kept for the backend's life (no failing round trip is repeated) and logged at info
//!   level; every answer is validated by the controller the same way in every mode.
//!   `temperature` 0 by default.
//! - The API key is read once from the environment variable named by `api_key_env` and sent
//!   as `Authorization: Bearer …`; it is never logged or printed (`Debug` redacts it). No
//!   variable set: no header (local servers).
//! - One connection per call, `http://` or `https://` (TLS through `fogline_io::http`:
//!   Mozilla's roots plus the PEM file `ca_cert`). The whole call — connect, send, wait,
//!   read, and a renegotiation's second request — is bounded by `timeout_ms`; the reply
//!   body by 4 MiB.
//! - The answer is `choices[0].message.content`; an error status, a reply that is not a chat
//!   completion, a refusal, or `finish_reason: "length"` is a [`BackendError`]. The content
//!   itself is validated by the controller like every other backend's answer.

use std::fmt;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use bytes::Bytes;
use fogline_io::http::{BaseUrl, PostError, Tls};
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

/// How the answer's JSON schema reaches the server.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StructuredOutput {
    /// `json_schema`, then `json_object`, then `prompt`, each tried when the server refused
    /// the one before (the default).
    #[default]
    Auto,
    /// `response_format: {"type": "json_schema", "json_schema": {"name", "strict", "schema"}}`
    /// (vLLM, llama.cpp's server, Ollama, hosted APIs).
    JsonSchema,
    /// `response_format: {"type": "json_object", "schema": …}` (llama-cpp-python, llama.cpp's
    /// server), the schema also in the system prompt.
    JsonObject,
    /// No `response_format`: the schema in the system prompt only.
    Prompt,
}

impl StructuredOutput {
    /// Every value, in the order `auto` tries the modes (after `auto` itself).
    pub const ALL: [StructuredOutput; 4] = [
        StructuredOutput::Auto,
        StructuredOutput::JsonSchema,
        StructuredOutput::JsonObject,
        StructuredOutput::Prompt,
    ];

    /// The snake-case name.
    pub fn name(self) -> &'static str {
        match self {
            StructuredOutput::Auto => "auto",
            StructuredOutput::JsonSchema => "json_schema",
            StructuredOutput::JsonObject => "json_object",
            StructuredOutput::Prompt => "prompt",
        }
    }

    /// The value named `s` (`auto`, `json_schema`, `json_object`, `prompt`).
    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|m| m.name() == s.trim())
    }

    fn is_auto(&self) -> bool {
        *self == StructuredOutput::Auto
    }

    /// The mode tried after this one was refused (`auto` only).
    fn next(self) -> Option<Self> {
        match self {
            StructuredOutput::Auto | StructuredOutput::JsonSchema => {
                Some(StructuredOutput::JsonObject)
            }
            StructuredOutput::JsonObject => Some(StructuredOutput::Prompt),
            StructuredOutput::Prompt => None,
        }
    }
}

/// Settings of the `openai` backend.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct OpenAiParams {
    /// The server, `http://host:port` or `https://host[:port]` (a path prefix is allowed; a
    /// trailing `/v1` is dropped).
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
    /// `https://`: a PEM file of certificates trusted besides the bundled roots (a private
    /// CA). Default: the process default (`fogline_io::http::set_default_ca_cert`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ca_cert: Option<PathBuf>,
    /// How the answer's schema reaches the server (default `auto`: negotiated).
    #[serde(skip_serializing_if = "StructuredOutput::is_auto")]
    pub structured_output: StructuredOutput,
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
            ca_cert: None,
            structured_output: StructuredOutput::Auto,
        }
    }
}

/// A blocking client of an OpenAI-compatible chat completions endpoint.
pub struct OpenAiBackend {
    params: OpenAiParams,
    url: BaseUrl,
    tls: Tls,
    path: String,
    api_key: Option<String>,
    /// The structured output mode the next request uses (never `Auto`).
    mode: StructuredOutput,
    /// The modes the server refused, in order.
    refused: Vec<StructuredOutput>,
    /// Whether the server has answered in `mode` yet.
    confirmed: bool,
    runtime: Runtime,
}

impl fmt::Debug for OpenAiBackend {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("OpenAiBackend")
            .field("params", &self.params)
            .field("api_key", &self.api_key.as_ref().map(|_| "<redacted>"))
            .field("structured_output", &self.mode)
            .finish_non_exhaustive()
    }
}

impl OpenAiParams {
    /// The base URL, checked (`http://` or `https://host[:port][/prefix]`): a malformed one
    /// is an error before any call is made.
    pub fn parsed_url(&self) -> Result<BaseUrl, RcoError> {
        let url = self.base_url.trim();
        BaseUrl::parse(url).map_err(|e| RcoError::Backend(format!("base URL {url:?}: {e}")))
    }

    /// The TLS settings: the bundled roots plus `ca_cert` (read now), or the process default.
    pub fn tls(&self) -> Result<Tls, RcoError> {
        match &self.ca_cert {
            Some(path) => Tls::new(Some(path)),
            None => Tls::process_default(),
        }
        .map_err(|e| RcoError::Backend(e.to_string()))
    }
}

/// Whether an error reply refuses the request's `response_format` (rather than failing for
/// another reason): HTTP 400, 422 or 500 whose body names it or the accepted values.
pub fn refuses_response_format(status: u16, body: &[u8]) -> bool {
    if !matches!(status, 400 | 422 | 500) {
        return false;
    }
    let text = String::from_utf8_lossy(body).to_ascii_lowercase();
    ["response_format", "json_schema", "json_object", "'text'"]
        .iter()
        .any(|w| text.contains(w))
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
        if api_key.is_some() && !base.tls && !base.is_loopback() {
            log::warn!(
                "the API key from ${} goes unencrypted to {}: use an https:// URL",
                params.api_key_env,
                base.origin()
            );
        }
        let tls = params.tls()?;
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .map_err(|e| RcoError::Backend(format!("cannot start the client runtime: {e}")))?;
        let mode = match params.structured_output {
            StructuredOutput::Auto => StructuredOutput::JsonSchema,
            m => m,
        };
        Ok(Self {
            path: format!("{prefix}{COMPLETIONS_PATH}"),
            url: base,
            tls,
            params,
            api_key,
            mode,
            refused: Vec::new(),
            confirmed: false,
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

    /// The structured output mode the next request uses (never `auto`: after a refusal, the
    /// mode the server is asked in next).
    pub fn mode(&self) -> StructuredOutput {
        self.mode
    }

    /// The JSON request body of `query` in the current mode ([`Self::mode`]).
    pub fn request_body(&self, query: &Query<'_>) -> Result<Value, BackendError> {
        self.request_body_in(query, self.mode)
    }

    /// The JSON request body of `query` in `mode` (`auto` is `json_schema`).
    pub fn request_body_in(
        &self,
        query: &Query<'_>,
        mode: StructuredOutput,
    ) -> Result<Value, BackendError> {
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
        // Outside json_schema the schema also bounds its free strings (see
        // `prompt::grammar_schema`), and the model reads it in the system prompt.
        let schema = match mode {
            StructuredOutput::Auto | StructuredOutput::JsonSchema => query.schema.clone(),
            StructuredOutput::JsonObject | StructuredOutput::Prompt => {
                super::prompt::grammar_schema(&query.schema)
            }
        };
        let system = match mode {
            StructuredOutput::Auto | StructuredOutput::JsonSchema => query.system.clone(),
            StructuredOutput::JsonObject | StructuredOutput::Prompt => {
                format!("{}\nThe JSON schema of the answer: {schema}", query.system)
            }
        };
        // Without images the user turn is a plain string: the form every chat template
        // reads (some text-only templates drop a list of parts).
        let user = if content.len() == 1 {
            Value::String(query.user.clone())
        } else {
            Value::Array(content)
        };
        let mut body = json!({
            "model": self.params.model,
            "messages": [
                {"role": "system", "content": system},
                {"role": "user", "content": user},
            ],
            "temperature": self.params.temperature,
            "max_tokens": self.params.max_tokens,
        });
        let format = match mode {
            StructuredOutput::Auto | StructuredOutput::JsonSchema => Some(json!({
                "type": "json_schema",
                "json_schema": {"name": query.schema_name, "strict": true, "schema": query.schema},
            })),
            StructuredOutput::JsonObject => Some(json!({"type": "json_object", "schema": schema})),
            StructuredOutput::Prompt => None,
        };
        if let (Some(f), Some(obj)) = (format, body.as_object_mut()) {
            obj.insert("response_format".into(), f);
        }
        Ok(body)
    }

    async fn post(&self, body: Vec<u8>) -> Result<(u16, Bytes), BackendError> {
        fogline_io::http::post_json(
            &self.url,
            &self.tls,
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
            _ => BackendError::Unavailable {
                url: self.params.base_url.trim().to_string(),
                reason: e.to_string(),
            },
        })
    }

    /// One request in `mode`, bounded by `deadline`: the status and the reply.
    fn exchange(
        &self,
        query: &Query<'_>,
        mode: StructuredOutput,
        deadline: Instant,
    ) -> Result<(u16, Bytes), BackendError> {
        let body = serde_json::to_vec(&self.request_body_in(query, mode)?)
            .map_err(|e| BackendError::Protocol(format!("cannot serialise the request: {e}")))?;
        let timeout = BackendError::Timeout {
            timeout_ms: self.params.timeout_ms,
        };
        let left = deadline
            .checked_duration_since(Instant::now())
            .filter(|d| !d.is_zero())
            .ok_or_else(|| timeout.clone())?;
        self.runtime
            .block_on(async { tokio::time::timeout(left, self.post(body)).await })
            .map_err(|_| timeout)?
    }

    /// Which structured output mode is in use, and why: what `fogline rco replay` prints.
    pub fn structured_output_note(&self) -> String {
        let mut s = self.mode.name().to_string();
        if !self.confirmed {
            s.push_str(" (no answer yet)");
        }
        if self.params.structured_output != StructuredOutput::Auto {
            s.push_str(" (set by the structured_output setting)");
        } else if !self.refused.is_empty() {
            let refused: Vec<&str> = self.refused.iter().map(|m| m.name()).collect();
            s.push_str(&format!(" (the server refused {})", refused.join(" and ")));
        }
        s
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
        let deadline = Instant::now() + Duration::from_millis(self.params.timeout_ms);
        loop {
            let (status, reply) = self.exchange(query, self.mode, deadline)?;
            if (200..300).contains(&status) {
                if !self.confirmed {
                    self.confirmed = true;
                    log::info!(
                        "{}: structured output by {}",
                        self.params.base_url.trim(),
                        self.structured_output_note()
                    );
                }
                return completion_content(&reply);
            }
            let next = match self.params.structured_output {
                StructuredOutput::Auto => self.mode.next(),
                _ => None,
            };
            match next {
                Some(next) if refuses_response_format(status, &reply) => {
                    log::info!(
                        "{}: the server refused response_format {} (HTTP {status}: {}); asking with {} from now on",
                        self.params.base_url.trim(),
                        self.mode.name(),
                        excerpt(&reply),
                        next.name()
                    );
                    self.refused.push(self.mode);
                    self.mode = next;
                    self.confirmed = false;
                }
                _ => {
                    return Err(BackendError::Status {
                        status,
                        body: excerpt(&reply),
                    });
                }
            }
        }
    }

    fn structured_output(&self) -> Option<String> {
        Some(self.structured_output_note())
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
        assert_eq!(b.url.authority, "127.0.0.1:8000");
        let b = OpenAiBackend::new(p("http://llm.local/proxy/")).unwrap();
        assert_eq!(b.path, "/proxy/v1/chat/completions");
        assert_eq!(b.url.authority, "llm.local:80");
        let b = OpenAiBackend::new(p("https://api.example.invalid")).unwrap();
        assert_eq!(
            (b.url.authority.as_str(), b.url.tls),
            ("api.example.invalid:443", true)
        );
        assert!(OpenAiBackend::new(p("ftp://api.example.invalid")).is_err());
        let bad_ca = OpenAiParams {
            ca_cert: Some("/nonexistent/ca.pem".into()),
            ..p("https://api.example.invalid")
        };
        let e = OpenAiBackend::new(bad_ca).unwrap_err().to_string();
        assert!(e.contains("/nonexistent/ca.pem"), "{e}");
    }

    #[test]
    fn refusals_of_the_response_format() {
        let llama_cpp_python = br#"{"error":{"message":"[{'type': 'literal_error', 'loc': ('body', 'response_format', 'type'), 'msg': "Input should be 'text' or 'json_object'"}]","type":"internal_server_error"}}"#;
        assert!(refuses_response_format(500, llama_cpp_python));
        assert!(refuses_response_format(
            400,
            b"{\"error\": \"json_schema is not supported\"}"
        ));
        assert!(refuses_response_format(
            422,
            b"unknown field response_format"
        ));
        // Other failures are not a refusal of the format.
        assert!(!refuses_response_format(
            500,
            b"{\"error\": \"overloaded\"}"
        ));
        assert!(!refuses_response_format(401, b"response_format"));
        assert!(!refuses_response_format(503, b"json_schema"));
        for m in StructuredOutput::ALL {
            assert_eq!(StructuredOutput::parse(m.name()), Some(m));
        }
        assert_eq!(StructuredOutput::parse("grammar"), None);
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
