//! The `openai` backend over HTTPS (issue 22, item 2): the mock server behind a TLS server
//! on 127.0.0.1 whose certificate a CA made in the test signed. Trusted through `ca_cert`
//! (what `--ca-cert` sets) the controller plans as over plain HTTP; without it, every call
//! fails with a message naming the URL and the unknown issuer, and the tick falls back.

use fogline_rco::{FallbackKind, OpenAiBackend, OpenAiParams, Rco, RcoParams, Source};

use crate::mock_server::{completion, mock};
use crate::tls_support::{Cert, pki, tls_front};
use crate::{GOOD_SC, N, clean, hazard_answer, plan_answer};

const KEY_ENV: &str = "FOGLINE_TEST_TLS_API_KEY";

fn good(name: &str) -> String {
    match name {
        "safety_constraints" => GOOD_SC.to_string(),
        "hazard_inference" => hazard_answer("move"),
        _ => plan_answer(2, [N, N, N], "move_forward", "constant_speed"),
    }
}

#[test]
fn https_with_the_ca_file_plans_and_without_it_falls_back_naming_the_problem() {
    let pki = pki();
    let m = mock(|name, _| (200, completion(&good(name)), 0));
    let front = tls_front(m.addr, pki.server(Cert::Good, &[b"http/1.1"]));
    let url = format!("https://127.0.0.1:{}/v1", front.port());
    let params = |ca: bool| OpenAiParams {
        base_url: url.clone(),
        model: "m".into(),
        api_key_env: KEY_ENV.into(),
        timeout_ms: 5_000,
        ca_cert: ca.then(|| pki.ca_pem.clone()),
        ..OpenAiParams::default()
    };

    let mut rco = Rco::new(
        RcoParams::default(),
        Box::new(OpenAiBackend::new(params(true)).unwrap()),
    )
    .unwrap();
    for t in 0..3 {
        let d = rco.step(&clean(t));
        assert!(d.fallback.is_none(), "{:?}", d.fallback);
        assert_eq!(d.source, Source::Plan);
    }
    let seen = m.seen.lock().unwrap().clone();
    assert!(seen.len() >= 3);
    assert!(
        seen[0]
            .head
            .starts_with("POST /v1/chat/completions HTTP/1.1")
    );
    assert!(
        seen[0]
            .head
            .to_ascii_lowercase()
            .contains(&format!("host: 127.0.0.1:{}", front.port())),
        "{}",
        seen[0].head
    );
    // The key comes from the environment only; none is set here, so none is sent.
    assert!(std::env::var_os(KEY_ENV).is_none());
    assert!(!seen[0].head.to_ascii_lowercase().contains("authorization"));

    let before = m.seen.lock().unwrap().len();
    let mut rco = Rco::new(
        RcoParams::default(),
        Box::new(OpenAiBackend::new(params(false)).unwrap()),
    )
    .unwrap();
    let d = rco.step(&clean(0));
    let f = d
        .fallback
        .expect("an untrusted certificate must not be used");
    assert_eq!(f.kind, FallbackKind::Backend);
    assert!(
        f.message.contains(&url)
            && f.message.contains("unknown issuer")
            && f.message.contains("--ca-cert"),
        "{}",
        f.message
    );
    assert_eq!(
        m.seen.lock().unwrap().len(),
        before,
        "nothing reached the server"
    );

    // A certificate for another name: refused even with the CA trusted.
    let other = tls_front(m.addr, pki.server(Cert::OtherName, &[b"http/1.1"]));
    let mut p = params(true);
    p.base_url = format!("https://127.0.0.1:{}", other.port());
    let mut rco = Rco::new(
        RcoParams::default(),
        Box::new(OpenAiBackend::new(p).unwrap()),
    )
    .unwrap();
    let f = rco.step(&clean(0)).fallback.unwrap();
    assert!(
        f.message
            .contains("not valid for the name 127.0.0.1 (it names elsewhere.invalid)"),
        "{}",
        f.message
    );
}
