//! The tables: the paper's tables 1–5, the data behind the figures, the statistics, the
//! run's parameters and every convention. Each returns an HTML fragment.

use std::fmt::Write as _;

use fogline_envelope::model::Threshold;

use crate::ctx::{AGG_ALL, Ctx};
use crate::draw::{esc, fixed, level, olevel, opct, pct, pval, sval, val};

/// A table builder: header cells, then rows of already-escaped cells.
pub(crate) struct Table {
    s: String,
}

impl Table {
    pub(crate) fn new(id: &str, caption: &str, head: &[&str], numeric: &[bool]) -> Self {
        let mut s = String::new();
        let _ = writeln!(s, "<div class=\"table-wrap\"><table id=\"{id}\">");
        let _ = writeln!(s, "<caption>{caption}</caption>");
        s.push_str("<thead><tr>");
        for (i, h) in head.iter().enumerate() {
            let cls = if numeric.get(i).copied().unwrap_or(false) {
                " class=\"num\""
            } else {
                ""
            };
            let _ = write!(s, "<th scope=\"col\"{cls}>{h}</th>");
        }
        s.push_str("</tr></thead>\n<tbody>\n");
        Self { s }
    }

    pub(crate) fn row(&mut self, cells: &[String], numeric: &[bool]) {
        self.s.push_str("<tr>");
        for (i, c) in cells.iter().enumerate() {
            if i == 0 {
                let _ = write!(self.s, "<th scope=\"row\">{c}</th>");
            } else {
                let cls = if numeric.get(i).copied().unwrap_or(false) {
                    " class=\"num\""
                } else {
                    ""
                };
                let _ = write!(self.s, "<td{cls}>{c}</td>");
            }
        }
        self.s.push_str("</tr>\n");
    }

    pub(crate) fn finish(mut self, foot: &str) -> String {
        self.s.push_str("</tbody>\n</table></div>\n");
        if !foot.is_empty() {
            let _ = writeln!(self.s, "<p class=\"foot\">{foot}</p>");
        }
        self.s
    }
}

fn threshold_cell(t: &Threshold) -> String {
    format!(
        "≤&nbsp;{}{}{}",
        esc(&olevel(t.sigma_star)),
        if t.right_censored {
            "<sup title=\"right-censored\">+</sup>"
        } else {
            ""
        },
        if t.pilot { "*" } else { "" }
    )
}

fn ci(c: Option<[Option<f64>; 2]>) -> String {
    c.map_or("—".into(), |[lo, hi]| {
        format!("[{}, {}]", olevel(lo), olevel(hi))
    })
}

fn yes_no(b: bool) -> String {
    if b { "yes".into() } else { "no".into() }
}

/// Table 1: scenario distribution.
pub(crate) fn table1(cx: &Ctx) -> String {
    let num = [false, true, true, true, true, true];
    let mut t = Table::new(
        "table-1",
        "<strong>Table 1.</strong> Scenario distribution, classified scenarios by complexity rank, then unclassified labels.",
        &[
            "Scenario",
            "n clips",
            "Rank",
            "Clean ADE (m)",
            "CoC flip rate",
            "Changed pairs",
        ],
        &num,
    );
    let mut rows: Vec<_> = cx.env.corpus.scenarios.iter().collect();
    rows.sort_by_key(|s| (s.rank.is_none(), s.rank.unwrap_or(0)));
    for s in rows {
        t.row(
            &[
                format!("{}{}", esc(&s.scenario), if s.pilot { "*" } else { "" }),
                s.n_clips.to_string(),
                s.rank.map_or("—".into(), |r| r.to_string()),
                val(s.clean_ade_mean_m),
                pct(s.flip_rate),
                s.n_changed.to_string(),
            ],
            &num,
        );
    }
    let c = &cx.env.corpus;
    t.row(
        &[
            "all".into(),
            c.n_clips.to_string(),
            String::new(),
            String::new(),
            if c.n_pairs > 0 {
                pct(c.n_changed as f64 / c.n_pairs as f64)
            } else {
                "—".into()
            },
            c.n_changed.to_string(),
        ],
        &num,
    );
    let mut foot = format!(
        "* pilot: fewer than {} clips. Unclassified labels (rank —) count in the aggregates only.",
        cx.env.parameters.min_clips
    );
    if c.n_incomplete_clips > 0 {
        let _ = write!(
            foot,
            " {} clip(s) lack some conditions.",
            c.n_incomplete_clips
        );
    }
    t.finish(&foot)
}

/// Table 2: per-scenario thresholds at the headline budget, plus every budget and family.
pub(crate) fn table2(cx: &Ctx) -> String {
    let Some(axis) = cx.axis.clone() else {
        return "<p class=\"note\">No thresholds: the envelope has no perturbation axis.</p>\n"
            .into();
    };
    let hb = cx.hb;
    let num = [false, true, true, true, false, true];
    let mut t = Table::new(
        "table-2",
        &format!(
            "<strong>Table 2.</strong> Per-scenario thresholds σ* on <code>{}</code> at the {}% ADE budget, with bootstrap 95% intervals.",
            esc(&axis),
            fixed(100.0 * hb, 0)
        ),
        &[
            "Scenario",
            "n clips",
            "Max level",
            "95% CI",
            "vs. aggregate",
            "Resamples at point",
        ],
        &num,
    );
    for th in cx
        .env
        .thresholds
        .iter()
        .filter(|t| t.axis == axis && t.budget == hb)
    {
        let key = th.sigma_star.map_or("none".into(), |v| format!("{v}"));
        t.row(
            &[
                esc(&Ctx::group_name(&th.scenario)),
                th.n_clips.to_string(),
                threshold_cell(th),
                ci(th.ci95),
                th.vs_aggregate.map_or("—".into(), |v| v.name().into()),
                opct(th.bootstrap_share.get(&key).copied()),
            ],
            &num,
        );
    }
    let mut s = t.finish(
        "<sup>+</sup> right-censored: no tested level fails, the true threshold may be higher. * pilot. \
         <em>none</em>: the smallest tested level already fails.",
    );
    // Every budget.
    let budgets: &[f64] = match cx.env.parameters.budgets.as_slice() {
        [] => &[hb],
        b => b,
    };
    let mut groups: Vec<&str> = Vec::new();
    for th in &cx.env.thresholds {
        if !groups.contains(&th.scenario.as_str()) {
            groups.push(&th.scenario);
        }
    }
    let heads: Vec<String> = std::iter::once("Scenario".to_string())
        .chain(budgets.iter().map(|b| format!("{}%", fixed(100.0 * b, 0))))
        .collect();
    let head_refs: Vec<&str> = heads.iter().map(String::as_str).collect();
    let num2: Vec<bool> = std::iter::once(false)
        .chain(budgets.iter().map(|_| true))
        .collect();
    let mut t = Table::new(
        "table-2-budgets",
        &format!(
            "<strong>Table 2b.</strong> Thresholds on <code>{}</code> at every budget.",
            esc(&axis)
        ),
        &head_refs,
        &num2,
    );
    for g in &groups {
        let mut cells = vec![esc(&Ctx::group_name(g))];
        for b in budgets {
            cells.push(
                cx.threshold(g, &axis, *b)
                    .map_or("—".into(), threshold_cell),
            );
        }
        t.row(&cells, &num2);
    }
    s.push_str(&t.finish(""));
    // Every family.
    let axes = &cx.env.axes;
    let heads: Vec<String> = std::iter::once("Scenario".to_string())
        .chain(axes.iter().map(|a| {
            format!(
                "{} ({})",
                esc(&a.axis),
                a.levels
                    .iter()
                    .map(|l| level(*l))
                    .collect::<Vec<_>>()
                    .join("/")
            )
        }))
        .collect();
    let head_refs: Vec<&str> = heads.iter().map(String::as_str).collect();
    let num3: Vec<bool> = std::iter::once(false)
        .chain(axes.iter().map(|_| true))
        .collect();
    let mut t = Table::new(
        "table-2-families",
        &format!(
            "<strong>Table 2c.</strong> Thresholds per perturbation family at the {}% budget, with 95% CI.",
            fixed(100.0 * hb, 0)
        ),
        &head_refs,
        &num3,
    );
    for g in &groups {
        let mut cells = vec![esc(&Ctx::group_name(g))];
        for a in axes {
            cells.push(cx.threshold(g, &a.axis, hb).map_or("—".into(), |t| {
                format!("{} {}", threshold_cell(t), ci(t.ci95))
            }));
        }
        t.row(&cells, &num3);
    }
    s.push_str(&t.finish(""));
    s
}

/// The dose-response points behind figure 1 (every axis).
pub(crate) fn dose_table(cx: &Ctx) -> String {
    let num = [false, true, true, true, true, true, true, true, false];
    let mut t = Table::new(
        "table-dose",
        "Dose-response: mean ADE per group, axis and level (the data of figure 1, every axis).",
        &[
            "Group",
            "Axis",
            "Level",
            "n pairs",
            "ADE clean (m)",
            "ADE perturbed (m)",
            "ΔADE (m)",
            "ΔADE 95% CI",
            "Within budget",
        ],
        &num,
    );
    for a in &cx.env.axes {
        let mut groups: Vec<&str> = Vec::new();
        for d in cx.env.dose_response.iter().filter(|d| d.axis == a.axis) {
            if !groups.contains(&d.scenario.as_str()) {
                groups.push(&d.scenario);
            }
        }
        for g in groups {
            for d in cx.dose(g, &a.axis) {
                t.row(
                    &[
                        esc(&Ctx::group_name(g)),
                        esc(&a.axis),
                        level(d.level),
                        d.n_pairs.to_string(),
                        val(d.mean_ade_clean_m),
                        val(d.mean_ade_attacked_m),
                        sval(d.delta_ade_m),
                        d.delta_ade_ci95_m
                            .map_or("—".into(), |[a, b]| format!("[{}, {}]", sval(a), sval(b))),
                        yes_no(cx.passes(d)),
                    ],
                    &num,
                );
            }
        }
    }
    t.finish(&format!(
        "Within budget: mean ADE perturbed &lt; (1 + {}) × mean ADE clean.",
        fixed(cx.hb, 2)
    ))
}

/// Table 3: severity bands, the BIC study, cross-validation and per-scenario mixtures.
pub(crate) fn table3(cx: &Ctx) -> String {
    let sv = &cx.env.severity;
    if !sv.defined {
        return format!(
            "<p class=\"note\" id=\"table-3\">Table 3 is empty: the severity mixture is undefined ({}).</p>\n",
            esc(sv.reason.as_deref().unwrap_or("no reason recorded"))
        );
    }
    let num = [false, true, true, true, true, true];
    let mut t = Table::new(
        "table-3",
        &format!(
            "<strong>Table 3.</strong> GMM severity bands on L2 of the {} changed-CoC pairs (k = {}, {}).",
            sv.n_changed,
            sv.chosen_k.map_or("—".into(), |k| k.to_string()),
            esc(&sv.bands_mode)
        ),
        &["Band", "Mean L2 (m)", "Std (m)", "Weight", "Share", "n"],
        &num,
    );
    for b in &sv.bands {
        t.row(
            &[
                esc(&b.name),
                val(b.mean_m),
                val(b.std_m),
                fixed(b.weight, 4),
                pct(b.share),
                b.n.to_string(),
            ],
            &num,
        );
    }
    let foot = if sv.boundaries_m.is_empty() {
        "No band boundaries (a single band).".to_string()
    } else {
        format!(
            "Band boundaries (m): {}. High-severity bands: {}.",
            sv.boundaries_m
                .iter()
                .map(|b| val(*b))
                .collect::<Vec<_>>()
                .join(", "),
            if cx.env.high_severity.bands.is_empty() {
                "none".into()
            } else {
                esc(&cx.env.high_severity.bands.join(", "))
            }
        )
    };
    let mut s = t.finish(&foot);
    if !sv.bic.is_empty() {
        let num = [true, true, true, true, true];
        let mut t = Table::new(
            "table-bic",
            "BIC over k: minimum over restart seeds, seeds choosing k, and the gains behind the choice.",
            &[
                "k",
                "min BIC",
                "Seeds choosing k",
                "Gain from k−1",
                "Gain ratio k / k+1",
            ],
            &num,
        );
        for r in &sv.bic {
            t.row(
                &[
                    r.k.to_string(),
                    fixed(r.min, 1),
                    r.chosen_count.to_string(),
                    r.gain.map_or("—".into(), |g| fixed(g, 1)),
                    r.gain_ratio.map_or("—".into(), |g| fixed(g, 2)),
                ],
                &num,
            );
        }
        s.push_str(&t.finish(""));
    }
    if !sv.cv_loglik.is_empty() {
        let num = [true, true, true, false];
        let mut t = Table::new(
            "table-cv",
            "Cross-validated held-out mean log-likelihood per k.",
            &["k", "Mean", "Folds beating k−1", "Per fold"],
            &num,
        );
        for r in &sv.cv_loglik {
            t.row(
                &[
                    r.k.to_string(),
                    fixed(r.mean, 4),
                    r.folds_beating_previous.to_string(),
                    r.folds
                        .iter()
                        .map(|v| fixed(*v, 4))
                        .collect::<Vec<_>>()
                        .join(", "),
                ],
                &num,
            );
        }
        s.push_str(&t.finish(""));
    }
    if !sv.per_scenario.is_empty() {
        let num = [false, true, true];
        let mut t = Table::new(
            "table-per-scenario-k",
            "Per-scenario mixtures: the BIC-optimal k within each scenario.",
            &["Scenario", "Changed pairs", "BIC-optimal k"],
            &num,
        );
        for m in &sv.per_scenario {
            t.row(
                &[
                    esc(&m.scenario),
                    m.n_changed.to_string(),
                    m.chosen_k.map_or_else(
                        || format!("— ({})", esc(m.reason.as_deref().unwrap_or("undefined"))),
                        |k| k.to_string(),
                    ),
                ],
                &num,
            );
        }
        s.push_str(&t.finish(""));
    }
    s
}

/// High-severity shares per scenario and per condition, and the joint table (figure 3's data).
pub(crate) fn high_tables(cx: &Ctx) -> String {
    let hs = &cx.env.high_severity;
    let hn = cx.high_name();
    let mut s = String::new();
    if hs.bands.is_empty() {
        s.push_str("<p class=\"note\">No high-severity bands: with fewer than two bands, P(high | changed) is undefined.</p>\n");
    }
    for (id, title, rows) in [
        ("table-high-scenario", "Scenario", &hs.by_scenario),
        ("table-high-condition", "Condition", &hs.by_condition),
    ] {
        let num = [false, true, true, true, true];
        let mut t = Table::new(
            id,
            &format!(
                "High-severity share P({} | changed) per {}.",
                esc(&hn),
                title.to_lowercase()
            ),
            &[
                title,
                "Changed pairs",
                "High",
                "P(high)",
                "Mean L2 changed (m)",
            ],
            &num,
        );
        for r in rows {
            t.row(
                &[
                    esc(&Ctx::group_name(&r.group)),
                    r.n_changed.to_string(),
                    r.n_high.to_string(),
                    opct(r.share),
                    r.mean_l2_changed_m.map_or("—".into(), val),
                ],
                &num,
            );
        }
        s.push_str(&t.finish(""));
    }
    let j = &cx.env.joint;
    if !j.bands.is_empty() {
        let heads: Vec<String> = std::iter::once("Scenario".to_string())
            .chain(j.bands.iter().map(|b| esc(b)))
            .chain(std::iter::once("n".to_string()))
            .collect();
        let head_refs: Vec<&str> = heads.iter().map(String::as_str).collect();
        let num: Vec<bool> = std::iter::once(false)
            .chain(j.bands.iter().map(|_| true))
            .chain(std::iter::once(true))
            .collect();
        let mut t = Table::new(
            "table-joint",
            "Joint scenario × band distribution of changed pairs (row %; the data of figure 3).",
            &head_refs,
            &num,
        );
        for (i, sc) in j.scenarios.iter().enumerate() {
            let n: usize = j.counts[i].iter().sum();
            let mut cells = vec![esc(sc)];
            for &cnt in &j.counts[i] {
                cells.push(if n > 0 {
                    fixed(100.0 * cnt as f64 / n as f64, 1)
                } else {
                    "—".into()
                });
            }
            cells.push(n.to_string());
            t.row(&cells, &num);
        }
        s.push_str(&t.finish("— : no changed pairs in this scenario."));
    }
    s
}

/// Table 4: the two-dimensional ODD entry.
pub(crate) fn table4(cx: &Ctx) -> String {
    if cx.env.odd.is_empty() {
        return "<p class=\"note\" id=\"table-4\">Table 4 is empty: no classified scenario has an ODD entry.</p>\n".into();
    }
    let num = [false, true, true, true, true, false, false];
    let hn = cx.high_name();
    let pi = cx.env.parameters.pi_star;
    let mut t = Table::new(
        "table-4",
        &format!(
            "<strong>Table 4.</strong> Two-dimensional ODD entry per scenario: σ* on <code>{}</code> at the {}% budget and P({} | changed){}.",
            esc(cx.axis.as_deref().unwrap_or("—")),
            fixed(100.0 * cx.hb, 0),
            esc(&hn),
            pi.map_or(String::new(), |p| format!(
                "; acceptance against π* = {}",
                pct(p)
            ))
        ),
        &[
            "Scenario",
            "n changed",
            "σ*",
            "95% CI",
            "P(high)",
            "Quadrant",
            "Accepted",
        ],
        &num,
    );
    for o in &cx.env.odd {
        let accepted = match (o.accepted, &o.acceptance_reason) {
            (None, _) => "— (no π*)".to_string(),
            (Some(a), Some(r)) => format!(
                "<span class=\"{}\">{}</span> — {}",
                if a { "ok" } else { "bad" },
                if a { "yes" } else { "no" },
                esc(r)
            ),
            (Some(a), None) => format!(
                "<span class=\"{}\">{}</span>",
                if a { "ok" } else { "bad" },
                if a { "yes" } else { "no" }
            ),
        };
        t.row(
            &[
                format!("{}{}", esc(&o.scenario), if o.pilot { "*" } else { "" }),
                o.n_changed.to_string(),
                format!(
                    "≤&nbsp;{}{}",
                    esc(&olevel(o.sigma_star)),
                    if o.right_censored { "<sup>+</sup>" } else { "" }
                ),
                ci(o.ci95),
                opct(o.p_high),
                esc(&o.quadrant),
                accepted,
            ],
            &num,
        );
    }
    t.finish(&format!(
        "Quadrant: threshold group (tight / match / loose against all clips) + severity group (mild: P(high) ≤ the corpus share{}; severe: ≥ {}× it; moderate between). * pilot.",
        cx.p_high_all().map_or(String::new(), |p| format!(" of {}", pct(p))),
        fixed(cx.severe_factor(), 1)
    ))
}

/// The statistics.
pub(crate) fn statistics(cx: &Ctx) -> String {
    let st = &cx.env.statistics;
    let num = [false, false];
    let mut t = Table::new(
        "table-statistics",
        "The statistics of the envelope paper, on this corpus.",
        &["Statistic", "Value"],
        &num,
    );
    let f4 = |x: Option<f64>| x.map_or("—".into(), |v| fixed(v, 4));
    let mut row = |k: &str, v: String| t.row(&[esc(k), v], &num);
    row(
        "pairs / changed",
        format!(
            "{} / {} ({})",
            st.n_pairs,
            st.n_changed,
            pct(st.change_rate)
        ),
    );
    row(
        "point-biserial r (coc_changed vs L2)",
        match (st.point_biserial_r, st.point_biserial_p) {
            (Some(r), Some(p)) => format!("{} (p = {})", fixed(r, 4), esc(&pval(p))),
            _ => "—".into(),
        },
    );
    row("Cohen's d (L2, changed vs unchanged)", f4(st.cohens_d));
    row(
        "mean L2 changed / unchanged (m)",
        format!(
            "{} / {} (ratio {})",
            st.mean_l2_changed_m.map_or("—".into(), val),
            st.mean_l2_unchanged_m.map_or("—".into(), val),
            st.l2_ratio.map_or("—".into(), |v| fixed(v, 2))
        ),
    );
    row(
        "per-condition change rate vs mean L2 (Pearson)",
        st.change_rate_vs_l2.map_or("—".into(), |c| {
            format!(
                "{} (p = {}, n = {})",
                fixed(c.r, 4),
                esc(&pval(c.p_value)),
                c.n
            )
        }),
    );
    row(
        "Jaccard vs L2 on changed pairs",
        st.jaccard_l2.map_or("—".into(), |[a, b]| {
            format!(
                "Pearson {} (p = {}), Spearman {} (p = {})",
                fixed(a.r, 4),
                esc(&pval(a.p_value)),
                fixed(b.r, 4),
                esc(&pval(b.p_value))
            )
        }),
    );
    // The same check with the semantic similarity (coc_cosine); absent, the reason.
    let semantic = |c: Option<[fogline_envelope::model::Corr; 2]>, key: &str| match c {
        Some([a, b]) => format!(
            "Pearson {} (p = {}), Spearman {} (p = {}), n = {}",
            fixed(a.r, 4),
            esc(&pval(a.p_value)),
            fixed(b.r, 4),
            esc(&pval(b.p_value)),
            a.n
        ),
        None => st
            .undefined
            .get(key)
            .map_or("—".into(), |why| format!("— ({})", esc(why))),
    };
    row(
        "semantic similarity (all-MiniLM-L6-v2 cosine) vs L2 on changed pairs",
        semantic(st.cosine_l2, "cosine_l2"),
    );
    row(
        "semantic similarity vs L2, mid-range Jaccard only",
        semantic(st.cosine_l2_mid_jaccard, "cosine_l2_mid_jaccard"),
    );
    row(
        "Mann–Whitney U: complete rewrites vs mid-range edits",
        st.mwu.as_ref().map_or("—".into(), |m| {
            format!(
                "U = {}, z = {}, p = {}, d = {}, n = {} vs {}, power(d = {}) = {}",
                fixed(m.u, 1),
                fixed(m.z, 3),
                esc(&pval(m.p_value)),
                fixed(m.cohens_d, 4),
                m.n_low,
                m.n_mid,
                m.power_effect_size,
                fixed(m.power, 4)
            )
        }),
    );
    row(
        "bimodality coefficient (L2, changed; > 0.555 suggests bimodality)",
        f4(st.bimodality_coefficient),
    );
    row(
        "χ² scenario × band",
        st.chi2.as_ref().map_or("—".into(), |c| {
            format!(
                "χ²({}) = {} (p = {})",
                c.dof,
                fixed(c.statistic, 2),
                esc(&pval(c.p_value))
            )
        }),
    );
    row("Cramér's V", f4(st.cramers_v));
    row(
        "ICC(2,1) / ICC(3,1) of flip flags",
        st.icc.as_ref().map_or("—".into(), |i| {
            format!(
                "{} / {} ({} clips × {} conditions)",
                fixed(i.icc2_1, 4),
                fixed(i.icc3_1, 4),
                i.n_clips,
                i.n_conditions
            )
        }),
    );
    row(
        "never-flip / always-flip clips",
        format!(
            "{} / {}",
            pct(st.never_flip_share),
            pct(st.always_flip_share)
        ),
    );
    row(
        "action kept by changed CoC (transition diagonal)",
        format!(
            "{} of {} pairs",
            opct(cx.env.transitions.diagonal_share),
            cx.env.transitions.n
        ),
    );
    for (k, v) in &st.undefined {
        row(&format!("{k} (undefined)"), esc(v));
    }
    t.finish("— : undefined for this corpus (the reason is listed as “undefined”).")
}

/// Table 5: the ISO 21448 assurance mapping and the A1 budget-sensitivity check.
pub(crate) fn table5(cx: &Ctx) -> String {
    let a = &cx.env.assurance;
    let num = [false, false, false];
    let mut t = Table::new(
        "table-5",
        "<strong>Table 5.</strong> ISO 21448 assurance mapping of the two-dimensional ODD entry, filled from this corpus.",
        &["Node", "Clause", "Content"],
        &num,
    );
    t.row(&["Goal".into(), "—".into(), esc(&a.goal)], &num);
    t.row(&["Strategy".into(), "—".into(), esc(&a.strategy)], &num);
    for n in &a.nodes {
        t.row(&[esc(&n.id), esc(&n.clause), esc(&n.text)], &num);
    }
    let mut s = t.finish("");
    if !a.budget_sensitivity.is_empty() {
        let sens = cx.env.parameters.budget_sensitivity;
        let hb = cx.hb;
        let h1 = format!("σ* at {}%", fixed(100.0 * hb * (1.0 - sens), 2));
        let h2 = format!("σ* at {}%", fixed(100.0 * hb, 0));
        let h3 = format!("σ* at {}%", fixed(100.0 * hb * (1.0 + sens), 2));
        let num = [false, true, true, true, false];
        let mut t = Table::new(
            "table-5-a1",
            &format!(
                "Assumption A1: thresholds under a ±{}% change of the budget.",
                fixed(100.0 * sens, 0)
            ),
            &["Group", &h1, &h2, &h3, "Stable"],
            &num,
        );
        for x in &a.budget_sensitivity {
            t.row(
                &[
                    esc(&Ctx::group_name(&x.scenario)),
                    olevel(x.sigma_star_low),
                    olevel(x.sigma_star),
                    olevel(x.sigma_star_high),
                    yes_no(x.stable),
                ],
                &num,
            );
        }
        s.push_str(&t.finish(""));
    }
    s
}

/// The run: input and checksum, producer, every parameter.
pub(crate) fn parameters(cx: &Ctx) -> String {
    let d = cx.env;
    let num = [false, false];
    let mut t = Table::new(
        "table-input",
        "The input analysed and the tool that analysed it.",
        &["Item", "Value"],
        &num,
    );
    t.row(
        &[
            "pairs table".into(),
            format!(
                "<code>{}</code> ({})",
                esc(&d.input.path),
                esc(d.input.format.name())
            ),
        ],
        &num,
    );
    t.row(
        &[
            "SHA-256 of its bytes".into(),
            if d.input.sha256.is_empty() {
                "— (in-memory table)".into()
            } else {
                format!("<code class=\"hash\">{}</code>", esc(&d.input.sha256))
            },
        ],
        &num,
    );
    t.row(&["rows read".into(), d.input.n_rows.to_string()], &num);
    t.row(&["generated by".into(), esc(&d.generated_by)], &num);
    t.row(
        &[
            "envelope schema version".into(),
            d.schema_version.to_string(),
        ],
        &num,
    );
    t.row(
        &["bootstrap resampling used".into(), esc(&d.bootstrap_method)],
        &num,
    );
    t.row(
        &[
            "report".into(),
            esc(&format!("fogline-report {}", env!("CARGO_PKG_VERSION"))),
        ],
        &num,
    );
    let mut s = t.finish("");
    let mut t = Table::new(
        "table-parameters",
        "Every parameter of the analysis, as recorded in envelope.json.",
        &["Parameter", "Value"],
        &num,
    );
    // Rendered generically from the parameters' JSON form, in key order.
    let params = match serde_json::to_value(&d.parameters) {
        Ok(serde_json::Value::Object(m)) => m,
        _ => serde_json::Map::new(),
    };
    for (k, v) in &params {
        let text = match v {
            serde_json::Value::String(s) => s.clone(),
            serde_json::Value::Null => "null (off / default)".into(),
            other => other.to_string(),
        };
        t.row(&[format!("<code>{}</code>", esc(k)), esc(&text)], &num);
    }
    s.push_str(&t.finish(""));
    s
}

/// Every convention.
pub(crate) fn conventions(cx: &Ctx) -> String {
    let mut s = String::from("<dl class=\"conventions\" id=\"conventions-list\">\n");
    for (k, v) in &cx.env.conventions {
        let _ = writeln!(s, "<dt><code>{}</code></dt><dd>{}</dd>", esc(k), esc(v));
    }
    s.push_str("</dl>\n");
    if cx.env.conventions.is_empty() {
        s = "<p class=\"note\">The envelope records no conventions.</p>\n".into();
    }
    s
}

/// The closed-loop table.
pub(crate) fn closed_loop(cx: &Ctx) -> String {
    let Some(cl) = cx.closed_loop else {
        return String::new();
    };
    let num = [false, true, true, true, true];
    let mut t = Table::new(
        "table-closed-loop",
        &format!(
            "Closed-loop scores per configuration ({}).",
            esc(&cl.source)
        ),
        &[
            "Configuration",
            "Routes",
            "Driving score",
            "Route completion (%)",
            "Infraction score",
        ],
        &num,
    );
    for r in &cl.configurations {
        t.row(
            &[
                esc(&r.configuration),
                r.n_routes.to_string(),
                fixed(r.driving_score, 1),
                fixed(r.route_completion, 1),
                fixed(r.infraction_score, 3),
            ],
            &num,
        );
    }
    t.finish("")
}

/// Whether the all-clips aggregate has a headline threshold.
pub(crate) fn has_aggregate(cx: &Ctx) -> bool {
    cx.headline(AGG_ALL).is_some()
}
