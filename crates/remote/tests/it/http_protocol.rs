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

fn png_b64(width: u32, height: u32) -> String {
    use base64::Engine as _;
    let img = image::RgbImage::from_pixel(width, height, image::Rgb([90, 90, 90]));
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png).unwrap();
    base64::engine::general_purpose::STANDARD.encode(out.into_inner())
}

fn one_frame_request(width: u32, height: u32, frames: usize, png: &str) -> String {
    let frames: Vec<String> = (0..frames)
        .map(|j| format!(r#"{{"t_s":-{j}.0,"image_format":"png","data":"{png}"}}"#))
        .collect();
    format!(
        r#"{{"scene_id":"s","seed":1,"cameras":[{{"id":"front_wide",
        "calibration":{{"width":{width},"height":{height},"fx":100,"fy":100,"cx":{cx},"cy":{cy},"x_m":0,"y_m":0,"z_m":1.5,"yaw_rad":0,"pitch_rad":0}},
        "frames":[{}]}}],"ego_history":[]}}"#,
        frames.join(","),
        cx = width / 2,
        cy = height / 2
    )
}

/// CRC-32 (IEEE), as PNG chunks carry it.
fn crc32(bytes: &[u8]) -> u32 {
    let mut c = 0xFFFF_FFFFu32;
    for &b in bytes {
        c ^= u32::from(b);
        for _ in 0..8 {
            c = if c & 1 == 1 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

#[test]
fn pixels_are_bounded_before_anything_is_decoded() {
    let limits = fogline_remote::Limits {
        max_request_pixels: 1_000_000,
        ..fogline_remote::Limits::default()
    };
    let server = http::serve(
        loopback(),
        Fake::new(Behaviour::Straight),
        ServeOptions {
            limits,
            ..ServeOptions::default()
        },
    )
    .unwrap();
    let addr = server.local_addr();
    // Four 600 × 600 frames declared: 1.44 M pixels, over the cap of 1 M → 413, unread.
    let small = png_b64(4, 4);
    let (status, body) = raw(
        addr,
        "POST",
        "/v1/plan",
        &one_frame_request(600, 600, 4, &small),
    );
    assert_eq!(status, 413, "{body}");
    let e = body["error"].as_str().unwrap();
    assert!(e.contains("1440000 pixels") && e.contains("1000000"), "{e}");
    // A frame whose header claims 12000 × 12000 in a request declaring 400 × 400: refused
    // from the header, before its 432 MB are allocated.
    let huge = {
        use base64::Engine as _;
        use image::ImageEncoder as _;
        let mut png = Vec::new();
        image::codecs::png::PngEncoder::new(&mut png)
            .write_image(
                &vec![0u8; 12000 * 3],
                12000,
                1,
                image::ExtendedColorType::Rgb8,
            )
            .unwrap();
        // Patch the IHDR height (bytes 20..24) to 12000, with the chunk's CRC: the header
        // alone says 12000².
        png[20..24].copy_from_slice(&12000u32.to_be_bytes());
        let crc = crc32(&png[12..29]);
        png[29..33].copy_from_slice(&crc.to_be_bytes());
        base64::engine::general_purpose::STANDARD.encode(png)
    };
    let (status, body) = raw(
        addr,
        "POST",
        "/v1/plan",
        &one_frame_request(400, 400, 1, &huge),
    );
    assert_eq!(status, 400, "{body}");
    let e = body["error"].as_str().unwrap();
    assert!(
        e.contains("12000x12000 but the calibration says 400x400"),
        "{e}"
    );
    // Within the caps it plans.
    let (status, body) = raw(
        addr,
        "POST",
        "/v1/plan",
        &one_frame_request(400, 400, 4, &png_b64(400, 400)),
    );
    assert_ne!(status, 413, "{body}");
    server.shutdown().unwrap();
}

#[test]
fn idle_and_half_sent_connections_are_closed_and_excess_ones_shed() {
    let limits = fogline_remote::Limits {
        max_connections: 8,
        idle_timeout: Duration::from_millis(300),
        header_timeout: Duration::from_millis(300),
        ..fogline_remote::Limits::default()
    };
    let server = http::serve(
        loopback(),
        Fake::new(Behaviour::Straight),
        ServeOptions {
            limits,
            ..ServeOptions::default()
        },
    )
    .unwrap();
    let addr = server.local_addr();
    let closed_within = |s: &mut TcpStream, d: Duration| {
        s.set_read_timeout(Some(d)).unwrap();
        let mut buf = [0u8; 512];
        // EOF or a reset: the server closed it; a timeout: still open.
        !matches!(s.read(&mut buf), Err(e) if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut))
    };
    // Eight connections fill the server: silent ones and ones with half a header.
    let mut held: Vec<TcpStream> = (0..8)
        .map(|i| {
            let mut s = TcpStream::connect(addr).unwrap();
            if i % 2 == 1 {
                s.write_all(b"GET /v1/health HTTP/1.1\r\nHo").unwrap();
            }
            s
        })
        .collect();
    std::thread::sleep(Duration::from_millis(100));
    // A ninth is closed as it arrives.
    let mut ninth = TcpStream::connect(addr).unwrap();
    assert!(
        closed_within(&mut ninth, Duration::from_secs(2)),
        "the ninth was kept"
    );
    // The held ones are closed once idle, and then the server answers again.
    for (i, s) in held.iter_mut().enumerate() {
        assert!(
            closed_within(s, Duration::from_secs(5)),
            "connection {i} was kept open"
        );
    }
    let (status, _) = raw(addr, "GET", "/v1/health", "");
    assert_eq!(status, 200);
    server.shutdown().unwrap();
}

#[test]
fn mutated_requests_get_an_answer_and_leave_the_server_serving() {
    // A valid plan request mutated 300 times (bytes flipped, inserted, deleted, cut): each
    // gets an HTTP answer (200 or a 4xx naming the problem), never a dropped connection.
    let server = http::serve(
        loopback(),
        Fake::new(Behaviour::Straight),
        ServeOptions::default(),
    )
    .unwrap();
    let addr = server.local_addr();
    let valid = one_frame_request(64, 48, 2, &png_b64(64, 48));
    let mut state = 0xF0661E_u64;
    let mut next = || {
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    };
    let mut statuses = std::collections::BTreeMap::new();
    for i in 0..300 {
        let mut body = valid.clone().into_bytes();
        for _ in 0..1 + next() % 3 {
            let at = (next() as usize) % (body.len() + 1);
            match next() % 4 {
                0 if !body.is_empty() => {
                    let k = at.min(body.len() - 1);
                    body[k] = next() as u8;
                }
                1 => body.insert(at, b"{}[],:\"0e9-"[(next() % 11) as usize]),
                2 => {
                    let end = (at + 1 + (next() as usize) % 40).min(body.len());
                    body.drain(at.min(end)..end);
                }
                _ => body.truncate(at),
            }
        }
        let mut s = TcpStream::connect(addr).unwrap();
        s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
        write!(
            s,
            "POST /v1/plan HTTP/1.1\r\nHost: t\r\nContent-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
            body.len()
        )
        .unwrap();
        s.write_all(&body).unwrap();
        let mut reply = Vec::new();
        s.read_to_end(&mut reply).unwrap();
        let text = String::from_utf8_lossy(&reply);
        let status: u16 = text
            .get(9..12)
            .and_then(|c| c.parse().ok())
            .unwrap_or_else(|| panic!("mutant {i}: no HTTP answer: {text:?}"));
        assert!(
            status == 200 || (400..500).contains(&status),
            "mutant {i}: {status}"
        );
        *statuses.entry(status).or_insert(0) += 1;
    }
    assert!(statuses.len() >= 2, "{statuses:?}");
    let (status, _) = raw(addr, "GET", "/v1/health", "");
    assert_eq!(status, 200);
    server.shutdown().unwrap();
}
