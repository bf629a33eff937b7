//! The plain-language summary at the top of the page.

use std::cmp::Ordering;

use fogline_envelope::model::VsAggregate;

use crate::ctx::{AGG_ALL, Ctx};
use crate::draw::{esc, fixed, level, olevel, opct, pct};

/// Ordinal comparison on the scale none < levels (levels ascending along the axis).
fn ord(a: Option<f64>, b: Option<f64>, levels: &[f64]) -> Ordering {
    let pos = |x: Option<f64>| {
        x.map_or(-1, |v| {
            levels.iter().position(|l| *l == v).map_or(-1, |p| p as i64)
        })
    };
    pos(a).cmp(&pos(b))
}

fn list(items: &[String]) -> String {
    items.join("; ")
}

/// The summary as an HTML list.
pub(crate) fn render(cx: &Ctx) -> String {
    let d = cx.env;
    let mut items: Vec<String> = Vec::new();
    let c = &d.corpus;
    items.push(format!(
        "<strong>Corpus.</strong> {} clips, {} (clip, condition) pairs under {} conditions; the explanation (CoC) changed in {} pairs ({}).",
        c.n_clips,
        c.n_pairs,
        c.conditions.len(),
        c.n_changed,
        if c.n_pairs > 0 { pct(c.n_changed as f64 / c.n_pairs as f64) } else { "—".into() }
    ));
    let axis = cx.axis.clone().unwrap_or_default();
    let levels: Vec<f64> = d
        .axes
        .iter()
        .find(|a| a.axis == axis)
        .map(|a| a.levels.clone())
        .unwrap_or_default();
    let budget = format!("{}% ADE budget", fixed(100.0 * cx.hb, 0));
    let agg = cx.headline(AGG_ALL);
    match agg {
        None => items.push(format!(
            "<strong>When.</strong> No aggregate threshold on <code>{}</code> was computed.",
            esc(&axis)
        )),
        Some(t) => {
            let what = match (t.sigma_star, t.right_censored) {
                (None, _) => format!(
                    "already exceeds the {budget} at the smallest tested level ({})",
                    levels.first().map_or("—".into(), |l| level(*l))
                ),
                (Some(v), true) => format!(
                    "stays within the {budget} at every tested level up to {} (right-censored)",
                    level(v)
                ),
                (Some(v), false) => format!(
                    "stays within the {budget} up to <code>{}</code> = {}",
                    esc(&axis),
                    level(v)
                ),
            };
            items.push(format!("<strong>When.</strong> All clips together {what}."));
        }
    }
    let mut looser = Vec::new();
    let mut tighter = Vec::new();
    let mut matches = Vec::new();
    let mut pilots = Vec::new();
    for sc in &cx.scenarios {
        let Some(t) = cx.headline(sc) else { continue };
        let pilot = if t.pilot { ", pilot" } else { "" };
        if t.pilot {
            pilots.push(esc(sc));
        }
        let cell = format!(
            "{} (≤ {}{}{pilot})",
            esc(sc),
            olevel(t.sigma_star),
            if t.right_censored { "+" } else { "" }
        );
        match t.vs_aggregate {
            Some(VsAggregate::Looser) => {
                let firm = match (t.ci95, agg) {
                    (Some([lo, _]), Some(a)) => ord(lo, a.sigma_star, &levels) == Ordering::Greater,
                    _ => false,
                };
                looser.push(format!(
                    "{cell}{}",
                    if t.ci95.is_none() {
                        ""
                    } else if firm {
                        " — its 95% CI stays above the aggregate"
                    } else {
                        " — its 95% CI reaches the aggregate's level"
                    }
                ));
            }
            Some(VsAggregate::Tighter) => tighter.push(cell),
            Some(VsAggregate::Matches) => matches.push(cell),
            None => {}
        }
    }
    if !looser.is_empty() {
        items.push(format!(
            "<strong>Looser than the aggregate</strong> (tolerate more): {}.",
            list(&looser)
        ));
    }
    if !tighter.is_empty() {
        items.push(format!(
            "<strong>Tighter than the aggregate</strong> (fail earlier): {}.",
            list(&tighter)
        ));
    }
    if !matches.is_empty() {
        items.push(format!(
            "<strong>Match the aggregate:</strong> {}.",
            list(&matches)
        ));
    }
    let all_censored = !cx.scenarios.is_empty()
        && cx
            .scenarios
            .iter()
            .all(|s| cx.headline(s).is_some_and(|t| t.right_censored))
        && agg.is_some_and(|t| t.right_censored);
    if all_censored {
        items.push(format!(
            "<strong>Every threshold is right-censored:</strong> no tested level breaks the {budget} for any scenario, so this corpus cannot say where the envelope ends; extend the grid beyond {}.",
            levels.last().map_or("—".into(), |l| level(*l))
        ));
    }
    if !pilots.is_empty() {
        items.push(format!(
            "<strong>Pilot estimates</strong> (fewer than {} clips; indicative only): {}.",
            d.parameters.min_clips,
            pilots.join(", ")
        ));
    }
    // Severity.
    let sv = &d.severity;
    let hn = cx.high_name();
    if !sv.defined {
        items.push(format!(
            "<strong>How severely.</strong> No severity bands could be fitted ({}).",
            esc(sv.reason.as_deref().unwrap_or("no reason recorded"))
        ));
    } else if d.high_severity.bands.is_empty() {
        items.push(format!(
            "<strong>How severely.</strong> The changed pairs' deviations form a single band (k = {}), so no failure can be singled out as high severity.",
            sv.chosen_k.map_or("—".into(), |k| k.to_string())
        ));
    } else {
        items.push(format!(
            "<strong>How severely.</strong> Changed pairs fall into {} severity bands; {} count as high severity and hold {} of all changed pairs.",
            sv.chosen_k.map_or("—".into(), |k| k.to_string()),
            esc(&hn),
            opct(cx.p_high_all())
        ));
        let pick = |group: &str| -> Vec<String> {
            d.odd
                .iter()
                .filter(|o| o.severity_group == group)
                .map(|o| {
                    format!(
                        "{} {}{}",
                        esc(&o.scenario),
                        opct(o.p_high),
                        if o.pilot { " (pilot)" } else { "" }
                    )
                })
                .collect()
        };
        let severe = pick("severe");
        if severe.is_empty() {
            items.push(format!(
                "<strong>Severe failures:</strong> no scenario reaches {}× the corpus share of {}.",
                fixed(cx.severe_factor(), 1),
                esc(&hn)
            ));
        } else {
            items.push(format!(
                "<strong>Failures are severe</strong> (P({} | changed) ≥ {}× the corpus share) in: {}.",
                esc(&hn),
                fixed(cx.severe_factor(), 1),
                list(&severe)
            ));
        }
        let undefined: Vec<String> = d
            .odd
            .iter()
            .filter(|o| o.p_high.is_none())
            .map(|o| esc(&o.scenario))
            .collect();
        if !undefined.is_empty() {
            items.push(format!(
                "<strong>No changed pairs</strong> (severity undefined): {}.",
                undefined.join(", ")
            ));
        }
        let loose_severe: Vec<String> = d
            .odd
            .iter()
            .filter(|o| o.threshold_group == "loose" && o.severity_group == "severe")
            .map(|o| esc(&o.scenario))
            .collect();
        if !loose_severe.is_empty() {
            items.push(format!(
                "<strong>Two dimensions matter:</strong> {} {} more than the aggregate yet {} severely when {} — a threshold alone would rate {} safe.",
                loose_severe.join(", "),
                if loose_severe.len() == 1 { "tolerates" } else { "tolerate" },
                if loose_severe.len() == 1 { "fails" } else { "fail" },
                if loose_severe.len() == 1 { "it fails" } else { "they fail" },
                if loose_severe.len() == 1 { "it" } else { "them" }
            ));
        }
    }
    // Acceptance.
    match d.parameters.pi_star {
        None => items.push(
            "<strong>Acceptance.</strong> No residual-risk budget π* was given, so no scenario was accepted or rejected (rerun the analysis with <code>--pi-star</code>).".into(),
        ),
        Some(pi) => {
            let sigma_op = d
                .parameters
                .sigma_op
                .map(level)
                .or_else(|| agg.map(|t| olevel(t.sigma_star)))
                .unwrap_or_else(|| "—".into());
            let pass: Vec<String> = d.odd.iter().filter(|o| o.accepted == Some(true)).map(|o| esc(&o.scenario)).collect();
            let fail: Vec<String> = d
                .odd
                .iter()
                .filter(|o| o.accepted == Some(false))
                .map(|o| format!("{}{}", esc(&o.scenario), o.acceptance_reason.as_deref().map_or(String::new(), |r| format!(" ({})", esc(r)))))
                .collect();
            items.push(format!(
                "<strong>Acceptance against π* = {}</strong> at σ_op = {}: pass — {}; fail — {}.",
                pct(pi),
                esc(&sigma_op),
                if pass.is_empty() { "none".into() } else { pass.join(", ") },
                if fail.is_empty() { "none".into() } else { list(&fail) }
            ));
        }
    }
    if !d.notes.is_empty() {
        items.push(format!(
            "<strong>{} note{} from the analysis</strong> are listed below.",
            d.notes.len(),
            if d.notes.len() == 1 { "" } else { "s" }
        ));
    }
    let mut s = String::from("<ul class=\"summary\">\n");
    for i in items {
        s.push_str("<li>");
        s.push_str(&i);
        s.push_str("</li>\n");
    }
    s.push_str("</ul>\n");
    s
}
