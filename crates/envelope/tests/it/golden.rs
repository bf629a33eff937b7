//! The whole analysis against golden values from the independent Python peer
//! (`crates/bench/python/envelope_peer.py`: pandas, SciPy, scikit-learn), written by
//! `tests/golden/make_envelope_golden.py` into `tests/golden/envelope_small.json` from
//! `tests/data/small.csv` (the synthetic corpus, 240 clips, seed 3, 1,920 pairs).
//!
//! Both sides run with the bootstrap off and 5 GMM restarts, defaults otherwise.
//!
//! - Deterministic quantities (counts, level means, every statistic that does not depend on
//!   the mixture) agree to 1e-9 relative; ΔADE, a difference of two means that can nearly
//!   cancel, to 1e-9 of the larger mean. Thresholds and censoring agree exactly.
//! - The mixture: the random streams differ (ChaCha8 vs NumPy's MT19937), so fits agree only
//!   where both reach the same optimum. The modal k must be equal, band means, standard
//!   deviations and weights within 1 %, and the minimum BIC per k within 0.1 % for k up to the
//!   chosen k (beyond it, local optima differ).
//! - Quantities of the hard band assignment (high-severity counts, the joint table, χ², V)
//!   inherit the 1 % of the bands. On this corpus, jittering every band mean, standard
//!   deviation and weight by up to ±1 % (3,000 random draws) reassigns at most 4 of the 820
//!   changed pairs, moves any high-severity count by at most 1, χ² by at most 7.6 % and
//!   Cramér's V by at most 3.7 %. The tolerances below are twice those: band counts within 8
//!   pairs, high-severity counts within 2, χ² within 15 %, V within 7.5 %, the same degrees of
//!   freedom and the same verdict at α = 0.05.

use std::path::Path;
use std::sync::OnceLock;

use fogline_envelope::{Envelope, EnvelopeParams, ReadOptions, ThresholdRule, read_pairs};
use serde_json::Value;

const GOLDEN: &str = include_str!("../golden/envelope_small.json");
const SMALL_CSV: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/small.csv");

/// Relative tolerance of deterministic quantities.
const REL: f64 = 1e-9;
/// Relative tolerance of band means, standard deviations and weights.
const BAND_REL: f64 = 0.01;
/// Relative tolerance of the minimum BIC per k (k up to the chosen k).
const BIC_REL: f64 = 1e-3;
/// Pairs by which a band's hard-assigned count may differ.
const BAND_N_ABS: i64 = 8;
/// Pairs by which a high-severity count may differ.
const HIGH_N_ABS: i64 = 2;
/// Relative tolerance of χ².
const CHI2_REL: f64 = 0.15;
/// Relative tolerance of Cramér's V.
const CRAMER_REL: f64 = 0.075;

fn golden() -> &'static Value {
    static G: OnceLock<Value> = OnceLock::new();
    G.get_or_init(|| {
        serde_json::from_str(GOLDEN).expect("tests/golden/envelope_small.json is valid JSON")
    })
}

fn params(rule: ThresholdRule) -> EnvelopeParams {
    EnvelopeParams {
        bootstrap: 0,
        restarts: 5,
        rule,
        ..EnvelopeParams::default()
    }
}

/// The envelopes of small.csv under the first-violation and the max-passing rule.
fn envelopes() -> &'static [Envelope; 2] {
    static E: OnceLock<[Envelope; 2]> = OnceLock::new();
    E.get_or_init(|| {
        let table =
            read_pairs(Path::new(SMALL_CSV), &ReadOptions::default()).expect("small.csv reads");
        [ThresholdRule::FirstViolation, ThresholdRule::MaxPassing].map(|rule| {
            fogline_envelope::analyze(&table, &params(rule)).expect("small.csv analyses")
        })
    })
}

fn env() -> &'static Envelope {
    &envelopes()[0]
}

fn close(a: f64, b: f64, rel: f64) -> bool {
    a == b || (a - b).abs() <= rel * a.abs().max(b.abs())
}

fn num(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("{v} is not a number"))
}

fn int(v: &Value) -> i64 {
    v.as_i64()
        .unwrap_or_else(|| panic!("{v} is not an integer"))
}

fn text(v: &Value) -> &str {
    v.as_str().unwrap_or_else(|| panic!("{v} is not a string"))
}

fn array(v: &Value) -> &Vec<Value> {
    v.as_array()
        .unwrap_or_else(|| panic!("{v} is not an array"))
}

/// Compares a Rust value (serialised) with a golden one: integers exactly, other numbers to
/// `rel`, strings, booleans and nulls exactly, objects key by key over the golden keys.
fn assert_matches(path: &str, rust: &Value, gold: &Value, rel: f64) {
    match (rust, gold) {
        (Value::Number(a), Value::Number(b)) => {
            if a.is_f64() || b.is_f64() {
                let (x, y) = (num(rust), num(gold));
                assert!(
                    close(x, y, rel),
                    "{path}: fogline {x:e}, peer {y:e} (rel {:.2e})",
                    (x - y).abs() / y.abs()
                );
            } else {
                assert_eq!(a.as_i64(), b.as_i64(), "{path}");
            }
        }
        (Value::Object(a), Value::Object(b)) => {
            for (k, g) in b {
                let r = a
                    .get(k)
                    .unwrap_or_else(|| panic!("{path}.{k}: missing on the fogline side"));
                assert_matches(&format!("{path}.{k}"), r, g, rel);
            }
        }
        (Value::Array(a), Value::Array(b)) => {
            assert_eq!(a.len(), b.len(), "{path}: lengths");
            for (i, (r, g)) in a.iter().zip(b).enumerate() {
                assert_matches(&format!("{path}[{i}]"), r, g, rel);
            }
        }
        _ => assert_eq!(rust, gold, "{path}"),
    }
}

fn json<T: serde::Serialize>(v: &T) -> Value {
    serde_json::to_value(v).expect("serialises")
}

#[test]
fn golden_was_made_from_this_csv() {
    let g = golden();
    assert_eq!(
        env().input.sha256,
        text(&g["input"]["sha256"]),
        "tests/data/small.csv changed: rerun tests/golden/make_envelope_golden.py"
    );
    assert_eq!(int(&g["meta"]["parameters"]["restarts"]), 5);
    assert_eq!(int(&g["meta"]["parameters"]["bootstrap"]), 0);
}

#[test]
fn corpus_counts_and_text_conventions() {
    let g = &golden()["corpus"];
    let c = &env().corpus;
    assert_eq!(c.n_pairs as i64, int(&g["n_pairs"]));
    assert_eq!(c.n_clips as i64, int(&g["n_clips"]));
    // coc_changed: whitespace-normalised exact comparison on both sides.
    assert_eq!(c.n_changed as i64, int(&g["n_changed"]));
    let gs = array(&g["scenarios"]);
    assert_eq!(c.scenarios.len(), gs.len());
    for s in gs {
        let name = text(&s["scenario"]);
        let r = c
            .scenarios
            .iter()
            .find(|x| x.scenario == name)
            .unwrap_or_else(|| panic!("scenario {name}"));
        assert_matches(&format!("corpus.scenarios[{name}]"), &json(r), s, REL);
    }
}

#[test]
fn axes_match() {
    let g = array(&golden()["axes"]);
    let axes = &env().axes;
    assert_eq!(axes.len(), g.len());
    for (a, ga) in axes.iter().zip(g) {
        assert_eq!(a.axis, text(&ga["axis"]));
        assert_eq!(a.family, text(&ga["family"]));
        let levels: Vec<f64> = array(&ga["levels"]).iter().map(num).collect();
        assert_eq!(a.levels, levels, "axis {}", a.axis);
        assert_matches(
            &format!("axes[{}].conditions", a.axis),
            &json(&a.conditions),
            &ga["conditions"],
            0.0,
        );
    }
}

#[test]
fn dose_response_means_match() {
    let g = array(&golden()["dose_response"]);
    let d = &env().dose_response;
    assert_eq!(d.len(), g.len(), "number of dose-response points");
    for gp in g {
        let (scen, axis, level) = (text(&gp["scenario"]), text(&gp["axis"]), num(&gp["level"]));
        let p = d
            .iter()
            .find(|p| p.scenario == scen && p.axis == axis && p.level == level)
            .unwrap_or_else(|| panic!("no dose point {scen}/{axis}/{level}"));
        let at = format!("dose {scen}/{axis}/{level}");
        assert_eq!(p.n_pairs as i64, int(&gp["n_pairs"]), "{at}");
        let (mc, ma) = (
            num(&gp["mean_ade_clean_m"]),
            num(&gp["mean_ade_attacked_m"]),
        );
        assert!(
            close(p.mean_ade_clean_m, mc, REL),
            "{at}: clean {} vs {mc}",
            p.mean_ade_clean_m
        );
        assert!(
            close(p.mean_ade_attacked_m, ma, REL),
            "{at}: attacked {} vs {ma}",
            p.mean_ade_attacked_m
        );
        // ΔADE may nearly cancel: compare it on the scale of the means.
        let dd = num(&gp["delta_ade_m"]);
        assert!(
            (p.delta_ade_m - dd).abs() <= REL * mc.abs().max(ma.abs()),
            "{at}: ΔADE {} vs {dd}",
            p.delta_ade_m
        );
    }
}

#[test]
fn thresholds_match_exactly_under_both_rules() {
    let g = array(&golden()["thresholds"]);
    let mut checked = 0;
    for e in envelopes() {
        for t in &e.thresholds {
            let gt = g
                .iter()
                .find(|x| {
                    text(&x["scenario"]) == t.scenario
                        && text(&x["axis"]) == t.axis
                        && num(&x["budget"]) == t.budget
                        && text(&x["rule"]) == t.rule
                })
                .unwrap_or_else(|| {
                    panic!(
                        "no golden threshold {}/{}/{}/{}",
                        t.scenario, t.axis, t.budget, t.rule
                    )
                });
            let at = format!(
                "threshold {}/{}/{}/{}",
                t.scenario, t.axis, t.budget, t.rule
            );
            assert_eq!(t.sigma_star, gt["sigma_star"].as_f64(), "{at}: σ*");
            assert_eq!(
                t.right_censored,
                gt["right_censored"].as_bool().expect("a bool"),
                "{at}: censoring"
            );
            assert_eq!(
                json(&t.vs_aggregate),
                gt["vs_aggregate"],
                "{at}: vs aggregate"
            );
            assert_eq!(t.n_clips as i64, int(&gt["n_clips"]), "{at}: clips");
            checked += 1;
        }
    }
    assert_eq!(checked, g.len(), "every golden threshold is checked");
}

#[test]
fn gmm_free_statistics_match() {
    let g = golden()["statistics"]
        .as_object()
        .expect("statistics is an object");
    let s = json(&env().statistics);
    for (k, gv) in g {
        assert_matches(&format!("statistics.{k}"), &s[k], gv, REL);
    }
}

#[test]
fn gmm_bands_match() {
    let g = &golden()["gmm"];
    let sev = &env().severity;
    assert!(sev.defined);
    assert_eq!(sev.n_changed as i64, int(&g["n_changed"]));
    let k = sev.chosen_k.expect("a chosen k");
    assert_eq!(k as i64, int(&g["chosen_k"]), "modal BIC-optimal k");
    for (row, gmin) in sev.bic.iter().zip(array(&g["bic_min"])).take(k) {
        assert!(
            close(row.min, num(gmin), BIC_REL),
            "min BIC at k = {}: {} vs {}",
            row.k,
            row.min,
            num(gmin)
        );
    }
    let gb = array(&g["bands"]);
    assert_eq!(sev.bands.len(), gb.len());
    for (b, gb) in sev.bands.iter().zip(gb) {
        assert_eq!(b.name, text(&gb["name"]));
        for (what, x, y) in [
            ("mean", b.mean_m, num(&gb["mean_m"])),
            ("std", b.std_m, num(&gb["std_m"])),
            ("weight", b.weight, num(&gb["weight"])),
        ] {
            assert!(close(x, y, BAND_REL), "band {} {what}: {x} vs {y}", b.name);
        }
        assert!(
            (b.n as i64 - int(&gb["n"])).abs() <= BAND_N_ABS,
            "band {} count: {} vs {}",
            b.name,
            b.n,
            gb["n"]
        );
    }
}

#[test]
fn per_scenario_changed_counts_match() {
    let g = array(&golden()["per_scenario"]);
    let ps = &env().severity.per_scenario;
    assert_eq!(ps.len(), g.len());
    for (m, gm) in ps.iter().zip(g) {
        assert_eq!(m.scenario, text(&gm["scenario"]));
        assert_eq!(m.n_changed as i64, int(&gm["n_changed"]), "{}", m.scenario);
    }
}

#[test]
fn gmm_dependent_quantities_within_tolerance() {
    let g = &golden()["gmm_dependent"];
    let e = env();
    assert_matches(
        "high_severity.bands",
        &json(&e.high_severity.bands),
        &g["high_bands"],
        0.0,
    );
    for (rows, grows, what) in [
        (&e.high_severity.by_scenario, &g["by_scenario"], "scenario"),
        (
            &e.high_severity.by_condition,
            &g["by_condition"],
            "condition",
        ),
    ] {
        let grows = array(grows);
        assert_eq!(rows.len(), grows.len(), "high-severity rows by {what}");
        for (r, gr) in rows.iter().zip(grows) {
            assert_eq!(r.group, text(&gr["group"]));
            assert_eq!(r.n_changed as i64, int(&gr["n_changed"]), "{}", r.group);
            let dn = (r.n_high as i64 - int(&gr["n_high"])).abs();
            assert!(
                dn <= HIGH_N_ABS,
                "{}: {} high-severity pairs vs {}",
                r.group,
                r.n_high,
                gr["n_high"]
            );
            if let (Some(s), Some(gs)) = (r.share, gr["share"].as_f64()) {
                assert!(
                    (s - gs).abs() <= HIGH_N_ABS as f64 / r.n_changed as f64 + 1e-12,
                    "{} share",
                    r.group
                );
            } else {
                assert_eq!(
                    r.share,
                    gr["share"].as_f64(),
                    "{} share defined on one side only",
                    r.group
                );
            }
        }
    }
    assert_matches(
        "joint.scenarios",
        &json(&e.joint.scenarios),
        &g["joint"]["scenarios"],
        0.0,
    );
    let chi = e.statistics.chi2.as_ref().expect("χ² is defined");
    let gchi = &g["chi2"];
    assert_eq!(chi.dof as i64, int(&gchi["dof"]), "χ² degrees of freedom");
    assert!(
        close(chi.statistic, num(&gchi["statistic"]), CHI2_REL),
        "χ² {} vs {}",
        chi.statistic,
        gchi["statistic"]
    );
    assert_eq!(
        chi.p_value < 0.05,
        num(&gchi["p_value"]) < 0.05,
        "χ² verdict at 0.05"
    );
    let v = e.statistics.cramers_v.expect("Cramér's V is defined");
    assert!(
        close(v, num(&g["cramers_v"]), CRAMER_REL),
        "Cramér's V {v} vs {}",
        g["cramers_v"]
    );
}
