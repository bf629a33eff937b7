//! Scratch evaluation of the reference planner on generated clips (development aid).
#![allow(clippy::print_stdout, clippy::unwrap_used, missing_docs)]
use fogline_planner::ReferencePlanner;
use fogline_types::clip::{CameraInput, PlannerInput};
use fogline_world::{ScenarioMix, WorldConfig, generate_clip};
use rayon::prelude::*;

fn main() {
    if let Ok(i) = std::env::var("PROBE") { probe(i.parse().unwrap()); return; }
    if let Ok(i) = std::env::var("DUMP") {
        dump(i.parse().unwrap());
        return;
    }
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args.get(1).map_or(200, |s| s.parse().unwrap());
    let only = args.get(2).cloned();
    let mix = match &only {
        Some(s) => ScenarioMix::only(s, n).unwrap(),
        None => ScenarioMix::paper_scaled(n),
    };
    let cfg = WorldConfig {
        mix,
        depth: false,
        ..WorldConfig::default()
    };
    let planner = ReferencePlanner::new();
    let rows: Vec<_> = (0..cfg.mix.total())
        .into_par_iter()
        .map(|i| {
            let clip = generate_clip(&cfg, i).unwrap();
            let cams: Vec<CameraInput> = clip
                .cameras
                .iter()
                .map(|c| CameraInput {
                    calib: c.calib,
                    frames: c.frames.iter().map(|f| f.image.data()).collect(),
                })
                .collect();
            let input = PlannerInput {
                cameras: cams,
                ego_history: &clip.ego_history,
            };
            let t = std::time::Instant::now();
            let (p, plan) = planner.plan_with_perception(&input).unwrap();
            let ms = t.elapsed().as_secs_f64() * 1e3;
            let ade = plan.trajectory.ade(&clip.ground_truth);
            (
                i,
                clip.scenario.clone(),
                clip.scene.decision.unwrap(),
                plan.decision,
                ade,
                ms,
                format!("{:?}", clip.scene.facts),
                format!("{p:?}"),
                plan.explanation,
            )
        })
        .collect();
    let mut by: std::collections::BTreeMap<String, Vec<&_>> = Default::default();
    for r in &rows {
        by.entry(r.1.clone()).or_default().push(r);
    }
    for (s, v) in &by {
        let mut ades: Vec<f64> = v.iter().map(|r| r.4).collect();
        ades.sort_by(f64::total_cmp);
        let agree = v.iter().filter(|r| r.2 == r.3).count();
        println!(
            "{s:16} n={:4} median ADE {:6.2} p90 {:6.2} agree {:5.1}%",
            v.len(),
            ades[ades.len() / 2],
            ades[ades.len() * 9 / 10],
            100.0 * agree as f64 / v.len() as f64
        );
    }
    let mut ms: Vec<f64> = rows.iter().map(|r| r.5).collect();
    ms.sort_by(f64::total_cmp);
    println!("planner ms median {:.2}", ms[ms.len() / 2]);
    if std::env::var("SHOW").is_ok() {
        for r in &rows {
            if r.2 != r.3 || r.4 > 3.0 {
                println!(
                    "#{} {} expert {:?} planner {:?} ADE {:.2}\n  facts {}\n  perc {}\n  {}",
                    r.0, r.1, r.2, r.3, r.4, r.6, r.7, r.8
                );
            }
        }
    }
}

#[allow(dead_code)]
pub fn dump(i: usize) {
    let cfg = WorldConfig {
        mix: ScenarioMix::paper_scaled(200),
        depth: false,
        ..WorldConfig::default()
    };
    let clip = generate_clip(&cfg, i).unwrap();
    for c in &clip.cameras {
        let f = &c.frames[3].image;
        image::save_buffer(
            format!("/tmp/dump_{i}_{}.png", c.calib.id.short()),
            f.data(),
            f.width(),
            f.height(),
            image::ExtendedColorType::Rgb8,
        )
        .unwrap();
    }
}

#[allow(dead_code)]
pub fn probe(i: usize) {
    use fogline_types::clip::CameraId;
    let cfg = WorldConfig { mix: ScenarioMix::paper_scaled(200), depth: false, ..WorldConfig::default() };
    let clip = generate_clip(&cfg, i).unwrap();
    let c = clip.cameras.iter().find(|c| c.calib.id == CameraId::FrontWide).unwrap();
    let v = fogline_planner::vision::View { calib: &c.calib, rgb: c.frames[3].image.data() };
    for y in [-1.7, -1.0, 0.0, 1.0, 1.7] {
        let mut s = String::new();
        for k in 0..16 {
            let x = 4.5 + 0.25 * k as f64;
            let col = v.at_point([x, y, 0.0]);
            s += &format!("{:?} ", col.map(|c| (c[0] as i32, c[1] as i32, c[2] as i32)));
        }
        println!("y={y}: {s}");
    }
}
