//! Special functions: the normal distribution, log-gamma, the regularized incomplete beta and
//! gamma functions, and the Student t and chi-square tails built on them.
//!
//! Everything here is implemented in this file (no numerics crate) to full double precision:
//!
//! - `erfc` follows W. J. Cody's rational approximations (Math. Comp. 1969, as in `CALERF`),
//!   with `exp(-x²/2)` evaluated by Cody's split so that far tails keep their relative accuracy;
//! - `norm_ppf` is Wichura's AS 241 (`PPND16`) followed by one Halley step;
//! - `ln_gamma` uses the Taylor series of `ln Γ(1+ε)` around 1 and 2 (exact zeros there) and
//!   Stirling's series with its error term above 10;
//! - the incomplete beta and gamma functions use modified-Lentz continued fractions, power
//!   series where those converge faster, DiDonato & Morris' asymptotic expansion (TOMS 708's
//!   `BGRAT`) for a large first parameter with a small second one near `x = 1` (the Student t
//!   with many degrees of freedom, where the continued fraction loses digits), and prefactors
//!   `x^a y^b / B(a,b)` and `x^a e^-x / Γ(a)` computed through Stirling's error term and
//!   `log1p(s) - s`, so that parameters in the millions do not cancel catastrophically.
//!
//! Tails are always computed directly, never as `1 - cdf`: a p-value of 1e-250 comes out with
//! ~1e-13 relative error rather than as 0. The golden tests (`tests/it/golden.rs`, ~1400
//! points including far tails and parameters up to 5e6) hold every function to 1e-12 relative
//! against mpmath at 50 digits; the worst errors observed are 6e-13 for `beta_inc_reg` (at
//! `a = b = 5e6`, `x = 0.5`, where the continued fraction needs thousands of terms), 9e-14
//! for `t_sf`, `chi2_sf` and `gamma_inc_upper_reg`, and 4e-16 for the normal functions and
//! `ln_gamma`. SciPy itself is less accurate at a few points (e.g. `gammaln(1 - 1e-6)`,
//! `stdtr(1, -1e-8)`).
//!
//! These are plain `f64 -> f64` functions. They never fail; outside their domain (a negative
//! degree of freedom, a probability outside [0, 1], a NaN argument) they return NaN, as
//! `scipy.special` does. The statistics built on them validate their inputs first, so they
//! neither see nor return NaN. Each call costs O(1), except the continued fractions,
//! which need O(√max(a, b)) iterations for parameters near the distribution's centre.

use std::f64::consts::{FRAC_1_SQRT_2, PI};

/// `ln √(2π)`.
const LN_SQRT_2PI: f64 = 0.9189385332046728;
/// `1 / √π`.
const FRAC_1_SQRT_PI: f64 = 0.5641895835477563;
/// `√(2π)`.
const SQRT_2PI: f64 = 2.5066282746310007;
/// Values below this are treated as zero in the modified Lentz algorithm.
const TINY: f64 = 1e-300;
/// Convergence tolerance of series and continued fractions.
const EPS: f64 = f64::EPSILON;
/// Iteration cap of series and continued fractions (they need O(√a) terms near the centre,
/// so this covers parameters up to ~1e8).
const MAX_ITER: usize = 200_000;
/// From this `a` on (with small `b`, `x >= 1/2`), `I_x(a, b)` uses the large-`a` expansion.
const LARGE_A: f64 = 15.0;
/// Above this, `ln Γ` and the prefactors use Stirling's series with its error term.
const STIRLING_MIN: f64 = 10.0;

// W. J. Cody, "Rational Chebyshev approximations for the error function", Math. Comp. 23
// (1969), coefficients as in his CALERF routine.
const CODY_A: [f64; 5] = [
    3.1611237438705655,
    113.86415415105016,
    377.485237685302,
    3209.3775891384694,
    0.18577770618460315,
];
const CODY_B: [f64; 4] = [
    23.601290952344122,
    244.02463793444417,
    1282.6165260773723,
    2844.236833439171,
];
const CODY_C: [f64; 9] = [
    0.5641884969886701,
    8.883149794388377,
    66.11919063714163,
    298.6351381974001,
    881.952221241769,
    1712.0476126340707,
    2051.0783778260716,
    1230.3393547979972,
    2.1531153547440383e-08,
];
const CODY_D: [f64; 8] = [
    15.744926110709835,
    117.6939508913125,
    537.1811018620099,
    1621.3895745666903,
    3290.7992357334597,
    4362.619090143247,
    3439.3676741437216,
    1230.3393548037495,
];
const CODY_P: [f64; 6] = [
    0.30532663496123236,
    0.36034489994980445,
    0.12578172611122926,
    0.016083785148742275,
    0.0006587491615298378,
    0.016315387137302097,
];
const CODY_Q: [f64; 5] = [
    2.568520192289822,
    1.8729528499234604,
    0.5279051029514285,
    0.06051834131244132,
    0.0023352049762686918,
];

// M. J. Wichura, "Algorithm AS 241: the percentage points of the normal distribution",
// Appl. Statist. 37 (1988). Coefficients in increasing powers.
const AS241_A: [f64; 8] = [
    3.3871328727963665,
    133.14166789178438,
    1971.5909503065513,
    13731.69376550946,
    45921.95393154987,
    67265.7709270087,
    33430.57558358813,
    2509.0809287301227,
];
const AS241_B: [f64; 8] = [
    1.0,
    42.31333070160091,
    687.1870074920579,
    5394.196021424751,
    21213.794301586597,
    39307.89580009271,
    28729.085735721943,
    5226.495278852854,
];
const AS241_C: [f64; 8] = [
    1.4234371107496835,
    4.630337846156546,
    5.769497221460691,
    3.6478483247632045,
    1.2704582524523684,
    0.2417807251774506,
    0.022723844989269184,
    0.0007745450142783414,
];
const AS241_D: [f64; 8] = [
    1.0,
    2.053191626637759,
    1.6763848301838038,
    0.6897673349851,
    0.14810397642748008,
    0.015198666563616457,
    0.0005475938084995345,
    1.0507500716444169e-09,
];
const AS241_E: [f64; 8] = [
    6.657904643501103,
    5.463784911164114,
    1.7848265399172913,
    0.29656057182850487,
    0.026532189526576124,
    0.0012426609473880784,
    2.7115555687434876e-05,
    2.0103343992922881e-07,
];
const AS241_F: [f64; 8] = [
    1.0,
    0.599832206555888,
    0.1369298809227358,
    0.014875361290850615,
    0.0007868691311456133,
    1.8463183175100548e-05,
    1.421511758316446e-07,
    2.0442631033899397e-15,
];

/// `ln Γ(1 + ε) = Σ_{k≥1} c_k ε^k` with `c_1 = -γ`, `c_k = (-1)^k ζ(k) / k` (k ≤ 56, enough
/// for |ε| ≤ 1/2 to double precision; computed with mpmath).
const LGAMMA1P_SERIES: [f64; 56] = [
    -0.5772156649015329,
    0.8224670334241132,
    -0.40068563438653143,
    0.27058080842778454,
    -0.20738555102867398,
    0.1695571769974082,
    -0.1440498967688461,
    0.12550966952474304,
    -0.11133426586956469,
    0.1000994575127818,
    -0.09095401714582904,
    0.083353840546109,
    -0.0769325164113522,
    0.07143294629536133,
    -0.06666870588242046,
    0.06250095514121304,
    -0.058823978658684585,
    0.055555767627403614,
    -0.05263167937961666,
    0.05000004769810169,
    -0.047619070330142226,
    0.04545455629320467,
    -0.04347826605304026,
    0.04166666915034121,
    -0.04000000119214014,
    0.03846153903467518,
    -0.037037037312989324,
    0.035714285847333355,
    -0.034482758684919304,
    0.03333333336437758,
    -0.03225806453115042,
    0.03125000000727597,
    -0.030303030306558044,
    0.029411764707594344,
    -0.02857142857226011,
    0.027777777778181998,
    -0.027027027027223673,
    0.02631578947377995,
    -0.025641025641072283,
    0.025000000000022737,
    -0.024390243902450117,
    0.023809523809529224,
    -0.023255813953491015,
    0.02272727272727402,
    -0.022222222222222855,
    0.021739130434782917,
    -0.021276595744681003,
    0.02083333333333341,
    -0.02040816326530616,
    0.020000000000000018,
    -0.019607843137254912,
    0.019230769230769235,
    -0.01886792452830189,
    0.01851851851851852,
    -0.01818181818181818,
    0.017857142857142856,
];

/// Stirling's series `B_{2k} / (2k (2k-1))`, k = 1..9.
const STIRLING: [f64; 9] = [
    0.08333333333333333,
    -0.002777777777777778,
    0.0007936507936507937,
    -0.0005952380952380953,
    0.0008417508417508417,
    -0.0019175269175269176,
    0.00641025641025641,
    -0.029550653594771242,
    0.17964437236883057,
];

/// `ln(sinh(s/2) / (s/2)) = Σ_{k≥1} c_k s^{2k}` with `c_k = B_{2k} / (2k (2k)!)` (mpmath).
const LN_SINHC: [f64; 30] = [
    0.041666666666666664,
    -0.00034722222222222224,
    5.5114638447971785e-06,
    -1.033399470899471e-07,
    2.08767569878681e-09,
    -4.403491782239578e-11,
    9.55895466477477e-13,
    -2.1185501852016142e-14,
    4.770034475709914e-16,
    -1.087434349279031e-17,
    2.5040921947091955e-19,
    -5.814360285755218e-21,
    1.3595027075497952e-22,
    -3.1976847953705525e-24,
    7.559841507792277e-26,
    -1.7952470840225633e-27,
    4.279919045926073e-29,
    -1.0238874835181417e-30,
    2.4570353308144855e-32,
    -5.912556039251575e-34,
    1.4263504196386035e-35,
    -3.448761101064296e-37,
    8.355995924900409e-39,
    -2.0284068901347272e-40,
    4.932494088401362e-42,
    -1.2013609118886046e-43,
    2.93037597123054e-45,
    -7.157631582051671e-47,
    1.7505303199257856e-48,
    -4.286340263736453e-50,
];

/// Polynomial with coefficients in increasing powers, by Horner's rule.
#[inline]
fn poly(c: &[f64], x: f64) -> f64 {
    c.iter().rev().fold(0.0, |acc, &ci| acc * x + ci)
}

// ---------------------------------------------------------------------------------------------
// Normal distribution
// ---------------------------------------------------------------------------------------------

/// `erf(u)` for `|u| <= 0.46875` (Cody's first interval).
fn erf_small(u: f64) -> f64 {
    let ysq = u * u;
    let mut num = CODY_A[4] * ysq;
    let mut den = ysq;
    for i in 0..3 {
        num = (num + CODY_A[i]) * ysq;
        den = (den + CODY_B[i]) * ysq;
    }
    u * (num + CODY_A[3]) / (den + CODY_B[3])
}

/// `exp(y²) · erfc(y)` for `y > 0.46875` (Cody's second and third intervals).
fn erfcx_large(y: f64) -> f64 {
    if y <= 4.0 {
        let mut num = CODY_C[8] * y;
        let mut den = y;
        for i in 0..7 {
            num = (num + CODY_C[i]) * y;
            den = (den + CODY_D[i]) * y;
        }
        (num + CODY_C[7]) / (den + CODY_D[7])
    } else if y >= 6.71e7 {
        FRAC_1_SQRT_PI / y
    } else {
        let ysq = 1.0 / (y * y);
        let mut num = CODY_P[5] * ysq;
        let mut den = ysq;
        for i in 0..4 {
            num = (num + CODY_P[i]) * ysq;
            den = (den + CODY_Q[i]) * ysq;
        }
        let r = ysq * (num + CODY_P[4]) / (den + CODY_Q[4]);
        (FRAC_1_SQRT_PI - r) / y
    }
}

/// `exp(-x²/2)` for `0 <= x <= 40` without the relative error `x²·ε` of squaring first:
/// `x = xs + δ` with `xs` a multiple of 1/16, so `xs²` is exact (Cody's split).
fn exp_neg_half_sq(x: f64) -> f64 {
    let xs = (x * 16.0).trunc() / 16.0;
    let del = (x - xs) * (x + xs);
    (-0.5 * xs * xs).exp() * (-0.5 * del).exp()
}

/// Standard normal survival function `1 - Φ(x) = erfc(x/√2) / 2`, computed directly (never
/// as `1 - Φ`), so upper tails keep full relative precision down to the smallest subnormal.
///
/// Matches `scipy.stats.norm.sf` / `scipy.special.ndtr(-x)` to 1e-12 relative over the whole
/// line (golden-tested, including `x = 37`, sf ≈ 6e-300). NaN gives NaN. Cost O(1).
pub fn norm_sf(x: f64) -> f64 {
    if x.is_nan() {
        return f64::NAN;
    }
    let u = x * FRAC_1_SQRT_2;
    if u.abs() <= 0.46875 {
        return 0.5 - 0.5 * erf_small(u);
    }
    let ax = x.abs();
    let tail = if ax > 40.0 {
        0.0
    } else {
        0.5 * erfcx_large(u.abs()) * exp_neg_half_sq(ax)
    };
    if x > 0.0 { tail } else { 1.0 - tail }
}

/// Standard normal distribution function `Φ(x) = norm_sf(-x)`; the lower tail is computed
/// directly. Matches `scipy.stats.norm.cdf` / `scipy.special.ndtr` to 1e-12 relative. Cost O(1).
pub fn norm_cdf(x: f64) -> f64 {
    norm_sf(-x)
}

/// Standard normal quantile `Φ⁻¹(p)`, `p` in (0, 1).
///
/// Wichura's AS 241 (relative accuracy ~1e-16) refined by one Halley step on [`norm_cdf`]
/// (lower half) or [`norm_sf`] (upper half, using `1 - p`, exact there). `p = 0` gives -∞,
/// `p = 1` gives +∞ (as SciPy); `p` outside [0, 1] or NaN gives NaN. Matches
/// `scipy.stats.norm.ppf` / `scipy.special.ndtri` to 1e-12 relative, including `p = 1e-300`.
/// Cost O(1).
pub fn norm_ppf(p: f64) -> f64 {
    if p.is_nan() || !(0.0..=1.0).contains(&p) {
        return f64::NAN;
    }
    if p == 0.0 {
        return f64::NEG_INFINITY;
    }
    if p == 1.0 {
        return f64::INFINITY;
    }
    let q = p - 0.5;
    let mut x = if q.abs() <= 0.425 {
        let r = 0.180625 - q * q;
        q * poly(&AS241_A, r) / poly(&AS241_B, r)
    } else {
        let tail = if q < 0.0 { p } else { 1.0 - p };
        let r = (-tail.ln()).sqrt();
        let v = if r <= 5.0 {
            let r = r - 1.6;
            poly(&AS241_C, r) / poly(&AS241_D, r)
        } else {
            let r = r - 5.0;
            poly(&AS241_E, r) / poly(&AS241_F, r)
        };
        if q < 0.0 { -v } else { v }
    };
    // One Halley step on f(x) = Φ(x) - p, with the tail of the side p is on.
    let ax = x.abs();
    if ax <= 37.0 {
        let density = exp_neg_half_sq(ax) / SQRT_2PI;
        // Φ(x) - p, from the tail p lies in (1 - p is exact for p > 1/2).
        let f = if q <= 0.0 {
            norm_cdf(x) - p
        } else {
            (1.0 - p) - norm_sf(x)
        };
        let t = f / density;
        if t.is_finite() {
            x -= t / (1.0 + 0.5 * x * t);
        }
    }
    x
}

// ---------------------------------------------------------------------------------------------
// Gamma function
// ---------------------------------------------------------------------------------------------

/// `ln Γ(1 + ε)` for `|ε| <= 1/2`, by its Taylor series (exact zero at ε = 0).
fn lgamma1p_series(e: f64) -> f64 {
    e * poly(&LGAMMA1P_SERIES, e)
}

/// `ln Γ(1 + a)` for `0 <= a <= 1` without forming `1 + a` (keeps tiny `a` exact).
fn ln_gamma_1p(a: f64) -> f64 {
    if a <= 0.5 {
        lgamma1p_series(a)
    } else {
        let e = a - 1.0;
        e.ln_1p() + lgamma1p_series(e)
    }
}

/// Stirling's error term `ln Γ(x) - [(x - ½) ln x - x + ln √(2π)]` for `x >= 10`.
fn stirlerr(x: f64) -> f64 {
    let w = 1.0 / (x * x);
    poly(&STIRLING, w) / x
}

/// `ln Γ(x)` for `x > 0`.
fn ln_gamma_pos(x: f64) -> f64 {
    if x < 0.5 {
        ln_gamma_1p(x) - x.ln()
    } else if x < 1.5 {
        lgamma1p_series(x - 1.0)
    } else if x < 2.5 {
        let e = x - 2.0;
        e.ln_1p() + lgamma1p_series(e)
    } else if x < STIRLING_MIN {
        // ln Γ(x) = ln[(x-1)(x-2)…(y)] + ln Γ(y), y in [1.5, 2.5); the subtractions are exact.
        let mut y = x;
        let mut prod = 1.0;
        while y >= 2.5 {
            y -= 1.0;
            prod *= y;
        }
        prod.ln() + ln_gamma_pos(y)
    } else {
        (x - 0.5) * x.ln() - x + LN_SQRT_2PI + stirlerr(x)
    }
}

/// `sin(πx)` with exact argument reduction.
fn sin_pi(x: f64) -> f64 {
    let r = x % 2.0;
    let n = (2.0 * r).round();
    let f = r - 0.5 * n;
    let a = PI * f;
    match (n as i64).rem_euclid(4) {
        0 => a.sin(),
        1 => a.cos(),
        2 => -a.sin(),
        _ => -a.cos(),
    }
}

/// Natural log of the absolute value of the gamma function, `ln |Γ(x)|`.
///
/// Positive `x`: Taylor series of `ln Γ(1+ε)` on [0.5, 2.5) (so the zeros at 1 and 2 are
/// exact and nearby values keep full relative precision), exact downward recurrence on
/// [2.5, 10), Stirling's series with 9 terms above. Negative non-integers use the reflection
/// formula. Poles (0, -1, -2, …) and +∞ give +∞, NaN gives NaN (as `scipy.special.gammaln`).
/// Relative error ≲ 1e-15 for `x > 0`, including next to the zeros at 1 and 2 where
/// `scipy.special.gammaln` loses digits (golden-tested against mpmath to 1e-12; observed
/// 4e-16). Cost O(1).
pub fn ln_gamma(x: f64) -> f64 {
    if x.is_nan() {
        return f64::NAN;
    }
    if x == f64::INFINITY {
        return f64::INFINITY;
    }
    if x <= 0.0 {
        if x == x.floor() {
            return f64::INFINITY;
        }
        let s = sin_pi(x).abs();
        return (PI / s).ln() - ln_gamma_pos(1.0 - x);
    }
    ln_gamma_pos(x)
}

/// `ln(1 + s) - s`, accurate for small `|s|` (no cancellation): with `u = s / (2 + s)`,
/// `ln(1+s) = 2 atanh(u)`, so `ln(1+s) - s = -s·u + 2(u³/3 + u⁵/5 + …)`.
fn log1pmx(s: f64) -> f64 {
    if s.abs() >= 0.5 {
        return s.ln_1p() - s;
    }
    let u = s / (2.0 + s);
    let u2 = u * u;
    let mut pow = u * u2;
    let mut sum = 0.0;
    let mut k = 3.0;
    loop {
        let term = pow / k;
        sum += term;
        if term.abs() <= sum.abs() * 1e-17 {
            break;
        }
        pow *= u2;
        k += 2.0;
    }
    -s * u + 2.0 * sum
}

/// `a · (ln r - s)` where `r = 1 + s`, given `ln r` separately for large `|s|`.
fn scaled_log1pmx(a: f64, s: f64, ln_r: f64) -> f64 {
    if s.abs() < 0.5 {
        a * log1pmx(s)
    } else {
        a * (ln_r - s)
    }
}

/// `ln(x^a e^{-x} / Γ(a))` for `a > 0`, `x > 0`.
fn ln_gamma_prefix(a: f64, x: f64) -> f64 {
    if a < STIRLING_MIN {
        a * x.ln() - x - ln_gamma(a)
    } else {
        // a ln x - x - ln Γ(a) = a [ln(x/a) - (x/a - 1)] + ½ ln a - ln √(2π) - stirlerr(a)
        let s = (x - a) / a;
        scaled_log1pmx(a, s, (x / a).ln()) + 0.5 * a.ln() - LN_SQRT_2PI - stirlerr(a)
    }
}

/// Regularized lower incomplete gamma `P(a, x)` by its power series (for `x < a + 1`).
fn gamma_p_series(a: f64, x: f64) -> f64 {
    let mut sum = 1.0;
    let mut term = 1.0;
    let mut ap = a;
    for _ in 0..MAX_ITER {
        ap += 1.0;
        term *= x / ap;
        sum += term;
        if term <= sum * EPS {
            break;
        }
    }
    (ln_gamma_prefix(a, x) + (sum / a).ln()).exp()
}

/// `Γ(a, x) e^x x^{-a}` by the continued fraction of `Q(a, x)` (modified Lentz), for
/// `x >= a + 1` or (`a < 1`, `x >= 1.5`).
fn gamma_q_cf_scaled(a: f64, x: f64) -> f64 {
    let mut b = x + 1.0 - a;
    let mut c = 1.0 / TINY;
    let mut d = 1.0 / b;
    let mut h = d;
    for i in 1..MAX_ITER {
        let fi = i as f64;
        let an = -fi * (fi - a);
        b += 2.0;
        d = an * d + b;
        if d.abs() < TINY {
            d = TINY;
        }
        c = b + an / c;
        if c.abs() < TINY {
            c = TINY;
        }
        d = 1.0 / d;
        let del = d * c;
        h *= del;
        if (del - 1.0).abs() <= EPS {
            break;
        }
    }
    h
}

/// Whether the continued fraction of `Q(a, x)` converges fast.
fn gamma_cf_region(a: f64, x: f64) -> bool {
    if a < 1.0 { x >= 1.5 } else { x >= a + 1.0 }
}

/// `Γ(a, x) e^x x^{-a}` for `a > 0`, `x > 0` (no overflow for the `x` used here).
fn gamma_upper_scaled(a: f64, x: f64) -> f64 {
    if gamma_cf_region(a, x) {
        gamma_q_cf_scaled(a, x)
    } else {
        gamma_inc_upper_reg(a, x) * (ln_gamma(a) + x - a * x.ln()).exp()
    }
}

/// `Q(a, x)` for `a < 1`, `x < 1.5`, without cancellation (Q ≈ a·E₁(x) for tiny a):
/// `Q = -expm1(a ln x - ln Γ(1+a)) - (x^a/Γ(1+a)) Σ_{n≥1} a (-x)^n / (n! (a+n))`.
fn gamma_q_small_a(a: f64, x: f64) -> f64 {
    let la = a * x.ln() - ln_gamma_1p(a);
    let first = -la.exp_m1();
    let mut term = 1.0;
    let mut sum = 0.0;
    for n in 1..MAX_ITER {
        let fnn = n as f64;
        term *= -x / fnn;
        let t = term / (a + fnn);
        sum += t;
        if t.abs() <= sum.abs() * EPS {
            break;
        }
    }
    first - la.exp() * (a * sum)
}

/// Regularized upper incomplete gamma function `Q(a, x) = Γ(a, x) / Γ(a)`, `a > 0`, `x >= 0`.
///
/// Power series for `P` when `x < a + 1` (where `Q` is not small, so `1 - P` is accurate), a
/// cancellation-free series when `a < 1` and `x < 1.5`, otherwise a modified-Lentz
/// continued fraction for `Q` itself, so far upper tails keep full relative precision. Matches
/// `scipy.special.gammaincc` to 1e-12 relative (golden-tested against mpmath). `x = 0` gives 1,
/// `x = ∞` gives 0; `a <= 0`, `a = ∞`, `x < 0` or NaN give NaN. Cost O(1) away from `x ≈ a`,
/// O(√a) iterations near it.
pub fn gamma_inc_upper_reg(a: f64, x: f64) -> f64 {
    if a.is_nan() || x.is_nan() || a <= 0.0 || a.is_infinite() || x < 0.0 {
        return f64::NAN;
    }
    if x == 0.0 {
        return 1.0;
    }
    if x.is_infinite() {
        return 0.0;
    }
    if gamma_cf_region(a, x) {
        (ln_gamma_prefix(a, x) + gamma_q_cf_scaled(a, x).ln()).exp()
    } else if a < 1.0 {
        gamma_q_small_a(a, x)
    } else {
        1.0 - gamma_p_series(a, x)
    }
}

// ---------------------------------------------------------------------------------------------
// Incomplete beta
// ---------------------------------------------------------------------------------------------

/// `ln(x^a y^b / B(a, b))` with `y = 1 - x` given separately (whichever of `x`, `y` is
/// smaller is taken as exact). Large parameters go through Stirling's error term so that
/// `ln Γ(a+b) - ln Γ(a) - ln Γ(b)` does not cancel.
fn ln_beta_prefix(a: f64, b: f64, x: f64, y: f64) -> f64 {
    let lnx = if x <= 0.5 { x.ln() } else { (-y).ln_1p() };
    let lny = if y <= 0.5 { y.ln() } else { (-x).ln_1p() };
    if a >= STIRLING_MIN && b >= STIRLING_MIN {
        // a ln(x/x0) + b ln(y/y0) + ½ ln(ab/(a+b)) - ln √(2π) + Δstirlerr, x0 = a/(a+b);
        // the linear parts of the two logs cancel exactly, leaving a·log1pmx + b·log1pmx.
        let ab = a + b;
        // t = x b - y a = x (a+b) - a = b - y (a+b), from whichever of x, y is exact, with
        // a+b as a double-double and one rounding (fma): t's relative error is multiplied by
        // a·s² in the exponent.
        let bb = ab - a;
        let ab_err = (a - (ab - bb)) + (b - bb);
        let t = if x <= y {
            x.mul_add(ab, -a) + x * ab_err
        } else {
            (-y).mul_add(ab, b) - y * ab_err
        };
        let sx = t / a;
        let sy = -t / b;
        let core =
            scaled_log1pmx(a, sx, lnx + (ab / a).ln()) + scaled_log1pmx(b, sy, lny + (ab / b).ln());
        core + 0.5 * (a / ab * b).ln() - LN_SQRT_2PI + stirlerr(ab) - stirlerr(a) - stirlerr(b)
    } else if a >= STIRLING_MIN {
        a * lnx + b * lny - ln_beta_large_a(a, b)
    } else if b >= STIRLING_MIN {
        a * lnx + b * lny - ln_beta_large_a(b, a)
    } else {
        a * lnx + b * lny + ln_gamma(a + b) - ln_gamma(a) - ln_gamma(b)
    }
}

/// `ln B(a, b)` for `a >= 10` through Stirling's error term:
/// `ln Γ(a+b) - ln Γ(a) = (a - ½) ln1p(b/a) + b ln(a+b) - b + stirlerr(a+b) - stirlerr(a)`.
fn ln_beta_large_a(a: f64, b: f64) -> f64 {
    let ab = a + b;
    ln_gamma(b) - ((a - 0.5) * (b / a).ln_1p() + b * ab.ln() - b + stirlerr(ab) - stirlerr(a))
}

/// `(I_x(a, b), 1 - I_x(a, b))` for large `a` and small `b` by the asymptotic expansion of
/// DiDonato & Morris (TOMS 708's `BGRAT`, after Temme). With `T = a + (b-1)/2`,
/// `ℓ = -ln x` (from `y`, so accurate for `x` near 1 where the continued fraction loses about
/// `1/y` of its digits) and `z = Tℓ`,
/// `I_x(a, b) = ℓ^b e^{-z} / B(a, b) · Σ_n d_n G_n`, `G_n = T^{-2n} Γ(b+2n, z) e^z z^{-b}`,
/// where `d_n` are the coefficients of `(sinh(s/2)/(s/2))^{b-1}` in `s^{2n}`; the complement
/// uses the lower incomplete gamma function the same way.
fn beta_inc_large_a(a: f64, b: f64, x: f64, y: f64) -> (f64, f64) {
    const TERMS: usize = 30;
    let ell = if x <= 0.5 { -x.ln() } else { -(-y).ln_1p() };
    let t = a + 0.5 * (b - 1.0);
    let z = t * ell;
    let ln_pf = b * ell.ln() - z - ln_beta_large_a(a, b);
    // Coefficients of exp((b-1) ln sinhc) by the recurrence n d_n = Σ k g_k d_{n-k}.
    let mut d = [0.0f64; TERMS + 1];
    d[0] = 1.0;
    for n in 1..=TERMS {
        let mut s = 0.0;
        for k in 1..=n {
            s += k as f64 * (b - 1.0) * LN_SINHC[k - 1] * d[n - k];
        }
        d[n] = s / n as f64;
    }
    let ell2 = ell * ell;
    let inv_t2 = 1.0 / (t * t);
    let mut g = gamma_upper_scaled(b, z);
    let mut sum = g;
    let mut pow = 1.0;
    for n in 0..TERMS {
        let s = b + 2.0 * n as f64;
        g = inv_t2 * (s * (s + 1.0) * g + (s + 1.0 + z) * pow);
        pow *= ell2;
        let term = d[n + 1] * g;
        sum += term;
        if term.abs() <= EPS * sum.abs() {
            break;
        }
    }
    let upper = (ln_pf + sum.ln()).exp();
    if upper <= 0.5 {
        return (upper, 1.0 - upper);
    }
    // The complement is the small one: sum T^{-(b+2n)} γ(b+2n, z) directly (z is small here).
    let mut lower = 0.0;
    let mut pow = 1.0;
    for n in 0..=TERMS {
        let s = b + 2.0 * n as f64;
        let (mut term, mut series, mut k) = (1.0, 1.0, 1.0);
        while term > series * EPS && k < 1000.0 {
            term *= z / (s + k);
            series += term;
            k += 1.0;
        }
        let c = d[n] * pow / s * series;
        lower += c;
        if n > 0 && c.abs() <= EPS * lower.abs() {
            break;
        }
        pow *= ell2;
    }
    let lower = (ln_pf + lower.ln()).exp();
    (1.0 - lower, lower)
}

/// Continued fraction of the incomplete beta function (modified Lentz, Numerical Recipes'
/// `betacf`); converges fast for `x < (a+1)/(a+b+2)`.
fn beta_cf(a: f64, b: f64, x: f64) -> f64 {
    let qab = a + b;
    let qap = a + 1.0;
    let qam = a - 1.0;
    let mut c = 1.0;
    let mut d = 1.0 - qab * x / qap;
    if d.abs() < TINY {
        d = TINY;
    }
    d = 1.0 / d;
    let mut h = d;
    for m in 1..MAX_ITER {
        let m = m as f64;
        let m2 = 2.0 * m;
        let aa = m * (b - m) * x / ((qam + m2) * (a + m2));
        d = 1.0 + aa * d;
        if d.abs() < TINY {
            d = TINY;
        }
        c = 1.0 + aa / c;
        if c.abs() < TINY {
            c = TINY;
        }
        d = 1.0 / d;
        h *= d * c;
        let aa = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2));
        d = 1.0 + aa * d;
        if d.abs() < TINY {
            d = TINY;
        }
        c = 1.0 + aa / c;
        if c.abs() < TINY {
            c = TINY;
        }
        d = 1.0 / d;
        let del = d * c;
        h *= del;
        if (del - 1.0).abs() <= EPS {
            break;
        }
    }
    h
}

/// Whether `(a, b)` is in the domain of [`beta_inc_large_a`]: `a >= 15` with `b <= 1` (TOMS
/// 708's condition), or `b <= 10` with `a >= 100 b` (where its terms still fall by a factor
/// of ~100 or more each).
fn large_a_regime(a: f64, b: f64) -> bool {
    a >= LARGE_A && (b <= 1.0 || (b <= 10.0 && a >= 100.0 * b))
}

/// `(I_x(a, b), 1 - I_x(a, b))` with `y = 1 - x` given separately; the one on the continued
/// fraction's side is computed directly, so whichever tail is small keeps relative precision.
pub(crate) fn beta_inc_pair(a: f64, b: f64, x: f64, y: f64) -> (f64, f64) {
    if x <= 0.0 {
        return (0.0, 1.0);
    }
    if y <= 0.0 {
        return (1.0, 0.0);
    }
    if large_a_regime(a, b) && x >= 0.5 {
        return beta_inc_large_a(a, b, x, y);
    }
    if large_a_regime(b, a) && y >= 0.5 {
        let (j, i) = beta_inc_large_a(b, a, y, x);
        return (i, j);
    }
    if x < (a + 1.0) / (a + b + 2.0) {
        let w = (ln_beta_prefix(a, b, x, y) + (beta_cf(a, b, x) / a).ln()).exp();
        (w, 1.0 - w)
    } else {
        let w = (ln_beta_prefix(b, a, y, x) + (beta_cf(b, a, y) / b).ln()).exp();
        (1.0 - w, w)
    }
}

/// Regularized incomplete beta function `I_x(a, b)`, `a, b > 0`, `x` in [0, 1].
///
/// Continued fraction (modified Lentz) on `x` when `x < (a+1)/(a+b+2)`, else `1 - I_{1-x}(b, a)`
/// with the complement's fraction, so the lower tail keeps full relative precision; the
/// prefactor `x^a (1-x)^b / B(a,b)` goes through Stirling's error term for large parameters.
/// When one parameter is large (>= 15, and >= 100× the other unless that is <= 1) and `x`
/// lies on its side of 1/2, the asymptotic expansion of DiDonato & Morris is used instead,
/// in terms of `ln x` taken from `1 - x` (the continued fraction would lose ~`1/(1-x)` of
/// its digits there). Matches `scipy.special.betainc` to 1e-12 relative (golden-tested
/// against mpmath, parameters from 0.1 to 5e6). `a` or `b` not positive and finite, `x`
/// outside [0, 1], or NaN give NaN. Cost O(1) in the tails and for the expansion,
/// O(√max(a, b)) iterations near the centre.
pub fn beta_inc_reg(a: f64, b: f64, x: f64) -> f64 {
    if a.is_nan()
        || b.is_nan()
        || x.is_nan()
        || a <= 0.0
        || b <= 0.0
        || a.is_infinite()
        || b.is_infinite()
    {
        return f64::NAN;
    }
    if !(0.0..=1.0).contains(&x) {
        return f64::NAN;
    }
    beta_inc_pair(a, b, x, 1.0 - x).0
}

/// Student t survival function `P(T > t)` with `df > 0` degrees of freedom (non-integer
/// allowed): `½ I_{df/(df+t²)}(df/2, ½)` for `t > 0`, `½ + ½ I_{t²/(df+t²)}(½, df/2)` for
/// `t < 0`, both arguments formed without cancellation.
///
/// For `df >= 30` and `t² <= df` the large-parameter expansion is used (elsewhere the continued
/// fraction is far from its threshold), so `df` in the millions keeps full precision. Matches `scipy.stats.t.sf` / `scipy.special.stdtr(df, -t)` to 1e-12 relative
/// (golden-tested against mpmath for `df` from 1 to 1e7, including p-values near 1e-300).
/// `df = ∞` gives [`norm_sf`]; `df <= 0` or NaN give NaN. Cost O(1) for `df >= 30`, as
/// [`beta_inc_reg`] otherwise.
pub fn t_sf(t: f64, df: f64) -> f64 {
    if t.is_nan() || df.is_nan() || df <= 0.0 {
        return f64::NAN;
    }
    if df.is_infinite() {
        return norm_sf(t);
    }
    if t == 0.0 {
        return 0.5;
    }
    if t.is_infinite() {
        return if t > 0.0 { 0.0 } else { 1.0 };
    }
    let tt = t * t;
    let (x, y) = if tt.is_finite() {
        let den = df + tt;
        (df / den, tt / den)
    } else {
        ((df / t) / t, 1.0)
    };
    let (ix, jx) = beta_inc_pair(0.5 * df, 0.5, x, y);
    if t > 0.0 { 0.5 * ix } else { 0.5 + 0.5 * jx }
}

/// Chi-square survival function `P(X > x)` with `df > 0` degrees of freedom:
/// `Q(df/2, x/2)` ([`gamma_inc_upper_reg`]).
///
/// Matches `scipy.stats.chi2.sf` / `scipy.special.chdtrc` to 1e-12 relative, including
/// p-values near 1e-300. `x <= 0` gives 1; `df <= 0` or NaN give NaN. Cost O(1), O(√df) near
/// `x ≈ df`.
pub fn chi2_sf(x: f64, df: f64) -> f64 {
    if x.is_nan() || df.is_nan() || df <= 0.0 || df.is_infinite() {
        return f64::NAN;
    }
    if x <= 0.0 {
        return 1.0;
    }
    gamma_inc_upper_reg(0.5 * df, 0.5 * x)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rel(a: f64, b: f64) -> f64 {
        if a == b {
            0.0
        } else {
            (a - b).abs() / a.abs().max(b.abs())
        }
    }

    #[test]
    fn normal_known_values() {
        assert_eq!(norm_cdf(0.0), 0.5);
        assert!(rel(norm_cdf(1.959963984540054), 0.975) < 1e-15);
        assert!(rel(norm_ppf(0.975), 1.959963984540054) < 1e-15);
        assert!(norm_sf(38.0) > 0.0);
        assert_eq!(norm_ppf(0.0), f64::NEG_INFINITY);
        assert!(norm_ppf(1.5).is_nan());
    }

    #[test]
    fn ln_gamma_known_values() {
        assert_eq!(ln_gamma(1.0), 0.0);
        assert_eq!(ln_gamma(2.0), 0.0);
        assert!(rel(ln_gamma(0.5), 0.5 * PI.ln()) < 1e-15);
        assert!(rel(ln_gamma(10.0), 362880f64.ln()) < 1e-15);
        assert!(rel(ln_gamma(101.0), 363.73937555556347) < 1e-15);
        assert_eq!(ln_gamma(-2.0), f64::INFINITY);
    }

    #[test]
    fn incomplete_functions_special_cases() {
        // I_x(1, 1) = x; Q(1, x) = e^{-x}; t with 1 df is Cauchy.
        assert!(rel(beta_inc_reg(1.0, 1.0, 0.3), 0.3) < 1e-15);
        assert!(rel(gamma_inc_upper_reg(1.0, 3.0), (-3.0f64).exp()) < 1e-15);
        assert!(rel(t_sf(1.0, 1.0), 0.25) < 1e-15);
        assert!(rel(chi2_sf(2.0, 2.0), (-1.0f64).exp()) < 1e-15);
        assert!(chi2_sf(1300.0, 1.0) > 0.0);
        assert!(t_sf(1e6, 3.0) > 0.0);
    }
}
