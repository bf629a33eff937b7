//! The ISO 21448 assurance mapping (table 5 of the envelope paper), filled from the numbers.

use crate::model::{Assurance, EvidenceNode, OddEntry, Sensitivity, Severity};
use crate::params::EnvelopeParams;

fn lvl(x: Option<f64>) -> String {
    x.map_or("none".into(), |v| format!("{v}"))
}

pub(crate) fn build(
    p: &EnvelopeParams,
    odd: &[OddEntry],
    severity: &Severity,
    sensitivity: &[Sensitivity],
    axis: &str,
    sigma_op: Option<f64>,
) -> Assurance {
    let b = p.headline_budget;
    let e1 = odd
        .iter()
        .map(|e| {
            let ci = e.ci95.map_or("no bootstrap".into(), |[lo, hi]| {
                format!("95% CI [{}, {}]", lvl(lo), lvl(hi))
            });
            format!(
                "{} ≤ {}{}{} ({ci})",
                e.scenario,
                lvl(e.sigma_star),
                if e.right_censored {
                    " (right-censored)"
                } else {
                    ""
                },
                if e.pilot { " [pilot]" } else { "" }
            )
        })
        .collect::<Vec<_>>()
        .join("; ");
    let e2 = if severity.defined {
        let per = odd
            .iter()
            .map(|e| {
                format!(
                    "{} {}",
                    e.scenario,
                    e.p_high
                        .map_or("undefined".into(), |v| format!("{:.1}%", 100.0 * v))
                )
            })
            .collect::<Vec<_>>()
            .join("; ");
        format!(
            "P(high | coc_changed) from a {}-band GMM on {} changed pairs: {per}",
            severity.bands.len(),
            severity.n_changed
        )
    } else {
        format!(
            "undefined: {}",
            severity
                .reason
                .clone()
                .unwrap_or_else(|| "no severity bands".into())
        )
    };
    let e3 = match p.pi_star {
        None => {
            "acceptance not evaluated: no residual-risk budget π* given (--pi-star)".to_string()
        }
        Some(pi) => {
            let acc: Vec<&str> = odd
                .iter()
                .filter(|e| e.accepted == Some(true))
                .map(|e| e.scenario.as_str())
                .collect();
            let rej: Vec<&str> = odd
                .iter()
                .filter(|e| e.accepted == Some(false))
                .map(|e| e.scenario.as_str())
                .collect();
            format!(
                "s passes iff σ_op ≤ σ*(s) and P(high | s) ≤ π* = {pi} at σ_op = {}: accepted {}; rejected {}",
                lvl(sigma_op),
                if acc.is_empty() {
                    "none".into()
                } else {
                    acc.join(", ")
                },
                if rej.is_empty() {
                    "none".into()
                } else {
                    rej.join(", ")
                }
            )
        }
    };
    let unstable: Vec<&str> = sensitivity
        .iter()
        .filter(|s| !s.stable)
        .map(|s| s.scenario.as_str())
        .collect();
    let a1 = format!(
        "the {:.0}% ADE budget is {} under ±{:.0}% sensitivity{}",
        100.0 * b,
        if unstable.is_empty() {
            "stable"
        } else {
            "not stable"
        },
        100.0 * p.budget_sensitivity,
        if unstable.is_empty() {
            String::new()
        } else {
            format!(" (thresholds move for {})", unstable.join(", "))
        }
    );
    Assurance {
        goal: format!(
            "For each scenario s, the planner's behaviour under {axis} perturbation is within the SOTIF ODD."
        ),
        strategy: "Argue over a two-dimensional envelope: a triggering-condition bound (Clause 7.3) paired with a residual-risk acceptance criterion (Clause 6.5).".into(),
        nodes: vec![
            EvidenceNode {
                id: "E1".into(),
                clause: "5.2, 7.3".into(),
                text: format!("per-scenario σ*(s) at the {:.0}% ADE budget with bootstrap 95% CI: {e1}", 100.0 * b),
            },
            EvidenceNode {
                id: "E2".into(),
                clause: "6.4".into(),
                text: e2,
            },
            EvidenceNode {
                id: "E3".into(),
                clause: "6.5, 12".into(),
                text: e3,
            },
            EvidenceNode {
                id: "A1".into(),
                clause: "assumption".into(),
                text: a1,
            },
            EvidenceNode {
                id: "A2".into(),
                clause: "assumption".into(),
                text: "the high-severity bands are a proxy for downstream severity pending a collision or rule-violation tie-in; choosing π* from a target societal risk level is out of scope".into(),
            },
        ],
        budget_sensitivity: sensitivity.to_vec(),
    }
}
