//! Both protocols: what goes in arrives, what comes back is checked, failures are named.

use std::io::{Read, Write};
use std::net::TcpListener;
use std::sync::Arc;
use std::thread;
use std::time::{Duration, Instant};

use fogline_remote::{FailureKind, ImageFormat, Planner};
use fogline_types::clip::{Decision, HISTORY};

use crate::*;

const SCENE: &str = "clip-000042";
const SEED: u64 = u64::MAX - 12_345;

#[test]
fn frames_calibration_history_and_ids_arrive_and_the_answer_comes_back() {
    for proto in BOTH {
        let fake = Fake::new(Behaviour::Straight);
        let server = start(proto, fake.clone());
        let c = client(
            proto,
            server.local_addr(),
            Duration::from_secs(20),
            ImageFormat::Png,
        );
        let clip = Clip::new(4);
        let out = c.plan(&clip.request(SCENE, SEED)).unwrap();

        // The answer.
        let expected = straight(SEED);
        assert_eq!(out.trajectory.xy.len(), 64);
        for (k, (a, b)) in out.trajectory.xy.iter().zip(&expected).enumerate() {
            close(a[0], b[0], 1e-4, &format!("{proto:?} x[{k}]"));
            close(a[1], b[1], 1e-4, &format!("{proto:?} y[{k}]"));
        }
        assert_eq!(out.explanation, EXPLANATION, "{proto:?}");
        assert_eq!(out.decision, Some(Decision::KeepLane), "{proto:?}");

        // What the planner saw.
        let seen = fake.last();
        assert_eq!(seen.scene_id, SCENE);
        assert_eq!(seen.seed, SEED);
        assert_eq!(seen.cameras.len(), 2);
        for (calib, frames) in &clip.cameras {
            let (got, got_frames) = seen
                .cameras
                .iter()
                .find(|c| c.0.id == calib.id)
                .unwrap_or_else(|| panic!("{proto:?}: {} missing", calib.id));
            assert_eq!((got.width, got.height), (calib.width, calib.height));
            for (what, a, b) in [
                ("fx", got.fx, calib.fx),
                ("fy", got.fy, calib.fy),
                ("cx", got.cx, calib.cx),
                ("cy", got.cy, calib.cy),
                ("x", got.x_m, calib.x_m),
                ("y", got.y_m, calib.y_m),
                ("z", got.z_m, calib.z_m),
                ("yaw", got.yaw_rad, calib.yaw_rad),
                ("pitch", got.pitch_rad, calib.pitch_rad),
            ] {
                close(a, b, 1e-5, &format!("{proto:?} {} {what}", calib.id));
            }
            assert_eq!(
                got_frames, frames,
                "{proto:?}: PNG frames must arrive exactly"
            );
        }
        assert_eq!(seen.history.len(), HISTORY);
        for (a, b) in seen.history.iter().zip(&clip.history) {
            close(a.t_s, b.t_s, 1e-6, "t_s");
            close(a.x_m, b.x_m, 1e-4, "x");
            close(a.y_m, b.y_m, 1e-4, "y");
            close(a.yaw_rad, b.yaw_rad, 1e-5, "yaw");
            close(a.speed_mps, b.speed_mps, 1e-5, "speed");
        }
        server.shutdown().unwrap();
    }
}

#[test]
fn jpeg_frames_arrive_close_to_the_originals() {
    for proto in BOTH {
        let fake = Fake::new(Behaviour::Straight);
        let server = start(proto, fake.clone());
        let c = client(
            proto,
            server.local_addr(),
            Duration::from_secs(20),
            ImageFormat::Jpeg { quality: 95 },
        );
        // Smooth frames (JPEG's case), one frame per camera.
        let mut clip = Clip::new(1);
        for (calib, frames) in &mut clip.cameras {
            let w = calib.width as usize;
            for f in frames.iter_mut() {
                for (i, px) in f.iter_mut().enumerate() {
                    let (x, y) = ((i / 3) % w, (i / 3) / w);
                    *px = (40 + 3 * x + 2 * y + 20 * (i % 3)) as u8;
                }
            }
        }
        c.plan(&clip.request(SCENE, 1)).unwrap();
        let seen = fake.last();
        for (calib, frames) in &clip.cameras {
            let got = &seen.cameras.iter().find(|c| c.0.id == calib.id).unwrap().1;
            assert_eq!(got.len(), 1);
            let mean_err = got[0]
                .iter()
                .zip(&frames[0])
                .map(|(a, b)| (f64::from(*a) - f64::from(*b)).abs())
                .sum::<f64>()
                / frames[0].len() as f64;
            assert!(
                mean_err < 4.0,
                "{proto:?} {}: mean error {mean_err}",
                calib.id
            );
        }
        server.shutdown().unwrap();
    }
}

fn failure_of(
    proto: Proto,
    behaviour: Behaviour,
    timeout: Duration,
) -> fogline_remote::PlanFailure {
    let server = start(proto, Fake::new(behaviour));
    let c = client(proto, server.local_addr(), timeout, ImageFormat::Png);
    let clip = Clip::new(2);
    let e = c.plan(&clip.request(SCENE, 7)).unwrap_err();
    server.shutdown().unwrap();
    e
}

#[test]
fn bad_answers_are_invalid_answers() {
    for proto in BOTH {
        let e = failure_of(proto, Behaviour::Nan, Duration::from_secs(20));
        assert_eq!(e.kind, FailureKind::InvalidAnswer, "{proto:?} NaN: {e}");
        let e = failure_of(proto, Behaviour::Short, Duration::from_secs(20));
        assert_eq!(
            e.kind,
            FailureKind::InvalidAnswer,
            "{proto:?} 10 waypoints: {e}"
        );
        let expected = match proto {
            Proto::Egodriver => "covers only 1.00 s of the 6.4 s horizon",
            Proto::Http => "10 waypoints, expected 64",
        };
        assert!(e.message.contains(expected), "{proto:?}: {e}");
    }
}

#[test]
fn a_slow_planner_is_a_timeout() {
    for proto in BOTH {
        let t = Instant::now();
        let e = failure_of(
            proto,
            Behaviour::Sleep(Duration::from_millis(1500)),
            Duration::from_millis(400),
        );
        assert_eq!(e.kind, FailureKind::Timeout, "{proto:?}: {e}");
        assert!(e.kind.retryable());
        // The client gave up at its limit; the server's shutdown let the planner finish.
        assert!(t.elapsed() < Duration::from_secs(8), "{proto:?}");
    }
}

#[test]
fn planner_errors_are_remote_errors_that_say_what_happened() {
    for proto in BOTH {
        for kind in [
            FailureKind::Remote,
            FailureKind::Input,
            FailureKind::Unavailable,
        ] {
            let e = failure_of(proto, Behaviour::Fail(kind), Duration::from_secs(20));
            assert_eq!(e.kind, FailureKind::Remote, "{proto:?} {kind:?}: {e}");
            assert!(e.message.contains("the model crashed"), "{proto:?}: {e}");
        }
        let e = failure_of(
            proto,
            Behaviour::Fail(FailureKind::Remote),
            Duration::from_secs(20),
        );
        match proto {
            Proto::Egodriver => assert!(e.message.contains("drive"), "{e}"),
            Proto::Http => assert!(e.message.contains("500"), "{e}"),
        }
    }
}

#[test]
fn a_closed_port_is_unavailable() {
    let port = TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap();
    // The listener is dropped: nothing listens there now.
    for proto in BOTH {
        let c = client(proto, port, Duration::from_secs(5), ImageFormat::Png);
        let clip = Clip::new(1);
        let t = Instant::now();
        let e = c.plan(&clip.request(SCENE, 1)).unwrap_err();
        assert_eq!(e.kind, FailureKind::Unavailable, "{proto:?}: {e}");
        assert!(t.elapsed() < Duration::from_secs(4), "{proto:?}");
    }
}

/// A TCP listener that answers every connection with `reply` (after reading a little)
/// and closes it.
fn rogue(reply: &'static [u8]) -> std::net::SocketAddr {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap();
    thread::spawn(move || {
        for stream in listener.incoming().take(16) {
            let Ok(mut s) = stream else { continue };
            let _ = s.set_read_timeout(Some(Duration::from_millis(200)));
            let mut buf = [0u8; 4096];
            let _ = s.read(&mut buf);
            let _ = s.write_all(reply);
            let _ = s.flush();
        }
    });
    addr
}

#[test]
fn garbage_or_a_dropped_connection_is_a_clean_failure() {
    let cases: [(&'static [u8], &str); 2] = [
        (
            b"HTTP/9 \x00\x01 this is not a protocol anyone speaks\r\n\r\n\xff\xfe",
            "garbage",
        ),
        (b"", "closed"),
    ];
    for (reply, what) in cases {
        for proto in BOTH {
            let addr = rogue(reply);
            let c = client(proto, addr, Duration::from_secs(10), ImageFormat::Png);
            let clip = Clip::new(1);
            let t = Instant::now();
            let e = c.plan(&clip.request(SCENE, 1)).unwrap_err();
            assert!(
                matches!(
                    e.kind,
                    FailureKind::InvalidAnswer | FailureKind::Unavailable
                ),
                "{proto:?} {what}: {e}"
            );
            assert!(
                t.elapsed() < Duration::from_secs(5),
                "{proto:?} {what}: took {:?}",
                t.elapsed()
            );
        }
    }
}

#[test]
fn many_threads_share_one_client() {
    for proto in BOTH {
        let fake = Fake::new(Behaviour::Straight);
        let server = start(proto, fake.clone());
        let c: Arc<dyn Planner> = client(
            proto,
            server.local_addr(),
            Duration::from_secs(30),
            ImageFormat::Png,
        )
        .into();
        let clip = Arc::new(Clip::new(4));
        let workers: Vec<_> = (0..4u64)
            .map(|w| {
                let c = Arc::clone(&c);
                let clip = Arc::clone(&clip);
                thread::spawn(move || {
                    for i in 0..3u64 {
                        let seed = w * 10 + i;
                        let out = c.plan(&clip.request("concurrent", seed)).unwrap();
                        let expected = straight(seed);
                        close(out.trajectory.xy[10][1], expected[10][1], 1e-5, "lateral");
                    }
                })
            })
            .collect();
        for w in workers {
            w.join().unwrap();
        }
        assert_eq!(fake.seen.lock().unwrap().len(), 12, "{proto:?}");
        server.shutdown().unwrap();
    }
}

#[test]
fn frames_that_do_not_match_their_calibration_are_input_errors() {
    for proto in BOTH {
        // Nothing listens: the request must fail before any connection.
        let c = client(
            proto,
            loopback_closed(),
            Duration::from_secs(5),
            ImageFormat::Png,
        );
        let mut clip = Clip::new(1);
        clip.cameras[0].1[0].pop();
        let e = c.plan(&clip.request(SCENE, 1)).unwrap_err();
        assert_eq!(e.kind, FailureKind::Input, "{proto:?}: {e}");
        assert!(!e.kind.retryable());
    }
}

fn loopback_closed() -> std::net::SocketAddr {
    TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
}

#[test]
fn clients_reconnect_after_the_server_restarts() {
    for proto in BOTH {
        let server = start(proto, Fake::new(Behaviour::Straight));
        let addr = server.local_addr();
        let c = client(proto, addr, Duration::from_secs(10), ImageFormat::Png);
        let clip = Clip::new(1);
        c.plan(&clip.request(SCENE, 1)).unwrap();
        server.shutdown().unwrap();
        let e = c.plan(&clip.request(SCENE, 1)).unwrap_err();
        assert_eq!(e.kind, FailureKind::Unavailable, "{proto:?}: {e}");

        // The same port again (the old listener is gone).
        let fake = Fake::new(Behaviour::Straight);
        let t = Instant::now();
        let again = loop {
            let served = match proto {
                Proto::Egodriver => fogline_remote::egodriver::serve(
                    addr,
                    fake.clone(),
                    fogline_remote::egodriver::ServeOptions::default(),
                ),
                Proto::Http => fogline_remote::http::serve(
                    addr,
                    fake.clone(),
                    fogline_remote::http::ServeOptions::default(),
                ),
            };
            match served {
                Ok(s) => break s,
                Err(e) if t.elapsed() < Duration::from_secs(10) => {
                    eprintln!("rebinding {addr}: {e}");
                    thread::sleep(Duration::from_millis(100));
                }
                Err(e) => panic!("cannot rebind {addr}: {e}"),
            }
        };
        let out = c.plan(&clip.request(SCENE, 2)).unwrap();
        assert_eq!(out.trajectory.xy.len(), 64);
        assert_eq!(fake.last().seed, 2);
        again.shutdown().unwrap();
    }
}
