//! The labels agree with the world's ground truth on hand-built scenes.

use std::f64::consts::{FRAC_PI_2, PI};

use fogline_dataset::scene::{LightColor, ScenePlan, Target, Town, label, scene_of};
use fogline_rco::Strategy;
use fogline_rco::deficit_eval::{HiddenClass, MotionLabel};
use fogline_sim::sense::{Daylight, Weather};
use fogline_types::clip::{CameraCalib, CameraId};
use fogline_world::render::render;

fn town() -> Town {
    Town {
        seed: 5,
        lane_width_m: 3.5,
        left_lanes: 0,
        urban: true,
        weather: Weather::Cloudy,
        daylight: Daylight::Noon,
    }
}

fn plan(target: Target, ego_speed_mps: f64, stop_line_m: Option<f64>) -> ScenePlan {
    ScenePlan {
        town: town(),
        clip_seed: 9,
        ego_speed_mps,
        stop_line_m,
        target,
        others: Vec::new(),
    }
}

fn user(class: HiddenClass, x_m: f64, y_m: f64, heading_rad: f64, speed_mps: f64) -> Target {
    Target {
        class,
        x_m,
        y_m,
        heading_rad,
        speed_mps,
        light: None,
    }
}

#[test]
fn a_walker_crossing_ahead_is_stop_observe_move() {
    // 15 m ahead, on the right kerb, walking left across the ego lane at 1.3 m/s; the ego
    // drives at 6 m/s: the walker is in the path within the horizon.
    let p = plan(
        user(HiddenClass::Pedestrian, 15.0, -2.6, FRAC_PI_2, 1.3),
        6.0,
        None,
    );
    let l = label(&p);
    assert_eq!(l.class, HiddenClass::Pedestrian);
    assert_eq!(l.motion, MotionLabel::Crossing);
    assert_eq!(l.strategy, Strategy::StopObserveMove);
    assert!(
        l.rationale.strategy.contains("should stop"),
        "{}",
        l.rationale.strategy
    );
    assert!(
        l.rationale.motion.contains("left"),
        "{}",
        l.rationale.motion
    );
    // Ground truth: the rendered walker is in front of the ego in the front view at t = 0,
    // and it moved towards the image centre (leftwards in the image) over the five seconds.
    let calib = CameraCalib::standard(CameraId::FrontWide, 192, 144);
    let scene = scene_of(&p);
    let centre_x = |t: f64| {
        let v = render(&scene, &calib, t, false);
        let b = v
            .boxes
            .iter()
            .find(|b| b.track_id == Some(fogline_dataset::scene::TARGET_TRACK))
            .expect("the walker is visible");
        assert_eq!(b.class, "pedestrian");
        b.x_px + b.width_px / 2.0
    };
    assert!(
        centre_x(-2.0) > centre_x(0.0),
        "it crosses towards the left"
    );
}

#[test]
fn an_oncoming_cyclist_in_the_other_lane_is_move() {
    let t = town();
    let p = plan(
        user(HiddenClass::Bicycle, 25.0, t.oncoming_lane_m(), PI, 4.5),
        6.0,
        None,
    );
    let l = label(&p);
    assert_eq!(l.class, HiddenClass::Bicycle);
    assert_eq!(l.motion, MotionLabel::Oncoming);
    assert_eq!(l.strategy, Strategy::Move);
    assert!(
        l.rationale.strategy.contains("no reason"),
        "{}",
        l.rationale.strategy
    );
}

#[test]
fn the_same_cyclist_in_the_ego_lane_is_stop_observe_move() {
    // Head-on in the ego lane: the expert brakes (the label follows the geometry, not the
    // class or the motion name).
    let p = plan(user(HiddenClass::Bicycle, 25.0, 0.0, PI, 4.5), 6.0, None);
    assert_eq!(label(&p).strategy, Strategy::StopObserveMove);
    // A slow cyclist leading in the ego lane 12 m ahead is caught up with: brake.
    let p = plan(user(HiddenClass::Bicycle, 16.0, -0.8, 0.0, 2.0), 8.0, None);
    let l = label(&p);
    assert_eq!(
        (l.motion, l.strategy),
        (MotionLabel::Leading, Strategy::StopObserveMove)
    );
    // A walker standing on the sidewalk: move.
    let p = plan(
        user(HiddenClass::Pedestrian, 12.0, -4.0, 0.0, 0.0),
        6.0,
        None,
    );
    let l = label(&p);
    assert_eq!(
        (l.motion, l.strategy),
        (MotionLabel::Static, Strategy::Move)
    );
}

#[test]
fn lights_and_signs_follow_their_state_and_distance() {
    let light = |c: LightColor| Target {
        class: HiddenClass::TrafficLight,
        x_m: 15.5,
        y_m: -3.25,
        heading_rad: 0.0,
        speed_mps: 0.0,
        light: Some(c),
    };
    let red = label(&plan(light(LightColor::Red), 6.0, Some(15.0)));
    assert_eq!(
        (red.motion, red.strategy),
        (MotionLabel::Static, Strategy::StopObserveMove)
    );
    assert!(red.rationale.strategy.contains("red"));
    let green = label(&plan(light(LightColor::Green), 6.0, Some(15.0)));
    assert_eq!(green.strategy, Strategy::Move);
    let sign = Target {
        class: HiddenClass::TrafficSign,
        x_m: 12.4,
        y_m: -3.15,
        heading_rad: 0.0,
        speed_mps: 0.0,
        light: None,
    };
    assert_eq!(
        label(&plan(sign, 6.0, Some(12.0))).strategy,
        Strategy::StopObserveMove
    );
    // Standing at the line: it has stopped, it may go.
    let at_line = Target { x_m: 5.4, ..sign };
    assert_eq!(
        label(&plan(at_line, 0.0, Some(5.0))).strategy,
        Strategy::Move
    );
}
