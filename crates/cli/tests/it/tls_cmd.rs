//! `--ca-cert` on the command line (issue 22, item 2): `fogline rco replay --backend openai`
//! against a mock OpenAI-compatible server behind TLS on 127.0.0.1, its certificate signed
//! by a CA made in the test: trusted with `--ca-cert`, refused without it (exit 1, every
//! tick's fallback naming the URL and the unknown issuer); a missing or broken file is an
//! error that names the flag.

use crate::mock_server::{completion, mock};
use crate::tls_support::{Cert, pki, tls_front};
use crate::{fogline, text};

const GOOD_SC: &str = r#"{"max_speed_kmh": 40, "min_following_distance_s": 3, "max_acceleration_mps2": 1.5, "max_deceleration_mps2": 3.0, "max_yaw_rate_dps": 10, "min_braking_distance_m": 25}"#;

fn good(name: &str) -> String {
    let n = "no_immediate_hazard";
    match name {
        "safety_constraints" => GOOD_SC.to_string(),
        "hazard_inference" => {
            r#"{"hazards": [], "strategy": "move", "rationale": "clear"}"#.to_string()
        }
        "stop_observe_move_plan" => format!(
            r#"{{"wait_steps": 2, "move_trigger": {{"cross_left": "{n}", "front_wide": "{n}", "cross_right": "{n}"}}, "rationale": "wait"}}"#
        ),
        _ => format!(
            r#"{{"steps": [{{"conditions": {{"cross_left": "{n}", "front_wide": "{n}", "cross_right": "{n}"}}, "behavior": "move_forward", "speed": "constant_speed"}}], "rationale": "go"}}"#
        ),
    }
}

#[test]
fn rco_replay_over_https_trusts_the_ca_cert_and_refuses_without_it() {
    let pki = pki();
    let m = mock(|name, _| (200, completion(&good(name)), 0));
    let front = tls_front(m.addr, pki.server(Cert::Good, &[b"http/1.1"]));
    let url = format!("https://127.0.0.1:{}", front.port());
    let data = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../rco/tests/data/observations.jsonl"
    );
    let dir = tempfile::tempdir().unwrap();
    let obs = dir.path().join("obs.jsonl");
    let first: Vec<String> = std::fs::read_to_string(data)
        .unwrap()
        .lines()
        .take(3)
        .map(str::to_string)
        .collect();
    std::fs::write(&obs, first.join("\n")).unwrap();
    let obs = obs.to_str().unwrap();
    let ca = pki.ca_pem.to_str().unwrap();
    let base = [
        "rco",
        "replay",
        obs,
        "--backend",
        "openai",
        "--url",
        &url,
        "--model",
        "m",
        "--api-key-env",
        "",
    ];

    let with: Vec<&str> = base.iter().copied().chain(["--ca-cert", ca]).collect();
    let o = fogline(&with);
    assert!(o.status.success(), "{}", text(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("0 fallbacks"), "{out}");
    assert!(
        out.contains("structured output: json_schema"),
        "the mode is said: {out}"
    );
    let served = m.seen.lock().unwrap().len();
    assert!(served >= 2, "{served} requests");

    let o = fogline(&base);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        out.contains(&format!("cannot reach {url}"))
            && out.contains("unknown issuer")
            && out.contains("--ca-cert FILE"),
        "{out}"
    );
    assert_eq!(
        m.seen.lock().unwrap().len(),
        served,
        "nothing reached the server"
    );

    // A file that is not there, or not PEM: refused before any call, the flag named.
    let missing = dir.path().join("missing.pem");
    let bad: Vec<&str> = base
        .iter()
        .copied()
        .chain(["--ca-cert", missing.to_str().unwrap()])
        .collect();
    let o = fogline(&bad);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("--ca-cert") && err.contains("missing.pem"),
        "{err}"
    );
    let not_pem: Vec<&str> = base.iter().copied().chain(["--ca-cert", obs]).collect();
    let o = fogline(&not_pem);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("--ca-cert") && err.contains("PEM"), "{err}");
}

#[test]
fn a_campaign_reaches_an_https_planner_with_the_ca_cert_and_not_without() {
    let pki = pki();
    let server = fogline_remote::http::serve(
        "127.0.0.1:0".parse().unwrap(),
        std::sync::Arc::new(fogline_campaign::BuiltinPlanner::new()),
        fogline_remote::http::ServeOptions::default(),
    )
    .unwrap();
    let front = tls_front(server.local_addr(), pki.server(Cert::Good, &[b"http/1.1"]));
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("tls.toml");
    std::fs::write(
        &cfg,
        format!(
            "[clips]\ncount = 2\nseed = 3\nwidth = 192\nheight = 108\n\
             [conditions]\nnames = [\"noise_30\"]\n\
             [planner]\nkind = \"http\"\nendpoint = \"https://127.0.0.1:{}\"\n\
             [run]\nconcurrency = 2\ntimeout_s = 30\nretries = 0\n",
            front.port()
        ),
    )
    .unwrap();
    let cfg = cfg.to_str().unwrap();
    let ca = pki.ca_pem.to_str().unwrap();
    let store = |name: &str| dir.path().join(name).to_str().unwrap().to_string();

    let trusted = store("trusted.sqlite");
    let o = fogline(&["--ca-cert", ca, "campaign", "run", cfg, "--store", &trusted]);
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    assert!(t.contains("4 ok, 0 failed"), "{t}");

    let untrusted = store("untrusted.sqlite");
    let o = fogline(&["campaign", "run", cfg, "--store", &untrusted]);
    let t = text(&o);
    assert!(t.contains("0 ok, 4 failed"), "{t}");
    let o = fogline(&["campaign", "status", &untrusted, "--json"]);
    let t = text(&o);
    assert!(
        t.contains("unknown issuer") && t.contains(&format!("https://127.0.0.1:{}", front.port())),
        "{t}"
    );
}

/// `fogline sim run --planner egodriver+https://HOST:PORT` names an egodriver policy behind
/// TLS (the client's TLS itself is tested in fogline-remote); an unknown scheme is refused
/// with the forms that are accepted.
#[test]
fn sim_planner_specs_name_an_egodriver_policy_behind_tls() {
    let p = fogline_api::sim::planner_at("egodriver+https://127.0.0.1:1", 60.0).unwrap();
    assert_eq!(p.describe(), "egodriver at https://127.0.0.1:1");
    let p = fogline_api::sim::planner_at("egodriver://127.0.0.1:1", 60.0).unwrap();
    assert_eq!(p.describe(), "egodriver at 127.0.0.1:1");
    let err = fogline_api::sim::planner_at("grpcs://127.0.0.1:1", 60.0)
        .err()
        .unwrap()
        .to_string();
    assert!(err.contains("egodriver+https://HOST[:PORT]"), "{err}");
}
