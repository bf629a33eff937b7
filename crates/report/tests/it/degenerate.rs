//! Degenerate inputs render honestly: an explanatory note, never a broken figure or NaN.

use fogline_envelope::{Bands, EnvelopeParams};
use fogline_report::{Report, ReportInput, ReportParams, render};

use crate::fixture::{edited, quick_params};

fn page(table: &fogline_envelope::PairTable, env: &fogline_envelope::Envelope) -> Report {
    let input = ReportInput::from_envelope(env)
        .unwrap()
        .with_pairs(table)
        .unwrap();
    let r = render(&input, &ReportParams::default()).unwrap();
    assert_sane(&r);
    r
}

fn assert_sane(r: &Report) {
    for needle in ["NaN", "Infinity", "inf%", "-0.0 ", ">-0<"] {
        assert!(!r.html.contains(needle), "the page contains {needle:?}");
    }
    for f in &r.figures {
        let html = &r.fragments.iter().find(|(k, _)| k == &f.id).unwrap().1;
        if f.drawn {
            assert!(
                html.contains("<svg ") && html.contains("role=\"img\""),
                "{}",
                f.id
            );
        } else {
            assert!(
                html.contains("Not drawn: ") && !html.contains("<svg "),
                "{}",
                f.id
            );
        }
    }
}

fn fragment<'a>(r: &'a Report, id: &str) -> &'a str {
    &r.fragments.iter().find(|(k, _)| k == id).unwrap().1
}

fn drawn(r: &Report, id: &str) -> bool {
    r.figures.iter().find(|f| f.id == id).unwrap().drawn
}

#[test]
fn a_scenario_without_changed_pairs() {
    let (table, env) = edited(120, &quick_params(), |sc, _, _, _, l2, clean, coc| {
        if sc == "TURN_RIGHT" {
            *coc = clean.to_string();
            *l2 = 1.0;
        }
    });
    let row = env
        .joint
        .scenarios
        .iter()
        .position(|s| s == "TURN_RIGHT")
        .unwrap();
    assert_eq!(env.joint.counts[row].iter().sum::<usize>(), 0);
    let r = page(&table, &env);
    assert!(drawn(&r, "fig-3"));
    let f3 = fragment(&r, "fig-3");
    assert!(f3.contains("no changed pairs"));
    assert!(f3.contains("TURN_RIGHT has no changed-CoC pairs: its severity profile"));
    let summary = fragment(&r, "summary");
    assert!(
        summary.contains("<strong>No changed pairs</strong> (severity undefined): TURN_RIGHT"),
        "{summary}"
    );
    assert!(fragment(&r, "table-high").contains("—"));
}

#[test]
fn a_single_band() {
    let params = EnvelopeParams {
        bands: Bands::Fixed(1),
        ..quick_params()
    };
    let (table, env) = edited(100, &params, |_, _, _, _, _, _, _| {});
    assert_eq!(env.severity.chosen_k, Some(1));
    let r = page(&table, &env);
    assert!(drawn(&r, "fig-2a"));
    assert!(fragment(&r, "fig-2a").contains("A single band"));
    assert!(drawn(&r, "fig-3"));
    assert!(fragment(&r, "fig-3").contains("P(high | changed) is undefined"));
    assert!(fragment(&r, "summary").contains("form a single band"));
    assert!(fragment(&r, "table-3").contains("No band boundaries"));
}

#[test]
fn all_thresholds_censored() {
    let (table, env) = edited(100, &quick_params(), |_, _, clean, attacked, _, _, _| {
        *attacked = *clean * 1.01;
    });
    assert!(env.thresholds.iter().all(|t| t.right_censored));
    let r = page(&table, &env);
    assert!(drawn(&r, "fig-1"));
    let f1 = fragment(&r, "fig-1");
    assert!(f1.contains("Every threshold is right-censored"));
    assert!(f1.contains("σ* ≥ 70 (censored)"));
    assert!(fragment(&r, "summary").contains("Every threshold is right-censored"));
    assert!(fragment(&r, "table-2").contains("<sup title=\"right-censored\">+</sup>"));
}

#[test]
fn every_level_fails() {
    let (table, env) = edited(100, &quick_params(), |_, _, clean, attacked, _, _, _| {
        *attacked = *clean * 2.0;
    });
    assert!(env.thresholds.iter().all(|t| t.sigma_star.is_none()));
    let r = page(&table, &env);
    assert!(fragment(&r, "fig-1").contains("σ*: none (fails at 10)"));
    assert!(
        fragment(&r, "summary")
            .contains("already exceeds the 15% ADE budget at the smallest tested level (10)")
    );
}

#[test]
fn no_changed_pairs_at_all() {
    let (table, env) = edited(80, &quick_params(), |_, _, _, _, l2, clean, coc| {
        *coc = clean.to_string();
        *l2 = 2.0;
    });
    assert!(!env.severity.defined);
    let r = page(&table, &env);
    for id in ["fig-2a", "fig-2b", "fig-3"] {
        assert!(!drawn(&r, id), "{id} should not be drawn");
    }
    assert!(fragment(&r, "fig-2a").contains("the severity mixture is undefined"));
    assert!(fragment(&r, "fig-2b").contains("no changed pairs in the classified scenarios"));
    assert!(fragment(&r, "table-3").contains("Table 3 is empty"));
    assert!(fragment(&r, "summary").contains("No severity bands could be fitted"));
    // The threshold side still works.
    assert!(drawn(&r, "fig-1") && drawn(&r, "fig-4"));
}

#[test]
fn no_bootstrap_no_histogram_no_closed_loop() {
    let params = EnvelopeParams {
        bootstrap: 0,
        ..quick_params()
    };
    let (_, env) = edited(80, &params, |_, _, _, _, _, _, _| {});
    let input = ReportInput::from_envelope(&env).unwrap();
    let r = render(&input, &ReportParams::default()).unwrap();
    assert_sane(&r);
    assert!(fragment(&r, "fig-1").contains("No confidence bands"));
    assert!(!fragment(&r, "fig-1").contains("class=\"ci-band\""));
    assert!(fragment(&r, "fig-2a").contains("No histogram"));
    assert!(!fragment(&r, "fig-2a").contains("class=\"hist\""));
    assert!(!drawn(&r, "fig-5"));
    assert!(fragment(&r, "fig-5").contains("--sim DIR"));
    assert!(fragment(&r, "table-2").contains("—"));
}
