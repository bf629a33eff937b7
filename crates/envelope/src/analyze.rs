//! The analysis: a [`PairTable`] and [`EnvelopeParams`] in, an [`Envelope`] out.

use std::collections::BTreeMap;

use fogline_stats::{contingency, correlation, describe, effect, gmm, icc, rank};
use fogline_types::Taxonomy;

use crate::error::{EnvelopeError, Result};
use crate::input::PairTable;
use crate::model::*;
use crate::params::{Bands, BootstrapMethod, EnvelopeParams, TaxonomyChoice};
use crate::threshold::{self, ClipSlots, Groups, Outcome};

/// Analyses a pairs table (sections 3–7 and tables 1–5 of the envelope paper).
pub fn analyze(t: &PairTable, p: &EnvelopeParams) -> Result<Envelope> {
    p.validate()?;
    if t.is_empty() {
        return Err(EnvelopeError::InvalidParam {
            name: "pairs",
            reason: "the table has no rows".into(),
        });
    }
    let mut notes = Vec::new();

    // ---- taxonomy and strata -------------------------------------------------------------
    let taxonomy = match &p.taxonomy {
        TaxonomyChoice::Given(tx) => tx.clone(),
        TaxonomyChoice::Auto => {
            let paper = Taxonomy::paper();
            if t.scenarios.iter().any(|s| paper.is_classified(s)) {
                paper
            } else {
                let tx =
                    Taxonomy::from_labels(t.scenarios.iter().map(String::as_str), &paper.other);
                notes.push(format!(
                    "no scenario label is one of the paper's seven classes: using the {} labels found in the data as the taxonomy",
                    tx.classes.len()
                ));
                tx
            }
        }
    };
    let n_strata = t.scenarios.len();
    let classified_stratum: Vec<bool> = t
        .scenarios
        .iter()
        .map(|s| taxonomy.is_classified(s))
        .collect();
    let mut unclassified_labels: Vec<String> = t
        .scenarios
        .iter()
        .filter(|s| !taxonomy.is_classified(s) && **s != taxonomy.other)
        .cloned()
        .collect();
    unclassified_labels.sort();
    if !unclassified_labels.is_empty() {
        notes.push(format!(
            "scenario labels not in the taxonomy are treated as {}: {}",
            taxonomy.other,
            unclassified_labels.join(", ")
        ));
    }
    let mut strata_clips: Vec<Vec<usize>> = vec![Vec::new(); n_strata];
    for (k, &s) in t.clip_scenario.iter().enumerate() {
        strata_clips[s as usize].push(k);
    }
    // Classified scenarios present, in rank order.
    let classified: Vec<(String, usize)> = taxonomy
        .classes
        .iter()
        .filter_map(|c| {
            t.scenarios
                .iter()
                .position(|s| s == c)
                .map(|i| (c.clone(), i))
        })
        .collect();
    let mut groups = Groups {
        names: classified.iter().map(|(n, _)| n.clone()).collect(),
        strata: classified.iter().map(|(_, s)| vec![*s]).collect(),
    };
    groups.names.push(AGG_CLASSIFIED.into());
    groups
        .strata
        .push(classified.iter().map(|(_, s)| *s).collect());
    groups.names.push(AGG_ALL.into());
    groups.strata.push((0..n_strata).collect());
    let n_groups = groups.names.len();
    let g_all = n_groups - 1;
    let g_clf = n_groups - 2;
    let group_clips: Vec<usize> = groups
        .strata
        .iter()
        .map(|ss| ss.iter().map(|&s| strata_clips[s].len()).sum())
        .collect();
    let is_pilot = |g: usize| g < g_clf && group_clips[g] < p.min_clips;
    if classified.is_empty() {
        notes.push("no classified scenario in the data: per-scenario results are empty".into());
    }
    if t.n_incomplete_clips > 0 {
        notes.push(format!(
            "{} clips lack some conditions: level means use the pairs present; the ICC uses complete clips only",
            t.n_incomplete_clips
        ));
    }

    // ---- axes, dose-response, thresholds --------------------------------------------------
    let (axes, slot_of_cond) = threshold::build_axes(t);
    if axes.is_empty() {
        return Err(EnvelopeError::InvalidParam {
            name: "pairs",
            reason: "no perturbed condition (every condition is at its family's identity level)"
                .into(),
        });
    }
    let slots = ClipSlots::build(t, &axes, &slot_of_cond);
    let ns = slots.n_slots;
    let group_sums: Vec<Vec<f64>> = groups
        .strata
        .iter()
        .map(|ss| {
            let mut acc = vec![0.0; slots.stride()];
            for &s in ss {
                for &k in &strata_clips[s] {
                    for (a, v) in acc.iter_mut().zip(slots.clip(k)) {
                        *a += v;
                    }
                }
            }
            acc
        })
        .collect();
    let means = |g: usize| -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let s = &group_sums[g];
        let cnt = s[2 * ns..3 * ns].to_vec();
        let mc = (0..ns)
            .map(|i| if cnt[i] > 0.0 { s[i] / cnt[i] } else { 0.0 })
            .collect();
        let ma = (0..ns)
            .map(|i| {
                if cnt[i] > 0.0 {
                    s[ns + i] / cnt[i]
                } else {
                    0.0
                }
            })
            .collect();
        (mc, ma, cnt)
    };
    let clock = std::time::Instant::now();
    let resampling = match p.bootstrap_method {
        BootstrapMethod::Multinomial => threshold::Resampling::Multinomial,
        BootstrapMethod::Poisson => threshold::Resampling::Poisson,
        BootstrapMethod::Auto if t.clip_ids.len() > p.poisson_min_clips => {
            notes.push(format!(
                "{} clips (more than {}): the bootstrap uses Poisson(1) clip weights",
                t.clip_ids.len(),
                p.poisson_min_clips
            ));
            threshold::Resampling::Poisson
        }
        BootstrapMethod::Auto => threshold::Resampling::Multinomial,
    };
    let boot = (p.bootstrap > 0).then(|| {
        threshold::bootstrap(
            &slots,
            &axes,
            &strata_clips,
            &groups,
            &p.budgets,
            p.rule,
            p.bootstrap,
            p.seed,
            resampling,
        )
    });

    log::debug!("bootstrap: {:.3} s", clock.elapsed().as_secs_f64());
    let budget_key = |b: f64| format!("{b}");
    let mut dose_response = Vec::new();
    for g in 0..n_groups {
        let (mc, ma, cnt) = means(g);
        for (ai, a) in axes.iter().enumerate() {
            for (li, &level) in a.levels.iter().enumerate() {
                let i = slots.axis_offset[ai] + li;
                if cnt[i] == 0.0 {
                    continue;
                }
                let ci = boot.as_ref().and_then(|b| {
                    let d = &b.delta[g][i];
                    Some([
                        threshold::percentile_sorted(d, 0.025)?,
                        threshold::percentile_sorted(d, 0.975)?,
                    ])
                });
                dose_response.push(DosePoint {
                    scenario: groups.names[g].clone(),
                    axis: a.axis.clone(),
                    level,
                    n_pairs: cnt[i] as usize,
                    mean_ade_clean_m: mc[i],
                    mean_ade_attacked_m: ma[i],
                    delta_ade_m: ma[i] - mc[i],
                    delta_ade_ci95_m: ci,
                    ratio: finite(ma[i] / mc[i]),
                    within_budget: p
                        .budgets
                        .iter()
                        .map(|&b| (budget_key(b), ma[i] < (1.0 + b) * mc[i]))
                        .collect(),
                });
            }
        }
    }

    let outcome = |g: usize, ai: usize, b: f64| -> Outcome {
        let (mc, ma, cnt) = means(g);
        let o = slots.axis_offset[ai];
        let m = axes[ai].levels.len();
        threshold::threshold(&mc[o..o + m], &ma[o..o + m], &cnt[o..o + m], b, p.rule)
    };
    let level_of = |ai: usize, o: Outcome| o.level.map(|l| axes[ai].levels[l]);
    let mut thresholds = Vec::new();
    for (ai, a) in axes.iter().enumerate() {
        for (bi, &b) in p.budgets.iter().enumerate() {
            let agg = outcome(g_all, ai, b);
            for g in 0..n_groups {
                let o = outcome(g, ai, b);
                let (ci95, share) = match &boot {
                    Some(bt) => {
                        let counts = &bt.counts[g][ai][bi];
                        let rank_value =
                            |r: usize| if r == 0 { None } else { Some(a.levels[r - 1]) };
                        let ci = [
                            threshold::ordinal_quantile(counts, 0.025).and_then(rank_value),
                            threshold::ordinal_quantile(counts, 0.975).and_then(rank_value),
                        ];
                        let mut share = BTreeMap::new();
                        for (r, &c) in counts.iter().enumerate() {
                            let key = if r == 0 {
                                "none".to_string()
                            } else {
                                format!("{}", a.levels[r - 1])
                            };
                            share.insert(key, c as f64 / bt.n as f64);
                        }
                        (Some(ci), share)
                    }
                    None => (None, BTreeMap::new()),
                };
                let vs = (g < g_clf).then(|| match o.rank().cmp(&agg.rank()) {
                    std::cmp::Ordering::Less => VsAggregate::Tighter,
                    std::cmp::Ordering::Equal => VsAggregate::Matches,
                    std::cmp::Ordering::Greater => VsAggregate::Looser,
                });
                thresholds.push(Threshold {
                    scenario: groups.names[g].clone(),
                    kind: if g < g_clf { "scenario" } else { "aggregate" }.into(),
                    axis: a.axis.clone(),
                    budget: b,
                    rule: p.rule.name().into(),
                    n_clips: group_clips[g],
                    sigma_star: level_of(ai, o),
                    right_censored: o.censored,
                    ci95,
                    bootstrap_share: share,
                    vs_aggregate: vs,
                    pilot: is_pilot(g),
                });
            }
        }
    }

    // ---- corpus summary and ΔADE map --------------------------------------------------------
    let mut scen_pairs = vec![0usize; n_strata];
    let mut scen_changed = vec![0usize; n_strata];
    let mut scen_clean = vec![0.0f64; n_strata];
    for r in 0..t.len() {
        let s = t.row_scenario(r) as usize;
        scen_pairs[s] += 1;
        scen_changed[s] += usize::from(t.changed[r]);
        scen_clean[s] += t.ade_clean_m[r];
    }
    let mut order: Vec<usize> = (0..n_strata).collect();
    order.sort_by_key(|&s| {
        (
            taxonomy.rank(&t.scenarios[s]).unwrap_or(usize::MAX),
            t.scenarios[s].clone(),
        )
    });
    let scenarios: Vec<ScenarioSummary> = order
        .iter()
        .map(|&s| ScenarioSummary {
            scenario: t.scenarios[s].clone(),
            rank: taxonomy.rank(&t.scenarios[s]),
            classified: classified_stratum[s],
            n_clips: strata_clips[s].len(),
            n_pairs: scen_pairs[s],
            n_changed: scen_changed[s],
            clean_ade_mean_m: scen_clean[s] / scen_pairs[s] as f64,
            flip_rate: scen_changed[s] as f64 / scen_pairs[s] as f64,
            pilot: classified_stratum[s] && strata_clips[s].len() < p.min_clips,
        })
        .collect();
    let n_cond = t.conditions.len();
    let mut cell = vec![(0usize, 0.0f64); (n_strata + 2) * n_cond];
    for r in 0..t.len() {
        let s = t.row_scenario(r) as usize;
        let c = t.condition[r] as usize;
        let d = t.ade_attacked_m[r] - t.ade_clean_m[r];
        for row in [
            Some(s),
            classified_stratum[s].then_some(n_strata),
            Some(n_strata + 1),
        ]
        .into_iter()
        .flatten()
        {
            let e = &mut cell[row * n_cond + c];
            e.0 += 1;
            e.1 += d;
        }
    }
    let mut delta_ade_map = Vec::new();
    let row_names: Vec<String> = order
        .iter()
        .map(|&s| t.scenarios[s].clone())
        .chain([AGG_CLASSIFIED.to_string(), AGG_ALL.to_string()])
        .collect();
    let row_index: Vec<usize> = order
        .iter()
        .copied()
        .chain([n_strata, n_strata + 1])
        .collect();
    for (name, &ri) in row_names.iter().zip(&row_index) {
        for c in 0..n_cond {
            let (n, sum) = cell[ri * n_cond + c];
            if n > 0 {
                delta_ade_map.push(MapCell {
                    scenario: name.clone(),
                    condition: t.conditions[c].name.clone(),
                    n_pairs: n,
                    delta_ade_m: sum / n as f64,
                });
            }
        }
    }

    // ---- severity -------------------------------------------------------------------------
    let changed_rows: Vec<usize> = (0..t.len()).filter(|&r| t.changed[r]).collect();
    let l2_changed: Vec<f64> = changed_rows.iter().map(|&r| t.l2_m[r]).collect();
    let sel_params = p.gmm_select_params();
    let clock = std::time::Instant::now();
    let selection = if l2_changed.len() < 2 {
        Err(format!(
            "{} changed pairs; a mixture needs at least 2",
            l2_changed.len()
        ))
    } else {
        let r = match p.bands {
            Bands::Auto => gmm::select_k(&l2_changed, &sel_params),
            Bands::Fixed(k) => gmm::select_k_fixed(&l2_changed, k, &sel_params),
        };
        r.map_err(|e| e.to_string())
    };
    let (severity, assignment) = match &selection {
        Ok(sel) => severity_from(sel, &l2_changed, p),
        Err(reason) => {
            notes.push(format!("severity bands undefined: {reason}"));
            (
                Severity {
                    defined: false,
                    reason: Some(reason.clone()),
                    n_changed: l2_changed.len(),
                    bands_mode: bands_mode(p).into(),
                    bic: Vec::new(),
                    chosen_per_seed: Vec::new(),
                    chosen_k: None,
                    cv_loglik: Vec::new(),
                    bands: Vec::new(),
                    boundaries_m: Vec::new(),
                    lower_bound: None,
                    per_scenario: Vec::new(),
                },
                Vec::new(),
            )
        }
    };
    log::debug!("severity bands: {:.3} s", clock.elapsed().as_secs_f64());
    let k = severity.bands.len();
    let n_high_bands = if k >= 2 { p.high_bands.min(k - 1) } else { 0 };
    if k >= 2 && p.high_bands > k - 1 {
        notes.push(format!(
            "only {k} bands: the top {n_high_bands} count as high severity (asked for {})",
            p.high_bands
        ));
    }
    let is_high = |band: usize| k >= 2 && band >= k - n_high_bands;
    let high_names: Vec<String> = (k - n_high_bands..k).map(|b| format!("C{b}")).collect();
    // band of each changed row, by changed index
    let high_row = |rows: &mut dyn Iterator<Item = usize>| -> (usize, usize, f64) {
        let (mut n, mut h, mut sum) = (0usize, 0usize, 0.0f64);
        for ci in rows {
            n += 1;
            sum += l2_changed[ci];
            if !assignment.is_empty() && is_high(assignment[ci]) {
                h += 1;
            }
        }
        (n, h, sum)
    };
    let mk_high = |group: String, (n, h, sum): (usize, usize, f64)| HighRow {
        group,
        n_changed: n,
        n_high: h,
        share: (n > 0 && n_high_bands > 0).then(|| h as f64 / n as f64),
        mean_l2_changed_m: (n > 0).then(|| sum / n as f64),
    };
    let stratum_of_changed: Vec<usize> = changed_rows
        .iter()
        .map(|&r| t.row_scenario(r) as usize)
        .collect();
    let mut by_scenario = Vec::new();
    for g in 0..n_groups {
        let members: Vec<bool> = {
            let mut m = vec![false; n_strata];
            for &s in &groups.strata[g] {
                m[s] = true;
            }
            m
        };
        let stats =
            high_row(&mut (0..changed_rows.len()).filter(|&ci| members[stratum_of_changed[ci]]));
        by_scenario.push(mk_high(groups.names[g].clone(), stats));
    }
    let by_condition: Vec<HighRow> = (0..n_cond)
        .map(|c| {
            let stats = high_row(
                &mut (0..changed_rows.len())
                    .filter(|&ci| t.condition[changed_rows[ci]] as usize == c),
            );
            mk_high(t.conditions[c].name.clone(), stats)
        })
        .collect();
    let high_severity = HighSeverity {
        bands: high_names,
        by_scenario,
        by_condition,
    };

    // joint scenario × band (classified scenarios)
    let mut counts = vec![vec![0usize; k]; classified.len()];
    if !assignment.is_empty() {
        for (ci, &s) in stratum_of_changed.iter().enumerate() {
            if let Some(gi) = classified.iter().position(|(_, cs)| *cs == s) {
                counts[gi][assignment[ci]] += 1;
            }
        }
    }
    let row_shares = counts
        .iter()
        .map(|row| {
            let n: usize = row.iter().sum();
            row.iter()
                .map(|&c| if n > 0 { c as f64 / n as f64 } else { 0.0 })
                .collect()
        })
        .collect();
    let joint = Joint {
        scenarios: classified.iter().map(|(n, _)| n.clone()).collect(),
        bands: (0..k).map(|b| format!("C{b}")).collect(),
        counts,
        row_shares,
    };

    // per-scenario mixtures
    let clock = std::time::Instant::now();
    let mut severity = severity;
    if severity.defined {
        for (name, s) in &classified {
            let x: Vec<f64> = (0..changed_rows.len())
                .filter(|&ci| stratum_of_changed[ci] == *s)
                .map(|ci| l2_changed[ci])
                .collect();
            let sp = gmm::SelectParams {
                k_max: p.per_scenario_k_max,
                restarts: 1,
                cv_folds: 0,
                ..sel_params.clone()
            };
            let mix = if x.len() < 2 {
                ScenarioMixture {
                    scenario: name.clone(),
                    n_changed: x.len(),
                    bic: Vec::new(),
                    chosen_k: None,
                    reason: Some(format!(
                        "{} changed pairs; a mixture needs at least 2",
                        x.len()
                    )),
                }
            } else {
                match gmm::select_k(&x, &sp) {
                    Ok(sel) => ScenarioMixture {
                        scenario: name.clone(),
                        n_changed: x.len(),
                        bic: sel
                            .k_values
                            .iter()
                            .copied()
                            .zip(sel.bic_min.iter().copied())
                            .collect(),
                        chosen_k: Some(sel.chosen_k),
                        reason: None,
                    },
                    Err(e) => ScenarioMixture {
                        scenario: name.clone(),
                        n_changed: x.len(),
                        bic: Vec::new(),
                        chosen_k: None,
                        reason: Some(e.to_string()),
                    },
                }
            };
            severity.per_scenario.push(mix);
        }
    }

    log::debug!(
        "per-scenario mixtures: {:.3} s",
        clock.elapsed().as_secs_f64()
    );
    // ---- statistics -------------------------------------------------------------------------
    let clock = std::time::Instant::now();
    let statistics =
        crate::statistics::compute(t, p, &changed_rows, &l2_changed, &joint, &slot_of_cond);

    log::debug!("statistics: {:.3} s", clock.elapsed().as_secs_f64());
    // ---- transitions ------------------------------------------------------------------------
    let labels = t.action_labels.clone();
    let na = labels.len();
    let mut tm = vec![vec![0usize; na]; na];
    for &r in &changed_rows {
        if classified_stratum[t.row_scenario(r) as usize] {
            tm[t.action_clean[r] as usize][t.action_attacked[r] as usize] += 1;
        }
    }
    let tn: usize = tm.iter().flatten().sum();
    let trace: usize = (0..na).map(|i| tm[i][i]).sum();
    let transitions = Transitions {
        by_action: (0..na)
            .map(|i| {
                let n: usize = tm[i].iter().sum();
                ActionDiagonal {
                    action: labels[i].clone(),
                    n,
                    diagonal_share: (n > 0).then(|| tm[i][i] as f64 / n as f64),
                }
            })
            .collect(),
        labels,
        counts: tm,
        n: tn,
        diagonal_share: (tn > 0).then(|| trace as f64 / tn as f64),
    };

    // ---- ODD entries -------------------------------------------------------------------------
    let odd_axis = match axes.iter().position(|a| a.axis == p.odd_family) {
        Some(i) => i,
        None => {
            notes.push(format!(
                "the ODD family {:?} is not in the data; the ODD entries use axis {:?}",
                p.odd_family, axes[0].axis
            ));
            0
        }
    };
    let hb = p.headline_budget;
    let overall_high = high_severity.by_scenario[g_all].share;
    let agg_out = outcome(g_all, odd_axis, hb);
    let sigma_op = p.sigma_op.or(level_of(odd_axis, agg_out));
    let mut odd = Vec::new();
    for (gi, (name, _)) in classified.iter().enumerate() {
        let th = thresholds
            .iter()
            .find(|x| x.scenario == *name && x.axis == axes[odd_axis].axis && x.budget == hb)
            .cloned();
        let Some(th) = th else { continue };
        let p_high = high_severity.by_scenario[gi].share;
        let group_of = |v: Option<VsAggregate>| match v {
            Some(VsAggregate::Tighter) => "tight",
            Some(VsAggregate::Matches) => "match",
            Some(VsAggregate::Looser) => "loose",
            None => "undefined",
        };
        let threshold_group = group_of(th.vs_aggregate);
        // Every axis's threshold at the headline budget, so a runtime monitor has an
        // envelope for each condition it estimates (the headline axis is among them).
        let per_axis: Vec<AxisThreshold> = axes
            .iter()
            .filter_map(|a| {
                let t = thresholds
                    .iter()
                    .find(|x| x.scenario == *name && x.axis == a.axis && x.budget == hb)?;
                Some(AxisThreshold {
                    axis: a.axis.clone(),
                    family: a.family.clone(),
                    descending: a.axis == "darken",
                    identity_level: fogline_types::Family::from_name(&a.family).identity_level(),
                    levels: a.levels.clone(),
                    sigma_star: t.sigma_star,
                    right_censored: t.right_censored,
                    ci95: t.ci95,
                    threshold_group: group_of(t.vs_aggregate).into(),
                })
            })
            .collect();
        let severity_group = match (p_high, overall_high) {
            (Some(ph), Some(po)) => {
                if ph <= po {
                    "mild"
                } else if ph < p.severe_factor * po {
                    "moderate"
                } else {
                    "severe"
                }
            }
            _ => "undefined",
        };
        let (accepted, acceptance_reason) = match p.pi_star {
            None => (None, None),
            Some(pi) => {
                let mut why = Vec::new();
                match (sigma_op, th.sigma_star) {
                    (None, _) => why.push("no operating level: the aggregate threshold is none and --sigma-op is unset".to_string()),
                    (Some(_), None) => why.push("σ* is none (the smallest level already fails)".to_string()),
                    (Some(op), Some(s)) if op > s => why.push(format!("σ_op {op} > σ* {s}")),
                    _ => {}
                }
                match p_high {
                    None => why.push("P(high) is undefined".to_string()),
                    Some(ph) if ph > pi => why.push(format!("P(high) {:.4} > π* {pi}", ph)),
                    _ => {}
                }
                let ok = why.is_empty();
                (
                    Some(ok),
                    Some(if ok {
                        format!(
                            "σ_op {} ≤ σ* and P(high) ≤ π* {pi}",
                            sigma_op.map_or("-".into(), |v| v.to_string())
                        )
                    } else {
                        why.join("; ")
                    }),
                )
            }
        };
        odd.push(OddEntry {
            scenario: name.clone(),
            rank: taxonomy.rank(name),
            n_clips: group_clips[gi],
            n_changed: high_severity.by_scenario[gi].n_changed,
            pilot: is_pilot(gi),
            axis: axes[odd_axis].axis.clone(),
            budget: hb,
            sigma_star: th.sigma_star,
            right_censored: th.right_censored,
            ci95: th.ci95,
            p_high,
            threshold_group: threshold_group.into(),
            severity_group: severity_group.into(),
            quadrant: format!("{threshold_group} + {severity_group}"),
            accepted,
            acceptance_reason,
            thresholds: per_axis,
        });
    }

    // ---- assurance (table 5) ------------------------------------------------------------------
    let s_lo = hb * (1.0 - p.budget_sensitivity);
    let s_hi = hb * (1.0 + p.budget_sensitivity);
    let budget_sensitivity: Vec<Sensitivity> = (0..n_groups)
        .map(|g| {
            let lo = level_of(odd_axis, outcome(g, odd_axis, s_lo));
            let mid = level_of(odd_axis, outcome(g, odd_axis, hb));
            let hi = level_of(odd_axis, outcome(g, odd_axis, s_hi));
            Sensitivity {
                scenario: groups.names[g].clone(),
                sigma_star_low: lo,
                sigma_star: mid,
                sigma_star_high: hi,
                stable: lo == mid && mid == hi,
            }
        })
        .collect();
    let assurance = crate::assurance::build(
        p,
        &odd,
        &severity,
        &budget_sensitivity,
        &axes[odd_axis].axis,
        sigma_op,
    );

    let conventions = crate::conventions(p);
    Ok(Envelope {
        schema_version: SCHEMA_VERSION,
        generated_by: format!("fogline-envelope {}", env!("CARGO_PKG_VERSION")),
        input: t.input.clone(),
        parameters: p.clone(),
        bootstrap_method: match (p.bootstrap, resampling) {
            (0, _) => "none",
            (_, threshold::Resampling::Multinomial) => "multinomial",
            (_, threshold::Resampling::Poisson) => "poisson",
        }
        .into(),
        conventions,
        corpus: Corpus {
            n_pairs: t.len(),
            n_clips: t.clip_ids.len(),
            n_changed: changed_rows.len(),
            n_incomplete_clips: t.n_incomplete_clips,
            taxonomy: taxonomy.classes.clone(),
            other_label: taxonomy.other.clone(),
            unclassified_labels,
            conditions: t.conditions.clone(),
            scenarios,
        },
        axes,
        dose_response,
        delta_ade_map,
        thresholds,
        severity,
        high_severity,
        joint,
        odd,
        statistics,
        transitions,
        assurance,
        notes,
    })
}

fn bands_mode(p: &EnvelopeParams) -> &'static str {
    match p.bands {
        Bands::Auto => "auto",
        Bands::Fixed(_) => "fixed",
    }
}

fn severity_from(sel: &gmm::Selection, x: &[f64], p: &EnvelopeParams) -> (Severity, Vec<usize>) {
    let m = &sel.model;
    let k = m.means.len();
    // x is finite by construction (validated on read), so prediction cannot fail.
    let assignment = m.predict(x).unwrap_or_else(|_| vec![0; x.len()]);
    let mut n_band = vec![0usize; k];
    for &b in &assignment {
        n_band[b] += 1;
    }
    let bands = (0..k)
        .map(|b| Band {
            name: format!("C{b}"),
            mean_m: m.means[b],
            std_m: m.variances[b].sqrt(),
            weight: m.weights[b],
            share: n_band[b] as f64 / x.len() as f64,
            n: n_band[b],
        })
        .collect();
    let bic = sel
        .k_values
        .iter()
        .enumerate()
        .map(|(i, &kk)| {
            let gain = sel.gains[i];
            let next = sel.gains.get(i + 1).copied().flatten();
            BicRow {
                k: kk,
                per_seed: sel.bic.iter().map(|row| row[i]).collect(),
                min: sel.bic_min[i],
                chosen_count: sel.chosen_count[i],
                gain,
                gain_ratio: match (gain, next) {
                    (Some(a), Some(b)) if b != 0.0 => finite(a / b),
                    _ => None,
                },
            }
        })
        .collect();
    let cv_loglik = sel
        .cv
        .as_ref()
        .map(|cv| {
            sel.k_values
                .iter()
                .enumerate()
                .map(|(i, &kk)| CvRow {
                    k: kk,
                    folds: cv.loglik[i].clone(),
                    mean: cv.mean[i],
                    folds_beating_previous: cv.folds_beating_previous[i],
                })
                .collect()
        })
        .unwrap_or_default();
    (
        Severity {
            defined: true,
            reason: None,
            n_changed: x.len(),
            bands_mode: bands_mode(p).into(),
            bic,
            chosen_per_seed: sel.chosen_per_restart.clone(),
            chosen_k: Some(sel.chosen_k),
            cv_loglik,
            bands,
            boundaries_m: boundaries(m, x),
            lower_bound: finite(m.lower_bound),
            per_scenario: Vec::new(),
        },
        assignment,
    )
}

/// Where the hard assignment switches band, found by bisection between consecutive sorted
/// sample values whose bands differ (within the data range only).
fn boundaries(m: &gmm::Gmm1d, x: &[f64]) -> Vec<f64> {
    let (lo, hi) = x
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    if lo >= hi || !lo.is_finite() || !hi.is_finite() {
        return Vec::new();
    }
    let n_grid = 2048;
    let grid: Vec<f64> = (0..=n_grid)
        .map(|i| lo + (hi - lo) * i as f64 / n_grid as f64)
        .collect();
    let predict1 = |v: f64| {
        m.predict(&[v])
            .ok()
            .and_then(|b| b.first().copied())
            .unwrap_or(0)
    };
    let bands: Vec<usize> = grid.iter().map(|&g| predict1(g)).collect();
    let mut out = Vec::new();
    for i in 1..grid.len() {
        if bands[i] != bands[i - 1] {
            let (mut a, mut b) = (grid[i - 1], grid[i]);
            let ba = bands[i - 1];
            for _ in 0..60 {
                let mid = 0.5 * (a + b);
                if predict1(mid) == ba {
                    a = mid;
                } else {
                    b = mid;
                }
            }
            out.push(0.5 * (a + b));
        }
    }
    out
}

#[allow(unused_imports)]
use {contingency as _, correlation as _, describe as _, effect as _, icc as _, rank as _};
