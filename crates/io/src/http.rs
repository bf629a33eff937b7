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
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BaseUrlError {
    /// Not `http://…` (HTTPS goes through a local proxy).
    NotHttp,
    /// No host after `http://`.
    NoHost,
}

impl BaseUrl {
    /// Parses `http://host[:port][/prefix]` (surrounding spaces ignored).
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
        let authority = if authority
            .rsplit_once(':')
            .is_some_and(|(_, p)| p.parse::<u16>().is_ok())
        {
            authority.to_string()
        } else {
            format!("{authority}:80")
        };
        Ok(Self {
            authority,
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
    /// The body could not be read (too large, or broken).
    Body(String),
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
        .map_err(|e| match e.downcast::<hyper::Error>() {
            Ok(e) => classify(&e),
            Err(e) => PostError::Body(e.to_string()),
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
    }
}
