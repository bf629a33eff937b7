//! Golden values from SciPy (and mpmath for the special functions), written by
//! `tests/golden/make_golden.py` into `tests/golden/stats.json`.
//!
//! Statistics must match SciPy to 1e-9 relative and fail exactly where the script recorded
//! an error. Special functions must match mpmath's 50-digit values to 1e-12 relative, and
//! SciPy's to 1e-12 wherever SciPy is itself within 1e-13 of mpmath (SciPy is off by up to
//! 3e-9 at a few points, e.g. `ln Γ(1 ± 1e-6)` and `t.sf(1e-8, 1)`, which we get right).
//! Values below `f64::MIN_POSITIVE` are subnormal and carry fewer significant bits; the
//! absolute floor of [`close`] covers them.

use fogline_stats::{contingency, correlation, describe, effect, icc, rank, special};
use serde_json::Value;

const GOLDEN: &str = include_str!("../golden/stats.json");

/// Relative tolerance of the statistics against SciPy.
const STAT_REL: f64 = 1e-9;
/// Relative tolerance of the special functions against mpmath (and accurate SciPy values).
const SPECIAL_REL: f64 = 1e-12;

/// `a` and `b` agree to `rel` relative, with an absolute floor of `rel · 1e-300` so exact
/// zeros and subnormals compare sensibly.
fn close(a: f64, b: f64, rel: f64) -> bool {
    a == b || (a - b).abs() <= rel * a.abs().max(b.abs()).max(1e-300)
}

fn golden() -> Value {
    serde_json::from_str(GOLDEN).expect("tests/golden/stats.json is valid JSON")
}

fn f64s(v: &Value) -> Vec<f64> {
    v.as_array()
        .expect("an array")
        .iter()
        .map(|x| x.as_f64().expect("a number"))
        .collect()
}

fn matrix(v: &Value) -> Vec<Vec<f64>> {
    v.as_array()
        .expect("an array of rows")
        .iter()
        .map(f64s)
        .collect()
}

fn num(v: &Value) -> f64 {
    v.as_f64().expect("a number")
}

fn count(v: &Value) -> usize {
    usize::try_from(v.as_u64().expect("a count")).expect("fits usize")
}

#[test]
fn golden_file_records_versions() {
    let g = golden();
    let meta = &g["meta"];
    for key in ["numpy", "scipy", "mpmath", "seed"] {
        assert!(!meta[key].is_null(), "meta.{key} missing");
    }
}

#[test]
fn special_functions_match_mpmath_and_scipy() {
    let g = golden();
    let points = g["special"].as_array().expect("special is an array");
    assert!(points.len() > 500, "too few special-function points");
    let mut failures = Vec::new();
    for p in points {
        let name = p["fn"].as_str().expect("fn name");
        let a = f64s(&p["args"]);
        let got = match name {
            "norm_cdf" => special::norm_cdf(a[0]),
            "norm_sf" => special::norm_sf(a[0]),
            "norm_ppf" => special::norm_ppf(a[0]),
            "ln_gamma" => special::ln_gamma(a[0]),
            "beta_inc_reg" => special::beta_inc_reg(a[0], a[1], a[2]),
            "gamma_inc_upper_reg" => special::gamma_inc_upper_reg(a[0], a[1]),
            "t_sf" => special::t_sf(a[0], a[1]),
            "chi2_sf" => special::chi2_sf(a[0], a[1]),
            other => panic!("unknown special function {other} in stats.json"),
        };
        let truth = num(&p["mp"]);
        let scipy = num(&p["scipy"]);
        if !close(got, truth, SPECIAL_REL) {
            failures.push(format!(
                "{name}{a:?}: got {got:e}, mpmath {truth:e} (rel {:.1e})",
                rel_err(got, truth)
            ));
        }
        if close(scipy, truth, 1e-13) && !close(got, scipy, SPECIAL_REL) {
            failures.push(format!(
                "{name}{a:?}: got {got:e}, scipy {scipy:e} (rel {:.1e})",
                rel_err(got, scipy)
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "{} special-function mismatches:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

fn rel_err(a: f64, b: f64) -> f64 {
    if a == b {
        0.0
    } else {
        (a - b).abs() / a.abs().max(b.abs())
    }
}

/// Runs one statistic on the case's arguments; `Err` carries the error's text.
fn run(case: &Value) -> Result<Value, String> {
    let args = &case["args"];
    let scalar = |r: fogline_stats::Result<f64>| r.map(|v| serde_json::json!({ "value": v }));
    let to_value = |v: Result<Value, serde_json::Error>| v.expect("result serializes");
    let out = match case["fn"].as_str().expect("fn name") {
        "mean" => scalar(describe::mean(&f64s(&args["x"]))),
        "variance_ddof0" => scalar(describe::variance(&f64s(&args["x"]), 0)),
        "variance_ddof1" => scalar(describe::variance(&f64s(&args["x"]), 1)),
        "skewness" => scalar(describe::skewness(&f64s(&args["x"]))),
        "excess_kurtosis" => scalar(describe::excess_kurtosis(&f64s(&args["x"]))),
        "bimodality_coefficient" => scalar(describe::bimodality_coefficient(&f64s(&args["x"]))),
        "pearson" => correlation::pearson(&f64s(&args["x"]), &f64s(&args["y"]))
            .map(|c| to_value(serde_json::to_value(c))),
        "spearman" => correlation::spearman(&f64s(&args["x"]), &f64s(&args["y"]))
            .map(|c| to_value(serde_json::to_value(c))),
        "point_biserial" => {
            let flags: Vec<bool> = args["flags"]
                .as_array()
                .expect("flags")
                .iter()
                .map(|f| f.as_bool().expect("a bool"))
                .collect();
            correlation::point_biserial(&flags, &f64s(&args["y"]))
                .map(|c| to_value(serde_json::to_value(c)))
        }
        "mann_whitney_u" => rank::mann_whitney_u(&f64s(&args["x"]), &f64s(&args["y"]))
            .map(|m| to_value(serde_json::to_value(m))),
        "cohens_d" => scalar(effect::cohens_d(&f64s(&args["x"]), &f64s(&args["y"]))),
        "two_sample_power" => scalar(effect::two_sample_power(
            num(&args["d"]),
            count(&args["n_x"]),
            count(&args["n_y"]),
            num(&args["alpha"]),
        )),
        "chi2_contingency" => contingency::chi2_contingency(&matrix(&args["table"]))
            .map(|c| to_value(serde_json::to_value(c))),
        "icc" => icc::icc(&matrix(&args["matrix"])).map(|c| to_value(serde_json::to_value(c))),
        other => panic!("unknown statistic {other} in stats.json"),
    };
    out.map_err(|e| e.to_string())
}

#[test]
fn statistics_match_scipy() {
    let g = golden();
    let cases = g["cases"].as_array().expect("cases is an array");
    assert!(cases.len() > 100, "too few statistic cases");
    let mut failures = Vec::new();
    for case in cases {
        let label = format!(
            "{} / {}",
            case["fn"].as_str().unwrap_or("?"),
            case["name"].as_str().unwrap_or("?")
        );
        let got = run(case);
        if case["error"].as_bool() == Some(true) {
            if let Ok(v) = got {
                failures.push(format!("{label}: expected an error, got {v}"));
            }
            continue;
        }
        let got = match got {
            Ok(v) => v,
            Err(e) => {
                failures.push(format!("{label}: unexpected error: {e}"));
                continue;
            }
        };
        let expect = case["expect"].as_object().expect("expect is an object");
        for (key, want) in expect {
            let have = &got[key.as_str()];
            let ok = if want.is_u64() {
                have.as_u64() == want.as_u64()
            } else {
                have.as_f64().is_some_and(|h| close(h, num(want), STAT_REL))
            };
            if !ok {
                failures.push(format!("{label}: {key} = {have}, SciPy {want}"));
            }
        }
    }
    assert!(
        failures.is_empty(),
        "{} mismatches against SciPy:\n{}",
        failures.len(),
        failures.join("\n")
    );
}
