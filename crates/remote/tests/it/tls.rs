//! Both clients over TLS (issue 22, item 2): the HTTP planner and the egodriver policy
//! behind a TLS server on 127.0.0.1 whose certificate a CA made in the test signed. Trusted
//! through the CA's PEM file they answer exactly as over plain TCP; without it, or with a
//! certificate for another name or an expired one, the call fails as `Unavailable` with a
//! message that names the endpoint and what is wrong with the certificate.

use std::time::Duration;

use fogline_io::http::Tls;
use fogline_remote::{FailureKind, ImageFormat, Planner};

use crate::tls_support::{Cert, pki, tls_front};
use crate::*;

fn tls_client(proto: Proto, url: String, tls: Tls) -> Box<dyn Planner> {
    let timeout = Duration::from_secs(10);
    match proto {
        Proto::Egodriver => Box::new(
            fogline_remote::egodriver::Client::with_tls(
                fogline_remote::egodriver::ClientOptions {
                    endpoint: url,
                    timeout,
                    image_format: ImageFormat::Png,
                    ..Default::default()
                },
                tls,
            )
            .unwrap(),
        ),
        Proto::Http => Box::new(
            fogline_remote::http::Client::with_tls(
                fogline_remote::http::ClientOptions {
                    url,
                    timeout,
                    image_format: ImageFormat::Png,
                },
                tls,
            )
            .unwrap(),
        ),
    }
}

fn alpn(proto: Proto) -> &'static [&'static [u8]] {
    match proto {
        Proto::Egodriver => &[b"h2"],
        Proto::Http => &[b"http/1.1"],
    }
}

#[test]
fn both_protocols_over_tls_trusted_by_the_ca_file_and_refused_without_it() {
    let pki = pki();
    let clip = Clip::new(2);
    let trusted = Tls::new(Some(&pki.ca_pem)).unwrap();
    let bundled_only = Tls::new(None).unwrap();
    for proto in BOTH {
        let fake = Fake::new(Behaviour::Straight);
        let server = start(proto, fake.clone());
        let good = tls_front(server.local_addr(), pki.server(Cert::Good, alpn(proto)));
        let url = format!("https://127.0.0.1:{}", good.port());

        // Trusted: the same answer as in the clear, every frame delivered.
        let out = tls_client(proto, url.clone(), trusted.clone())
            .plan(&clip.request("tls", 7))
            .unwrap_or_else(|e| panic!("{proto:?} over TLS: {e}"));
        // The egodriver contract carries f32: as close as the plain round trip gets.
        for (got, want) in out.trajectory.xy.iter().zip(straight(7)) {
            close(got[0], want[0], 1e-5, "x");
            close(got[1], want[1], 1e-5, "y");
        }
        assert_eq!(out.trajectory.xy.len(), straight(7).len());
        assert_eq!(out.explanation, EXPLANATION, "{proto:?}");
        let seen = fake.last();
        assert_eq!(seen.seed, 7);
        assert_eq!(seen.cameras.len(), clip.cameras.len());
        // By name too (the certificate names localhost).
        let by_name = format!("https://localhost:{}", good.port());
        tls_client(proto, by_name, trusted.clone())
            .plan(&clip.request("tls", 8))
            .unwrap_or_else(|e| panic!("{proto:?} over TLS to localhost: {e}"));

        // Not trusted: refused, the endpoint and the reason named.
        let e = tls_client(proto, url.clone(), bundled_only.clone())
            .plan(&clip.request("tls", 9))
            .unwrap_err();
        assert_eq!(e.kind, FailureKind::Unavailable, "{proto:?}: {e}");
        let m = e.to_string();
        assert!(
            m.contains(&format!("127.0.0.1:{}", good.port())) && m.contains("unknown issuer"),
            "{proto:?}: {m}"
        );
        assert!(m.contains("--ca-cert"), "{proto:?}: {m}");

        // A certificate for another name, and an expired one.
        for (cert, words) in [
            (Cert::OtherName, "not valid for the name 127.0.0.1"),
            (Cert::Expired, "expired at 2001-01-01"),
        ] {
            let front = tls_front(server.local_addr(), pki.server(cert, alpn(proto)));
            let url = format!("https://127.0.0.1:{}", front.port());
            let e = tls_client(proto, url, trusted.clone())
                .plan(&clip.request("tls", 10))
                .unwrap_err();
            assert_eq!(e.kind, FailureKind::Unavailable, "{proto:?} {cert:?}: {e}");
            let m = e.to_string();
            assert!(
                m.contains(words) && m.contains(&format!("127.0.0.1:{}", front.port())),
                "{proto:?} {cert:?}: {m}"
            );
        }
        if proto == Proto::Http {
            let front = tls_front(
                server.local_addr(),
                pki.server(Cert::OtherName, alpn(proto)),
            );
            let e = tls_client(
                proto,
                format!("https://127.0.0.1:{}", front.port()),
                trusted.clone(),
            )
            .plan(&clip.request("tls", 11))
            .unwrap_err();
            assert!(e.to_string().contains("elsewhere.invalid"), "{e}");
        }

        // https:// to a plain server: said so, not a hang or garbage.
        let e = tls_client(
            proto,
            format!("https://127.0.0.1:{}", server.local_addr().port()),
            trusted.clone(),
        )
        .plan(&clip.request("tls", 12))
        .unwrap_err();
        assert_eq!(e.kind, FailureKind::Unavailable, "{proto:?}: {e}");
        assert!(
            e.to_string()
                .contains("TLS: the server does not speak TLS here"),
            "{proto:?}: {e}"
        );
    }
}

#[test]
fn the_process_default_ca_file_reaches_clients_built_without_tls_settings() {
    // What `--ca-cert` does for planners built from a campaign's configuration.
    let pki = pki();
    let server = start(Proto::Http, Fake::new(Behaviour::Straight));
    let front = tls_front(
        server.local_addr(),
        pki.server(Cert::Good, alpn(Proto::Http)),
    );
    let opts = || fogline_remote::http::ClientOptions {
        url: format!("https://127.0.0.1:{}", front.port()),
        timeout: Duration::from_secs(10),
        image_format: ImageFormat::Png,
    };
    let clip = Clip::new(1);
    fogline_io::http::set_default_ca_cert(Some(&pki.ca_pem)).unwrap();
    let with = fogline_remote::http::Client::new(opts()).unwrap();
    fogline_io::http::set_default_ca_cert(None).unwrap();
    let without = fogline_remote::http::Client::new(opts()).unwrap();
    with.plan(&clip.request("default", 1)).unwrap();
    let e = without.plan(&clip.request("default", 1)).unwrap_err();
    assert!(e.to_string().contains("unknown issuer"), "{e}");
}
