//! Closed-loop evaluation: the experiments of the LLM-RCO paper (sections 6–7) on fogline's
//! own world — a Longest6-like route suite through procedural towns, a camera-driven
//! baseline agent driving from rendered frames, perception deficits (traffic lights, stop
//! signs, pedestrians, bicycles masked whenever visible), the LLM-RCO take-over while a
//! deficit is present, and CARLA Leaderboard 1.0 scores.
//!
//! Use it to measure how a deficit changes a camera-driven agent's driving and what the
//! RCO controller does about it, per configuration: tables shaped like the paper's tables
//! 1–3 and figure 8, and one record per route run.
//!
//! - [`score`]: Leaderboard 1.0 scoring and every criterion (route completion, infractions,
//!   blocked, route deviation, timeout, game- and system-time limits).
//! - [`vehicle`]: the kinematic bicycle model tuned for CARLA, 20 Hz.
//! - [`town`], [`route`], [`suite`]: towns, routes, the suite (and suite files).
//! - [`traffic`]: rule-obeying vehicles, pedestrians and cyclists, crossing events.
//! - [`sense`]: the scene around the ego for the renderer, weather, daylight, deficits.
//! - [`agent`]: the baseline (reference planner + PID + pure pursuit + unstick rule).
//! - [`run`]: one route under one configuration, the closed loop at 20 Hz.
//! - [`config`], [`experiment`], [`output`]: configurations, parallel runs, tables, files.
//! - [`compare`]: two sets of runs compared configuration by configuration (`fogline sim
//!   compare`).
//!
//! ```
//! use fogline_sim::score::{Event, EventKind, RouteScore, ScoringParams};
//!
//! // A completed route with one vehicle collision and one red light (a golden case of the
//! // leaderboard reference): IS = 0.60 · 0.70 = 0.42, DS = 42.
//! let e = [
//!     Event::new(EventKind::CollisionVehicle, 10.0, 0.0, 0.0),
//!     Event::new(EventKind::RedLight, 20.0, 5.0, 0.0),
//! ];
//! let s = RouteScore::of(100.0, &e, &ScoringParams::default());
//! assert!((s.driving_score - 42.0).abs() < 1e-9);
//! ```
//!
//! A whole experiment (the quick suite, every main configuration; about 30 s in release
//! builds on two cores):
//!
//! ```no_run
//! use fogline_sim::config::{BackendSetup, ConfigSet, configs};
//! use fogline_sim::experiment::{ExperimentParams, run_experiment};
//! use fogline_sim::run::RunParams;
//! use fogline_sim::sense::DeficitKind;
//! use fogline_sim::suite::SuiteParams;
//!
//! let params = ExperimentParams {
//!     suite: SuiteParams::quick(),
//!     seeds: vec![0],
//!     configs: configs(&[ConfigSet::Main], &DeficitKind::ALL, &BackendSetup::Rules),
//!     run: RunParams::default(),
//!     system_time_limit_s: 1800.0,
//!     llm_latency_ms: Some(1000.0),
//!     routes: None,
//! };
//! let results = run_experiment(&params, 0, &|_, _| {})?;
//! print!("{}", fogline_sim::output::markdown(&results));
//! # Ok::<(), fogline_sim::SimError>(())
//! ```

pub mod agent;
pub mod compare;
pub mod config;
pub mod experiment;
pub mod geom;
pub mod output;
pub mod ramp;
pub mod route;
pub mod run;
pub mod score;
pub mod sense;
pub mod suite;
pub mod town;
pub mod traffic;
pub mod vehicle;

/// Errors of the closed-loop simulator.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SimError {
    /// A setting is invalid.
    #[error("invalid parameters: {0}")]
    Params(String),
    /// A suite file is invalid.
    #[error("suite file {file}: {message}")]
    Suite {
        /// The file.
        file: String,
        /// What is wrong.
        message: String,
    },
    /// The RCO controller cannot be set up.
    #[error("rco: {0}")]
    Rco(String),
    /// Reading a file failed.
    #[error("cannot read {path}")]
    Read {
        /// The file.
        path: String,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
    /// A records file (`records.jsonl`) has a line that is not a run record.
    #[error("records file {file}, line {line}: {message}")]
    Records {
        /// The file.
        file: String,
        /// The line, from 1.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// Writing results failed.
    #[error("cannot write {path}")]
    Io {
        /// The file.
        path: String,
        /// The cause.
        #[source]
        source: std::io::Error,
    },
}
