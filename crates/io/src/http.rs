//! The HTTP/1 client fogline's outgoing calls share (the OpenAI-compatible LLM backend, the
//! HTTP/JSON planner client): a `http://host[:port][/prefix]` base URL, one JSON POST per
//! connection, the reply body read up to a limit, failures classified so each caller can say
//! what went wrong in its own terms. The caller bounds the call's time (a dropped call leaves
//! no task behind).

use bytes::Bytes;
use http_body_util::{BodyExt as _, Full, Limited};
use hyper::header::{ACCEPT, AUTHORIZATION, CONTENT_TYPE, HOST};
use hyper_util::rt::TokioIo;

/// A base URL split into what to connect to and the path prefix.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BaseUrl {
    /// `host:port` (port 80 when the URL gives none).
    pub authority: String,
    /// The path prefix, without a trailing slash (empty for none).
    pub prefix: String,
}

/// Why a base URL was refused.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum BaseUrlError {
    /// Not `http://…` (HTTPS goes through a local proxy).
    NotHttp,
    /// No host after `http://`.
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
            Self::NotHttp => f.write_str(
                "only http://host[:port][/prefix] is supported (put an HTTPS service behind a local proxy)",
            ),
            Self::NoHost => f.write_str("no host after http://"),
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
    /// Parses `http://host[:port][/prefix]` (surrounding spaces ignored): the host a name,
    /// an IPv4 address or an IPv6 address in brackets, the port 1–65535 (80 when absent).
    pub fn parse(url: &str) -> Result<Self, BaseUrlError> {
        let rest = url
            .trim()
            .strip_prefix("http://")
            .ok_or(BaseUrlError::NotHttp)?;
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
        let (host, port) = if let Some(v6) = authority.strip_prefix('[') {
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
            (format!("[{addr}]"), port)
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
            (host.to_string(), port)
        };
        let port = match port {
            None => 80,
            Some(p) => match p.parse::<u16>() {
                Ok(n) if n > 0 => n,
                _ => return Err(BaseUrlError::BadPort(p.to_string())),
            },
        };
        Ok(Self {
            authority: format!("{host}:{port}"),
            prefix: prefix.to_string(),
        })
    }
}

/// Why a POST failed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum PostError {
    /// The TCP connection could not be made.
    Connect(String),
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

/// POSTs `body` (JSON) to `path` on `authority` over a new connection, with a bearer token
/// when given, and reads the reply's status and body (at most `max_body` bytes). Runs on the
/// caller's tokio runtime.
pub async fn post_json(
    authority: &str,
    path: &str,
    body: Vec<u8>,
    bearer: Option<&str>,
    max_body: usize,
) -> Result<(u16, Bytes), PostError> {
    let stream = tokio::net::TcpStream::connect(authority)
        .await
        .map_err(|e| PostError::Connect(e.to_string()))?;
    let _ = stream.set_nodelay(true);
    let (mut sender, connection) = hyper::client::conn::http1::handshake(TokioIo::new(stream))
        .await
        .map_err(|e| classify(&e))?;
    let _driver = AbortOnDrop(tokio::spawn(async move {
        if let Err(e) = connection.await {
            log::debug!("http client connection: {e}");
        }
    }));
    let mut request = hyper::Request::post(path)
        .header(HOST, authority)
        .header(CONTENT_TYPE, "application/json")
        .header(ACCEPT, "application/json");
    if let Some(key) = bearer {
        request = request.header(AUTHORIZATION, format!("Bearer {key}"));
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
            (u.authority.as_str(), u.prefix.as_str()),
            ("127.0.0.1:8000", "/v1")
        );
        let u = BaseUrl::parse("http://planner").unwrap_or_else(|e| panic!("{e:?}"));
        assert_eq!(
            (u.authority.as_str(), u.prefix.as_str()),
            ("planner:80", "")
        );
        assert_eq!(BaseUrl::parse("https://x"), Err(BaseUrlError::NotHttp));
        assert_eq!(BaseUrl::parse("http:///x"), Err(BaseUrlError::NoHost));
        let u = BaseUrl::parse("http://[::1]:9000/v1").unwrap_or_else(|e| panic!("{e:?}"));
        assert_eq!(u.authority, "[::1]:9000");
        let u = BaseUrl::parse("http://[::1]").unwrap_or_else(|e| panic!("{e:?}"));
        assert_eq!(u.authority, "[::1]:80");
        for (bad, want) in [
            ("http://[::1", BaseUrlError::BadHost("[::1".into())),
            ("http://[::zz]:80", BaseUrlError::BadHost("[::zz]".into())),
            ("http://[::1]x", BaseUrlError::BadHost("[::1]x".into())),
            ("http://host:abc", BaseUrlError::BadPort("abc".into())),
            ("http://host:0", BaseUrlError::BadPort("0".into())),
            ("http://host:70000", BaseUrlError::BadPort("70000".into())),
            ("http://ho st:80", BaseUrlError::BadHost("ho st".into())),
            ("http://:80", BaseUrlError::BadHost(String::new())),
            ("http://a:1:2", BaseUrlError::BadPort("1:2".into())),
            (
                "http://u@host",
                BaseUrlError::Unsupported("user info".into()),
            ),
            (
                "http://host/v1?x=1",
                BaseUrlError::Unsupported("query or fragment".into()),
            ),
        ] {
            assert_eq!(BaseUrl::parse(bad), Err(want), "{bad}");
        }
        // Every refusal reads as a sentence.
        let e = BaseUrl::parse("http://[::1").unwrap_err().to_string();
        assert!(e.contains("[::1") && e.contains("IPv6"), "{e}");
    }
}
