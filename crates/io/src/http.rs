//! The HTTP/1 client fogline's outgoing calls share (the OpenAI-compatible LLM backend, the
//! HTTP/JSON planner client), and the connector under the egodriver gRPC client: a
//! `http://` or `https://` base URL ([`BaseUrl`]), one JSON POST per connection
//! ([`post_json`]), the reply body read up to a limit, failures classified so each caller
//! can say what went wrong in its own terms. The caller bounds the call's time (a dropped
//! call leaves no task behind).
//!
//! TLS ([`Tls`]): rustls on the ring provider, TLS 1.2 and 1.3, the server's certificate
//! checked against Mozilla's roots (bundled, the same on every machine) plus, when given,
//! the certificates of a PEM file (a private CA: `--ca-cert FILE` on the command line).
//! A certificate problem is a [`PostError::Tls`] that says what is wrong (unknown issuer,
//! a name it is not valid for, expired, a server that does not speak TLS). A bearer token
//! is sent as a header and never logged.

use std::path::{Path, PathBuf};
use std::pin::Pin;
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll};

use bytes::Bytes;
use http_body_util::{BodyExt as _, Full, Limited};
use hyper::header::{ACCEPT, AUTHORIZATION, CONTENT_TYPE, HOST};
use hyper_util::rt::TokioIo;
use rustls::pki_types::pem::PemObject as _;
use rustls::pki_types::{CertificateDer, ServerName};
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::TcpStream;

/// A base URL split into what to connect to and the path prefix.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BaseUrl {
    /// `host:port` (port 80, or 443 with `https://`, when the URL gives none).
    pub authority: String,
    /// The path prefix, without a trailing slash (empty for none).
    pub prefix: String,
    /// `https://`: the connection is TLS.
    pub tls: bool,
    /// The host, IPv6 addresses without their brackets (the name the server's certificate
    /// must be valid for).
    pub host: String,
    /// The port.
    pub port: u16,
}

/// Why a base URL was refused.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum BaseUrlError {
    /// Neither `http://…` nor `https://…`.
    Scheme,
    /// No host after the scheme.
    NoHost,
    /// The host is not a name, an IPv4 address or a bracketed IPv6 address.
    BadHost(String),
    /// The port is not a number in 1–65535.
    BadPort(String),
    /// User info, a query or a fragment, which a base URL does not take.
    Unsupported(String),
}

impl std::fmt::Display for BaseUrlError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Scheme => {
                f.write_str("expected http://host[:port][/prefix] or https://host[:port][/prefix]")
            }
            Self::NoHost => f.write_str("no host after the scheme"),
            Self::BadHost(h) => write!(
                f,
                "host {h:?} is not a host name, an IPv4 address or a bracketed IPv6 address"
            ),
            Self::BadPort(p) => write!(f, "port {p:?} is not a number in 1-65535"),
            Self::Unsupported(what) => write!(f, "a base URL takes no {what}"),
        }
    }
}

impl std::error::Error for BaseUrlError {}

impl BaseUrl {
    /// Parses `http://host[:port][/prefix]` or `https://…` (surrounding spaces ignored): the
    /// host a name, an IPv4 address or an IPv6 address in brackets, the port 1–65535 (80 or
    /// 443 when absent).
    pub fn parse(url: &str) -> Result<Self, BaseUrlError> {
        let url = url.trim();
        let (rest, tls) = if let Some(r) = url.strip_prefix("http://") {
            (r, false)
        } else if let Some(r) = url.strip_prefix("https://") {
            (r, true)
        } else {
            return Err(BaseUrlError::Scheme);
        };
        let (authority, prefix) = match rest.find('/') {
            Some(i) => (&rest[..i], rest[i..].trim_end_matches('/')),
            None => (rest, ""),
        };
        if authority.is_empty() {
            return Err(BaseUrlError::NoHost);
        }
        if authority.contains('@') {
            return Err(BaseUrlError::Unsupported("user info".into()));
        }
        if rest.contains('?') || rest.contains('#') {
            return Err(BaseUrlError::Unsupported("query or fragment".into()));
        }
        if prefix.chars().any(|c| c.is_whitespace() || c.is_control()) {
            return Err(BaseUrlError::Unsupported("spaces in its path".into()));
        }
        let (host, bracketed, port) = if let Some(v6) = authority.strip_prefix('[') {
            let (addr, after) = v6
                .split_once(']')
                .ok_or_else(|| BaseUrlError::BadHost(authority.to_string()))?;
            if addr.parse::<std::net::Ipv6Addr>().is_err() {
                return Err(BaseUrlError::BadHost(format!("[{addr}]")));
            }
            let port = match after {
                "" => None,
                p => Some(
                    p.strip_prefix(':')
                        .ok_or_else(|| BaseUrlError::BadHost(authority.to_string()))?,
                ),
            };
            (addr.to_string(), format!("[{addr}]"), port)
        } else {
            let (host, port) = match authority.split_once(':') {
                Some((h, p)) => (h, Some(p)),
                None => (authority, None),
            };
            let name_ok = !host.is_empty()
                && host.len() <= 253
                && host
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '.' | '_'))
                && !host.starts_with(['-', '.'])
                && !host.contains("..");
            if !name_ok {
                return Err(BaseUrlError::BadHost(host.to_string()));
            }
            (host.to_string(), host.to_string(), port)
        };
        let port = match port {
            None if tls => 443,
            None => 80,
            Some(p) => match p.parse::<u16>() {
                Ok(n) if n > 0 => n,
                _ => return Err(BaseUrlError::BadPort(p.to_string())),
            },
        };
        Ok(Self {
            authority: format!("{bracketed}:{port}"),
            prefix: prefix.to_string(),
            tls,
            host,
            port,
        })
    }

    /// `http` or `https`.
    pub fn scheme(&self) -> &'static str {
        if self.tls { "https" } else { "http" }
    }

    /// `scheme://host:port`, for messages.
    pub fn origin(&self) -> String {
        format!("{}://{}", self.scheme(), self.authority)
    }

    /// The `Host` header: the host alone on the scheme's default port, else `host:port`.
    pub fn host_header(&self) -> String {
        let default = if self.tls { 443 } else { 80 };
        match self.authority.rsplit_once(':') {
            Some((host, _)) if self.port == default => host.to_string(),
            _ => self.authority.clone(),
        }
    }

    /// Whether the host is a loopback address or `localhost` (traffic that stays on this
    /// machine).
    pub fn is_loopback(&self) -> bool {
        self.host.eq_ignore_ascii_case("localhost")
            || self
                .host
                .parse::<std::net::IpAddr>()
                .is_ok_and(|a| a.is_loopback())
    }
}

/// Why a TLS setting was refused: the CA certificate file cannot be used.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum TlsError {
    /// The file cannot be read.
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// The file holds no PEM certificate, or a broken one.
    Pem {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// A certificate of the file cannot be a root.
    Root {
        /// The file.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// The TLS configuration cannot be built.
    Config(String),
}

impl std::fmt::Display for TlsError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Read { path, reason } => {
                write!(
                    f,
                    "CA certificate file {}: cannot read: {reason}",
                    path.display()
                )
            }
            Self::Pem { path, reason } => write!(
                f,
                "CA certificate file {}: {reason} (expected PEM certificates, -----BEGIN CERTIFICATE-----)",
                path.display()
            ),
            Self::Root { path, reason } => write!(
                f,
                "CA certificate file {}: a certificate cannot be used as a root: {reason}",
                path.display()
            ),
            Self::Config(e) => write!(f, "cannot set up TLS: {e}"),
        }
    }
}

impl std::error::Error for TlsError {}

/// The application protocol a TLS connection offers (ALPN).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Alpn {
    /// HTTP/1.1 (the JSON clients).
    Http1,
    /// HTTP/2 (gRPC).
    H2,
}

/// How `https://` connections check the server: Mozilla's roots (bundled) plus the
/// certificates of an optional PEM file. Cheap to clone.
#[derive(Clone)]
pub struct Tls {
    ca_cert: Option<PathBuf>,
    extra_roots: usize,
    http1: Arc<rustls::ClientConfig>,
    h2: Arc<rustls::ClientConfig>,
}

impl std::fmt::Debug for Tls {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Tls")
            .field("ca_cert", &self.ca_cert)
            .field("extra_roots", &self.extra_roots)
            .finish_non_exhaustive()
    }
}

/// The CA certificate file every [`Tls::process_default`] adds (set by the command line).
static DEFAULT_CA_CERT: Mutex<Option<PathBuf>> = Mutex::new(None);

/// Reads the certificates of a PEM file.
fn read_pem_certs(path: &Path) -> Result<Vec<CertificateDer<'static>>, TlsError> {
    let bytes = std::fs::read(path).map_err(|e| TlsError::Read {
        path: path.to_path_buf(),
        reason: e.to_string(),
    })?;
    let certs = CertificateDer::pem_slice_iter(&bytes)
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| TlsError::Pem {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?;
    if certs.is_empty() {
        return Err(TlsError::Pem {
            path: path.to_path_buf(),
            reason: "no certificate in it".into(),
        });
    }
    Ok(certs)
}

impl Tls {
    /// Mozilla's roots plus, when `ca_cert` is given, every certificate of that PEM file
    /// (read now: a missing or broken file is an error before any connection).
    pub fn new(ca_cert: Option<&Path>) -> Result<Self, TlsError> {
        let mut roots = rustls::RootCertStore::empty();
        roots.extend(webpki_roots::TLS_SERVER_ROOTS.iter().cloned());
        let mut extra_roots = 0;
        if let Some(path) = ca_cert {
            for cert in read_pem_certs(path)? {
                roots.add(cert).map_err(|e| TlsError::Root {
                    path: path.to_path_buf(),
                    reason: e.to_string(),
                })?;
                extra_roots += 1;
            }
        }
        let provider = Arc::new(rustls::crypto::ring::default_provider());
        let roots = Arc::new(roots);
        let config = |alpn: &[u8]| -> Result<Arc<rustls::ClientConfig>, TlsError> {
            let mut c = rustls::ClientConfig::builder_with_provider(provider.clone())
                .with_safe_default_protocol_versions()
                .map_err(|e| TlsError::Config(e.to_string()))?
                .with_root_certificates(roots.clone())
                .with_no_client_auth();
            c.alpn_protocols = vec![alpn.to_vec()];
            Ok(Arc::new(c))
        };
        Ok(Self {
            ca_cert: ca_cert.map(Path::to_path_buf),
            extra_roots,
            http1: config(b"http/1.1")?,
            h2: config(b"h2")?,
        })
    }

    /// Mozilla's roots plus the file [`set_default_ca_cert`] named, if any: what a client
    /// built without TLS settings of its own uses.
    pub fn process_default() -> Result<Self, TlsError> {
        let path = DEFAULT_CA_CERT
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .clone();
        Self::new(path.as_deref())
    }

    /// The PEM file whose certificates are trusted besides the bundled roots.
    pub fn ca_cert(&self) -> Option<&Path> {
        self.ca_cert.as_deref()
    }

    fn config(&self, alpn: Alpn) -> Arc<rustls::ClientConfig> {
        match alpn {
            Alpn::Http1 => self.http1.clone(),
            Alpn::H2 => self.h2.clone(),
        }
    }
}

/// Makes every later [`Tls::process_default`] trust the certificates of `ca_cert` too (or
/// only the bundled roots with `None`); the file is checked now. What `--ca-cert FILE` does
/// for the clients a command builds from a configuration.
pub fn set_default_ca_cert(ca_cert: Option<&Path>) -> Result<(), TlsError> {
    if let Some(path) = ca_cert {
        Tls::new(Some(path))?;
    }
    *DEFAULT_CA_CERT
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner) = ca_cert.map(Path::to_path_buf);
    Ok(())
}

/// Why a POST (or a connection) failed.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum PostError {
    /// The TCP connection could not be made.
    Connect(String),
    /// The TLS handshake failed: a certificate problem, or a peer that does not speak TLS.
    Tls(String),
    /// The peer answered with something that is not HTTP.
    NotHttp(String),
    /// The HTTP layer timed out.
    Timeout(String),
    /// The connection failed before a complete answer (closed, reset, …).
    Connection(String),
    /// The body could not be read (broken).
    Body(String),
    /// The body is longer than the limit, in bytes.
    TooLarge(usize),
    /// The request could not be built.
    Request(String),
}

impl std::fmt::Display for PostError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Connect(e) => write!(f, "cannot connect: {e}"),
            Self::Tls(e) => write!(f, "TLS: {e}"),
            Self::NotHttp(e) => write!(f, "not an HTTP answer: {e}"),
            Self::Timeout(e) => f.write_str(e),
            Self::Connection(e) => {
                write!(f, "the connection failed before a complete answer: {e}")
            }
            Self::Body(e) => write!(f, "the answer cannot be read: {e}"),
            Self::TooLarge(n) => write!(f, "the answer is longer than the limit of {n} bytes"),
            Self::Request(e) => write!(f, "cannot build the request: {e}"),
        }
    }
}

impl std::error::Error for PostError {}

/// `secs` since the Unix epoch as `YYYY-MM-DD HH:MM:SS UTC`.
fn utc(secs: u64) -> String {
    let days = (secs / 86_400) as i64;
    let rem = secs % 86_400;
    // Days to a civil date (the proleptic Gregorian calendar).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}-{month:02}-{day:02} {:02}:{:02}:{:02} UTC",
        rem / 3600,
        rem / 60 % 60,
        rem % 60
    )
}

/// A name as the certificate check reports it (`DnsName("host")`, `IpAddress(…)`), plain.
fn plain_name(n: &str) -> &str {
    match (n.find('('), n.strip_suffix(')')) {
        (Some(open), Some(inner)) if open < inner.len() => inner[open + 1..].trim_matches('"'),
        _ => n,
    }
}

/// What a failed handshake means, in words a user can act on.
fn tls_problem(e: &rustls::Error, host: &str) -> String {
    use rustls::CertificateError as C;
    use rustls::Error as E;
    let cert = |what: String| format!("the server's certificate {what}");
    match e {
        E::InvalidCertificate(c) => match c {
            C::UnknownIssuer => cert(
                "is not signed by a trusted root (unknown issuer); a private CA's certificate is \
                 trusted with --ca-cert FILE (PEM)"
                    .into(),
            ),
            C::NotValidForName => cert(format!("is not valid for the name {host}")),
            C::NotValidForNameContext { presented, .. } => cert(format!(
                "is not valid for the name {host} (it names {})",
                if presented.is_empty() {
                    "nothing".to_string()
                } else {
                    presented
                        .iter()
                        .map(|n| plain_name(n))
                        .collect::<Vec<_>>()
                        .join(", ")
                }
            )),
            C::Expired => cert("has expired".into()),
            C::ExpiredContext { time, not_after } => cert(format!(
                "expired at {} (now {})",
                utc(not_after.as_secs()),
                utc(time.as_secs())
            )),
            C::NotValidYet => cert("is not valid yet (check the clock)".into()),
            C::NotValidYetContext { time, not_before } => cert(format!(
                "is not valid before {} (now {}; check the clock)",
                utc(not_before.as_secs()),
                utc(time.as_secs())
            )),
            C::Revoked => cert("has been revoked".into()),
            C::BadSignature => cert("has a bad signature".into()),
            C::InvalidPurpose | C::InvalidPurposeContext { .. } => {
                cert("is not meant for a TLS server".into())
            }
            other => cert(format!("was rejected: {other:?}")),
        },
        E::InvalidMessage(_)
        | E::InappropriateMessage { .. }
        | E::InappropriateHandshakeMessage { .. } => {
            "the server does not speak TLS here (a plain-HTTP server takes an http:// URL)".into()
        }
        E::AlertReceived(alert) => format!("the server ended the handshake ({alert:?})"),
        E::NoCertificatesPresented => "the server presented no certificate".into(),
        E::NoApplicationProtocol => {
            "the server does not offer the application protocol (ALPN) this client needs".into()
        }
        other => format!("the handshake failed: {other}"),
    }
}

/// A connection, plain or TLS. Implements tokio's `AsyncRead`/`AsyncWrite`.
#[derive(Debug)]
pub enum Stream {
    /// Plain TCP.
    Plain(TcpStream),
    /// TLS over TCP.
    Tls(Box<tokio_rustls::client::TlsStream<TcpStream>>),
}

impl AsyncRead for Stream {
    fn poll_read(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<std::io::Result<()>> {
        match self.get_mut() {
            Stream::Plain(s) => Pin::new(s).poll_read(cx, buf),
            Stream::Tls(s) => Pin::new(s.as_mut()).poll_read(cx, buf),
        }
    }
}

impl AsyncWrite for Stream {
    fn poll_write(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<std::io::Result<usize>> {
        match self.get_mut() {
            Stream::Plain(s) => Pin::new(s).poll_write(cx, buf),
            Stream::Tls(s) => Pin::new(s.as_mut()).poll_write(cx, buf),
        }
    }

    fn poll_flush(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<std::io::Result<()>> {
        match self.get_mut() {
            Stream::Plain(s) => Pin::new(s).poll_flush(cx),
            Stream::Tls(s) => Pin::new(s.as_mut()).poll_flush(cx),
        }
    }

    fn poll_shutdown(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<std::io::Result<()>> {
        match self.get_mut() {
            Stream::Plain(s) => Pin::new(s).poll_shutdown(cx),
            Stream::Tls(s) => Pin::new(s.as_mut()).poll_shutdown(cx),
        }
    }

    fn poll_write_vectored(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[std::io::IoSlice<'_>],
    ) -> Poll<std::io::Result<usize>> {
        match self.get_mut() {
            Stream::Plain(s) => Pin::new(s).poll_write_vectored(cx, bufs),
            Stream::Tls(s) => Pin::new(s.as_mut()).poll_write_vectored(cx, bufs),
        }
    }

    fn is_write_vectored(&self) -> bool {
        match self {
            Stream::Plain(s) => s.is_write_vectored(),
            Stream::Tls(s) => s.is_write_vectored(),
        }
    }
}

/// Opens a connection to `url`'s host and port: plain TCP for `http://`, TLS checked by
/// `tls` (offering `alpn`) for `https://`. Runs on the caller's tokio runtime.
pub async fn connect(url: &BaseUrl, tls: &Tls, alpn: Alpn) -> Result<Stream, PostError> {
    let tcp = TcpStream::connect(&url.authority)
        .await
        .map_err(|e| PostError::Connect(e.to_string()))?;
    let _ = tcp.set_nodelay(true);
    if !url.tls {
        return Ok(Stream::Plain(tcp));
    }
    let name = match url.host.parse::<std::net::IpAddr>() {
        Ok(ip) => ServerName::IpAddress(ip.into()),
        Err(_) => ServerName::try_from(url.host.clone())
            .map_err(|e| PostError::Tls(format!("{:?} is not a server name: {e}", url.host)))?,
    };
    let connector = tokio_rustls::TlsConnector::from(tls.config(alpn));
    match connector.connect(name, tcp).await {
        Ok(s) => Ok(Stream::Tls(Box::new(s))),
        Err(e) => {
            let rustls_error = e
                .get_ref()
                .and_then(|inner| inner.downcast_ref::<rustls::Error>());
            Err(PostError::Tls(match rustls_error {
                Some(r) => tls_problem(r, &url.host),
                None if e.kind() == std::io::ErrorKind::UnexpectedEof => {
                    "the server closed the connection during the handshake (is it a TLS server?)"
                        .into()
                }
                None => format!("the handshake failed: {e}"),
            }))
        }
    }
}

fn classify(e: &hyper::Error) -> PostError {
    if e.is_parse() || e.is_parse_status() || e.is_parse_too_large() {
        PostError::NotHttp(e.to_string())
    } else if e.is_timeout() {
        PostError::Timeout(e.to_string())
    } else {
        let cause = std::error::Error::source(e)
            .map(|s| format!(": {s}"))
            .unwrap_or_default();
        PostError::Connection(format!("{e}{cause}"))
    }
}

/// Aborts a spawned task when dropped (a call that timed out leaves no task behind).
struct AbortOnDrop(tokio::task::JoinHandle<()>);

impl Drop for AbortOnDrop {
    fn drop(&mut self) {
        self.0.abort();
    }
}

/// POSTs `body` (JSON) to `path` on `url`'s server over a new connection (TLS checked by
/// `tls` for `https://`), with a bearer token when given, and reads the reply's status and
/// body (at most `max_body` bytes). Runs on the caller's tokio runtime.
pub async fn post_json(
    url: &BaseUrl,
    tls: &Tls,
    path: &str,
    body: Vec<u8>,
    bearer: Option<&str>,
    max_body: usize,
) -> Result<(u16, Bytes), PostError> {
    let stream = connect(url, tls, Alpn::Http1).await?;
    let (mut sender, connection) = hyper::client::conn::http1::handshake(TokioIo::new(stream))
        .await
        .map_err(|e| classify(&e))?;
    let _driver = AbortOnDrop(tokio::spawn(async move {
        if let Err(e) = connection.await {
            log::debug!("http client connection: {e}");
        }
    }));
    let mut request = hyper::Request::post(path)
        .header(HOST, url.host_header())
        .header(CONTENT_TYPE, "application/json")
        .header(ACCEPT, "application/json");
    if let Some(key) = bearer {
        let mut value = hyper::header::HeaderValue::from_str(&format!("Bearer {key}"))
            .map_err(|_| PostError::Request("the API key is not a valid header value".into()))?;
        value.set_sensitive(true);
        request = request.header(AUTHORIZATION, value);
    }
    let request = request
        .body(Full::new(Bytes::from(body)))
        .map_err(|e| PostError::Request(e.to_string()))?;
    let response = sender
        .send_request(request)
        .await
        .map_err(|e| classify(&e))?;
    let status = response.status().as_u16();
    let body = Limited::new(response.into_body(), max_body)
        .collect()
        .await
        .map_err(|e| {
            if e.is::<http_body_util::LengthLimitError>() {
                return PostError::TooLarge(max_body);
            }
            match e.downcast::<hyper::Error>() {
                Ok(e) => classify(&e),
                Err(e) => PostError::Body(e.to_string()),
            }
        })?
        .to_bytes();
    Ok((status, body))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base_urls() {
        let u = BaseUrl::parse(" http://127.0.0.1:8000/v1/ ").unwrap_or_else(|e| panic!("{e:?}"));
        assert_eq!(
            (u.authority.as_str(), u.prefix.as_str(), u.tls),
            ("127.0.0.1:8000", "/v1", false)
        );
        assert_eq!(u.host_header(), "127.0.0.1:8000");
        let u = BaseUrl::parse("http://planner").unwrap_or_else(|e| panic!("{e:?}"));
        assert_eq!(
            (u.authority.as_str(), u.prefix.as_str()),
            ("planner:80", "")
        );
        assert_eq!(u.host_header(), "planner");
        let u =
            BaseUrl::parse("https://llm.example.invalid/proxy").unwrap_or_else(|e| panic!("{e:?}"));
        assert_eq!(
            (
                u.authority.as_str(),
                u.prefix.as_str(),
                u.tls,
                u.host.as_str(),
                u.port
            ),
            (
                "llm.example.invalid:443",
                "/proxy",
                true,
                "llm.example.invalid",
                443
            )
        );
        assert_eq!(u.host_header(), "llm.example.invalid");
        assert_eq!(u.origin(), "https://llm.example.invalid:443");
        assert!(!u.is_loopback());
        let u = BaseUrl::parse("https://[::1]:8443").unwrap_or_else(|e| panic!("{e:?}"));
        assert_eq!(
            (u.host.as_str(), u.authority.as_str()),
            ("::1", "[::1]:8443")
        );
        assert!(u.is_loopback());
        assert_eq!(BaseUrl::parse("ftp://x"), Err(BaseUrlError::Scheme));
        assert_eq!(BaseUrl::parse("127.0.0.1:80"), Err(BaseUrlError::Scheme));
        assert_eq!(BaseUrl::parse("http:///x"), Err(BaseUrlError::NoHost));
        assert_eq!(BaseUrl::parse("https://"), Err(BaseUrlError::NoHost));
        let u = BaseUrl::parse("http://[::1]:9000/v1").unwrap_or_else(|e| panic!("{e:?}"));
        assert_eq!(u.authority, "[::1]:9000");
        let u = BaseUrl::parse("http://[::1]").unwrap_or_else(|e| panic!("{e:?}"));
        assert_eq!(u.authority, "[::1]:80");
        assert_eq!(u.host_header(), "[::1]");
        for (bad, want) in [
            ("http://[::1", BaseUrlError::BadHost("[::1".into())),
            ("http://[::zz]:80", BaseUrlError::BadHost("[::zz]".into())),
            ("http://[::1]x", BaseUrlError::BadHost("[::1]x".into())),
            ("http://host:abc", BaseUrlError::BadPort("abc".into())),
            ("http://host:0", BaseUrlError::BadPort("0".into())),
            ("https://host:70000", BaseUrlError::BadPort("70000".into())),
            ("http://ho st:80", BaseUrlError::BadHost("ho st".into())),
            ("http://:80", BaseUrlError::BadHost(String::new())),
            ("http://a:1:2", BaseUrlError::BadPort("1:2".into())),
            (
                "http://u@host",
                BaseUrlError::Unsupported("user info".into()),
            ),
            (
                "https://host/v1?x=1",
                BaseUrlError::Unsupported("query or fragment".into()),
            ),
        ] {
            assert_eq!(BaseUrl::parse(bad), Err(want), "{bad}");
        }
        // Every refusal reads as a sentence.
        let e = BaseUrl::parse("http://[::1").unwrap_err().to_string();
        assert!(e.contains("[::1") && e.contains("IPv6"), "{e}");
        let e = BaseUrl::parse("ws://x").unwrap_err().to_string();
        assert!(e.contains("https://"), "{e}");
    }

    #[test]
    fn names() {
        assert_eq!(
            plain_name("DnsName(\"elsewhere.invalid\")"),
            "elsewhere.invalid"
        );
        assert_eq!(plain_name("IpAddress(127.0.0.1)"), "127.0.0.1");
        assert_eq!(plain_name("localhost"), "localhost");
    }

    #[test]
    fn dates() {
        assert_eq!(utc(0), "1970-01-01 00:00:00 UTC");
        assert_eq!(utc(951_782_400), "2000-02-29 00:00:00 UTC");
        assert_eq!(utc(1_700_000_000), "2023-11-14 22:13:20 UTC");
    }

    #[test]
    fn ca_cert_files_are_checked_when_set() {
        let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
        let missing = dir.path().join("missing.pem");
        let e = Tls::new(Some(&missing)).unwrap_err();
        assert!(matches!(e, TlsError::Read { .. }), "{e}");
        assert!(e.to_string().contains("missing.pem"), "{e}");
        let empty = dir.path().join("empty.pem");
        std::fs::write(&empty, "not a certificate\n").unwrap_or_else(|e| panic!("{e}"));
        let e = Tls::new(Some(&empty)).unwrap_err();
        assert!(matches!(e, TlsError::Pem { .. }), "{e}");
        assert!(e.to_string().contains("BEGIN CERTIFICATE"), "{e}");
        let broken = dir.path().join("broken.pem");
        std::fs::write(
            &broken,
            "-----BEGIN CERTIFICATE-----\nMIIB\n-----END CERTIFICATE-----\n",
        )
        .unwrap_or_else(|e| panic!("{e}"));
        assert!(Tls::new(Some(&broken)).is_err());
        let key = rcgen::KeyPair::generate().unwrap_or_else(|e| panic!("{e}"));
        let cert = rcgen::CertificateParams::new(vec!["localhost".to_string()])
            .and_then(|p| p.self_signed(&key))
            .unwrap_or_else(|e| panic!("{e}"));
        let good = dir.path().join("ca.pem");
        std::fs::write(&good, cert.pem()).unwrap_or_else(|e| panic!("{e}"));
        let tls = Tls::new(Some(&good)).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(tls.ca_cert(), Some(good.as_path()));
        assert_eq!(tls.extra_roots, 1);
        assert!(set_default_ca_cert(Some(&missing)).is_err());
    }
}
