//! Perception from pixels: image quality, the road's appearance with distance, lane
//! geometry, the road surface ahead (occupancy per lateral bin), the lead object and its
//! motion, brake lamps, stop lines and crossings, stop signs and traffic lights, the end of
//! the road.
//!
//! Every measurement goes through the cameras' calibration and flat-ground geometry: a ground
//! point `(x, y, 0)` is read from the front-tele camera when it is far enough to be in its
//! view (≥ 13 m) and from the front-wide camera otherwise. Every reading is a *pooled* mean
//! over a patch whose size follows the frame's measured noise (see [`crate::vision`]), and
//! every test is relative to the scene's own references: the asphalt's colour at that
//! distance ([`RoadModel`]) and the frame's white level.

use crate::vision::{
    LampColour, Refs, Rgb, Sample, Smoothed, View, chroma, gain_of, is_object, is_road,
    is_sign_red, is_sign_red_hazed, is_white_paint, is_yellow_paint, lamp_colour, lamp_colour_over,
    lum, road_distance, round_exact, round_pos, round_px,
};
use fogline_types::clip::{CameraId, EgoPose, PlannerInput};

/// A traffic-light state as seen.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Lamp {
    /// Red.
    Red,
    /// Amber.
    Amber,
    /// Green.
    Green,
}

/// What kind of object blocks the lane.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ObjectKind {
    /// A vehicle (wide at cabin height).
    Vehicle,
    /// A person or cyclist (narrow at torso height).
    Person,
}

/// The nearest object in the ego lane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LeadSeen {
    /// Ground contact distance from the rear axle, m.
    pub contact_x: f64,
    /// Bumper-to-bumper gap, m.
    pub gap: f64,
    /// Speed along the lane, m/s.
    pub speed: f64,
    /// Standard error of `speed`, m/s (from the scatter of the track about its line; 0 when
    /// the speed is the ego's own, for want of a track).
    pub speed_se: f64,
    /// Speed across the lane, m/s, left positive (from the same registration as `speed`;
    /// 0 without a track): a road user crossing moves across, a vehicle ahead along.
    pub lateral_speed: f64,
    /// Brake lamps lit.
    pub braking: bool,
    /// Vehicle or person.
    pub kind: ObjectKind,
    /// Width at 1.3 m height, m.
    pub width_m: f64,
    /// Its right-most lateral extent relative to the lane centre, m.
    pub right_edge: f64,
    /// Its left-most lateral extent, m.
    pub left_edge: f64,
    /// Confidence in [0, 1]: how clearly its face stands out from the asphalt, given the
    /// measured noise.
    pub confidence: f64,
    /// Its track over the clip's frames: the ground contact (m ahead of the rear axle at
    /// the latest frame, ego motion removed) in the latest frame and 1, 2 and 3 frames
    /// (0.1 s each) before it, where it was found.
    pub track: [Option<f64>; 4],
}

impl LeadSeen {
    /// In how many of the clip's frames it was found (1 when its face could not be
    /// followed: its speed is then the ego's own, a placeholder).
    pub fn frames_seen(&self) -> usize {
        self.track.iter().flatten().count()
    }
}

/// The lane the ego drives in.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LaneSeen {
    /// Curvature from the markings, 1/m.
    pub kappa: f64,
    /// The lane's heading relative to the car, rad (left positive): the slope of the lane
    /// centre at the ego. A car that stopped a few degrees off its lane (the end of a turn)
    /// sees its lane run off to one side; without this term the far marking would run into
    /// the lane's interior, where a patch across paint and asphalt reads as an object.
    pub heading: f64,
    /// Lateral position of the lane centre at the ego, m (left positive).
    pub offset: f64,
    /// Lane width, m.
    pub width: f64,
    /// Marking points used.
    pub points: usize,
    /// The left boundary is a dashed white line (a same-direction lane beyond it).
    pub left_dashed_white: bool,
    /// Standard error of `offset`, m (from the fit's residuals and point count).
    pub offset_se: f64,
    /// Standard error of `kappa`, 1/m.
    pub kappa_se: f64,
    /// How much brighter than the asphalt the white markings read (median over the
    /// marking points, 0–255 levels): the paint's own contrast in this frame.
    pub paint_contrast: Option<f64>,
}

/// The measured quality of the front cameras' latest frames.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImageQuality {
    /// Estimated noise σ (0–255), the larger of the front-wide and front-tele estimates.
    pub noise_sigma: f64,
    /// The front-wide frame's white level (0–255).
    pub white: f64,
    /// Exposure scale the thresholds use (1 in daylight).
    pub gain: f64,
}

/// Everything perceived.
#[derive(Debug, Clone, PartialEq)]
pub struct Perception {
    /// Ego speed from the history, m/s.
    pub speed: f64,
    /// Curvature of the history, 1/m.
    pub kappa_history: f64,
    /// Curvature used for planning (markings fused with the history), 1/m.
    pub kappa: f64,
    /// Lane width used for planning, m.
    pub lane_width: f64,
    /// Lane centre offset used for planning, m.
    pub lane_offset: f64,
    /// Lane heading relative to the car used for perception, rad (left positive): the
    /// lane centre at distance `x` is `lane_offset + lane_heading·x + ½·kappa·x²`.
    pub lane_heading: f64,
    /// The marking fit, when the markings were found.
    pub lane: Option<LaneSeen>,
    /// Asphalt luminance reference just ahead of the car.
    pub road_lum: f32,
    /// The nearest object in the lane.
    pub lead: Option<LeadSeen>,
    /// The left lane has a same-direction lane and nothing in it within 60 m.
    pub left_lane_free: bool,
    /// The road ends ahead at this distance (a T-junction).
    pub road_end: Option<f64>,
    /// Asphalt opens to the right before the road end.
    pub right_branch: bool,
    /// Stop line distance.
    pub stop_line: Option<f64>,
    /// Zebra crossing start distance.
    pub zebra: Option<f64>,
    /// Traffic light state and estimated distance.
    pub light: Option<(Lamp, f64)>,
    /// Stop sign distance.
    pub stop_sign: Option<f64>,
    /// The frames' measured quality.
    pub quality: ImageQuality,
    /// The nearest object in the lane to the left (its lateral extents relative to that
    /// lane's centre, one lane width left of the ego lane's; its `speed` signed, negative
    /// for one coming towards the car); only looked for when asked ([`perceive_objects`],
    /// [`Knowing::left_lane`]), `None` otherwise.
    pub left_object: Option<LeadSeen>,
    /// The nearest road user on the right kerb within [`KERB_REACH_M`]: on the shoulder or
    /// the sidewalk, 0.2–3 m right of the lane's right marking (someone who may step off
    /// it into the lane); its lateral extents relative to the ego lane's centre (its
    /// `left_edge` is the one nearest the lane; the other takes in the ground its body
    /// hides beyond it). Not tracked over the clip's frames (its speeds are placeholders,
    /// as an untracked lead's: [`LeadSeen::frames_seen`] is 1); a driver follows it over
    /// its steps. Only looked for when asked ([`Knowing::kerb`]), `None` otherwise.
    pub kerb_object: Option<LeadSeen>,
}

/// Bins across the lane, m.
/// The eight neighbours of a grid cell, as (column, row) offsets.
const NEIGHBOURS_8: [(isize, isize); 8] = [
    (-1, -1),
    (0, -1),
    (1, -1),
    (-1, 0),
    (1, 0),
    (-1, 1),
    (0, 1),
    (1, 1),
];

const BIN: f64 = 0.1;
const HALF_LANE_BINS: i32 = 17;
/// From this distance on, ground points are read from the tele camera.
const TELE_FROM_M: f64 = 13.0;
/// Speed across the lane from which a road user on a crossing is crossing it, m/s (a walker
/// crosses at 1–1.5 m/s).
const CROSSING_MPS: f64 = 0.8;
/// How far ahead the kerb is scanned for road users, m ([`Perception::kerb_object`]).
pub const KERB_REACH_M: f64 = 35.0;
/// The kerb scan's strip: from this far outside the lane's right marking, m ...
const KERB_FROM_M: f64 = 0.2;
/// ... out to this far, m (a shoulder, a kerb and the near part of a sidewalk).
const KERB_TO_M: f64 = 3.0;

struct Eyes<'a> {
    wide: Option<View<'a>>,
    tele: Option<View<'a>>,
    /// Earlier frames of each camera (frames back, view, the rig's pose then in the rig
    /// frame at `t0`), for pooling static ground features over time; empty on clean frames.
    past_wide: Vec<Past<'a>>,
    past_tele: Vec<Past<'a>>,
}

/// An earlier frame: how many frames back, its view, and the rig's pose `[x, y, yaw]` then.
type Past<'a> = (usize, View<'a>, [f64; 3]);

/// The rig-frame point `p` (at `t0`) as seen from a rig at pose `[x, y, yaw]`.
#[inline]
fn into_pose(p: [f64; 3], pose: [f64; 3]) -> [f64; 3] {
    let (dx, dy) = (p[0] - pose[0], p[1] - pose[1]);
    let (s, c) = pose[2].sin_cos();
    [c * dx + s * dy, -s * dx + c * dy, p[2]]
}

impl<'a> Eyes<'a> {
    /// The camera that reads rig-frame point `p`: tele from 13 m on when it sees it.
    #[inline]
    fn view_for(&self, p: [f64; 3]) -> Option<&View<'a>> {
        self.view_proj(p).map(|(v, _)| v)
    }

    /// [`Eyes::view_for`] with `p`'s projection `(u, v, range)` in that view.
    #[inline]
    fn view_proj(&self, p: [f64; 3]) -> Option<(&View<'a>, (f64, f64, f64))> {
        if p[0] >= TELE_FROM_M
            && let Some(t) = &self.tele
            && let Some(q) = t.project(p)
        {
            return Some((t, q));
        }
        let w = self.wide.as_ref()?;
        w.project(p).map(|q| (w, q))
    }

    /// [`Eyes::ground`] and the view that read it.
    #[inline]
    fn ground_read(&self, x: f64, y: f64, lat: f64, dep: f64) -> Option<(&View<'a>, Sample)> {
        let p = [x, y, 0.0];
        let (view, proj) = self.view_proj(p)?;
        view.around_at(p, proj, lat, dep).map(|s| (view, s))
    }

    /// Reading `first` of ground point `p` in `view` ([`Eyes::ground_read`]), averaged with
    /// the same ground point in that camera's earlier frames (ego motion from the history):
    /// for the static paint on the road, whose pixels move between frames but whose colour
    /// does not. Each earlier frame adds independent noise samples, so four frames halve
    /// the noise of the reading.
    #[inline]
    fn pooled_over_past(
        &self,
        view: &View<'a>,
        p: [f64; 3],
        first: Sample,
        lat: f64,
        dep: f64,
    ) -> Sample {
        let past = if view.calib.id == CameraId::FrontTele {
            &self.past_tele
        } else {
            &self.past_wide
        };
        if past.is_empty() {
            return first;
        }
        let (mut acc, mut n) = (first.c, 1.0f32);
        for (_, v, pose) in past {
            if let Some(q) = v.around(into_pose(p, *pose), lat, dep) {
                for c in 0..3 {
                    acc[c] += q.c[c];
                }
                n += 1.0;
            }
        }
        Sample {
            c: [acc[0] / n, acc[1] / n, acc[2] / n],
            s: first.s / n.sqrt(),
        }
    }

    /// A pooled reading of ground point `(x, y)` over about `lat × dep` metres.
    #[inline]
    fn ground(&self, x: f64, y: f64, lat: f64, dep: f64) -> Option<Sample> {
        self.point([x, y, 0.0], lat, dep)
    }

    /// A pooled reading of the pixels at ground point `(x, y)`: 4 × 4 pixels on a clean
    /// frame; as noise grows, wider (up to `lat` m) and then taller upward, up to the rows
    /// where the ground `reach` m beyond the point would show. Ground with nothing on it
    /// shows asphalt there; an object standing within `reach` shows its face. Rising from
    /// the point keeps the patch off the nearer ground, and the reach bounds how far ahead
    /// of an object its contact can be read.
    #[inline]
    fn ground_up(&self, x: f64, y: f64, lat: f64, reach: f64) -> Option<Sample> {
        let p = [x, y, 0.0];
        let (view, (u, v0, range)) = self.view_proj(p)?;
        let need = f64::from((view.sigma / crate::vision::TARGET_NOISE).powi(2));
        if need <= 16.0 {
            return view.patch(u, v0, 4, 4);
        }
        let (_, v_far, _) = view.project_any([x + reach, y, 0.0])?;
        let cols = (need / 4.0).clamp(4.0, (lat * view.calib.fx / range).max(4.0));
        let rows = (need / cols).clamp(4.0, (v0 - v_far + 2.0).max(4.0));
        let half = cols / 2.0;
        view.rect_sample(
            round_px(u - half),
            round_px(v0 + 2.0 - rows),
            round_px(u + half),
            round_px(v0 + 2.0),
        )
    }

    /// A pooled reading around rig-frame point `p`.
    #[inline]
    fn point(&self, p: [f64; 3], lat: f64, dep: f64) -> Option<Sample> {
        self.view_proj(p)
            .and_then(|(v, proj)| v.around_at(p, proj, lat, dep))
    }
}

/// The asphalt's expected colour as a function of distance, measured in the frame: per 1 m
/// band, the median over a wide lateral span of the road (the ego lane and the lane to its
/// left), kept only where it changes smoothly from the band before (fog brightens distant
/// asphalt gradually; an object, a crossing or the end of the road changes it abruptly and
/// is not the road's appearance).
pub struct RoadModel {
    x0: f64,
    cols: Vec<Rgb>,
    gain: f32,
}

impl RoadModel {
    const STEP: f64 = 1.0;

    /// The references at distance `x`.
    #[inline]
    pub fn refs(&self, x: f64) -> Refs {
        let i = round_pos(((x - self.x0) / Self::STEP).max(0.0));
        Refs {
            road: self.cols[i.min(self.cols.len() - 1)],
            gain: self.gain,
        }
    }

    /// Asphalt luminance just ahead of the car.
    pub fn near_lum(&self) -> f32 {
        lum(self.cols[0])
    }
}

/// The rig's pose `[x, y, yaw]` at time `t` (s, ≤ 0) from the history, when a pose lies
/// within 20 ms of it.
fn pose_at(h: &[EgoPose], t: f64) -> Option<[f64; 3]> {
    h.iter()
        .filter(|p| (p.t_s - t).abs() < 0.02)
        .map(|p| [p.x_m, p.y_m, p.yaw_rad])
        .next()
}

/// Speed and the curvature of the path ahead: the history's, or the navigation's where the
/// history is too short to measure one (see [`Knowing::nav_kappa`]).
fn path_motion(h: &[EgoPose], nav_kappa: Option<f64>) -> (f64, f64) {
    let (speed, kappa, measured) = history_motion(h);
    match nav_kappa {
        Some(k) if !measured && k.is_finite() => (speed, k),
        _ => (speed, kappa),
    }
}

/// Speed, path curvature and whether the curvature was measured (over more than 2 m of
/// path; else it is 0).
fn history_motion(h: &[EgoPose]) -> (f64, f64, bool) {
    let Some(last) = h.last() else {
        return (0.0, 0.0, false);
    };
    let mut len = 0.0;
    for w in h.windows(2) {
        len += (w[1].x_m - w[0].x_m).hypot(w[1].y_m - w[0].y_m);
    }
    let speed = if last.speed_mps.is_finite() && last.speed_mps >= 0.0 {
        last.speed_mps
    } else if h.len() >= 2 {
        let p = &h[h.len() - 2];
        (last.x_m - p.x_m).hypot(last.y_m - p.y_m) / (last.t_s - p.t_s).max(1e-3)
    } else {
        0.0
    };
    let first = &h[0];
    let measured = len > 2.0;
    let kappa = if measured {
        (last.yaw_rad - first.yaw_rad) / len
    } else {
        0.0
    };
    (speed, if kappa.is_finite() { kappa } else { 0.0 }, measured)
}

/// The view of camera `id`'s latest frame, read directly (see [`View::pooled`] for frames
/// read all over), with its quality measured.
fn find<'a>(input: &'a PlannerInput<'a>, id: CameraId) -> Option<View<'a>> {
    input
        .cameras
        .iter()
        .find(|c| c.calib.id == id)
        .and_then(|c| c.frames.last().map(|f| View::plain(&c.calib, f, None)))
}

/// The frame `back` frames before `latest`'s, of the same camera, sharing its measured
/// quality ([`View::sibling`]).
fn earlier<'a>(
    input: &'a PlannerInput<'a>,
    latest: Option<&View<'a>>,
    back: usize,
) -> Option<View<'a>> {
    let latest = latest?;
    let cam = input
        .cameras
        .iter()
        .find(|c| c.calib.id == latest.calib.id)?;
    let n = cam.frames.len();
    (n > back).then(|| latest.sibling(cam.frames[n - 1 - back]))
}

/// Runs every perception step on `input`.
pub fn perceive(input: &PlannerInput<'_>) -> Perception {
    perceive_with(input, false, &Knowing::default())
}

/// [`perceive`], and the nearest object in the lane to the left as well
/// ([`Perception::left_object`]; planning does not need it, so [`perceive`] skips it).
pub fn perceive_objects(input: &PlannerInput<'_>) -> Perception {
    perceive_with(input, true, &Knowing::default())
}

/// A region of one camera's latest frame that the perception knows it lost (a deficit:
/// [`crate::detect::find_deficits`] finds them), `[x0, y0, x1, y1]` in pixels.
pub type Lost = (CameraId, [f64; 4]);

/// What a driving stack knows besides its frames and its history.
#[derive(Debug, Clone, Copy, Default)]
pub struct Knowing<'a> {
    /// The regions of the latest frames known to be lost: a lamp or a sign face read inside
    /// one is no reading (a deficit's red outline is not a red lamp).
    pub lost: &'a [Lost],
    /// The navigation's path curvature, 1/m, left positive (e.g. the arc to the route's
    /// target point): the lane model's curvature when the history is too short to give one
    /// (under 2 m of path: a car standing or creeping). A car waiting in a junction to turn
    /// looks along the arc it is about to drive, not straight at the corner ahead of it.
    pub nav_kappa: Option<f64>,
    /// Look for the nearest object in the lane to the left as well
    /// ([`Perception::left_object`], as [`perceive_objects`] does): a car about to enter a
    /// junction asks, to see who is coming or starting across it.
    pub left_lane: bool,
    /// Look for a road user on the right kerb as well ([`Perception::kerb_object`]): a
    /// driver watches the sidewalk ahead for someone about to step into the road.
    pub kerb: bool,
}

/// [`perceive`] knowing what [`Knowing`] holds. With nothing known it equals [`perceive`].
pub fn perceive_knowing(input: &PlannerInput<'_>, knowing: &Knowing<'_>) -> Perception {
    perceive_with(input, knowing.left_lane, knowing)
}

/// Whether `(u, v)` of `camera`'s latest frame lies in or next to a lost region: within
/// half the region's larger side (at least 2 pixels) of it. Pixels at a lost region's edge
/// belong to what it hides (a lamp half out of a mask, the outline's blur).
fn in_lost(lost: &[Lost], camera: CameraId, u: f64, v: f64) -> bool {
    lost.iter().any(|(c, b)| {
        let m = (0.5 * (b[2] - b[0]).max(b[3] - b[1])).max(2.0);
        *c == camera && u >= b[0] - m && u <= b[2] + m && v >= b[1] - m && v <= b[3] + m
    })
}

fn perceive_with(input: &PlannerInput<'_>, left_object: bool, knowing: &Knowing<'_>) -> Perception {
    let lost = knowing.lost;
    let (speed, kappa_history) = path_motion(input.ego_history, knowing.nav_kappa);
    // A summed-area table pays off only where patches grow large, on noisy frames; clean
    // frames are read through small patches summed directly.
    let latest = |id: CameraId| {
        let v = find(input, id)?;
        Some(if v.sigma > 6.0 { v.pooled() } else { v })
    };
    let mut eyes = Eyes {
        wide: latest(CameraId::FrontWide),
        tele: latest(CameraId::FrontTele),
        past_wide: Vec::new(),
        past_tele: Vec::new(),
    };
    let sigma = eyes
        .wide
        .iter()
        .chain(eyes.tele.iter())
        .map(|v| v.sigma)
        .fold(0f32, f32::max);
    // With noise, the earlier frames are pooled too (static features only).
    if sigma > 6.0 {
        for back in 1..4 {
            let Some(pose) = pose_at(input.ego_history, -0.1 * back as f64) else {
                continue;
            };
            if let Some(v) = earlier(input, eyes.wide.as_ref(), back) {
                eyes.past_wide.push((back, v, pose));
            }
            if let Some(v) = earlier(input, eyes.tele.as_ref(), back) {
                eyes.past_tele.push((back, v, pose));
            }
        }
    }
    let white = eyes
        .wide
        .as_ref()
        .or(eyes.tele.as_ref())
        .map_or(255.0, |v| v.white);
    let gain = gain_of(white);
    let quality = ImageQuality {
        noise_sigma: f64::from(sigma),
        white: f64::from(white),
        gain: f64::from(gain),
    };
    let prior = |x: f64| 0.5 * kappa_history * x * x;
    let road = road_model(&eyes, &prior, gain);
    let lane = fit_lane(&eyes, kappa_history, &road, sigma);
    let (kappa, lane_width, lane_offset, lane_heading) = match lane {
        Some(l) => {
            // Inverse-variance fusion of the markings' curvature with the history's (whose
            // uncertainty is that of a curvature held over the next second or two), and of
            // the offset with the prior of a car that keeps its lane (centred, ±0.3 m).
            // A clean fit weighs as much as the history; a noisy one less, in proportion.
            let var_h = 0.0015f64.powi(2);
            let var_m = l.kappa_se.powi(2);
            let w = 0.5 * var_h / (var_h + var_m);
            let kappa = w * l.kappa + (1.0 - w) * kappa_history;
            let var_o = l.offset_se.powi(2).max(1e-8);
            let var_p = 0.3f64.powi(2);
            let offset = (l.offset / var_o) / (1.0 / var_o + 1.0 / var_p);
            (kappa, l.width.clamp(2.8, 4.2), offset, l.heading)
        }
        None => (kappa_history, 3.5, 0.0, 0.0),
    };
    let centre = |x: f64| lane_offset + lane_heading * x + 0.5 * kappa * x * x;
    let paint = lane.and_then(|l| l.paint_contrast).map(|c| c as f32);
    let (stop_line, zebra, zebra_end) = transverse_marks(&eyes, &centre, &road, paint);
    // Ground samples are trusted while the lane model's lateral sag stays within 3 m.
    let x_max = if kappa.abs() > 1e-6 {
        (6.0 / kappa.abs()).sqrt().min(70.0)
    } else {
        70.0
    };
    let xs: Vec<f64> = sample_distances()
        .into_iter()
        .filter(|&x| x <= x_max)
        .collect();
    // On a stop line or a crossing, grey brighter than asphalt is paint seen edge-on.
    // A reading whose patch spans ground from `x0` to `x1` (noisy patches rise in the image
    // over farther ground) is painted when that span meets the paint.
    let painted = |x0: f64, x1: f64| {
        stop_line.is_some_and(|s| x0 < s + 1.0 && x1 > s - 1.0)
            || zebra.is_some_and(|z| {
                // Where the stripes were seen to end, when that is beyond the usual 4 m (a
                // far crossing's start reads early under noise, its end does not).
                let end = zebra_end.map_or(z + 4.0, |e| e.max(z + 4.0));
                x0 < end && x1 > z - 0.5
            })
    };
    // A crossing's stripes, where they were seen (a stop line's band is too short to pass
    // for the end of the road).
    let on_zebra = |x0: f64, x1: f64| {
        zebra.is_some_and(|z| x0 < zebra_end.map_or(z + 4.0, |e| e.max(z + 4.0)) && x1 > z - 0.5)
    };
    let inner = lane_width / 2.0 - 0.4;
    let half = lane_width / 2.0;
    let ego = Span {
        shift: 0.0,
        inner,
        half,
    };
    let left = Span {
        shift: lane_width,
        inner: 1.0,
        half,
    };
    let asphalt = Ground {
        road: &road,
        paving: None,
    };
    let ego_bins = first_blocked(&eyes, &xs, &centre, ego, asphalt, &painted);
    let left_bins = first_blocked(&eyes, &xs, &centre, left, asphalt, &painted);
    // Noise hides the far edge of a T-junction from the fine bins' small patches; a step in
    // the colour of the whole road across both lanes, pooled over metres of ground and the
    // clip's frames, still shows it. Taken only with asphalt opening to the right before it
    // (what a T-junction is) and no road user before it in the ego lane, whose far side
    // could make such a step.
    let bins_end = road_end(&ego_bins, &left_bins);
    // The nearest road user in the ego lane, when the bins see no end to the road.
    let lead_any = bins_end
        .is_none()
        .then(|| lead_of(&eyes, &ego_bins, &centre, &road, speed))
        .flatten();
    let road_end = bins_end.or_else(|| {
        (sigma > 6.0)
            .then(|| road_end_step(&eyes, &centre, lane_width, gain, &on_zebra))
            .flatten()
            .filter(|&x_end| right_branch(&eyes, &centre, x_end, lane_width, gain))
            .filter(|&x_end| {
                // A road user before it hides the ground behind it from the ego lane: the
                // step may be its far side. (One at the step may be the edge itself.)
                lead_any.is_none_or(|l| l.contact_x > x_end - 2.0)
            })
    });
    let right_branch =
        road_end.is_some_and(|x_end| right_branch(&eyes, &centre, x_end, lane_width, gain));
    let lead = match road_end {
        None => lead_any,
        // With a road end, only objects clearly nearer than it count.
        Some(x_end) => {
            let mut bins = ego_bins.clone();
            for b in bins.iter_mut() {
                if *b > x_end - 3.0 {
                    *b = f64::INFINITY;
                }
            }
            lead_of(&eyes, &bins, &centre, &road, speed)
        }
    };
    let left_dashed = lane.is_some_and(|l| l.left_dashed_white);
    // Beyond the lead, the left lane is hidden behind it: look up to just past the lead.
    let horizon = lead.map_or(60.0, |l| (l.contact_x + 3.0).min(60.0));
    let left_lane_free = left_dashed
        && left_bins
            .iter()
            .enumerate()
            .filter(|&(i, &x)| x <= horizon && supported(&left_bins, i))
            .count()
            == 0;
    // Its motion, tracked over the frames (for the lead only: the detector runs more often).
    // In the ego lane a road user is only ever read as going the car's way (or standing).
    let lead = lead.map(|l| {
        let m = lead_motion(input, &eyes, &centre, speed, l);
        LeadSeen {
            speed: m.speed.max(0.0),
            ..m
        }
    });
    // Anything on a crossing that stands (along the lane, within its speed's uncertainty)
    // or moves across the lane is a road user crossing there.
    let lead = lead.map(|mut l| {
        if zebra.is_some_and(|z| l.contact_x > z - 1.0 && l.contact_x < z + 4.0)
            && (l.speed - 2.0 * l.speed_se < 2.0 || l.lateral_speed.abs() >= CROSSING_MPS)
        {
            l.kind = ObjectKind::Person;
        }
        l
    });
    let light = traffic_light(&eyes, lost);
    let stop_sign = stop_sign(&eyes, gain, lost);
    let left_object = left_object
        .then(|| {
            let left_centre = |x: f64| centre(x) + lane_width;
            lead_of(&eyes, &left_bins, &left_centre, &road, speed)
                .map(|l| lead_motion(input, &eyes, &left_centre, speed, l))
        })
        .flatten();
    let kerb_object = knowing
        .kerb
        .then(|| kerb_object(&eyes, &xs, &centre, half, &road, gain, speed, &painted))
        .flatten();
    Perception {
        speed,
        kappa_history,
        kappa,
        lane_width,
        lane_offset,
        lane_heading,
        lane,
        road_lum: road.near_lum(),
        lead,
        left_lane_free,
        road_end,
        right_branch,
        stop_line,
        zebra,
        light,
        stop_sign,
        quality,
        left_object,
        kerb_object,
    }
}

/// The nearest road user on the right kerb ([`Perception::kerb_object`]): the lane scan
/// ([`first_blocked`], [`lead_of`]) run over a strip right of the lane's marking, where
/// the ground is asphalt (a shoulder), the sidewalk's paving (measured as the road is,
/// [`ground_model`]) or a blend of both (the kerb seen from afar).
#[allow(clippy::too_many_arguments)]
fn kerb_object(
    eyes: &Eyes<'_>,
    xs: &[f64],
    centre: &dyn Fn(f64) -> f64,
    half: f64,
    road: &RoadModel,
    gain: f32,
    speed: f64,
    painted: &dyn Fn(f64, f64) -> bool,
) -> Option<LeadSeen> {
    // The strip's middle, right of the lane centre.
    let mid = half + 0.5 * (KERB_FROM_M + KERB_TO_M);
    let strip = 0.5 * (KERB_TO_M - KERB_FROM_M);
    let kerb_centre = |x: f64| centre(x) - mid;
    // The paving: the strip's outer part (a shoulder's asphalt lies at its inner edge).
    let paving = ground_model(
        eyes,
        &kerb_centre,
        gain,
        (-strip, strip - 0.6),
        (-strip, strip - 0.6),
    );
    let xs: Vec<f64> = xs.iter().copied().filter(|&x| x <= KERB_REACH_M).collect();
    let span = Span {
        shift: 0.0,
        inner: strip,
        half: strip + 0.1,
    };
    let ground = Ground {
        road,
        paving: Some(&paving),
    };
    let bins = first_blocked(eyes, &xs, &kerb_centre, span, ground, painted);
    let found = lead_of(eyes, &bins, &kerb_centre, &paving, speed)?;
    // The bins need four blocked samples in a row, which a narrow body off the camera's
    // axis gives on its far side (the ground it hides beyond it) more than on its near
    // side: the edge nearest the lane is read across the ground it stands on instead,
    // one sample at a time, inwards from the nearest bin blocked within 2 m of its contact.
    let x = found.contact_x;
    let mut edge = bins
        .iter()
        .enumerate()
        .filter(|&(_, &b)| b >= x && b < x + 2.0)
        .map(|(i, _)| (i as i32 - HALF_LANE_BINS) as f64 * BIN)
        .fold(found.left_edge.min(-strip), f64::max);
    // (Across the rows from 1.2 m short of the contact: where one camera hands over to the
    // other, the contact may read up to a metre beyond the body.)
    let covered = |on: f64, y: f64| {
        eyes.ground(on, kerb_centre(on) + y, 0.05, 0.2)
            .is_some_and(|s| ground.rejects(s, on, false))
    };
    let start = edge;
    for k in 0..=7 {
        let on = x - 1.2 + 0.2 * f64::from(k);
        let mut e = start;
        while e + 0.05 <= strip + 0.2 && covered(on, e + 0.05) {
            e += 0.05;
        }
        edge = edge.max(e);
    }
    Some(LeadSeen {
        right_edge: found.right_edge - mid,
        left_edge: edge - mid,
        ..found
    })
}

/// Per-channel median.
fn median_rgb(v: &mut [Rgb]) -> Option<Rgb> {
    if v.is_empty() {
        return None;
    }
    let mut out = [0f32; 3];
    let mid = v.len() / 2;
    for c in 0..3 {
        v.select_nth_unstable_by(mid, |a, b| a[c].total_cmp(&b[c]));
        out[c] = v[mid][c];
    }
    Some(out)
}

/// Measures the [`RoadModel`]: the near reference from grey ground 5–9 m ahead, then one
/// band per metre out to 70 m.
fn road_model(eyes: &Eyes<'_>, centre: &dyn Fn(f64) -> f64, gain: f32) -> RoadModel {
    ground_model(eyes, centre, gain, (-1.2, 1.2), (-1.4, 5.0))
}

/// A [`RoadModel`] of the ground between `lats` (m from `centre(x)`, left positive): the
/// near reference from `near` 5–9 m ahead, then one band per metre. The road's is read
/// over the ego lane and the one to its left; a sidewalk's over its paving.
fn ground_model(
    eyes: &Eyes<'_>,
    centre: &dyn Fn(f64) -> f64,
    gain: f32,
    near: (f64, f64),
    lats: (f64, f64),
) -> RoadModel {
    let band = |x0: f64, x1: f64, lo: f64, hi: f64| -> Option<Rgb> {
        let mut v = Vec::with_capacity(48);
        let mut x = x0;
        while x < x1 {
            let mut y = lo;
            while y <= hi {
                if let Some(s) = eyes.ground(x, centre(x) + y, 0.35, 0.6) {
                    v.push(s.c);
                }
                y += 0.4;
            }
            x += 0.5;
        }
        median_rgb(&mut v)
    };
    // The near reference, 5–9 m ahead.
    let near = band(5.0, 9.0, near.0, near.1).unwrap_or([90.0, 90.0, 95.0]);
    let x0 = 5.0;
    let mut cols = vec![near];
    let mut last = near;
    let mut last_x = x0;
    let mut x = x0 + RoadModel::STEP;
    while x <= 70.5 {
        if let Some(c) = band(x, x + RoadModel::STEP, lats.0, lats.1) {
            let dx = (x - last_x) as f32;
            let d = [c[0] - last[0], c[1] - last[1], c[2] - last[2]];
            // Smooth drift only: at most 3.5 levels per metre in luminance (Koschmieder
            // fog at visibility 160 m brightens asphalt by under 3 per metre), with the
            // channels moving together.
            let dx = dx.min(3.0);
            if lum(d).abs() <= 4.0 * gain + 3.5 * dx && chroma(d) <= 8.0 * gain.max(0.5) + dx {
                last = c;
                last_x = x;
            }
        }
        cols.push(last);
        x += RoadModel::STEP;
    }
    RoadModel { x0, cols, gain }
}

/// Marking points found on both sides of the ego lane, with what they tell of the left
/// boundary and the paint.
#[derive(Default)]
struct Markings {
    /// (x, y, left).
    pts: Vec<(f64, f64, bool)>,
    left_white: usize,
    left_yellow: usize,
    left_hits: usize,
    rows: usize,
    contrasts: Vec<f32>,
}

/// The distances of the rows [`find_markings`] reads, m: every 0.5 m from 5 m, every metre
/// from 15 m to 34 m.
fn marking_rows() -> impl Iterator<Item = f64> {
    std::iter::successors(Some(5.0f64), |&x| {
        Some(x + if x < 15.0 { 0.5 } else { 1.0 })
    })
    .take_while(|&x| x <= 34.0)
}

/// Looks for the markings in windows either side of `centre(x)`, the expected lane centre.
fn find_markings(eyes: &Eyes<'_>, road: &RoadModel, centre: &dyn Fn(f64) -> f64) -> Markings {
    find_markings_reaching(eyes, road, centre, 0).unwrap_or_default()
}

/// [`find_markings`], given up (`None`) as soon as it can no longer find `at_least` marking
/// points (each row adds at most two): for a search that only wants a reading finding that
/// many, the rest of the scan cannot change its outcome.
fn find_markings_reaching(
    eyes: &Eyes<'_>,
    road: &RoadModel,
    centre: &dyn Fn(f64) -> f64,
    at_least: usize,
) -> Option<Markings> {
    let mut m = Markings::default();
    let rows_total = marking_rows().count();
    for x in marking_rows() {
        if m.pts.len() + 2 * (rows_total - m.rows) < at_least {
            return None;
        }
        m.rows += 1;
        let yc = centre(x);
        let refs = road.refs(x);
        // Paint is pooled along the line (1.5 m of it) and narrowly across it.
        let dep = (0.1 * x).clamp(1.0, 2.5);
        for (left, lo, hi) in [(false, -2.5, -0.95), (true, 0.95, 2.5)] {
            // Runs of paint samples in the window; the run nearest the expected boundary
            // (about half a lane from the centre), at most 0.35 m wide, is the marking.
            // (start, end, n, yellow, brightest luminance above the asphalt)
            let mut runs: Vec<(f64, f64, usize, usize, f32)> = Vec::new();
            let mut y = lo;
            while y <= hi {
                // Pooled over the earlier frames too, unless the latest frame alone shows
                // plain asphalt (most of the window).
                let read = eyes.ground_read(x, yc + y, 0.06, dep);
                let plain_asphalt = read.is_some_and(|(_, s)| {
                    lum(s.c) - lum(refs.road) < 20.0 * refs.gain
                        && s.c[0] - s.c[2] < 30.0 * refs.gain
                });
                let pooled = read.map(|(view, first)| {
                    if plain_asphalt {
                        first
                    } else {
                        eyes.pooled_over_past(view, [x, yc + y, 0.0], first, 0.06, dep)
                    }
                });
                if let Some(s) = pooled {
                    let yl = is_yellow_paint(s, &refs);
                    if yl || is_white_paint(s, &refs) {
                        let above = lum(s.c) - lum(refs.road);
                        match runs.last_mut() {
                            Some(r) if y - r.1 < 0.06 => {
                                r.1 = y;
                                r.2 += 1;
                                r.3 += usize::from(yl);
                                r.4 = r.4.max(above);
                            }
                            _ => runs.push((y, y, 1, usize::from(yl), above)),
                        }
                    }
                }
                y += 0.04;
            }
            let expect = if left { 1.75 } else { -1.75 };
            let best = runs.iter().filter(|r| r.1 - r.0 <= 0.35).min_by(|a, b| {
                let da = (0.5 * (a.0 + a.1) - expect).abs();
                let db = (0.5 * (b.0 + b.1) - expect).abs();
                da.total_cmp(&db)
            });
            if let Some(&(a, b, n, yellow, above)) = best {
                let ym = 0.5 * (a + b);
                if yellow * 2 <= n && x < 20.0 {
                    m.contrasts.push(above);
                }
                m.pts.push((x, yc + ym, left));
                if left {
                    m.left_hits += 1;
                    if yellow * 2 > n {
                        m.left_yellow += 1;
                    } else {
                        m.left_white += 1;
                    }
                }
            }
        }
    }
    Some(m)
}

/// The least-squares fit of `y = a_side + b·x + c·x²` to marking points: `(a_right,
/// a_left, b, c, rss, var_b, var_c)` (the variances per unit residual variance), or `None`
/// when a side has fewer than three points or the points do not fix the shape.
fn fit_with_heading(pts: &[(f64, f64, bool)]) -> Option<[f64; 7]> {
    let (mut n, mut sx, mut sq, mut sy) = ([0.0f64; 2], [0.0f64; 2], [0.0f64; 2], [0.0f64; 2]);
    let (mut xx, mut xq, mut qq, mut xy, mut qy) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for &(x, y, left) in pts {
        let k = usize::from(left);
        let q = x * x;
        n[k] += 1.0;
        sx[k] += x;
        sq[k] += q;
        sy[k] += y;
        xx += x * x;
        xq += x * q;
        qq += q * q;
        xy += x * y;
        qy += q * y;
    }
    if n[0] < 3.0 || n[1] < 3.0 {
        return None;
    }
    // The side intercepts eliminated (a_k = (sy_k − b sx_k − c sq_k) / n_k): a 2×2 system
    // in (b, c) on sums centred per side.
    let centred = |u: &[f64; 2], v: &[f64; 2]| (0..2).map(|k| u[k] * v[k] / n[k]).sum::<f64>();
    let a11 = xx - centred(&sx, &sx);
    let a12 = xq - centred(&sx, &sq);
    let a22 = qq - centred(&sq, &sq);
    let r1 = xy - centred(&sx, &sy);
    let r2 = qy - centred(&sq, &sy);
    let det = a11 * a22 - a12 * a12;
    if det.abs() < 1e-9 {
        return None;
    }
    let b = (r1 * a22 - r2 * a12) / det;
    let c = (a11 * r2 - a12 * r1) / det;
    let a = [0, 1].map(|k| (sy[k] - b * sx[k] - c * sq[k]) / n[k]);
    let rss: f64 = pts
        .iter()
        .map(|&(x, y, left)| (y - a[usize::from(left)] - b * x - c * x * x).powi(2))
        .sum();
    Some([a[0], a[1], b, c, rss, a22 / det, a11 / det])
}

/// The least heading the lane fit takes from the markings, rad, and only when it stands
/// [`HEADING_MIN_Z`] standard errors clear of zero: a car keeps to its lane's direction
/// on almost every frame, and a free heading term there only adds to the offset's and the
/// curvature's scatter (measured on `fogline planner eval`: the ADE's mean under noise σ 30
/// doubles). After a turn a car can stand 4° off its lane (traced: seed 0 route 33, 0.07
/// rad), and there the term is what keeps the far marking out of the lane's interior.
const HEADING_MIN_RAD: f64 = 0.04;

/// See [`HEADING_MIN_RAD`].
const HEADING_MIN_Z: f64 = 6.0;

/// The greatest heading the fit takes from the markings, rad.
const HEADING_MAX_RAD: f64 = 0.12;

/// The lane headings relative to the car the markings are looked for along when the
/// car's own axis finds few, rad.
const HEADING_CANDIDATES_RAD: [f64; 4] = [-0.1, -0.05, 0.05, 0.1];

/// The heading is read only from markings on frames this clean (noise σ, 0–255): on noisier
/// ones the marking points pooled over the clip's frames scatter enough to fake one
/// (measured: `fogline planner eval --clips 300 --seed 11 --conditions noise_30` changed
/// three decisions with it and none without).
const HEADING_MAX_SIGMA: f32 = 12.0;

/// Fits `y = a_side + c·x²` to the marking points on both sides of the ego lane, or
/// `y = a_side + b·x + c·x²` when the markings show the lane at an angle to the car (see
/// [`HEADING_MIN_RAD`]); the markings are then looked for again along the fitted lane, as
/// the search windows follow the prior's curve, which a lane at an angle leaves within
/// metres.
fn fit_lane(eyes: &Eyes<'_>, kappa_prior: f64, road: &RoadModel, sigma: f32) -> Option<LaneSeen> {
    let m = find_markings(eyes, road, &|x| 0.5 * kappa_prior * x * x);
    if sigma <= HEADING_MAX_SIGMA {
        if let Some(lane) = fit_lane_at_angle(eyes, road, &m) {
            return Some(lane);
        }
        // A lane at an angle of a few degrees leaves the search windows within metres, so
        // the reading along the car's axis finds few markings. Where fewer than three rows
        // in four found them on both sides, look along lanes turned by the candidate
        // headings and take the reading that finds the most.
        // The reading taken is the last of those finding the most points, and only when
        // that is more than half as many again as along the axis: a candidate that can no
        // longer reach that many, nor the best one before it, is given up as it scans.
        if 4 * m.pts.len() < 6 * m.rows {
            let need = 3 * m.pts.len() / 2 + 1;
            let mut best: Option<Markings> = None;
            for &h in &HEADING_CANDIDATES_RAD {
                let floor = best.as_ref().map_or(need, |b| b.pts.len().max(need));
                let centre = |x: f64| h * x + 0.5 * kappa_prior * x * x;
                if let Some(c) = find_markings_reaching(eyes, road, &centre, floor)
                    && c.pts.len() >= floor
                {
                    best = Some(c);
                }
            }
            if let Some(best) = best
                && let Some(lane) = fit_lane_at_angle(eyes, road, &best)
            {
                return Some(lane);
            }
        }
    }
    let fit = |pts: &[(f64, f64, bool)]| -> Option<(f64, f64, f64, f64, f64)> {
        // Unknowns aR, aL, c. Normal equations.
        let (mut nr, mut nl) = (0.0, 0.0);
        let (mut sr, mut sl) = (0.0, 0.0);
        let (mut qr, mut ql) = (0.0, 0.0);
        let (mut qq, mut qy) = (0.0, 0.0);
        for &(x, y, left) in pts {
            let q = x * x;
            if left {
                nl += 1.0;
                sl += y;
                ql += q;
            } else {
                nr += 1.0;
                sr += y;
                qr += q;
            }
            qq += q * q;
            qy += q * y;
        }
        if nr < 3.0 || nl < 3.0 {
            return None;
        }
        // aR = (sr - c qr)/nr, aL = (sl - c ql)/nl; substitute into the c equation.
        let den = qq - qr * qr / nr - ql * ql / nl;
        if den.abs() < 1e-9 {
            return None;
        }
        let c = (qy - qr * sr / nr - ql * sl / nl) / den;
        Some((
            (sr - c * qr) / nr,
            (sl - c * ql) / nl,
            c,
            1.0 / nr + 1.0 / nl,
            den,
        ))
    };
    let (ar, al, c, _, _) = fit(&m.pts)?;
    // One round of outlier removal.
    let kept: Vec<(f64, f64, bool)> = m
        .pts
        .iter()
        .copied()
        .filter(|&(x, y, left)| {
            let a = if left { al } else { ar };
            (y - a - c * x * x).abs() < 0.35
        })
        .collect();
    let (ar, al, c, inv_n, den) = fit(&kept)?;
    let width = al - ar;
    if !(2.6..=4.6).contains(&width) || kept.len() < 10 {
        return None;
    }
    // Residual spread → standard errors of the offset (mean of the two sides) and of 2c.
    let rss: f64 = kept
        .iter()
        .map(|&(x, y, left)| {
            let a = if left { al } else { ar };
            (y - a - c * x * x).powi(2)
        })
        .sum();
    let s2 = (rss / (kept.len() as f64 - 3.0).max(1.0)).max(0.02f64.powi(2));
    let offset_se = (0.25 * s2 * inv_n).sqrt();
    let kappa_se = 2.0 * (s2 / den.max(1e-9)).sqrt();
    Some(lane_seen(
        m,
        kept.len(),
        [ar, al, 0.0, c],
        offset_se,
        kappa_se,
    ))
}

/// The lane with a heading term, when the markings `m` show one clearly (see
/// [`HEADING_MIN_RAD`]).
fn fit_lane_at_angle(eyes: &Eyes<'_>, road: &RoadModel, m: &Markings) -> Option<LaneSeen> {
    // The fit after one round of outlier removal, the points kept per side and the
    // residual variance, when its heading is clear.
    let fit_kept = |pts: &[(f64, f64, bool)]| -> Option<([f64; 2], [f64; 7], f64)> {
        let [ar, al, b, c, ..] = fit_with_heading(pts)?;
        let kept: Vec<(f64, f64, bool)> = pts
            .iter()
            .copied()
            .filter(|&(x, y, left)| {
                let a = if left { al } else { ar };
                (y - a - b * x - c * x * x).abs() < 0.35
            })
            .collect();
        let f = fit_with_heading(&kept)?;
        let s2 = (f[4] / (kept.len() as f64 - 4.0).max(1.0)).max(0.02f64.powi(2));
        // A clear heading, within what a car standing in its lane can have (a fit across a
        // junction's cross street is not one), with the lane centre within a lane width.
        let clear = f[2].abs() > HEADING_MIN_RAD
            && f[2].abs() <= HEADING_MAX_RAD
            && f[2].abs() > HEADING_MIN_Z * (s2 * f[5]).sqrt()
            && (0.5 * (f[0] + f[1])).abs() < 1.5;
        let mut sides = [0.0f64; 2];
        for &(_, _, left) in &kept {
            sides[usize::from(left)] += 1.0;
        }
        clear.then_some((sides, f, s2))
    };
    let (_, [ar, al, b, c, ..], _) = fit_kept(&m.pts)?;
    let mid = 0.5 * (ar + al);
    let again = find_markings(eyes, road, &|x| mid + b * x + c * x * x);
    let ([nr, nl], [ar, al, b, c, _, _, var_c], s2) = fit_kept(&again.pts)?;
    let n = (nr + nl) as usize;
    if !(2.6..=4.6).contains(&(al - ar)) || n < 10 {
        return None;
    }
    // Standard errors as for the fit without heading: of the offset from the sides' means,
    // of 2c from the fit.
    let offset_se = (0.25 * s2 * (1.0 / nr + 1.0 / nl)).sqrt();
    let kappa_se = 2.0 * (s2 * var_c).sqrt();
    Some(lane_seen(again, n, [ar, al, b, c], offset_se, kappa_se))
}

/// A [`LaneSeen`] from the fitted `[a_right, a_left, b, c]` of `n` marking points of `m`.
fn lane_seen(
    m: Markings,
    n: usize,
    [ar, al, b, c]: [f64; 4],
    offset_se: f64,
    kappa_se: f64,
) -> LaneSeen {
    let Markings {
        left_white,
        left_yellow,
        left_hits,
        rows,
        mut contrasts,
        ..
    } = m;
    LaneSeen {
        kappa: 2.0 * c,
        heading: b,
        offset: 0.5 * (al + ar),
        width: al - ar,
        points: n,
        left_dashed_white: left_white > left_yellow && left_hits * 10 < rows * 8,
        offset_se,
        kappa_se,
        paint_contrast: (contrasts.len() >= 4).then(|| {
            contrasts.sort_by(f32::total_cmp);
            f64::from(contrasts[contrasts.len() / 2])
        }),
    }
}

/// Ground distances sampled ahead: 0.25 m steps to 30 m, 0.5 m to 70 m.
fn sample_distances() -> Vec<f64> {
    let mut xs = Vec::with_capacity(200);
    let mut x = 4.5;
    while x <= 70.0 {
        xs.push(x);
        x += if x < 30.0 { 0.25 } else { 0.5 };
    }
    xs
}

/// Is the ground at `(x, y)` blocked (not the [`Ground`] expected there, nor a blend of its
/// asphalt and its paving)? `painted` marks distances with transverse paint,
/// where grey brighter than asphalt is paint seen edge-on.
#[inline]
fn blocked_at(
    eyes: &Eyes<'_>,
    ground: Ground<'_>,
    x: f64,
    y: f64,
    lat: f64,
    reach: f64,
    painted: bool,
) -> bool {
    eyes.ground_up(x, y, lat, reach)
        .is_some_and(|s| ground.rejects(s, x, painted))
}

/// The ground a bin scan expects: the asphalt, and where the scan covers a sidewalk, its
/// paving too.
#[derive(Clone, Copy)]
struct Ground<'a> {
    road: &'a RoadModel,
    paving: Option<&'a RoadModel>,
}

impl Ground<'_> {
    /// Whether reading `s` of ground `x` m ahead is none of this ground: not its asphalt
    /// (nor paint, where `painted`), not its paving, nor a blend of the two.
    #[inline]
    fn rejects(&self, s: Sample, x: f64, painted: bool) -> bool {
        let road = self.road.refs(x);
        not_road(s, &road, painted)
            && self.paving.is_none_or(|p| {
                let paving = p.refs(x);
                not_road(s, &paving, painted) && !is_mixed(s, &road, &paving)
            })
    }
}

/// Whether reading `s` is a mixture of two grounds' colours (`a`'s and `b`'s asphalt
/// references): a patch straddling where one meets the other (the kerb between a shoulder
/// and a sidewalk, seen from afar) reads as a blend of both, which is neither, but is still
/// ground. The blend nearest `s` on the line between the two colours is taken as the
/// reference.
#[inline]
fn is_mixed(s: Sample, a: &Refs, b: &Refs) -> bool {
    let d = [
        b.road[0] - a.road[0],
        b.road[1] - a.road[1],
        b.road[2] - a.road[2],
    ];
    let e = [s.c[0] - a.road[0], s.c[1] - a.road[1], s.c[2] - a.road[2]];
    let dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    if dd < 1.0 {
        return false;
    }
    let t = ((e[0] * d[0] + e[1] * d[1] + e[2] * d[2]) / dd).clamp(0.0, 1.0);
    let blend = Refs {
        road: [
            a.road[0] + t * d[0],
            a.road[1] + t * d[1],
            a.road[2] + t * d[2],
        ],
        gain: a.gain,
    };
    road_distance(s, &blend) <= 1.0
}

/// A ground reading that is neither asphalt nor paint; where `painted` (transverse paint at
/// that distance), grey brighter than asphalt is taken for paint seen edge-on.
#[inline]
fn not_road(s: Sample, refs: &Refs, painted: bool) -> bool {
    let paint_blend = painted
        && chroma(s.c) < 30.0 * refs.gain.max(0.5) + 4.5 * s.s
        && lum(s.c) > lum(refs.road) - 10.0 * refs.gain;
    !(is_road(s, refs) || paint_blend)
}

/// [`road_end`] on noisy frames, as a step in the ground's colour: where every quarter of
/// the road across the ego lane and the lane to its left (pooled over the clip's frames
/// and over metres of ground, [`ground_rect_static`]) changes from what lies just before to
/// something else that persists beyond. The far edge of a T-junction spans the road; a road
/// user covers a quarter or two of it.
fn road_end_step(
    eyes: &Eyes<'_>,
    centre: &dyn Fn(f64) -> f64,
    lane_width: f64,
    gain: f32,
    on_zebra: &dyn Fn(f64, f64) -> bool,
) -> Option<f64> {
    const SEGMENTS: usize = 4;
    // Half-metre slices of each segment from X0 on, read once; windows average them.
    const X0: f64 = 9.0;
    const SLICE: f64 = 0.5;
    const SLICES: usize = 131;
    let (y0, y1) = (-lane_width / 2.0 + 0.3, 1.5 * lane_width - 0.3);
    let seg_w = (y1 - y0) / SEGMENTS as f64;
    let floor = 12.0 * gain;
    // Read on first use: most frames have no step in the first segment, and the others
    // are then never read.
    let slices: Vec<Vec<std::cell::OnceCell<Option<Sample>>>> = (0..SEGMENTS)
        .map(|_| (0..SLICES).map(|_| std::cell::OnceCell::new()).collect())
        .collect();
    let slice = |k: usize, i: usize| {
        *slices[k][i].get_or_init(|| {
            let (a, b) = (y0 + k as f64 * seg_w, y0 + (k + 1) as f64 * seg_w);
            let x = X0 + SLICE * i as f64;
            let c = centre(x + 0.5 * SLICE);
            ground_rect_static(eyes, x, x + SLICE, c + a, c + b)
        })
    };
    // The mean of segment `k` over `x0..x1`, when most of its slices were seen.
    let window = |k: usize, x0: f64, x1: f64| -> Option<Sample> {
        let i0 = ((x0 - X0) / SLICE) as usize;
        let i1 = (((x1 - X0) / SLICE) as usize).min(SLICES);
        if i0 >= i1 {
            return None;
        }
        let (mut sum, mut var, mut m) = ([0f32; 3], 0f32, 0usize);
        for q in (i0..i1).filter_map(|i| slice(k, i)) {
            for ch in 0..3 {
                sum[ch] += q.c[ch];
            }
            var += q.s * q.s;
            m += 1;
        }
        if m == 0 || m * 2 < i1 - i0 {
            return None;
        }
        let m = m as f32;
        Some(Sample {
            c: sum.map(|v| v / m),
            s: var.sqrt() / m,
        })
    };
    let differs = |a: Sample, b: Sample| {
        let (d, n) = step_between(a, b);
        d > floor.max(6.0 * n)
    };
    let mut x = 15.0;
    while x <= 62.0 {
        let steps = !on_zebra(x - 6.0, x - 1.0)
            && (0..SEGMENTS).all(|k| {
                // What lies before is one stretch of road (no paint, no object), and what
                // lies beyond differs from it near, farther and farther still.
                let (Some(b0), Some(b1)) =
                    (window(k, x - 6.0, x - 3.5), window(k, x - 3.5, x - 1.0))
                else {
                    return false;
                };
                if differs(b0, b1) {
                    return false;
                }
                let Some(before) = window(k, x - 6.0, x - 1.0) else {
                    return false;
                };
                [(0.5, 2.5), (3.0, 6.0), (7.0, 12.0)]
                    .iter()
                    .all(|&(a, b)| window(k, x + a, x + b).is_some_and(|w| differs(w, before)))
            });
        if steps {
            return Some(x);
        }
        x += 0.5;
    }
    None
}

/// The mean colour of the ground rectangle `x0..x1` × `y0..y1` (rig frame, m) over the
/// clip's frames (static ground; ego motion from the history), read through every pixel it
/// covers in the camera that sees its middle.
fn ground_rect_static(eyes: &Eyes<'_>, x0: f64, x1: f64, y0: f64, y1: f64) -> Option<Sample> {
    let (xm, ym) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
    let view = eyes.view_for([xm, ym, 0.0])?;
    let past = if view.calib.id == CameraId::FrontTele {
        &eyes.past_tele
    } else {
        &eyes.past_wide
    };
    let read = |v: &View<'_>, pose: Option<[f64; 3]>| {
        let at = |x: f64, y: f64| {
            let p = pose.map_or([x, y, 0.0], |q| into_pose([x, y, 0.0], q));
            v.project_any(p)
        };
        let (ul, _, _) = at(xm, y1)?;
        let (ur, _, _) = at(xm, y0)?;
        let (_, vn, _) = at(x0, ym)?;
        let (_, vf, _) = at(x1, ym)?;
        let rows = (vn - vf).max(1.0);
        v.rect(
            round_px(ul.min(ur)),
            round_px(vf),
            round_px(ul.max(ur)),
            round_px(vf + rows),
        )
        .map(|(c, n)| (c, n as f32, v.sigma))
    };
    let mut parts = vec![read(view, None)?];
    for (_, v, pose) in past {
        if let Some(r) = read(v, Some(*pose)) {
            parts.push(r);
        }
    }
    let k = parts.len() as f32;
    let mut c = [0f32; 3];
    let mut var = 0f32;
    for (pc, n, sigma) in &parts {
        for i in 0..3 {
            c[i] += pc[i] / k;
        }
        var += sigma * sigma / n / (k * k);
    }
    Some(Sample { c, s: var.sqrt() })
}

/// Colour distance between two readings over its noise: `(distance, noise)`.
fn step_between(a: Sample, b: Sample) -> (f32, f32) {
    let d = [a.c[0] - b.c[0], a.c[1] - b.c[1], a.c[2] - b.c[2]];
    (
        (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt(),
        (a.s * a.s + b.s * b.s).sqrt(),
    )
}

/// The lane a bin scan covers: its centre `shift` m left of the ego lane's, the half-width
/// `inner` of its sampled interior and its half-width `half` to the markings, m.
#[derive(Clone, Copy)]
struct Span {
    shift: f64,
    inner: f64,
    half: f64,
}

/// For each lateral bin of the lane `lane` (see [`Span`]), the first distance
/// at which the ground is not road (four samples in a row), or `+inf`.
fn first_blocked(
    eyes: &Eyes<'_>,
    xs: &[f64],
    centre: &dyn Fn(f64) -> f64,
    lane: Span,
    ground: Ground<'_>,
    painted: &dyn Fn(f64, f64) -> bool,
) -> Vec<f64> {
    let Span { shift, inner, half } = lane;
    (-HALF_LANE_BINS..=HALF_LANE_BINS)
        .map(|b| {
            if (f64::from(b) * BIN).abs() > inner {
                return f64::NAN; // not sampled: on or beyond the lane's markings
            }
            let y = shift + f64::from(b) * BIN;
            // Patches rise over farther ground only on noisy frames (see `Eyes::ground_up`).
            let rises = eyes.wide.as_ref().is_some_and(|v| v.sigma > 12.0);
            // Pool across at most 0.5 m, and never onto the lane's markings (a blend of
            // paint and asphalt is neither).
            let lat = (2.0 * (inner + 0.2 - (f64::from(b) * BIN).abs())).clamp(0.1, 0.25);
            // Four blocked samples in a row: an object occludes the ground behind it, a
            // painted line seen at a grazing angle does not.
            let mut run = 0;
            for (i, &x) in xs.iter().enumerate() {
                // A patch rising in the image reads ground farther out *and* farther from
                // the camera's axis (image columns fan out on the ground): it may rise only
                // as far as keeps it off the lane's outer marking.
                let yr = centre(x) + y;
                let room = (half - 0.1 - f64::from(b) * BIN * yr.signum()).max(0.05);
                let reach = (x * room / (2.0 * yr.abs().max(1e-3))).clamp(0.3, 4.0);
                let rise = if rises { reach } else { 0.0 };
                let blocked = blocked_at(eyes, ground, x, yr, lat, reach, painted(x, x + rise));
                run = if blocked { run + 1 } else { 0 };
                if run == 4 {
                    return xs[i - 3];
                }
            }
            f64::INFINITY
        })
        .collect()
}

/// Bin `i` is blocked and so is a neighbour within two bins, at about the same distance
/// (3 m): a road user is wider than one bin; a single blocked bin is a speck of noise.
fn supported(bins: &[f64], i: usize) -> bool {
    let x = bins[i];
    x.is_finite()
        && (i.saturating_sub(2)..(i + 3).min(bins.len()))
            .any(|j| j != i && (bins[j] - x).abs() < 3.0)
}

/// The road ends where (nearly) every bin of the ego lane and of the lane to its left is
/// blocked at about the same distance.
fn road_end(ego: &[f64], left: &[f64]) -> Option<f64> {
    // Bins outside the lane interiors are NaN (not sampled).
    let all: Vec<f64> = ego
        .iter()
        .chain(left)
        .copied()
        .filter(|x| !x.is_nan())
        .collect();
    if all.is_empty() {
        return None;
    }
    let finite: Vec<f64> = all.iter().copied().filter(|x| x.is_finite()).collect();
    // Noise hides some of the far edge; three quarters of the bins must see it.
    if finite.len() * 4 < all.len() * 3 {
        return None;
    }
    let mut s = finite.clone();
    s.sort_by(f64::total_cmp);
    let med = s[s.len() / 2];
    let near = s.iter().filter(|&&x| (x - med).abs() < 3.0).count();
    (near * 10 >= all.len() * 7).then_some(med)
}

/// Asphalt opening to the right of the lane before the road end: somewhere in the last
/// two and a half lane widths, two metres of ground 1–4 m right of the lane, pooled over the
/// clip's frames ([`ground_rect_static`]), have the colour of the lane beside them (a
/// sidewalk or a verge does not; a road branching off does). The road end is read where the
/// ground stops being road, which is at the far side of the branch, or of its sidewalk.
fn right_branch(
    eyes: &Eyes<'_>,
    centre: &dyn Fn(f64) -> f64,
    x_end: f64,
    w: f64,
    gain: f32,
) -> bool {
    let mut x = x_end - 2.5 * w;
    while x + 2.0 <= x_end {
        let c = centre(x + 1.0);
        let lane = ground_rect_static(eyes, x, x + 2.0, c - w / 2.0 + 0.3, c + w / 2.0 - 0.3);
        let right = ground_rect_static(eyes, x, x + 2.0, c - w / 2.0 - 4.0, c - w / 2.0 - 1.0);
        if lane.zip(right).is_some_and(|(l, r)| {
            let (d, n) = step_between(l, r);
            d < (12.0 * gain).max(6.0 * n)
        }) {
            return true;
        }
        x += 1.0;
    }
    false
}

fn lead_of(
    eyes: &Eyes<'_>,
    bins: &[f64],
    centre: &dyn Fn(f64) -> f64,
    road: &RoadModel,
    ego_speed: f64,
) -> Option<LeadSeen> {
    let finite: Vec<(f64, f64)> = bins
        .iter()
        .enumerate()
        .filter(|(_, x)| x.is_finite())
        .map(|(i, &x)| ((i as i32 - HALF_LANE_BINS) as f64 * BIN, x))
        .collect();
    // The object: the nearest contact with a blocked neighbour bin and at least three bins
    // blocked within 6 m of it; a lone blocked bin is a speck, not a road user.
    let mut order: Vec<(f64, f64)> = finite.clone();
    order.sort_by(|a, b| a.1.total_cmp(&b.1));
    let (contact, obj) = order.iter().find_map(|&(at, c)| {
        let obj: Vec<(f64, f64)> = finite
            .iter()
            .copied()
            .filter(|p| p.1 >= c && p.1 < c + 6.0)
            .collect();
        // Lateral neighbours of the contact bin within the object.
        let near = obj.iter().filter(|p| (p.0 - at).abs() <= 3.5 * BIN).count();
        // A narrow road user (a walker is 0.3 m across) blocks few bins at its contact,
        // but it also hides the ground behind it from the bins whose rays pass its body:
        // bins blocked farther on, along the same bearing from the camera, are its support.
        let support = || {
            let (cx, cy) = eyes
                .view_for([c, centre(c) + at, 0.0])
                .map_or((0.0, 0.0), |v| (v.calib.x_m, v.calib.y_m));
            let bearing = |y: f64, x: f64| (y - cy) / (x - cx).max(1.0);
            let lo = bearing(centre(c) + at - 0.25, c);
            let hi = bearing(centre(c) + at + 0.25, c);
            finite
                .iter()
                .filter(|p| {
                    p.1 >= c
                        && p.1 < c + 30.0
                        && (lo..=hi).contains(&bearing(centre(p.1) + p.0, p.1))
                })
                .count()
        };
        (near >= 2 && (obj.len() >= 3 || support() >= 3)).then_some((c, obj))
    })?;
    let right_edge = obj.iter().map(|p| p.0).fold(f64::INFINITY, f64::min);
    let left_edge = obj.iter().map(|p| p.0).fold(f64::NEG_INFINITY, f64::max);
    // Widths at body height (0.5 m) and cabin/torso height (1.3 m), just behind the contact:
    // a vehicle is wide at both, a pedestrian at neither, a cyclist only at the bicycle.
    let xw = contact + 0.4;
    let mid = 0.5 * (left_edge + right_edge);
    let width_at = |z: f64| {
        // What lies behind a point at height z seen past the object: the ground where the
        // line of sight meets it.
        let cam_h = 1.6;
        let behind = if z < cam_h - 0.05 {
            (xw * cam_h / (cam_h - z)).min(70.0)
        } else {
            70.0
        };
        let refs = road.refs(behind);
        // The contiguous run of object pixels through the object's middle (background seen
        // past a narrow object is usually not contiguous with it).
        let hit = |b: i32| {
            let y = centre(xw) + mid + f64::from(b) * BIN;
            eyes.point([xw, y, z], 0.15, if z > 1.0 { 0.8 } else { 0.5 })
                .is_some_and(|s| is_object(s, &refs))
        };
        let start = (-3..=3).find(|&b| hit(b));
        let Some(b0) = start else { return 0.0 };
        // Noise drops single samples from a face: the run bridges one missed bin.
        let (mut lo, mut hi) = (b0, b0);
        while lo > -25 {
            if hit(lo - 1) {
                lo -= 1;
            } else if lo > -24 && hit(lo - 2) {
                lo -= 2;
            } else {
                break;
            }
        }
        while hi < 25 {
            if hit(hi + 1) {
                hi += 1;
            } else if hi < 24 && hit(hi + 2) {
                hi += 2;
            } else {
                break;
            }
        }
        f64::from(hi - lo + 1) * BIN
    };
    let (low, high) = (width_at(0.5), width_at(1.3));
    let width_m = low.min(high);
    // Ground contact across ≥ 1.2 m (two wheels) or a wide body: a vehicle.
    let kind = if width_m >= 1.0 || left_edge - right_edge >= 1.2 {
        ObjectKind::Vehicle
    } else {
        ObjectKind::Person
    };
    // Confidence: the face just above the contact, pooled over the object's width, against
    // the asphalt it hides.
    let confidence = {
        let refs = road.refs(contact);
        let y0 = centre(contact) + mid;
        eyes.point(
            [contact + 0.2, y0, 0.45],
            (left_edge - right_edge).max(0.3),
            0.5,
        )
        .map_or(0.0, |s| {
            f64::from((road_distance(s, &refs) - 0.5).clamp(0.0, 1.0))
        })
    };
    let braking = brake_lamps(eyes, contact, centre);
    // Untracked until `lead_motion`: the ego's own speed, with no uncertainty claimed.
    Some(LeadSeen {
        contact_x: contact,
        gap: contact - REAR_WHEEL_TO_BUMPER - fogline_types::motion::EGO_FRONT_M,
        speed: ego_speed,
        speed_se: 0.0,
        lateral_speed: 0.0,
        braking,
        kind,
        width_m,
        right_edge,
        left_edge,
        confidence,
        track: [Some(contact), None, None, None],
    })
}

/// How far a vehicle's rear wheels touch the ground ahead of its rear bumper, m.
const REAR_WHEEL_TO_BUMPER: f64 = 0.57;

/// Lit red lamps on the rear of the object whose contact is at `contact`: patches sized to a
/// lamp (about 0.2 m) or smaller, scanned over the rear face.
fn brake_lamps(eyes: &Eyes<'_>, contact: f64, centre: &dyn Fn(f64) -> f64) -> bool {
    let view = if contact >= TELE_FROM_M {
        eyes.tele.as_ref().or(eyes.wide.as_ref())
    } else {
        eyes.wide.as_ref()
    };
    let Some(view) = view else {
        return false;
    };
    let x = contact - REAR_WHEEL_TO_BUMPER;
    let yc = centre(x);
    let corners = [[x - 0.2, yc + 1.2, 1.2], [x - 0.2, yc - 1.2, 0.55]];
    let (Some(a), Some(b)) = (view.project_any(corners[0]), view.project_any(corners[1])) else {
        return false;
    };
    let lamp_px = 0.2 * view.calib.fx / (x - view.calib.x_m).max(1.0);
    let k = lamp_patch(view.sigma, lamp_px);
    let (w, h) = (view.width() as f64, view.height() as f64);
    let (u0, u1) = (a.0.min(b.0).max(0.0), a.0.max(b.0).min(w - 1.0));
    let (v0, v1) = (a.1.min(b.1).max(0.0), a.1.max(b.1).min(h - 1.0));
    let step = (k as f64 / 2.0).max(1.0);
    let mut n = 0.0;
    let mut v = v0;
    while v <= v1 {
        let mut u = u0;
        while u <= u1 {
            if let Some(s) = view.patch(u + 0.5, v + 0.5, k, k)
                && lamp_colour(s, view.white) == Some(LampColour::Red)
            {
                n += step * step;
            }
            u += step;
        }
        v += step;
    }
    n >= 2.0
}

/// At most this many template samples on a lead's face (about one per pixel up close, sparser
/// on a large face).
const MAX_FACE_SAMPLES: f64 = 500.0;

/// `lead` with its motion found by registering its rear face between frames, as a tracker
/// does (unchanged, untracked, when the face cannot be followed). The face
/// at `t0` (a vertical plane at its bumper, across the width the bins found and up to 1.5 m,
/// box-filtered against the noise and sampled about every other pixel) is the template. In
/// each earlier frame, the face's position then — along the lane and across it — is the one
/// whose image matches the template best: a coarse grid over both, then line searches along,
/// across and along again, each refined by a parabola fitted to the costs around its least.
/// Every pixel of the face votes, so noise that moves one edge by a pixel, or a speck that a
/// contact scan would stop at, barely moves the match; and a road user crossing the lane is
/// followed across it instead of being lost. The speeds are the least-squares slopes of the
/// positions over time in the rig frame at `t0` (ego motion removed through the history's
/// poses); the track holds the contacts.
fn lead_motion(
    input: &PlannerInput<'_>,
    eyes: &Eyes<'_>,
    centre: &dyn Fn(f64) -> f64,
    ego_speed: f64,
    lead: LeadSeen,
) -> LeadSeen {
    let (contact0, right, left) = (lead.contact_x, lead.right_edge, lead.left_edge);
    let mut track = [Some(contact0), None, None, None];
    let untracked = |track| LeadSeen { track, ..lead };
    let tele = contact0 >= TELE_FROM_M && eyes.tele.is_some();
    let (latest, past) = if tele {
        (eyes.tele.as_ref(), &eyes.past_tele)
    } else {
        (eyes.wide.as_ref(), &eyes.past_wide)
    };
    let Some(view0) = latest else {
        return untracked(track);
    };
    let face = contact0 - REAR_WHEEL_TO_BUMPER;
    let (y0, y1, z0, z1) = (right - 0.15, left + 0.15, 0.05, 1.5);
    // Noise is filtered away before matching (a k × k box takes σ to σ/k); samples then
    // need be no denser than half the box.
    let k = ((view0.sigma / 6.0).ceil() as usize).clamp(3, 7) | 1;
    let px = (face - view0.calib.x_m).max(1.0) / view0.calib.fx;
    let step =
        (px * (k as f64 / 2.0).max(1.0)).max(((y1 - y0) * (z1 - z0) / MAX_FACE_SAMPLES).sqrt());
    // The face's corners at distance `x` as seen from `pose`, as a pixel rectangle with a
    // margin for the filter.
    let corners = |view: &View<'_>, xs: &[f64], pad: f64, pose: [f64; 3]| {
        let (mut u0, mut v0, mut u1, mut v1) = (
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        );
        for &x in xs {
            let yc = centre(x);
            for (y, z) in [
                (y0 - pad, z0),
                (y0 - pad, z1),
                (y1 + pad, z0),
                (y1 + pad, z1),
            ] {
                let (u, v, _) = view.project_any(into_pose([x, yc + y, z], pose))?;
                (u0, v0, u1, v1) = (u0.min(u), v0.min(v), u1.max(u), v1.max(v));
            }
        }
        let m = k as f64 + 2.0;
        Some((u0 - m, v0 - m, u1 + m, v1 + m))
    };
    let Some(now) = corners(view0, &[face], 0.0, [0.0; 3]).and_then(|r| Smoothed::new(view0, r, k))
    else {
        return untracked(track);
    };
    // The template: (lateral offset from the lane centre, height, colour).
    let yc = centre(face);
    let mut template: Vec<(f64, f64, Rgb)> = Vec::new();
    let mut z = z0;
    while z <= z1 {
        let mut y = y0;
        while y <= y1 {
            if let Some((u, v, _)) = view0.project([face, yc + y, z])
                && let Some(c) = now.bilinear(u, v)
            {
                template.push((y, z, c));
            }
            y += step;
        }
        z += step;
    }
    if template.len() < 30 {
        return untracked(track);
    }
    let mut ts = vec![0.0];
    let mut xs = vec![face];
    let mut ys = vec![0.0];
    let (mut v_hat, mut lat_hat) = (ego_speed, 0.0);
    for back in 1..4 {
        let t = -0.1 * back as f64;
        let pose = pose_at(input.ego_history, t).unwrap_or([ego_speed * t, 0.0, 0.0]);
        let owned;
        let view = match past.iter().find(|p| p.0 == back) {
            Some(p) => &p.1,
            None => {
                owned = earlier(input, Some(view0), back);
                match owned.as_ref() {
                    Some(v) => v,
                    None => continue,
                }
            }
        };
        // The first earlier frame allows any speed within 15 m/s of the ego's and a road
        // user crossing at up to 6 m/s; later ones search near the motion found so far.
        let (x_prior, y_prior) = (face + v_hat * t, lat_hat * t);
        let (x_half, y_half) = if back == 1 { (1.5, 0.6) } else { (0.8, 0.4) };
        let reach = [x_prior - x_half - 0.3, x_prior + x_half + 0.3];
        let Some(then) = corners(view, &reach, y_prior.abs() + y_half + 0.1, pose)
            .and_then(|r| Smoothed::new(view, r, k))
        else {
            continue;
        };
        // Mean squared colour difference with the face at `x`, `dy` beside where it was
        // (following the lane); `None` when too few samples are in the frame, or as soon
        // as the cost is sure to exceed `bound` (the sum only grows, and at most every
        // sample is read: the partial sum over that count bounds the mean from below).
        let cost = |x: f64, dy: f64, stride: usize, bound: f64| -> Option<f64> {
            let plane = view.plane(x, centre(x) + dy, pose);
            let most = template.len().div_ceil(stride) as f64;
            let (mut sum, mut n) = (0.0f64, 0usize);
            for (i, &(y, z, c)) in template.iter().step_by(stride).enumerate() {
                if let Some((u, v)) = plane.uv(y, z)
                    && let Some(d) = then.bilinear(u, v)
                {
                    let e = (d[0] - c[0]).powi(2) + (d[1] - c[1]).powi(2) + (d[2] - c[2]).powi(2);
                    sum += f64::from(e);
                    n += 1;
                }
                if i % 16 == 15 && sum / most > bound {
                    return None;
                }
            }
            (n * stride * 10 >= template.len() * 7).then(|| sum / n as f64)
        };
        // A coarse grid over both (on every third sample), then along the lane, across it
        // and along again from its best cell. The grid's cells are read in order and the
        // first least one wins; a cell is given up once it is sure to cost more than the
        // best so far or than the prior's own cell (read first), which cannot change the
        // winner and saves most of the reads.
        let mut cell = None;
        let (nx, ny) = ((x_half / 0.2).round() as i32, (y_half / 0.1).round() as i32);
        let at_prior = cost(x_prior, y_prior, 3, f64::INFINITY).unwrap_or(f64::INFINITY);
        for i in -nx..=nx {
            for j in -ny..=ny {
                let (x, y) = (x_prior + 0.2 * f64::from(i), y_prior + 0.1 * f64::from(j));
                let bound = cell.map_or(at_prior, |(_, _, b): (f64, f64, f64)| b.min(at_prior));
                // The prior's own cell was read already (and is never given up: its cost
                // bounds the rest).
                let read = if (i, j) == (0, 0) {
                    at_prior.is_finite().then_some(at_prior)
                } else {
                    cost(x, y, 3, bound)
                };
                if let Some(c) = read
                    && cell.is_none_or(|(_, _, b)| c < b)
                {
                    cell = Some((x, y, c));
                }
            }
        }
        let Some((x, dy, _)) = cell else { continue };
        let full = |x, dy| cost(x, dy, 1, f64::INFINITY);
        let Some(x) = best_match(&|x| full(x, dy), x, 0.4, 0.1) else {
            continue;
        };
        let dy = best_match(&|y| full(x, y), dy, 0.2, 0.05).unwrap_or(dy);
        let x = best_match(&|x| full(x, dy), x, 0.2, 0.05).unwrap_or(x);
        ts.push(t);
        xs.push(x);
        ys.push(dy);
        track[back] = Some(x + REAR_WHEEL_TO_BUMPER);
        if let (Some((v, _)), Some((l, _))) = (slope(&ts, &xs), slope(&ts, &ys)) {
            (v_hat, lat_hat) = (v, l);
        }
    }
    match (slope(&ts, &xs), slope(&ts, &ys)) {
        (Some((v, se)), Some((lateral, _))) => LeadSeen {
            speed: v.max(0.0),
            speed_se: se,
            lateral_speed: lateral,
            track,
            ..lead
        },
        _ => untracked(track),
    }
}

/// The position within `centre ± half` (grid `step`) where `cost` is least, refined by a
/// parabola fitted to the costs of the seven grid points around it; `None` when the least
/// cost lies on the edge of the range (the match is outside it) or cannot be read.
fn best_match(cost: &dyn Fn(f64) -> Option<f64>, centre: f64, half: f64, step: f64) -> Option<f64> {
    let n = (half / step).round() as i32;
    let at = |i: i32| centre + f64::from(i) * step;
    let costs: Vec<f64> = (-n..=n)
        .map(|i| cost(at(i)).unwrap_or(f64::INFINITY))
        .collect();
    let (i, c) = costs.iter().enumerate().min_by(|a, b| a.1.total_cmp(b.1))?;
    if !c.is_finite() || i == 0 || i + 1 == costs.len() {
        return None;
    }
    // Least-squares parabola c = a·d² + b·d + e over the window, d in grid steps from i.
    let (lo, hi) = (i.saturating_sub(3), (i + 3).min(costs.len() - 1));
    let (mut s, mut sd, mut sd2, mut sd3, mut sd4) = (0.0, 0.0, 0.0, 0.0, 0.0);
    let (mut sc, mut sdc, mut sd2c) = (0.0, 0.0, 0.0);
    for (j, &cj) in costs.iter().enumerate().take(hi + 1).skip(lo) {
        if !cj.is_finite() {
            continue;
        }
        let d = j as f64 - i as f64;
        s += 1.0;
        sd += d;
        sd2 += d * d;
        sd3 += d * d * d;
        sd4 += d * d * d * d;
        sc += cj;
        sdc += d * cj;
        sd2c += d * d * cj;
    }
    // Normal equations of the 3 × 3 system, by Cramer's rule.
    let det3 = |m: [[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let m = [[sd4, sd3, sd2], [sd3, sd2, sd], [sd2, sd, s]];
    let det = det3(m);
    let off = if s >= 3.0 && det.abs() > 1e-9 {
        let a = det3([[sd2c, sd3, sd2], [sdc, sd2, sd], [sc, sd, s]]) / det;
        let b = det3([[sd4, sd2c, sd2], [sd3, sdc, sd], [sd2, sc, s]]) / det;
        if a > 0.0 {
            (-b / (2.0 * a)).clamp(-1.0, 1.0)
        } else {
            0.0
        }
    } else {
        0.0
    };
    Some(at(i as i32 - n) + off * step)
}

/// Least-squares slope of `xs` over `ts` and its standard error (at least that of a 2 cm
/// scatter); `None` for fewer than two points.
fn slope(ts: &[f64], xs: &[f64]) -> Option<(f64, f64)> {
    if ts.len() < 2 {
        return None;
    }
    let n = ts.len() as f64;
    let (mt, mx) = (ts.iter().sum::<f64>() / n, xs.iter().sum::<f64>() / n);
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (t, x) in ts.iter().zip(xs) {
        sxy += (t - mt) * (x - mx);
        sxx += (t - mt) * (t - mt);
    }
    let v = sxy / sxx.max(1e-9);
    let ssr: f64 = ts
        .iter()
        .zip(xs)
        .map(|(t, x)| (x - mx - v * (t - mt)).powi(2))
        .sum();
    let var = (ssr / (n - 2.0).max(1.0)).max(0.02f64.powi(2));
    let se = (var / sxx.max(1e-9)).sqrt();
    (v.is_finite() && se.is_finite()).then_some((v, se))
}

/// Stop line (a solid white band across the lane) and zebra (half-covered bands over ≥ 2 m)
/// along the lane centre. At each distance the share of white across the lane is read from
/// the mean brightness of the ground strip ±1.2 m around the centre (one pooled strip of
/// pixels), between the asphalt's level and the paint's.
fn transverse_marks(
    eyes: &Eyes<'_>,
    centre: &dyn Fn(f64) -> f64,
    road: &RoadModel,
    paint: Option<f32>,
) -> (Option<f64>, Option<f64>, Option<f64>) {
    // The paint's contrast near the car: as measured on the lane markings, else what white
    // paint on asphalt reads in daylight scaled by the exposure.
    let near_contrast = paint.unwrap_or(140.0 * road.gain).max(20.0 * road.gain);
    let mut profile: Vec<(f64, f64)> = Vec::new();
    let mut x = 4.5;
    while x <= 60.0 {
        let refs = road.refs(x);
        let yc = centre(x);
        // Fog pulls paint and asphalt toward the airlight alike, shrinking their contrast
        // as the asphalt brightens with distance.
        let fog = ((lum(refs.road) - road.near_lum()) / 140.0).clamp(0.0, 0.9);
        let contrast = near_contrast * (1.0 - fog);
        // Eight strips of 0.3 m across the lane; strips that a road user hides (clearly
        // darker or more coloured than asphalt and paint) are left out.
        let (mut sum, mut n) = (0.0, 0);
        for k in 0..8 {
            let y0 = yc - 1.2 + 0.3 * f64::from(k);
            let Some(s) = strip_mean(eyes, x, y0, y0 + 0.3, 0.1) else {
                continue;
            };
            let se = s.s / 3f32.sqrt();
            let d = lum(s.c) - lum(refs.road);
            let dc = [
                s.c[0] - refs.road[0],
                s.c[1] - refs.road[1],
                s.c[2] - refs.road[2],
            ];
            if d < -(20.0 * refs.gain + 3.0 * se)
                || chroma(dc) > 40.0 * refs.gain.max(0.5) + 4.5 * s.s
            {
                continue;
            }
            // Noise makes the share uncertain; shrink it toward "none" by one standard error.
            sum += f64::from(((d - se) / contrast).clamp(0.0, 1.0));
            n += 1;
        }
        let share = if n >= 3 {
            sum / f64::from(n)
        } else {
            profile.last().map_or(0.0, |p| p.1)
        };
        profile.push((x, share));
        x += 0.1;
    }
    let mut stop = None;
    let mut zebra = None;
    let mut zebra_end = None;
    let mut i = 0;
    while i < profile.len() {
        if profile[i].1 >= 0.7 {
            let start = profile[i].0;
            let mut j = i;
            while j < profile.len() && profile[j].1 >= 0.7 {
                j += 1;
            }
            let len = profile[j - 1].0 - start;
            if len <= 1.2 && stop.is_none() {
                stop = Some(start + len / 2.0);
            }
            i = j;
            continue;
        }
        if (0.25..0.7).contains(&profile[i].1) && zebra.is_none() {
            let start = profile[i].0;
            let mut j = i;
            while j < profile.len() && (0.2..0.8).contains(&profile[j].1) {
                j += 1;
            }
            if profile[j.min(profile.len() - 1)].0 - start >= 2.0 {
                zebra = Some(start);
                zebra_end = Some(profile[j.min(profile.len() - 1)].0);
            }
            i = j.max(i + 1);
            continue;
        }
        i += 1;
    }
    (stop, zebra, zebra_end)
}

/// The mean over the ground strip from `(x, y0)` to `(x, y1)`, `dep` m deep: one rectangle of
/// pixels in the camera that reads distance `x`.
fn strip_mean(eyes: &Eyes<'_>, x: f64, y0: f64, y1: f64, dep: f64) -> Option<Sample> {
    let view = eyes.view_for([x, 0.5 * (y0 + y1), 0.0])?;
    let (ua, va, _) = view.project_any([x, y0, 0.0])?;
    let (ub, vb, _) = view.project_any([x, y1, 0.0])?;
    let rows = (view.calib.fy * view.calib.z_m * dep / (x * x)).max(1.0);
    let v = 0.5 * (va + vb);
    let (u0, u1) = (ua.min(ub), ua.max(ub));
    let y0p = round_exact(v - rows / 2.0);
    view.rect_sample(
        round_exact(u0),
        y0p,
        round_exact(u1),
        y0p + round_pos(rows).max(1) as isize,
    )
}

/// The side of the square patch that reads a lamp `lamp_px` pixels across: enough pixels
/// to quiet noise `sigma`, but well inside the lamp (at most 60 % of it) so that the
/// patch's mean is the lamp's colour and not a mix with its housing.
fn lamp_patch(sigma: f32, lamp_px: f64) -> usize {
    let want = (f64::from(sigma) / 6.0).ceil().max(1.0);
    want.min((0.6 * lamp_px).floor()).max(1.0) as usize
}

/// The mean of the `k × k` block whose top-left pixel is `(u, v)` (the pixel itself for
/// `k = 1`).
#[inline]
fn block(view: &View<'_>, u: usize, v: usize, k: usize) -> Option<Sample> {
    if k == 1 {
        return Some(Sample {
            c: view.pixel(u, v),
            s: view.sigma,
        });
    }
    view.rect_sample(u as isize, v as isize, (u + k) as isize, (v + k) as isize)
}

/// Lamp-coloured blocks of a view's region: the block side follows the noise (so a block's
/// mean is clean enough to read its hue) and is at most `max_k` pixels.
fn lamp_blocks(
    view: &View<'_>,
    u_range: (usize, usize),
    v_range: (usize, usize),
    max_k: usize,
) -> (usize, Vec<(LampColour, usize, usize)>) {
    let k = lamp_patch(view.sigma, max_k as f64 / 0.6);
    // Blocks of 3 px or more overlap by half their side, so that a lamp only a little wider
    // than a block still holds one whole block whatever its position (smaller blocks tile).
    let step = if k >= 3 { k.div_ceil(2) } else { k };
    let mut out = Vec::new();
    let mut v = v_range.0;
    while v + k <= v_range.1 {
        let mut u = u_range.0;
        while u + k <= u_range.1 {
            // Both lamp tests start by asking for the white level (a lamp is an emitter):
            // most blocks end at that test, here without a call.
            if let Some(s) = block(view, u, v, k)
                && s.c[0].max(s.c[1]) + 2.0 * s.s >= 0.9 * view.white
                && let Some(col) =
                    lamp_colour(s, view.white).or_else(|| veiled_lamp(view, s, (u, v), k))
            {
                out.push((col, u, v));
            }
            u += step;
        }
        v += step;
    }
    (k, out)
}

/// The colour of a lamp washed out by a veil ([`lamp_colour_over`]), read against its
/// housing: the darkest of the blocks around block `(u, v)`, two and four block sides away
/// in the eight directions (a lamp's housing surrounds it; the unlit lamps above and below
/// are as dark). Only bright blocks with some hue are tested: the grey sky is not.
fn veiled_lamp(view: &View<'_>, s: Sample, (u, v): (usize, usize), k: usize) -> Option<LampColour> {
    let [r, g, b] = s.c;
    let top = r.max(g);
    if top + 2.0 * s.s < 0.9 * view.white || top - r.min(g).min(b) < 0.2 * view.white + 3.0 * s.s {
        return None;
    }
    let mut housing: Option<Sample> = None;
    // `k` is at least 1 (see `lamp_patch`).
    for step in [2 * k as isize, 4 * k as isize] {
        for (du, dv) in NEIGHBOURS_8 {
            let (bu, bv) = (u as isize + du * step, v as isize + dv * step);
            if bu < 0 || bv < 0 || bu as usize + k > view.width() || bv as usize + k > view.height()
            {
                continue;
            }
            if let Some(n) = block(view, bu as usize, bv as usize, k)
                && housing.is_none_or(|h| lum(n.c) < lum(h.c))
            {
                housing = Some(n);
            }
        }
    }
    lamp_colour_over(s, housing?, view.white)
}

/// The farthest a signal head is read, m (the world's junctions put a head up to about
/// 90 m ahead of a car that begins braking for it).
const LAMP_READ_MAX_M: f64 = 100.0;
/// Height of the lowest lamp's lower edge (the green lamp, centre 4.88 m), m.
const LAMP_LOWEST_M: f64 = 4.7;

/// Lit lamps above the horizon: the colour with the most lamp pixels in one compact
/// cluster, and a distance from the lamp's elevation (signal heads hang about 5 m up).
fn traffic_light(eyes: &Eyes<'_>, lost: &[Lost]) -> Option<(Lamp, f64)> {
    for view in [&eyes.tele, &eyes.wide].into_iter().flatten() {
        let cy = view.calib.cy;
        // Nothing nearer the horizon than the lowest lamp seen from `LAMP_READ_MAX_M`: the
        // band just above it holds the far street (the red outline of a walker's mask, tail
        // lights on a crest), which read as heads hundreds of metres away (traced: seed 0
        // route 34, a red 'seen' 750 m off held the car at a stop sign's line).
        let rows_far = view.calib.fy * (LAMP_LOWEST_M - view.calib.z_m) / LAMP_READ_MAX_M;
        let top = (cy - rows_far.max(2.0)).max(0.0) as usize;
        let w = view.width();
        let lo = (w as f64 * 0.2) as usize;
        let hi = (w as f64 * 0.8) as usize;
        // Signal heads (lamps 4.9–5.5 m up) seen from 8 m or further lie within these rows.
        let rows_up = (view.calib.fy * (5.6 - view.calib.z_m) / 8.0).ceil();
        let first = (cy - rows_up).max(0.0) as usize;
        let (k, blocks) = lamp_blocks(view, (lo, hi), (first, top), 3);
        let reach = 6usize.max(2 * k);
        // The largest compact cluster of each colour outside the lost regions: (pixels, mean
        // row).
        let compact = |col: LampColour| -> (usize, f64) {
            let pts: Vec<(usize, usize)> = blocks
                .iter()
                .filter(|b| b.0 == col)
                .map(|b| (b.1, b.2))
                .collect();
            let mut best: (usize, f64) = (0, 0.0);
            for &(u0, v0) in pts.iter().take(400) {
                let near: Vec<&(usize, usize)> = pts
                    .iter()
                    .filter(|p| p.0.abs_diff(u0) <= reach && p.1.abs_diff(v0) <= reach)
                    .collect();
                if near.len() * k * k > best.0 {
                    let half = k as f64 / 2.0;
                    let vm =
                        near.iter().map(|p| p.1 as f64).sum::<f64>() / near.len() as f64 + half;
                    if !lost.is_empty() {
                        let um =
                            near.iter().map(|p| p.0 as f64).sum::<f64>() / near.len() as f64 + half;
                        if in_lost(lost, view.calib.id, um, vm) {
                            continue;
                        }
                    }
                    best = (near.len() * k * k, vm);
                }
            }
            best
        };
        let best = [
            (Lamp::Red, compact(LampColour::Red), 5.52),
            (Lamp::Amber, compact(LampColour::Amber), 5.2),
            (Lamp::Green, compact(LampColour::Green), 4.88),
        ]
        .into_iter()
        .max_by_key(|(_, (n, _), _)| *n)?;
        let (lamp, (n, vmean), h) = best;
        if n >= 3 {
            let elev = (cy - vmean) / view.calib.fy;
            let dist = if elev > 1e-3 {
                (h - view.calib.z_m) / elev
            } else {
                80.0
            };
            return Some((lamp, dist + view.calib.x_m));
        }
    }
    None
}

/// The world's stop sign as a driver knows it: a red octagon 0.74 m across its corners and
/// 0.68 m across its flats (flat at the top), inside a white rim, a white legend across its
/// middle, its centre 2.25 m up: 0.65 m above the cameras.
const SIGN_FACE_M: f64 = 0.684;
/// Height of a stop sign's centre above the cameras, m.
const SIGN_RISE_M: f64 = 0.65;
/// The farthest a stop sign is read, m (from the camera).
const SIGN_READ_MAX_M: f64 = 50.0;

/// A stop sign: a *face* of sign red right of the lane and above the horizon, whose size
/// and elevation give one distance.
///
/// Red blocks (single pixels on clean frames; on noisy ones blocks large enough for their
/// mean to be judged) are grouped into 8-connected components, largest first, and a
/// component is a face when it
/// - is red as paint is red through haze ([`is_sign_red`], or [`is_sign_red_hazed`]: fog
///   adds the same grey to every channel, so the ratios of the channels fall with distance
///   but their differences only with the transmission);
/// - is about as tall as wide (an octagon), does not touch the frame's edge (a cut face's
///   width is no measure of its distance), and its width and the elevation of its centre
///   give the same distance within a pixel's rounding of each;
/// - is red *throughout*: its middle holds red and the white legend, never a dark core (a
///   lost region — a black fill inside a red outline — is not a sign, however red its
///   ring), and its colour is lit paint, which reflects some of every channel (a full-scale
///   pure red with no green or blue is an overlay: a deficit's outline, too small for a
///   fill in the wide view);
/// - stands right of the lane and is not in a region the perception knows it lost.
///
/// The telephoto view is read first (a face 20 m away is 17 px across in it), then the
/// wide view (3–4 px at 20 m, 7 px at 10 m, where the sign has left the telephoto view).
fn stop_sign(eyes: &Eyes<'_>, gain: f32, lost: &[Lost]) -> Option<f64> {
    for view in [&eyes.tele, &eyes.wide].into_iter().flatten() {
        if let Some(d) = sign_in_view(view, gain, lost) {
            return Some(d + view.calib.x_m);
        }
    }
    None
}

/// An 8-connected component of sign-red blocks: the blocks' top-left pixels and the
/// component's pixel box (`u1`, `v1` exclusive).
struct RedBlob {
    blocks: Vec<(usize, usize)>,
    u0: usize,
    u1: usize,
    v0: usize,
    v1: usize,
}

/// The distance (from the camera) of the nearest-looking stop-sign face in one view.
fn sign_in_view(view: &View<'_>, gain: f32, lost: &[Lost]) -> Option<f64> {
    let (cx, cy) = (view.calib.cx, view.calib.cy);
    let w = view.width();
    let k = lamp_patch(view.sigma, 10.0);
    // A face (centre 0.65 m above the camera, 0.84 m tall with its rim) seen from 6 m or
    // further lies within these rows above the horizon.
    let rows_up = (view.calib.fy * (SIGN_RISE_M + 0.45) / 6.0).ceil();
    let v_first = (cy - rows_up).max(0.0) as usize;
    let v_end = (cy - 1.0).max(0.0) as usize;
    let u_first = cx as usize + 3;
    if v_end < v_first + k || u_first + k > w {
        return None;
    }
    let (gw, gh) = ((w - u_first) / k, (v_end - v_first) / k);
    let at = |i: usize, j: usize| (u_first + i * k, v_first + j * k);
    let red: Vec<bool> = (0..gw * gh)
        .map(|c| {
            let (u, v) = at(c % gw, c / gw);
            // On noisy frames a block's hue is uncertain: only the strict test (the hazed
            // one's margins let noisy dusk sky and warm walls through: phantom signs in
            // `fogline planner eval` at noise σ 30).
            block(view, u, v, k)
                .is_some_and(|s| is_sign_red(s, gain) || (k == 1 && is_sign_red_hazed(s, gain)))
        })
        .collect();
    let mut seen = vec![false; red.len()];
    let mut blobs: Vec<RedBlob> = Vec::new();
    let mut stack = Vec::new();
    for start in 0..red.len() {
        if !red[start] || seen[start] {
            continue;
        }
        seen[start] = true;
        stack.push(start);
        let mut blob = RedBlob {
            blocks: Vec::new(),
            u0: usize::MAX,
            u1: 0,
            v0: usize::MAX,
            v1: 0,
        };
        while let Some(c) = stack.pop() {
            let (i, j) = (c % gw, c / gw);
            let (u, v) = at(i, j);
            blob.blocks.push((u, v));
            blob.u0 = blob.u0.min(u);
            blob.u1 = blob.u1.max(u + k);
            blob.v0 = blob.v0.min(v);
            blob.v1 = blob.v1.max(v + k);
            for (di, dj) in NEIGHBOURS_8 {
                let (ni, nj) = (i as isize + di, j as isize + dj);
                if ni < 0 || nj < 0 || ni >= gw as isize || nj >= gh as isize {
                    continue;
                }
                let n = nj as usize * gw + ni as usize;
                if red[n] && !seen[n] {
                    seen[n] = true;
                    stack.push(n);
                }
            }
        }
        blobs.push(blob);
    }
    blobs.sort_by_key(|b| std::cmp::Reverse(b.blocks.len()));
    blobs
        .iter()
        .take(8)
        .find_map(|b| sign_face(view, b, k, lost))
}

/// The distance (from the camera) of the stop sign whose face `b` is, if it is one (see
/// [`stop_sign`]).
fn sign_face(view: &View<'_>, b: &RedBlob, k: usize, lost: &[Lost]) -> Option<f64> {
    let (cx, cy) = (view.calib.cx, view.calib.cy);
    let (fx, fy) = (view.calib.fx, view.calib.fy);
    let n_px = b.blocks.len() * k * k;
    let (w_px, h_px) = ((b.u1 - b.u0) as f64, (b.v1 - b.v0) as f64);
    // At least 2 × 2 pixels and 4 of them: nothing smaller has a shape.
    if n_px < 4 || w_px < 2.0 || h_px < 2.0 {
        return None;
    }
    // As tall as wide, within a pixel's rounding of each side.
    if h_px > 1.5 * w_px + 1.0 || w_px > 1.5 * h_px + 1.0 {
        return None;
    }
    // A face cut by the frame's edge (the telephoto view close up) has no measurable width.
    if b.u1 + k > view.width() || b.v0 < k {
        return None;
    }
    let u_mid = 0.5 * (b.u0 + b.u1) as f64;
    let v_mid = 0.5 * (b.v0 + b.v1) as f64;
    let rise_px = cy - v_mid;
    if rise_px <= 0.0 {
        return None;
    }
    // Width and elevation agree: the ranges each allows with a block of rounding (a pixel
    // on clean frames) overlap.
    let by_width = |px: f64| fx * SIGN_FACE_M / px.max(0.5);
    let by_rise = |px: f64| SIGN_RISE_M * fy / px.max(0.5);
    let kf = k as f64;
    let (w_near, w_far) = (by_width(w_px + kf), by_width(w_px - kf));
    let (e_near, e_far) = (by_rise(rise_px + kf), by_rise(rise_px - kf));
    if w_near.max(e_near) > w_far.min(e_far) {
        return None;
    }
    // Each reading weighted by how many pixels it spans.
    let (d_w, d_e) = (by_width(w_px), by_rise(rise_px));
    let d = (d_w * w_px + d_e * rise_px) / (w_px + rise_px);
    // Beyond 50 m a face is a few pixels even in the telephoto view (other red specks are
    // as large), and a stop from the 8 m/s cruise needs 13 m: such a sign is read later.
    if d > SIGN_READ_MAX_M {
        return None;
    }
    // Signs stand beside the road: its centre well right of the lane.
    let lateral = -(u_mid - cx) * d / fx;
    if lateral > -2.0 || in_lost(lost, view.calib.id, u_mid, v_mid) {
        return None;
    }
    // Lit paint: the face's mean colour reflects some green and blue.
    let mut face = [0f32; 3];
    let mut s2 = 0f32;
    for &(u, v) in &b.blocks {
        let s = block(view, u, v, k)?;
        for (f, c) in face.iter_mut().zip(s.c) {
            *f += c;
        }
        s2 += s.s * s.s;
    }
    let n = b.blocks.len() as f32;
    let face = face.map(|c| c / n);
    let face_s = (s2 / n).sqrt() / n.sqrt();
    if face[1].max(face[2]) + 2.0 * face_s < 0.06 * face[0] {
        return None;
    }
    // No dark core: the middle third of the box (at least one pixel each way) holds red and
    // the white legend; a pixel darker than half the face's luminance is neither, and a
    // quarter of them is a hole.
    let third = |a: usize, b: usize| {
        let len = b - a;
        let m = len.div_ceil(3).max(1);
        let lo = a + (len - m) / 2;
        (lo, lo + m)
    };
    let ((mu0, mu1), (mv0, mv1)) = (third(b.u0, b.u1), third(b.v0, b.v1));
    let dark_below = 0.5 * lum(face);
    let (mut dark, mut all) = (0usize, 0usize);
    for v in mv0..mv1 {
        for u in mu0..mu1 {
            all += 1;
            dark += usize::from(lum(view.pixel(u, v)) + 2.0 * view.sigma < dark_below);
        }
    }
    if 4 * dark >= all.max(1) {
        return None;
    }
    Some(d)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_lane_fit_reads_the_heading_of_a_lane_at_an_angle() {
        // Markings 3.5 m apart, the lane turned 0.07 rad to the left of the car (where a
        // car stands after a turn), a gentle curve and ±2 cm of scatter.
        let (b, c) = (0.07, 0.002);
        let mut pts = Vec::new();
        for i in 0..40 {
            let x = 5.0 + 0.75 * f64::from(i);
            let wiggle = 0.02 * if i % 2 == 0 { 1.0 } else { -1.0 };
            pts.push((x, -1.75 + b * x + c * x * x + wiggle, false));
            pts.push((x, 1.75 + b * x + c * x * x - wiggle, true));
        }
        let [ar, al, fb, fc, rss, var_b, _] = fit_with_heading(&pts).unwrap();
        assert!((fb - b).abs() < 2e-3, "heading {fb}");
        assert!((fc - c).abs() < 1e-4, "c {fc}");
        assert!(
            (ar + 1.75).abs() < 0.02 && (al - 1.75).abs() < 0.02,
            "{ar} {al}"
        );
        // Clear by the gate's measure: many standard errors from zero.
        let s2 = rss / (pts.len() as f64 - 4.0);
        assert!(fb / (s2 * var_b).sqrt() > HEADING_MIN_Z);
        // The same lane straight ahead: no heading.
        let straight: Vec<_> = pts.iter().map(|&(x, y, l)| (x, y - b * x, l)).collect();
        let [.., fb0, _, _, _, _] = fit_with_heading(&straight).unwrap();
        assert!(fb0.abs() < 2e-3, "heading {fb0}");
        // Too few points on a side: no fit.
        assert!(fit_with_heading(&pts[..4]).is_none());
    }

    #[test]
    fn a_standing_car_looks_along_the_navigations_arc_a_moving_one_along_its_own() {
        let pose = |t_s: f64, x_m: f64, yaw_rad: f64| EgoPose {
            t_s,
            x_m,
            y_m: 0.0,
            yaw_rad,
            speed_mps: 0.0,
        };
        // Standing: four poses at the origin, no path to measure a curvature on.
        let standing: Vec<EgoPose> = (0..4)
            .map(|k| pose(-0.1 * f64::from(3 - k), 0.0, 0.0))
            .collect();
        assert_eq!(path_motion(&standing, None).1, 0.0);
        assert_eq!(path_motion(&standing, Some(-0.125)).1, -0.125);
        assert_eq!(path_motion(&standing, Some(f64::NAN)).1, 0.0);
        // Moving 3 m on an arc of curvature 0.02: the history's own curvature stands.
        let moving: Vec<EgoPose> = (0..4)
            .map(|k| {
                let back = f64::from(3 - k);
                pose(-0.1 * back, -back, -0.02 * back)
            })
            .collect();
        let (_, k) = path_motion(&moving, Some(-0.125));
        assert!((k - 0.02).abs() < 1e-9, "{k}");
    }

    #[test]
    fn a_lone_blocked_bin_is_a_speck_and_a_neighbour_supports_it() {
        let inf = f64::INFINITY;
        let bins = [
            inf, 7.8, inf, inf, inf, 30.0, 31.0, inf, 40.0, inf, inf, 60.0,
        ];
        // 7.8: nothing blocked within two bins; 30.0 and 31.0 support each other; 40.0 has
        // 31.0 two bins away but 9 m farther; 60.0 is alone at the edge.
        let supported: Vec<usize> = (0..bins.len()).filter(|&i| supported(&bins, i)).collect();
        assert_eq!(supported, vec![5, 6]);
        assert!(!super::supported(&[f64::NAN, 5.0, f64::NAN], 1));
    }

    #[test]
    fn the_road_ends_where_most_bins_of_both_lanes_are_blocked_at_one_distance() {
        let inf = f64::INFINITY;
        let nan = f64::NAN;
        // A T-junction: every sampled bin blocked at 36 m ± 1 m, the unsampled ones NaN.
        let ego = [nan, 36.0, 36.5, 35.5, 36.0, nan];
        let left = [nan, 36.0, 37.0, 36.0, nan];
        assert_eq!(road_end(&ego, &left), Some(36.0));
        // A car in the ego lane only: the left lane is open, so the road goes on.
        let left_open = [nan, inf, inf, inf, nan];
        assert_eq!(road_end(&ego, &left_open), None);
        // Blocked at scattered distances: no single far edge.
        let scattered = [nan, 12.0, 25.0, 40.0, 55.0, nan];
        assert_eq!(road_end(&scattered, &left), None);
        assert_eq!(road_end(&[nan, nan], &[]), None);
    }

    #[test]
    fn rounding_and_summed_areas_agree_with_the_plain_ways() {
        // Half away from zero exactly, where `x + 0.5` would not be.
        for x in [
            0.0,
            0.49999999999999994,
            0.5,
            1.5,
            2.4999999999999996,
            2.5,
            7.25,
            1e15 + 0.5,
            4503599627370497.0,
        ] {
            assert_eq!(round_pos(x), x.round() as usize, "{x}");
        }
        assert_eq!(round_pos(f64::NAN), 0);
        for x in [
            -0.5,
            -0.49999999999999994,
            -2.5,
            -7.75,
            3.5,
            -1e15 - 0.5,
            0.0,
            -0.0,
        ] {
            assert_eq!(round_exact(x), x.round() as isize, "{x}");
        }
        assert_eq!(round_exact(f64::NAN), 0);
        assert_eq!(round_exact(1e300), isize::MAX);
        // A summed-area table's patch means equal the pixels summed directly.
        let calib = fogline_types::clip::CameraCalib::standard(CameraId::FrontWide, 23, 11);
        let rgb: Vec<u8> = (0..23 * 11 * 3).map(|i| (i * 37 % 251) as u8).collect();
        let plain = View::plain(&calib, &rgb, Some(0.0));
        let pooled = View::plain(&calib, &rgb, Some(0.0)).pooled();
        for (x0, y0, x1, y1) in [
            (0, 0, 23, 11),
            (3, 2, 9, 7),
            (-4, 5, 30, 6),
            (22, 10, 23, 11),
        ] {
            assert_eq!(plain.rect(x0, y0, x1, y1), pooled.rect(x0, y0, x1, y1));
        }
        // Rectangles past what one packed look-up sums exactly (8,224 pixels of 255) are
        // summed in bands: still exact, on a saturated frame and a busy one.
        let calib = fogline_types::clip::CameraCalib::standard(CameraId::FrontWide, 300, 200);
        for fill in [|_| 255u8, |i: usize| (i * 7919 % 256) as u8] {
            let rgb: Vec<u8> = (0..300 * 200 * 3).map(fill).collect();
            let plain = View::plain(&calib, &rgb, Some(0.0));
            let pooled = View::plain(&calib, &rgb, Some(0.0)).pooled();
            for (x0, y0, x1, y1) in [
                (0, 0, 300, 200),
                (0, 0, 91, 91),
                (0, 0, 92, 90),
                (10, 3, 11, 200),
                (-5, 17, 299, 140),
                (150, 0, 151, 1),
            ] {
                assert_eq!(plain.rect(x0, y0, x1, y1), pooled.rect(x0, y0, x1, y1));
            }
        }
    }

    /// Issue 17: the stop-sign reader on synthetic frames drawn from the sign's geometry
    /// (not from the renderer, and with no seed the reader was tuned on).
    mod stop_sign_reader {
        use super::super::*;
        use fogline_types::clip::CameraCalib;

        /// The closed loop's cameras: wide 192 × 144 at 90°, tele 256 × 192 at 30°.
        pub(super) fn cams() -> (CameraCalib, CameraCalib) {
            let mut wide = CameraCalib::standard(CameraId::FrontWide, 192, 144);
            wide.fx = 96.0;
            wide.fy = 96.0;
            let tele = CameraCalib::standard(CameraId::FrontTele, 256, 192);
            (wide, tele)
        }

        /// What a frame shows at each pixel: `None` for the background (sky above the
        /// horizon, asphalt below).
        pub(super) type Painter<'a> = &'a dyn Fn([f64; 3]) -> Option<[f32; 3]>;

        /// A frame of `calib` with solids painted by `paint`, which gets the ray (rig frame,
        /// unit along the optical axis); `veil` is the Koschmieder transmission of
        /// everything painted (airlight 204), `light` the scene's light.
        pub(super) fn frame(
            calib: &CameraCalib,
            paint: Painter<'_>,
            light: f32,
            veil: f32,
        ) -> Vec<u8> {
            let (w, h) = (calib.width as usize, calib.height as usize);
            let mut rgb = vec![0u8; w * h * 3];
            for v in 0..h {
                for u in 0..w {
                    let ray = calib.ray(u as f64 + 0.5, v as f64 + 0.5);
                    let c = match paint(ray) {
                        Some(c) => c.map(|x| x * light * veil + 204.0 * (1.0 - veil)),
                        None if ray[2] > 0.0 => [150.0, 170.0, 200.0].map(|x| x * light),
                        None => [90.0, 90.0, 95.0].map(|x| x * light),
                    };
                    for (k, x) in c.iter().enumerate() {
                        rgb[(v * w + u) * 3 + k] = x.round().clamp(0.0, 255.0) as u8;
                    }
                }
            }
            rgb
        }

        /// A regular octagon with flats at the top, apothem `a`, at offset `(y, z)`.
        fn octagon(y: f64, z: f64, a: f64) -> bool {
            y.abs() <= a && z.abs() <= a && y.abs() + z.abs() <= a * std::f64::consts::SQRT_2
        }

        /// Where the ray from `calib`'s camera meets the plane `x = x_m`, as `(y, z)`.
        pub(super) fn on_plane(calib: &CameraCalib, ray: [f64; 3], x_m: f64) -> Option<(f64, f64)> {
            if ray[0] <= 1e-9 {
                return None;
            }
            let t = (x_m - calib.x_m) / ray[0];
            Some((calib.y_m + t * ray[1], calib.z_m + t * ray[2]))
        }

        /// The world's stop sign facing the camera, `dist_m` ahead of it and 3.15 m to the
        /// right (where the towns put it for a car in its lane): a red octagon (apothem
        /// 0.342 m) in a white rim (0.388 m), a white legend 0.36 × 0.09 m, centre 2.25 m up.
        fn sign(calib: &CameraCalib, dist_m: f64, ray: [f64; 3]) -> Option<[f32; 3]> {
            let (y, z) = on_plane(calib, ray, calib.x_m + dist_m)?;
            let (dy, dz) = (y + 3.15, z - 2.25);
            if dy.abs() <= 0.18 && dz.abs() <= 0.045 {
                Some([240.0; 3])
            } else if octagon(dy, dz, 0.342) {
                Some([196.0, 22.0, 32.0])
            } else if octagon(dy, dz, 0.388) {
                Some([240.0; 3])
            } else {
                None
            }
        }

        /// `f` on the eyes of these cameras' clean frames (no earlier frames).
        pub(super) fn with_eyes<R>(
            wide_rgb: &[u8],
            tele_rgb: &[u8],
            f: impl FnOnce(&Eyes<'_>) -> R,
        ) -> R {
            let (wide, tele) = cams();
            let eyes = Eyes {
                wide: Some(View::plain(&wide, wide_rgb, Some(0.0))),
                tele: Some(View::plain(&tele, tele_rgb, Some(0.0))),
                past_wide: Vec::new(),
                past_tele: Vec::new(),
            };
            f(&eyes)
        }

        fn read(wide_rgb: &[u8], tele_rgb: &[u8], lost: &[Lost]) -> Option<f64> {
            with_eyes(wide_rgb, tele_rgb, |eyes| {
                let white = eyes.wide.as_ref().map_or(255.0, |v| v.white);
                stop_sign(eyes, gain_of(white), lost)
            })
        }

        /// Draws a deficit's mask over the pixel box `(u0, v0, u1, v1)`: black inside a
        /// 2-pixel outline of pure red (as `fogline-perturb` draws it).
        pub(super) fn mask(
            rgb: &mut [u8],
            w: usize,
            (u0, v0, u1, v1): (usize, usize, usize, usize),
        ) {
            for v in v0..v1 {
                for u in u0..u1 {
                    let ring = u < u0 + 2 || u + 2 >= u1 || v < v0 + 2 || v + 2 >= v1;
                    let px = if ring { [255, 0, 0] } else { [0, 0, 0] };
                    rgb[(v * w + u) * 3..(v * w + u) * 3 + 3].copy_from_slice(&px);
                }
            }
        }

        /// The pixel box of the sign's face (with its rim) in `calib`'s frame.
        fn face_box(calib: &CameraCalib, dist_m: f64) -> (usize, usize, usize, usize) {
            let x = calib.x_m + dist_m;
            let (a, _, _) = calib.project([x, -3.15 + 0.42, 2.25 + 0.42]).unwrap();
            let (_, b, _) = calib.project([x, -3.15 + 0.42, 2.25 + 0.42]).unwrap();
            let (c, d, _) = calib.project([x, -3.15 - 0.42, 2.25 - 0.42]).unwrap();
            (
                a.floor() as usize,
                b.floor() as usize,
                c.ceil() as usize,
                d.ceil() as usize,
            )
        }

        #[test]
        fn a_sign_is_read_at_every_distance_a_stop_needs_in_clear_air_haze_and_at_night() {
            let (wide, tele) = cams();
            // A car at 8 m/s needs 12.8 m at 2.5 m/s²; from 28 m in the telephoto view, from
            // 21 m in the wide view alone (the telephoto's sign hidden), down to 8 m where
            // it has left the telephoto view.
            for (light, veil_per_m) in [(1.0f32, 0.0f64), (0.55, 0.0), (0.88, 3.912 / 120.0)] {
                for dist_m in [8.0, 10.0, 13.0, 16.0, 19.0, 21.0, 23.0, 25.0, 28.0] {
                    let veil = (-veil_per_m * dist_m).exp() as f32;
                    let paint = |c: &CameraCalib| {
                        let c = *c;
                        move |ray: [f64; 3]| sign(&c, dist_m, ray)
                    };
                    let w = frame(&wide, &paint(&wide), light, veil);
                    let t = frame(&tele, &paint(&tele), light, veil);
                    let truth = dist_m + wide.x_m;
                    let got = read(&w, &t, &[]);
                    assert!(
                        got.is_some_and(|d| (d - truth).abs() <= 0.2 * truth),
                        "light {light} veil {veil:.2} at {dist_m} m: {got:?}"
                    );
                    // The wide view alone (the telephoto's sign masked and known lost): its
                    // face is 3 px across at 21 m, enough to stop from the cruise in time;
                    // at 25 m (2.6 px) it is not read.
                    if dist_m <= 22.0 {
                        let mut t_masked = t.clone();
                        let bx = face_box(&tele, dist_m);
                        let bx = (bx.0, bx.1, bx.2.min(256), bx.3);
                        mask(&mut t_masked, 256, bx);
                        let lost = [(
                            CameraId::FrontTele,
                            [bx.0 as f64, bx.1 as f64, bx.2 as f64, bx.3 as f64],
                        )];
                        let got = read(&w, &t_masked, &lost);
                        assert!(
                            got.is_some_and(|d| (d - truth).abs() <= 0.25 * truth),
                            "wide only, light {light} veil {veil:.2} at {dist_m} m: {got:?}"
                        );
                    }
                }
            }
        }

        #[test]
        fn a_deficits_mask_is_no_sign_whether_or_not_it_is_known_lost() {
            let (wide, tele) = cams();
            let empty = |_: [f64; 3]| None;
            for dist_m in [8.0, 12.0, 16.0, 20.0, 25.0, 35.0] {
                let mut w = frame(&wide, &empty, 1.0, 1.0);
                let mut t = frame(&tele, &empty, 1.0, 1.0);
                let bw = face_box(&wide, dist_m);
                mask(&mut w, 192, bw);
                let bt = face_box(&tele, dist_m);
                if bt.2 <= 256 {
                    mask(&mut t, 256, bt);
                }
                assert_eq!(read(&w, &t, &[]), None, "mask at {dist_m} m ({bw:?})");
            }
        }

        #[test]
        fn red_cars_brake_lamps_and_signal_lamps_are_no_sign() {
            let (wide, tele) = cams();
            for dist_m in [8.0, 12.0, 18.0, 25.0, 35.0] {
                // A red car parked at the kerb (body 0.3–1.5 m up), its lit brake lamps at
                // 1.0 m, and a red van's box up to 2.9 m beside it; a red signal lamp 5.5 m up.
                let things = |c: CameraCalib| {
                    move |ray: [f64; 3]| {
                        let (y, z) = on_plane(&c, ray, c.x_m + dist_m)?;
                        if (y + 3.4).abs() <= 0.9
                            && (z - 1.0).abs() <= 0.12
                            && (y + 3.4).abs() >= 0.6
                        {
                            Some([255.0, 34.0, 28.0])
                        } else if ((y + 3.4).abs() <= 0.9 && (0.3..=1.5).contains(&z))
                            || ((y + 6.0).abs() <= 1.1 && (0.5..=2.9).contains(&z))
                        {
                            // The car's body and the van's box: the same paint.
                            Some([150.0, 28.0, 30.0])
                        } else if (y - 1.5).powi(2) + (z - 5.5).powi(2) <= 0.15f64.powi(2) {
                            Some([255.0, 42.0, 30.0])
                        } else {
                            None
                        }
                    }
                };
                for light in [1.0f32, 0.55] {
                    let w = frame(&wide, &things(wide), light, 1.0);
                    let t = frame(&tele, &things(tele), light, 1.0);
                    assert_eq!(read(&w, &t, &[]), None, "at {dist_m} m, light {light}");
                }
            }
        }
    }

    /// The kerb scan on synthetic frames ray-cast from a street's geometry (not from the
    /// renderer): asphalt, the lane's edge line, a shoulder, a sidewalk's paving and grass
    /// beyond it, with or without a walker standing on the paving or the shoulder.
    mod kerb_scan {
        use super::super::*;
        use super::stop_sign_reader::cams;
        use fogline_types::clip::CameraCalib;

        /// A walker: standing at `(x, y)` (its body's middle), 0.4 m deep, 0.5 m across,
        /// 1.75 m tall; dark trousers below 0.9 m, a shirt above.
        #[derive(Clone, Copy)]
        struct Walker {
            x: f64,
            y: f64,
            legs: [f32; 3],
            shirt: [f32; 3],
        }

        /// The ground's colour at `(x, y)`: the lane centred on `y = 0` (3.5 m wide, its
        /// right edge line 0.15 m wide), a 0.5 m shoulder, the kerb at y = −2.25, 3 m of
        /// paving and grass beyond; the road's left half and the opposite lane up to 5.75.
        fn ground(y: f64) -> [f32; 3] {
            if (-1.85..=-1.70).contains(&y) {
                [225.0, 225.0, 220.0]
            } else if (-2.25..=5.75).contains(&y) {
                [90.0, 90.0, 95.0]
            } else if (-5.25..-2.25).contains(&y) {
                [165.0, 163.0, 160.0]
            } else {
                [80.0, 120.0, 60.0]
            }
        }

        /// A frame of `calib` of the street with `walker` on it, under `light`.
        fn frame(calib: &CameraCalib, walker: Option<Walker>, light: f32) -> Vec<u8> {
            let (w, h) = (calib.width as usize, calib.height as usize);
            let o = [calib.x_m, calib.y_m, calib.z_m];
            let mut rgb = vec![0u8; w * h * 3];
            for v in 0..h {
                for u in 0..w {
                    let d = calib.ray(u as f64 + 0.5, v as f64 + 0.5);
                    // The ground, where the ray meets it.
                    let mut best = (f64::INFINITY, [150.0f32, 170.0, 200.0]);
                    if d[2] < 0.0 {
                        let t = -o[2] / d[2];
                        best = (t, ground(o[1] + t * d[1]));
                    }
                    // The walker's box (slabs).
                    if let Some(wk) = walker {
                        let lo = [wk.x - 0.2, wk.y - 0.25, 0.0];
                        let hi = [wk.x + 0.2, wk.y + 0.25, 1.75];
                        let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
                        for k in 0..3 {
                            if d[k].abs() < 1e-12 {
                                if o[k] < lo[k] || o[k] > hi[k] {
                                    t0 = f64::INFINITY;
                                }
                                continue;
                            }
                            let (a, b) = ((lo[k] - o[k]) / d[k], (hi[k] - o[k]) / d[k]);
                            t0 = t0.max(a.min(b));
                            t1 = t1.min(a.max(b));
                        }
                        if t0 <= t1 && t0 < best.0 {
                            let z = o[2] + t0 * d[2];
                            best = (t0, if z < 0.9 { wk.legs } else { wk.shirt });
                        }
                    }
                    for (k, x) in best.1.iter().enumerate() {
                        rgb[(v * w + u) * 3 + k] = (x * light).round().clamp(0.0, 255.0) as u8;
                    }
                }
            }
            rgb
        }

        fn scan(walker: Option<Walker>, light: f32) -> Option<LeadSeen> {
            let (wide, tele) = cams();
            let (w, t) = (frame(&wide, walker, light), frame(&tele, walker, light));
            let eyes = Eyes {
                wide: Some(View::plain(&wide, &w, Some(0.0))),
                tele: Some(View::plain(&tele, &t, Some(0.0))),
                past_wide: Vec::new(),
                past_tele: Vec::new(),
            };
            let white = eyes.wide.as_ref().map_or(255.0, |v| v.white);
            let gain = gain_of(white);
            let centre = |_: f64| 0.0;
            let road = road_model(&eyes, &centre, gain);
            let no_paint = |_: f64, _: f64| false;
            kerb_object(
                &eyes,
                &sample_distances(),
                &centre,
                1.75,
                &road,
                gain,
                8.0,
                &no_paint,
            )
        }

        #[test]
        fn an_empty_sidewalk_and_its_kerb_are_ground_by_day_and_by_night() {
            for light in [1.0f32, 0.5] {
                assert_eq!(scan(None, light), None, "light {light}");
            }
        }

        #[test]
        fn a_walker_on_the_sidewalk_or_the_shoulder_is_found_where_it_stands() {
            let clothes = [
                ([40.0f32, 38.0, 35.0], [40.0f32, 50.0, 110.0]),
                ([70.0, 70.0, 120.0], [200.0, 60.0, 50.0]),
            ];
            for light in [1.0f32, 0.5] {
                for (legs, shirt) in clothes {
                    // From the shoulder to 2 m beyond the marking (where the towns' walkers
                    // walk the sidewalk's middle); farther out, a body's shadow on the
                    // ground leaves the strip too soon to be read.
                    for y in [-2.0, -2.7, -3.5] {
                        for x in [8.0, 12.0, 16.0, 20.0, 25.0, 30.0] {
                            let walker = Walker { x, y, legs, shirt };
                            let got = scan(Some(walker), light);
                            let what = format!("light {light} {legs:?} at ({x}, {y}): {got:?}");
                            let k = got.expect(&what);
                            // Its near face, in metres ahead of the rear axle, and its edge
                            // nearest the lane.
                            // (Beyond 30 m the scan samples every 0.5 m and needs four
                            // in a row.)
                            let slack = if x < 28.0 { 1.5 } else { 2.5 };
                            assert!((k.contact_x - (x - 0.2)).abs() <= slack, "{what}");
                            assert!((k.left_edge - (y + 0.25)).abs() <= 0.35, "{what}");
                        }
                    }
                }
            }
        }
    }

    /// The lamp reader on synthetic frames: a lit signal head where the towns hang one,
    /// and the far street's red things that sit just above the horizon.
    mod lamp_reader {
        use super::super::*;
        use super::stop_sign_reader::{cams, frame, mask, on_plane, with_eyes};
        use fogline_types::clip::CameraCalib;

        fn read(wide_rgb: &[u8], tele_rgb: &[u8]) -> Option<(Lamp, f64)> {
            with_eyes(wide_rgb, tele_rgb, |eyes| traffic_light(eyes, &[]))
        }

        #[test]
        fn a_red_head_is_read_with_its_distance() {
            let (wide, tele) = cams();
            for dist_m in [12.0, 25.0, 40.0, 60.0] {
                // A dark housing 0.4 × 1.1 m, 1.5 m left of the camera, its red lamp lit
                // (0.15 m radius, centre 5.52 m up).
                let head = |c: CameraCalib| {
                    move |ray: [f64; 3]| {
                        let (y, z) = on_plane(&c, ray, c.x_m + dist_m)?;
                        if (y - 1.5).powi(2) + (z - 5.52).powi(2) <= 0.15f64.powi(2) {
                            Some([255.0, 40.0, 30.0])
                        } else if (y - 1.5).abs() <= 0.2 && (z - 5.2).abs() <= 0.55 {
                            Some([30.0, 30.0, 30.0])
                        } else {
                            None
                        }
                    }
                };
                let w = frame(&wide, &head(wide), 1.0, 1.0);
                let t = frame(&tele, &head(tele), 1.0, 1.0);
                let (lamp, d) = read(&w, &t).unwrap_or_else(|| panic!("no lamp at {dist_m} m"));
                assert_eq!(lamp, Lamp::Red, "at {dist_m} m");
                let from_camera = d - tele.x_m;
                assert!(
                    (from_camera - dist_m).abs() < 0.2 * dist_m,
                    "{from_camera:.1} m for a head {dist_m} m off"
                );
            }
        }

        #[test]
        fn a_masked_walker_far_down_the_street_is_no_red_lamp() {
            // Before the reader kept to the rows of heads within `LAMP_READ_MAX_M`, the top
            // of a far walker's mask (a red outline just above the horizon) read as a red
            // head hundreds of metres off, and the car stopped for it at a nearer
            // junction's line.
            let (wide, tele) = cams();
            let empty = |_: [f64; 3]| None;
            for dist_m in [40.0, 80.0, 150.0, 400.0] {
                let mut w = frame(&wide, &empty, 1.0, 1.0);
                let mut t = frame(&tele, &empty, 1.0, 1.0);
                for (c, rgb) in [(&wide, &mut w), (&tele, &mut t)] {
                    // A walker 1.8 m tall and 0.6 m wide in the lane, boxed 2 px wide.
                    let x = c.x_m + dist_m;
                    let (u0, v0, _) = c.project([x, 0.3, 1.8]).expect("ahead");
                    let (u1, v1, _) = c.project([x, -0.3, 0.0]).expect("ahead");
                    let b = (
                        u0.floor() as usize - 2,
                        v0.floor() as usize - 2,
                        u1.ceil() as usize + 2,
                        v1.ceil() as usize + 2,
                    );
                    mask(rgb, c.width as usize, b);
                }
                assert_eq!(read(&w, &t), None, "walker masked {dist_m} m off");
            }
        }
    }

    /// The marking search along candidate headings gives up a reading only when it can no
    /// longer find as many points as asked: what it keeps is the whole reading.
    mod marking_search {
        use super::super::*;
        use super::stop_sign_reader::{cams, frame, with_eyes};
        use fogline_types::clip::CameraCalib;

        #[test]
        fn a_marking_reading_is_given_up_only_when_it_can_no_longer_reach_the_count_asked() {
            let (wide, tele) = cams();
            // Lanes at several angles to the car, with both markings, with the left one
            // only, and with none; the search looks along the car's axis and along turned
            // lanes, as `fit_lane` does.
            for (heading, sides) in [
                (0.0, [true, true]),
                (0.06, [true, true]),
                (-0.09, [true, false]),
                (0.03, [true, false]),
                (0.0, [false, false]),
            ] {
                let paint = |c: &CameraCalib| {
                    let c = *c;
                    move |ray: [f64; 3]| -> Option<[f32; 3]> {
                        if ray[2] >= -1e-9 {
                            return None;
                        }
                        let t = -c.z_m / ray[2];
                        let (x, y) = (c.x_m + t * ray[0], c.y_m + t * ray[1]);
                        let lane = y - heading * x;
                        let on = |side: f64| (lane - side).abs() <= 0.07;
                        ((sides[0] && on(1.75)) || (sides[1] && on(-1.75)))
                            .then_some([232.0, 232.0, 226.0])
                    }
                };
                let w = frame(&wide, &paint(&wide), 1.0, 1.0);
                let t = frame(&tele, &paint(&tele), 1.0, 1.0);
                with_eyes(&w, &t, |eyes| {
                    let axis = |x: f64| 0.0 * x;
                    let road = road_model(eyes, &axis, 1.0);
                    for h in [0.0, -0.1, -0.05, 0.05, 0.1] {
                        let centre = move |x: f64| h * x;
                        let whole = find_markings(eyes, &road, &centre);
                        let found = whole.pts.len();
                        assert_eq!(whole.rows, marking_rows().count());
                        for at_least in [0, 1, found / 2, found, found + 1, 2 * whole.rows] {
                            let got = find_markings_reaching(eyes, &road, &centre, at_least);
                            match got {
                                Some(m) => assert_eq!(
                                    (m.pts, m.rows, m.left_hits),
                                    (whole.pts.clone(), whole.rows, whole.left_hits),
                                    "lane {heading} sides {sides:?}, along {h}, {at_least}"
                                ),
                                None => assert!(
                                    found < at_least,
                                    "given up at {at_least} with {found} to find \
                                     (lane {heading} sides {sides:?}, along {h})"
                                ),
                            }
                        }
                        // Asked for every row's two points, a reading that misses some
                        // before its last row is given up.
                        if found + 2 < 2 * whole.rows {
                            assert!(
                                find_markings_reaching(eyes, &road, &centre, 2 * whole.rows)
                                    .is_none()
                            );
                        }
                        if heading == h && sides[0] {
                            assert!(found >= whole.rows / 2, "{found} on lane {heading}");
                        }
                    }
                });
            }
        }
    }
}
