//! Render cost in the sim's towns: `cargo run --release -p fogline-sim --example render_bench`.
#![allow(clippy::print_stdout, clippy::unwrap_used)]

use std::time::Instant;

use fogline_sim::sense::{Daylight, PartsCache, Weather, look, scene_at};
use fogline_sim::suite::{Suite, SuiteParams};
use fogline_sim::traffic::Traffic;
use fogline_sim::vehicle::VehicleState;
use fogline_types::clip::{CameraCalib, CameraId};

fn main() {
    let s = Suite::build(&SuiteParams::quick(), 0, 4.0).unwrap();
    let case = &s.cases[1];
    let town = &s.towns[case.town];
    let traffic = Traffic::new(town, &case.route, Default::default(), 1);
    let cache = PartsCache::new(town);
    let lk = look(Weather::Cloudy, Daylight::Noon);
    for (name, cam, w, h, fov) in [
        ("wide120 384x216", CameraId::FrontWide, 384, 216, None),
        ("wide120 256x144", CameraId::FrontWide, 256, 144, None),
        ("wide90 320x240", CameraId::FrontWide, 320, 240, Some(90.0)),
        ("tele30 320x240", CameraId::FrontTele, 320, 240, None),
        ("tele30 256x144", CameraId::FrontTele, 256, 144, None),
        ("cross120 256x144", CameraId::CrossLeft, 256, 144, None),
    ] {
        let mut calib = CameraCalib::standard(cam, w, h);
        if let Some(f) = fov {
            let fx = f64::from(w) / 2.0 / (f64::to_radians(f) / 2.0).tan();
            calib.fx = fx;
            calib.fy = fx;
        }
        let mut total = 0.0;
        let mut n = 0;
        let (mut ns, mut no) = (0, 0);
        for k in 0..40 {
            let sdist = 10.0 + 9.0 * k as f64;
            let (p, u) = case.route.pose(sdist);
            let ego = VehicleState {
                x_m: p[0],
                y_m: p[1],
                yaw_rad: u[1].atan2(u[0]),
                speed_mps: 5.0,
            };
            let around = scene_at(town, &traffic, &cache, &ego, 0.0, lk);
            let scene = around.for_camera(&calib);
            ns += scene.strips.len();
            no += scene.solids.len();
            let t0 = Instant::now();
            for _ in 0..5 {
                let _ = fogline_world::render::render(&scene, &calib, 0.0, false);
            }
            total += t0.elapsed().as_secs_f64();
            n += 5;
        }
        println!(
            "{name:18} {:.3} ms/frame, {:.1} strips, {:.1} solids",
            total * 1000.0 / n as f64,
            ns as f64 / 40.0,
            no as f64 / 40.0
        );
    }
}
