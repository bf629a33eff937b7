//! The evaluation: the rules backend end to end, and an OpenAI-compatible mock server that
//! checks the request and answers well, badly and not at all.

use std::sync::atomic::{AtomicUsize, Ordering};

use base64::Engine as _;
use fogline_dataset::eval::{EvalParams, evaluate, markdown, read_eval, write_eval};
use fogline_dataset::observe::{assessment, observations};
use fogline_dataset::sample::{Manifest, read_samples};
use fogline_dataset::{DatasetError, Split};
use fogline_rco::backend::Backend;
use fogline_rco::{HazardState, OpenAiBackend, OpenAiParams, RulesBackend, Strategy};
use serde_json::{Value, json};

use crate::mock_server::{Seen, completion, mock};
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
    // The planning prompt follows every hazard inference, for the strategy it chose; a move
    // plan stops the car exactly when the front view shows an immediate hazard (rule P4).
    let manifest = Manifest::read(dir).unwrap();
    let samples = read_samples(dir).unwrap();
    for a in &e.answers {
        let chosen = a.answer_strategy.unwrap();
        let prompt = match chosen {
            Strategy::Move => "move_plan",
            Strategy::StopObserveMove => "stop_observe_move_plan",
        };
        assert_eq!(a.plan_prompt.as_deref(), Some(prompt), "{}", a.id);
        assert!(
            a.plan_invalid.is_none() && a.plan_latency_ms.is_some(),
            "{}",
            a.id
        );
        let s = samples.iter().find(|s| s.id == a.id).unwrap();
        let front = assessment(&observations(&manifest, s, None).unwrap()).front_immediate();
        let stops = chosen == Strategy::StopObserveMove || front;
        assert_eq!(
            a.plan_strategy,
            Some(if stops {
                Strategy::StopObserveMove
            } else {
                Strategy::Move
            }),
            "{}: {:?}",
            a.id,
            a.plan_summary
        );
        assert_eq!(a.plan_ok, a.plan_strategy == Some(a.strategy));
    }
    assert_eq!(e.overall.plan_invalid.hits, 0);
    assert_eq!(
        e.plan_latency.iter().map(|p| p.latency.calls).sum::<u64>(),
        32
    );
    assert_eq!(
        e.by_class.iter().map(|r| r.plan_strategy.hits).sum::<u64>(),
        e.overall.plan_strategy.hits
    );
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
    assert!(md.contains("| hazard_inference | 32 |"), "{md}");
}

/// A condition naming every view's state, as an answer writes it.
fn conditions(c: &fogline_rco::Condition) -> Value {
    let mut m = serde_json::Map::new();
    for (cam, state) in &c.views {
        m.insert(cam.short().into(), state.name().into());
    }
    Value::Object(m)
}

/// The opposite states.
fn flipped(c: &fogline_rco::Condition) -> Value {
    let mut m = serde_json::Map::new();
    for (cam, state) in &c.views {
        let other = match state {
            HazardState::ImmediateHazard => HazardState::NoImmediateHazard,
            HazardState::NoImmediateHazard => HazardState::ImmediateHazard,
        };
        m.insert(cam.short().into(), other.name().into());
    }
    Value::Object(m)
}

#[test]
fn openai_requests_carry_the_frames_in_order_and_bad_answers_are_counted() {
    let dir = small_set();
    let manifest = Manifest::read(dir).unwrap();
    let samples: Vec<_> = read_samples(dir)
        .unwrap()
        .into_iter()
        .filter(|s| s.split == Split::Test)
        .collect();
    assert_eq!(samples.len(), 8);
    // The states the verifier observes at each sample's last frame (what a plan must name).
    let observed: Vec<fogline_rco::Condition> = samples
        .iter()
        .map(|s| assessment(&observations(&manifest, s, None).unwrap()).observed())
        .collect();
    let hazard_calls = std::sync::Arc::new(AtomicUsize::new(0));
    let move_calls = std::sync::Arc::new(AtomicUsize::new(0));
    let (h, m) = (hazard_calls.clone(), move_calls.clone());
    // Hazard inference, per call: malformed JSON; an HTTP error; a good answer under
    // stop-observe-move; then good answers under move. Move plans, per call: right; its
    // first step's conditions wrong; malformed; a stop; an HTTP error.
    let mock = mock(move |schema, _| match schema {
        "hazard_inference" => {
            let k = h.fetch_add(1, Ordering::SeqCst);
            let strategy = if k == 2 { "stop-observe-move" } else { "move" };
            match k {
                0 => (200, completion("{\"hazards\": [oops"), 0),
                1 => (500, "{\"error\": \"boom\"}".into(), 0),
                _ => (
                    200,
                    completion(&format!(
                        r#"{{"hazards": [{{"camera": "front_wide", "object": "pedestrian", "motion": "crossing the road"}}], "strategy": "{strategy}", "rationale": "r"}}"#
                    )),
                    0,
                ),
            }
        }
        "stop_observe_move_plan" => (
            200,
            completion(
                r#"{"wait_steps": 5, "move_trigger": {"cross_left": "no_immediate_hazard", "front_wide": "no_immediate_hazard", "cross_right": "no_immediate_hazard"}, "rationale": "wait"}"#,
            ),
            0,
        ),
        "move_plan" => {
            let j = m.fetch_add(1, Ordering::SeqCst);
            let now = &observed[3 + j];
            let plan = |c: Value, behavior: &str, speed: &str| {
                completion(
                    &json!({"steps": [{"conditions": c, "behavior": behavior, "speed": speed}], "rationale": "p"})
                        .to_string(),
                )
            };
            match j {
                0 => (
                    200,
                    plan(conditions(now), "move_forward", "constant_speed"),
                    0,
                ),
                1 => (200, plan(flipped(now), "move_forward", "constant_speed"), 0),
                2 => (200, completion("{\"steps\": []}"), 0),
                3 => (200, plan(conditions(now), "stop", "quick_deceleration"), 0),
                _ => (503, "{}".into(), 0),
            }
        }
        _ => (400, "{}".into(), 0),
    });
    let url = format!("http://{}", mock.addr);
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
        limit: Some(8),
        jobs: 1,
    };
    let e = evaluate(dir, &params, "mock", &factory).unwrap();
    assert_eq!(e.samples, 8);
    assert_eq!(e.overall.invalid.hits, 2, "one malformed, one HTTP error");
    let a = &e.answers;
    assert!(a[0].invalid.as_deref().unwrap().starts_with("rejected"));
    assert!(a[1].invalid.as_deref().unwrap().starts_with("no answer"));
    for x in &a[..2] {
        // The controller falls back without planning: no planning call, no plan.
        assert_eq!(x.plan_prompt, None);
        assert_eq!(x.plan_latency_ms, None);
        assert_eq!(
            x.plan_invalid.as_deref(),
            Some("no hazard inference to plan from")
        );
    }
    assert!(a[2].invalid.is_none());
    assert_eq!(a[2].answer_object.as_deref(), Some("pedestrian"));
    // The planning prompt follows the strategy hazard inference chose.
    assert_eq!(a[2].plan_prompt.as_deref(), Some("stop_observe_move_plan"));
    assert_eq!(a[2].plan_strategy, Some(Strategy::StopObserveMove));
    assert!(
        a[2].plan_summary
            .as_deref()
            .unwrap()
            .starts_with("wait 5 ticks")
    );
    for x in &a[3..] {
        assert_eq!(x.plan_prompt.as_deref(), Some("move_plan"));
        assert!(x.plan_latency_ms.is_some());
    }
    assert_eq!(a[3].plan_strategy, Some(Strategy::Move));
    assert_eq!(
        a[3].plan_summary.as_deref(),
        Some("1 step: move_forward/constant_speed")
    );
    assert!(
        a[4].plan_invalid
            .as_deref()
            .unwrap()
            .starts_with("refused by the verifier at its first step"),
        "{:?}",
        a[4].plan_invalid
    );
    assert!(
        a[5].plan_invalid
            .as_deref()
            .unwrap()
            .starts_with("rejected")
    );
    assert_eq!(
        a[6].plan_strategy,
        Some(Strategy::StopObserveMove),
        "a stop"
    );
    assert!(
        a[7].plan_invalid
            .as_deref()
            .unwrap()
            .starts_with("no answer")
    );
    for (x, s) in a.iter().zip(&samples) {
        assert_eq!(x.plan_ok, x.plan_strategy == Some(s.strategy), "{}", x.id);
    }
    assert_eq!(e.overall.plan_invalid.hits, 5);
    assert_eq!(e.overall.plan_invalid.n, 8);
    // Latency per prompt: 8 hazard inference calls, 5 move plans, 1 stop-observe-move plan.
    assert_eq!(e.latency.calls, 8);
    let calls: Vec<(&str, u64)> = e
        .plan_latency
        .iter()
        .map(|p| (p.prompt.as_str(), p.latency.calls))
        .collect();
    assert_eq!(calls, [("move_plan", 5), ("stop_observe_move_plan", 1)]);
    let md = markdown(&e);
    assert!(md.contains("| move_plan | 5 |"), "{md}");
    assert!(md.contains("## Planning prompt"), "{md}");
    // The requests, in order: the controller's schemas, frames as PNG data URLs in order —
    // 15 for hazard inference (three views × five frames), the last frame's three views for
    // planning, which is told the hazard inferred.
    let seen = mock.seen.lock().unwrap();
    assert_eq!(seen.len(), 8 + 6);
    let mut requests = seen.iter();
    for (i, sample) in samples.iter().enumerate() {
        let hazard = requests.next().unwrap();
        let mut expected: Vec<&str> = sample
            .frames
            .iter()
            .flat_map(|f| f.views.iter().map(|v| v.image.as_str()))
            .collect();
        check_request(dir, hazard, "hazard_inference", &expected);
        let schema = &hazard.body["response_format"]["json_schema"]["schema"];
        assert!(schema["properties"]["hazards"].is_object());
        assert_eq!(
            schema["properties"]["strategy"]["enum"][1],
            "stop-observe-move"
        );
        if i < 2 {
            continue;
        }
        let plan = requests.next().unwrap();
        expected.drain(..expected.len() - 3);
        let name = if i == 2 {
            "stop_observe_move_plan"
        } else {
            "move_plan"
        };
        check_request(dir, plan, name, &expected);
        let text = plan.body["messages"][1]["content"][0]["text"]
            .as_str()
            .unwrap();
        assert!(
            text.contains("a pedestrian (front_wide), which is crossing the road"),
            "{text}"
        );
    }
    assert!(requests.next().is_none());
}

/// A request has the schema `name` and carries `images` (paths in the data set), in order,
/// as PNG data URLs of exactly their pixels.
fn check_request(dir: &std::path::Path, req: &Seen, name: &str, images: &[&str]) {
    let b = &req.body;
    assert_eq!(b["response_format"]["type"], "json_schema");
    assert_eq!(b["response_format"]["json_schema"]["name"], name);
    let content = b["messages"][1]["content"].as_array().unwrap();
    let urls: Vec<&str> = content
        .iter()
        .filter(|c| c["type"] == "image_url")
        .map(|c| c["image_url"]["url"].as_str().unwrap())
        .collect();
    assert_eq!(urls.len(), images.len(), "{name}");
    for (u, path) in urls.iter().zip(images) {
        let b64 = u.strip_prefix("data:image/png;base64,").unwrap();
        let png = base64::engine::general_purpose::STANDARD
            .decode(b64)
            .unwrap();
        let sent = fogline_io::decode_rgb(&png).unwrap();
        let file = fogline_io::decode_rgb(&std::fs::read(dir.join(path)).unwrap()).unwrap();
        assert_eq!(
            sent, file,
            "{name} {path}: the frame sent is the file, in order"
        );
    }
    let text: &Value = &content[0];
    assert!(text["text"].as_str().unwrap().contains("front_wide"));
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
    assert_eq!(e.overall.plan_invalid.hits, 2);
    assert!(e.plan_latency.iter().all(|p| p.latency.calls == 0));
}
