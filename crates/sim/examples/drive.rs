//! Drives one route of a suite under one configuration and prints the record.
//!
//! `cargo run --release -p fogline-sim --example drive -- [quick|full] ROUTE CONFIG [WIDTH HEIGHT AGENT_HZ]`
//! with `RUST_LOG=fogline_sim=trace` for a line per second.
#![allow(clippy::print_stdout, clippy::unwrap_used)]

use fogline_sim::config::{BackendSetup, ConfigSet, configs};
use fogline_sim::run::{RunParams, run_route};
use fogline_sim::sense::DeficitKind;
use fogline_sim::suite::{Suite, SuiteParams};

fn main() {
    env_logger::init();
    let args: Vec<String> = std::env::args().collect();
    let suite = if args.get(1).map(String::as_str) == Some("full") {
        SuiteParams::longest6()
    } else {
        SuiteParams::quick()
    };
    let route: usize = args.get(2).map_or(0, |s| s.parse().unwrap());
    let name = args.get(3).cloned().unwrap_or_else(|| "no_deficit".into());
    let mut params = RunParams::default();
    if let Some(w) = args.get(4) {
        params.sensors.width = w.parse().unwrap();
        params.sensors.height = args[5].parse().unwrap();
        params.sensors.agent_hz = args[6].parse().unwrap();
    }
    let s = Suite::build(&suite, 0, params.traffic.events_per_km).unwrap();
    let all = configs(
        &[ConfigSet::Main, ConfigSet::Ablation, ConfigSet::Sweep],
        &DeficitKind::ALL,
        &BackendSetup::Rules,
    );
    let config = all.iter().find(|c| c.name == name).unwrap();
    let case = &s.cases[route];
    println!(
        "route {route}: town {} length {:.0} m, {} junctions ({:?}), {} events, {:?}/{:?}",
        case.town,
        case.route.length_m(),
        case.route.junctions.len(),
        case.route
            .junctions
            .iter()
            .map(|j| format!("{:?}{}", j.control, j.turn()))
            .collect::<Vec<_>>(),
        case.route.events.len(),
        case.weather,
        case.daylight
    );
    let r = run_route(&s.towns[case.town], case, config, &params, 0).unwrap();
    println!(
        "{}: RC {:.1} IS {:.3} DS {:.1} {:?} game {:.0} s AS {:.2} wall {:.2} s plans {} unstick {} deficit {:.0} s takeover {:.0} s",
        r.config,
        r.score.route_completion,
        r.score.infraction_score,
        r.score.driving_score,
        r.termination,
        r.game_time_s,
        r.avg_speed_mps,
        r.wall_s,
        r.plans,
        r.unstick,
        r.deficit_s,
        r.takeover_s
    );
    println!("signals {:?} wall parts {:?}", r.signals, r.wall_parts_s);
    for e in &r.events {
        println!(
            "  {:?} at {:.1} s ({:.0}, {:.0})",
            e.kind, e.t_s, e.x_m, e.y_m
        );
    }
    if let Some(st) = &r.rco {
        println!("rco {st:?}");
    }
}
