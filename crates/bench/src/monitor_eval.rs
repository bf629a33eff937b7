//! `fogline bench monitor-eval`: the runtime ODD monitor ([`fogline_monitor::Monitor`]) on
//! the demo corpus against the decision the true condition gives (issue 20).
//!
//! The corpus is `fogline demo`'s: `clips` world clips in the paper's scenario mix at the
//! campaign's size (world seed `world_seed`, 576×320). Each clip gets its own noise level σ
//! drawn uniformly from `[0, max_sigma)` (the SplitMix64 word `stats::seed::child(seed,
//! [0x5157, clip])`, its top 53 bits as a fraction), not only the envelope's grid levels.
//! The monitored camera's four frames get fogline's `noise_<σ>` (σ to three decimals,
//! perturbation seed `seed`, the campaign's per-frame keys) and the monitor steps over them
//! in order, as `fogline monitor run` does on a clip (`Monitor::step_frame`). Its decision
//! after the last frame is compared with the one the true condition gives against the same
//! `odd.json` entry: out when σ is beyond the noise limit (σ*, or 0 when σ* is none); the
//! frames have no other perturbation, so the true gain 1 and fog 0 are inside on every
//! other axis.
//!
//! Two monitors run on every clip: one watching the noise axis alone (the measurement the
//! issue asks for) and the default one watching every axis the entry has a threshold for
//! (noise, darken, brighten, fog), whose estimation errors on the other axes can also take
//! it out. Per scenario the report counts the clips whose σ is more than `band` from the
//! limit (goal: ≥ 95 % agreement) and, apart, those within ±`band`. Clips whose scenario has
//! no entry (`OTHER`) are counted as skipped.

use std::collections::BTreeMap;
use std::io::Write;
use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use fogline_monitor::{Monitor, MonitorParams};
use fogline_perturb::{FrameInput, FrameKey, Perturbation};
use fogline_types::clip::CameraId;
use fogline_types::odd::OddSpec;
use rayon::prelude::*;
use serde::Serialize;

/// The agreement goal on clips farther than the band from the threshold.
pub const AGREEMENT_GOAL: f64 = 0.95;

/// What `fogline bench monitor-eval` runs.
#[derive(Debug, Clone, clap::Args)]
pub struct MonitorEval {
    /// The envelope's odd.json (e.g. `fogline demo`'s).
    #[arg(long)]
    pub odd: PathBuf,
    /// Clips of the corpus (`fogline demo`'s default: 300).
    #[arg(long, default_value_t = 300)]
    pub clips: usize,
    /// World seed of the corpus (`fogline demo --seed`).
    #[arg(long, default_value_t = 0)]
    pub world_seed: u64,
    /// Seed of the σ draws and of the noise.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Frame width, px (the demo campaign's).
    #[arg(long, default_value_t = 576)]
    pub width: u32,
    /// Frame height, px.
    #[arg(long, default_value_t = 320)]
    pub height: u32,
    /// σ is drawn uniformly from [0, max_sigma).
    #[arg(long, default_value_t = 80.0)]
    pub max_sigma: f64,
    /// Half-width of the band around the threshold reported apart, σ levels.
    #[arg(long, default_value_t = 5.0)]
    pub band: f64,
    /// The camera monitored.
    #[arg(long, default_value = "front_wide", value_parser = parse_camera)]
    pub camera: CameraId,
    /// The monitor's minimum dwell, steps (default: the monitor's).
    #[arg(long)]
    pub min_dwell_steps: Option<usize>,
    /// Print JSON (every clip) instead of the tables.
    #[arg(long)]
    pub json: bool,
}

fn parse_camera(s: &str) -> Result<CameraId, String> {
    CameraId::parse(s)
        .ok_or_else(|| format!("{s:?}: expected cross_left, front_wide, cross_right or front_tele"))
}

/// One clip of the evaluation.
#[derive(Debug, Clone, Serialize)]
pub struct ClipResult {
    /// Clip index in the corpus.
    pub clip: usize,
    /// Its scenario.
    pub scenario: String,
    /// The noise added (σ, 0–255 scale).
    pub sigma: f64,
    /// The noise limit of the scenario's entry (None: no entry, the clip is skipped).
    pub limit: Option<f64>,
    /// The monitor's smoothed σ̂ after the last frame.
    pub sigma_hat: Option<f64>,
    /// In the envelope by the true σ.
    pub truth_in: Option<bool>,
    /// The noise-axis monitor's decision after the last frame.
    pub noise_monitor_in: Option<bool>,
    /// The all-axes monitor's decision after the last frame.
    pub full_monitor_in: Option<bool>,
    /// Why the all-axes monitor decided as it did (its last record's reason).
    pub full_reason: Option<String>,
}

/// Agreement counts of one scenario and one monitor.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Agreement {
    /// Clips farther than the band from the limit.
    pub far: usize,
    /// Of those, decisions equal to the true one.
    pub far_agree: usize,
    /// Clips within ±band of the limit.
    pub band: usize,
    /// Of those, decisions equal to the true one.
    pub band_agree: usize,
}

impl Agreement {
    fn add(&mut self, far: bool, agree: bool) {
        if far {
            self.far += 1;
            self.far_agree += usize::from(agree);
        } else {
            self.band += 1;
            self.band_agree += usize::from(agree);
        }
    }

    /// Share of far clips that agree (None without far clips).
    pub fn far_share(&self) -> Option<f64> {
        (self.far > 0).then(|| self.far_agree as f64 / self.far as f64)
    }

    /// Share of band clips that agree (None without band clips).
    pub fn band_share(&self) -> Option<f64> {
        (self.band > 0).then(|| self.band_agree as f64 / self.band as f64)
    }
}

/// One scenario's row.
#[derive(Debug, Clone, Serialize)]
pub struct ScenarioRow {
    /// Scenario (or `ALL` for the total).
    pub scenario: String,
    /// Clips evaluated.
    pub clips: usize,
    /// The noise limit (σ*, or 0 when σ* is none); None for the total.
    pub limit: Option<f64>,
    /// σ* is right-censored.
    pub right_censored: bool,
    /// Mean |σ̂ − σ| of the smoothed estimate after the last frame.
    pub mae: f64,
    /// The noise-axis monitor.
    pub noise: Agreement,
    /// The all-axes monitor.
    pub full: Agreement,
}

/// The evaluation's result.
#[derive(Debug, Clone, Serialize)]
pub struct EvalReport {
    /// The odd.json read.
    pub odd: String,
    /// Its producer and input hash.
    pub odd_generated_by: String,
    /// SHA-256 of the pairs table behind it.
    pub odd_input_sha256: String,
    /// The monitor's parameters (the all-axes monitor; the noise one watches that axis only).
    pub params: MonitorParams,
    /// Per scenario (the entries' order), then `ALL`.
    pub rows: Vec<ScenarioRow>,
    /// Clips without an entry, by scenario.
    pub skipped: BTreeMap<String, usize>,
    /// Every clip.
    pub clips: Vec<ClipResult>,
    /// Seconds the evaluation took.
    pub seconds: f64,
}

/// σ of clip `clip`: uniform on [0, max) from the seed (three decimals).
pub fn draw_sigma(seed: u64, clip: usize, max: f64) -> f64 {
    let word = fogline_stats::seed::child(seed, &[0x5157, clip as u64]);
    let u = (word >> 11) as f64 / (1u64 << 53) as f64;
    (u * max * 1000.0).floor() / 1000.0
}

/// Runs the evaluation.
pub fn evaluate(a: &MonitorEval) -> Result<EvalReport> {
    if !(a.max_sigma.is_finite() && a.max_sigma > 0.0 && a.max_sigma <= 255.0) {
        bail!("--max-sigma must be in (0, 255]");
    }
    if !(a.band.is_finite() && a.band >= 0.0) {
        bail!("--band must be a non-negative number");
    }
    let start = std::time::Instant::now();
    let odd = OddSpec::read(&a.odd).map_err(anyhow::Error::msg)?;
    let d = MonitorParams::default();
    let full_params = MonitorParams {
        min_dwell_steps: a.min_dwell_steps.unwrap_or(d.min_dwell_steps),
        ..d
    };
    full_params
        .validate()
        .context("invalid monitor parameters")?;
    let noise_params = MonitorParams {
        axes: vec!["gaussian_noise".into()],
        ..full_params.clone()
    };
    let cfg = fogline_api::planner_eval::world_config(a.clips, a.world_seed, a.width, a.height)?;
    let cam = a.camera;
    log::info!(
        "monitor eval: {} clips (world seed {}) at {}x{}, σ ~ U[0, {}) seed {}, camera {}",
        a.clips,
        a.world_seed,
        a.width,
        a.height,
        a.max_sigma,
        a.seed,
        cam.short()
    );
    let progress = fogline_io::Progress::new(a.clips, "clips");
    let clips: Vec<ClipResult> = (0..a.clips)
        .into_par_iter()
        .map(|i| -> Result<ClipResult> {
            let clip = fogline_world::generate_clip_cameras(&cfg, i, &[cam])?;
            let sigma = draw_sigma(a.seed, i, a.max_sigma);
            let mut r = ClipResult {
                clip: i,
                scenario: clip.scenario.clone(),
                sigma,
                limit: None,
                sigma_hat: None,
                truth_in: None,
                noise_monitor_in: None,
                full_monitor_in: None,
                full_reason: None,
            };
            let Some(entry) = odd.entry(&clip.scenario) else {
                progress.inc();
                return Ok(r);
            };
            let Some(noise) = entry.threshold("gaussian_noise") else {
                bail!(
                    "{}: entry {} has no gaussian_noise threshold",
                    a.odd.display(),
                    clip.scenario
                );
            };
            r.limit = Some(noise.limit());
            r.truth_in = Some(noise.inside(sigma));
            let p = Perturbation::parse(&format!("noise_{sigma:.3}"))?.prepare(a.seed)?;
            let mut mn = Monitor::new(&odd, &clip.scenario, noise_params.clone())?;
            let mut mf = Monitor::new(&odd, &clip.scenario, full_params.clone())?;
            let camera = clip
                .cameras
                .first()
                .context("the clip was rendered without its camera")?;
            for (k, f) in camera.frames.iter().enumerate() {
                let key = FrameKey::new(i as u64, cam.index() as u64, k as u64);
                let noisy = p.apply(&FrameInput::new(&f.image, key))?.frame;
                let (w, h) = (noisy.width() as usize, noisy.height() as usize);
                let rn = mn.step_frame(noisy.data(), w, h)?;
                let rf = mf.step_frame(noisy.data(), w, h)?;
                r.sigma_hat = rn.axes.first().map(|x| x.smoothed);
                r.noise_monitor_in = Some(rn.in_envelope);
                r.full_monitor_in = Some(rf.in_envelope);
                r.full_reason = Some(rf.reason);
            }
            progress.inc();
            Ok(r)
        })
        .collect::<Result<Vec<_>>>()?;
    progress.finish();

    let mut rows = Vec::new();
    let mut skipped = BTreeMap::new();
    let mut total = ScenarioRow {
        scenario: "ALL".into(),
        clips: 0,
        limit: None,
        right_censored: false,
        mae: 0.0,
        noise: Agreement::default(),
        full: Agreement::default(),
    };
    let mut total_err = 0.0;
    for e in &odd.entries {
        let mine: Vec<&ClipResult> = clips.iter().filter(|c| c.scenario == e.scenario).collect();
        let Some(noise) = e.threshold("gaussian_noise") else {
            continue;
        };
        let mut row = ScenarioRow {
            scenario: e.scenario.clone(),
            clips: mine.len(),
            limit: Some(noise.limit()),
            right_censored: noise.right_censored,
            mae: 0.0,
            noise: Agreement::default(),
            full: Agreement::default(),
        };
        let mut err = 0.0;
        for c in &mine {
            let (Some(limit), Some(truth)) = (c.limit, c.truth_in) else {
                continue;
            };
            let far = (c.sigma - limit).abs() > a.band;
            let agree_n = c.noise_monitor_in == Some(truth);
            let agree_f = c.full_monitor_in == Some(truth);
            row.noise.add(far, agree_n);
            row.full.add(far, agree_f);
            total.noise.add(far, agree_n);
            total.full.add(far, agree_f);
            err += (c.sigma_hat.unwrap_or(f64::NAN) - c.sigma).abs();
        }
        total_err += err;
        total.clips += mine.len();
        row.mae = if mine.is_empty() {
            0.0
        } else {
            err / mine.len() as f64
        };
        rows.push(row);
    }
    total.mae = if total.clips > 0 {
        total_err / total.clips as f64
    } else {
        0.0
    };
    rows.push(total);
    for c in clips.iter().filter(|c| c.limit.is_none()) {
        *skipped.entry(c.scenario.clone()).or_insert(0) += 1;
    }
    Ok(EvalReport {
        odd: a.odd.display().to_string(),
        odd_generated_by: odd.generated_by.clone(),
        odd_input_sha256: odd.input_sha256.clone(),
        params: full_params,
        rows,
        skipped,
        clips,
        seconds: start.elapsed().as_secs_f64(),
    })
}

fn pct(s: Option<f64>) -> String {
    s.map_or_else(|| "-".into(), |v| format!("{:.1}%", 100.0 * v))
}

fn goal(s: Option<f64>) -> &'static str {
    match s {
        None => "-",
        Some(v) if v >= AGREEMENT_GOAL => "met",
        Some(_) => "NOT met",
    }
}

/// Writes the tables.
pub fn write_report(a: &MonitorEval, r: &EvalReport, out: &mut dyn Write) -> Result<()> {
    writeln!(
        out,
        "fogline bench monitor-eval: {} clips (world seed {}, {}x{}, camera {}), sigma ~ U[0, {}) per clip (seed {}), 4 frames each",
        a.clips,
        a.world_seed,
        a.width,
        a.height,
        a.camera.short(),
        a.max_sigma,
        a.seed
    )?;
    writeln!(
        out,
        "odd.json: {} ({}, pairs sha256 {}…); monitor: ewma_alpha {}, z {}, min_dwell_steps {}, noise margin {}",
        r.odd,
        r.odd_generated_by,
        r.odd_input_sha256.get(..12).unwrap_or(&r.odd_input_sha256),
        r.params.ewma_alpha,
        r.params.z,
        r.params.min_dwell_steps,
        r.params.noise_margin
    )?;
    writeln!(
        out,
        "truth: out when sigma > limit (sigma*, or 0 when sigma* is none); far = |sigma - limit| > {}, band = within +-{}\n",
        a.band, a.band
    )?;
    for (title, pick) in [
        (
            "noise-axis monitor (watches gaussian_noise)",
            (|row: &ScenarioRow| row.noise.clone()) as fn(&ScenarioRow) -> Agreement,
        ),
        (
            "all-axes monitor (gaussian_noise, darken, brighten, fog; the default)",
            |row: &ScenarioRow| row.full.clone(),
        ),
    ] {
        writeln!(out, "{title}")?;
        writeln!(
            out,
            "{:<16} {:>5} {:>7} {:>6}  {:>9} {:>8}  {:>9} {:>8}  goal >= 95% far",
            "scenario", "clips", "limit", "MAE", "far", "agree", "band", "agree"
        )?;
        for row in &r.rows {
            let g = pick(row);
            let limit = row.limit.map_or_else(
                || "-".to_string(),
                |l| format!("{l:.0}{}", if row.right_censored { "+" } else { "" }),
            );
            writeln!(
                out,
                "{:<16} {:>5} {:>7} {:>6.2}  {:>4}/{:<4} {:>8}  {:>4}/{:<4} {:>8}  {}",
                row.scenario,
                row.clips,
                limit,
                row.mae,
                g.far_agree,
                g.far,
                pct(g.far_share()),
                g.band_agree,
                g.band,
                pct(g.band_share()),
                goal(g.far_share())
            )?;
        }
        writeln!(out)?;
    }
    if !r.skipped.is_empty() {
        let s: Vec<String> = r.skipped.iter().map(|(k, v)| format!("{k} {v}")).collect();
        writeln!(out, "skipped (no odd.json entry): {}", s.join(", "))?;
    }
    let wrong: Vec<&ClipResult> = r
        .clips
        .iter()
        .filter(|c| match (c.limit, c.truth_in) {
            (Some(l), Some(t)) => {
                (c.sigma - l).abs() > a.band
                    && (c.noise_monitor_in != Some(t) || c.full_monitor_in != Some(t))
            }
            _ => false,
        })
        .collect();
    writeln!(
        out,
        "far clips where a monitor disagrees with the truth: {}",
        wrong.len()
    )?;
    for c in wrong.iter().take(12) {
        writeln!(
            out,
            "  clip {:>4} {:<15} sigma {:>6.2} sigma_hat {:>6.2} limit {:>3} truth {} noise-monitor {} all-axes {} ({})",
            c.clip,
            c.scenario,
            c.sigma,
            c.sigma_hat.unwrap_or(f64::NAN),
            c.limit.unwrap_or(f64::NAN),
            io(c.truth_in),
            io(c.noise_monitor_in),
            io(c.full_monitor_in),
            c.full_reason.as_deref().unwrap_or("-")
        )?;
    }
    writeln!(out, "\n{:.1} s", r.seconds)?;
    Ok(())
}

fn io(v: Option<bool>) -> &'static str {
    match v {
        Some(true) => "in",
        Some(false) => "out",
        None => "-",
    }
}

/// Runs the evaluation and writes its tables (or JSON with `json`) to `out`.
pub fn run(a: &MonitorEval, out: &mut dyn Write) -> Result<()> {
    let r = evaluate(a)?;
    if a.json {
        writeln!(out, "{}", serde_json::to_string_pretty(&r)?)?;
    } else {
        write_report(a, &r, out)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sigma_draws_are_uniform_and_seeded() {
        let v: Vec<f64> = (0..4000).map(|i| draw_sigma(0, i, 80.0)).collect();
        assert!(v.iter().all(|s| (0.0..80.0).contains(s)));
        let mean = v.iter().sum::<f64>() / v.len() as f64;
        assert!((mean - 40.0).abs() < 1.5, "{mean}");
        // Each 10-wide bin holds about an eighth.
        for b in 0..8 {
            let n = v
                .iter()
                .filter(|s| (b as f64 * 10.0..(b + 1) as f64 * 10.0).contains(*s))
                .count();
            assert!((400..600).contains(&n), "bin {b}: {n}");
        }
        assert_eq!(draw_sigma(3, 7, 80.0), draw_sigma(3, 7, 80.0));
        assert_ne!(draw_sigma(3, 7, 80.0), draw_sigma(4, 7, 80.0));
    }
}
