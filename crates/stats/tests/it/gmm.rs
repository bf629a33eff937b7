//! Gaussian mixtures: golden values from scikit-learn (tests/golden/gmm.json, made by
//! tests/golden/make_gmm_golden.py), unit-level behaviour, determinism and invariants.

use fogline_stats::StatsError;
use fogline_stats::gmm::{
    Gmm1d, GmmParams, SKLEARN_KMEANS_MAX_N, SelectParams, Selection, select_k, select_k_fixed,
};
use fogline_stats::seed;
use proptest::prelude::*;
use serde_json::Value;

fn golden() -> Value {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/golden/gmm.json");
    let text = std::fs::read_to_string(path).expect("tests/golden/gmm.json is readable");
    serde_json::from_str(&text).expect("tests/golden/gmm.json is valid JSON")
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .expect("an array")
        .iter()
        .map(|x| x.as_f64().expect("a number"))
        .collect()
}

fn int(v: &Value) -> usize {
    v.as_u64().expect("an integer") as usize
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

/// Our fit against scikit-learn's (components sorted by mean): means and standard deviations
/// within 1 % relative, weights within 1 % relative or 0.002 absolute.
fn assert_fit_close(name: &str, g: &Gmm1d, sk: &Value) {
    let (means, stds, weights) = (
        floats(&sk["means"]),
        floats(&sk["stds"]),
        floats(&sk["weights"]),
    );
    assert_eq!(
        g.n_components(),
        means.len(),
        "{name}: number of components"
    );
    let our_stds = g.stds();
    for j in 0..means.len() {
        let mean_tol = 0.01 * means[j].abs().max(stds[j]);
        assert!(
            (g.means[j] - means[j]).abs() <= mean_tol,
            "{name} mean {j}: {} vs {}",
            g.means[j],
            means[j]
        );
        assert!(
            rel(our_stds[j], stds[j]) <= 0.01,
            "{name} std {j}: {} vs {}",
            our_stds[j],
            stds[j]
        );
        let w_ok =
            rel(g.weights[j], weights[j]) <= 0.01 || (g.weights[j] - weights[j]).abs() <= 0.002;
        assert!(
            w_ok,
            "{name} weight {j}: {} vs {}",
            g.weights[j], weights[j]
        );
    }
}

fn check_against_golden(sklearn_kmeans_max_n: usize, check_bic_table: bool) {
    let g = golden();
    for set in g["sets"].as_array().expect("sets") {
        let name = set["name"].as_str().expect("name");
        let x = floats(&set["x"]);
        let true_k = int(&set["true_k"]);
        let p = SelectParams {
            cv_folds: 0,
            sklearn_kmeans_max_n,
            ..SelectParams::default()
        };
        let sel = select_k(&x, &p).expect("select_k succeeds");
        assert_eq!(
            sel.chosen_k,
            int(&set["modal_k"]),
            "{name}: chosen k vs scikit-learn's modal k"
        );
        assert_fit_close(name, &sel.model, &set["fit_modal_k"]);
        let sk_bic = floats(&set["bic_min"]);
        let upto = if check_bic_table { true_k } else { 1 };
        for ki in 0..upto {
            let r = rel(sel.bic_min[ki], sk_bic[ki]);
            assert!(r <= 1e-3, "{name}: min BIC at k = {} off by {r:e}", ki + 1);
        }
        // k = 1 is deterministic: the BIC agrees to rounding.
        let k1 = &set["k1"];
        assert!(
            rel(sel.bic_min[0], k1["bic"].as_f64().expect("bic")) < 1e-12,
            "{name}: k = 1 BIC"
        );
        let fit1 = Gmm1d::fit(&x, &GmmParams::default()).expect("k = 1 fit");
        assert!(
            rel(fit1.means[0], k1["mean"].as_f64().expect("mean")) < 1e-12,
            "{name}: k = 1 mean"
        );
        assert!(
            rel(fit1.variances[0], k1["variance"].as_f64().expect("var")) < 1e-12,
            "{name}: k = 1 var"
        );
        assert!(
            rel(
                fit1.score(&x).expect("score"),
                k1["score"].as_f64().expect("score")
            ) < 1e-12
        );
    }
}

#[test]
fn select_k_matches_sklearn_golden() {
    check_against_golden(SKLEARN_KMEANS_MAX_N, true);
}

#[test]
fn converged_kmeans_mode_still_matches_sklearn_choice_and_bands() {
    check_against_golden(0, false);
}

#[test]
fn golden_file_records_versions() {
    let g = golden();
    for key in ["sklearn", "numpy", "scipy", "python"] {
        assert!(g["versions"][key].is_string(), "versions.{key}");
    }
}

/// `n` points: two thirds around 2.7, one third around 12.7, both with standard deviation 0.4
/// (Box–Muller on a seeded stream).
fn two_clusters(n: usize) -> Vec<f64> {
    use rand::Rng;
    let mut rng = seed::rng(99, &[n as u64]);
    (0..n)
        .map(|i| {
            let (u1, u2): (f64, f64) = (1.0 - rng.random::<f64>(), rng.random());
            let z = (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
            (if i % 3 == 0 { 12.7 } else { 2.7 }) + 0.4 * z
        })
        .collect()
}

#[test]
fn one_component_is_sample_mean_and_population_variance() {
    let x: Vec<f64> = (0..777)
        .map(|i| ((i * 31) % 211) as f64 * 0.37 - 5.0)
        .collect();
    let n = x.len() as f64;
    let mean = x.iter().sum::<f64>() / n;
    let var = x.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / n;
    for reg_covar in [1e-6, 0.5] {
        let g = Gmm1d::fit(
            &x,
            &GmmParams {
                reg_covar,
                ..GmmParams::default()
            },
        )
        .expect("fit");
        assert!((g.means[0] - mean).abs() <= 1e-12 * mean.abs());
        assert!((g.variances[0] - (var + reg_covar)).abs() <= 1e-12 * (var + reg_covar));
        assert_eq!(g.weights, vec![1.0]);
        assert!(g.converged);
        assert_eq!(g.n_samples, x.len());
    }
}

#[test]
fn weights_sum_to_one_and_components_ascend() {
    let x = two_clusters(900);
    for k in 1..=6 {
        let g = Gmm1d::fit(
            &x,
            &GmmParams {
                n_components: k,
                seed: 3,
                ..GmmParams::default()
            },
        )
        .expect("fit");
        assert!(
            (g.weights.iter().sum::<f64>() - 1.0).abs() < 1e-12,
            "k = {k}"
        );
        assert!(g.means.windows(2).all(|w| w[0] <= w[1]), "k = {k}");
        assert!(g.variances.iter().all(|&v| v >= 1e-6));
        assert!(g.lower_bound.is_finite() && g.n_iter >= 1);
    }
}

#[test]
fn identical_values_fit_one_component_and_reject_more() {
    let x = vec![4.25; 50];
    let g = Gmm1d::fit(&x, &GmmParams::default()).expect("k = 1 fits constant data");
    assert_eq!(g.means, vec![4.25]);
    assert!((g.variances[0] - 1e-6).abs() < 1e-18);
    assert!(g.score(&x).expect("score").is_finite());
    assert!(g.bic(&x).expect("bic").is_finite());
    let err = Gmm1d::fit(
        &x,
        &GmmParams {
            n_components: 2,
            ..GmmParams::default()
        },
    );
    assert!(matches!(err, Err(StatsError::Undefined { .. })), "{err:?}");

    let sel = select_k(
        &x,
        &SelectParams {
            restarts: 3,
            ..SelectParams::default()
        },
    )
    .expect("select_k");
    assert_eq!(sel.k_values, vec![1]);
    assert_eq!(sel.chosen_k, 1);
    assert!(sel.bic_min[0].is_finite());
    let cv = sel.cv.expect("cross-validation runs on 50 values");
    assert!(cv.loglik[0].iter().all(|v| v.is_finite()));
    assert!(select_k_fixed(&x, 2, &SelectParams::default()).is_err());
}

#[test]
fn invalid_input_is_an_error() {
    let p2 = GmmParams {
        n_components: 2,
        ..GmmParams::default()
    };
    assert!(matches!(
        Gmm1d::fit(&[1.0], &p2),
        Err(StatsError::TooFewSamples {
            needed: 2,
            got: 1,
            ..
        })
    ));
    assert!(matches!(
        Gmm1d::fit(
            &[1.0, 2.0, 3.0],
            &GmmParams {
                n_components: 0,
                ..GmmParams::default()
            }
        ),
        Err(StatsError::InvalidParam {
            name: "n_components",
            ..
        })
    ));
    assert!(matches!(
        Gmm1d::fit(
            &[1.0, 2.0, 3.0],
            &GmmParams {
                n_components: 17,
                ..GmmParams::default()
            }
        ),
        Err(StatsError::InvalidParam { .. })
    ));
    assert!(matches!(
        Gmm1d::fit(&[1.0, f64::NAN, 3.0], &p2),
        Err(StatsError::NonFinite { index: 1, .. })
    ));
    assert!(matches!(
        Gmm1d::fit(&[1.0, 2.0, f64::INFINITY], &p2),
        Err(StatsError::NonFinite { index: 2, .. })
    ));
    assert!(matches!(
        Gmm1d::fit(
            &[1.0, 2.0],
            &GmmParams {
                reg_covar: 0.0,
                ..GmmParams::default()
            }
        ),
        Err(StatsError::InvalidParam {
            name: "reg_covar",
            ..
        })
    ));
    assert!(matches!(
        Gmm1d::fit(&[-1e300, 1e300], &GmmParams::default()),
        Err(StatsError::Undefined { .. })
    ));
    assert!(matches!(
        select_k(&[], &SelectParams::default()),
        Err(StatsError::TooFewSamples { .. })
    ));
    assert!(matches!(
        select_k(
            &[1.0, 2.0],
            &SelectParams {
                cv_folds: 1,
                ..SelectParams::default()
            }
        ),
        Err(StatsError::InvalidParam {
            name: "cv_folds",
            ..
        })
    ));
    assert!(matches!(
        select_k_fixed(&[1.0, 2.0, 3.0], 4, &SelectParams::default()),
        Err(StatsError::TooFewSamples {
            needed: 4,
            got: 3,
            ..
        })
    ));
}

#[test]
fn select_k_caps_k_by_distinct_values_and_skips_cv_on_tiny_samples() {
    let x = [1.0, 1.0, 2.0, 9.0, 9.0, 9.5];
    let sel = select_k(
        &x,
        &SelectParams {
            restarts: 2,
            ..SelectParams::default()
        },
    )
    .expect("select_k");
    assert_eq!(sel.k_values, vec![1, 2, 3, 4]);
    assert!(sel.cv.is_none(), "n = 6 < 2 * 5 folds");
    assert!(sel.bic.iter().flatten().all(|b| b.is_finite()));
}

fn bits(s: &Selection) -> Vec<u64> {
    let mut v: Vec<u64> = s.bic.iter().flatten().map(|b| b.to_bits()).collect();
    v.extend(
        s.model
            .means
            .iter()
            .chain(&s.model.variances)
            .chain(&s.model.weights)
            .map(|b| b.to_bits()),
    );
    if let Some(cv) = &s.cv {
        v.extend(cv.loglik.iter().flatten().map(|b| b.to_bits()));
    }
    v
}

#[test]
fn same_seed_gives_bit_identical_results() {
    let x = two_clusters(700);
    let p = SelectParams {
        restarts: 4,
        k_max: 5,
        seed: 11,
        ..SelectParams::default()
    };
    let a = select_k(&x, &p).expect("select_k");
    let b = select_k(&x, &p).expect("select_k");
    assert_eq!(bits(&a), bits(&b));
    assert_eq!(a, b);
    let c = select_k(&x, &SelectParams { seed: 12, ..p }).expect("select_k");
    assert_eq!(c.chosen_k, a.chosen_k);
}

#[test]
fn results_do_not_depend_on_thread_count() {
    let x = two_clusters(1500);
    let p = SelectParams {
        restarts: 6,
        k_max: 6,
        seed: 5,
        ..SelectParams::default()
    };
    // Large enough for the parallel pass over pieces of the data.
    let big: Vec<f64> = (0..140_000)
        .map(|i| (if i % 4 == 0 { 30.0 } else { 0.0 }) + ((i * 7919) % 10007) as f64 / 2000.0)
        .collect();
    let gp = GmmParams {
        n_components: 3,
        seed: 9,
        ..GmmParams::default()
    };
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("a thread pool");
        pool.install(|| {
            (
                select_k(&x, &p).expect("select_k"),
                Gmm1d::fit(&big, &gp).expect("fit"),
            )
        })
    };
    let (s1, f1) = run(1);
    let (s2, f2) = run(2);
    assert_eq!(bits(&s1), bits(&s2));
    assert_eq!(s1, s2);
    assert_eq!(f1, f2);
}

#[test]
fn select_k_fits_are_the_standalone_fits() {
    let x = two_clusters(600);
    let p = SelectParams {
        restarts: 5,
        k_max: 4,
        seed: 21,
        cv_folds: 0,
        ..SelectParams::default()
    };
    let sel = select_k(&x, &p).expect("select_k");
    let ci = sel.chosen_k - 1;
    let column: Vec<f64> = sel.bic.iter().map(|row| row[ci]).collect();
    let r = (0..column.len()).fold(0, |b, i| if column[i] < column[b] { i } else { b });
    let gp = GmmParams {
        n_components: sel.chosen_k,
        seed: seed::child(p.seed, &[r as u64, sel.chosen_k as u64]),
        ..GmmParams::default()
    };
    let g = Gmm1d::fit(&x, &gp).expect("fit");
    assert_eq!(g, sel.model);
    assert!(rel(g.bic(&x).expect("bic"), sel.bic[r][ci]) < 1e-12);
}

#[test]
fn select_k_fixed_forces_k_and_keeps_the_table() {
    let x = two_clusters(600);
    let p = SelectParams {
        restarts: 3,
        k_max: 4,
        ..SelectParams::default()
    };
    let free = select_k(&x, &p).expect("select_k");
    assert_eq!(free.chosen_k, 2);
    let forced = select_k_fixed(&x, 3, &p).expect("select_k_fixed");
    assert_eq!(forced.chosen_k, 3);
    assert_eq!(forced.model.n_components(), 3);
    assert_eq!(forced.bic, free.bic);
    assert_eq!(forced.chosen_per_restart, free.chosen_per_restart);
    let wider = select_k_fixed(&x, 6, &p).expect("select_k_fixed beyond k_max");
    assert_eq!(wider.k_values, (1..=6).collect::<Vec<_>>());
    assert_eq!(wider.model.n_components(), 6);
}

#[test]
fn selection_summaries_are_consistent() {
    let x = two_clusters(800);
    let sel = select_k(
        &x,
        &SelectParams {
            restarts: 4,
            k_max: 5,
            ..SelectParams::default()
        },
    )
    .expect("select_k");
    assert_eq!(sel.bic.len(), 4);
    assert_eq!(sel.chosen_count.iter().sum::<usize>(), 4);
    assert_eq!(sel.gains[0], None);
    for ki in 1..sel.k_values.len() {
        assert_eq!(sel.gains[ki], Some(sel.bic_min[ki - 1] - sel.bic_min[ki]));
    }
    for (ki, m) in sel.bic_min.iter().enumerate() {
        assert!(sel.bic.iter().all(|row| row[ki] >= *m));
    }
    let cv = sel.cv.as_ref().expect("cross-validation");
    assert_eq!(cv.folds, 5);
    assert_eq!(cv.loglik.len(), sel.k_values.len());
    assert!(
        cv.loglik
            .iter()
            .all(|row| row.len() == 5 && row.iter().all(|v| v.is_finite()))
    );
    assert_eq!(cv.folds_beating_previous[0], 0);
    assert_eq!(
        cv.folds_beating_previous[1], 5,
        "two clusters beat one in every fold"
    );
    for ki in 0..sel.k_values.len() {
        assert!((cv.mean[ki] - cv.loglik[ki].iter().sum::<f64>() / 5.0).abs() < 1e-12);
    }
    let json = serde_json::to_string(&sel).expect("serialise");
    let back: Selection = serde_json::from_str(&json).expect("deserialise");
    assert_eq!(back.chosen_k, sel.chosen_k);
}

#[test]
fn predictions_use_sorted_components() {
    let x = two_clusters(600);
    let g = Gmm1d::fit(
        &x,
        &GmmParams {
            n_components: 2,
            ..GmmParams::default()
        },
    )
    .expect("fit");
    assert_eq!(g.predict(&[2.5, 12.5]).expect("predict"), vec![0, 1]);
    let pr = g.predict_proba(&[2.5, 12.5]).expect("predict_proba");
    assert!(pr[0][0] > 0.999 && pr[1][1] > 0.999);
    assert!(g.pdf(2.5) > g.pdf(7.0));
    assert_eq!(g.pdf(f64::INFINITY), 0.0);
}

fn clustered() -> impl Strategy<Value = Vec<f64>> {
    (
        prop::collection::vec((0usize..3, -1.0f64..1.0), 4..60),
        0.1f64..20.0,
    )
        .prop_map(|(pts, gap)| pts.into_iter().map(|(c, e)| c as f64 * gap + e).collect())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 32, ..ProptestConfig::default() })]

    #[test]
    fn fits_are_valid_mixtures(x in clustered(), k in 1usize..5, seed in 0u64..1000) {
        let n_distinct = {
            let mut v = x.clone();
            v.sort_by(f64::total_cmp);
            v.dedup();
            v.len()
        };
        prop_assume!(k <= n_distinct);
        let reg_covar = 1e-6;
        let g = Gmm1d::fit(&x, &GmmParams { n_components: k, seed, ..GmmParams::default() }).expect("fit");
        prop_assert!((g.weights.iter().sum::<f64>() - 1.0).abs() < 1e-9);
        prop_assert!(g.weights.iter().all(|&w| w > 0.0));
        prop_assert!(g.variances.iter().all(|&v| v >= reg_covar && v.is_finite()));
        prop_assert!(g.means.windows(2).all(|w| w[0] <= w[1]));
        prop_assert!(g.bic(&x).expect("bic").is_finite());
        prop_assert!(g.predict(&x).expect("predict").iter().all(|&l| l < k));
    }

    #[test]
    fn selections_are_finite(x in clustered(), seed in 0u64..1000) {
        let p = SelectParams { k_max: 3, restarts: 2, n_init: 2, seed, ..SelectParams::default() };
        let sel = select_k(&x, &p).expect("select_k");
        prop_assert!(sel.bic.iter().flatten().all(|b| b.is_finite()));
        prop_assert!(sel.k_values.contains(&sel.chosen_k));
        prop_assert!((sel.model.weights.iter().sum::<f64>() - 1.0).abs() < 1e-9);
        if let Some(cv) = &sel.cv {
            prop_assert!(cv.loglik.iter().flatten().all(|v| v.is_finite()));
        }
    }
}
