//! The generator: determinism, completeness, geometry of depth and boxes.

use fogline_types::clip::{CameraId, Decision, FRAMES, HISTORY, HORIZON};
use fogline_world::config::SCENARIOS;
use fogline_world::{ScenarioMix, WorldConfig, generate_clip};

fn small(mix: ScenarioMix) -> WorldConfig {
    WorldConfig {
        seed: 11,
        width: 192,
        height: 108,
        depth: true,
        mix,
    }
}

#[test]
fn same_seed_same_clip_other_index_other_clip() {
    let cfg = small(ScenarioMix::uniform(2));
    let a = generate_clip(&cfg, 3).unwrap();
    let b = generate_clip(&cfg, 3).unwrap();
    assert_eq!(a, b);
    let c = generate_clip(&cfg, 2).unwrap();
    assert_ne!(a.cameras[1].frames[3].image, c.cameras[1].frames[3].image);
    let other_seed = WorldConfig { seed: 12, ..cfg };
    let d = generate_clip(&other_seed, 3).unwrap();
    assert_ne!(a.ground_truth, d.ground_truth);
}

#[test]
fn every_scenario_renders_four_cameras_with_depth_boxes_and_a_future() {
    let cfg = small(ScenarioMix::uniform(1));
    for (i, s) in SCENARIOS.iter().enumerate() {
        let clip = generate_clip(&cfg, i).unwrap();
        assert_eq!(clip.scenario, *s);
        assert_eq!(clip.cameras.len(), 4);
        assert_eq!(clip.ego_history.len(), HISTORY);
        assert!(clip.ego_history[HISTORY - 1].x_m.abs() < 1e-12);
        clip.ground_truth.validate().unwrap();
        assert_eq!(clip.ground_truth.xy.len(), HORIZON);
        for cam in &clip.cameras {
            assert_eq!(cam.frames.len(), FRAMES);
            for f in &cam.frames {
                let depth = f.depth.as_ref().unwrap();
                let d = depth.depth_m();
                let w = cam.calib.width as usize;
                // Level cameras: the top row is sky (or a building), the bottom row is ground
                // a few metres away.
                let bottom = &d[d.len() - w..];
                assert!(
                    bottom
                        .iter()
                        .all(|v| v.is_finite() && *v > 1.0 && *v < 20.0),
                    "{s}"
                );
                assert!(d.iter().all(|v| !v.is_nan() && *v > 0.0));
                for b in &f.boxes {
                    b.validate(0, cam.calib.width, cam.calib.height).unwrap();
                }
            }
        }
        assert!(clip.scene.decision.is_some());
    }
}

#[test]
fn the_lead_vehicle_gets_a_box_in_the_front_cameras() {
    let cfg = small(ScenarioMix::only("FOLLOW_VEHICLE", 4).unwrap());
    for i in 0..4 {
        let clip = generate_clip(&cfg, i).unwrap();
        assert!(matches!(
            clip.scene.decision,
            Some(Decision::FollowLead | Decision::SlowForLead)
        ));
        let tele = &clip.cameras[CameraId::FrontTele.index()];
        let last = &tele.frames[FRAMES - 1];
        let centre = f64::from(tele.calib.width) / 2.0;
        assert!(
            last.boxes.iter().any(|b| {
                (b.class == "car" || b.class == "truck")
                    && b.x_px <= centre
                    && b.x_px + b.width_px >= centre
            }),
            "clip {i}: {:?}",
            last.boxes
        );
    }
}

#[test]
fn bad_parameters_are_refused_with_their_name() {
    let mut cfg = small(ScenarioMix::uniform(1));
    cfg.width = 5000;
    let e = generate_clip(&cfg, 0).unwrap_err().to_string();
    assert!(e.contains("width") && e.contains("1920"), "{e}");
    let cfg = small(ScenarioMix::uniform(1));
    let e = generate_clip(&cfg, 8).unwrap_err().to_string();
    assert!(e.contains("index"), "{e}");
}
