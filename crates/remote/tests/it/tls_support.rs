//! TLS for the tests: a private CA made in the test (rcgen), server certificates signed by
//! it (good, for another name, expired), and a TLS front on 127.0.0.1 that forwards every
//! connection to a plain server — so the servers the tests already have (the mock LLM, the
//! HTTP planner, the egodriver server) are reached over `https://`. Shared by the
//! integration tests of fogline-remote, fogline-rco and fogline-cli (`#[path]`-included
//! there).

#![allow(dead_code)]

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;

use rcgen::{
    BasicConstraints, CertificateParams, CertifiedIssuer, DnType, IsCa, KeyPair, KeyUsagePurpose,
};
use rustls::pki_types::{CertificateDer, PrivateKeyDer, PrivatePkcs8KeyDer};

/// Which certificate a server presents.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Cert {
    /// Signed by the test CA for `localhost` and `127.0.0.1`, valid now.
    Good,
    /// Signed by the test CA for `elsewhere.invalid` only.
    OtherName,
    /// Signed by the test CA for `127.0.0.1`, expired in 2001.
    Expired,
}

/// A private CA and its PEM file.
pub struct Pki {
    /// Holds the files.
    pub dir: tempfile::TempDir,
    /// The CA certificate, PEM (what `--ca-cert` takes).
    pub ca_pem: PathBuf,
    ca: CertifiedIssuer<'static, KeyPair>,
}

/// A new private CA.
pub fn pki() -> Pki {
    let mut params = CertificateParams::new(Vec::<String>::new()).unwrap();
    params.is_ca = IsCa::Ca(BasicConstraints::Unconstrained);
    params
        .distinguished_name
        .push(DnType::CommonName, "fogline test CA");
    params.key_usages = vec![
        KeyUsagePurpose::KeyCertSign,
        KeyUsagePurpose::CrlSign,
        KeyUsagePurpose::DigitalSignature,
    ];
    let ca = CertifiedIssuer::self_signed(params, KeyPair::generate().unwrap()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let ca_pem = dir.path().join("ca.pem");
    std::fs::write(&ca_pem, ca.pem()).unwrap();
    Pki { dir, ca_pem, ca }
}

impl Pki {
    /// A server configuration presenting `cert`, offering `alpn` (e.g. `h2`).
    pub fn server(&self, cert: Cert, alpn: &[&[u8]]) -> Arc<rustls::ServerConfig> {
        let names: Vec<String> = match cert {
            Cert::Good => vec!["localhost".into(), "127.0.0.1".into()],
            Cert::OtherName => vec!["elsewhere.invalid".into()],
            Cert::Expired => vec!["127.0.0.1".into()],
        };
        let mut params = CertificateParams::new(names).unwrap();
        params
            .distinguished_name
            .push(DnType::CommonName, "fogline test server");
        if cert == Cert::Expired {
            params.not_before = rcgen::date_time_ymd(2000, 1, 1);
            params.not_after = rcgen::date_time_ymd(2001, 1, 1);
        }
        let key = KeyPair::generate().unwrap();
        let leaf = params.signed_by(&key, &self.ca).unwrap();
        let chain: Vec<CertificateDer<'static>> = vec![leaf.der().clone()];
        let key = PrivateKeyDer::Pkcs8(PrivatePkcs8KeyDer::from(key.serialize_der()));
        let mut config = rustls::ServerConfig::builder_with_provider(Arc::new(
            rustls::crypto::ring::default_provider(),
        ))
        .with_safe_default_protocol_versions()
        .unwrap()
        .with_no_client_auth()
        .with_single_cert(chain, key)
        .unwrap();
        config.alpn_protocols = alpn.iter().map(|p| p.to_vec()).collect();
        Arc::new(config)
    }
}

/// A TLS server on 127.0.0.1 (its address returned) that forwards every connection, once
/// its handshake succeeded, to the plain server at `upstream`. It runs until the test
/// process ends.
pub fn tls_front(upstream: SocketAddr, config: Arc<rustls::ServerConfig>) -> SocketAddr {
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap();
    listener.set_nonblocking(true).unwrap();
    std::thread::spawn(move || {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap();
        rt.block_on(async move {
            let listener = tokio::net::TcpListener::from_std(listener).unwrap();
            let acceptor = tokio_rustls::TlsAcceptor::from(config);
            loop {
                let Ok((tcp, _)) = listener.accept().await else {
                    continue;
                };
                let acceptor = acceptor.clone();
                tokio::spawn(async move {
                    // A refused handshake ends here: the client saw the alert.
                    let Ok(mut tls) = acceptor.accept(tcp).await else {
                        return;
                    };
                    let Ok(mut plain) = tokio::net::TcpStream::connect(upstream).await else {
                        return;
                    };
                    let _ = tokio::io::copy_bidirectional(&mut tls, &mut plain).await;
                });
            }
        });
    });
    addr
}
