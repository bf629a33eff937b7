//! The guard in front of a live egodriver driver on 127.0.0.1: hand-over and hand-back on
//! live frames, mutated messages (the fuzz suite), and a driver behind TLS.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::print_stdout)]

mod fuzz;
mod handback;
mod tls;
#[path = "../../../remote/tests/it/tls_support.rs"]
mod tls_support;

use std::net::SocketAddr;
use std::sync::Arc;

use fogline_guard::{GuardLog, GuardParams, GuardRecord, MemoryLog};
use fogline_remote::{PlanFailure, PlanRequest, Planner, ServerHandle};
use fogline_types::clip::{CameraCalib, CameraId, Decision, HORIZON, PlannerOutput, Trajectory};
use fogline_types::odd::OddSpec;

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

/// The guard crate's example `odd.json`: LANE_KEEPING, σ* 20, darken 0.4, brighten 1.6, fog 0.7.
pub(crate) fn odd() -> OddSpec {
    fogline_guard::example_odd("test")
}

/// The guard's log, kept in memory.
#[derive(Clone, Default)]
pub(crate) struct MemLog(MemoryLog);

impl MemLog {
    pub(crate) fn sink(&self) -> GuardLog {
        self.0.sink()
    }

    pub(crate) fn records(&self) -> Vec<GuardRecord> {
        let text = String::from_utf8(self.0.contents()).unwrap();
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
