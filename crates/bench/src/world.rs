//! `fogline bench world`: world generation and rendering on every core (clips per second,
//! the paper-size corpus projected against its goal), then the reference planner's time per
//! clip on one thread under each condition, next to its goal.

use std::collections::BTreeMap;
use std::io::Write;
use std::time::Instant;

use anyhow::Result;
use fogline_api::planner_eval::{
    PAPER_CLIPS, PLAN_GOAL_MS, Timing, WORLD_GOAL_S, condition_frames, parse_conditions,
    run_planner, timing, world_config,
};
use fogline_io::Progress;
use fogline_planner::ReferencePlanner;
use fogline_world::{Clip, generate_clip};
use rayon::prelude::*;

/// What `fogline bench world` runs.
#[derive(Debug, Clone)]
pub struct WorldBench {
    /// Clips generated (the paper's scenario mix scaled to this number).
    pub clips: usize,
    /// Clips the planner is timed on (default: `clips`).
    pub plan_clips: Option<usize>,
    /// World seed.
    pub seed: u64,
    /// Image width of every camera, pixels.
    pub width: u32,
    /// Image height of every camera, pixels.
    pub height: u32,
    /// Conditions the planner is timed under (`clean` is always timed, first).
    pub plan_conditions: Vec<String>,
    /// Seed of the perturbations' random streams.
    pub perturb_seed: u64,
    /// Print JSON instead of the report.
    pub json: bool,
}

fn fmt_ms(v: Option<f64>) -> String {
    v.map_or("-".into(), |v| format!("{v:.2}"))
}

/// Runs the benchmark, writing its report (or its JSON) to `out`.
pub fn run(a: &WorldBench, out: &mut dyn Write) -> Result<()> {
    let cfg = world_config(a.clips, a.seed, a.width, a.height)?;
    let plan_clips = a.plan_clips.unwrap_or(a.clips).min(a.clips);
    let threads = rayon::current_num_threads();
    log::info!(
        "bench world: {} clips at {}x{} (4 cameras x 4 frames, RGB + depth + boxes), {threads} threads; then the planner on {plan_clips} clips, one thread",
        a.clips,
        a.width,
        a.height
    );

    // (a) generation + rendering on every core. One clip first, untimed, to warm up.
    std::hint::black_box(generate_clip(&cfg, 0)?);
    let progress = Progress::new(a.clips, "clips");
    let t = Instant::now();
    let bytes: usize = (0..a.clips)
        .into_par_iter()
        .map(|i| {
            let clip = generate_clip(&cfg, i)?;
            progress.inc();
            Ok(std::hint::black_box(clip)
                .cameras
                .iter()
                .flat_map(|c| &c.frames)
                .map(|f| f.image.data().len())
                .sum::<usize>())
        })
        .collect::<Result<Vec<usize>, fogline_world::WorldError>>()?
        .into_iter()
        .sum();
    let world_s = t.elapsed().as_secs_f64();
    progress.finish();
    let clips_per_s = a.clips as f64 / world_s;
    let ms_per_clip = world_s * 1e3 / a.clips as f64;
    let projected_s = world_s * PAPER_CLIPS as f64 / a.clips as f64;
    log::info!(
        "generated {} clips ({:.1} MB of RGB) in {world_s:.2} s",
        a.clips,
        bytes as f64 / 1e6
    );

    // (b) the planner, one thread, under each condition: clips are generated in parallel in
    // small batches (untimed), perturbed (untimed), then planned one after the other on this
    // thread while the pool is idle.
    let conditions = parse_conditions(&a.plan_conditions, a.perturb_seed)?;
    let planner = ReferencePlanner::new();
    let mut plan_ms: Vec<Vec<f64>> = vec![Vec::with_capacity(plan_clips); conditions.len()];
    let mut failures: BTreeMap<(usize, String), usize> = BTreeMap::new();
    let batch = (2 * threads).max(1);
    let progress = Progress::new(plan_clips, "clips planned");
    let mut warmed = false;
    for start in (0..plan_clips).step_by(batch) {
        let end = (start + batch).min(plan_clips);
        let clips = (start..end)
            .into_par_iter()
            .map(|i| generate_clip(&cfg, i))
            .collect::<Result<Vec<Clip>, _>>()?;
        for (clip, i) in clips.iter().zip(start..end) {
            let key = fogline_campaign::runner::clip_key(i);
            for (c, cond) in conditions.iter().enumerate() {
                let frames = condition_frames(clip, key, cond)?;
                if !warmed {
                    std::hint::black_box(run_planner(&planner, clip, &frames));
                    warmed = true;
                }
                let rec = run_planner(&planner, clip, &frames);
                match rec.result {
                    Ok(_) => plan_ms[c].push(rec.plan_ms),
                    Err(why) => *failures.entry((c, why)).or_default() += 1,
                }
            }
            progress.inc();
        }
    }
    progress.finish();
    let names: Vec<String> = conditions
        .iter()
        .map(|p| p.perturbation().name.clone())
        .collect();
    let answered: Vec<usize> = plan_ms.iter().map(Vec::len).collect();
    let plans: Vec<Timing> = plan_ms.into_iter().map(timing).collect();

    let world_met = projected_s <= WORLD_GOAL_S;
    let met = |t: &Timing| t.median_ms.map(|m| m <= PLAN_GOAL_MS);
    if a.json {
        let v = serde_json::json!({
            "world": {
                "clips": a.clips,
                "width": a.width,
                "height": a.height,
                "cameras": fogline_types::clip::CameraId::ALL.len(),
                "frames_per_camera": fogline_types::clip::FRAMES,
                "depth": true,
                "threads": threads,
                "wall_s": world_s,
                "clips_per_s": clips_per_s,
                "ms_per_clip": ms_per_clip,
                "core_ms_per_clip": ms_per_clip * threads as f64,
                "projected_1996_clips_s": projected_s,
                "goal": format!("{PAPER_CLIPS} clips <= {WORLD_GOAL_S} s on two cores"),
                "goal_s": WORLD_GOAL_S,
                "met": world_met,
            },
            "planner": names.iter().enumerate().map(|(c, name)| serde_json::json!({
                "condition": name,
                "clips": plan_clips,
                "answered": answered[c],
                "threads": 1,
                "median_ms": plans[c].median_ms,
                "p95_ms": plans[c].p95_ms,
                "mean_ms": plans[c].mean_ms,
                "goal": format!("<= {PLAN_GOAL_MS} ms per clip, one thread"),
                "goal_ms": PLAN_GOAL_MS,
                "met": met(&plans[c]),
                "failures": failures.iter().filter(|((k, _), _)| *k == c).map(|((_, reason), clips)| serde_json::json!({
                    "reason": reason, "clips": clips,
                })).collect::<Vec<_>>(),
            })).collect::<Vec<_>>(),
        });
        writeln!(out, "{}", serde_json::to_string_pretty(&v)?)?;
        return Ok(());
    }
    writeln!(
        out,
        "fogline bench world: {} clips, {}x{}, 4 cameras x 4 frames, RGB + depth + boxes, in memory",
        a.clips, a.width, a.height
    )?;
    writeln!(
        out,
        "world    {threads} threads: {world_s:.2} s wall, {clips_per_s:.1} clips/s, {ms_per_clip:.1} ms/clip ({:.1} core-ms/clip)",
        ms_per_clip * threads as f64
    )?;
    writeln!(
        out,
        "goal     {PAPER_CLIPS} clips <= {WORLD_GOAL_S:.0} s on two cores: {projected_s:.1} s at {threads} threads{}  {}",
        if a.clips == PAPER_CLIPS {
            ""
        } else {
            " (projected)"
        },
        if world_met { "met" } else { "NOT met" }
    )?;
    for (c, name) in names.iter().enumerate() {
        let plan = &plans[c];
        writeln!(
            out,
            "planner  {name}, one thread, {} of {plan_clips} clips answered: {} ms/clip median, {} p95, {} mean; goal <= {PLAN_GOAL_MS:.0} ms/clip median: {}",
            answered[c],
            fmt_ms(plan.median_ms),
            fmt_ms(plan.p95_ms),
            fmt_ms(plan.mean_ms),
            match met(plan) {
                Some(true) => "met",
                Some(false) => "NOT met",
                None => "not measured (no clip answered)",
            }
        )?;
    }
    for ((c, reason), clips) in &failures {
        writeln!(
            out,
            "planner failed under {} on {clips} clips: {reason}",
            names[*c]
        )?;
    }
    Ok(())
}
