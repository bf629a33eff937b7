//! Integration tests of fogline-sim: the "must show" list of issue 7.

#![allow(clippy::unwrap_used)]

mod bad_input;
mod closed_loop;
mod ramps;
mod scoring;
mod side_look;
mod sign_reader;

use fogline_sim::config::{BackendSetup, Config, RcoSetup};
use fogline_sim::experiment::ExperimentParams;
use fogline_sim::run::RunParams;
use fogline_sim::sense::{Daylight, DeficitKind, Weather};
use fogline_sim::suite::{RouteSpec, SuiteParams};
use fogline_sim::town::TownParams;

/// A small suite: one 3×3 town whose junctions are all signalised, `routes` routes of
/// `length_m` in clear noon light.
pub fn tiny_suite(routes: usize, length_m: f64) -> SuiteParams {
    SuiteParams {
        name: "tiny".into(),
        towns: 1,
        routes_per_town: routes,
        min_route_m: length_m,
        max_route_m: length_m,
        mean_route_m: length_m,
        town: TownParams {
            nx: 3,
            ny: 3,
            signal_share: 1.0,
            ..TownParams::default()
        },
        routes: (0..routes)
            .map(|_| RouteSpec {
                town: 0,
                length_m,
                weather: Weather::Cloudy,
                daylight: Daylight::Noon,
            })
            .collect(),
    }
}

/// An experiment on `suite` with `configs`.
pub fn experiment(suite: SuiteParams, configs: Vec<Config>, seed: u64) -> ExperimentParams {
    ExperimentParams {
        suite,
        seeds: vec![seed],
        configs,
        run: RunParams::default(),
        system_time_limit_s: 1800.0,
        llm_latency_ms: Some(1000.0),
        routes: None,
    }
}

/// The traffic-light deficit with the RCO take-over (rules backend).
pub fn tl_rco() -> Config {
    Config::with_rco(
        DeficitKind::TrafficLight,
        RcoSetup {
            backend: BackendSetup::Rules,
            ..RcoSetup::default()
        },
    )
}
