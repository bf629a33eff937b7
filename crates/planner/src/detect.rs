//! Detections as an API: the road users the perception found — with their boxes in the image
//! and their tracks over the clip's frames — and the perception-deficit regions recognised in
//! a frame by what they look like (a black fill inside a red outline). Closed-loop code and
//! the override can work from these instead of the renderer's ground-truth boxes.
//!
//! ```
//! use fogline_planner::detect::find_deficits;
//!
//! // A 64 × 48 grey frame with one deficit drawn on it: black, outlined 2 px red.
//! let (w, h) = (64usize, 48usize);
//! let mut rgb = vec![120u8; w * h * 3];
//! for y in 10..30 {
//!     for x in 20..44 {
//!         let ring = x < 22 || x >= 42 || y < 12 || y >= 28;
//!         let px = if ring { [255, 0, 0] } else { [0, 0, 0] };
//!         rgb[(y * w + x) * 3..(y * w + x) * 3 + 3].copy_from_slice(&px);
//!     }
//! }
//! let found = find_deficits(&rgb, w, h)?;
//! assert_eq!(found.len(), 1);
//! assert_eq!((found[0].x0, found[0].y0, found[0].x1, found[0].y1), (20, 10, 44, 30));
//! # Ok::<(), fogline_planner::PlannerError>(())
//! ```

use crate::PlannerError;
use crate::perceive::{LeadSeen, ObjectKind, Perception};
use fogline_types::clip::{CameraCalib, CameraId, PlannerInput};

/// A deficit region found in a frame: a rectangle filled black inside a red outline.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeficitSeen {
    /// Left column (inclusive), px.
    pub x0: u32,
    /// Top row (inclusive), px.
    pub y0: u32,
    /// Right column (exclusive), px.
    pub x1: u32,
    /// Bottom row (exclusive), px.
    pub y1: u32,
    /// Share of the rectangle's 2-pixel border that reads red, in [0, 1].
    pub outline: f64,
    /// Mean luminance of the interior, 0–255 (near 0 for a black fill; noise clipped at 0
    /// raises it: about 0.4 σ).
    pub fill_lum: f64,
}

/// Which lane an object was found in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LaneOf {
    /// The ego lane.
    Ego,
    /// The lane to its left.
    Left,
}

/// A road user the perception found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ObjectSeen {
    /// Its lane.
    pub lane: LaneOf,
    /// What the perception reads in the lane: contact, extents, speed, kind, track.
    pub seen: LeadSeen,
    /// The camera whose latest frame it was read from.
    pub camera: CameraId,
    /// Its box in that frame `[x0, y0, x1, y1]`, px (clamped to the image): the perceived
    /// footprint raised to the height of its kind (1.5 m for a vehicle, 1.8 m for a person).
    pub bbox: [f64; 4],
}

/// What [`crate::ReferencePlanner::detect`] finds in one input.
#[derive(Debug, Clone, PartialEq)]
pub struct Detections {
    /// Road users in the ego lane and the lane to its left, nearest first per lane.
    pub objects: Vec<ObjectSeen>,
    /// Deficit regions per camera, in the latest frame of each camera of the input.
    pub deficits: Vec<(CameraId, DeficitSeen)>,
}

/// Objects of `p` with their image boxes: the lead in the ego lane, and the one in the lane
/// to the left when `p` comes from [`crate::perceive::perceive_objects`].
pub fn objects(p: &Perception, input: &PlannerInput<'_>) -> Vec<ObjectSeen> {
    let centre = |x: f64| p.lane_offset + p.lane_heading * x + 0.5 * p.kappa * x * x;
    let mut out = Vec::new();
    for (lane, seen, shift) in [
        (LaneOf::Ego, p.lead, 0.0),
        (LaneOf::Left, p.left_object, p.lane_width),
    ] {
        let Some(seen) = seen else { continue };
        let x = seen.contact_x;
        let yc = centre(x) + shift;
        let height = match seen.kind {
            ObjectKind::Vehicle => 1.5,
            ObjectKind::Person => 1.8,
        };
        let corners = [
            [x, yc + seen.right_edge - 0.05],
            [x, yc + seen.left_edge + 0.05],
        ];
        let tele = (x >= 13.0)
            .then(|| {
                input
                    .cameras
                    .iter()
                    .find(|c| c.calib.id == CameraId::FrontTele)
            })
            .flatten();
        let wide = input
            .cameras
            .iter()
            .find(|c| c.calib.id == CameraId::FrontWide);
        let boxed = [tele, wide]
            .into_iter()
            .flatten()
            .find_map(|c| image_box(&c.calib, &corners, height).map(|b| (c.calib.id, b)));
        if let Some((camera, bbox)) = boxed {
            out.push(ObjectSeen {
                lane,
                seen,
                camera,
                bbox,
            });
        }
    }
    out
}

/// The box in `calib`'s image of the upright rectangle standing on the ground segment
/// `corners` and `height` m tall, clamped to the image; `None` when its foot is not in view.
fn image_box(calib: &CameraCalib, corners: &[[f64; 2]; 2], height: f64) -> Option<[f64; 4]> {
    let (w, h) = (f64::from(calib.width), f64::from(calib.height));
    let mut b = [
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    ];
    for c in corners {
        for z in [0.0, height] {
            let (u, v, _) = calib.project([c[0], c[1], z])?;
            b = [b[0].min(u), b[1].min(v), b[2].max(u), b[3].max(v)];
        }
    }
    let b = [b[0].max(0.0), b[1].max(0.0), b[2].min(w), b[3].min(h)];
    (b[2] > b[0] && b[3] > b[1]).then_some(b)
}

/// Deficit regions in one RGB8 frame (`width × height × 3` bytes): connected groups of red
/// pixels (red exceeds green and blue by 96 levels, with at least two red neighbours) whose
/// bounding box (at least 8 × 8 pixels) has a red border (at least 60 % of its 2-pixel ring
/// and half of each side) around a dark interior (mean luminance at most 64, at most 20 %
/// red); a box too small for a fill counts when it is a solid bar of saturated red (at least
/// 2 × 8 pixels, twice as tall as wide, at least 80 % of it red ≥ 230 with green and blue
/// ≤ 30: a distant lamp's mask). A stop sign's face, a red car or a lit lamp is red *inside*, so it is
/// not taken; two overlapping deficits whose outlines merge are reported as their union when
/// the union's border still reads red, and missed otherwise.
pub fn find_deficits(
    rgb: &[u8],
    width: usize,
    height: usize,
) -> Result<Vec<DeficitSeen>, PlannerError> {
    if width == 0 || height == 0 || rgb.len() != width * height * 3 {
        return Err(PlannerError::Input(format!(
            "frame of {} bytes, expected {width}x{height} RGB8 ({} bytes)",
            rgb.len(),
            width * height * 3
        )));
    }
    let raw: Vec<bool> = rgb
        .chunks_exact(3)
        .map(|p| {
            let (r, g, b) = (i32::from(p[0]), i32::from(p[1]), i32::from(p[2]));
            r >= 128 && r - g >= 96 && r - b >= 96
        })
        .collect();
    // A red pixel of a line has red neighbours (an outline's has at least three); one with
    // fewer than two is a speck of noise, which must not join an outline and stretch its box.
    let red: Vec<bool> = (0..raw.len())
        .map(|i| {
            let (x, y) = ((i % width) as i64, (i / width) as i64);
            raw[i]
                && (-1i64..=1)
                    .flat_map(|dy| (-1i64..=1).map(move |dx| (dx, dy)))
                    .filter(|&(dx, dy)| {
                        let (nx, ny) = (x + dx, y + dy);
                        (dx, dy) != (0, 0)
                            && nx >= 0
                            && ny >= 0
                            && nx < width as i64
                            && ny < height as i64
                            && raw[ny as usize * width + nx as usize]
                    })
                    .count()
                    >= 2
        })
        .collect();
    let mut out = Vec::new();
    for (x0, y0, x1, y1) in groups(&red, width, height, |_| true) {
        // The smallest deficit worth reporting: a 2-pixel ring, then a 1-pixel margin, around
        // at least 2 × 2 pixels of fill.
        if x1 - x0 < 8 || y1 - y0 < 8 {
            // Too small for a fill with a margin: the mask of a distant lamp, tall and narrow
            // (a signal head), at least 2 px wide, 6 px tall and twice as tall as wide (a lit
            // lamp is round, a sign's face as wide as tall). With no room inside, its outline
            // is a solid red bar, red nearly throughout; from 5 px across, a narrow ring
            // around a black core. The red is the outline's own, saturated (a painted lamp or
            // a red car's flank is lit, shaded and mixed with its surroundings).
            let (bw, bh) = (x1 - x0, y1 - y0);
            if bw >= 2 && bh >= 6 && bh >= 2 * bw {
                let pure = |i: usize| {
                    let p = &rgb[i * 3..i * 3 + 3];
                    red[i] && p[0] >= 230 && p[1] <= 30 && p[2] <= 30
                };
                let (mut all, mut ring, mut ring_pure) = (0usize, 0usize, 0usize);
                let (mut core, mut core_lum) = (0usize, 0u64);
                for y in y0..y1 {
                    for x in x0..x1 {
                        let i = y * width + x;
                        let p = pure(i);
                        all += usize::from(p);
                        if x < x0 + 2 || x >= x1 - 2 || y < y0 + 2 || y >= y1 - 2 {
                            ring += 1;
                            ring_pure += usize::from(p);
                        } else {
                            core += 1;
                            let q = &rgb[i * 3..i * 3 + 3];
                            core_lum += u64::from(q[0]) + u64::from(q[1]) + u64::from(q[2]);
                        }
                    }
                }
                let share = all as f64 / (bw * bh) as f64;
                let ring_share = ring_pure as f64 / ring.max(1) as f64;
                let core_lum = if core > 0 {
                    core_lum as f64 / (3 * core) as f64
                } else {
                    0.0
                };
                let bar = share >= 0.8;
                let narrow_ring = bw >= 5 && core > 0 && ring_share >= 0.8 && core_lum <= 40.0;
                if bar || narrow_ring {
                    out.push(DeficitSeen {
                        x0: x0 as u32,
                        y0: y0 as u32,
                        x1: x1 as u32,
                        y1: y1 as u32,
                        outline: if bar { share } else { ring_share },
                        fill_lum: if bar { 0.0 } else { core_lum },
                    });
                }
            }
            continue;
        }
        // Each side of the ring must read red (a lamp or a sign face is round: its box's
        // corners are not red, but its sides are; what tells it apart is its red interior).
        let side_red = |xs: std::ops::Range<usize>, ys: std::ops::Range<usize>| {
            let n = xs.len() * ys.len();
            let r = ys
                .flat_map(|y| xs.clone().map(move |x| y * width + x))
                .filter(|&i| red[i])
                .count();
            r as f64 / n as f64
        };
        let sides = [
            side_red(x0..x1, y0..y0 + 2),
            side_red(x0..x1, y1 - 2..y1),
            side_red(x0..x0 + 2, y0..y1),
            side_red(x1 - 2..x1, y0..y1),
        ];
        if sides.iter().any(|&s| s < 0.5) {
            continue;
        }
        let (mut ring, mut ring_red) = (0usize, 0usize);
        let (mut inner, mut inner_red, mut inner_lum) = (0usize, 0usize, 0u64);
        for y in y0..y1 {
            for x in x0..x1 {
                let i = y * width + x;
                let on_ring = x < x0 + 2 || x >= x1 - 2 || y < y0 + 2 || y >= y1 - 2;
                if on_ring {
                    ring += 1;
                    ring_red += usize::from(red[i]);
                } else if x >= x0 + 3 && x < x1 - 3 && y >= y0 + 3 && y < y1 - 3 {
                    inner += 1;
                    inner_red += usize::from(red[i]);
                    let p = &rgb[i * 3..i * 3 + 3];
                    inner_lum += u64::from(p[0]) + u64::from(p[1]) + u64::from(p[2]);
                }
            }
        }
        let outline = ring_red as f64 / ring as f64;
        let fill_lum = inner_lum as f64 / (3 * inner.max(1)) as f64;
        if outline >= 0.6 && fill_lum <= 64.0 && inner_red * 5 <= inner {
            out.push(DeficitSeen {
                x0: x0 as u32,
                y0: y0 as u32,
                x1: x1 as u32,
                y1: y1 as u32,
                outline,
                fill_lum,
            });
        }
    }
    Ok(out)
}

/// The bounding boxes `(x0, y0, x1, y1)` (ends exclusive) of the connected groups of `set`
/// pixels (8-neighbourhood), in the order of their first pixel; `counted` picks which of a
/// group's pixels its box covers (a group with none of them is left out).
fn groups(
    set: &[bool],
    width: usize,
    height: usize,
    counted: impl Fn(usize) -> bool,
) -> Vec<(usize, usize, usize, usize)> {
    let mut seen = vec![false; set.len()];
    let mut found = Vec::new();
    let mut stack = Vec::new();
    for start in 0..set.len() {
        if !set[start] || seen[start] {
            continue;
        }
        let (mut x0, mut y0, mut x1, mut y1) = (width, height, 0, 0);
        seen[start] = true;
        stack.push(start);
        while let Some(i) = stack.pop() {
            let (x, y) = (i % width, i / width);
            if counted(i) {
                x0 = x0.min(x);
                y0 = y0.min(y);
                x1 = x1.max(x + 1);
                y1 = y1.max(y + 1);
            }
            for dy in -1i64..=1 {
                for dx in -1i64..=1 {
                    let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                    if nx < 0 || ny < 0 || nx >= width as i64 || ny >= height as i64 {
                        continue;
                    }
                    let j = ny as usize * width + nx as usize;
                    if set[j] && !seen[j] {
                        seen[j] = true;
                        stack.push(j);
                    }
                }
            }
        }
        if x1 > x0 {
            found.push((x0, y0, x1, y1));
        }
    }
    found
}

/// A vehicle-like road user moving in the view of a camera that stood still: a group of
/// pixels whose luminance changed between two frames, wider than tall, standing on the
/// ground.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MoverSeen {
    /// Left column (inclusive) of the changed pixels, px.
    pub x0: u32,
    /// Top row (inclusive), px.
    pub y0: u32,
    /// Right column (exclusive), px.
    pub x1: u32,
    /// Bottom row (exclusive), px.
    pub y1: u32,
    /// Changed pixels in the group.
    pub changed: u32,
    /// Bearing of the group's bottom centre in the rig frame, radians (0 straight ahead,
    /// left positive).
    pub bearing_rad: f64,
}

/// A pixel whose luminance `(R + 2G + B) / 4` changed by more than this between the two
/// frames has changed, at the least (0–255 scale); with sensor noise the bar is
/// [`MOVER_NOISE_SIGMAS`] times the noise of the difference, estimated from its median
/// absolute value (most of a still scene does not move). The closed loop's frames of a
/// still scene are identical (its atmosphere is deterministic): the floor is what a dark
/// car 40 m off in heavy rain still changes.
pub const MOVER_DIFF_LUM: i32 = 4;

/// The change threshold in standard deviations of the difference's noise.
pub const MOVER_NOISE_SIGMAS: f64 = 4.0;

/// The fewest changed pixels a mover has (fewer is a flicker, not a road user).
pub const MOVER_MIN_CHANGED: u32 = 3;

/// The vehicle-like road users that moved between `before` and `now`, two RGB8 frames of
/// the camera `calib` taken while it stood still (the car waiting at a line): groups of
/// changed pixels (one pixel of gap bridged; a uniformly coloured car changes only at its
/// leading and trailing edges, which are joined), whose changed pixels span more columns
/// than rows (a car seen from any side is wider than tall; a walker is not, even with the
/// ground it covered between the frames, nor are the few pixels of a far walker's legs) and whose bottom lies below the horizon (on the ground: a
/// lamp changing colour above the road is no mover). A classic motion detector for a
/// static camera; it says nothing when the camera moved.
pub fn movers(
    before: &[u8],
    now: &[u8],
    calib: &CameraCalib,
) -> Result<Vec<MoverSeen>, PlannerError> {
    let (width, height) = (calib.width as usize, calib.height as usize);
    let expect = width * height * 3;
    if width == 0 || height == 0 || before.len() != expect || now.len() != expect {
        return Err(PlannerError::Input(format!(
            "frames of {} and {} bytes, expected {width}x{height} RGB8 ({expect} bytes) each",
            before.len(),
            now.len()
        )));
    }
    let lum = |p: &[u8]| (i32::from(p[0]) + 2 * i32::from(p[1]) + i32::from(p[2])) / 4;
    let diff: Vec<u8> = before
        .chunks_exact(3)
        .zip(now.chunks_exact(3))
        .map(|(a, b)| (lum(a) - lum(b)).unsigned_abs() as u8)
        .collect();
    // The noise of the difference from its median absolute value (a histogram: luminance
    // differences are 0–255); σ = 1.4826 × MAD for Gaussian noise.
    let mut hist = [0usize; 256];
    for &d in &diff {
        hist[usize::from(d)] += 1;
    }
    let (mut below, mut median) = (0usize, 0usize);
    for (v, &n) in hist.iter().enumerate() {
        below += n;
        if 2 * below >= diff.len() {
            median = v;
            break;
        }
    }
    let bar = f64::from(MOVER_DIFF_LUM).max(MOVER_NOISE_SIGMAS * 1.4826 * median as f64);
    let changed: Vec<bool> = diff.iter().map(|&d| f64::from(d) > bar).collect();
    // Bridge one pixel: a changed pixel's 3 × 3 neighbourhood joins its group.
    let mut bridged = changed.clone();
    for (i, _) in changed.iter().enumerate().filter(|(_, c)| **c) {
        let (x, y) = (i % width, i / width);
        for ny in y.saturating_sub(1)..(y + 2).min(height) {
            for nx in x.saturating_sub(1)..(x + 2).min(width) {
                bridged[ny * width + nx] = true;
            }
        }
    }
    // A uniformly coloured body changes only at its leading and trailing edges: two groups
    // with the same rows (top and bottom within a pixel or a fifth of the height) and a gap
    // of at most four heights between them are one road user.
    let mut found = groups(&bridged, width, height, |i| changed[i]);
    let mut merged = true;
    while merged {
        merged = false;
        'pairs: for a in 0..found.len() {
            for b in a + 1..found.len() {
                let (p, q) = (found[a], found[b]);
                let tall = (p.3 - p.1).max(q.3 - q.1);
                let slack = (tall / 5).max(1);
                let gap = q.0.saturating_sub(p.2).max(p.0.saturating_sub(q.2));
                if p.1.abs_diff(q.1) <= slack && p.3.abs_diff(q.3) <= slack && gap <= 4 * tall {
                    found[a] = (p.0.min(q.0), p.1.min(q.1), p.2.max(q.2), p.3.max(q.3));
                    found.swap_remove(b);
                    merged = true;
                    break 'pairs;
                }
            }
        }
    }
    let mut out = Vec::new();
    for (x0, y0, x1, y1) in found {
        let count = (y0..y1)
            .flat_map(|y| (x0..x1).map(move |x| y * width + x))
            .filter(|&i| changed[i])
            .count() as u32;
        if count < MOVER_MIN_CHANGED || x1 - x0 <= y1 - y0 {
            continue;
        }
        let ray = calib.ray((x0 + x1) as f64 / 2.0, y1 as f64 - 0.5);
        if ray[2] >= 0.0 {
            continue;
        }
        out.push(MoverSeen {
            x0: x0 as u32,
            y0: y0 as u32,
            x1: x1 as u32,
            y1: y1 as u32,
            changed: count,
            bearing_rad: ray[1].atan2(ray[0]),
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(w: usize, h: usize, bg: [u8; 3]) -> Vec<u8> {
        bg.iter().copied().cycle().take(w * h * 3).collect()
    }

    fn paint(
        rgb: &mut [u8],
        w: usize,
        r: (usize, usize, usize, usize),
        f: impl Fn(usize, usize) -> [u8; 3],
    ) {
        for y in r.1..r.3 {
            for x in r.0..r.2 {
                rgb[(y * w + x) * 3..(y * w + x) * 3 + 3].copy_from_slice(&f(x, y));
            }
        }
    }

    fn deficit(rgb: &mut [u8], w: usize, r: (usize, usize, usize, usize)) {
        paint(rgb, w, r, |x, y| {
            if x < r.0 + 2 || x >= r.2 - 2 || y < r.1 + 2 || y >= r.3 - 2 {
                [255, 0, 0]
            } else {
                [0, 0, 0]
            }
        });
    }

    /// Deterministic noise: a hash of the position, roughly uniform in ±`amp`.
    fn noisy(rgb: &mut [u8], amp: i32) {
        noisy_salted(rgb, amp, 0);
    }

    /// [`noisy`] drawn afresh for each `salt` (another frame's noise).
    fn noisy_salted(rgb: &mut [u8], amp: i32, salt: u64) {
        for (i, v) in rgb.iter_mut().enumerate() {
            let h = (i as u64 ^ salt.wrapping_mul(0xD1B5_4A32_D192_ED03))
                .wrapping_mul(0x9E37_79B9_7F4A_7C15)
                .rotate_left(17);
            let d = (h % (2 * amp as u64 + 1)) as i32 - amp;
            *v = (i32::from(*v) + d).clamp(0, 255) as u8;
        }
    }

    #[test]
    fn a_car_moving_past_a_still_camera_is_a_mover_and_a_walker_or_a_lamp_is_not() {
        let calib = CameraCalib::standard(CameraId::CrossLeft, 192, 144);
        let (w, h) = (192, 144);
        let bg = frame(w, h, [96, 98, 100]);
        assert!(movers(&bg, &bg, &calib).unwrap().is_empty());
        // A dark car 14 × 5 px below the horizon (row 72), 3 px further right a step later;
        // a walker 2 × 9 px a pixel on; a lamp above the horizon turning from red to green.
        let scene = |car_x: usize, walker_x: usize, lamp: [u8; 3]| {
            let mut f = bg.clone();
            paint(&mut f, w, (car_x, 80, car_x + 14, 85), |_, _| [30, 32, 36]);
            paint(&mut f, w, (walker_x, 70, walker_x + 2, 79), |_, _| {
                [150, 60, 60]
            });
            paint(&mut f, w, (150, 20, 156, 26), |_, _| lamp);
            f
        };
        let a = scene(40, 120, [250, 20, 20]);
        let b = scene(43, 121, [20, 250, 60]);
        let got = movers(&a, &b, &calib).unwrap();
        assert_eq!(got.len(), 1, "{got:?}");
        let m = got[0];
        // Both edges changed (the car's uniform middle did not): the box spans them.
        assert_eq!((m.x0, m.y0, m.x1, m.y1), (40, 80, 57, 85));
        assert_eq!(m.changed, 30);
        // Its bottom centre (column 48.5) lies atan(47.5 / fx) = 40.6° left of the axis of
        // a camera turned 60° left (fx = 96 / tan 60°); through the right camera, turned
        // 60° right, the same pixels lie 19.4° right of straight ahead.
        let expect = |yaw: f64| yaw + (47.5f64 / (96.0 / 60f64.to_radians().tan())).atan();
        assert!((m.bearing_rad - expect(60f64.to_radians())).abs() < 1e-9);
        let right = CameraCalib::standard(CameraId::CrossRight, 192, 144);
        let r = movers(&a, &b, &right).unwrap();
        assert!(r.len() == 1 && (r[0].bearing_rad - expect(-60f64.to_radians())).abs() < 1e-9);
        assert!((r[0].bearing_rad.to_degrees() + 19.4).abs() < 0.1);
        // With fresh sensor noise in each frame (uniform ±12: σ 6.9 per frame, 9.8 in the
        // difference) the bar rises above the noise and the car is still the one mover.
        let (mut na, mut nb) = (a.clone(), b.clone());
        noisy_salted(&mut na, 12, 1);
        noisy_salted(&mut nb, 12, 2);
        let got = movers(&na, &nb, &calib).unwrap();
        assert_eq!(got.len(), 1, "{got:?}");
        assert!(got[0].x0 >= 38 && got[0].x1 <= 59 && got[0].y0 >= 78 && got[0].y1 <= 87);
        let still = movers(
            &na,
            &{
                let mut c = a.clone();
                noisy_salted(&mut c, 12, 3);
                c
            },
            &calib,
        )
        .unwrap();
        assert!(still.is_empty(), "{still:?}");
        // Frames of another size are an error, not a guess.
        assert!(movers(&a, &b[..b.len() - 3], &calib).is_err());
    }

    #[test]
    fn finds_each_outlined_black_box_and_nothing_red_inside() {
        let (w, h) = (160, 90);
        let mut rgb = frame(w, h, [110, 112, 118]);
        deficit(&mut rgb, w, (10, 10, 40, 50));
        deficit(&mut rgb, w, (100, 60, 112, 70));
        // A stop-sign-like red face and a lone red pixel: red inside, not outlines.
        paint(&mut rgb, w, (60, 20, 80, 40), |_, _| [196, 22, 32]);
        paint(&mut rgb, w, (130, 10, 131, 11), |_, _| [255, 0, 0]);
        // A dark patch without an outline.
        paint(&mut rgb, w, (60, 60, 90, 80), |_, _| [5, 5, 5]);
        let got = find_deficits(&rgb, w, h).unwrap();
        let boxes: Vec<_> = got.iter().map(|d| (d.x0, d.y0, d.x1, d.y1)).collect();
        assert_eq!(boxes, vec![(10, 10, 40, 50), (100, 60, 112, 70)]);
        assert!(got.iter().all(|d| d.outline == 1.0 && d.fill_lum == 0.0));
    }

    #[test]
    fn a_distant_lamps_mask_is_a_solid_red_bar_and_a_lit_lamp_is_not() {
        let (w, h) = (120, 80);
        let mut rgb = frame(w, h, [90, 92, 96]);
        // A mask 3 px wide and 10 tall: all outline, no room for fill.
        paint(&mut rgb, w, (40, 10, 43, 20), |_, _| [255, 0, 0]);
        // A lit red lamp: a 4 × 4 disc-like blob; a wide red bar (a tail lamp).
        paint(&mut rgb, w, (80, 10, 84, 14), |_, _| [255, 0, 0]);
        paint(&mut rgb, w, (60, 50, 76, 53), |_, _| [255, 0, 0]);
        // Farther still: a bar 3 px wide and 7 tall.
        paint(&mut rgb, w, (100, 10, 103, 17), |_, _| [255, 0, 0]);
        // A narrow mask with a black core (6 × 21, as a signal head's mask at 40 m in the
        // closed loop's tele view), and the same ring around a lit grey core, which is not
        // a mask.
        let ring = |x0: usize, y0: usize, core: [u8; 3]| {
            move |x: usize, y: usize| {
                if x < x0 + 2 || x >= x0 + 4 || y < y0 + 2 || y >= y0 + 19 {
                    [255, 0, 0]
                } else {
                    core
                }
            }
        };
        paint(&mut rgb, w, (10, 30, 16, 51), ring(10, 30, [0, 0, 0]));
        paint(&mut rgb, w, (25, 30, 31, 51), ring(25, 30, [160, 160, 160]));
        let got = find_deficits(&rgb, w, h).unwrap();
        let boxes: Vec<_> = got.iter().map(|d| (d.x0, d.y0, d.x1, d.y1)).collect();
        assert_eq!(
            boxes,
            vec![(40, 10, 43, 20), (100, 10, 103, 17), (10, 30, 16, 51)]
        );
    }

    #[test]
    fn survives_noise_and_rejects_bad_sizes() {
        let (w, h) = (120, 80);
        let mut rgb = frame(w, h, [90, 90, 95]);
        deficit(&mut rgb, w, (30, 20, 70, 60));
        noisy(&mut rgb, 60);
        let got = find_deficits(&rgb, w, h).unwrap();
        assert_eq!(got.len(), 1, "{got:?}");
        assert_eq!(
            (got[0].x0, got[0].y0, got[0].x1, got[0].y1),
            (30, 20, 70, 60)
        );
        assert!(got[0].fill_lum > 0.0 && got[0].fill_lum < 40.0);
        assert!(find_deficits(&rgb, w, h + 1).is_err());
        assert!(find_deficits(&[], 0, 0).is_err());
    }

    #[test]
    fn an_object_box_stands_on_its_contact() {
        let calib = CameraCalib::standard(CameraId::FrontWide, 576, 320);
        let b = image_box(&calib, &[[10.0, -0.9], [10.0, 0.9]], 1.5).unwrap();
        // Centred, its foot well below the horizon, its top (1.5 m, the camera is 1.6 m up)
        // just below it...
        assert!(b[0] < calib.cx && b[2] > calib.cx, "{b:?}");
        assert!(
            b[3] > calib.cy + 20.0 && (b[1] - calib.cy).abs() < 5.0,
            "{b:?}"
        );
        // ...and smaller when farther.
        let far = image_box(&calib, &[[20.0, -0.9], [20.0, 0.9]], 1.5).unwrap();
        assert!(far[2] - far[0] < b[2] - b[0]);
        // Behind the camera: not in view.
        assert!(image_box(&calib, &[[-5.0, -0.9], [-5.0, 0.9]], 1.5).is_none());
    }
}
