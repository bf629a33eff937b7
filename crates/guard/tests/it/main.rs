//! The guard in front of a live egodriver driver on 127.0.0.1: hand-over and hand-back on
//! live frames, and mutated messages (the fuzz suite).

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)]

mod fuzz;
mod handback;

use std::io::Write;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex};

use fogline_guard::{GuardLog, GuardParams, GuardRecord};
use fogline_remote::{PlanFailure, PlanRequest, Planner, ServerHandle};
use fogline_types::clip::{CameraCalib, CameraId, Decision, HORIZON, PlannerOutput, Trajectory};
use fogline_types::odd::{AxisThreshold, OddEntry, OddSpec};

/// The driver: a straight trajectory at 5 m/s, whatever it sees.
pub(crate) struct Straight;

impl Planner for Straight {
    fn describe(&self) -> String {
        "straight test driver".into()
    }

    fn plan(&self, _request: &PlanRequest<'_>) -> Result<PlannerOutput, PlanFailure> {
        Ok(PlannerOutput {
            trajectory: Trajectory {
                xy: (1..=HORIZON).map(|k| [0.5 * k as f64, 0.0]).collect(),
            },
            explanation: "keep the lane".into(),
            decision: Some(Decision::KeepLane),
        })
    }
}

pub(crate) fn loopback() -> SocketAddr {
    "127.0.0.1:0".parse().unwrap()
}

/// The driver served over egodriver on a free loopback port.
pub(crate) fn driver() -> ServerHandle {
    fogline_remote::egodriver::serve(
        loopback(),
        Arc::new(Straight),
        fogline_remote::egodriver::ServeOptions::default(),
    )
    .unwrap()
}

fn threshold(axis: &str, sigma_star: f64, descending: bool, identity: f64) -> AxisThreshold {
    serde_json::from_value(serde_json::json!({
        "axis": axis,
        "family": if axis == "darken" || axis == "brighten" { "brightness" } else { axis },
        "descending": descending, "identity_level": identity, "levels": [],
        "sigma_star": sigma_star, "right_censored": false, "ci95": null,
        "threshold_group": "match",
    }))
    .unwrap()
}

/// An `odd.json` with one LANE_KEEPING entry: σ* 20, darken 0.4, brighten 1.6, fog 0.7.
pub(crate) fn odd() -> OddSpec {
    let mut odd = OddSpec::new(
        "test",
        "00",
        Some("gaussian_noise".into()),
        0.15,
        "first-violation",
    );
    odd.entries.push(OddEntry {
        scenario: "LANE_KEEPING".into(),
        rank: Some(1),
        n_clips: 40,
        n_changed: 9,
        pilot: false,
        axis: "gaussian_noise".into(),
        budget: 0.15,
        sigma_star: Some(20.0),
        right_censored: false,
        ci95: None,
        p_high: Some(0.2),
        threshold_group: "match".into(),
        severity_group: "mild".into(),
        quadrant: "match + mild".into(),
        accepted: None,
        acceptance_reason: None,
        thresholds: vec![
            threshold("gaussian_noise", 20.0, false, 0.0),
            threshold("darken", 0.4, true, 1.0),
            threshold("brighten", 1.6, false, 1.0),
            threshold("fog", 0.7, false, 0.0),
        ],
    });
    odd
}

/// A log kept in memory.
#[derive(Clone, Default)]
pub(crate) struct MemLog(Arc<Mutex<Vec<u8>>>);

impl Write for MemLog {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(buf);
        Ok(buf.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl MemLog {
    pub(crate) fn sink(&self) -> GuardLog {
        Arc::new(Mutex::new(Box::new(self.clone())))
    }

    pub(crate) fn records(&self) -> Vec<GuardRecord> {
        let text = String::from_utf8(self.0.lock().unwrap().clone()).unwrap();
        text.lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect()
    }
}

/// The guard on a free loopback port in front of `driver`, logging to `log`.
pub(crate) fn guard(driver: SocketAddr, log: &MemLog) -> ServerHandle {
    fogline_guard::guard(
        loopback(),
        odd(),
        GuardParams {
            driver: format!("http://{driver}"),
            scenario: "LANE_KEEPING".into(),
            driver_timeout_ms: 2_000,
            ..GuardParams::default()
        },
        Some(log.sink()),
    )
    .unwrap()
}

/// The front-wide camera at the world's default size.
pub(crate) fn front() -> CameraCalib {
    CameraCalib::standard(CameraId::FrontWide, 576, 320)
}

pub(crate) fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap()
}
