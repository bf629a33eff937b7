//! Development aid for the reference planner's perception: which decisions and percepts a
//! condition changes, per scenario, on world clips (the expert's decisions come from the
//! world, which is why this lives beside the campaign and not in the planner).
//!
//! ```sh
//! cargo run --release -p fogline-campaign --example percept_diff -- 400 7 noise_30,noise_50
//! ```
//!
//! Arguments: clips (paper mix), world seed, conditions. Environment: `VERBOSE=1` lists every
//! clip whose decision changed with the percepts that changed; `CLEAN=1` lists the clean
//! clips that disagree with the expert; `BOXES=1` prints the renderer's non-car boxes and
//! the scene facts of each clip (what is really there); `SPEED=1` prints, for clips with a
//! lead, its true speed beside the clean and perturbed estimates and their standard errors,
//! the true and perceived gaps, both ADEs and both decisions;
//! `ONLY=i,j` runs those clip indices only;
//! `THREADS=n` (default 2). Prints, per condition and scenario, clean and perturbed agreement
//! with the expert, the mean ADE before and after, and the flips against the clean decision.
#![allow(
    clippy::print_stdout,
    clippy::print_stderr,
    clippy::too_many_lines,
    clippy::type_complexity
)]
use fogline_campaign::runner::{clip_key, condition_frames, planner_input};
use fogline_perturb::Perturbation;
use fogline_planner::ReferencePlanner;
use fogline_world::{ScenarioMix, WorldConfig, generate_clip};
use std::collections::BTreeMap;

static PLAN_NS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
static PLAN_N: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let clips: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(300);
    let seed: u64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(0);
    let conds: Vec<String> = args
        .get(3)
        .map_or("noise_30,noise_50,noise_70", String::as_str)
        .split(',')
        .map(String::from)
        .collect();
    let verbose = std::env::var("VERBOSE").is_ok();
    let cfg = WorldConfig {
        seed,
        mix: ScenarioMix::paper_scaled(clips),
        ..WorldConfig::default()
    };
    let mut prepared = vec![Perturbation::identity().prepare(0)?];
    for c in &conds {
        let parsed = Perturbation::parse(c).map_err(|e| format!("condition {c:?}: {e}"))?;
        prepared.push(parsed.prepare(0)?);
    }
    let planner = ReferencePlanner::new();
    let n = cfg.mix.total();
    let conds = &conds;
    let results: Vec<Vec<String>> = std::thread::scope(|s| {
        let nt: usize = std::env::var("THREADS")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(2);
        let hs: Vec<_> = (0..nt)
            .map(|t| {
                let (cfg, prepared, planner) = (&cfg, &prepared, &planner);
                s.spawn(move || {
                    let mut out = Vec::new();
                    for i in (t..n).step_by(nt).filter(|i| std::env::var("ONLY").map_or(true, |o| o.split(',').any(|x| x == i.to_string()))) {
                        let clip = match generate_clip(cfg, i) {
                            Ok(c) => c,
                            Err(e) => {
                                eprintln!("clip {i}: {e}");
                                continue;
                            }
                        };
                        let key = clip_key(i);
                        let mut clean = None;
                        for (ci, cond) in prepared.iter().enumerate() {
                            let Ok(frames) = condition_frames(&clip, key, cond) else {
                                eprintln!("clip {i}: the condition could not be applied");
                                continue;
                            };
                            let input = planner_input(&clip, &frames);
                            let t0 = std::time::Instant::now();
                            let Ok((p, plan)) = planner.plan_with_perception(&input) else {
                                eprintln!("clip {i}: the planner refused its input");
                                continue;
                            };
                            PLAN_NS.fetch_add(t0.elapsed().as_nanos() as u64, std::sync::atomic::Ordering::Relaxed);
                            PLAN_N.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                            let ade = plan.trajectory.ade(&clip.ground_truth);
                            if ci == 0 {
                                if std::env::var("CLEAN").is_ok() && clip.scene.decision != Some(plan.decision) {
                                    eprintln!("CLEAN {} {i} {:?} -> {:?} ade {ade:.2} lead {:?} light {:?} sign {:?} end {:?} rb {} zebra {:?} line {:?} lane {:?} leftfree {}", clip.scenario, clip.scene.decision, plan.decision, p.lead.map(|l| (l.kind, l.contact_x as i32, l.right_edge, l.left_edge, l.speed as i32, l.width_m, (l.lateral_speed * 10.0).round() / 10.0, (l.speed_se * 10.0).round() / 10.0)), p.light, p.stop_sign.map(|x| x as i32), p.road_end, p.right_branch, p.zebra, p.stop_line, p.lane.map(|l| (l.offset, l.width)), p.left_lane_free);
                                }
                                if std::env::var("BOXES").is_ok() {
                                    for cam in &clip.cameras {
                                        if let Some(f) = cam.frames.last() {
                                            for b in f.boxes.iter().filter(|b| b.class != "car") {
                                                eprintln!("BOX {i} {:?} {} x {:.0} y {:.0} w {:.0} h {:.0}", cam.calib.id, b.class, b.x_px, b.y_px, b.width_px, b.height_px);
                                            }
                                        }
                                    }
                                    eprintln!("FACTS {i} {:?}", clip.scene.facts);
                                }
                                clean = Some((p, plan.decision, ade));
                                continue;
                            }
                            let Some((cp, cd, cade)) = clean.as_ref() else {
                                continue;
                            };
                            if std::env::var("SPEED").is_ok()
                                && let Some(v) = clip.scene.facts.get("lead_speed_mps").and_then(|v| v.as_f64())
                            {
                                let g = clip.scene.facts.get("lead_gap_m").and_then(|v| v.as_f64()).unwrap_or(f64::NAN);
                                eprintln!("SPEED {} {i} true {v:.2} clean {:?} noisy {:?} gap {g:.2} {:?} {:?} ade {cade:.2} {ade:.2} dec {cd:?} {:?}", clip.scenario, cp.lead.map(|l| (l.speed, l.speed_se)), p.lead.map(|l| (l.speed, l.speed_se)), cp.lead.map(|l| l.gap), p.lead.map(|l| l.gap), plan.decision);
                            }
                            let mut what = Vec::new();
                            let lk = |l: &Option<fogline_planner::perceive::LeadSeen>| {
                                l.map(|l| format!("{:?}@{:.0}", l.kind, l.contact_x))
                            };
                            if cp.lead.map(|l| l.kind) != p.lead.map(|l| l.kind)
                                || cp.lead.is_some_and(|a| p.lead.is_some_and(|b| (a.contact_x - b.contact_x).abs() > 3.0))
                            {
                                what.push(format!("lead {:?}->{:?}", lk(&cp.lead), lk(&p.lead)));
                            }
                            if cp.light.map(|l| l.0) != p.light.map(|l| l.0) {
                                what.push(format!("light {:?}->{:?}", cp.light, p.light));
                            }
                            if cp.stop_sign.is_some() != p.stop_sign.is_some() {
                                what.push(format!("sign {:?}->{:?}", cp.stop_sign, p.stop_sign));
                            }
                            if cp.road_end.is_some() != p.road_end.is_some() || cp.right_branch != p.right_branch {
                                what.push(format!("end {:?}{}->{:?}{}", cp.road_end, cp.right_branch, p.road_end, p.right_branch));
                            }
                            if cp.zebra.is_some() != p.zebra.is_some() {
                                what.push(format!("zebra {:?}->{:?}", cp.zebra, p.zebra));
                            }
                            if cp.stop_line.is_some() != p.stop_line.is_some() {
                                what.push(format!("line {:?}->{:?}", cp.stop_line, p.stop_line));
                            }
                            if cp.lane.is_some() != p.lane.is_some() {
                                what.push("lane lost/found".into());
                            }
                            if cp.left_lane_free != p.left_lane_free {
                                what.push("leftfree".into());
                            }
                            if (cp.lane_offset - p.lane_offset).abs() > 0.1 {
                                what.push(format!("offset {:.2}->{:.2}", cp.lane_offset, p.lane_offset));
                            }
                            out.push(format!(
                                "{}\t{}\t{}\t{:?}\t{:?}\t{:?}\t{:.2}\t{:.2}\t{}",
                                conds[ci - 1],
                                clip.scenario,
                                i,
                                clip.scene.decision,
                                cd,
                                plan.decision,
                                cade,
                                ade,
                                what.join("; ")
                            ));
                        }
                    }
                    out
                })
            })
            .collect();
        hs.into_iter().filter_map(|h| h.join().ok()).collect()
    });
    let mut lines: Vec<String> = results.into_iter().flatten().collect();
    lines.sort();
    // Summary: per condition, scenario: n, agree, mean ade clean/cond, flips vs clean, causes.
    let mut agg: BTreeMap<(String, String), (usize, usize, f64, f64, usize, usize)> =
        BTreeMap::new();
    let mut causes: BTreeMap<(String, String), usize> = BTreeMap::new();
    for l in &lines {
        let f: Vec<&str> = l.split('\t').collect();
        for sc in [f[1], "ALL"] {
            let e = agg.entry((f[0].into(), sc.into())).or_default();
            e.0 += 1;
            e.1 += usize::from(f[3] == format!("Some({})", f[5]));
            e.2 += f[6].parse::<f64>().unwrap_or(f64::NAN);
            e.3 += f[7].parse::<f64>().unwrap_or(f64::NAN);
            e.4 += usize::from(f[4] != f[5]);
            e.5 += usize::from(f[3] == format!("Some({})", f[4]));
        }
        if f[4] != f[5] || verbose {
            for w in f[8].split("; ").filter(|w| !w.is_empty()) {
                let k = w.split_whitespace().next().unwrap_or("").to_string();
                *causes.entry((f[0].into(), k)).or_default() += 1;
            }
        }
        if verbose && f[4] != f[5] {
            println!("{l}");
        }
    }
    for ((c, s), (n, a, ac, ad, fl, ca)) in &agg {
        println!(
            "{c:10} {s:15} n {n:4} clean agree {:5.1}% agree {:5.1}% ade {:.3} -> {:.3} ({:+.0}%) flips {fl}",
            100.0 * *ca as f64 / *n as f64,
            100.0 * *a as f64 / *n as f64,
            ac / *n as f64,
            ad / *n as f64,
            100.0 * (ad / ac - 1.0)
        );
    }
    println!(
        "plan ms mean {:.2}",
        PLAN_NS.load(std::sync::atomic::Ordering::Relaxed) as f64
            / 1e6
            / PLAN_N.load(std::sync::atomic::Ordering::Relaxed).max(1) as f64
    );
    for ((c, k), n) in &causes {
        println!("cause {c} {k} {n}");
    }
    Ok(())
}
