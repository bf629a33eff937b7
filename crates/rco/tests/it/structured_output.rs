//! Structured output negotiation (issue 22, item 3) against mock servers on 127.0.0.1 that
//! refuse what llama-cpp-python, or a stricter server, refuses: `json_schema` first, then
//! `json_object` with the schema, then the schema in the prompt; the mode taken is kept
//! (no failing round trip twice), said by the backend and by `rco replay`, and every
//! answer is validated the same way.

use std::net::SocketAddr;

use fogline_rco::backend::openai::refuses_response_format;
use fogline_rco::{
    FallbackKind, OpenAiBackend, OpenAiParams, Rco, RcoParams, Source, StructuredOutput, replay,
};
use serde_json::Value;

use crate::mock_server::{Reply, completion, mock, request_schema};
use crate::{GOOD_SC, N, clean, hazard_answer, plan_answer};

/// What llama-cpp-python's server answers to `response_format: {type: "json_schema"}`.
const LLAMA_CPP_PYTHON_500: &str = r#"{"error":{"message":"[{'type': 'literal_error', 'loc': ('body', 'response_format', 'type'), 'msg': \"Input should be 'text' or 'json_object'\", 'input': 'json_schema', 'ctx': {'expected': \"'text' or 'json_object'\"}}]","type":"internal_server_error","param":null,"code":null}}"#;

fn good(name: &str) -> String {
    match name {
        "safety_constraints" => GOOD_SC.to_string(),
        "hazard_inference" => hazard_answer("move"),
        "move_plan" => plan_answer(2, [N, N, N], "move_forward", "constant_speed"),
        other => panic!("unexpected task {other:?}"),
    }
}

/// An RCO on an OpenAI-compatible backend at `addr`, in structured output `mode`.
fn rco_at(addr: SocketAddr, mode: StructuredOutput) -> Rco {
    let backend = OpenAiBackend::new(OpenAiParams {
        base_url: format!("http://{addr}"),
        model: "m".into(),
        api_key_env: String::new(),
        timeout_ms: 5_000,
        structured_output: mode,
        ..OpenAiParams::default()
    })
    .unwrap();
    Rco::new(RcoParams::default(), Box::new(backend)).unwrap()
}

/// A good answer to `name`, once the request's system prompt carries the answer's schema.
fn good_with_the_schema_in_the_prompt(name: &str, body: &Value) -> Reply {
    let system = body["messages"][0]["content"].as_str().unwrap();
    assert!(
        system.contains("The JSON schema of the answer: {"),
        "{system}"
    );
    (200, completion(&good(name)), 0)
}

/// The request's `response_format.type`, or `none`.
fn format_type(body: &Value) -> String {
    body["response_format"]["type"]
        .as_str()
        .unwrap_or("none")
        .to_string()
}

#[test]
fn a_server_that_refuses_json_schema_gets_json_object_with_the_schema_from_then_on() {
    let m = mock(|name, body| match format_type(body).as_str() {
        "json_schema" => (500, LLAMA_CPP_PYTHON_500.into(), 0),
        "json_object" => {
            // The schema travels in response_format (for the server's grammar) and in the
            // system prompt (for the model).
            let props = &body["response_format"]["schema"]["properties"];
            assert!(props.is_object());
            // Free text is bounded for the server's grammar.
            if props["rationale"].is_object() {
                assert_eq!(
                    props["rationale"]["pattern"],
                    fogline_rco::backend::prompt::TEXT_PATTERN
                );
            }
            good_with_the_schema_in_the_prompt(name, body)
        }
        other => panic!("unexpected response_format {other}"),
    });
    let mut rco = rco_at(m.addr, StructuredOutput::Auto);
    assert_eq!(
        rco.structured_output().unwrap(),
        "json_schema (no answer yet)"
    );
    let obs: Vec<_> = (0..4).map(clean).collect();
    let mut out = Vec::new();
    let replayed = replay::run(&mut rco, &obs, false, &mut out).unwrap();
    assert_eq!(replayed.fallbacks, 0);
    let seen = m.seen.lock().unwrap().clone();
    let types: Vec<String> = seen.iter().map(|s| format_type(&s.body)).collect();
    // One refused json_schema request, at the very first call; json_object ever after.
    assert_eq!(types[0], "json_schema");
    assert!(types[1..].iter().all(|t| t == "json_object"), "{types:?}");
    assert!(types.len() >= 4, "{types:?}");
    // The retry asked the same question.
    assert_eq!(request_schema(&seen[0].body), request_schema(&seen[1].body));
    let text = String::from_utf8(out).unwrap();
    assert!(
        text.contains("structured output: json_object (the server refused json_schema)"),
        "{text}"
    );
}

#[test]
fn a_server_that_refuses_both_formats_gets_the_schema_in_the_prompt() {
    let m = mock(|name, body| match format_type(body).as_str() {
        "json_schema" => (
            400,
            r#"{"error": "unsupported parameter: response_format.json_schema"}"#.into(),
            0,
        ),
        "json_object" => (
            422,
            r#"{"detail": "response_format: json_object is not supported"}"#.into(),
            0,
        ),
        "none" => good_with_the_schema_in_the_prompt(name, body),
        other => panic!("unexpected response_format {other}"),
    });
    let mut rco = rco_at(m.addr, StructuredOutput::Auto);
    for t in 0..3 {
        let d = rco.step(&clean(t));
        assert!(d.fallback.is_none(), "{:?}", d.fallback);
        assert_eq!(d.source, Source::Plan);
    }
    let types: Vec<String> = m
        .seen
        .lock()
        .unwrap()
        .iter()
        .map(|s| format_type(&s.body))
        .collect();
    assert_eq!(&types[..3], ["json_schema", "json_object", "none"]);
    assert!(types[3..].iter().all(|t| t == "none"), "{types:?}");
    assert_eq!(
        rco.structured_output().unwrap(),
        "prompt (the server refused json_schema and json_object)"
    );
}

#[test]
fn other_errors_do_not_change_the_mode_and_a_set_mode_is_never_renegotiated() {
    // An overloaded server: the call fails, the mode stays json_schema.
    let m = mock(|_, _| (500, r#"{"error": {"message": "overloaded"}}"#.into(), 0));
    let mut rco = rco_at(m.addr, StructuredOutput::Auto);
    let d = rco.step(&clean(0));
    assert_eq!(d.fallback.as_ref().unwrap().kind, FallbackKind::Backend);
    assert_eq!(m.seen.lock().unwrap().len(), 1, "no renegotiation");
    assert!(rco.structured_output().unwrap().starts_with("json_schema"));

    // json_object set by the user: never json_schema, and the refusal of a set mode is an
    // error, not a renegotiation.
    let m = mock(|name, body| match format_type(body).as_str() {
        "json_object" => (200, completion(&good(name)), 0),
        _ => (500, LLAMA_CPP_PYTHON_500.into(), 0),
    });
    let mut rco = rco_at(m.addr, StructuredOutput::JsonObject);
    assert!(rco.step(&clean(0)).fallback.is_none());
    assert!(
        m.seen
            .lock()
            .unwrap()
            .iter()
            .all(|s| format_type(&s.body) == "json_object")
    );
    assert_eq!(
        rco.structured_output().unwrap(),
        "json_object (set by the structured_output setting)"
    );
    let m = mock(|_, _| (500, LLAMA_CPP_PYTHON_500.into(), 0));
    let mut rco = rco_at(m.addr, StructuredOutput::JsonSchema);
    let d = rco.step(&clean(0));
    let f = d.fallback.unwrap();
    assert_eq!(f.kind, FallbackKind::Backend);
    assert!(f.message.contains("HTTP status 500"), "{}", f.message);
    assert_eq!(m.seen.lock().unwrap().len(), 1);
}

#[test]
fn answers_in_every_mode_are_validated_the_same_way() {
    // The same invalid plan (an unknown behaviour) is refused whatever the mode.
    for mode in [
        StructuredOutput::JsonSchema,
        StructuredOutput::JsonObject,
        StructuredOutput::Prompt,
    ] {
        let m = mock(|name, _| {
            let text = if name == "move_plan" {
                plan_answer(1, [N, N, N], "fly", "constant_speed")
            } else {
                good(name)
            };
            (200, completion(&text), 0)
        });
        let mut rco = rco_at(m.addr, mode);
        let d = rco.step(&clean(0));
        let f = d.fallback.unwrap_or_else(|| panic!("{mode:?}: accepted"));
        assert_eq!(f.kind, FallbackKind::Answer, "{mode:?}");
        assert!(f.message.contains("fly"), "{mode:?}: {}", f.message);
    }
    assert!(refuses_response_format(
        500,
        LLAMA_CPP_PYTHON_500.as_bytes()
    ));
}
