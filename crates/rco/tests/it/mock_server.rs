//! A mock OpenAI-compatible server on 127.0.0.1 for tests: it records every request and
//! answers with what the test's closure says. Shared by the integration tests of
//! fogline-rco and fogline-dataset (`#[path]`-included there).

#![allow(dead_code)]

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use serde_json::{Value, json};

/// A request as the mock server saw it.
#[derive(Debug, Clone)]
pub struct Seen {
    pub head: String,
    pub body: Value,
}

/// What the mock answers: status, body, delay.
pub type Reply = (u16, String, u64);

pub struct Mock {
    pub addr: SocketAddr,
    pub seen: Arc<Mutex<Vec<Seen>>>,
}

fn read_request(s: &mut TcpStream) -> Option<(String, Vec<u8>)> {
    let mut buf = Vec::new();
    let mut chunk = [0u8; 8192];
    let head_end = loop {
        let n = s.read(&mut chunk).ok()?;
        if n == 0 {
            return None;
        }
        buf.extend_from_slice(&chunk[..n]);
        if let Some(i) = buf.windows(4).position(|w| w == b"\r\n\r\n") {
            break i + 4;
        }
    };
    let head = String::from_utf8_lossy(&buf[..head_end]).to_string();
    let len = head
        .lines()
        .find_map(|l| {
            let (k, v) = l.split_once(':')?;
            k.eq_ignore_ascii_case("content-length")
                .then(|| v.trim().parse::<usize>().ok())?
        })
        .unwrap_or(0);
    while buf.len() < head_end + len {
        let n = s.read(&mut chunk).ok()?;
        if n == 0 {
            return None;
        }
        buf.extend_from_slice(&chunk[..n]);
    }
    Some((head, buf[head_end..head_end + len].to_vec()))
}

/// The schema a request carries, in whichever structured output mode: the
/// `json_schema.schema` of `response_format`, its `schema`, or the one written into the
/// system prompt.
pub fn request_schema(body: &Value) -> Option<Value> {
    let f = &body["response_format"];
    if f["json_schema"]["schema"].is_object() {
        return Some(f["json_schema"]["schema"].clone());
    }
    if f["schema"].is_object() {
        return Some(f["schema"].clone());
    }
    let system = body["messages"][0]["content"].as_str()?;
    let (_, text) = system.split_once("The JSON schema of the answer: ")?;
    serde_json::from_str(text.trim()).ok()
}

/// The task a request asks: the `json_schema` name, or else the one its schema implies.
pub fn task_name(body: &Value) -> String {
    if let Some(name) = body["response_format"]["json_schema"]["name"].as_str() {
        return name.to_string();
    }
    let Some(schema) = request_schema(body) else {
        return String::new();
    };
    let props = &schema["properties"];
    let name = if props["hazards"].is_object() {
        "hazard_inference"
    } else if props["steps"].is_object() {
        "move_plan"
    } else if props["wait_steps"].is_object() {
        "stop_observe_move_plan"
    } else if props["max_speed_kmh"].is_object() {
        "safety_constraints"
    } else {
        ""
    };
    name.to_string()
}

/// Starts a server on 127.0.0.1 answering each request with `reply(task name, request)`.
pub fn mock(reply: impl Fn(&str, &Value) -> Reply + Send + Sync + 'static) -> Mock {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap();
    let seen = Arc::new(Mutex::new(Vec::new()));
    let reply = Arc::new(reply);
    let log = seen.clone();
    std::thread::spawn(move || {
        for stream in listener.incoming() {
            let Ok(mut s) = stream else { continue };
            let reply = reply.clone();
            let log = log.clone();
            std::thread::spawn(move || {
                let Some((head, body)) = read_request(&mut s) else {
                    return;
                };
                let body: Value = serde_json::from_slice(&body).unwrap_or(Value::Null);
                let name = task_name(&body);
                log.lock().unwrap().push(Seen {
                    head,
                    body: body.clone(),
                });
                let (status, text, delay_ms) = reply(&name, &body);
                std::thread::sleep(Duration::from_millis(delay_ms));
                let resp = format!(
                    "HTTP/1.1 {status} X\r\nContent-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{text}",
                    text.len()
                );
                let _ = s.write_all(resp.as_bytes());
            });
        }
    });
    Mock { addr, seen }
}

/// A chat completion whose content is `content`.
pub fn completion(content: &str) -> String {
    json!({"id": "x", "object": "chat.completion",
           "choices": [{"index": 0, "message": {"role": "assistant", "content": content}, "finish_reason": "stop"}]})
    .to_string()
}
