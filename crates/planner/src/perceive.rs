//! Perception from pixels: lane geometry, the road surface ahead (occupancy per lateral bin),
//! the lead object and its motion, brake lamps, stop lines and crossings, stop signs and
//! traffic lights, the end of the road.
//!
//! Every measurement goes through the cameras' calibration and flat-ground geometry: a ground
//! point `(x, y, 0)` is projected into the front-tele camera when it is far enough to be in
//! its view (≥ 13 m) and into the front-wide camera otherwise, and its colour is classified.

use crate::vision::{
    View, chroma, is_amber_lamp, is_green_lamp, is_red_lamp, is_road, is_sign_red, is_white_paint,
    is_yellow_paint, lum,
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
}

/// The lane the ego drives in.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LaneSeen {
    /// Curvature from the markings, 1/m.
    pub kappa: f64,
    /// Lateral position of the lane centre at the ego, m (left positive).
    pub offset: f64,
    /// Lane width, m.
    pub width: f64,
    /// Marking points used.
    pub points: usize,
    /// The left boundary is a dashed white line (a same-direction lane beyond it).
    pub left_dashed_white: bool,
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
    /// The marking fit, when the markings were found.
    pub lane: Option<LaneSeen>,
    /// Asphalt luminance reference.
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
}

/// Bins across the lane, m.
const BIN: f64 = 0.1;
const HALF_LANE_BINS: i32 = 17;

struct Eyes<'a> {
    wide: Option<View<'a>>,
    tele: Option<View<'a>>,
}

impl<'a> Eyes<'a> {
    /// The colour at ground point `(x, y)`: tele when it sees it from 13 m on, else wide.
    #[inline]
    fn ground(&self, x: f64, y: f64) -> Option<[f32; 3]> {
        self.point([x, y, 0.0])
    }

    /// Like [`Eyes::ground`] over a 4×4 patch: for the road surface and objects on it.
    #[inline]
    fn surface(&self, x: f64, y: f64) -> Option<[f32; 3]> {
        let p = [x, y, 0.0];
        if p[0] >= 13.0
            && let Some(t) = &self.tele
            && let Some(c) = t.at_point_k(p, 4)
        {
            return Some(c);
        }
        self.wide.as_ref().and_then(|w| w.at_point_k(p, 4))
    }

    #[inline]
    fn point(&self, p: [f64; 3]) -> Option<[f32; 3]> {
        if p[0] >= 13.0
            && let Some(t) = &self.tele
            && let Some(c) = t.at_point(p)
        {
            return Some(c);
        }
        self.wide.as_ref().and_then(|w| w.at_point(p))
    }
}

fn history_motion(h: &[EgoPose]) -> (f64, f64) {
    let Some(last) = h.last() else {
        return (0.0, 0.0);
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
    let kappa = if len > 2.0 {
        (last.yaw_rad - first.yaw_rad) / len
    } else {
        0.0
    };
    (speed, if kappa.is_finite() { kappa } else { 0.0 })
}

fn find<'a>(input: &'a PlannerInput<'a>, id: CameraId, frame_from_end: usize) -> Option<View<'a>> {
    input
        .cameras
        .iter()
        .find(|c| c.calib.id == id)
        .and_then(|c| {
            let n = c.frames.len();
            (n > frame_from_end).then(|| View {
                calib: &c.calib,
                rgb: c.frames[n - 1 - frame_from_end],
            })
        })
}

/// Runs every perception step on `input`.
pub fn perceive(input: &PlannerInput<'_>) -> Perception {
    let (speed, kappa_history) = history_motion(input.ego_history);
    let eyes = Eyes {
        wide: find(input, CameraId::FrontWide, 0),
        tele: find(input, CameraId::FrontTele, 0),
    };
    let road_lum = road_reference(&eyes, kappa_history);
    let lane = fit_lane(&eyes, kappa_history, road_lum);
    let (kappa, lane_width, lane_offset) = match lane {
        Some(l) => (
            0.5 * (l.kappa + kappa_history),
            l.width.clamp(2.8, 4.2),
            l.offset,
        ),
        None => (kappa_history, 3.5, 0.0),
    };
    let centre = |x: f64| lane_offset + 0.5 * kappa * x * x;
    // Occupancy of the ego lane: first blocked distance per lateral bin.
    let (stop_line, zebra) = transverse_marks(&eyes, &centre, road_lum);
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
    let painted = |x: f64| {
        stop_line.is_some_and(|s| (x - s).abs() < 1.0)
            || zebra.is_some_and(|z| x > z - 0.5 && x < z + 4.0)
    };
    let inner = lane_width / 2.0 - 0.4;
    let ego_bins = first_blocked(&eyes, &xs, &centre, 0.0, inner, road_lum, &painted);
    let left_bins = first_blocked(&eyes, &xs, &centre, lane_width, 1.0, road_lum, &painted);
    let road_end = road_end(&ego_bins, &left_bins);
    let right_branch =
        road_end.is_some_and(|x_end| right_branch(&eyes, &centre, x_end, lane_width, road_lum));
    let lead = road_end
        .is_none()
        .then(|| lead_of(input, &eyes, &ego_bins, &centre, road_lum, speed))
        .flatten()
        .or_else(|| {
            // With a road end, only objects clearly nearer than it count.
            road_end.and_then(|x_end| {
                let mut bins = ego_bins.clone();
                for b in bins.iter_mut() {
                    if *b > x_end - 3.0 {
                        *b = f64::INFINITY;
                    }
                }
                lead_of(input, &eyes, &bins, &centre, road_lum, speed)
            })
        });
    let left_dashed = lane.is_some_and(|l| l.left_dashed_white);
    // Beyond the lead, the left lane is hidden behind it: look up to just past the lead.
    let horizon = lead.map_or(60.0, |l| (l.contact_x + 3.0).min(60.0));
    let left_lane_free = left_dashed
        && left_bins
            .iter()
            .filter(|x| !x.is_nan())
            .all(|&x| x > horizon);
    // Anything nearly stationary standing on a crossing is a road user crossing there.
    let lead = lead.map(|mut l| {
        if zebra.is_some_and(|z| l.contact_x > z - 1.0 && l.contact_x < z + 4.0) && l.speed < 2.0 {
            l.kind = ObjectKind::Person;
        }
        l
    });
    let light = traffic_light(&eyes);
    let stop_sign = stop_sign(&eyes);
    Perception {
        speed,
        kappa_history,
        kappa,
        lane_width,
        lane_offset,
        lane,
        road_lum,
        lead,
        left_lane_free,
        road_end,
        right_branch,
        stop_line,
        zebra,
        light,
        stop_sign,
    }
}

/// Median luminance of grey ground just ahead of the car.
fn road_reference(eyes: &Eyes<'_>, kappa: f64) -> f32 {
    let mut v = Vec::with_capacity(64);
    for i in 0..8 {
        let x = 5.0 + 0.6 * i as f64;
        for j in -3..=3 {
            let y = 0.5 * kappa * x * x + 0.25 * j as f64;
            if let Some(c) = eyes.surface(x, y)
                && chroma(c) < 30.0
            {
                v.push(lum(c));
            }
        }
    }
    if v.is_empty() {
        return 90.0;
    }
    v.sort_by(f32::total_cmp);
    v[v.len() / 2]
}

/// Fits `y = a_side + c·x²` to the marking points on both sides of the ego lane.
fn fit_lane(eyes: &Eyes<'_>, kappa_prior: f64, road: f32) -> Option<LaneSeen> {
    let mut pts: Vec<(f64, f64, bool)> = Vec::new(); // (x, y, left)
    let (mut left_white, mut left_yellow, mut left_hits, mut rows) = (0, 0, 0, 0);
    let mut x = 5.0;
    while x <= 34.0 {
        rows += 1;
        let yc = 0.5 * kappa_prior * x * x;
        for (left, lo, hi) in [(false, -2.5, -0.95), (true, 0.95, 2.5)] {
            // Runs of paint samples in the window; the run nearest the expected boundary
            // (about half a lane from the centre), at most 0.35 m wide, is the marking.
            let mut runs: Vec<(f64, f64, usize, usize)> = Vec::new(); // (start, end, n, yellow)
            let mut y = lo;
            while y <= hi {
                if let Some(c) = eyes.ground(x, yc + y) {
                    let yl = is_yellow_paint(c, road);
                    if yl || is_white_paint(c, road) {
                        match runs.last_mut() {
                            Some(r) if y - r.1 < 0.06 => {
                                r.1 = y;
                                r.2 += 1;
                                r.3 += usize::from(yl);
                            }
                            _ => runs.push((y, y, 1, usize::from(yl))),
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
            if let Some(&(a, b, n, yellow)) = best {
                let ym = 0.5 * (a + b);
                pts.push((x, yc + ym, left));
                if left {
                    left_hits += 1;
                    if yellow * 2 > n {
                        left_yellow += 1;
                    } else {
                        left_white += 1;
                    }
                }
            }
        }
        x += if x < 15.0 { 0.5 } else { 1.0 };
    }
    let fit = |pts: &[(f64, f64, bool)]| -> Option<(f64, f64, f64)> {
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
        Some(((sr - c * qr) / nr, (sl - c * ql) / nl, c))
    };
    let (ar, al, c) = fit(&pts)?;
    // One round of outlier removal.
    let kept: Vec<(f64, f64, bool)> = pts
        .iter()
        .copied()
        .filter(|&(x, y, left)| {
            let a = if left { al } else { ar };
            (y - a - c * x * x).abs() < 0.35
        })
        .collect();
    let (ar, al, c) = fit(&kept)?;
    let width = al - ar;
    if !(2.6..=4.6).contains(&width) || kept.len() < 10 {
        return None;
    }
    Some(LaneSeen {
        kappa: 2.0 * c,
        offset: 0.5 * (al + ar),
        width,
        points: kept.len(),
        left_dashed_white: left_white > left_yellow && left_hits * 10 < rows * 8,
    })
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

/// For each lateral bin of the lane centred `shift` m left of the ego lane, the first distance
/// at which the ground is not road (two consecutive samples), or `+inf`.
fn first_blocked(
    eyes: &Eyes<'_>,
    xs: &[f64],
    centre: &dyn Fn(f64) -> f64,
    shift: f64,
    inner: f64,
    road: f32,
    painted: &dyn Fn(f64) -> bool,
) -> Vec<f64> {
    (-HALF_LANE_BINS..=HALF_LANE_BINS)
        .map(|b| {
            if (f64::from(b) * BIN).abs() > inner {
                return f64::NAN; // not sampled: on or beyond the lane's markings
            }
            let y = shift + f64::from(b) * BIN;
            // Four blocked samples in a row: an object occludes the ground behind it, a
            // painted line seen at a grazing angle does not.
            let mut run = 0;
            for (i, &x) in xs.iter().enumerate() {
                let blocked = eyes.surface(x, centre(x) + y).is_some_and(|c| {
                    let paint_blend = painted(x) && chroma(c) < 30.0 && lum(c) > road - 10.0;
                    !(is_road(c, road) || paint_blend)
                });
                run = if blocked { run + 1 } else { 0 };
                if run == 4 {
                    return xs[i - 3];
                }
            }
            f64::INFINITY
        })
        .collect()
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
    if finite.len() * 10 < all.len() * 9 {
        return None;
    }
    let mut s = finite.clone();
    s.sort_by(f64::total_cmp);
    let med = s[s.len() / 2];
    let near = s.iter().filter(|&&x| (x - med).abs() < 3.0).count();
    (near * 10 >= all.len() * 8).then_some(med)
}

/// Asphalt to the right of the lane, a little before the road end.
fn right_branch(
    eyes: &Eyes<'_>,
    centre: &dyn Fn(f64) -> f64,
    x_end: f64,
    w: f64,
    road: f32,
) -> bool {
    let (mut road_n, mut n) = (0, 0);
    let mut x = x_end - 2.0 * w;
    while x < x_end - 1.0 {
        for k in 0..6 {
            let y = centre(x) - w / 2.0 - 1.5 - 0.5 * k as f64;
            if let Some(c) = eyes.ground(x, y) {
                n += 1;
                road_n += usize::from(is_road(c, road));
            }
        }
        x += 0.5;
    }
    n > 0 && road_n * 10 >= n * 6
}

fn lead_of(
    input: &PlannerInput<'_>,
    eyes: &Eyes<'_>,
    bins: &[f64],
    centre: &dyn Fn(f64) -> f64,
    road: f32,
    ego_speed: f64,
) -> Option<LeadSeen> {
    let finite: Vec<(f64, f64)> = bins
        .iter()
        .enumerate()
        .filter(|(_, x)| x.is_finite())
        .map(|(i, &x)| ((i as i32 - HALF_LANE_BINS) as f64 * BIN, x))
        .collect();
    if finite.len() < 2 {
        return None;
    }
    let contact = finite.iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
    // The object: bins blocked within 6 m of the nearest contact.
    let obj: Vec<(f64, f64)> = finite
        .iter()
        .copied()
        .filter(|p| p.1 < contact + 6.0)
        .collect();
    if obj.len() < 2 {
        return None;
    }
    let right_edge = obj.iter().map(|p| p.0).fold(f64::INFINITY, f64::min);
    let left_edge = obj.iter().map(|p| p.0).fold(f64::NEG_INFINITY, f64::max);
    // Widths at body height (0.5 m) and cabin/torso height (1.3 m), just behind the contact:
    // a vehicle is wide at both, a pedestrian at neither, a cyclist only at the bicycle.
    let xw = contact + 0.4;
    let mid = 0.5 * (left_edge + right_edge);
    let width_at = |z: f64| {
        // The contiguous run of object pixels through the object's middle (background seen
        // past a narrow object is usually not contiguous with it).
        let hit = |b: i32| {
            let y = centre(xw) + mid + f64::from(b) * BIN;
            eyes.point([xw, y, z]).is_some_and(|c| is_object(c, road))
        };
        let start = (-3..=3).find(|&b| hit(b));
        let Some(b0) = start else { return 0.0 };
        let (mut lo, mut hi) = (b0, b0);
        while lo > -25 && hit(lo - 1) {
            lo -= 1;
        }
        while hi < 25 && hit(hi + 1) {
            hi += 1;
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
    let braking = brake_lamps(eyes, contact, centre);
    let speed = lead_speed(input, centre, road, contact, ego_speed, &obj);
    Some(LeadSeen {
        contact_x: contact,
        gap: contact - REAR_WHEEL_TO_BUMPER - fogline_types::motion::EGO_FRONT_M,
        speed,
        braking,
        kind,
        width_m,
        right_edge,
        left_edge,
    })
}

/// How far a vehicle's rear wheels touch the ground ahead of its rear bumper, m.
const REAR_WHEEL_TO_BUMPER: f64 = 0.57;

/// Clearly not the road surface (a tighter test than [`is_road`], for pixels above ground).
/// (Only used above the ground, where there is no paint and, below the camera, no sky.)
fn is_object(c: [f32; 3], road: f32) -> bool {
    (lum(c) - road).abs() > 14.0 || chroma(c) > 24.0
}

fn brake_lamps(eyes: &Eyes<'_>, contact: f64, centre: &dyn Fn(f64) -> f64) -> bool {
    let view = if contact >= 13.0 {
        &eyes.tele
    } else {
        &eyes.wide
    };
    let Some(view) = view.as_ref().or(eyes.wide.as_ref()) else {
        return false;
    };
    let x = contact - REAR_WHEEL_TO_BUMPER;
    let yc = centre(x);
    let corners = [[x - 0.2, yc + 1.2, 1.2], [x - 0.2, yc - 1.2, 0.55]];
    let (Some(a), Some(b)) = (
        view.calib.project(corners[0]),
        view.calib.project(corners[1]),
    ) else {
        return false;
    };
    let (u0, u1) = (
        a.0.min(b.0).max(0.0) as usize,
        a.0.max(b.0).max(0.0) as usize,
    );
    let (v0, v1) = (
        a.1.min(b.1).max(0.0) as usize,
        a.1.max(b.1).max(0.0) as usize,
    );
    let (w, h) = (view.width(), view.height());
    let mut n = 0;
    for v in v0..=v1.min(h - 1) {
        for u in u0..=u1.min(w - 1) {
            n += usize::from(is_red_lamp(view.pixel(u, v)) && is_red_lamp(view.patch2(u, v)));
        }
    }
    n >= 2
}

/// Lead speed from the contact distance in the four frames (least squares over time), in the
/// rig frame at `t0` using the ego history for the earlier frames.
fn lead_speed(
    input: &PlannerInput<'_>,
    centre: &dyn Fn(f64) -> f64,
    road: f32,
    contact0: f64,
    ego_speed: f64,
    obj: &[(f64, f64)],
) -> f64 {
    let bins: Vec<f64> = obj.iter().map(|p| p.0).collect();
    let hist = input.ego_history;
    let mut ts = Vec::new();
    let mut xs = Vec::new();
    for back in 0..4 {
        let eyes = Eyes {
            wide: find(input, CameraId::FrontWide, back),
            tele: find(input, CameraId::FrontTele, back),
        };
        if eyes.wide.is_none() && eyes.tele.is_none() {
            continue;
        }
        // Ego pose at that frame (0.1 s per frame back).
        let t = -0.1 * back as f64;
        let ego_x = hist.iter().rev().nth(back).map_or(ego_speed * t, |p| p.x_m);
        let lo = contact0 - ego_x - 8.0;
        let hi = contact0 - ego_x + 8.0;
        let mut best = f64::INFINITY;
        for &y in &bins {
            let mut prev = false;
            let mut x = lo.max(4.5);
            while x <= hi {
                let blocked = eyes
                    .surface(x, centre(x + ego_x) + y)
                    .is_some_and(|c| !is_road(c, road));
                if blocked && prev {
                    best = best.min(x - 0.1);
                    break;
                }
                prev = blocked;
                x += 0.1;
            }
        }
        if best.is_finite() {
            ts.push(t);
            xs.push(best + ego_x);
        }
    }
    if ts.len() < 3 {
        return ego_speed;
    }
    let n = ts.len() as f64;
    let (mt, mx) = (ts.iter().sum::<f64>() / n, xs.iter().sum::<f64>() / n);
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (t, x) in ts.iter().zip(&xs) {
        sxy += (t - mt) * (x - mx);
        sxx += (t - mt) * (t - mt);
    }
    let v = sxy / sxx.max(1e-9);
    if v.is_finite() { v.max(0.0) } else { ego_speed }
}

/// Stop line (a solid white band across the lane) and zebra (half-covered bands over ≥ 2 m)
/// along the lane centre.
fn transverse_marks(
    eyes: &Eyes<'_>,
    centre: &dyn Fn(f64) -> f64,
    road: f32,
) -> (Option<f64>, Option<f64>) {
    let mut profile = Vec::new();
    let mut x = 4.5;
    while x <= 60.0 {
        let (mut white, mut n) = (0, 0);
        for k in -6..=6 {
            if let Some(c) = eyes.ground(x, centre(x) + 0.2 * f64::from(k)) {
                n += 1;
                white += usize::from(is_white_paint(c, road));
            }
        }
        profile.push((x, if n > 0 { white as f64 / n as f64 } else { 0.0 }));
        x += 0.1;
    }
    let mut stop = None;
    let mut zebra = None;
    let mut i = 0;
    while i < profile.len() {
        if profile[i].1 >= 0.75 {
            let start = profile[i].0;
            let mut j = i;
            while j < profile.len() && profile[j].1 >= 0.75 {
                j += 1;
            }
            let len = profile[j - 1].0 - start;
            if len <= 1.2 && stop.is_none() {
                stop = Some(start + len / 2.0);
            }
            i = j;
            continue;
        }
        if (0.25..0.75).contains(&profile[i].1) && zebra.is_none() {
            let start = profile[i].0;
            let mut j = i;
            while j < profile.len() && (0.2..0.8).contains(&profile[j].1) {
                j += 1;
            }
            if profile[j.min(profile.len() - 1)].0 - start >= 2.0 {
                zebra = Some(start);
            }
            i = j.max(i + 1);
            continue;
        }
        i += 1;
    }
    (stop, zebra)
}

/// Lit lamps above the horizon: the colour with the most pixels, and a distance from the
/// lamp's elevation (signal heads hang about 5 m up).
fn traffic_light(eyes: &Eyes<'_>) -> Option<(Lamp, f64)> {
    for view in [&eyes.tele, &eyes.wide].into_iter().flatten() {
        let cy = view.calib.cy;
        let top = (cy - 2.0).max(0.0) as usize;
        let (mut r, mut g, mut a) = (Vec::new(), Vec::new(), Vec::new());
        let w = view.width();
        let lo = (w as f64 * 0.2) as usize;
        let hi = (w as f64 * 0.8) as usize;
        for v in 0..top {
            for u in lo..hi {
                let c = view.pixel(u, v);
                if c[0] < 190.0 && c[1] < 180.0 {
                    continue;
                }
                // Confirmed on the 2×2 mean: a lit lamp is a patch, noise is a speck.
                let m = view.patch2(u, v);
                if is_red_lamp(c) && is_red_lamp(m) {
                    r.push((u, v));
                } else if is_green_lamp(c) && is_green_lamp(m) {
                    g.push((u, v));
                } else if is_amber_lamp(c) && is_amber_lamp(m) {
                    a.push((u, v));
                }
            }
        }
        // The largest compact cluster of each colour: (pixels, mean row).
        let compact = |pts: Vec<(usize, usize)>| -> (usize, f64) {
            let mut best: (usize, f64) = (0, 0.0);
            for &(u0, v0) in pts.iter().take(400) {
                let near: Vec<&(usize, usize)> = pts
                    .iter()
                    .filter(|p| p.0.abs_diff(u0) <= 6 && p.1.abs_diff(v0) <= 6)
                    .collect();
                if near.len() > best.0 {
                    let vm = near.iter().map(|p| p.1 as f64).sum::<f64>() / near.len() as f64;
                    best = (near.len(), vm);
                }
            }
            best
        };
        let (r, g, a) = (compact(r), compact(g), compact(a));
        let best = [
            (Lamp::Red, r, 5.52),
            (Lamp::Amber, a, 5.2),
            (Lamp::Green, g, 4.88),
        ]
        .into_iter()
        .max_by_key(|(_, (n, _), _)| *n)?;
        let (lamp, (n, vmean), h) = best;
        if n >= 3 {
            let v = vmean + 0.5;
            let elev = (cy - v) / view.calib.fy;
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

/// A stop sign: a compact patch of sign red, right of centre, well above the horizon.
fn stop_sign(eyes: &Eyes<'_>) -> Option<f64> {
    for (view, min_px) in [(&eyes.tele, 12usize), (&eyes.wide, 8usize)] {
        let Some(view) = view else { continue };
        let (cx, cy) = (view.calib.cx, view.calib.cy);
        let (w, _) = (view.width(), view.height());
        let mut pts: Vec<(usize, usize)> = Vec::new();
        for v in 0..(cy - 1.0).max(0.0) as usize {
            for u in (cx as usize + 3)..w {
                let c = view.pixel(u, v);
                if is_sign_red(c) && !is_red_lamp(c) && is_sign_red(view.patch2(u, v)) {
                    pts.push((u, v));
                }
            }
        }
        if pts.len() < min_px {
            continue;
        }
        // The largest cluster by column gaps.
        pts.sort_unstable();
        let mut best: &[(usize, usize)] = &[];
        let mut start = 0;
        for i in 1..=pts.len() {
            if i == pts.len() || pts[i].0 > pts[i - 1].0 + 3 {
                if i - start > best.len() {
                    best = &pts[start..i];
                }
                start = i;
            }
        }
        if best.len() < min_px {
            continue;
        }
        let u0 = best.iter().map(|p| p.0).min().unwrap_or(0);
        let u1 = best.iter().map(|p| p.0).max().unwrap_or(0);
        let vmean = best.iter().map(|p| p.1 as f64).sum::<f64>() / best.len() as f64 + 0.5;
        let width_px = (u1 - u0 + 1) as f64;
        let elev = (cy - vmean) / view.calib.fy;
        // The red face is about 0.74 m across, its centre 0.65 m above the camera.
        let d_width = view.calib.fx * 0.74 / width_px;
        let d_elev = if elev > 1e-3 { 0.65 / elev } else { d_width };
        let ratio = d_elev / d_width;
        if !(0.5..=2.0).contains(&ratio) {
            continue;
        }
        let d = 0.5 * (d_width + d_elev);
        // Signs stand beside the road: its centre must be well right of the lane.
        let u_mid = 0.5 * (u0 + u1) as f64 + 0.5;
        let lateral = -(u_mid - cx) * d / view.calib.fx;
        if lateral > -2.0 {
            continue;
        }
        return Some(d + view.calib.x_m);
    }
    None
}
