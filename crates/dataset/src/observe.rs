//! A sample as the RCO controller sees it: five [`Observation`]s (its views with their
//! deficit regions, the visible road users and the calibrations), and the controller's own
//! queries over them: hazard inference (`fogline_rco::backend::prompt::hazard_query`) and
//! the short-term motion planner's (`move_query`, `som_query`) — the same prompts, images
//! and schemas as in the closed loop.

use std::path::Path;
use std::sync::Arc;

use fogline_rco::Strategy;
use fogline_rco::action::HazardInference;
use fogline_rco::backend::{Query, QueryContext, prompt};
use fogline_rco::verifier::{Assessment, VerifierParams, assess};
use fogline_rco::{
    EgoState, NavDirection, Navigation, Observation, PixelBox, RoadGeometry, RoadLayout,
    Surroundings, TrafficEnv, TrafficObject, View,
};
use fogline_types::clip::CameraId;

use crate::DatasetError;
use crate::sample::{Manifest, SampleRecord};

/// The views, in the RCO's order.
pub const VIEWS: [CameraId; 3] = [
    CameraId::CrossLeft,
    CameraId::FrontWide,
    CameraId::CrossRight,
];
/// At most this many images per query (every view of every frame).
pub const MAX_IMAGES: usize = 15;
/// The planning limits the queries mention and the answers are validated against (the
/// controller's defaults, `RcoParams::plan_limit` and `wait_limit`).
pub const PLAN_LIMIT: usize = 5;
/// The largest wait of a stop-observe-move plan, ticks.
pub const WAIT_LIMIT: u32 = 30;

/// The five observations of a sample, oldest first; with `pixels_from` (the data set
/// directory) the frames are read and decoded, else the views carry no pixels (text only).
pub fn observations(
    manifest: &Manifest,
    sample: &SampleRecord,
    pixels_from: Option<&Path>,
) -> Result<Vec<Observation>, DatasetError> {
    if sample.frames.is_empty() {
        return Err(DatasetError::Params(format!(
            "sample {}: no frames",
            sample.id
        )));
    }
    let mut out = Vec::with_capacity(sample.frames.len());
    for (k, f) in sample.frames.iter().enumerate() {
        let mut views = Vec::with_capacity(f.views.len());
        for v in &f.views {
            let calib = manifest.calib(v.camera).copied().ok_or_else(|| {
                DatasetError::Params(format!(
                    "sample {}: camera {} is not in the manifest",
                    sample.id,
                    v.camera.short()
                ))
            })?;
            let rgb = match pixels_from {
                Some(dir) => {
                    let path = dir.join(&v.image);
                    let bytes = std::fs::read(&path).map_err(|e| DatasetError::io(&path, e))?;
                    let img = fogline_io::decode_rgb(&bytes)
                        .map_err(|e| DatasetError::invalid(&path, 0, e))?;
                    if (img.width, img.height) != (calib.width, calib.height) {
                        return Err(DatasetError::invalid(
                            &path,
                            0,
                            format!(
                                "{}x{} px, the manifest's {} camera is {}x{}",
                                img.width,
                                img.height,
                                v.camera.short(),
                                calib.width,
                                calib.height
                            ),
                        ));
                    }
                    Some(Arc::from(img.rgb))
                }
                None => None,
            };
            views.push(View {
                camera: v.camera,
                width: calib.width,
                height: calib.height,
                rgb,
                deficits: v
                    .deficits
                    .iter()
                    .map(|d| {
                        PixelBox::new(
                            f64::from(d[0]),
                            f64::from(d[1]),
                            f64::from(d[2].saturating_sub(d[0])),
                            f64::from(d[3].saturating_sub(d[1])),
                        )
                    })
                    .collect(),
                objects: v
                    .objects
                    .iter()
                    .map(|o| TrafficObject {
                        class: o.class.clone(),
                        track_id: o.track_id,
                        rect: PixelBox::new(
                            o.bbox[0],
                            o.bbox[1],
                            o.bbox[2] - o.bbox[0],
                            o.bbox[3] - o.bbox[1],
                        ),
                    })
                    .collect(),
                calib: Some(calib),
            });
        }
        out.push(Observation {
            tick: k as u64,
            views,
            ego: EgoState {
                speed_mps: f.ego_speed_mps,
                accel_x_mps2: 0.0,
                yaw_rate_rps: 0.0,
                follow_distance_m: None,
            },
            navigation: Navigation {
                direction: NavDirection::FollowLane,
                target_x_m: 20.0,
                target_y_m: 0.0,
                road: RoadGeometry {
                    layout: RoadLayout::Straight,
                    two_way: true,
                    lanes: 1,
                },
            },
            surroundings: Surroundings {
                weather: sample.weather.rco(),
                daylight: sample.daylight.rco(),
                traffic_env: TrafficEnv::Urban,
                traffic_density: 0,
            },
        });
    }
    for o in &out {
        o.validate()
            .map_err(|e| DatasetError::Params(format!("sample {}: {e}", sample.id)))?;
    }
    Ok(out)
}

/// What a hazard query borrows: the verifier's assessment of the last frame.
pub fn assessment(history: &[Observation]) -> Assessment {
    let n = history.len();
    let prev = n.checked_sub(2).and_then(|i| history.get(i));
    match history.last() {
        Some(now) => assess(prev, now, &VIEWS, &VerifierParams::default()),
        None => Assessment {
            views: Vec::new(),
            change: None,
        },
    }
}

/// The controller's hazard inference query over a sample's observations (one frame per
/// second).
pub fn hazard_query<'a>(history: &'a [Observation], assessment: &'a Assessment) -> Query<'a> {
    prompt::hazard_query(context(history, assessment, None), MAX_IMAGES)
}

/// The controller's planning query after `hazard` (equation 5): the move plan or the
/// stop-observe-move plan, whichever strategy the hazard inference chose, over the last
/// frame's views, told the hazards inferred. Its context is the hazard query's, with the
/// tick the samples' frame interval (1 s): a backend that places the hazards from the
/// history (the rules' ground geometry) needs the frames' true spacing, so the prompt's
/// steps are 1 s here, where the closed loop's are 0.1 s.
pub fn plan_query<'a>(
    history: &'a [Observation],
    assessment: &'a Assessment,
    hazard: &'a HazardInference,
) -> Query<'a> {
    let ctx = context(history, assessment, Some(hazard));
    match hazard.strategy {
        Strategy::Move => prompt::move_query(ctx),
        Strategy::StopObserveMove => prompt::som_query(ctx),
    }
}

/// A query's context (one frame per second).
fn context<'a>(
    history: &'a [Observation],
    assessment: &'a Assessment,
    hazard: Option<&'a HazardInference>,
) -> QueryContext<'a> {
    QueryContext {
        history,
        views: &VIEWS,
        assessment,
        hazard,
        plan_limit: PLAN_LIMIT,
        wait_limit: WAIT_LIMIT,
        constraints: None,
        ticks_since_stop: None,
        stopped_for: &[],
        hazard_ratio: VerifierParams::default().hazard_ratio,
        dt_s: 1.0,
    }
}
