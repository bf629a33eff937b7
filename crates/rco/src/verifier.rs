//! The action condition verifier (section 4), rule-based and cheap enough for every tick.
//!
//! **Deficit consistency** (figure 4, left): between the previous tick and this one, per view,
//! the number of deficit regions must not change (a count change is a *quantity
//! realignment*, a drop to zero a *disappearance*) and no region may shift by more than
//! `max_shift_frac × image width` pixels. A region's shift is measured twice: in image space
//! (`|Δc|`, the displacement of its centre) and against the background (`|Δc − Δb|`, where
//! `Δb` is the displacement of the textured background around the region, found by block
//! matching the two frames). The smaller one counts: a deficit fixed on the sensor (dirt, a
//! dead area) stays put in the image, a masked static object moves with the background, and
//! only a region that moves against both (a masked moving object, a changing attack) is
//! inconsistent. Without pixels (or on a texture-less background) only the image-space shift
//! is available.
//!
//! **Immediate hazard** (figure 4, right): per view, the ratio
//! `(Σ deficit area + Σ traffic-object box area) / image area` (boxes clipped to the image,
//! overlaps counted twice, objects of the configured traffic classes only) above
//! `hazard_ratio` (the paper's 0.05) means an immediate hazard near the vehicle. A configured
//! view missing from the observation counts as one full-frame deficit (ratio 1).
//!
//! An action runs only when its condition holds: deficits consistent and every view in the
//! state the condition names.

use std::collections::BTreeMap;
use std::fmt;

use fogline_types::clip::CameraId;
use serde::{Deserialize, Serialize};

use crate::RcoError;
use crate::action::{Condition, HazardState};
use crate::observation::{Observation, PixelBox, View};

/// Settings of the verifier.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct VerifierParams {
    /// Area ratio above which a view has an immediate hazard (paper: 0.05).
    pub hazard_ratio: f64,
    /// Largest shift of a deficit region between two ticks, as a fraction of the image width.
    pub max_shift_frac: f64,
    /// Object classes counted in the ratio (the paper's YOLO traffic classes and synonyms).
    pub traffic_classes: Vec<String>,
    /// Search radius of the background block matching, px.
    pub background_search_px: u32,
    /// Smallest luminance standard deviation (0–255 scale) of the background ring for a
    /// background shift to be trusted.
    pub background_min_texture: f64,
}

impl Default for VerifierParams {
    fn default() -> Self {
        Self {
            hazard_ratio: 0.05,
            max_shift_frac: 0.02,
            traffic_classes: [
                "car",
                "truck",
                "bus",
                "bicycle",
                "pedestrian",
                "motorcycle",
                "person",
                "cyclist",
                "motorbike",
                "rider",
                "vehicle",
                "van",
            ]
            .iter()
            .map(|s| s.to_string())
            .collect(),
            background_search_px: 12,
            background_min_texture: 3.0,
        }
    }
}

impl VerifierParams {
    /// Checks the settings.
    pub fn validate(&self) -> Result<(), RcoError> {
        if !(self.hazard_ratio.is_finite() && self.hazard_ratio > 0.0) {
            return Err(RcoError::Params(format!(
                "verifier.hazard_ratio {} must be finite and > 0",
                self.hazard_ratio
            )));
        }
        if !(self.max_shift_frac.is_finite() && self.max_shift_frac >= 0.0) {
            return Err(RcoError::Params(format!(
                "verifier.max_shift_frac {} must be finite and >= 0",
                self.max_shift_frac
            )));
        }
        if self.background_search_px > 64 {
            return Err(RcoError::Params(format!(
                "verifier.background_search_px {} must be <= 64",
                self.background_search_px
            )));
        }
        if !self.background_min_texture.is_finite() || self.background_min_texture < 0.0 {
            return Err(RcoError::Params(
                "verifier.background_min_texture must be finite and >= 0".into(),
            ));
        }
        Ok(())
    }

    fn is_traffic(&self, class: &str) -> bool {
        self.traffic_classes
            .iter()
            .any(|c| c.eq_ignore_ascii_case(class))
    }
}

/// One view as the verifier sees it at this tick.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ViewAssessment {
    /// The camera.
    pub camera: CameraId,
    /// Whether the view was in the observation.
    pub present: bool,
    /// Deficit regions (a missing view counts one).
    pub deficits: usize,
    /// `(deficit area + traffic-object area) / image area`.
    pub area_ratio: f64,
    /// `immediate_hazard` when the ratio exceeds the threshold.
    pub state: HazardState,
}

/// Why the deficits are not consistent.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Inconsistency {
    /// The view disappeared from the observation.
    ViewLost {
        /// The camera.
        camera: CameraId,
    },
    /// The view came back.
    ViewRestored {
        /// The camera.
        camera: CameraId,
    },
    /// The number of deficit regions changed (quantity realignment).
    CountChanged {
        /// The camera.
        camera: CameraId,
        /// Regions before.
        before: usize,
        /// Regions now.
        now: usize,
    },
    /// Every deficit region disappeared.
    Disappeared {
        /// The camera.
        camera: CameraId,
        /// Regions before.
        before: usize,
    },
    /// A region moved against the image and against the background.
    Shifted {
        /// The camera.
        camera: CameraId,
        /// Index of the region in this tick's list.
        deficit: usize,
        /// The shift, px (the smaller of image-space and background-relative).
        shift_px: f64,
        /// The limit, px.
        limit_px: f64,
    },
}

impl fmt::Display for Inconsistency {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Inconsistency::ViewLost { camera } => write!(f, "view {} lost", camera.short()),
            Inconsistency::ViewRestored { camera } => {
                write!(f, "view {} restored", camera.short())
            }
            Inconsistency::CountChanged {
                camera,
                before,
                now,
            } => write!(f, "{}: deficit count {before} -> {now}", camera.short()),
            Inconsistency::Disappeared { camera, before } => {
                write!(f, "{}: {before} deficit(s) disappeared", camera.short())
            }
            Inconsistency::Shifted {
                camera,
                deficit,
                shift_px,
                limit_px,
            } => write!(
                f,
                "{}: deficit {deficit} shifted {shift_px:.1} px (limit {limit_px:.1})",
                camera.short()
            ),
        }
    }
}

/// The verifier's view of one tick: per-view states and the consistency with the previous
/// tick.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Assessment {
    /// The configured views, in order.
    pub views: Vec<ViewAssessment>,
    /// The first inconsistency with the previous tick, if any.
    pub change: Option<Inconsistency>,
}

impl Assessment {
    /// The observed state of `camera` (`immediate_hazard` for a camera not assessed).
    pub fn state(&self, camera: CameraId) -> HazardState {
        self.views
            .iter()
            .find(|v| v.camera == camera)
            .map_or(HazardState::ImmediateHazard, |v| v.state)
    }

    /// Whether a front view (a camera looking along the rig's x axis) shows an immediate
    /// hazard: what the rules backend stops for and the controller's shield enforces.
    pub fn front_immediate(&self) -> bool {
        self.views
            .iter()
            .any(|v| is_front(v.camera) && v.state == HazardState::ImmediateHazard)
    }

    /// The observed states as a condition (what a plan made now would require).
    pub fn observed(&self) -> Condition {
        Condition {
            views: self.views.iter().map(|v| (v.camera, v.state)).collect(),
        }
    }

    /// Deficit counts per camera (`None`: view missing).
    pub fn counts(&self) -> BTreeMap<CameraId, Option<usize>> {
        self.views
            .iter()
            .map(|v| (v.camera, v.present.then_some(v.deficits)))
            .collect()
    }
}

/// Why an action was not executed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Refusal {
    /// The deficits changed since the previous tick.
    Inconsistent {
        /// What changed.
        change: Inconsistency,
    },
    /// The deficit count differs from the one the plan was made with.
    CountSincePlan {
        /// The camera.
        camera: CameraId,
        /// Regions when the plan was made (`None`: view missing).
        at_plan: Option<usize>,
        /// Regions now.
        now: Option<usize>,
    },
    /// A view is not in the state the condition requires.
    Condition {
        /// The camera.
        camera: CameraId,
        /// The state required.
        required: HazardState,
        /// The state observed.
        observed: HazardState,
    },
    /// The condition does not name every configured view.
    MissingView {
        /// The camera.
        camera: CameraId,
    },
}

impl fmt::Display for Refusal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Refusal::Inconsistent { change } => write!(f, "inconsistent deficits: {change}"),
            Refusal::CountSincePlan {
                camera,
                at_plan,
                now,
            } => {
                let s = |c: &Option<usize>| c.map_or("missing".into(), |n| n.to_string());
                write!(
                    f,
                    "{}: deficit count {} at plan time, {} now",
                    camera.short(),
                    s(at_plan),
                    s(now)
                )
            }
            Refusal::Condition {
                camera,
                required,
                observed,
            } => write!(
                f,
                "{}: requires {}, observed {}",
                camera.short(),
                required.name(),
                observed.name()
            ),
            Refusal::MissingView { camera } => {
                write!(f, "condition names no state for {}", camera.short())
            }
        }
    }
}

/// `(Σ deficit area + Σ traffic-object box area) / image area` of one view (boxes clipped to
/// the image).
pub fn area_ratio(view: &View, params: &VerifierParams) -> f64 {
    let (w, h) = (view.width, view.height);
    let deficits = view
        .deficits
        .iter()
        .fold(0.0, |a, d| a + d.clipped(w, h).area());
    let objects = view
        .objects
        .iter()
        .filter(|o| params.is_traffic(&o.class))
        .fold(0.0, |a, o| a + o.rect.clipped(w, h).area());
    let area = view.area();
    if area > 0.0 {
        (deficits + objects) / area
    } else {
        1.0
    }
}

/// The state of a view: `immediate_hazard` when `ratio > hazard_ratio`.
pub fn hazard_state(ratio: f64, params: &VerifierParams) -> HazardState {
    if ratio > params.hazard_ratio || ratio.is_nan() {
        HazardState::ImmediateHazard
    } else {
        HazardState::NoImmediateHazard
    }
}

/// Assesses `now` (against `prev`, the previous tick, when there is one) for the configured
/// `views`.
pub fn assess(
    prev: Option<&Observation>,
    now: &Observation,
    views: &[CameraId],
    params: &VerifierParams,
) -> Assessment {
    let mut out = Vec::with_capacity(views.len());
    let mut change = None;
    for &camera in views {
        let v = now.view(camera);
        let a = match v {
            Some(v) => {
                let ratio = area_ratio(v, params);
                ViewAssessment {
                    camera,
                    present: true,
                    deficits: v.deficits.len(),
                    area_ratio: ratio,
                    state: hazard_state(ratio, params),
                }
            }
            None => ViewAssessment {
                camera,
                present: false,
                deficits: 1,
                area_ratio: 1.0,
                state: HazardState::ImmediateHazard,
            },
        };
        out.push(a);
        if change.is_none()
            && let Some(p) = prev
        {
            change = compare_views(camera, p.view(camera), v, params);
        }
    }
    Assessment { views: out, change }
}

/// The first inconsistency between a view at the previous tick and now.
pub fn compare_views(
    camera: CameraId,
    prev: Option<&View>,
    now: Option<&View>,
    params: &VerifierParams,
) -> Option<Inconsistency> {
    let (prev, now) = match (prev, now) {
        (None, None) => return None,
        (Some(_), None) => return Some(Inconsistency::ViewLost { camera }),
        (None, Some(_)) => return Some(Inconsistency::ViewRestored { camera }),
        (Some(p), Some(n)) => (p, n),
    };
    let (before, count) = (prev.deficits.len(), now.deficits.len());
    if before != count {
        return Some(if count == 0 {
            Inconsistency::Disappeared { camera, before }
        } else {
            Inconsistency::CountChanged {
                camera,
                before,
                now: count,
            }
        });
    }
    let limit_px = params.max_shift_frac * f64::from(now.width);
    let pairs = match_regions(&prev.deficits, &now.deficits);
    for (i, j) in pairs {
        let (a, b) = (prev.deficits[j], now.deficits[i]);
        let (ca, cb) = (a.center(), b.center());
        let (dx, dy) = (cb.0 - ca.0, cb.1 - ca.1);
        let raw = dx.hypot(dy);
        if raw <= limit_px {
            continue;
        }
        let shift_px = match background_shift(prev, now, &a, params) {
            Some((bx, by)) => raw.min((dx - bx).hypot(dy - by)),
            None => raw,
        };
        if shift_px > limit_px {
            return Some(Inconsistency::Shifted {
                camera,
                deficit: i,
                shift_px,
                limit_px,
            });
        }
    }
    None
}

/// Pairs each region of `now` with a distinct region of `prev` (same count): greedily, the
/// nearest centres first. Returns `(index in now, index in prev)`.
fn match_regions(prev: &[PixelBox], now: &[PixelBox]) -> Vec<(usize, usize)> {
    let mut cand: Vec<(f64, usize, usize)> = Vec::with_capacity(prev.len() * now.len());
    for (i, b) in now.iter().enumerate() {
        for (j, a) in prev.iter().enumerate() {
            let (ca, cb) = (a.center(), b.center());
            cand.push(((cb.0 - ca.0).hypot(cb.1 - ca.1), i, j));
        }
    }
    cand.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)).then(x.2.cmp(&y.2)));
    let mut used_now = vec![false; now.len()];
    let mut used_prev = vec![false; prev.len()];
    let mut out = Vec::with_capacity(now.len());
    for (_, i, j) in cand {
        if !used_now[i] && !used_prev[j] {
            used_now[i] = true;
            used_prev[j] = true;
            out.push((i, j));
        }
    }
    out.sort_unstable();
    out
}

/// The displacement `(Δu, Δv)` of the background around `region` (a box of `prev`) from
/// `prev` to `now`, px, by block matching luminance `(R + 2G + B) / 4` on a ring around the
/// region (its margin at least the search radius + 16 px): a sparse grid (about 256 samples)
/// outside every deficit of both frames (grown by 2 px), an
/// exhaustive search of the integer offsets within `±background_search_px` (partial sums
/// stop as soon as they exceed the best so far); the offset with the smallest sum of
/// absolute differences wins, ties going to the smaller offset (zero first). `None` without
/// pixels of equal size, with fewer than 32 usable samples, or on a background whose
/// luminance spread is below `background_min_texture`.
pub fn background_shift(
    prev: &View,
    now: &View,
    region: &PixelBox,
    params: &VerifierParams,
) -> Option<(f64, f64)> {
    let (Some(pa), Some(pb)) = (prev.rgb.as_deref(), now.rgb.as_deref()) else {
        return None;
    };
    if prev.width != now.width || prev.height != now.height {
        return None;
    }
    let (w, h) = (prev.width as i64, prev.height as i64);
    let r = i64::from(params.background_search_px);
    let margin = (0.5 * region.width_px.max(region.height_px)).max(r as f64 + 16.0);
    let ring = region.expanded(margin);
    let x0 = (ring.x_px.floor() as i64).max(r);
    let y0 = (ring.y_px.floor() as i64).max(r);
    let x1 = (ring.x_end_px().ceil() as i64).min(w - r);
    let y1 = (ring.y_end_px().ceil() as i64).min(h - r);
    if x1 <= x0 || y1 <= y0 {
        return None;
    }
    let area = ((x1 - x0) * (y1 - y0)) as f64;
    let step = ((area / 256.0).sqrt().ceil() as i64).max(1);
    let masks: Vec<PixelBox> = prev
        .deficits
        .iter()
        .chain(&now.deficits)
        .map(|d| d.expanded(2.0))
        .collect();
    let lum = |px: &[u8], i: usize| -> i32 {
        (i32::from(px[i]) + 2 * i32::from(px[i + 1]) + i32::from(px[i + 2])) / 4
    };
    // (index of the sample's first byte, its luminance in `prev`)
    let mut pts: Vec<(i64, i32)> = Vec::with_capacity(320);
    let mut y = y0;
    while y < y1 {
        let mut x = x0;
        while x < x1 {
            let (u, v) = (x as f64 + 0.5, y as f64 + 0.5);
            if !masks.iter().any(|m| m.contains(u, v)) {
                let i = (y * w + x) * 3;
                pts.push((i, lum(pa, i as usize)));
            }
            x += step;
        }
        y += step;
    }
    if pts.len() < 32 {
        return None;
    }
    let n = pts.len() as f64;
    let mean = pts.iter().map(|p| f64::from(p.1)).sum::<f64>() / n;
    let var = pts
        .iter()
        .map(|p| (f64::from(p.1) - mean).powi(2))
        .sum::<f64>()
        / n;
    if var.sqrt() < params.background_min_texture {
        return None;
    }
    // Sum of absolute differences at offset `d` (in bytes), stopping above `stop`.
    let sad = |d: i64, stop: i64| -> i64 {
        let mut total = 0i64;
        for &(i, l) in &pts {
            total += i64::from((l - lum(pb, (i + d) as usize)).abs());
            if total > stop {
                break;
            }
        }
        total
    };
    let mut best = (sad(0, i64::MAX), 0i64, 0i64);
    for dy in -r..=r {
        for dx in -r..=r {
            if dx == 0 && dy == 0 {
                continue;
            }
            let c = sad((dy * w + dx) * 3, best.0);
            let closer = dx * dx + dy * dy < best.1 * best.1 + best.2 * best.2;
            if c < best.0 || (c == best.0 && closer) {
                best = (c, dx, dy);
            }
        }
    }
    Some((best.1 as f64, best.2 as f64))
}

/// Checks the hazard part of a condition against the assessment: every configured view must
/// be in the state the condition names.
pub fn check_states(condition: &Condition, assessment: &Assessment) -> Result<(), Refusal> {
    for v in &assessment.views {
        let Some(&required) = condition.views.get(&v.camera) else {
            return Err(Refusal::MissingView { camera: v.camera });
        };
        if required != v.state {
            return Err(Refusal::Condition {
                camera: v.camera,
                required,
                observed: v.state,
            });
        }
    }
    Ok(())
}

/// Checks `consistent_deficit` for a plan made at an earlier tick: no change since the
/// previous tick, and the same deficit counts as when the plan was made.
pub fn check_consistency(
    at_plan: &BTreeMap<CameraId, Option<usize>>,
    assessment: &Assessment,
) -> Result<(), Refusal> {
    if let Some(change) = assessment.change {
        return Err(Refusal::Inconsistent { change });
    }
    let now = assessment.counts();
    for (camera, count) in &now {
        let before = at_plan.get(camera).copied().flatten();
        if at_plan.contains_key(camera) && before != *count {
            return Err(Refusal::CountSincePlan {
                camera: *camera,
                at_plan: before,
                now: *count,
            });
        }
    }
    Ok(())
}

/// Whether `camera` looks forward (along the rig's x axis).
pub fn is_front(camera: CameraId) -> bool {
    camera.yaw_rad() == 0.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::observation::TrafficObject;
    use std::sync::Arc;

    fn view(w: u32, h: u32) -> View {
        View::new(CameraId::FrontWide, w, h)
    }

    #[test]
    fn ratio_counts_deficits_and_traffic_objects_only() {
        let mut v = view(100, 100);
        v.deficits.push(PixelBox::new(0.0, 0.0, 10.0, 20.0)); // 200
        v.objects.push(TrafficObject {
            class: "car".into(),
            track_id: None,
            rect: PixelBox::new(50.0, 50.0, 10.0, 10.0), // 100
        });
        v.objects.push(TrafficObject {
            class: "tree".into(),
            track_id: None,
            rect: PixelBox::new(0.0, 0.0, 50.0, 50.0),
        });
        // A box reaching outside the image counts only its inside part.
        v.deficits.push(PixelBox::new(95.0, 95.0, 10.0, 10.0)); // 25
        let r = area_ratio(&v, &VerifierParams::default());
        assert!((r - 325.0 / 10_000.0).abs() < 1e-12);
    }

    #[test]
    fn threshold_is_strictly_greater() {
        let p = VerifierParams::default();
        assert_eq!(hazard_state(0.05, &p), HazardState::NoImmediateHazard);
        assert_eq!(hazard_state(0.050_000_1, &p), HazardState::ImmediateHazard);
    }

    #[test]
    fn background_shift_finds_the_scene_motion() {
        let (w, h) = (160u32, 120u32);
        let tex = |x: i64, y: i64| -> u8 {
            // A hash of 2 × 2 blocks: textured, not periodic.
            let mut z = ((x.div_euclid(2) as u64) << 32) ^ (y.div_euclid(2) as u64);
            z = (z ^ (z >> 31)).wrapping_mul(0x9E37_79B9_7F4A_7C15);
            z = (z ^ (z >> 29)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            (z >> 56) as u8
        };
        let frame = |shift: i64| -> Arc<[u8]> {
            let mut px = Vec::with_capacity((w * h * 3) as usize);
            for y in 0..i64::from(h) {
                for x in 0..i64::from(w) {
                    let t = tex(x - shift, y);
                    px.extend_from_slice(&[t, t, t]);
                }
            }
            Arc::from(px)
        };
        let mut a = view(w, h);
        a.rgb = Some(frame(0));
        let mut b = view(w, h);
        b.rgb = Some(frame(5));
        let region = PixelBox::new(70.0, 50.0, 20.0, 20.0);
        a.deficits.push(region);
        b.deficits.push(PixelBox::new(75.0, 50.0, 20.0, 20.0));
        let s = background_shift(&a, &b, &region, &VerifierParams::default()).unwrap();
        assert_eq!(s, (5.0, 0.0));
    }
}
