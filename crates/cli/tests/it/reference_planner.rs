//! The reference planner on clips from the world: accurate on clean clips, worse under
//! noise, and unable to see anything but pixels (the crate graph is checked in
//! `architecture.rs`).

use fogline_perturb::frame::{Frame, FrameKey};
use fogline_perturb::perturbation::{FrameInput, Perturbation};
use fogline_planner::ReferencePlanner;
use fogline_types::clip::{CameraInput, PlannerInput};
use fogline_world::{Clip, ScenarioMix, WorldConfig, generate_clip};

struct Outcome {
    agree: bool,
    ade: f64,
    explanation: String,
}

/// The planner's input: `frames` (one list per camera of `clip`) and the clip's history.
fn input<'a>(clip: &'a Clip, frames: &'a [Vec<Frame>]) -> PlannerInput<'a> {
    let cameras = clip
        .cameras
        .iter()
        .zip(frames)
        .map(|(c, fs)| CameraInput {
            calib: c.calib,
            frames: fs.iter().map(Frame::data).collect(),
        })
        .collect();
    PlannerInput {
        cameras,
        ego_history: &clip.ego_history,
    }
}

fn run(clip: &Clip, frames: &[Vec<Frame>]) -> Outcome {
    let out = ReferencePlanner::new().plan(&input(clip, frames)).unwrap();
    Outcome {
        agree: out.decision == clip.scene.decision,
        ade: out.trajectory.ade(&clip.ground_truth),
        explanation: out.explanation,
    }
}

fn frames(clip: &Clip, index: usize, condition: &str) -> Vec<Vec<Frame>> {
    if condition == "clean" {
        return clip
            .cameras
            .iter()
            .map(|c| c.frames.iter().map(|f| f.image.clone()).collect())
            .collect();
    }
    let prepared = Perturbation::parse(condition).unwrap().prepare(5).unwrap();
    clip.cameras
        .iter()
        .enumerate()
        .map(|(c, cam)| {
            cam.frames
                .iter()
                .enumerate()
                .map(|(k, f)| {
                    let key = FrameKey::new(index as u64, c as u64, k as u64);
                    prepared
                        .apply(&FrameInput::new(&f.image, key))
                        .unwrap()
                        .frame
                })
                .collect()
        })
        .collect()
}

#[test]
fn clean_clips_are_driven_like_the_expert_and_noise_degrades_the_planner() {
    let config = WorldConfig {
        seed: 3,
        depth: false,
        mix: ScenarioMix::paper_scaled(40),
        ..WorldConfig::default()
    };
    let mut clean = Vec::new();
    let mut noisy = Vec::new();
    for i in 0..config.mix.total() {
        let clip = generate_clip(&config, i).unwrap();
        clean.push(run(&clip, &frames(&clip, i, "clean")));
        noisy.push(run(&clip, &frames(&clip, i, "noise_70")));
    }
    let share = |v: &[Outcome]| v.iter().filter(|o| o.agree).count() as f64 / v.len() as f64;
    let median = |v: &[Outcome]| {
        let mut a: Vec<f64> = v.iter().map(|o| o.ade).collect();
        a.sort_by(f64::total_cmp);
        a[a.len() / 2]
    };
    // Measured on 1,996 clips: 96 % agreement; 40 clips leave room for sampling error.
    assert!(share(&clean) >= 0.85, "clean agreement {}", share(&clean));
    assert!(median(&clean) <= 2.5, "clean median ADE {}", median(&clean));
    assert!(
        share(&noisy) < share(&clean),
        "noise_70 agreement {} vs clean {}",
        share(&noisy),
        share(&clean)
    );
    let changed = clean
        .iter()
        .zip(&noisy)
        .filter(|(a, b)| a.explanation != b.explanation)
        .count();
    assert!(
        changed >= 4,
        "explanations changed on {changed} of 40 clips"
    );
}

#[test]
fn the_planner_is_deterministic_and_rejects_malformed_input() {
    let config = WorldConfig {
        seed: 9,
        depth: false,
        mix: ScenarioMix::uniform(1),
        ..WorldConfig::default()
    };
    let clip = generate_clip(&config, 2).unwrap();
    let f = frames(&clip, 2, "noise_30");
    let a = run(&clip, &f);
    let b = run(&clip, &f);
    assert_eq!(a.explanation, b.explanation);
    assert_eq!(a.ade, b.ade);
    // A frame of the wrong size is named in the error.
    let bad = [0u8; 12];
    let mut cameras: Vec<CameraInput> = clip
        .cameras
        .iter()
        .map(|c| CameraInput {
            calib: c.calib,
            frames: c.frames.iter().map(|f| f.image.data()).collect(),
        })
        .collect();
    cameras[1].frames[0] = &bad;
    let input = PlannerInput {
        cameras,
        ego_history: &clip.ego_history,
    };
    let e = ReferencePlanner::new()
        .plan(&input)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("camera_front_wide_120fov frame 0") && e.contains("expected"),
        "{e}"
    );
}

/// The perception measures the frames' noise from the pixels and loses its cues gradually:
/// noise the stack was not told about costs a few decisions at σ 30, not most of them.
#[test]
fn perception_measures_the_noise_and_degrades_gradually() {
    let config = WorldConfig {
        seed: 11,
        depth: false,
        mix: ScenarioMix::paper_scaled(40),
        ..WorldConfig::default()
    };
    let planner = ReferencePlanner::new();
    let conditions = ["clean", "noise_30", "noise_70"];
    let mut agree = [0usize; 3];
    let mut sigma = [Vec::new(), Vec::new(), Vec::new()];
    let n = config.mix.total();
    for i in 0..n {
        let clip = generate_clip(&config, i).unwrap();
        for (k, cond) in conditions.iter().enumerate() {
            let fs = frames(&clip, i, cond);
            let (p, plan) = planner.plan_with_perception(&input(&clip, &fs)).unwrap();
            agree[k] += usize::from(Some(plan.decision) == clip.scene.decision);
            sigma[k].push(p.quality.noise_sigma);
        }
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    // Clean renders have no noise; σ 30 reads as ~30; σ 70 reads lower than 70 (clipping
    // at 0 and 255 censors it) but far above σ 30.
    assert!(mean(&sigma[0]) < 1.0, "clean σ̂ {}", mean(&sigma[0]));
    assert!(
        (mean(&sigma[1]) - 30.0).abs() < 3.0,
        "noise_30 σ̂ {}",
        mean(&sigma[1])
    );
    assert!(mean(&sigma[2]) > 45.0, "noise_70 σ̂ {}", mean(&sigma[2]));
    let share = |k: usize| agree[k] as f64 / n as f64;
    // Measured on 1,996 clips (docs/world.md): 96 % clean, 95 % at σ 30, 83 % at σ 70.
    assert!(share(0) >= 0.85, "clean {}", share(0));
    assert!(
        share(1) >= share(0) - 0.1,
        "noise_30 {} vs clean {}",
        share(1),
        share(0)
    );
    assert!(share(2) >= 0.55, "noise_70 {}", share(2));
    assert!(
        share(2) <= share(1),
        "noise_70 {} vs noise_30 {}",
        share(2),
        share(1)
    );
}

/// The far edge of a T-junction is a step in the colour of the whole road; noise that
/// hides it from the fine bins does not hide it from the road pooled over metres and
/// frames, and a vehicle ahead (with a road on its right or not) is not taken for it.
#[test]
fn a_t_junction_is_seen_through_noise_and_a_lead_is_not_taken_for_one() {
    let planner = ReferencePlanner::new();
    let turn = WorldConfig {
        seed: 23,
        depth: false,
        mix: ScenarioMix::only("TURN_RIGHT", 10).unwrap(),
        ..WorldConfig::default()
    };
    let follow = WorldConfig {
        mix: ScenarioMix::only("FOLLOW_VEHICLE", 10).unwrap(),
        ..turn.clone()
    };
    let mut ends = [0usize; 2];
    let mut phantom = [0usize; 2];
    for (k, cond) in ["noise_30", "noise_50"].iter().enumerate() {
        for i in 0..10 {
            let clip = generate_clip(&turn, i).unwrap();
            let fs = frames(&clip, i, cond);
            let (p, plan) = planner.plan_with_perception(&input(&clip, &fs)).unwrap();
            ends[k] += usize::from(p.road_end.is_some() && p.right_branch);
            assert!(plan.trajectory.ade(&clip.ground_truth).is_finite());
            let clip = generate_clip(&follow, i).unwrap();
            let fs = frames(&clip, i, cond);
            let (p, _) = planner.plan_with_perception(&input(&clip, &fs)).unwrap();
            phantom[k] += usize::from(p.road_end.is_some());
        }
    }
    // Measured on this seed: 10 of 10 junctions seen at σ 30 and at σ 50, no phantom ends;
    // before the step detector, 4 and 2 of 10.
    assert!(ends[0] >= 8, "T-junctions seen at σ 30: {} of 10", ends[0]);
    assert!(ends[1] >= 6, "T-junctions seen at σ 50: {} of 10", ends[1]);
    assert!(
        phantom.iter().sum::<usize>() <= 1,
        "phantom road ends behind leads: {phantom:?}"
    );
}

/// A lead's speed comes from registering its whole rear face between the clip's frames, so
/// noise that jitters a contact scan by a pixel (half a metre at 30 m) does not turn into
/// metres per second; and a lead driving ahead is not seen moving across the lane.
#[test]
fn a_lead_is_tracked_by_its_face_through_noise() {
    let planner = ReferencePlanner::new();
    let follow = WorldConfig {
        seed: 29,
        depth: false,
        mix: ScenarioMix::only("FOLLOW_VEHICLE", 12).unwrap(),
        ..WorldConfig::default()
    };
    let passing = WorldConfig {
        mix: ScenarioMix::only("PASSING", 8).unwrap(),
        ..follow.clone()
    };
    // Per condition: absolute speed errors and the largest sideways speed.
    let mut errors: [Vec<f64>; 2] = [Vec::new(), Vec::new()];
    let mut sideways = [0f64; 2];
    for (config, n) in [(&follow, 12), (&passing, 8)] {
        for i in 0..n {
            let clip = generate_clip(config, i).unwrap();
            let truth = clip.scene.facts["lead_speed_mps"].as_f64().unwrap();
            for (k, cond) in ["clean", "noise_30"].iter().enumerate() {
                let fs = frames(&clip, i, cond);
                let (p, _) = planner.plan_with_perception(&input(&clip, &fs)).unwrap();
                let lead = p.lead.expect("the lead is seen");
                errors[k].push((lead.speed - truth).abs());
                sideways[k] = sideways[k].max(lead.lateral_speed.abs());
            }
        }
    }
    let mean = |e: &[f64]| e.iter().sum::<f64>() / e.len() as f64;
    let worst = |e: &[f64]| e.iter().copied().fold(0.0, f64::max);
    // Measured on this seed (20 leads): mean error 0.71 m/s clean and 0.66 at σ 30, worst
    // 2.2 and 2.3, sideways at most 0.18; the contact scan before it: mean 0.82 and 1.65,
    // worst 4.4 and 13.9 m/s (it fails here).
    for (k, cond) in ["clean", "σ 30"].iter().enumerate() {
        assert!(
            mean(&errors[k]) < 0.8 && worst(&errors[k]) < 2.5,
            "lead speed error {cond}: mean {:.2}, worst {:.2} m/s",
            mean(&errors[k]),
            worst(&errors[k])
        );
        assert!(
            sideways[k] < 0.8,
            "a lead driving ahead seen moving across at {:.2} m/s ({cond})",
            sideways[k]
        );
    }
}

/// Intersection over union of two `[x0, y0, x1, y1]` boxes.
fn iou(a: [f64; 4], b: [f64; 4]) -> f64 {
    let w = (a[2].min(b[2]) - a[0].max(b[0])).max(0.0);
    let h = (a[3].min(b[3]) - a[1].max(b[1])).max(0.0);
    let inter = w * h;
    let area = |r: [f64; 4]| (r[2] - r[0]) * (r[3] - r[1]);
    inter / (area(a) + area(b) - inter).max(1e-9)
}

/// What the perception detects is an API that downstream code can use instead of the
/// renderer's boxes: its road users' boxes cover the renderer's box of a road user, and the
/// deficit regions it recognises in masked frames (from the pixels alone) are the ones the
/// mask drew.
#[test]
fn detections_match_the_renderers_boxes_and_the_drawn_deficits() {
    use fogline_planner::detect::LaneOf;
    let config = WorldConfig {
        seed: 13,
        depth: false,
        mix: ScenarioMix::paper_scaled(40),
        ..WorldConfig::default()
    };
    let planner = ReferencePlanner::new();
    let mask = Perturbation::parse("mask_all").unwrap().prepare(0).unwrap();
    let (mut objects, mut matched) = (0, 0);
    let (mut drawn, mut found_exact, mut spurious) = (0, 0, 0);
    let n = config.mix.total();
    for i in 0..n {
        let clip = generate_clip(&config, i).unwrap();
        let clean = frames(&clip, i, "clean");
        let d = planner.detect(&input(&clip, &clean)).unwrap();
        assert!(d.deficits.is_empty(), "clip {i}: deficits in a clean frame");
        for o in d.objects.iter().filter(|o| o.lane == LaneOf::Ego) {
            objects += 1;
            let cam = clip
                .cameras
                .iter()
                .find(|c| c.calib.id == o.camera)
                .unwrap();
            let truth = &cam.frames.last().unwrap().boxes;
            let best = truth
                .iter()
                .filter(|b| {
                    ["car", "truck", "pedestrian", "cyclist", "barrier"].contains(&b.class.as_str())
                })
                .map(|b| {
                    iou(
                        o.bbox,
                        [b.x_px, b.y_px, b.x_px + b.width_px, b.y_px + b.height_px],
                    )
                })
                .fold(0.0, f64::max);
            matched += usize::from(best >= 0.2);
        }
        // Every object masked in the latest frames, then found again from the pixels.
        for (c, cam) in clip.cameras.iter().enumerate() {
            {
                let f = cam.frames.last().unwrap();
                let mut fi = FrameInput::new(&f.image, FrameKey::new(i as u64, c as u64, 3));
                fi.boxes = &f.boxes;
                let applied = mask.apply(&fi).unwrap();
                let found = fogline_planner::detect::find_deficits(
                    applied.frame.data(),
                    cam.calib.width as usize,
                    cam.calib.height as usize,
                )
                .unwrap();
                let rects: Vec<_> = applied.deficits.iter().map(|r| r.rect).collect();
                // A region apart from every other one (its outline cannot merge) and large
                // enough to hold a ring is found exactly.
                for (k, r) in rects.iter().enumerate() {
                    let apart = rects.iter().enumerate().all(|(j, o)| {
                        j == k
                            || o.x0 > r.x1 + 1
                            || r.x0 > o.x1 + 1
                            || o.y0 > r.y1 + 1
                            || r.y0 > o.y1 + 1
                    });
                    if apart && r.x1 - r.x0 >= 8 && r.y1 - r.y0 >= 8 {
                        drawn += 1;
                        found_exact += usize::from(
                            found
                                .iter()
                                .any(|d| (d.x0, d.y0, d.x1, d.y1) == (r.x0, r.y0, r.x1, r.y1)),
                        );
                    }
                }
                // Nothing is found where no mask was drawn.
                spurious += found
                    .iter()
                    .filter(|d| {
                        !rects.iter().any(|r| {
                            d.x0 >= r.x0.saturating_sub(1)
                                && d.x1 <= r.x1 + 1
                                && d.y0 >= r.y0.saturating_sub(1)
                                && d.y1 <= r.y1 + 1
                                || (r.x0 >= d.x0 && r.x1 <= d.x1 && r.y0 >= d.y0 && r.y1 <= d.y1)
                        })
                    })
                    .count();
            }
        }
    }
    eprintln!(
        "objects {objects}, matched {matched}; deficits drawn {drawn}, found exactly {found_exact}, spurious {spurious}"
    );
    assert!(
        objects >= 10,
        "only {objects} objects detected on {n} clips"
    );
    assert!(
        matched * 4 >= objects * 3,
        "{matched} of {objects} detected objects overlap a renderer box"
    );
    assert!(drawn >= 20, "only {drawn} separate deficits drawn");
    assert_eq!(found_exact, drawn, "deficits found exactly");
    assert_eq!(spurious, 0, "deficits found where none was drawn");
}

/// A plan that stops says where (`Plan::stop_at`): the perceived stop point, just before the
/// stop line the planner saw, and never behind the car; a plan that does not stop has none.
#[test]
fn a_stopping_plan_reports_its_stop_point() {
    use fogline_types::clip::Decision;
    let planner = ReferencePlanner::new();
    let config = WorldConfig {
        seed: 31,
        depth: false,
        mix: ScenarioMix::only("STOP_SIGNAL", 8).unwrap(),
        ..WorldConfig::default()
    };
    let mut stops = 0;
    for i in 0..config.mix.total() {
        let clip = generate_clip(&config, i).unwrap();
        let fs = frames(&clip, i, "clean");
        let (p, plan) = planner.plan_with_perception(&input(&clip, &fs)).unwrap();
        let stopping = matches!(
            plan.decision,
            Decision::StopForSign | Decision::StopForRedLight | Decision::YieldToCrossing
        );
        assert_eq!(plan.stop_at.is_some(), stopping, "{:?}", plan.decision);
        let front = fogline_types::motion::EGO_FRONT_M;
        if let Some(at) = plan.stop_at {
            stops += 1;
            // Short of what it stops for, with the front bumper.
            let before = match plan.decision {
                Decision::StopForSign => p.stop_sign,
                Decision::StopForRedLight => p.light.map(|l| l.1),
                _ => p.lead.map(|l| l.contact_x),
            }
            .unwrap_or(f64::INFINITY);
            assert!(at + front < before, "stop at {at} for {before}");
            // Where a stop line was seen near the sign: 0.5 m before it.
            if let (Some(line), Some(sign)) = (p.stop_line, p.stop_sign)
                && plan.decision == Decision::StopForSign
                && (line - sign).abs() < 6.0
            {
                assert!(
                    (at - (line - front - 0.5)).abs() < 1e-9,
                    "{at} vs line {line}"
                );
            }
        }
    }
    assert!(stops >= 4, "stopping plans: {stops} of 8");
}
