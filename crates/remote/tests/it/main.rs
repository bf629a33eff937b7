//! Loopback round trips of both protocols: a fake planner served, a client calling it.

#![allow(clippy::unwrap_used)]

mod egodriver_contract;
mod http_protocol;
mod round_trip;
mod tls;
mod tls_support;

use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use fogline_remote::{FailureKind, PlanFailure, PlanRequest, Planner, ServerHandle};
use fogline_types::clip::{
    CameraCalib, CameraId, CameraInput, Decision, EgoPose, HISTORY, HORIZON, PlannerInput,
    PlannerOutput, Trajectory,
};

/// What the fake planner does.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Behaviour {
    /// A straight trajectory at 5 m/s, offset laterally by `(seed % 100) · 1 cm`.
    Straight,
    /// Waypoint 5 is NaN.
    Nan,
    /// Ten waypoints only.
    Short,
    /// Sleeps this long, then answers straight.
    Sleep(Duration),
    /// Fails with this kind.
    Fail(FailureKind),
}

/// What the fake planner received.
#[derive(Debug, Clone)]
pub(crate) struct Seen {
    pub(crate) scene_id: String,
    pub(crate) seed: u64,
    pub(crate) cameras: Vec<(CameraCalib, Vec<Vec<u8>>)>,
    pub(crate) history: Vec<EgoPose>,
}

pub(crate) struct Fake {
    pub(crate) behaviour: Behaviour,
    pub(crate) seen: Mutex<Vec<Seen>>,
}

pub(crate) const EXPLANATION: &str = "Keep the lane: the road ahead is clear.";

impl Fake {
    pub(crate) fn new(behaviour: Behaviour) -> Arc<Self> {
        Arc::new(Self {
            behaviour,
            seen: Mutex::new(Vec::new()),
        })
    }

    pub(crate) fn last(&self) -> Seen {
        self.seen.lock().unwrap().last().cloned().unwrap()
    }
}

/// The straight answer for `seed`.
pub(crate) fn straight(seed: u64) -> Vec<[f64; 2]> {
    (1..=HORIZON)
        .map(|k| [0.5 * k as f64, (seed % 100) as f64 * 0.01])
        .collect()
}

impl Planner for Fake {
    fn describe(&self) -> String {
        "fake planner".into()
    }

    fn plan(&self, request: &PlanRequest<'_>) -> Result<PlannerOutput, PlanFailure> {
        self.seen.lock().unwrap().push(Seen {
            scene_id: request.scene_id.to_string(),
            seed: request.seed,
            cameras: request
                .input
                .cameras
                .iter()
                .map(|c| (c.calib, c.frames.iter().map(|f| f.to_vec()).collect()))
                .collect(),
            history: request.input.ego_history.to_vec(),
        });
        let mut xy = straight(request.seed);
        match self.behaviour {
            Behaviour::Straight => {}
            Behaviour::Nan => xy[5][1] = f64::NAN,
            Behaviour::Short => xy.truncate(10),
            Behaviour::Sleep(d) => std::thread::sleep(d),
            Behaviour::Fail(kind) => {
                return Err(PlanFailure::new(kind, "the model crashed on this input"));
            }
        }
        Ok(PlannerOutput {
            trajectory: Trajectory { xy },
            explanation: EXPLANATION.into(),
            decision: Some(Decision::KeepLane),
        })
    }
}

/// Which protocol.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Proto {
    Egodriver,
    Http,
}

pub(crate) const BOTH: [Proto; 2] = [Proto::Egodriver, Proto::Http];

pub(crate) fn loopback() -> SocketAddr {
    "127.0.0.1:0".parse().unwrap()
}

/// Serves `planner` over `proto` on a free loopback port.
pub(crate) fn start(proto: Proto, planner: Arc<dyn Planner>) -> ServerHandle {
    match proto {
        Proto::Egodriver => fogline_remote::egodriver::serve(
            loopback(),
            planner,
            fogline_remote::egodriver::ServeOptions::default(),
        )
        .unwrap(),
        Proto::Http => fogline_remote::http::serve(
            loopback(),
            planner,
            fogline_remote::http::ServeOptions::default(),
        )
        .unwrap(),
    }
}

/// A client of `proto` for `addr`.
pub(crate) fn client(
    proto: Proto,
    addr: SocketAddr,
    timeout: Duration,
    format: fogline_remote::ImageFormat,
) -> Box<dyn Planner> {
    match proto {
        Proto::Egodriver => Box::new(
            fogline_remote::egodriver::Client::new(fogline_remote::egodriver::ClientOptions {
                endpoint: addr.to_string(),
                timeout,
                image_format: format,
                ..Default::default()
            })
            .unwrap(),
        ),
        Proto::Http => Box::new(
            fogline_remote::http::Client::new(fogline_remote::http::ClientOptions {
                url: format!("http://{addr}"),
                timeout,
                image_format: format,
            })
            .unwrap(),
        ),
    }
}

/// A small two-camera clip with textured frames and a curving, accelerating history.
pub(crate) struct Clip {
    pub(crate) cameras: Vec<(CameraCalib, Vec<Vec<u8>>)>,
    pub(crate) history: Vec<EgoPose>,
}

impl Clip {
    pub(crate) fn new(frames: usize) -> Self {
        let mut front = CameraCalib::standard(CameraId::FrontWide, 48, 24);
        front.pitch_rad = 0.05;
        front.cx = 23.25;
        let mut left = CameraCalib::standard(CameraId::CrossLeft, 32, 20);
        left.x_m = 2.1;
        left.y_m = 0.4;
        left.z_m = 1.4;
        let cameras = [front, left]
            .into_iter()
            .enumerate()
            .map(|(c, calib)| {
                let n = calib.width as usize * calib.height as usize * 3;
                let frames = (0..frames)
                    .map(|j| {
                        (0..n)
                            .map(|i| ((i * 31 + j * 97 + c * 13) % 256) as u8)
                            .collect()
                    })
                    .collect();
                (calib, frames)
            })
            .collect();
        // Ending at the origin with yaw 0; a gentle left curve before it.
        let history = (0..HISTORY)
            .map(|i| {
                let t = -0.1 * (HISTORY - 1 - i) as f64;
                EgoPose {
                    t_s: t,
                    x_m: 6.0 * t,
                    y_m: 0.3 * t * t,
                    yaw_rad: -0.02 * t,
                    speed_mps: 6.0 + 0.5 * t,
                }
            })
            .collect();
        Self { cameras, history }
    }

    pub(crate) fn request<'a>(&'a self, scene_id: &'a str, seed: u64) -> PlanRequest<'a> {
        PlanRequest {
            scene_id,
            seed,
            input: PlannerInput {
                cameras: self
                    .cameras
                    .iter()
                    .map(|(calib, frames)| CameraInput {
                        calib: *calib,
                        frames: frames.iter().map(|f| f.as_slice()).collect(),
                    })
                    .collect(),
                ego_history: &self.history,
            },
        }
    }
}

/// Asserts `a` and `b` agree to `tol`.
pub(crate) fn close(a: f64, b: f64, tol: f64, what: &str) {
    assert!((a - b).abs() <= tol, "{what}: {a} vs {b}");
}
