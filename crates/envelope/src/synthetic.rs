//! A synthetic pairs corpus with known structure, for tests, benchmarks and a first look.
//!
//! This is a statistical model of a campaign's output — not a planner: scenario shares like
//! table 1 of the envelope paper, per-scenario noise sensitivity, CoC flips that grow with
//! the perturbation level, and L2 deviations of changed pairs drawn from six bands. Every draw
//! comes from `seed`.

use fogline_stats::seed;
use rand::Rng;

use crate::input::PairTable;

/// Parameters of [`corpus`].
#[derive(Debug, Clone, PartialEq)]
pub struct SyntheticParams {
    /// Clips (each under the paper's eight conditions).
    pub n_clips: usize,
    /// Seed.
    pub seed: u64,
}

impl Default for SyntheticParams {
    fn default() -> Self {
        Self {
            n_clips: 1996,
            seed: 0,
        }
    }
}

/// Scenario, share of clips, clean ADE (m), noise sensitivity (ΔADE fraction per unit σ/70).
const SCENARIOS: [(&str, f64, f64, f64); 8] = [
    ("LANE_KEEPING", 213.0, 1.31, 0.19),
    ("NUDGE_RIGHT", 7.0, 1.94, 0.45),
    ("FOLLOW_VEHICLE", 475.0, 1.75, 0.18),
    ("PASSING", 177.0, 1.54, 0.08),
    ("TURN_RIGHT", 40.0, 3.11, 0.05),
    ("STOP_SIGNAL", 302.0, 2.47, 0.10),
    ("INTERSECTION", 344.0, 2.12, 0.11),
    ("OTHER", 438.0, 1.90, 0.15),
];

/// The paper's eight perturbed conditions with a severity in [0, 1].
const CONDITIONS: [(&str, f64); 8] = [
    ("noise_10", 0.10),
    ("noise_30", 0.35),
    ("noise_50", 0.65),
    ("noise_70", 0.95),
    ("dark", 0.55),
    ("bright", 0.45),
    ("fog_03", 0.40),
    ("fog_07", 0.80),
];

const BANDS: [(f64, f64, f64); 6] = [
    (5.3, 1.6, 0.35),
    (16.0, 3.0, 0.31),
    (29.4, 4.5, 0.17),
    (47.2, 6.5, 0.11),
    (76.0, 9.0, 0.04),
    (124.2, 14.0, 0.02),
];

const PHRASES: [&str; 10] = [
    "Keep lane and maintain speed on the clear road.",
    "Slow down because the lead vehicle is braking ahead.",
    "Follow the lead vehicle at a safe distance.",
    "Nudge left to increase clearance from the parked vehicle on the right.",
    "Pass the slower vehicle on the left.",
    "Turn right at the junction after yielding to pedestrians.",
    "Stop because the stop sign requires a full stop.",
    "Stop for the red light at the intersection.",
    "Proceed through the intersection as the light is green.",
    "Continue straight and keep the lane.",
];

fn normal(rng: &mut impl Rng) -> f64 {
    // Box–Muller; the second variate is discarded to keep draws aligned per use.
    let u1: f64 = rng.random::<f64>().max(f64::MIN_POSITIVE);
    let u2: f64 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// One generated row (borrowed texts).
#[derive(Debug, Clone, Copy)]
pub struct SyntheticRow<'a> {
    /// Clip number.
    pub clip: usize,
    /// Scenario label.
    pub scenario: &'static str,
    /// Condition name.
    pub condition: &'static str,
    /// Clean ADE (m).
    pub ade_clean: f64,
    /// Perturbed ADE (m).
    pub ade_attacked: f64,
    /// L2 deviation (m).
    pub l2: f64,
    /// Clean CoC.
    pub coc_clean: &'static str,
    /// Perturbed CoC.
    pub coc_attacked: &'a str,
}

/// Calls `f` for every row of the corpus, clip by clip, in the paper's condition order.
pub fn for_each_row(p: &SyntheticParams, mut f: impl FnMut(SyntheticRow<'_>)) {
    let total: f64 = SCENARIOS.iter().map(|s| s.1).sum();
    let mut rewrite = String::new();
    for k in 0..p.n_clips {
        let mut rng = seed::rng(p.seed, &[0x5EED, k as u64]);
        // Scenario by share (deterministic cycling keeps small corpora balanced).
        let pos = ((k as f64 + 0.5) / p.n_clips as f64) * total;
        let mut acc = 0.0;
        let mut s = SCENARIOS.len() - 1;
        for (i, sc) in SCENARIOS.iter().enumerate() {
            acc += sc.1;
            if pos < acc {
                s = i;
                break;
            }
        }
        let (scenario, _, clean_mean, sens) = SCENARIOS[s];
        let clean = clean_mean * (0.35 * normal(&mut rng)).exp();
        let fragility = (0.8 * normal(&mut rng)).exp();
        let base_phrase = (s + rng.random_range(0..3)) % PHRASES.len();
        let tilt = if scenario == "STOP_SIGNAL" || scenario == "INTERSECTION" {
            1.8
        } else {
            1.0
        };
        for &(condition, sev) in CONDITIONS.iter() {
            let p_flip = (0.08 + 0.5 * sev * fragility).min(0.95);
            let flipped = rng.random::<f64>() < p_flip;
            let noise = 0.05 * normal(&mut rng);
            let damage = sens * sev * sev * fragility * (1.0 + 0.5 * normal(&mut rng)).max(0.0);
            let attacked = clean * (1.0 + damage + noise).max(0.05);
            let coc_clean = PHRASES[base_phrase];
            let (l2, coc_attacked) = if flipped {
                let u: f64 = rng.random();
                let wsum: f64 = BANDS
                    .iter()
                    .enumerate()
                    .map(|(i, b)| if i >= 4 { b.2 * tilt } else { b.2 })
                    .sum();
                let mut cum = 0.0;
                let mut band = BANDS.len() - 1;
                for (i, b) in BANDS.iter().enumerate() {
                    cum += if i >= 4 { b.2 * tilt } else { b.2 } / wsum;
                    if u < cum {
                        band = i;
                        break;
                    }
                }
                let l2 = (BANDS[band].0 + BANDS[band].1 * normal(&mut rng)).max(0.1);
                let alt =
                    (base_phrase + 1 + rng.random_range(0..PHRASES.len() - 1)) % PHRASES.len();
                rewrite.clear();
                if rng.random::<f64>() < 0.6 {
                    // A surface rewrite of the same decision.
                    rewrite.push_str(PHRASES[base_phrase].trim_end_matches('.'));
                    rewrite.push_str(" now.");
                } else {
                    rewrite.push_str(PHRASES[alt]);
                }
                (l2, rewrite.as_str())
            } else {
                ((4.1 * (0.6 * normal(&mut rng)).exp()).max(0.01), coc_clean)
            };
            f(SyntheticRow {
                clip: k,
                scenario,
                condition,
                ade_clean: clean,
                ade_attacked: attacked,
                l2,
                coc_clean,
                coc_attacked,
            });
        }
    }
}

/// Generates a synthetic pairs table (through the same validating builder as the readers).
pub fn corpus(p: &SyntheticParams) -> PairTable {
    let name = format!("synthetic(n_clips={}, seed={})", p.n_clips, p.seed);
    let opts = crate::input::ReadOptions::default();
    let mut rows = Vec::with_capacity(p.n_clips * CONDITIONS.len());
    for_each_row(p, |r| {
        rows.push((
            format!("clip_{:06}", r.clip),
            r.scenario,
            r.condition,
            r.ade_clean,
            r.ade_attacked,
            r.l2,
            r.coc_clean,
            r.coc_attacked.to_string(),
        ))
    });
    crate::input::table_from_rows(
        &name,
        &opts,
        rows.iter().map(|r| crate::input::RowRef {
            clip_id: &r.0,
            scenario: r.1,
            condition: r.2,
            ade_clean: r.3,
            ade_attacked: r.4,
            l2: r.5,
            coc_clean: r.6,
            coc_attacked: &r.7,
        }),
    )
    .expect("the synthetic corpus is valid by construction")
}

/// Streams the corpus as CSV (header + rows) into `w`.
pub fn write_csv(p: &SyntheticParams, w: &mut impl std::io::Write) -> std::io::Result<()> {
    writeln!(
        w,
        "clip_id,scenario,attack,ade_clean,ade_attacked,l2,coc_clean,coc_attacked"
    )?;
    let mut err = Ok(());
    for_each_row(p, |r| {
        if err.is_ok() {
            err = writeln!(
                w,
                "clip_{:06},{},{},{:.6},{:.6},{:.6},\"{}\",\"{}\"",
                r.clip,
                r.scenario,
                r.condition,
                r.ade_clean,
                r.ade_attacked,
                r.l2,
                r.coc_clean,
                r.coc_attacked
            );
        }
    });
    err
}
