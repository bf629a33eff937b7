//! The HTTP server's answers to requests a client library would not send.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::time::Duration;

use fogline_remote::http::{self, ServeOptions};

use crate::*;

/// Sends a raw HTTP/1.1 request and returns the status code and the body.
fn raw(addr: SocketAddr, method: &str, path: &str, body: &str) -> (u16, serde_json::Value) {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    write!(
        s,
        "{method} {path} HTTP/1.1\r\nHost: test\r\nContent-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{body}",
        body.len()
    )
    .unwrap();
    let mut text = String::new();
    s.read_to_string(&mut text).unwrap();
    let status: u16 = text[9..12].parse().unwrap();
    let body = text.split_once("\r\n\r\n").unwrap().1;
    (status, serde_json::from_str(body).unwrap())
}

#[test]
fn health_errors_and_status_codes() {
    let server = http::serve(
        loopback(),
        Fake::new(Behaviour::Straight),
        ServeOptions::default(),
    )
    .unwrap();
    let addr = server.local_addr();
    let (status, body) = raw(addr, "GET", "/v1/health", "");
    assert_eq!(status, 200);
    assert_eq!(body["status"], "ok");
    assert_eq!(body["planner"], "fake planner");

    let (status, body) = raw(addr, "POST", "/v1/plan", "{not json");
    assert_eq!(status, 400);
    assert!(
        body["error"].as_str().unwrap().contains("invalid request"),
        "{body}"
    );

    let (status, _) = raw(addr, "GET", "/v1/plan", "");
    assert_eq!(status, 405);
    let (status, _) = raw(addr, "GET", "/elsewhere", "");
    assert_eq!(status, 404);

    let unknown_camera = r#"{"scene_id":"s","seed":1,"cameras":[{"id":"camera_rear_tele_30fov",
        "calibration":{"width":2,"height":2,"fx":1,"fy":1,"cx":1,"cy":1,"x_m":0,"y_m":0,"z_m":1,"yaw_rad":0,"pitch_rad":0},
        "frames":[]}],"ego_history":[]}"#;
    let (status, body) = raw(addr, "POST", "/v1/plan", unknown_camera);
    assert_eq!(status, 400);
    assert!(
        body["error"]
            .as_str()
            .unwrap()
            .contains("camera_rear_tele_30fov"),
        "{body}"
    );

    let bad_frame = r#"{"scene_id":"s","seed":1,"cameras":[{"id":"front_wide",
        "calibration":{"width":2,"height":2,"fx":1,"fy":1,"cx":1,"cy":1,"x_m":0,"y_m":0,"z_m":1,"yaw_rad":0,"pitch_rad":0},
        "frames":[{"t_s":0,"image_format":"png","data":"aGVsbG8="}]}],"ego_history":[]}"#;
    let (status, body) = raw(addr, "POST", "/v1/plan", bad_frame);
    assert_eq!(status, 400);
    assert!(body["error"].as_str().unwrap().contains("frame"), "{body}");
    server.shutdown().unwrap();

    // A planner refusing its input is a 422 with the failure kind.
    let server = http::serve(
        loopback(),
        Fake::new(Behaviour::Fail(fogline_remote::FailureKind::Input)),
        ServeOptions::default(),
    )
    .unwrap();
    let no_cameras = r#"{"scene_id":"s","seed":1,"cameras":[],"ego_history":[]}"#;
    let (status, body) = raw(server.local_addr(), "POST", "/v1/plan", no_cameras);
    assert_eq!(status, 422);
    assert_eq!(body["kind"], "input");
    server.shutdown().unwrap();
}
