//! Gaussian noise against its law: moments on mid-grey and a χ² goodness-of-fit test.
//!
//! The expected law is computed here from `fogline_stats::special::norm_cdf`, independently
//! of the crate's sampling tables. Seeds are fixed, so the tests are deterministic; the
//! thresholds are set so that a correct sampler passes with the fixed seed and would pass for
//! almost any other (p > 1e-4 — a correct sampler fails one case with probability 1e-4 —,
//! moments within 5 standard errors). `the_chi2_test_rejects_a_wrong_law` shows the power:
//! a 2 % error in σ, or floor rounding, gives p < 1e-6.

use fogline_perturb::{Frame, FrameKey};
use fogline_stats::special::{chi2_sf, norm_cdf};

use crate::apply;

/// P(out = v) for v = 0..=255 when `x` gets rounded N(0, σ²) noise and is clipped.
fn law(x: i32, sigma: f64) -> Vec<f64> {
    let cdf = |k: f64| norm_cdf(k / sigma);
    (0..256)
        .map(|v: i32| {
            let k = f64::from(v - x);
            let lo = if v == 0 { 0.0 } else { cdf(k - 0.5) };
            let hi = if v == 255 { 1.0 } else { cdf(k + 0.5) };
            hi - lo
        })
        .collect()
}

fn counts(frame: &Frame) -> Vec<u64> {
    let mut c = vec![0u64; 256];
    for &v in frame.data() {
        c[v as usize] += 1;
    }
    c
}

/// Pearson's χ² of `observed` against `p` (bins with expected < 5 merged outward from the
/// tails into their neighbours); returns (statistic, degrees of freedom, p-value).
fn chi2(observed: &[u64], p: &[f64]) -> (f64, f64, f64) {
    let n: u64 = observed.iter().sum();
    let n = n as f64;
    let mut bins: Vec<(f64, f64)> = Vec::new(); // (observed, expected)
    let (mut o_acc, mut e_acc) = (0.0, 0.0);
    for (&o, &pv) in observed.iter().zip(p) {
        o_acc += o as f64;
        e_acc += n * pv;
        if e_acc >= 5.0 {
            bins.push((o_acc, e_acc));
            (o_acc, e_acc) = (0.0, 0.0);
        }
    }
    if let Some(last) = bins.last_mut() {
        last.0 += o_acc;
        last.1 += e_acc;
    }
    let stat: f64 = bins.iter().map(|(o, e)| (o - e) * (o - e) / e).sum();
    let df = (bins.len() - 1) as f64;
    (stat, df, chi2_sf(stat, df))
}

/// Mean, standard deviation of `out − x`, and their standard errors under the law.
struct Moments {
    mean: f64,
    std: f64,
    law_mean: f64,
    law_std: f64,
    se_mean: f64,
    se_std: f64,
}

fn moments(frame: &Frame, x: i32, sigma: f64) -> Moments {
    let data = frame.data();
    let n = data.len() as f64;
    let mean = data
        .iter()
        .map(|&v| f64::from(v) - f64::from(x))
        .sum::<f64>()
        / n;
    let var = data
        .iter()
        .map(|&v| (f64::from(v) - f64::from(x) - mean).powi(2))
        .sum::<f64>()
        / (n - 1.0);
    let p = law(x, sigma);
    let d = |v: usize| v as f64 - f64::from(x);
    let law_mean: f64 = p.iter().enumerate().map(|(v, pv)| pv * d(v)).sum();
    let m = |k: i32| -> f64 {
        p.iter()
            .enumerate()
            .map(|(v, pv)| pv * (d(v) - law_mean).powi(k))
            .sum()
    };
    let (m2, m4) = (m(2), m(4));
    Moments {
        mean,
        std: var.sqrt(),
        law_mean,
        law_std: m2.sqrt(),
        se_mean: (m2 / n).sqrt(),
        // delta method: Var(s) ≈ (μ4 − σ⁴) / (4 σ² n)
        se_std: ((m4 - m2 * m2) / (4.0 * m2 * n)).sqrt(),
    }
}

#[test]
fn noise_on_mid_grey_has_the_stated_mean_and_std() {
    let grey = Frame::filled(1920, 1080, [128, 128, 128]).unwrap();
    for (sigma, stated) in [(10.0, 10.00), (30.0, 30.00), (50.0, 49.50), (70.0, 65.73)] {
        let out = apply(
            &format!("noise_{sigma}"),
            2024,
            &grey,
            FrameKey::new(1, 0, 0),
        );
        let m = moments(&out, 128, sigma);
        // The exact law: mean shift −Φ(−127.5/σ) (128 is 128 levels from 0 but only 127 from
        // 255, so clipping is slightly asymmetric: −0.034 at σ = 70, 0.00 to two decimals for
        // σ <= 30), std 10.004 / 30.001 / 49.510 / 65.748 — the stated figures to within 0.02
        // (the reference's 65.73 is itself a sample estimate, one standard error off).
        assert!(
            (m.law_mean + norm_cdf(-127.5 / sigma)).abs() < 1e-12,
            "σ {sigma}: law mean {}",
            m.law_mean
        );
        assert!(
            (m.law_std - stated).abs() < 0.02,
            "σ {sigma}: law std {} vs stated {stated}",
            m.law_std
        );
        // The sample matches the law, and the stated figures, within 5 standard errors.
        assert!(
            (m.mean - m.law_mean).abs() < 5.0 * m.se_mean && m.mean.abs() < 5.0 * m.se_mean,
            "σ {sigma}: mean shift {} (law {}, se {})",
            m.mean,
            m.law_mean,
            m.se_mean
        );
        assert!(
            (m.std - m.law_std).abs() < 5.0 * m.se_std
                && (m.std - stated).abs() < 5.0 * m.se_std + 0.005,
            "σ {sigma}: std {} vs {} (se {})",
            m.std,
            m.law_std,
            m.se_std
        );
        eprintln!(
            "σ {sigma}: mean shift {:+.4} (law {:+.4}), std {:.4} (law {:.4}, stated {stated}), se {:.4}",
            m.mean, m.law_mean, m.std, m.law_std, m.se_std
        );
    }
}

#[test]
fn added_noise_passes_a_chi2_test_against_the_rounded_gaussian_law() {
    // Mid-grey and near-black (where clipping piles mass at 0).
    for (x, sigma) in [
        (128u8, 10.0),
        (128, 30.0),
        (128, 70.0),
        (5, 10.0),
        (250, 50.0),
    ] {
        let frame = Frame::filled(1024, 1024, [x, x, x]).unwrap();
        let out = apply(
            &format!("noise_{sigma}"),
            11,
            &frame,
            FrameKey::new(2, 0, 5),
        );
        let (stat, df, p) = chi2(&counts(&out), &law(i32::from(x), sigma));
        assert!(
            p > 1e-4,
            "x {x} σ {sigma}: χ² = {stat:.1} on {df} df, p = {p:.2e}"
        );
    }
}

#[test]
fn the_chi2_test_rejects_a_wrong_law() {
    // The test has power: the law of σ = 10 does not fit noise of σ = 10.2 (2 % off), nor
    // floor-rounded noise (what the Python peers do).
    let frame = Frame::filled(1024, 1024, [128, 128, 128]).unwrap();
    let out = apply("noise_10.2", 11, &frame, FrameKey::new(2, 0, 5));
    let (_, _, p) = chi2(&counts(&out), &law(128, 10.0));
    assert!(p < 1e-6, "p = {p:.2e}");
    let out = apply("noise_10", 11, &frame, FrameKey::new(2, 0, 5));
    let floored: Vec<f64> = (0..256)
        .map(|v: i32| {
            // floor(x + n) = x + k  ⇔  k <= n < k + 1
            let k = f64::from(v - 128);
            norm_cdf((k + 1.0) / 10.0) - norm_cdf(k / 10.0)
        })
        .collect();
    let (_, _, p) = chi2(&counts(&out), &floored);
    assert!(p < 1e-6, "p = {p:.2e}");
}

#[test]
fn shot_noise_has_poisson_moments() {
    // out = s·N, N ~ Poisson(x/s): mean x, variance s·x (no clipping at x = 64, s = 2).
    let frame = Frame::filled(512, 512, [64, 64, 64]).unwrap();
    let out = apply("shot_2", 3, &frame, FrameKey::default());
    let d = out.data();
    let n = d.len() as f64;
    let mean = d.iter().map(|&v| f64::from(v)).sum::<f64>() / n;
    let var = d
        .iter()
        .map(|&v| (f64::from(v) - mean).powi(2))
        .sum::<f64>()
        / (n - 1.0);
    assert!((mean - 64.0).abs() < 5.0 * (128.0 / n).sqrt(), "{mean}");
    assert!((var - 128.0).abs() < 128.0 * 0.02, "{var}");
    // Every output is a multiple of s.
    assert!(d.iter().all(|&v| v % 2 == 0));
}

#[test]
fn impulse_noise_hits_the_stated_fraction_half_salt_half_pepper() {
    let frame = Frame::filled(512, 512, [100, 100, 100]).unwrap();
    let out = apply("impulse_0.1", 3, &frame, FrameKey::default());
    let n = out.data().len() as f64;
    let zeros = out.data().iter().filter(|&&v| v == 0).count() as f64;
    let full = out.data().iter().filter(|&&v| v == 255).count() as f64;
    let se = (0.05 * 0.95 / n).sqrt();
    assert!((zeros / n - 0.05).abs() < 5.0 * se, "{}", zeros / n);
    assert!((full / n - 0.05).abs() < 5.0 * se, "{}", full / n);
    assert_eq!(
        zeros + full + out.data().iter().filter(|&&v| v == 100).count() as f64,
        n
    );
}
