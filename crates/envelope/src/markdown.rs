//! `envelope.md`: the paper's tables and every statistic, human-readable.
//!
//! Output is deterministic for a given [`Envelope`]: fixed float precision, sorted keys.

use std::fmt::Write;

use crate::model::*;

fn f(x: f64, prec: usize) -> String {
    format!("{x:.prec$}")
}

fn of(x: Option<f64>, prec: usize) -> String {
    x.map_or("—".into(), |v| f(v, prec))
}

fn pct(x: Option<f64>) -> String {
    x.map_or("—".into(), |v| format!("{:.1}%", 100.0 * v))
}

fn lvl(x: Option<f64>) -> String {
    x.map_or("none".into(), |v| format!("{v}"))
}

fn pval(p: f64) -> String {
    if p == 0.0 {
        "< 1e-300".into()
    } else if p < 1e-3 {
        format!("{p:.2e}")
    } else {
        format!("{p:.4}")
    }
}

fn threshold_cell(t: &Threshold) -> String {
    format!(
        "≤ {}{}{}",
        lvl(t.sigma_star),
        if t.right_censored { "⁺" } else { "" },
        if t.pilot { "*" } else { "" }
    )
}

fn ci(c: Option<[Option<f64>; 2]>) -> String {
    c.map_or("—".into(), |[lo, hi]| {
        format!("[{}, {}]", lvl(lo), lvl(hi))
    })
}

/// Renders the whole envelope as Markdown.
pub fn render(e: &Envelope) -> String {
    let mut s = String::new();
    let p = &e.parameters;
    let hb = p.headline_budget;
    let odd_axis = e
        .odd
        .first()
        .map_or_else(|| e.axes[0].axis.clone(), |o| o.axis.clone());
    let _ = writeln!(s, "# Safety envelope\n");
    let _ = writeln!(
        s,
        "Input `{}` ({} rows, sha256 `{}`); {} clips, {} pairs, {} with a changed CoC ({:.1}%). \
         Headline budget {:.0}% on axis `{}`, rule `{}`, {} bootstrap resamples, seed {}.\n",
        e.input.path,
        e.corpus.n_pairs,
        if e.input.sha256.is_empty() {
            "—"
        } else {
            &e.input.sha256
        },
        e.corpus.n_clips,
        e.corpus.n_pairs,
        e.corpus.n_changed,
        100.0 * e.corpus.n_changed as f64 / e.corpus.n_pairs as f64,
        100.0 * hb,
        odd_axis,
        p.rule.name(),
        p.bootstrap,
        p.seed
    );
    if !e.notes.is_empty() {
        let _ = writeln!(s, "**Notes**\n");
        for n in &e.notes {
            let _ = writeln!(s, "- {n}");
        }
        let _ = writeln!(s);
    }

    // Table 1
    let _ = writeln!(s, "## Table 1 — scenario distribution\n");
    let _ = writeln!(
        s,
        "| Scenario | n clips | Rank | Clean ADE (m) | CoC flip rate | Changed pairs |"
    );
    let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|");
    for sc in &e.corpus.scenarios {
        let _ = writeln!(
            s,
            "| {}{} | {} | {} | {} | {} | {} |",
            sc.scenario,
            if sc.pilot { "*" } else { "" },
            sc.n_clips,
            sc.rank.map_or("—".into(), |r| r.to_string()),
            f(sc.clean_ade_mean_m, 2),
            pct(Some(sc.flip_rate)),
            sc.n_changed
        );
    }
    let _ = writeln!(
        s,
        "\n\\* pilot (fewer than {} clips). Unclassified labels are kept in aggregates only.\n",
        p.min_clips
    );

    // Table 2
    let _ = writeln!(
        s,
        "## Table 2 — per-scenario thresholds ({:.0}% ADE budget, `{}`)\n",
        100.0 * hb,
        odd_axis
    );
    let _ = writeln!(
        s,
        "| Scenario | n | Max level | 95% CI | vs. aggregate | share of resamples at point |"
    );
    let _ = writeln!(s, "|---|---:|---:|---:|---|---:|");
    for t in e
        .thresholds
        .iter()
        .filter(|t| t.axis == odd_axis && t.budget == hb)
    {
        let key = t.sigma_star.map_or("none".into(), |v| format!("{v}"));
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} |",
            t.scenario,
            t.n_clips,
            threshold_cell(t),
            ci(t.ci95),
            t.vs_aggregate.map_or("—".into(), |v| format!("{v:?}")),
            pct(t.bootstrap_share.get(&key).copied())
        );
    }
    let _ = writeln!(
        s,
        "\n⁺ right-censored (no tested level fails); \\* pilot; `none`: the smallest level already fails.\n"
    );

    // Budgets and families
    let _ = writeln!(s, "### Thresholds at every budget (`{odd_axis}`)\n");
    let groups: Vec<String> = {
        let mut g: Vec<String> = Vec::new();
        for t in &e.thresholds {
            if !g.contains(&t.scenario) {
                g.push(t.scenario.clone());
            }
        }
        g
    };
    let _ = write!(s, "| Scenario |");
    for b in &p.budgets {
        let _ = write!(s, " {:.0}% |", 100.0 * b);
    }
    let _ = writeln!(s, "\n|---|{}", "---:|".repeat(p.budgets.len()));
    for g in &groups {
        let _ = write!(s, "| {g} |");
        for b in &p.budgets {
            let cell = e
                .thresholds
                .iter()
                .find(|t| &t.scenario == g && t.axis == odd_axis && t.budget == *b)
                .map_or("—".into(), threshold_cell);
            let _ = write!(s, " {cell} |");
        }
        let _ = writeln!(s);
    }
    let _ = writeln!(
        s,
        "\n### Thresholds per family ({:.0}% budget)\n",
        100.0 * hb
    );
    let _ = write!(s, "| Scenario |");
    for a in &e.axes {
        let _ = write!(
            s,
            " {} ({}) |",
            a.axis,
            a.levels
                .iter()
                .map(|l| format!("{l}"))
                .collect::<Vec<_>>()
                .join("/")
        );
    }
    let _ = writeln!(s, "\n|---|{}", "---:|".repeat(e.axes.len()));
    for g in &groups {
        let _ = write!(s, "| {g} |");
        for a in &e.axes {
            let cell = e
                .thresholds
                .iter()
                .find(|t| &t.scenario == g && t.axis == a.axis && t.budget == hb)
                .map_or("—".into(), |t| {
                    format!("{} {}", threshold_cell(t), ci(t.ci95))
                });
            let _ = write!(s, " {cell} |");
        }
        let _ = writeln!(s);
    }

    // Dose-response
    let _ = writeln!(s, "\n## Dose-response (mean ADE per level)\n");
    for a in &e.axes {
        let _ = writeln!(s, "### `{}`\n", a.axis);
        let _ = writeln!(
            s,
            "| Scenario | Level | n | ADE clean (m) | ADE perturbed (m) | ΔADE (m) | ΔADE 95% CI | ratio |"
        );
        let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|---:|---:|");
        for d in e.dose_response.iter().filter(|d| d.axis == a.axis) {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {} | {} | {} |",
                d.scenario,
                d.level,
                d.n_pairs,
                f(d.mean_ade_clean_m, 3),
                f(d.mean_ade_attacked_m, 3),
                f(d.delta_ade_m, 3),
                d.delta_ade_ci95_m.map_or("—".into(), |[lo, hi]| format!(
                    "[{}, {}]",
                    f(lo, 3),
                    f(hi, 3)
                )),
                of(d.ratio, 3)
            );
        }
        let _ = writeln!(s);
    }

    // ΔADE map
    let _ = writeln!(s, "## Scenario × condition ΔADE (m)\n");
    let conds: Vec<String> = e.corpus.conditions.iter().map(|c| c.name.clone()).collect();
    let _ = writeln!(s, "| Scenario | {} |", conds.join(" | "));
    let _ = writeln!(s, "|---|{}", "---:|".repeat(conds.len()));
    let mut rows: Vec<String> = Vec::new();
    for c in &e.delta_ade_map {
        if !rows.contains(&c.scenario) {
            rows.push(c.scenario.clone());
        }
    }
    for r in &rows {
        let _ = write!(s, "| {r} |");
        for c in &conds {
            let v = e
                .delta_ade_map
                .iter()
                .find(|m| &m.scenario == r && &m.condition == c);
            let _ = write!(
                s,
                " {} |",
                v.map_or("—".into(), |m| format!("{:+.3}", m.delta_ade_m))
            );
        }
        let _ = writeln!(s);
    }

    // Severity
    let sv = &e.severity;
    let _ = writeln!(
        s,
        "\n## Table 3 — severity bands (changed-CoC pairs, n = {})\n",
        sv.n_changed
    );
    if !sv.defined {
        let _ = writeln!(s, "Undefined: {}.\n", sv.reason.clone().unwrap_or_default());
    } else {
        let _ = writeln!(
            s,
            "Chosen k = {} ({}).\n",
            sv.chosen_k.map_or("—".into(), |k| k.to_string()),
            sv.bands_mode
        );
        let _ = writeln!(s, "| Band | Mean L2 (m) | Std (m) | Weight | Share | n |");
        let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|");
        for b in &sv.bands {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {} |",
                b.name,
                f(b.mean_m, 2),
                f(b.std_m, 2),
                f(b.weight, 4),
                pct(Some(b.share)),
                b.n
            );
        }
        if !sv.boundaries_m.is_empty() {
            let _ = writeln!(
                s,
                "\nBand boundaries (m): {}.",
                sv.boundaries_m
                    .iter()
                    .map(|b| f(*b, 2))
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        }
        let _ = writeln!(s, "\n### BIC over k\n");
        let _ = writeln!(
            s,
            "| k | min BIC | seeds choosing k | gain from k−1 | gain ratio k / k+1 |"
        );
        let _ = writeln!(s, "|---:|---:|---:|---:|---:|");
        for r in &sv.bic {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} |",
                r.k,
                f(r.min, 1),
                r.chosen_count,
                of(r.gain, 1),
                of(r.gain_ratio, 2)
            );
        }
        if !sv.cv_loglik.is_empty() {
            let _ = writeln!(s, "\n### Cross-validated held-out log-likelihood\n");
            let _ = writeln!(s, "| k | mean | folds beating k−1 | per fold |");
            let _ = writeln!(s, "|---:|---:|---:|---|");
            for r in &sv.cv_loglik {
                let _ = writeln!(
                    s,
                    "| {} | {} | {} | {} |",
                    r.k,
                    f(r.mean, 4),
                    r.folds_beating_previous,
                    r.folds
                        .iter()
                        .map(|v| f(*v, 4))
                        .collect::<Vec<_>>()
                        .join(", ")
                );
            }
        }
        let _ = writeln!(s, "\n### Per-scenario mixtures\n");
        let _ = writeln!(s, "| Scenario | changed pairs | BIC-optimal k |");
        let _ = writeln!(s, "|---|---:|---:|");
        for m in &sv.per_scenario {
            let _ = writeln!(
                s,
                "| {} | {} | {} |",
                m.scenario,
                m.n_changed,
                m.chosen_k.map_or_else(
                    || format!("— ({})", m.reason.clone().unwrap_or_default()),
                    |k| k.to_string()
                )
            );
        }
    }

    // High severity
    let hs = &e.high_severity;
    let hb_names = if hs.bands.is_empty() {
        "—".to_string()
    } else {
        hs.bands.join("/")
    };
    let _ = writeln!(s, "\n## High-severity share ({hb_names})\n");
    for (title, rows) in [
        ("Scenario", &hs.by_scenario),
        ("Condition", &hs.by_condition),
    ] {
        let _ = writeln!(
            s,
            "| {title} | changed pairs | high | P(high) | mean L2 changed (m) |"
        );
        let _ = writeln!(s, "|---|---:|---:|---:|---:|");
        for r in rows {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} |",
                r.group,
                r.n_changed,
                r.n_high,
                pct(r.share),
                of(r.mean_l2_changed_m, 2)
            );
        }
        let _ = writeln!(s);
    }

    // Joint
    let _ = writeln!(s, "## Joint scenario × band (row %)\n");
    if e.joint.bands.is_empty() {
        let _ = writeln!(s, "Undefined: no severity bands.\n");
    } else {
        let _ = writeln!(s, "| Scenario | {} | n |", e.joint.bands.join(" | "));
        let _ = writeln!(s, "|---|{}---:|", "---:|".repeat(e.joint.bands.len()));
        for (i, sc) in e.joint.scenarios.iter().enumerate() {
            let n: usize = e.joint.counts[i].iter().sum();
            let cells: Vec<String> = e.joint.row_shares[i]
                .iter()
                .map(|v| format!("{:.1}", 100.0 * v))
                .collect();
            let _ = writeln!(s, "| {sc} | {} | {n} |", cells.join(" | "));
        }
        let _ = writeln!(s);
    }

    // Table 4
    let _ = writeln!(s, "## Table 4 — two-dimensional ODD entry\n");
    let _ = writeln!(
        s,
        "| Scenario | n changed | σ* | 95% CI | P(high) | Quadrant | Accepted |"
    );
    let _ = writeln!(s, "|---|---:|---:|---:|---:|---|---|");
    for o in &e.odd {
        let _ = writeln!(
            s,
            "| {}{} | {} | ≤ {}{} | {} | {} | {} | {} |",
            o.scenario,
            if o.pilot { "*" } else { "" },
            o.n_changed,
            lvl(o.sigma_star),
            if o.right_censored { "⁺" } else { "" },
            ci(o.ci95),
            pct(o.p_high),
            o.quadrant,
            match (o.accepted, &o.acceptance_reason) {
                (None, _) => "— (no π*)".to_string(),
                (Some(a), Some(r)) => format!("{} — {r}", if a { "yes" } else { "no" }),
                (Some(a), None) => (if a { "yes" } else { "no" }).to_string(),
            }
        );
    }

    // Statistics
    let st = &e.statistics;
    let _ = writeln!(s, "\n## Statistics\n");
    let _ = writeln!(s, "| Statistic | Value |");
    let _ = writeln!(s, "|---|---|");
    let mut row = |k: &str, v: String| {
        let _ = writeln!(s, "| {k} | {v} |");
    };
    row(
        "pairs / changed",
        format!(
            "{} / {} ({:.1}%)",
            st.n_pairs,
            st.n_changed,
            100.0 * st.change_rate
        ),
    );
    row(
        "point-biserial r (coc_changed vs L2)",
        match (st.point_biserial_r, st.point_biserial_p) {
            (Some(r), Some(p)) => format!("{} (p = {})", f(r, 4), pval(p)),
            _ => "—".into(),
        },
    );
    row("Cohen's d (L2, changed vs unchanged)", of(st.cohens_d, 4));
    row(
        "mean L2 changed / unchanged (m)",
        format!(
            "{} / {} (ratio {})",
            of(st.mean_l2_changed_m, 3),
            of(st.mean_l2_unchanged_m, 3),
            of(st.l2_ratio, 3)
        ),
    );
    row(
        "per-condition change rate vs mean L2 (Pearson)",
        st.change_rate_vs_l2.map_or("—".into(), |c| {
            format!("{} (p = {}, n = {})", f(c.r, 4), pval(c.p_value), c.n)
        }),
    );
    row(
        "Jaccard vs L2 on changed pairs",
        st.jaccard_l2.map_or("—".into(), |[a, b]| {
            format!(
                "Pearson {} (p = {}), Spearman {} (p = {})",
                f(a.r, 4),
                pval(a.p_value),
                f(b.r, 4),
                pval(b.p_value)
            )
        }),
    );
    let semantic = |c: Option<[crate::model::Corr; 2]>| {
        c.map_or("—".into(), |[a, b]| {
            format!(
                "Pearson {} (p = {}), Spearman {} (p = {}), n = {}",
                f(a.r, 4),
                pval(a.p_value),
                f(b.r, 4),
                pval(b.p_value),
                a.n
            )
        })
    };
    row(
        "semantic similarity (MiniLM cosine) vs L2 on changed pairs",
        semantic(st.cosine_l2),
    );
    row(
        "semantic similarity vs L2, mid-range Jaccard only",
        semantic(st.cosine_l2_mid_jaccard),
    );
    row(
        "Mann–Whitney U: complete rewrites vs mid-range edits",
        st.mwu.as_ref().map_or("—".into(), |m| {
            format!(
                "U = {}, z = {}, p = {}, d = {}, n = {} vs {}, power(d = {}) = {}",
                f(m.u, 1),
                f(m.z, 3),
                pval(m.p_value),
                f(m.cohens_d, 4),
                m.n_low,
                m.n_mid,
                m.power_effect_size,
                f(m.power, 4)
            )
        }),
    );
    row(
        "bimodality coefficient (L2, changed)",
        of(st.bimodality_coefficient, 4),
    );
    row(
        "χ² scenario × band",
        st.chi2.as_ref().map_or("—".into(), |c| {
            format!(
                "χ²({}) = {} (p = {})",
                c.dof,
                f(c.statistic, 2),
                pval(c.p_value)
            )
        }),
    );
    row("Cramér's V", of(st.cramers_v, 4));
    row(
        "ICC(2,1) / ICC(3,1) of flip flags",
        st.icc.as_ref().map_or("—".into(), |i| {
            format!(
                "{} / {} ({} clips × {} conditions)",
                f(i.icc2_1, 4),
                f(i.icc3_1, 4),
                i.n_clips,
                i.n_conditions
            )
        }),
    );
    row(
        "never-flip / always-flip clips",
        format!(
            "{} / {}",
            pct(Some(st.never_flip_share)),
            pct(Some(st.always_flip_share))
        ),
    );
    for (k, v) in &st.undefined {
        row(&format!("{k} (undefined)"), v.clone());
    }

    // Transitions
    let tr = &e.transitions;
    let _ = writeln!(
        s,
        "\n## Action transitions (changed pairs, classified scenarios, n = {})\n",
        tr.n
    );
    let _ = writeln!(
        s,
        "Rows: action of the clean CoC; columns: of the perturbed CoC. Diagonal share overall: {}.\n",
        pct(tr.diagonal_share)
    );
    let used: Vec<usize> = (0..tr.labels.len())
        .filter(|&i| tr.counts[i].iter().sum::<usize>() > 0 || tr.counts.iter().any(|r| r[i] > 0))
        .collect();
    let _ = writeln!(
        s,
        "| clean \\ perturbed | {} | diagonal |",
        used.iter()
            .map(|&i| tr.labels[i].as_str())
            .collect::<Vec<_>>()
            .join(" | ")
    );
    let _ = writeln!(s, "|---|{}---:|", "---:|".repeat(used.len()));
    for &i in &used {
        let cells: Vec<String> = used.iter().map(|&j| tr.counts[i][j].to_string()).collect();
        let _ = writeln!(
            s,
            "| {} | {} | {} |",
            tr.labels[i],
            cells.join(" | "),
            pct(tr.by_action[i].diagonal_share)
        );
    }

    // Table 5
    let a = &e.assurance;
    let _ = writeln!(s, "\n## Table 5 — ISO 21448 assurance mapping\n");
    let _ = writeln!(s, "| Node | Clause | Content |");
    let _ = writeln!(s, "|---|---|---|");
    let _ = writeln!(s, "| Goal | — | {} |", a.goal);
    let _ = writeln!(s, "| Strategy | — | {} |", a.strategy);
    for n in &a.nodes {
        let _ = writeln!(s, "| {} | {} | {} |", n.id, n.clause, n.text);
    }
    let _ = writeln!(
        s,
        "\n### A1 — budget sensitivity (±{:.0}%)\n",
        100.0 * p.budget_sensitivity
    );
    let _ = writeln!(
        s,
        "| Scenario | σ* at {:.2}% | σ* at {:.0}% | σ* at {:.2}% | stable |",
        100.0 * hb * (1.0 - p.budget_sensitivity),
        100.0 * hb,
        100.0 * hb * (1.0 + p.budget_sensitivity)
    );
    let _ = writeln!(s, "|---|---:|---:|---:|---|");
    for x in &a.budget_sensitivity {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} |",
            x.scenario,
            lvl(x.sigma_star_low),
            lvl(x.sigma_star),
            lvl(x.sigma_star_high),
            if x.stable { "yes" } else { "no" }
        );
    }

    // Parameters and conventions
    let _ = writeln!(s, "\n## Parameters and conventions\n");
    let _ = writeln!(
        s,
        "budgets {:?} (headline {}), rule {}, bootstrap {}, seed {}, k_max {}, restarts {}, n_init {}, cv folds {}, bands {:?}, high bands {}, π* {}, σ_op {}, min clips {}, L2: {}.\n",
        p.budgets,
        hb,
        p.rule.name(),
        p.bootstrap,
        p.seed,
        p.k_max,
        p.restarts,
        p.n_init,
        p.cv_folds,
        p.bands,
        p.high_bands,
        p.pi_star.map_or("off".into(), |v| v.to_string()),
        p.sigma_op.map_or("aggregate σ*".into(), |v| v.to_string()),
        p.min_clips,
        p.l2_aggregation
    );
    for (k, v) in &e.conventions {
        let _ = writeln!(s, "- **{k}**: {v}");
    }
    s
}
