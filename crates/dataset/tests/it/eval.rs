//! The evaluation: the rules backend end to end, and an OpenAI-compatible mock server that
//! checks the request and answers well, badly and not at all.

use std::sync::atomic::{AtomicUsize, Ordering};

use base64::Engine as _;
use fogline_dataset::eval::{EvalParams, evaluate, read_eval, write_eval};
use fogline_dataset::sample::read_samples;
use fogline_dataset::{DatasetError, Split};
use fogline_rco::backend::Backend;
use fogline_rco::{OpenAiBackend, OpenAiParams, RulesBackend};
use serde_json::Value;

use crate::mock_server::{completion, mock};
use crate::small_set;

#[test]
fn the_rules_backend_is_scored_per_class_and_label() {
    let dir = small_set();
    let params = EvalParams {
        split: None,
        limit: None,
        jobs: 2,
    };
    let factory = || Ok(Box::new(RulesBackend::default()) as Box<dyn Backend>);
    let e = evaluate(dir, &params, "rules", &factory).unwrap();
    assert_eq!(e.samples, 32);
    assert_eq!(e.answers.len(), 32);
    assert_eq!(e.by_class.iter().map(|r| r.samples).sum::<u64>(), 32);
    assert_eq!(e.by_motion.iter().map(|r| r.samples).sum::<u64>(), 32);
    assert_eq!(
        e.overall.invalid.hits, 0,
        "the rules backend always answers validly"
    );
    let m = &e.by_strategy[0];
    assert_eq!(m.group, "move");
    assert_eq!(m.move_recall.n, m.samples);
    for r in e.by_class.iter().chain([&e.overall]) {
        let o = r.object;
        assert!(o.ci_low.unwrap() <= o.value.unwrap() && o.value.unwrap() <= o.ci_high.unwrap());
    }
    // The same answers with one worker (deterministic backend, order kept).
    let one = evaluate(
        dir,
        &EvalParams {
            jobs: 1,
            ..params.clone()
        },
        "rules",
        &factory,
    )
    .unwrap();
    let strip = |e: &fogline_rco::deficit_eval::DeficitEval| {
        e.answers
            .iter()
            .map(|a| (a.id.clone(), a.answer_object.clone(), a.answer_strategy))
            .collect::<Vec<_>>()
    };
    assert_eq!(strip(&e), strip(&one));
    // Written and read back through the one typed definition.
    let out = tempfile::tempdir().unwrap();
    let files = write_eval(&e, out.path()).unwrap();
    assert_eq!(read_eval(&files[0]).unwrap(), e);
    let md = std::fs::read_to_string(&files[1]).unwrap();
    assert!(
        md.contains("| traffic_light |") && md.contains("Latency per call"),
        "{md}"
    );
}

#[test]
fn openai_requests_carry_the_frames_in_order_and_bad_answers_are_counted() {
    let dir = small_set();
    let calls = std::sync::Arc::new(AtomicUsize::new(0));
    let n = calls.clone();
    // Every third call: malformed JSON; every third + 1: an HTTP error; else a good answer.
    let m = mock(move |_, _| {
        let k = n.fetch_add(1, Ordering::SeqCst);
        match k % 3 {
            0 => (200, completion("{\"hazards\": [oops"), 0),
            1 => (500, "{\"error\": \"boom\"}".into(), 0),
            _ => (
                200,
                completion(
                    r#"{"hazards": [{"camera": "front_wide", "object": "pedestrian", "motion": "crossing the road"}], "strategy": "stop-observe-move", "rationale": "r"}"#,
                ),
                0,
            ),
        }
    });
    let url = format!("http://{}", m.addr);
    let factory = || -> Result<Box<dyn Backend>, DatasetError> {
        let p = OpenAiParams {
            base_url: url.clone(),
            api_key_env: String::new(),
            timeout_ms: 5_000,
            ..OpenAiParams::default()
        };
        Ok(Box::new(
            OpenAiBackend::new(p).map_err(|e| DatasetError::Backend(e.to_string()))?,
        ))
    };
    let params = EvalParams {
        split: Some(Split::Test),
        limit: Some(6),
        jobs: 1,
    };
    let e = evaluate(dir, &params, "mock", &factory).unwrap();
    assert_eq!(e.samples, 6);
    assert_eq!(e.overall.invalid.hits, 4, "two malformed, two HTTP errors");
    assert!(
        e.answers[0]
            .invalid
            .as_deref()
            .unwrap()
            .starts_with("rejected")
    );
    assert!(
        e.answers[1]
            .invalid
            .as_deref()
            .unwrap()
            .starts_with("no answer")
    );
    assert!(e.answers[2].invalid.is_none());
    assert_eq!(e.answers[2].answer_object.as_deref(), Some("pedestrian"));
    // The requests: the controller's schema, 15 frames as PNG data URLs in sample order.
    let seen = m.seen.lock().unwrap();
    assert_eq!(seen.len(), 6);
    let samples: Vec<_> = read_samples(dir)
        .unwrap()
        .into_iter()
        .filter(|s| s.split == Split::Test)
        .collect();
    for (req, sample) in seen.iter().zip(&samples) {
        let b = &req.body;
        assert_eq!(b["response_format"]["type"], "json_schema");
        assert_eq!(
            b["response_format"]["json_schema"]["name"],
            "hazard_inference"
        );
        let schema = &b["response_format"]["json_schema"]["schema"];
        assert!(schema["properties"]["hazards"].is_object());
        assert_eq!(
            schema["properties"]["strategy"]["enum"][1],
            "stop-observe-move"
        );
        let content = b["messages"][1]["content"].as_array().unwrap();
        let urls: Vec<&str> = content
            .iter()
            .filter(|c| c["type"] == "image_url")
            .map(|c| c["image_url"]["url"].as_str().unwrap())
            .collect();
        assert_eq!(urls.len(), 15);
        let expected: Vec<&str> = sample
            .frames
            .iter()
            .flat_map(|f| f.views.iter().map(|v| v.image.as_str()))
            .collect();
        for (u, path) in urls.iter().zip(&expected) {
            let b64 = u.strip_prefix("data:image/png;base64,").unwrap();
            let png = base64::engine::general_purpose::STANDARD
                .decode(b64)
                .unwrap();
            let sent = fogline_io::decode_rgb(&png).unwrap();
            let file = fogline_io::decode_rgb(&std::fs::read(dir.join(path)).unwrap()).unwrap();
            assert_eq!(sent, file, "{path}: the frame sent is the file, in order");
        }
        let text: &Value = &content[0];
        assert!(text["text"].as_str().unwrap().contains("front_wide"));
    }
}

#[test]
fn an_unreachable_server_is_counted_not_fatal() {
    let dir = small_set();
    let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let url = format!("http://{}", l.local_addr().unwrap());
    drop(l);
    let factory = || -> Result<Box<dyn Backend>, DatasetError> {
        let p = OpenAiParams {
            base_url: url.clone(),
            api_key_env: String::new(),
            timeout_ms: 2_000,
            ..OpenAiParams::default()
        };
        Ok(Box::new(
            OpenAiBackend::new(p).map_err(|e| DatasetError::Backend(e.to_string()))?,
        ))
    };
    let params = EvalParams {
        split: Some(Split::Val),
        limit: Some(2),
        jobs: 1,
    };
    let e = evaluate(dir, &params, "down", &factory).unwrap();
    assert_eq!(e.overall.invalid.hits, 2);
    assert_eq!(e.overall.strategy.hits, 0);
}
