//! Fault injection on loopback: misbehaving planners behind both protocols. The campaign
//! completes and every failure is recorded with its kind and reason.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::sync::Arc;
use std::time::Duration;

use fogline_campaign::runner::Silent;
use fogline_campaign::store::Outcome;
use fogline_campaign::{Campaign, CampaignConfig, Shard, Store, planner_for, run, run_options};
use fogline_remote::{FailureKind, PlanFailure, PlanRequest, Planner};
use fogline_types::clip::{PlannerOutput, Trajectory};

const CLIPS: usize = 7;

fn config(kind: &str, endpoint: &str) -> CampaignConfig {
    CampaignConfig::from_toml(&format!(
        "[clips]\ncount = {CLIPS}\nseed = 11\nwidth = 160\nheight = 96\n\
         [conditions]\nnames = [\"noise_30\"]\n\
         [planner]\nkind = \"{kind}\"\nendpoint = \"{endpoint}\"\n\
         [run]\nconcurrency = 4\ntimeout_s = 0.5\nretries = 1\nbackoff_ms = 10\n"
    ))
    .unwrap()
}

/// Runs the campaign and returns, per clip index, the (kind, attempts) of its runs.
fn outcomes(cfg: &CampaignConfig) -> Vec<Vec<(String, u32, String)>> {
    let dir = tempfile::tempdir().unwrap();
    let campaign = Campaign::new(cfg.clone()).unwrap();
    let planner = planner_for(cfg).unwrap();
    let mut store = Store::create(
        &dir.path().join("s.sqlite"),
        &campaign.store_meta(Shard::ALL),
    )
    .unwrap();
    let s = run(
        &campaign,
        &mut store,
        planner.as_ref(),
        &run_options(cfg, Shard::ALL),
        &Silent,
    )
    .unwrap();
    assert_eq!(s.ran, CLIPS * 2, "every run is recorded");
    let runs = store.runs().unwrap();
    (0..CLIPS)
        .map(|i| {
            runs.iter()
                .filter(|r| r.clip_index as usize == i)
                .map(|r| match &r.outcome {
                    Outcome::Ok { .. } => ("ok".to_string(), r.attempts, String::new()),
                    Outcome::Failed { kind, reason } => (kind.clone(), r.attempts, reason.clone()),
                })
                .collect()
        })
        .collect()
}

fn clip_of(scene_id: &str) -> usize {
    scene_id.rsplit('_').next().unwrap().parse().unwrap()
}

fn straight(n: usize, v: f64) -> Vec<[f64; 2]> {
    (1..=n).map(|i| [v * i as f64, 0.0]).collect()
}

/// A hand-written HTTP server on 127.0.0.1 that misbehaves by clip index.
fn misbehaving_http() -> String {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap();
    std::thread::spawn(move || {
        for stream in listener.incoming() {
            let Ok(stream) = stream else { continue };
            std::thread::spawn(move || serve_one(stream));
        }
    });
    format!("http://{addr}")
}

fn serve_one(mut stream: TcpStream) {
    let mut reader = BufReader::new(stream.try_clone().unwrap());
    let mut len = 0usize;
    loop {
        let mut line = String::new();
        if reader.read_line(&mut line).unwrap_or(0) == 0 {
            return;
        }
        let l = line.trim_end().to_ascii_lowercase();
        if l.is_empty() {
            break;
        }
        if let Some(v) = l.strip_prefix("content-length:") {
            len = v.trim().parse().unwrap_or(0);
        }
    }
    let mut body = vec![0; len];
    if reader.read_exact(&mut body).is_err() {
        return;
    }
    let v: serde_json::Value = serde_json::from_slice(&body).unwrap_or_default();
    let clip = clip_of(v["scene_id"].as_str().unwrap_or("x_0"));
    let respond = |stream: &mut TcpStream, status: &str, body: &str| {
        let _ = write!(
            stream,
            "HTTP/1.1 {status}\r\ncontent-type: application/json\r\ncontent-length: {}\r\nconnection: close\r\n\r\n{body}",
            body.len()
        );
    };
    let ok = |n: usize| {
        serde_json::json!({"trajectory": straight(n, 0.5), "explanation": "Keep lane.", "decision": null})
            .to_string()
    };
    match clip {
        0 => respond(&mut stream, "200 OK", &ok(64)),
        1 => {
            std::thread::sleep(Duration::from_millis(1500));
            respond(&mut stream, "200 OK", &ok(64));
        }
        2 => respond(
            &mut stream,
            "500 Internal Server Error",
            r#"{"error":"planner crashed"}"#,
        ),
        3 => respond(&mut stream, "200 OK", &ok(63)),
        4 => respond(&mut stream, "200 OK", &ok(64).replacen("0.5", "NaN", 1)),
        5 => {
            let _ = stream.write_all(b"\x00\x17garbage\xff\xfe not http at all\r\n\r\n");
        }
        _ => {} // 6: drop the connection without a word
    }
    let _ = stream.flush();
}

#[test]
fn an_http_planner_that_misbehaves_every_way_is_recorded_run_by_run() {
    let url = misbehaving_http();
    let o = outcomes(&config("http", &url));
    let kinds = |i: usize| {
        o[i].iter()
            .map(|(k, a, _)| (k.as_str(), *a))
            .collect::<Vec<_>>()
    };
    assert_eq!(kinds(0), vec![("ok", 1); 2]);
    assert_eq!(kinds(1), vec![("timeout", 2); 2], "timed out, retried once");
    assert_eq!(kinds(2), vec![("remote_error", 2); 2]);
    assert_eq!(kinds(3), vec![("invalid_answer", 1); 2], "63 waypoints");
    assert_eq!(kinds(4), vec![("invalid_answer", 1); 2], "NaN is not JSON");
    for (k, _, reason) in &o[5] {
        assert!(
            k == "invalid_answer" || k == "unavailable",
            "garbage: {k}: {reason}"
        );
    }
    assert_eq!(kinds(6), vec![("unavailable", 2); 2], "dropped connection");
    assert!(o[2][0].2.contains("planner crashed"), "{}", o[2][0].2);
    assert!(o[3][0].2.contains("63"), "{}", o[3][0].2);
    for runs in &o {
        for (k, _, reason) in runs {
            assert!(
                k == "ok" || !reason.is_empty(),
                "a failure without a reason: {k}"
            );
        }
    }
}

/// A planner served over egodriver that misbehaves by clip index.
struct Misbehaving;

impl Planner for Misbehaving {
    fn describe(&self) -> String {
        "misbehaving".into()
    }
    fn plan(&self, r: &PlanRequest<'_>) -> Result<PlannerOutput, PlanFailure> {
        let out = |xy: Vec<[f64; 2]>| PlannerOutput {
            trajectory: Trajectory { xy },
            explanation: "Keep lane.".into(),
            decision: None,
        };
        match clip_of(r.scene_id) {
            0 => Ok(out(straight(64, 0.5))),
            1 => {
                std::thread::sleep(Duration::from_millis(1500));
                Ok(out(straight(64, 0.5)))
            }
            2 => Err(PlanFailure::new(FailureKind::Remote, "planner crashed")),
            3 => Ok(out(straight(10, 0.5))),
            4 => Ok(out(straight(64, f64::NAN))),
            _ => Ok(out(straight(64, 0.4))),
        }
    }
}

#[test]
fn an_egodriver_planner_that_misbehaves_is_recorded_and_a_dead_endpoint_too() {
    // A planner that hangs holds its plan slot until it returns: room for all of them, so
    // the well-behaved clips are not queued behind the hung ones (what this test is about is
    // how the client records each misbehaviour).
    let server = fogline_remote::egodriver::serve(
        "127.0.0.1:0".parse().unwrap(),
        Arc::new(Misbehaving),
        fogline_remote::egodriver::ServeOptions {
            limits: fogline_remote::Limits {
                max_concurrent_requests: 16,
                ..Default::default()
            },
            ..Default::default()
        },
    )
    .unwrap();
    let o = outcomes(&config("egodriver", &server.local_addr().to_string()));
    let kinds = |i: usize| {
        o[i].iter()
            .map(|(k, a, _)| (k.as_str(), *a))
            .collect::<Vec<_>>()
    };
    assert_eq!(kinds(0), vec![("ok", 1); 2]);
    assert_eq!(kinds(1), vec![("timeout", 2); 2]);
    assert_eq!(kinds(2), vec![("remote_error", 2); 2]);
    assert!(o[2][0].2.contains("planner crashed"), "{}", o[2][0].2);
    for i in [3, 4] {
        for (k, _, reason) in &o[i] {
            assert!(
                k == "invalid_answer" || k == "remote_error",
                "clip {i}: {k}: {reason}"
            );
            assert!(!reason.is_empty());
        }
    }
    assert_eq!(kinds(5), vec![("ok", 1); 2]);
    server.shutdown().unwrap();

    // A listener that drops every connection: every run fails as unavailable, after a retry.
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap();
    std::thread::spawn(move || {
        for s in listener.incoming() {
            drop(s);
        }
    });
    let o = outcomes(&config("egodriver", &addr.to_string()));
    for runs in &o {
        for (k, a, reason) in runs {
            assert_eq!((k.as_str(), *a), ("unavailable", 2), "{reason}");
        }
    }
}
