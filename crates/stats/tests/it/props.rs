//! Property tests: invariants every statistic keeps on arbitrary inputs.

use fogline_stats::{contingency, correlation, describe, effect, icc, rank, special};
use proptest::prelude::*;

/// A sample with continuous values or heavy ties (small integers).
fn sample(min_len: usize, max_len: usize) -> impl Strategy<Value = Vec<f64>> {
    prop_oneof![
        prop::collection::vec(-1e3f64..1e3, min_len..max_len),
        prop::collection::vec((0i32..5).prop_map(f64::from), min_len..max_len),
    ]
}

/// Two samples of equal length.
fn paired(min_len: usize, max_len: usize) -> impl Strategy<Value = (Vec<f64>, Vec<f64>)> {
    (min_len..max_len).prop_flat_map(|n| {
        let v = || {
            prop_oneof![
                prop::collection::vec(-1e3f64..1e3, n),
                prop::collection::vec((0i32..4).prop_map(f64::from), n),
            ]
        };
        (v(), v())
    })
}

fn in_unit(p: f64) -> bool {
    (0.0..=1.0).contains(&p)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn correlations_are_bounded_finite_and_symmetric((x, y) in paired(2, 60)) {
        for (f, name) in [
            (correlation::pearson as fn(&[f64], &[f64]) -> _, "pearson"),
            (correlation::spearman, "spearman"),
        ] {
            if let Ok(c) = f(&x, &y) {
                prop_assert!(c.r.abs() <= 1.0 && c.r.is_finite(), "{name} r = {}", c.r);
                prop_assert!(in_unit(c.p_value), "{name} p = {}", c.p_value);
                let swapped = f(&y, &x).expect("swapping arguments keeps it defined");
                prop_assert_eq!(swapped.r, c.r);
                prop_assert_eq!(swapped.p_value, c.p_value);
            }
        }
    }

    #[test]
    fn point_biserial_is_bounded(flags in prop::collection::vec(any::<bool>(), 2..60), seed in any::<u64>()) {
        let y: Vec<f64> = flags.iter().enumerate().map(|(i, &f)| {
            let h = fogline_stats::seed::child(seed, &[i as u64]);
            (h % 1000) as f64 / 100.0 + if f { 1.0 } else { 0.0 }
        }).collect();
        if let Ok(c) = correlation::point_biserial(&flags, &y) {
            prop_assert!(c.r.abs() <= 1.0 && c.r.is_finite());
            prop_assert!(in_unit(c.p_value));
        }
    }

    #[test]
    fn mann_whitney_u_is_consistent(x in sample(1, 40), y in sample(1, 40)) {
        let nxy = (x.len() * y.len()) as f64;
        match (rank::mann_whitney_u(&x, &y), rank::mann_whitney_u(&y, &x)) {
            (Ok(a), Ok(b)) => {
                prop_assert!((0.0..=nxy).contains(&a.u), "u = {} of {}", a.u, nxy);
                prop_assert_eq!(a.u + b.u, nxy);
                prop_assert!(in_unit(a.p_value) && a.z.is_finite());
                prop_assert_eq!(a.p_value, b.p_value);
                prop_assert_eq!(a.z, b.z);
            }
            (Err(_), Err(_)) => {}
            (a, b) => prop_assert!(false, "asymmetric outcome {a:?} vs {b:?}"),
        }
    }

    #[test]
    fn chi_square_is_bounded(rows in 2usize..5, cols in 2usize..5, cells in prop::collection::vec(0u32..30, 16)) {
        let table: Vec<Vec<f64>> =
            (0..rows).map(|i| (0..cols).map(|j| f64::from(cells[i * 4 + j])).collect()).collect();
        if let Ok(c) = contingency::chi2_contingency(&table) {
            prop_assert!(in_unit(c.cramers_v), "V = {}", c.cramers_v);
            prop_assert!(in_unit(c.p_value), "p = {}", c.p_value);
            prop_assert!(c.statistic.is_finite() && c.statistic >= 0.0);
            prop_assert!(c.rows_used >= 2 && c.cols_used >= 2);
        }
    }

    #[test]
    fn descriptive_statistics_are_finite(x in sample(1, 80)) {
        if let Ok(m) = describe::mean(&x) {
            prop_assert!(m.is_finite());
        }
        if let Ok(v) = describe::variance(&x, 1) {
            prop_assert!(v.is_finite() && v >= 0.0);
        }
        for v in [describe::skewness(&x), describe::excess_kurtosis(&x)].into_iter().flatten() {
            prop_assert!(v.is_finite());
        }
        if let Ok(bc) = describe::bimodality_coefficient(&x) {
            prop_assert!(bc.is_finite() && bc > 0.0, "BC = {bc}");
        }
    }

    #[test]
    fn effect_sizes_are_finite(x in sample(1, 40), y in sample(1, 40), alpha in 0.001f64..0.5) {
        if let Ok(d) = effect::cohens_d(&x, &y) {
            prop_assert!(d.is_finite());
            let p = effect::two_sample_power(d, x.len(), y.len(), alpha).expect("valid power inputs");
            prop_assert!(in_unit(p) && p >= alpha * (1.0 - 1e-12), "power {p} at alpha {alpha}");
        }
    }

    #[test]
    fn icc_is_at_most_one(n in 2usize..12, k in 2usize..5, cells in prop::collection::vec(-50.0f64..50.0, 60)) {
        let m: Vec<Vec<f64>> = (0..n).map(|i| cells[i * k..i * k + k].to_vec()).collect();
        if let Ok(r) = icc::icc(&m) {
            prop_assert!(r.icc2_1.is_finite() && r.icc2_1 <= 1.0 + 1e-12);
            prop_assert!(r.icc3_1.is_finite() && r.icc3_1 <= 1.0 + 1e-12);
        }
    }

    #[test]
    fn distribution_tails_are_probabilities(t in -60.0f64..60.0, df in 0.5f64..1e6, a in 0.01f64..1e3, x in 0.0f64..1.0) {
        let sf = special::t_sf(t, df);
        prop_assert!(in_unit(sf));
        prop_assert!((special::t_sf(-t, df) - (1.0 - sf)).abs() < 1e-12);
        prop_assert!(in_unit(special::chi2_sf(t * t, df)));
        prop_assert!(in_unit(special::beta_inc_reg(a, df.min(1e4), x)));
        prop_assert!(in_unit(special::gamma_inc_upper_reg(a, t.abs() * 10.0)));
        prop_assert!((special::norm_cdf(t / 8.0) + special::norm_sf(t / 8.0) - 1.0).abs() < 1e-15);
        // Round trip on the lower half, where p carries the quantile's precision.
        let p = special::norm_cdf(t / 8.0);
        if t <= 0.0 && p > 0.0 {
            prop_assert!((special::norm_ppf(p) - t / 8.0).abs() < 1e-9 * (1.0 + (t / 8.0).abs()));
        }
    }
}
