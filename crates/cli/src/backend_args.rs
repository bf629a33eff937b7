//! The override's backend as `fogline rco replay`, `fogline rco eval` and `fogline sim run`
//! take it (a private CA of an https:// URL: the global `--ca-cert`).

use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use fogline_rco::{OpenAiParams, StructuredOutput};

/// Who answers the RCO controller's queries.
#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum BackendArg {
    /// Offline, deterministic commonsense rules.
    Rules,
    /// An OpenAI-compatible /v1/chat/completions server.
    Openai,
    /// Red team: the most dangerous well-formed answers (no hazards, quick acceleration, the
    /// loosest constraints), to show what the hard limits and the shield hold.
    Hostile,
    /// Red team, asking also for a deceleration limit that would weaken braking.
    HostileWeakBrakes,
}

/// The `openai` backend's flags.
#[derive(Args)]
pub struct OpenAiArgs {
    /// openai: the server's base URL, http:// or https://.
    #[arg(long, default_value = "http://127.0.0.1:8000")]
    url: String,
    /// openai: the model name.
    #[arg(long, default_value = "Qwen/Qwen2-VL-2B-Instruct")]
    model: String,
    /// openai: the environment variable holding the API key (never printed).
    #[arg(long, default_value = "OPENAI_API_KEY")]
    api_key_env: String,
    /// openai: the time limit of one call, ms.
    #[arg(long, default_value_t = 20_000)]
    timeout_ms: u64,
    /// openai: how the answer's JSON schema reaches the server: auto (negotiated),
    /// json_schema, json_object or prompt.
    #[arg(long, default_value = "auto", value_parser = |s: &str| StructuredOutput::parse(s).ok_or("expected auto, json_schema, json_object or prompt"))]
    structured_output: StructuredOutput,
}

impl OpenAiArgs {
    /// The backend's settings, the URL checked now (an error names `--url`).
    pub fn params(&self) -> Result<OpenAiParams> {
        let p = OpenAiParams {
            base_url: self.url.clone(),
            model: self.model.clone(),
            api_key_env: self.api_key_env.clone(),
            timeout_ms: self.timeout_ms,
            structured_output: self.structured_output,
            ..OpenAiParams::default()
        };
        p.parsed_url()
            .with_context(|| format!("--backend openai --url {}", self.url))?;
        Ok(p)
    }
}
