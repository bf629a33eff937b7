//! The planner's stop-sign reader on the closed loop's own frames (issue 17): the towns'
//! stop signs rendered through the agent's two cameras at the distances a stop needs, in
//! every weather and daylight of the suite, with and without the stop-sign deficit.
//!
//! The towns here are drawn with seeds no route suite uses (the suite's towns are drawn
//! with the run seed, 0–4 in the figures), and no reader threshold was tuned on them: the
//! reader was measured on town seed 41 (`the_tuning_towns_signs_stay_read_from_6_to_25_m` prints a
//! table) and is checked here on town seeds 57 and 58.

use fogline_perturb::frame::FrameKey;
use fogline_planner::perceive::{Knowing, Lost, perceive_knowing};
use fogline_sim::geom::{P2, add, right_of};
use fogline_sim::route;
use fogline_sim::run::SensorParams;
use fogline_sim::sense::{Daylight, DeficitKind, Lens, PartsCache, Weather, look, scene_at, see};
use fogline_sim::town::{DIRS, HALF_ROAD_M, LANE_W_M, Town, TownParams};
use fogline_sim::traffic::{Traffic, TrafficParams};
use fogline_sim::vehicle::VehicleState;
use fogline_types::clip::{CAMERA_X_M, CameraCalib, CameraInput, EgoPose, PlannerInput};
use fogline_world::scene::Draw;

/// The agent's two cameras at the closed loop's default sizes.
fn cameras() -> (CameraCalib, CameraCalib) {
    let ([_, wide, _], tele) = SensorParams::default().cameras();
    (wide, tele)
}

/// A town with its static parts and no traffic.
pub(crate) struct Place {
    pub(crate) town: Town,
    pub(crate) cache: PartsCache,
    pub(crate) traffic: Traffic,
}

fn place(seed: u64, index: u64, vehicles: usize) -> Place {
    place_route(seed, index, vehicles).0
}

/// A town, traffic around a 600 m route through it, and the route.
pub(crate) fn place_route(seed: u64, index: u64, vehicles: usize) -> (Place, route::Route) {
    place_with(seed, index, vehicles, 0)
}

/// [`place_route`] with `pedestrians` walkers too.
pub(crate) fn place_with(
    seed: u64,
    index: u64,
    vehicles: usize,
    pedestrians: usize,
) -> (Place, route::Route) {
    let town = Town::generate(TownParams::default(), seed, index);
    let mut d = Draw::new(seed, &[index, 0x516]);
    let r = route::generate(&town, 600.0, 0.0, &mut d).unwrap();
    let traffic = Traffic::new(
        &town,
        &r,
        TrafficParams {
            vehicles,
            pedestrians,
            cyclist_share: 0.0,
            events_per_km: 0.0,
        },
        seed,
    );
    let cache = PartsCache::new(&town);
    (
        Place {
            town,
            cache,
            traffic,
        },
        r,
    )
}

/// What the reader says from one pose: the sign distance (from the rig origin, as the
/// planner reports it) without and with the lost regions the override finds.
#[derive(Debug, Clone, Copy)]
struct Reading {
    blind: Option<f64>,
    knowing: Option<f64>,
    /// Whether the deficit hid something in either view.
    masked: bool,
    /// Whether it hid something in the wide view, and in the telephoto view.
    wide_masked: bool,
    tele_masked: bool,
}

fn read_at(
    p: &Place,
    ego: &VehicleState,
    weather: Weather,
    daylight: Daylight,
    deficit: Option<DeficitKind>,
    key: u64,
) -> Reading {
    let (wide, tele) = cameras();
    let lens = Lens::new(weather, deficit).unwrap();
    let sc = scene_at(
        &p.town,
        &p.traffic,
        &p.cache,
        ego,
        0.0,
        look(weather, daylight),
    );
    let w = see(&sc, &wide, &lens, FrameKey::new(key, 0, 0));
    let t = see(&sc, &tele, &lens, FrameKey::new(key, 1, 0));
    let masked = !w.deficits.is_empty() || !t.deficits.is_empty();
    let lost = fogline_sim::run::lost_in(&[(&wide, &w.frame), (&tele, &t.frame)]);
    let history = [EgoPose {
        t_s: 0.0,
        x_m: 0.0,
        y_m: 0.0,
        yaw_rad: 0.0,
        speed_mps: 0.0,
    }];
    let read = |lost: &[Lost]| {
        let input = PlannerInput {
            cameras: vec![
                CameraInput {
                    calib: wide,
                    frames: vec![w.frame.data()],
                },
                CameraInput {
                    calib: tele,
                    frames: vec![t.frame.data()],
                },
            ],
            ego_history: &history,
        };
        perceive_knowing(
            &input,
            &Knowing {
                lost,
                nav_kappa: Some(0.0),
                ..Knowing::default()
            },
        )
        .stop_sign
    };
    Reading {
        blind: read(&[]),
        knowing: read(&lost),
        masked,
        wide_masked: !w.deficits.is_empty(),
        tele_masked: !t.deficits.is_empty(),
    }
}

/// The ego in the approach lane of `sign`, its cameras `dist_m` short of the sign (along
/// the lane).
pub(crate) fn approach(p: &Place, sign: usize, dist_m: f64) -> VehicleState {
    let s = &p.town.signs[sign];
    let u: P2 = DIRS[s.din];
    let r = right_of(u);
    // The sign stands `HALF_ROAD_M + 0.9` right of the road's centre, the lane's middle
    // `LANE_W_M / 2`.
    let lane = add(s.pos, r, -(HALF_ROAD_M + 0.9 - LANE_W_M / 2.0));
    let at = add(lane, u, -(dist_m + CAMERA_X_M));
    VehicleState {
        x_m: at[0],
        y_m: at[1],
        yaw_rad: u[1].atan2(u[0]),
        speed_mps: 0.0,
    }
}

/// The signs of a town whose approach is straight road for `reach_m` before the sign (no
/// junction of its own in between).
pub(crate) fn signs_with_room(p: &Place, reach_m: f64) -> Vec<usize> {
    (0..p.town.signs.len())
        .filter(|&k| {
            let s = &p.town.signs[k];
            let u = DIRS[s.din];
            let back = add(s.pos, u, -reach_m);
            p.town.nodes.iter().all(|n| {
                // Nodes on the approach between `back` and the sign's junction.
                let along = (n.pos[0] - back[0]) * u[0] + (n.pos[1] - back[1]) * u[1];
                let across = (n.pos[0] - back[0]) * -u[1] + (n.pos[1] - back[1]) * u[0];
                !(across.abs() < 12.0 && along > -5.0 && along < reach_m - 5.0)
            })
        })
        .collect()
}

pub(crate) const LIGHTS: [(Weather, Daylight); 8] = [
    (Weather::Cloudy, Daylight::Noon),
    (Weather::Wet, Daylight::Morning),
    (Weather::SoftRain, Daylight::Dawn),
    (Weather::WetCloudy, Daylight::Sunset),
    (Weather::MidRain, Daylight::Twilight),
    (Weather::HardRain, Daylight::Night),
    (Weather::Cloudy, Daylight::Night),
    (Weather::HardRain, Daylight::Noon),
];

/// Recall per distance, clean frames and under the deficit (with the override's lost
/// regions), and false readings (a sign read from a mask, or at the wrong distance).
#[derive(Debug, Default, Clone, Copy)]
struct Tally {
    n: usize,
    read: usize,
    near_truth: usize,
}

fn tally_line(label: &str, t: &Tally) -> String {
    format!(
        "{label:>28}: {:>3}/{:<3} read, {:>3} within 25 % of the truth",
        t.read, t.n, t.near_truth
    )
}

/// The reader's tallies per distance, clean and under the deficit, and the lines that print
/// them.
fn measure(seed: u64, towns: u64, dists: &[f64]) -> (Vec<Vec<Tally>>, Vec<String>) {
    let mut out = Vec::new();
    let mut tallies = Vec::new();
    for deficit in [None, Some(DeficitKind::StopSign)] {
        let mut per_d = vec![Tally::default(); dists.len()];
        let mut mask_reads = 0usize;
        let mut mask_n = 0usize;
        for ti in 0..towns {
            let p = place(seed, ti, 0);
            for (si, sign) in signs_with_room(&p, 45.0).into_iter().enumerate().take(6) {
                for (li, &(w, l)) in LIGHTS.iter().enumerate() {
                    for (di, &d) in dists.iter().enumerate() {
                        let ego = approach(&p, sign, d);
                        let key = (ti * 1000 + si as u64) * 100 + li as u64 * 10 + di as u64;
                        let r = read_at(&p, &ego, w, l, deficit, key);
                        // The override knows the lost regions; without a deficit there are
                        // none and both readings agree.
                        let got = if deficit.is_some() {
                            r.knowing
                        } else {
                            r.blind
                        };
                        let truth = d + CAMERA_X_M;
                        let t = &mut per_d[di];
                        t.n += 1;
                        if let Some(x) = got {
                            t.read += 1;
                            if (x - truth).abs() <= 0.25 * truth {
                                t.near_truth += 1;
                            }
                        }
                        if deficit.is_some() && r.masked {
                            mask_n += 1;
                            // Blind (no lost regions given): a reading from the mask.
                            if r.blind.is_some() && r.knowing.is_none() {
                                mask_reads += 1;
                            }
                        }
                    }
                }
            }
        }
        out.push(format!(
            "deficit {:?}",
            deficit.map_or("none", DeficitKind::name)
        ));
        for (d, t) in dists.iter().zip(&per_d) {
            out.push(tally_line(&format!("{d:.0} m"), t));
        }
        if deficit.is_some() {
            out.push(format!(
                "  masked frames: {mask_n}, read blind but not knowing: {mask_reads}"
            ));
        }
        tallies.push(per_d);
    }
    (tallies, out)
}

/// The town the reader's thresholds were measured on (seed 41): its recall table is printed
/// (`cargo nextest run -p fogline-sim sign_reader::the_tuning --no-capture`) and held — every
/// sign read within 25 % of its distance from 6 to 25 m in clean frames, in every lighting.
/// The checks on towns nothing was tuned on are the tests below.
#[test]
fn the_tuning_towns_signs_stay_read_from_6_to_25_m() {
    let dists = [6.0, 9.0, 12.0, 15.0, 18.0, 20.0, 22.0, 25.0, 30.0, 40.0];
    let (tallies, lines) = measure(41, 3, &dists);
    for line in &lines {
        eprintln!("{line}");
    }
    for (d, t) in dists.iter().zip(&tallies[0]).filter(|(d, _)| **d <= 25.0) {
        assert!(t.n > 0 && t.near_truth == t.n, "{d} m: {t:?}");
    }
}

/// False readings along routes with traffic: poses every 10 m of a route, in every
/// lighting, where no sign faces the ego within 80 m ahead on its right. Returns (poses,
/// readings).
fn false_readings(seed: u64, towns: u64) -> (usize, usize, Vec<String>) {
    let (mut n, mut bad) = (0usize, 0usize);
    let mut notes = Vec::new();
    for ti in 0..towns {
        let (p, r) = place_route(seed, ti, 40);
        let len = r.length_m();
        let mut s = 5.0;
        let mut k = 0u64;
        while s < len - 5.0 {
            let (pos, u) = r.pose(s);
            let yaw = u[1].atan2(u[0]);
            let sign_ahead = p.town.signs.iter().any(|sg| {
                let (dx, dy) = (sg.pos[0] - pos[0], sg.pos[1] - pos[1]);
                let ahead = dx * u[0] + dy * u[1];
                let left = -dx * u[1] + dy * u[0];
                let facing = (sg.yaw - yaw).sin().abs() < 0.5 && (sg.yaw - yaw).cos() > 0.0;
                facing && ahead > -2.0 && ahead < 80.0 && left < 0.0 && left > -9.0
            });
            if !sign_ahead {
                let ego = VehicleState {
                    x_m: pos[0],
                    y_m: pos[1],
                    yaw_rad: yaw,
                    speed_mps: 0.0,
                };
                let (w, l) = LIGHTS[(k as usize) % LIGHTS.len()];
                let rd = read_at(&p, &ego, w, l, None, 7000 + k);
                n += 1;
                if let Some(d) = rd.blind {
                    bad += 1;
                    notes.push(format!(
                        "town {seed}/{ti} s {s:.0} {} {}: {d:.1} m",
                        w.name(),
                        l.name()
                    ));
                }
            }
            s += 10.0;
            k += 1;
        }
    }
    (n, bad, notes)
}

/// The distances a stop needs: from 8 m/s at 2.5 m/s² a car needs 12.8 m, so a reading by
/// 20 m leaves room; 8 m is where the sign leaves the telephoto view.
const NEEDED: [f64; 6] = [8.0, 11.0, 14.0, 17.0, 20.0, 23.0];

#[test]
fn a_visible_sign_is_read_at_the_distances_a_stop_needs() {
    // Clean frames (no deficit), every lighting and weather of `LIGHTS` except heavy rain at
    // night (a face 20 m away in 120 m visibility at night keeps too little of its red).
    let mut t = Tally::default();
    let mut misses = Vec::new();
    for town in 0..2 {
        let p = place(57, town, 0);
        for sign in signs_with_room(&p, 45.0).into_iter().take(3) {
            for (li, &(w, l)) in LIGHTS.iter().enumerate() {
                for (di, &d) in NEEDED.iter().enumerate() {
                    let r = read_at(
                        &p,
                        &approach(&p, sign, d),
                        w,
                        l,
                        None,
                        (li * 10 + di) as u64,
                    );
                    let truth = d + CAMERA_X_M;
                    t.n += 1;
                    if r.blind.is_some_and(|x| (x - truth).abs() <= 0.25 * truth) {
                        t.near_truth += 1;
                    } else {
                        misses.push(format!("{} {} {d} m: {:?}", w.name(), l.name(), r.blind));
                    }
                }
            }
        }
    }
    assert!(
        t.near_truth * 100 >= 90 * t.n,
        "{} of {} read within 25 %; misses: {misses:?}",
        t.near_truth,
        t.n
    );
}

#[test]
fn under_the_deficit_the_mask_is_never_read_and_the_unmasked_sign_is() {
    let mut from_mask = Vec::new();
    let (mut unmasked_n, mut unmasked_read) = (0usize, 0usize);
    for town in 0..2 {
        let p = place(58, town, 0);
        for sign in signs_with_room(&p, 45.0).into_iter().take(3) {
            for (li, &(w, l)) in LIGHTS.iter().enumerate() {
                for (di, &d) in [10.0, 13.0, 16.0, 20.0, 22.0, 24.0].iter().enumerate() {
                    let ego = approach(&p, sign, d);
                    let key = (li * 10 + di) as u64;
                    let masked = read_at(&p, &ego, w, l, Some(DeficitKind::StopSign), key);
                    // Within about 18 m the face is big enough for the detector in both
                    // views (within 11 m it has left the telephoto view): masked wherever it
                    // is seen, nothing is left to read, whether the reader is told where the
                    // lost regions are or not.
                    if masked.wide_masked && (masked.tele_masked || d < 11.0) {
                        if masked.blind.is_some() || masked.knowing.is_some() {
                            from_mask.push(format!(
                                "{} {} {d} m: {:?}/{:?}",
                                w.name(),
                                l.name(),
                                masked.blind,
                                masked.knowing
                            ));
                        }
                    } else if !masked.wide_masked && d <= 22.0 && w != Weather::HardRain {
                        // Beyond it the wide view's face is too small for the detector and
                        // stays visible: the override (knowing the telephoto's mask is
                        // lost) still reads the sign.
                        unmasked_n += 1;
                        let truth = d + CAMERA_X_M;
                        unmasked_read += usize::from(
                            masked
                                .knowing
                                .is_some_and(|x| (x - truth).abs() <= 0.25 * truth),
                        );
                    }
                }
            }
        }
    }
    assert!(from_mask.is_empty(), "read from a mask: {from_mask:?}");
    assert!(unmasked_n >= 20, "{unmasked_n} unmasked wide-view signs");
    assert!(
        unmasked_read * 100 >= 80 * unmasked_n,
        "{unmasked_read} of {unmasked_n} unmasked wide-view signs read"
    );
}

#[test]
fn no_sign_is_read_where_none_stands_red_cars_and_lamps_included() {
    let (n, bad, notes) = false_readings(57, 2);
    assert!(n > 50, "{n} poses");
    assert!(
        bad == 0,
        "{bad} of {n} poses without a sign read one: {notes:?}"
    );
}
