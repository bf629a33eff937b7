//! A driver behind TLS (issue 22, item 2): the guard reaches `https://127.0.0.1:PORT` (a
//! TLS front made in the test over the plain driver) when its CA file trusts the
//! certificate, and answers every call itself — a safe stop whose reason names the
//! untrusted certificate — when it does not.

use fogline_guard::GuardParams;
use fogline_guard::session::{LoopSession, connect};

use crate::handback::live_frames;
use crate::tls_support::{Cert, pki, tls_front};
use crate::*;

/// Drives `n` clean frames through a guard in front of `driver_url`; the log's records.
fn drive_through(
    driver_url: &str,
    ca_cert: Option<std::path::PathBuf>,
    n: usize,
) -> Vec<GuardRecord> {
    let log = MemLog::default();
    let guard = fogline_guard::guard(
        loopback(),
        odd(),
        GuardParams {
            driver: driver_url.to_string(),
            scenario: "LANE_KEEPING".into(),
            driver_timeout_ms: 2_000,
            ca_cert,
            ..GuardParams::default()
        },
        Some(log.sink()),
    )
    .unwrap();
    runtime().block_on(async {
        let rpc = connect(guard.local_addr()).await.unwrap();
        let mut s = LoopSession::start(rpc, "tls", &front(), 5.0).await.unwrap();
        for f in live_frames(n, 0..0) {
            let step = s.step(f).await.unwrap();
            assert!(step.response.trajectory.is_some_and(|t| t.poses.len() > 1));
        }
        s.close().await.unwrap();
    });
    log.records()
}

#[test]
fn the_guard_reaches_a_tls_driver_trusted_by_its_ca_file_and_stops_safely_without_it() {
    let pki = pki();
    let driver = driver();
    let front = tls_front(driver.local_addr(), pki.server(Cert::Good, &[b"h2"]));
    let url = format!("https://127.0.0.1:{}", front.port());

    let trusted = drive_through(&url, Some(pki.ca_pem.clone()), 4);
    assert_eq!(trusted.len(), 4);
    assert!(
        trusted.iter().all(|r| r.source == "driver"),
        "{:?}",
        trusted
            .iter()
            .map(|r| (&r.source, &r.reason))
            .collect::<Vec<_>>()
    );

    let untrusted = drive_through(&url, None, 3);
    assert_eq!(untrusted.len(), 3);
    assert!(
        untrusted.iter().all(|r| r.source == "safe_stop"),
        "{untrusted:?}"
    );
    // The first call met the fault; its reason says what is wrong with the certificate.
    let reasons: Vec<&str> = untrusted
        .iter()
        .filter_map(|r| r.reason.as_deref())
        .collect();
    assert!(
        reasons
            .iter()
            .any(|r| r.contains("not signed by a trusted root")),
        "{reasons:?}"
    );

    // A broken address is refused when the guard starts, naming the field.
    let err = fogline_guard::guard(
        loopback(),
        odd(),
        GuardParams {
            driver: "ftp://127.0.0.1:1".into(),
            scenario: "LANE_KEEPING".into(),
            ..GuardParams::default()
        },
        None,
    )
    .err()
    .unwrap()
    .to_string();
    assert!(
        err.contains("driver") && err.contains("https://HOST[:PORT]"),
        "{err}"
    );
}
