//! Dose-response curves, thresholds σ*(s) and the clip-level bootstrap.
//!
//! Per group (a classified scenario, or an aggregate) and axis, the mean clean and perturbed
//! ADE at each level are taken over the group's pairs at that level (paired: the clean mean is
//! over the same pairs). A level *passes* budget b when mean ADE_attacked < (1+b)·mean
//! ADE_clean. The bootstrap resamples clips with replacement *within each scenario label*
//! (every clip carries all its conditions along); the aggregates of a resample are the sums of
//! its scenario strata, i.e. a stratified bootstrap. Resample `r` of stratum `s` draws from
//! `seed::rng(seed, [BOOT, s, r / CHUNK])`, so results do not depend on the thread count.

use fogline_stats::seed;
use fogline_types::Family;
use rand::Rng;
use rayon::prelude::*;

use crate::input::PairTable;
use crate::model::Axis;
use crate::params::ThresholdRule;

/// Stream tag of the multinomial bootstrap.
const BOOT: u64 = 0xB007;
/// Stream tag of the Poisson bootstrap.
const BOOT_POISSON: u64 = 0xB0B0;

/// How a resample weights the clips of a stratum.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Resampling {
    /// n draws with replacement (the classic bootstrap).
    Multinomial,
    /// Independent Poisson(1) weights per clip (the Poisson bootstrap).
    Poisson,
}

/// P(X ≤ i) for X ~ Poisson(1), scaled to 2³² and rounded, i = 0..12. X > 11 has probability
/// below 2⁻³², so a uniform 32-bit word `u` maps to X = #{i : u ≥ T[i]} ∈ 0..=12.
fn poisson1_thresholds() -> &'static [u32; 12] {
    static T: std::sync::OnceLock<[u32; 12]> = std::sync::OnceLock::new();
    T.get_or_init(|| {
        let mut t = [0u32; 12];
        let mut term = (-1.0f64).exp();
        let mut cdf = 0.0;
        for (i, slot) in t.iter_mut().enumerate() {
            if i > 0 {
                term /= i as f64;
            }
            cdf += term;
            *slot = (cdf * 4_294_967_296.0).round().min(f64::from(u32::MAX)) as u32;
        }
        t
    })
}

/// A Poisson(1) draw by inversion of a uniform 32-bit word.
#[inline]
fn poisson1_slow(u: u32) -> u8 {
    poisson1_thresholds()
        .iter()
        .map(|&x| u8::from(u >= x))
        .sum()
}

/// The draw of every 32-bit word whose top 16 bits are the index, or 0xFF where the 2¹⁶
/// words of that index straddle a threshold (then [`poisson1_slow`] decides). Exact.
fn poisson1_lut() -> &'static [u8] {
    static L: std::sync::OnceLock<Vec<u8>> = std::sync::OnceLock::new();
    L.get_or_init(|| {
        (0u32..1 << 16)
            .map(|h| {
                let lo = poisson1_slow(h << 16);
                let hi = poisson1_slow((h << 16) | 0xFFFF);
                if lo == hi { lo } else { 0xFF }
            })
            .collect()
    })
}

/// A Poisson(1) draw by inversion of a uniform 32-bit word (table first, exact).
#[cfg(test)]
#[inline]
fn poisson1(u: u32) -> f64 {
    let c = poisson1_lut()[(u >> 16) as usize];
    f64::from(if c == 0xFF { poisson1_slow(u) } else { c })
}

/// Fills `w` with Poisson(1) weights from `rng` (two per 64-bit word).
#[inline]
fn poisson1_fill(rng: &mut seed::Xoshiro256pp, raw: &mut [u32], w: &mut [f64]) {
    for pair in raw.chunks_mut(2) {
        let u = rng.next_u64();
        pair[0] = u as u32;
        if let Some(x) = pair.get_mut(1) {
            *x = (u >> 32) as u32;
        }
    }
    let lut = poisson1_lut();
    for (wi, &u) in w.iter_mut().zip(raw.iter()) {
        let c = lut[(u >> 16) as usize];
        *wi = f64::from(if c == 0xFF { poisson1_slow(u) } else { c });
    }
}

/// Resamples per work item.
pub(crate) const CHUNK: usize = 64;

/// Builds the ordered axes: one per family, brightness split into darken (< 1, descending
/// gain) and brighten (> 1, ascending gain); other families ascending level. Conditions at
/// the family's identity level are left out (they are not perturbations).
pub(crate) fn build_axes(t: &PairTable) -> (Vec<Axis>, Vec<Option<(usize, usize)>>) {
    let mut axes: Vec<Axis> = Vec::new();
    let mut slot_of_cond = vec![None; t.conditions.len()];
    let mut keyed: Vec<(String, String, f64, usize)> = Vec::new();
    for (ci, c) in t.conditions.iter().enumerate() {
        let id = c.family.identity_level();
        let (axis, key) = match &c.family {
            Family::Brightness if c.level < id => ("darken".to_string(), id - c.level),
            Family::Brightness if c.level > id => ("brighten".to_string(), c.level - id),
            Family::Brightness => continue,
            f => {
                if c.level == id {
                    continue;
                }
                (f.name().to_string(), c.level)
            }
        };
        keyed.push((axis, c.family.name().to_string(), key, ci));
    }
    keyed.sort_by(|a, b| a.0.cmp(&b.0).then(a.2.total_cmp(&b.2)));
    for (axis, family, key, ci) in keyed {
        let level = t.conditions[ci].level;
        let ai = match axes.iter().position(|a| a.axis == axis) {
            Some(i) => i,
            None => {
                axes.push(Axis {
                    axis: axis.clone(),
                    family,
                    levels: Vec::new(),
                    conditions: Vec::new(),
                });
                axes.len() - 1
            }
        };
        let a = &mut axes[ai];
        let li = match a.levels.iter().position(|&l| l == level) {
            Some(i) => i,
            None => {
                a.levels.push(level);
                a.conditions.push(Vec::new());
                a.levels.len() - 1
            }
        };
        a.conditions[li].push(t.conditions[ci].name.clone());
        let _ = key;
        slot_of_cond[ci] = Some((ai, li));
    }
    // Gaussian noise first (the paper's headline axis), then alphabetical.
    let mut order: Vec<usize> = (0..axes.len()).collect();
    order.sort_by_key(|&i| (axes[i].axis != "gaussian_noise", axes[i].axis.clone()));
    let remap: Vec<usize> = {
        let mut r = vec![0; axes.len()];
        for (new, &old) in order.iter().enumerate() {
            r[old] = new;
        }
        r
    };
    let axes_sorted: Vec<Axis> = order.iter().map(|&i| axes[i].clone()).collect();
    let slots = slot_of_cond
        .into_iter()
        .map(|s| s.map(|(a, l)| (remap[a], l)))
        .collect();
    (axes_sorted, slots)
}

/// Per-clip sums over the flattened (axis, level) slots.
pub(crate) struct ClipSlots {
    /// Number of slots.
    pub n_slots: usize,
    /// First slot of each axis.
    pub axis_offset: Vec<usize>,
    /// Per clip: [clean sums (n_slots), attacked sums (n_slots), counts (n_slots)].
    pub values: Vec<f64>,
    /// Every clip has exactly one pair in every slot.
    pub uniform: bool,
    /// `uniform`, and every clip's clean ADE is the same in every slot (one clean run per
    /// clip): the bootstrap then sums it once per draw, which gives bit-identical sums.
    pub uniform_clean: bool,
}

impl ClipSlots {
    pub(crate) fn build(
        t: &PairTable,
        axes: &[Axis],
        slot_of_cond: &[Option<(usize, usize)>],
    ) -> Self {
        let mut axis_offset = Vec::with_capacity(axes.len());
        let mut n_slots = 0;
        for a in axes {
            axis_offset.push(n_slots);
            n_slots += a.levels.len();
        }
        let stride = 3 * n_slots;
        let mut values = vec![0.0; t.clip_ids.len() * stride];
        for row in 0..t.len() {
            if let Some((a, l)) = slot_of_cond[t.condition[row] as usize] {
                let s = axis_offset[a] + l;
                let base = t.clip[row] as usize * stride;
                values[base + s] += t.ade_clean_m[row];
                values[base + n_slots + s] += t.ade_attacked_m[row];
                values[base + 2 * n_slots + s] += 1.0;
            }
        }
        let uniform = values
            .chunks(stride.max(1))
            .all(|c| c[2 * n_slots..].iter().all(|&v| v == 1.0));
        let uniform_clean = uniform
            && n_slots > 0
            && values
                .chunks(stride)
                .all(|c| c[..n_slots].iter().all(|&v| v == c[0]));
        Self {
            n_slots,
            axis_offset,
            values,
            uniform,
            uniform_clean,
        }
    }

    pub(crate) fn stride(&self) -> usize {
        3 * self.n_slots
    }

    pub(crate) fn clip(&self, k: usize) -> &[f64] {
        &self.values[k * self.stride()..(k + 1) * self.stride()]
    }
}

/// The threshold outcome: index of the threshold level, or None ("none").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Outcome {
    pub level: Option<usize>,
    pub censored: bool,
}

impl Outcome {
    /// Ordinal rank: none = 0, level i = i + 1.
    pub(crate) fn rank(self) -> usize {
        self.level.map_or(0, |l| l + 1)
    }
}

/// Reads the threshold off per-level means. Levels without pairs (count 0) are skipped.
pub(crate) fn threshold(
    clean: &[f64],
    attacked: &[f64],
    count: &[f64],
    budget: f64,
    rule: ThresholdRule,
) -> Outcome {
    let passes = |i: usize| attacked[i] < (1.0 + budget) * clean[i];
    let present = (0..clean.len()).filter(|&i| count[i] > 0.0);
    match rule {
        ThresholdRule::FirstViolation => {
            let mut last_ok = None;
            for i in present {
                if !passes(i) {
                    return Outcome {
                        level: last_ok,
                        censored: false,
                    };
                }
                last_ok = Some(i);
            }
            Outcome {
                level: last_ok,
                censored: last_ok.is_some(),
            }
        }
        ThresholdRule::MaxPassing => {
            let last = present.clone().next_back();
            let best = {
                let mut p = present;
                p.rfind(|&i| passes(i))
            };

            Outcome {
                level: best,
                censored: best.is_some() && best == last,
            }
        }
    }
}

/// Group definitions over strata (scenario labels).
pub(crate) struct Groups {
    /// Group names.
    pub names: Vec<String>,
    /// Strata of each group.
    pub strata: Vec<Vec<usize>>,
}

/// Bootstrap results per group.
pub(crate) struct BootResult {
    /// [group][axis][budget][rank] counts of resamples.
    pub counts: Vec<Vec<Vec<Vec<usize>>>>,
    /// [group][slot] → sorted ΔADE over resamples.
    pub delta: Vec<Vec<Vec<f64>>>,
    /// Resamples drawn.
    pub n: usize,
}

/// Runs the stratified clip-level bootstrap.
#[allow(clippy::too_many_arguments)]
pub(crate) fn bootstrap(
    slots: &ClipSlots,
    axes: &[Axis],
    strata_clips: &[Vec<usize>],
    groups: &Groups,
    budgets: &[f64],
    rule: ThresholdRule,
    n_resamples: usize,
    seed_value: u64,
    method: Resampling,
) -> BootResult {
    let ns = slots.n_slots;
    let stride = slots.stride();
    let n_chunks = n_resamples.div_ceil(CHUNK);
    let n_groups = groups.names.len();
    let n_rank: Vec<usize> = axes.iter().map(|a| a.levels.len() + 1).collect();

    struct ChunkOut {
        counts: Vec<Vec<Vec<Vec<usize>>>>,
        delta: Vec<Vec<Vec<f64>>>,
    }

    // Each stratum's clips packed contiguously, each row holding only what a draw adds:
    // [clean, attacked × ns] when the clean ADE is one value per clip, [clean × ns,
    // attacked × ns] when counts are all 1, else [clean, attacked, counts] × ns. The sums are
    // the same additions in the same order whichever layout is used.
    let width = if slots.uniform_clean {
        ns + 1
    } else if slots.uniform {
        2 * ns
    } else {
        stride
    };
    let packed: Vec<Vec<f64>> = strata_clips
        .iter()
        .map(|clips| {
            let mut v = Vec::with_capacity(clips.len() * width);
            for &k in clips {
                let c = slots.clip(k);
                if slots.uniform_clean {
                    v.push(c[0]);
                    v.extend_from_slice(&c[ns..2 * ns]);
                } else {
                    v.extend_from_slice(&c[..width]);
                }
            }
            v
        })
        .collect();

    let chunks: Vec<ChunkOut> = (0..n_chunks)
        .into_par_iter()
        .map(|c| {
            let lo = c * CHUNK;
            let hi = (lo + CHUNK).min(n_resamples);
            let mut counts: Vec<Vec<Vec<Vec<usize>>>> = (0..n_groups)
                .map(|_| {
                    n_rank
                        .iter()
                        .map(|&nr| vec![vec![0usize; nr]; budgets.len()])
                        .collect()
                })
                .collect();
            let mut delta = vec![vec![Vec::with_capacity(hi - lo); ns]; n_groups];
            let r_n = hi - lo;
            let n_strata = strata_clips.len();
            let mut gsum = vec![0.0; stride];
            let mut mc = vec![0.0; ns];
            let mut ma = vec![0.0; ns];
            // Stratum sums of every resample of the chunk: [resample][stratum][stride].
            let mut all = vec![0.0; r_n * n_strata * stride];
            let unpack = |acc_w: &[f64], total: f64, acc: &mut [f64]| {
                if slots.uniform_clean {
                    acc[..ns].fill(acc_w[0]);
                    acc[ns..2 * ns].copy_from_slice(&acc_w[1..]);
                } else {
                    acc[..width].copy_from_slice(acc_w);
                }
                if slots.uniform {
                    acc[2 * ns..].fill(total);
                }
            };
            for (s, rows) in packed.iter().enumerate() {
                let n = strata_clips[s].len();
                if n == 0 {
                    continue;
                }
                match method {
                    Resampling::Multinomial => {
                        // n draws with replacement per resample, resample by resample.
                        let mut rng = seed::rng(seed_value, &[BOOT, s as u64, c as u64]);
                        let mut acc_w = vec![0.0; width];
                        for r in 0..r_n {
                            acc_w.fill(0.0);
                            for _ in 0..n {
                                let k = rng.random_range(0..n);
                                let row = &rows[k * width..(k + 1) * width];
                                for (a, v) in acc_w.iter_mut().zip(row) {
                                    *a += v;
                                }
                            }
                            let at = (r * n_strata + s) * stride;
                            unpack(&acc_w, n as f64, &mut all[at..at + stride]);
                        }
                    }
                    Resampling::Poisson => {
                        // Every clip gets an independent Poisson(1) weight in every resample;
                        // clips stream in order, all resamples of the chunk at once.
                        let mut rng = seed::Xoshiro256pp::new(
                            seed_value,
                            &[BOOT_POISSON, s as u64, c as u64],
                        );
                        let mut acc_t = vec![0.0; width * r_n];
                        let mut total = vec![0.0; r_n];
                        let mut w = vec![0.0; r_n];
                        let mut raw = vec![0u32; r_n];
                        for k in 0..n {
                            poisson1_fill(&mut rng, &mut raw, &mut w);
                            let w = &w[..];
                            let row = &rows[k * width..(k + 1) * width];
                            for (j, &v) in row.iter().enumerate() {
                                for (a, &wr) in acc_t[j * r_n..(j + 1) * r_n].iter_mut().zip(w) {
                                    *a += wr * v;
                                }
                            }
                            for (t, &wr) in total.iter_mut().zip(w) {
                                *t += wr;
                            }
                        }
                        let mut acc_w = vec![0.0; width];
                        for r in 0..r_n {
                            for (j, a) in acc_w.iter_mut().enumerate() {
                                *a = acc_t[j * r_n + r];
                            }
                            let at = (r * n_strata + s) * stride;
                            unpack(&acc_w, total[r], &mut all[at..at + stride]);
                        }
                    }
                }
            }
            for r in 0..r_n {
                let stratum_sum = &all[r * n_strata * stride..(r + 1) * n_strata * stride];
                for g in 0..n_groups {
                    gsum.fill(0.0);
                    for &s in &groups.strata[g] {
                        for (a, v) in gsum
                            .iter_mut()
                            .zip(&stratum_sum[s * stride..(s + 1) * stride])
                        {
                            *a += v;
                        }
                    }
                    let (clean, rest) = gsum.split_at(ns);
                    let (att, cnt) = rest.split_at(ns);
                    for i in 0..ns {
                        if cnt[i] > 0.0 {
                            mc[i] = clean[i] / cnt[i];
                            ma[i] = att[i] / cnt[i];
                            delta[g][i].push(ma[i] - mc[i]);
                        }
                    }
                    for (ai, a) in axes.iter().enumerate() {
                        let o = slots.axis_offset[ai];
                        let m = a.levels.len();
                        for (bi, &b) in budgets.iter().enumerate() {
                            let out =
                                threshold(&mc[o..o + m], &ma[o..o + m], &cnt[o..o + m], b, rule);
                            counts[g][ai][bi][out.rank()] += 1;
                        }
                    }
                }
            }
            ChunkOut { counts, delta }
        })
        .collect();

    let mut counts: Vec<Vec<Vec<Vec<usize>>>> = (0..n_groups)
        .map(|_| {
            n_rank
                .iter()
                .map(|&nr| vec![vec![0usize; nr]; budgets.len()])
                .collect()
        })
        .collect();
    let mut delta = vec![vec![Vec::with_capacity(n_resamples); ns]; n_groups];
    for ch in chunks {
        for g in 0..n_groups {
            for (ai, per_b) in ch.counts[g].iter().enumerate() {
                for (bi, ranks) in per_b.iter().enumerate() {
                    for (r, &v) in ranks.iter().enumerate() {
                        counts[g][ai][bi][r] += v;
                    }
                }
            }
            for (i, d) in ch.delta[g].iter().enumerate() {
                delta[g][i].extend_from_slice(d);
            }
        }
    }
    for g in delta.iter_mut() {
        for d in g.iter_mut() {
            d.sort_unstable_by(f64::total_cmp);
        }
    }
    BootResult {
        counts,
        delta,
        n: n_resamples,
    }
}

/// numpy's default (linear) percentile of sorted data, q in [0, 1].
pub(crate) fn percentile_sorted(sorted: &[f64], q: f64) -> Option<f64> {
    if sorted.is_empty() {
        return None;
    }
    let h = (sorted.len() - 1) as f64 * q;
    let lo = h.floor() as usize;
    let hi = h.ceil() as usize;
    Some(sorted[lo] + (h - lo as f64) * (sorted[hi] - sorted[lo]))
}

/// Inverse-CDF quantile on ordinal ranks: the smallest rank whose cumulative share ≥ q.
pub(crate) fn ordinal_quantile(counts: &[usize], q: f64) -> Option<usize> {
    let total: usize = counts.iter().sum();
    if total == 0 {
        return None;
    }
    let mut cum = 0usize;
    for (r, &c) in counts.iter().enumerate() {
        cum += c;
        // cum / total >= q, in integers to avoid rounding at exact boundaries.
        if (cum as f64) >= q * total as f64 - 1e-9 * total as f64 {
            return Some(r);
        }
    }
    Some(counts.len() - 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    const ONES: [f64; 4] = [1.0; 4];

    #[test]
    fn first_violation_rule() {
        let clean = [1.0; 4];
        // passes, passes, fails, passes
        let att = [1.0, 1.1, 1.2, 1.0];
        let o = threshold(&clean, &att, &ONES, 0.15, ThresholdRule::FirstViolation);
        assert_eq!(
            o,
            Outcome {
                level: Some(1),
                censored: false
            }
        );
        let o = threshold(&clean, &att, &ONES, 0.15, ThresholdRule::MaxPassing);
        assert_eq!(
            o,
            Outcome {
                level: Some(3),
                censored: true
            }
        );
        // exactly at the budget fails (strict <)
        let o = threshold(
            &clean,
            &[1.15, 1.0, 1.0, 1.0],
            &ONES,
            0.15,
            ThresholdRule::FirstViolation,
        );
        assert_eq!(
            o,
            Outcome {
                level: None,
                censored: false
            }
        );
        let o = threshold(
            &clean,
            &[1.0; 4],
            &ONES,
            0.15,
            ThresholdRule::FirstViolation,
        );
        assert_eq!(
            o,
            Outcome {
                level: Some(3),
                censored: true
            }
        );
        let o = threshold(&clean, &[2.0; 4], &ONES, 0.15, ThresholdRule::MaxPassing);
        assert_eq!(
            o,
            Outcome {
                level: None,
                censored: false
            }
        );
    }

    #[test]
    fn missing_levels_are_skipped() {
        let o = threshold(
            &[1.0; 3],
            &[1.0, 9.0, 1.0],
            &[1.0, 0.0, 1.0],
            0.1,
            ThresholdRule::FirstViolation,
        );
        assert_eq!(
            o,
            Outcome {
                level: Some(2),
                censored: true
            }
        );
    }

    #[test]
    fn poisson_weights_follow_the_law() {
        let t = poisson1_thresholds();
        assert_eq!(t[0], (4_294_967_296.0 * (-1.0f64).exp()).round() as u32);
        assert!(t.windows(2).all(|p| p[0] < p[1]));
        assert_eq!(poisson1(0), 0.0);
        assert!(poisson1(u32::MAX) >= 11.0);
        // The table agrees with the threshold compares everywhere near every threshold.
        for &x in t.iter() {
            for u in [
                x.saturating_sub(70_000),
                x.saturating_sub(1),
                x,
                x.saturating_add(1),
                x.saturating_add(70_000),
            ] {
                assert_eq!(poisson1(u), f64::from(poisson1_slow(u)), "{u}");
            }
        }
        // One straddling bucket per distinct threshold bucket (the top thresholds share one).
        let mut buckets: Vec<u32> = t
            .iter()
            .filter(|&&x| x & 0xFFFF != 0)
            .map(|&x| x >> 16)
            .collect();
        buckets.dedup();
        assert_eq!(
            poisson1_lut().iter().filter(|&&c| c == 0xFF).count(),
            buckets.len()
        );
        // Empirical mean and variance of 2^20 draws are 1 within sampling error.
        let mut g = fogline_stats::seed::Xoshiro256pp::new(1, &[2]);
        let n = 1 << 20;
        let (mut s1, mut s2) = (0.0, 0.0);
        for _ in 0..n {
            let w = poisson1(g.next_u64() as u32);
            s1 += w;
            s2 += w * w;
        }
        let mean = s1 / n as f64;
        let var = s2 / n as f64 - mean * mean;
        assert!((mean - 1.0).abs() < 5.0 / (n as f64).sqrt(), "{mean}");
        assert!((var - 1.0).abs() < 10.0 / (n as f64).sqrt(), "{var}");
    }

    #[test]
    fn quantiles() {
        assert_eq!(percentile_sorted(&[1.0, 2.0, 3.0, 4.0], 0.5), Some(2.5));
        assert_eq!(percentile_sorted(&[1.0, 2.0, 3.0, 4.0], 0.025), Some(1.075));
        assert_eq!(ordinal_quantile(&[25, 50, 925], 0.025), Some(0));
        assert_eq!(ordinal_quantile(&[24, 51, 925], 0.025), Some(1));
        assert_eq!(ordinal_quantile(&[0, 0, 1000], 0.975), Some(2));
        assert_eq!(ordinal_quantile(&[0, 975, 25], 0.975), Some(1));
    }
}
