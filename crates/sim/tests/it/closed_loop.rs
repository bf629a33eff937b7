//! The closed loop: deficits change the red-light behaviour, runs are deterministic and
//! independent of the thread count, outputs are written.

use std::sync::Arc;

use fogline_sim::config::Config;
use fogline_sim::experiment::{run_experiment, run_experiment_with};
use fogline_sim::output::write_all;
use fogline_sim::run::{RouteRecord, Termination};
use fogline_sim::sense::DeficitKind;
use fogline_types::clip::{HORIZON, PlannerOutput, Trajectory};
use fogline_types::planner::{FailureKind, PlanFailure, PlanRequest, Planner};

use super::{experiment, tiny_suite, tl_rco};

/// A record without what is measured on the wall clock (run times, the backend's measured
/// latency and the system time built from it).
fn comparable(r: &RouteRecord) -> serde_json::Value {
    let mut v = serde_json::to_value(r).unwrap();
    let o = v.as_object_mut().unwrap();
    o.remove("wall_s");
    o.remove("wall_parts_s");
    o.remove("system_time_s");
    if let Some(rco) = o.get_mut("rco").and_then(|x| x.as_object_mut()) {
        rco.remove("llm_latency_ms");
    }
    if let Some(tl) = o.get_mut("timeline").and_then(|x| x.as_array_mut()) {
        for p in tl {
            p.as_array_mut().unwrap().truncate(3);
        }
    }
    v
}

#[test]
fn same_seed_same_scores_whatever_the_thread_count() {
    let configs = vec![Config::no_deficit(), tl_rco()];
    let params = experiment(tiny_suite(2, 140.0), configs, 11);
    let a = run_experiment(&params, 1, &|_, _| {}).unwrap();
    let b = run_experiment(&params, 2, &|_, _| {}).unwrap();
    let c = run_experiment(&params, 2, &|_, _| {}).unwrap();
    assert_eq!(a.records.len(), 4);
    for ((x, y), z) in a.records.iter().zip(&b.records).zip(&c.records) {
        assert_eq!(comparable(x), comparable(y));
        assert_eq!(comparable(y), comparable(z));
    }
    assert_eq!(
        serde_json::to_value(&a.summary.configs[0].unlimited).unwrap(),
        serde_json::to_value(&b.summary.configs[0].unlimited).unwrap()
    );
    // Another seed draws other routes and traffic.
    let other = run_experiment(
        &experiment(tiny_suite(2, 140.0), vec![Config::no_deficit()], 12),
        2,
        &|_, _| {},
    )
    .unwrap();
    assert_ne!(comparable(&other.records[0]), comparable(&a.records[0]));
}

#[test]
fn a_traffic_light_deficit_changes_the_red_light_behaviour_and_rco_changes_it_again() {
    let configs = vec![
        Config::no_deficit(),
        Config::deficit(DeficitKind::TrafficLight),
        tl_rco(),
    ];
    let params = experiment(tiny_suite(2, 260.0), configs, 4);
    let results = run_experiment(&params, 0, &|_, _| {}).unwrap();
    let s = &results.summary;
    let none = s.config("no_deficit").unwrap();
    let tl = s.config("traffic_light/no_rco").unwrap();
    let rco = s.config("traffic_light/rco").unwrap();
    // The deficit is there (lights masked in the agent's frames) only in the deficit runs, and
    // the controller drives only with RCO.
    assert_eq!(none.deficit_share, 0.0);
    assert!(tl.deficit_share > 0.2 && rco.deficit_share > 0.2);
    assert_eq!(tl.takeover_share, 0.0);
    assert!(rco.takeover_share > 0.2);
    // The red-light behaviour (approaches reached, red encounters, stops at red,
    // infractions) differs in each configuration.
    let key = |c: &fogline_sim::experiment::ConfigSummary| {
        (c.signals, c.unlimited.avg_speed_mps.by_route.mean.to_bits())
    };
    assert_ne!(key(none), key(tl));
    assert_ne!(key(tl), key(rco));
    // Red lights are not scored under the traffic-light deficit.
    for r in results.records.iter().filter(|r| r.config != "no_deficit") {
        let reds = r
            .events
            .iter()
            .filter(|e| e.kind == fogline_sim::score::EventKind::RedLight)
            .count();
        let p = fogline_sim::score::ScoringParams {
            red_light: 1.0,
            ..Default::default()
        };
        assert_eq!(
            p.infraction_score(&r.events),
            r.score.infraction_score,
            "{reds}"
        );
    }
    // The outputs: JSON, records, tables and the report's document.
    let dir = tempfile::tempdir().unwrap();
    let w = write_all(&results, dir.path()).unwrap();
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&w.results).unwrap()).unwrap();
    assert_eq!(doc["kind"], "fogline.sim_results");
    assert_eq!(doc["records"].as_array().unwrap().len(), 6);
    let lines = std::fs::read_to_string(&w.records).unwrap();
    assert_eq!(lines.lines().count(), 6);
    let md = std::fs::read_to_string(&w.tables).unwrap();
    assert!(md.contains("Table 1") && md.contains("Table 2") && md.contains("Red-light"));
    // Each configuration's unstick firings are its records' own, and the runs table prints
    // them with the count per run.
    for c in &s.configs {
        let n: u64 = results
            .records
            .iter()
            .filter(|r| r.config == c.config)
            .map(|r| u64::from(r.unstick))
            .sum();
        assert_eq!(c.unstick, n, "{}", c.config);
        let cell = format!("| {n} ({:.2}) |", n as f64 / c.unlimited.runs as f64);
        assert!(
            md.lines()
                .any(|l| l.starts_with(&format!("| {} |", c.config)) && l.contains(&cell)),
            "{cell}"
        );
    }
    let cl: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&w.closed_loop).unwrap()).unwrap();
    assert_eq!(cl["configurations"].as_array().unwrap().len(), 3);
    assert!(cl["configurations"][0]["driving_score"].is_number());
}

#[test]
fn one_route_of_the_suite_and_the_baseline_alone() {
    // `routes` picks routes of the suite: the record is the one the whole suite gives.
    let all = experiment(tiny_suite(2, 140.0), vec![Config::no_deficit()], 11);
    let whole = run_experiment(&all, 2, &|_, _| {}).unwrap();
    let one = fogline_sim::experiment::ExperimentParams {
        routes: Some(vec![1]),
        ..all.clone()
    };
    let picked = run_experiment(&one, 1, &|_, _| {}).unwrap();
    assert_eq!(picked.records.len(), 1);
    assert_eq!(picked.records[0].route, 1);
    let same = whole.records.iter().find(|r| r.route == 1).unwrap();
    assert_eq!(comparable(&picked.records[0]), comparable(same));
    // Only the baseline ran: its table has one column, with figures in it.
    let md = fogline_sim::output::markdown(&picked);
    assert!(md.contains("| Experiment | Metric | All routes |"), "{md}");
    let rc = md
        .lines()
        .find_map(|l| l.strip_prefix("| No deficit | RC | "))
        .unwrap_or_else(|| panic!("{md}"));
    assert!(rc.starts_with(|c: char| c.is_ascii_digit()), "{md}");
    assert!(!md.contains("(no configuration of this table ran)"), "{md}");
    // No deficit run: their time is zero, not "-0.0".
    assert!(md.contains("with a deficit took 0.0 s"), "{md}");
    // A route the suite does not have is an error naming it.
    let bad = fogline_sim::experiment::ExperimentParams {
        routes: Some(vec![5]),
        ..all
    };
    let e = bad.validate().unwrap_err().to_string();
    assert!(e.contains("route 5") && e.contains("2 route(s)"), "{e}");
}

#[test]
fn the_override_sees_only_what_the_pixels_show() {
    use fogline_perturb::frame::Frame;
    use fogline_planner::detect::{LaneOf, ObjectSeen};
    use fogline_planner::perceive::{LeadSeen, ObjectKind};
    use fogline_sim::run::pixel_view;
    use fogline_types::clip::{CameraCalib, CameraId};

    // A grey 576×320 frame with one deficit drawn as the lens draws it (black, 2 px red
    // outline) and a red patch that is not one (a lamp-like blob, red inside).
    let (w, h) = (576usize, 320usize);
    let mut rgb = vec![118u8; w * h * 3];
    let mut paint = |x0: usize, y0: usize, x1: usize, y1: usize, ring: bool| {
        for y in y0..y1 {
            for x in x0..x1 {
                let edge = x < x0 + 2 || x >= x1 - 2 || y < y0 + 2 || y >= y1 - 2;
                let px = if !ring || edge {
                    [250, 10, 12]
                } else {
                    [0, 0, 0]
                };
                rgb[(y * w + x) * 3..(y * w + x) * 3 + 3].copy_from_slice(&px);
            }
        }
    };
    paint(300, 150, 330, 214, true);
    paint(100, 40, 112, 52, false);
    let frame = Frame::new(w as u32, h as u32, rgb).unwrap();
    let calib = CameraCalib::standard(CameraId::FrontWide, 576, 320);
    // One road user the agent's perception found in this camera, one in another camera.
    let seen = |camera| ObjectSeen {
        lane: LaneOf::Ego,
        seen: LeadSeen {
            contact_x: 12.0,
            gap: 8.3,
            speed: 0.0,
            speed_se: 0.0,
            lateral_speed: 0.0,
            braking: false,
            kind: ObjectKind::Vehicle,
            width_m: 1.8,
            right_edge: -0.9,
            left_edge: 0.9,
            confidence: 1.0,
            track: [Some(12.0), None, None, None],
        },
        camera,
        bbox: [250.0, 140.0, 330.0, 200.0],
    };
    let view = pixel_view(
        &calib,
        &frame,
        &[seen(CameraId::FrontWide), seen(CameraId::FrontTele)],
    );
    // The deficit is found from its pixels alone, the red blob is not a deficit...
    assert_eq!(view.deficits.len(), 1, "{:?}", view.deficits);
    let d = view.deficits[0];
    assert_eq!(
        (d.x_px, d.y_px, d.width_px, d.height_px),
        (300.0, 150.0, 30.0, 64.0)
    );
    // ...the objects are the perception's detections in this camera, without track ids
    // (nobody hands the override a tracker's identities), and the camera is calibrated.
    assert_eq!(view.objects.len(), 1);
    assert_eq!(view.objects[0].class, "car");
    assert_eq!(view.objects[0].track_id, None);
    assert_eq!(view.calib, Some(calib));
    assert_eq!(view.rgb.as_deref(), Some(frame.data()));
}

#[test]
fn the_override_can_only_make_the_agent_more_cautious() {
    use fogline_sim::run::supervise;
    use fogline_sim::vehicle::VehicleControl;
    let c = |throttle, brake, steer| VehicleControl {
        throttle,
        brake,
        steer,
    };
    // The agent brakes for the car ahead while the override would drive on: the agent wins.
    assert_eq!(
        supervise(c(0.0, 0.6, 0.1), c(0.7, 0.0, -0.3)),
        c(0.0, 0.6, 0.1)
    );
    // The override stops for a hidden walker while the agent would accelerate.
    assert_eq!(
        supervise(c(1.0, 0.0, 0.0), c(0.0, 0.8, 0.2)),
        c(0.0, 0.8, 0.0)
    );
    // Both drive: the lower throttle.
    assert_eq!(
        supervise(c(0.5, 0.0, 0.0), c(0.7, 0.0, 0.0)),
        c(0.5, 0.0, 0.0)
    );
}

/// A planner that always plans to stand still.
struct Frozen;

impl Planner for Frozen {
    fn describe(&self) -> String {
        "frozen".into()
    }
    fn plan(&self, _: &PlanRequest<'_>) -> Result<PlannerOutput, PlanFailure> {
        Ok(PlannerOutput {
            trajectory: Trajectory {
                xy: vec![[0.0, 0.0]; HORIZON],
            },
            explanation: "Stand still.".into(),
            decision: None,
        })
    }
}

/// A planner that cannot be reached.
struct Down;

impl Planner for Down {
    fn describe(&self) -> String {
        "down".into()
    }
    fn plan(&self, _: &PlanRequest<'_>) -> Result<PlannerOutput, PlanFailure> {
        Err(PlanFailure::new(
            FailureKind::Unavailable,
            "connection refused",
        ))
    }
}

#[test]
fn a_planner_under_test_drives_the_car() {
    let params = experiment(tiny_suite(1, 140.0), vec![Config::no_deficit()], 11);
    let run = |p: Arc<dyn Planner>| run_experiment_with(&params, Some(p), 1, &|_, _| {}).unwrap();
    // A planner that plans to stand keeps the car standing, whatever the baseline would do.
    let frozen = run(Arc::new(Frozen));
    let r = &frozen.records[0];
    assert!(r.odometer_m < 0.5 && r.plan_errors == 0, "{r:?}");
    assert_ne!(r.termination, Termination::Completed);
    // A planner that fails: the car brakes on every failed call, and the record counts them.
    let down = run(Arc::new(Down));
    let r = &down.records[0];
    assert!(r.plans > 0 && r.plan_errors == r.plans, "{r:?}");
    assert!(r.odometer_m < 0.5, "{r:?}");
    assert_eq!(down.driver, "down");
    assert!(fogline_sim::output::markdown(&down).contains("driven by down"));
    // The baseline drives the same route itself.
    let own = run_experiment(&params, 1, &|_, _| {}).unwrap();
    assert!(own.records[0].score.route_completion > 50.0);
    assert_eq!(own.driver, "the baseline's rules on the reference planner");
}
