//! `fogline rco bench`: the per-tick cost of the LLM-RCO controller's rule-based path and of
//! its verifier for three 576×320 views of a synthetic scene, next to the goal of 1 ms per
//! tick (p95).

use std::io::Write;
use std::time::Instant;

use anyhow::{Result, bail};
use fogline_rco::synth::BenchScene;
use fogline_rco::{Rco, RcoParams, verifier};
use serde::Serialize;

/// What `fogline rco bench` runs.
#[derive(Debug, Clone)]
pub struct RcoBench {
    /// Ticks timed per case (after 10 untimed ones).
    pub ticks: u64,
    /// Seed of the synthetic textures.
    pub seed: u64,
    /// Print the figures as JSON.
    pub json: bool,
}

#[derive(Serialize)]
struct Figures {
    case: String,
    ticks: u64,
    median_us: f64,
    p95_us: f64,
    max_us: f64,
    mean_us: f64,
    goal_us: f64,
    met: bool,
}

fn figures(case: &str, mut us: Vec<f64>) -> Figures {
    us.sort_by(f64::total_cmp);
    let n = us.len().max(1);
    let q = |p: f64| {
        us.get(((n as f64 - 1.0) * p).round() as usize)
            .copied()
            .unwrap_or(0.0)
    };
    let p95 = q(0.95);
    Figures {
        case: case.into(),
        ticks: us.len() as u64,
        median_us: q(0.5),
        p95_us: p95,
        max_us: us.last().copied().unwrap_or(0.0),
        mean_us: us.iter().sum::<f64>() / n as f64,
        goal_us: 1000.0,
        met: p95 <= 1000.0,
    }
}

/// Runs the benchmark, writing its table (or JSON) to `out`.
pub fn run(a: &RcoBench, out: &mut dyn Write) -> Result<()> {
    if a.ticks == 0 {
        bail!("--ticks must be at least 1");
    }
    let params = RcoParams::default();
    let warm = 10u64;
    let mut rows = Vec::new();
    // 3 px/tick: the deficits stay within the shift limit (image-space check only);
    // 14 px/tick: above the 11.5 px limit, so the verifier matches the background every tick.
    for flow in [3u32, 14] {
        let scene = BenchScene {
            seed: a.seed,
            flow_px_per_tick: flow,
        };
        log::info!(
            "rendering and timing {} ticks at {flow} px/tick",
            a.ticks + warm
        );
        let mut verifier_us = Vec::new();
        let mut tick_us = Vec::new();
        let mut rco = Rco::with_rules(params.clone())?;
        let mut prev = None;
        for t in 0..a.ticks + warm {
            let obs = scene.observation(t);
            let t0 = Instant::now();
            let s = verifier::assess(prev.as_ref(), &obs, &params.views, &params.verifier);
            let v = t0.elapsed().as_secs_f64() * 1e6;
            std::hint::black_box(&s);
            let t0 = Instant::now();
            let d = rco.step(&obs);
            let r = t0.elapsed().as_secs_f64() * 1e6;
            std::hint::black_box(&d);
            if t >= warm {
                verifier_us.push(v);
                tick_us.push(r);
            }
            prev = Some(obs);
        }
        rows.push(figures(
            &format!("verifier, scene flow {flow} px/tick"),
            verifier_us,
        ));
        rows.push(figures(
            &format!("rules tick (step), scene flow {flow} px/tick"),
            tick_us,
        ));
    }
    if a.json {
        writeln!(out, "{}", serde_json::to_string_pretty(&rows)?)?;
        return Ok(());
    }
    writeln!(
        out,
        "three 576x320 views (cross-left, front-wide, cross-right), {} timed ticks per case, one thread",
        a.ticks
    )?;
    writeln!(
        out,
        "{:<44} {:>10} {:>10} {:>10} {:>10}  goal",
        "case", "median µs", "p95 µs", "max µs", "mean µs"
    )?;
    for r in &rows {
        writeln!(
            out,
            "{:<44} {:>10.1} {:>10.1} {:>10.1} {:>10.1}  ≤ {:.0} µs per tick: {}",
            r.case,
            r.median_us,
            r.p95_us,
            r.max_us,
            r.mean_us,
            r.goal_us,
            if r.met { "met (p95)" } else { "NOT met (p95)" }
        )?;
    }
    if cfg!(debug_assertions) {
        writeln!(
            out,
            "(a debug build: run `cargo run --release -- rco bench` for the real figures)"
        )?;
    }
    Ok(())
}
