//! `fogline guard`: a proxy in front of any egodriver driver that watches the cameras
//! against the envelope and drives in the driver's place while the car is out of it.
//!
//! The guard speaks AlpaSim's `egodriver.EgodriverService` contract on both sides
//! (simulator → guard → driver). Every call is forwarded to the driver; on the way, the
//! frames of one camera (the monitored one) step a [`fogline_monitor::Monitor`] against the
//! scenario's `odd.json` entry. At each `drive`:
//!
//! - **inside the envelope, the driver healthy**: the driver's answer is passed back as it is
//!   (source `driver`);
//! - **out of the envelope** (the monitor's decision, with its hysteresis and minimum dwell):
//!   the guard answers itself with the RCO's plan ([`fogline_rco::Rco`], rules backend)
//!   integrated with a kinematic bicycle over the horizon (source `override`). Noise,
//!   darkness and fog degrade the whole frame, so the RCO sees the monitored view as one
//!   frame-wide deficit region ([`takeover`]); the driver keeps receiving every frame, and
//!   the answer goes back to it when the monitor re-enters;
//! - **the driver fails** (an error, no answer within `driver_timeout_ms`, a lost
//!   connection) while the cameras are inside: a safe stop (constant deceleration along the
//!   current heading, source `safe_stop`); the driver is tried again after
//!   `fault_retry_calls` `drive` calls (its session re-opened). A driver fault is never an
//!   error of the guard's own calls.
//!
//! Every `drive` writes one [`GuardRecord`] (a JSON line) to the log, if one is set.
//!
//! ```no_run
//! use fogline_guard::{GuardParams, guard};
//! use fogline_types::odd::OddSpec;
//!
//! let odd = OddSpec::read("fogline-demo/odd.json".as_ref()).map_err(std::io::Error::other)?;
//! let params = GuardParams {
//!     driver: "http://127.0.0.1:50051".into(),
//!     scenario: "LANE_KEEPING".into(),
//!     ..GuardParams::default()
//! };
//! let handle = guard("127.0.0.1:50052".parse().unwrap(), odd, params, None)?;
//! println!("guarding on {}", handle.local_addr());
//! handle.wait_for_signal()?;
//! # Ok::<(), std::io::Error>(())
//! ```

use std::io::Write;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex};

use fogline_monitor::{MonitorParams, MonitorRecord};
use fogline_remote::{Limits, ServerHandle};
use fogline_types::odd::OddSpec;
use serde::{Deserialize, Serialize};

pub mod proxy;
pub mod session;
pub mod takeover;

pub use takeover::{TakeoverAnswer, VehicleParams};

/// Errors of the guard's setup.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum GuardError {
    /// A parameter is out of its range.
    #[error("invalid guard parameter {what}: expected {expected}")]
    Params {
        /// The parameter.
        what: &'static str,
        /// What it must be.
        expected: String,
    },
    /// The monitor refused the `odd.json` or the scenario.
    #[error("the monitor cannot watch scenario {scenario:?}")]
    Monitor {
        /// The scenario.
        scenario: String,
        /// Why.
        #[source]
        source: fogline_monitor::MonitorError,
    },
    /// The RCO refused its parameters.
    #[error("the RCO cannot start")]
    Rco(#[source] fogline_rco::RcoError),
}

/// Settings of [`guard`].
#[derive(Debug, Clone)]
pub struct GuardParams {
    /// The driver's address, `http://HOST:PORT` or `https://HOST[:PORT]` (TLS: Mozilla's
    /// roots and the process's CA certificate file, `--ca-cert`).
    pub driver: String,
    /// The scenario whose `odd.json` entry the monitor uses.
    pub scenario: String,
    /// The logical id of the monitored camera; default: the first declared camera whose id
    /// contains `front_wide`, else the first declared one.
    pub camera: Option<String>,
    /// The monitor's policy.
    pub monitor: MonitorParams,
    /// The longest wait for any driver call, ms.
    pub driver_timeout_ms: u64,
    /// After a driver fault, `drive` calls answered by the guard before the driver is tried
    /// again.
    pub fault_retry_calls: u64,
    /// The vehicle model and horizon of the guard's own answers.
    pub vehicle: VehicleParams,
    /// The server's limits (connections, timeouts, decoded pixels per frame).
    pub limits: Limits,
    /// A PEM file of CA certificates trusted, on top of Mozilla's roots, for an `https://`
    /// driver; `None`: the process default (`fogline_io::http::set_default_ca_cert`, what
    /// the CLI's `--ca-cert` sets).
    pub ca_cert: Option<std::path::PathBuf>,
}

impl Default for GuardParams {
    fn default() -> Self {
        Self {
            driver: "http://127.0.0.1:50051".into(),
            scenario: String::new(),
            camera: None,
            monitor: MonitorParams::default(),
            driver_timeout_ms: 1_000,
            fault_retry_calls: 10,
            vehicle: VehicleParams::default(),
            limits: Limits::default(),
            ca_cert: None,
        }
    }
}

impl GuardParams {
    /// Checks every field (and the monitor's and the vehicle's parameters).
    pub fn validate(&self) -> Result<(), GuardError> {
        let bad = |what: &'static str, expected: &str| GuardError::Params {
            what,
            expected: expected.to_string(),
        };
        if let Err(e) = fogline_remote::egodriver::endpoint_url(&self.driver) {
            return Err(bad(
                "driver",
                &format!("an address http://HOST:PORT or https://HOST[:PORT] ({e})"),
            ));
        }
        if self.scenario.is_empty() {
            return Err(bad("scenario", "a scenario of the odd.json"));
        }
        if self.driver_timeout_ms == 0 {
            return Err(bad("driver_timeout_ms", "at least 1 ms"));
        }
        if self.fault_retry_calls == 0 {
            return Err(bad("fault_retry_calls", "at least 1 call"));
        }
        self.monitor
            .validate()
            .map_err(|e| bad("monitor", &e.to_string()))?;
        self.vehicle.validate()?;
        self.limits.validate().map_err(|e| bad("limits", &e))
    }
}

/// One `drive` call as the guard answered it: a row of the JSON-lines log.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GuardRecord {
    /// The session.
    pub session: String,
    /// `drive` calls before this one in the session.
    pub call: u64,
    /// The call's `time_now_us`.
    pub time_now_us: u64,
    /// Who answered: `driver`, `override` (the RCO, out of the envelope), `safe_stop` (the
    /// driver failed while inside) or `refused` (the driver refused the message: its gRPC
    /// error was passed back).
    pub source: String,
    /// Why the guard answered (the monitor's reason, the driver's fault), or null.
    pub reason: Option<String>,
    /// The monitor's decision before this call (true before any frame).
    pub in_envelope: bool,
    /// The driver's answer time, ms (null when it was not asked or did not answer).
    pub driver_ms: Option<f64>,
    /// The guard's own answer (null when the driver answered).
    pub takeover: Option<TakeoverAnswer>,
    /// The monitor's latest record (null before the first monitored frame).
    pub monitor: Option<MonitorRecord>,
}

/// Where the guard writes its records.
pub type GuardLog = Arc<Mutex<Box<dyn Write + Send>>>;

/// Starts the guard on `addr` (port 0 picks a free port) in front of `params.driver`,
/// watching `params.scenario` of `odd`; records go to `log` as JSON lines. The socket is
/// bound before this returns; the driver need not be up yet (it is connected lazily).
pub fn guard(
    addr: SocketAddr,
    odd: OddSpec,
    params: GuardParams,
    log: Option<GuardLog>,
) -> std::io::Result<ServerHandle> {
    params.validate().map_err(std::io::Error::other)?;
    let limits = params.limits.clone();
    let service = proxy::Guard::new(odd, params, log).map_err(std::io::Error::other)?;
    let describe = service.describe();
    fogline_remote::egodriver::serve_contract(addr, service, &limits, &describe)
}

/// A one-entry `odd.json` for examples, tests and `fogline bench guard`: LANE_KEEPING with
/// σ* 20, darken 0.4, brighten 1.6 and fog 0.7 (`generated_by` names who made it).
pub fn example_odd(generated_by: &str) -> fogline_types::odd::OddSpec {
    use fogline_types::odd::{AxisThreshold, OddEntry, OddSpec};
    let threshold = |axis: &str, limit: f64, descending: bool, identity: f64| AxisThreshold {
        axis: axis.into(),
        family: if axis == "darken" || axis == "brighten" {
            "brightness".into()
        } else {
            axis.into()
        },
        descending,
        identity_level: identity,
        levels: Vec::new(),
        sigma_star: Some(limit),
        right_censored: false,
        ci95: None,
        threshold_group: "match".into(),
    };
    let mut odd = OddSpec::new(
        generated_by,
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

/// A [`GuardLog`] kept in memory, for the benchmark and the tests to read back.
#[derive(Clone, Default)]
pub struct MemoryLog(Arc<Mutex<Vec<u8>>>);

impl Write for MemoryLog {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .extend_from_slice(buf);
        Ok(buf.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl MemoryLog {
    /// The log to hand to the guard.
    pub fn sink(&self) -> GuardLog {
        Arc::new(Mutex::new(Box::new(self.clone())))
    }

    /// What was written so far.
    pub fn contents(&self) -> Vec<u8> {
        self.0
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .clone()
    }
}
