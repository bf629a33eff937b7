//! Clip generation: scene → cameras → expert.

use crate::clip::{CameraClip, CameraFrame, Clip, SceneInfo};
use crate::config::WorldConfig;
use crate::error::WorldError;
use crate::render::render;
use crate::scenarios::{Built, build};
use fogline_stats::seed::child;
use fogline_types::clip::{CameraCalib, CameraId, DT_S, EgoPose, FRAMES, HISTORY};

/// Generates clip `index` of the corpus described by `config` (deterministic: the same
/// config and index give the same clip, byte for byte).
pub fn generate_clip(config: &WorldConfig, index: usize) -> Result<Clip, WorldError> {
    generate_clip_cameras(config, index, &CameraId::ALL)
}

/// [`generate_clip`] rendering only `cameras` (in the rig's order, whatever the order given):
/// the same scene, and for each camera rendered the same pixels, depth and boxes as the full
/// clip. For consumers that look at some cameras only (a campaign with a planner that says
/// which cameras it uses).
pub fn generate_clip_cameras(
    config: &WorldConfig,
    index: usize,
    cameras: &[CameraId],
) -> Result<Clip, WorldError> {
    config.validate()?;
    let (Some(scenario), Some(id)) = (config.mix.scenario_of(index), config.clip_id(index)) else {
        return Err(WorldError::invalid(
            "index",
            index,
            format!("below the mix's total of {} clips", config.mix.total()),
        ));
    };
    let seed = child(config.seed, &[index as u64]);
    let built = build(scenario, seed);
    Ok(render_clip(&built, config, id, scenario, cameras))
}

/// The frame times of a clip, s relative to `t0` (oldest first).
pub fn frame_times() -> [f64; FRAMES] {
    std::array::from_fn(|k| round_time(-DT_S * (FRAMES - 1 - k) as f64))
}

fn render_clip(
    built: &Built,
    config: &WorldConfig,
    id: String,
    scenario: &str,
    only: &[CameraId],
) -> Clip {
    let scene = &built.scene;
    let cameras = CameraId::ALL
        .iter()
        .filter(|cam| only.contains(cam))
        .map(|&cam| {
            let calib = CameraCalib::standard(cam, config.width, config.height);
            let frames = frame_times()
                .iter()
                .map(|&t| {
                    let view = render(scene, &calib, t, config.depth);
                    CameraFrame {
                        t_s: t,
                        image: view.image,
                        depth: view.depth,
                        boxes: view.boxes,
                    }
                })
                .collect();
            CameraClip { calib, frames }
        })
        .collect();
    let ego_history = (0..HISTORY)
        .map(|k| {
            let t = -DT_S * (HISTORY - 1 - k) as f64;
            let (x, y, yaw) = scene.ego.pose_at(t);
            EgoPose {
                t_s: round_time(t),
                x_m: x,
                y_m: y,
                yaw_rad: yaw,
                speed_mps: scene.ego.speed,
            }
        })
        .collect();
    Clip {
        id,
        scenario: scenario.to_string(),
        cameras,
        ego_history,
        ground_truth: built.truth.clone(),
        scene: SceneInfo {
            decision: Some(built.decision),
            facts: built.facts.clone(),
        },
    }
}

fn round_time(t: f64) -> f64 {
    (t * 1000.0).round() / 1000.0 + 0.0
}
