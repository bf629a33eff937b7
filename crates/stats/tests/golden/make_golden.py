#!/usr/bin/env python3
"""Writes stats.json: inputs and SciPy's outputs for the golden tests of fogline-stats.

Run from anywhere:  python3 crates/stats/tests/golden/make_golden.py
Needs numpy, scipy and mpmath (mpmath ships with SymPy). Deterministic: every random input
comes from numpy.random.default_rng(SEED). Inputs are rounded to a few decimals so the file
stays small; they are stored as exactly the doubles SciPy saw (repr round-trips).

Layout:
  meta:     versions and seed
  special:  [{fn, args, mp, scipy}]  special functions; `mp` is mpmath at 50 digits (the
            truth), `scipy` the scipy.special / scipy.stats value
  cases:    [{fn, name, args, expect | error: true}]  statistics; `expect` holds SciPy's
            outputs (or, where noted in `note`, fogline's documented convention)
"""

import json
import math
import warnings
from pathlib import Path

import mpmath as mp
import numpy as np
import scipy
import scipy.special as sc
from scipy import stats

SEED = 20240611
mp.mp.dps = 50
rng = np.random.default_rng(SEED)
warnings.simplefilter("ignore")


def fl(v):
    """A Python float (JSON number) from a numpy or mpmath scalar."""
    return float(v)


def rounded(a, decimals=4):
    return [float(v) for v in np.round(np.asarray(a, dtype=float), decimals)]


# ---------------------------------------------------------------------------------------------
# Special functions
# ---------------------------------------------------------------------------------------------

special = []


def add_special(fn, args, truth, sp):
    truth = fl(truth)
    sp = fl(sp)
    # Keep only points whose value is representable and nonzero (or exactly 0/1 limits).
    if math.isnan(truth) or math.isnan(sp):
        return
    special.append({"fn": fn, "args": [fl(a) for a in args], "mp": truth, "scipy": sp})


norm_x = sorted(
    set(
        [0.0, 1e-300, 1e-10, 0.3, 0.46875 * math.sqrt(2), 0.5, 0.6629126073623883, 0.7, 1.0,
         1.5, 1.959963984540054, 2.5, 3.0, 4.0, 5.0, 5.656854249492381, 5.7, 6.0, 7.5, 8.0,
         10.0, 12.5, 15.0, 20.0, 25.0, 30.0, 33.3, 35.0, 37.0, 37.5, 38.0]
    )
)
for x in norm_x:
    for s in (x, -x):
        add_special("norm_cdf", [s], mp.ncdf(s), stats.norm.cdf(s))
        add_special("norm_sf", [s], mp.ncdf(-mp.mpf(s)), stats.norm.sf(s))

ppf_p = [1e-300, 1e-250, 1e-200, 1e-150, 1e-100, 1e-50, 1e-30, 1e-20, 1e-15, 1e-10, 1e-7,
         1e-5, 1e-3, 0.01, 0.025, 0.05, 0.1, 0.2, 0.3, 0.4, 0.45, 0.5, 0.55, 0.6, 0.75, 0.9,
         0.95, 0.975, 0.99, 0.999, 1 - 1e-5, 1 - 1e-10, 1 - 2**-40, 1 - 2**-52]
for p in ppf_p:
    x0 = stats.norm.ppf(p)
    pm = mp.mpf(p)
    # Solved in log space on the tail p lies in (1 - p is exact for p >= 1/2).
    if p < 0.5:
        root = mp.findroot(lambda x: mp.log(mp.ncdf(x)) - mp.log(pm), mp.mpf(x0))
    else:
        root = mp.findroot(lambda x: mp.log(mp.ncdf(-x)) - mp.log(1 - pm), mp.mpf(x0))
    add_special("norm_ppf", [p], root, x0)

lg_x = [1e-300, 1e-20, 1e-8, 1e-3, 0.1, 0.25, 0.5, 0.75, 0.9, 0.99, 0.999999, 1.0, 1.000001,
        1.01, 1.1, 1.25, 1.4616321449683622, 1.5, 1.75, 1.9, 1.99, 2.0, 2.01, 2.1, 2.4, 2.5,
        2.6, 3.0, 3.7, 5.5, 9.99, 10.0, 10.01, 12.5, 30.0, 100.0, 171.5, 1000.5, 1e5, 1e10,
        1e15, 1e100, 1e300, -0.5, -1.5, -2.3, -10.7, -100.25]
for x in lg_x:
    add_special("ln_gamma", [x], mp.log(abs(mp.gamma(x))) if x < 0 else mp.loggamma(x), sc.gammaln(x))

def _betacf_mp(a, b, x):
    """Continued fraction of I_x(a, b) (Numerical Recipes' betacf) in 50-digit arithmetic."""
    tiny = mp.mpf("1e-300")
    qab, qap, qam = a + b, a + 1, a - 1
    c, d = mp.mpf(1), 1 - qab * x / qap
    d = 1 / (d if abs(d) > tiny else tiny)
    h = d
    for m in range(1, 2_000_000):
        m2 = 2 * m
        aa = m * (b - m) * x / ((qam + m2) * (a + m2))
        d = 1 + aa * d
        d = 1 / (d if abs(d) > tiny else tiny)
        c = 1 + aa / c
        h *= d * c
        aa = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2))
        d = 1 + aa * d
        d = 1 / (d if abs(d) > tiny else tiny)
        c = 1 + aa / c
        delta = d * c
        h *= delta
        if abs(delta - 1) < mp.mpf(10) ** (-45):
            return h
    raise RuntimeError("betacf did not converge")


def betainc_mp(a, b, x):
    """Regularized I_x(a, b) to ~45 digits. mpmath's own betainc (hypergeometric series)
    fails to converge for large parameters, so this evaluates the continued fraction in
    50-digit arithmetic instead, cross-checked against mp.betainc where that converges."""
    a, b, x = mp.mpf(a), mp.mpf(b), mp.mpf(x)
    if x == 0:
        return mp.mpf(0)
    if x == 1:
        return mp.mpf(1)
    lnpre = a * mp.log(x) + b * mp.log(1 - x) - (mp.loggamma(a) + mp.loggamma(b) - mp.loggamma(a + b))
    if x < (a + 1) / (a + b + 2):
        return mp.exp(lnpre) * _betacf_mp(a, b, x) / a
    return 1 - mp.exp(lnpre) * _betacf_mp(b, a, 1 - x) / b


for (a, b, x) in [(0.5, 0.5, 0.3), (2.5, 10.0, 0.1), (37.5, 1.0, 0.99), (10.0, 200.0, 0.05)]:
    ref = mp.betainc(a, b, 0, x, regularized=True)
    assert abs(betainc_mp(a, b, x) / ref - 1) < mp.mpf(10) ** -40, (a, b, x)


beta_ab = [0.5, 1.0, 2.5, 10.0, 37.5, 200.0, 5000.0, 250000.0]
beta_x = [1e-10, 1e-3, 0.01, 0.1, 0.3, 0.5, 0.7, 0.9, 0.99, 0.999]
for a in beta_ab:
    for b in beta_ab:
        if a * b > 1e7:
            continue
        for x in beta_x:
            v = betainc_mp(a, b, x)
            if v < mp.mpf("1e-300"):
                continue
            add_special("beta_inc_reg", [a, b, x], v, sc.betainc(a, b, x))
# Near the centre of large symmetric parameters (Pearson p-values for large n).
for a in [500.0, 5e4, 5e6]:
    for x in [0.5 - 3 / math.sqrt(a), 0.5 - 10 / math.sqrt(a), 0.5 - 1 / math.sqrt(a), 0.5]:
        v = betainc_mp(a, a, x)
        add_special("beta_inc_reg", [a, a, x], v, sc.betainc(a, a, x))

# Large a with small b near x = 1: the t distribution with many degrees of freedom
# (asymptotic-expansion path), and moderate b where the continued fraction is used.
for a in [15.0, 16.0, 50.0, 1e3, 1e5, 5e6]:
    for b in [0.1, 0.5, 1.0, 2.0, 5.0]:
        for x in [0.5, 0.9, 0.99, 1 - 1e-4, 1 - 1e-6, 1 - 1e-8]:
            if b >= 2.0 and a < 1e3:
                continue
            v = betainc_mp(a, b, x)
            if v < mp.mpf("1e-300"):
                continue
            add_special("beta_inc_reg", [a, b, x], v, sc.betainc(a, b, x))
            w = betainc_mp(b, a, 1 - x)
            if w >= mp.mpf("1e-300"):
                add_special("beta_inc_reg", [b, a, 1 - x], w, sc.betainc(b, a, 1 - x))

gam_a = [1e-3, 0.1, 0.5, 0.9, 1.0, 2.5, 10.0, 50.5, 500.0, 1e4]
gam_fac = [1e-3, 0.1, 0.5, 0.9, 0.99, 1.0, 1.01, 1.1, 2.0, 5.0, 20.0]
for a in gam_a:
    xs = [a * f for f in gam_fac] + [0.01, 0.5, 1.0, 1.4, 1.6, 3.0, 30.0, 300.0, 650.0]
    for x in sorted(set(xs)):
        v = mp.gammainc(a, x, mp.inf, regularized=True)
        if v < mp.mpf("1e-300"):
            continue
        add_special("gamma_inc_upper_reg", [a, x], v, sc.gammaincc(a, x))


def t_sf_mp(t, df):
    t, df = mp.mpf(t), mp.mpf(df)
    if t == 0:
        return mp.mpf("0.5")
    x = df / (df + t * t)
    half = betainc_mp(df / 2, mp.mpf("0.5"), x) / 2
    return half if t > 0 else 1 - half


for df in [1.0, 2.0, 3.0, 4.5, 10.0, 29.0, 30.0, 31.0, 60.0, 100.0, 998.0, 3e4, 1e5, 1e7]:
    for t in [-50.0, -5.0, -3.0, -1.0, -0.1, 0.0, 1e-8, 0.01, 0.1, 0.5, 1.0, 2.0, 3.0, 5.0,
              10.0, 30.0, 40.0, 100.0, 1e3, 1e6]:
        v = t_sf_mp(t, df)
        if v < mp.mpf("1e-300"):
            continue
        add_special("t_sf", [t, df], v, stats.t.sf(t, df))

for df in [1.0, 2.0, 3.0, 5.0, 10.0, 24.0, 99.0, 1000.0]:
    for x in sorted(set([1e-6, 0.01, 0.5 * df, 0.9 * df, df, 1.1 * df, 2 * df, 5 * df, 10 * df,
                         50.0, 300.0, 1300.0])):
        v = mp.gammainc(mp.mpf(df) / 2, mp.mpf(x) / 2, mp.inf, regularized=True)
        if v < mp.mpf("1e-300"):
            continue
        add_special("chi2_sf", [x, df], v, stats.chi2.sf(x, df))

# ---------------------------------------------------------------------------------------------
# Statistics
# ---------------------------------------------------------------------------------------------

cases = []


def case(fn, name, args, expect=None, note=None):
    c = {"fn": fn, "name": name, "args": args}
    if expect is None:
        c["error"] = True
    else:
        c["expect"] = expect
    if note:
        c["note"] = note
    cases.append(c)


def finite_or_none(v):
    v = float(v)
    return None if math.isnan(v) or math.isinf(v) else v


# describe -------------------------------------------------------------------------------------
def describe_case(name, x):
    x = np.asarray(x, dtype=float)
    n = len(x)
    args = {"x": [float(v) for v in x]}
    case("mean", name, args, {"value": fl(np.mean(x))} if n >= 1 else None)
    for ddof in (0, 1):
        case(f"variance_ddof{ddof}", name, args,
             {"value": fl(np.var(x, ddof=ddof))} if n > ddof else None)
    g = finite_or_none(stats.skew(x, bias=False)) if n >= 3 else None
    k = finite_or_none(stats.kurtosis(x, fisher=True, bias=False)) if n >= 4 else None
    case("skewness", name, args, None if g is None else {"value": g})
    case("excess_kurtosis", name, args, None if k is None else {"value": k})
    if g is None or k is None:
        case("bimodality_coefficient", name, args)
    else:
        bc = (g * g + 1) / (k + 3 * (n - 1) ** 2 / ((n - 2) * (n - 3)))
        case("bimodality_coefficient", name, args, {"value": bc})


describe_case("normal_200", rounded(rng.normal(3.0, 2.0, 200)))
describe_case("lognormal_300", rounded(rng.lognormal(0.0, 0.8, 300)))
describe_case("bimodal_400", rounded(np.concatenate([rng.normal(-2, 0.7, 200), rng.normal(2.5, 1.0, 200)])))
describe_case("int_ties_150", [float(v) for v in rng.integers(0, 5, 150)])
describe_case("offset_1e6", rounded(1e6 + rng.normal(0, 1, 60), 3))
describe_case("n1", [4.25])
describe_case("n2", [1.0, 3.5])
describe_case("n3", [1.0, 2.0, 7.0])
describe_case("n4", [1.0, 2.0, 7.0, -3.5])
describe_case("constant_10", [2.5] * 10)


# correlation ----------------------------------------------------------------------------------
def corr_pair(n, rho, integer=False, decimals=3):
    z1 = rng.normal(size=n)
    z2 = rho * z1 + math.sqrt(1 - rho * rho) * rng.normal(size=n)
    if integer:
        return [float(v) for v in np.round(z1 * 2)], [float(v) for v in np.round(z2 * 2)]
    return rounded(z1, decimals), rounded(z2, decimals)


def corr_cases(name, x, y, spearman=True, pearson=True):
    args = {"x": x, "y": y}
    xa, ya = np.asarray(x), np.asarray(y)
    const = np.all(xa == xa[0]) or np.all(ya == ya[0])
    if pearson:
        if const:
            case("pearson", name, args)
        else:
            r = stats.pearsonr(xa, ya)
            case("pearson", name, args, {"r": fl(r.statistic), "p_value": fl(r.pvalue), "n": len(x)})
    if spearman:
        if const:
            case("spearman", name, args)
        elif len(x) == 2:
            r = np.sign(x[1] - x[0]) * np.sign(y[1] - y[0])
            case("spearman", name, args, {"r": fl(r), "p_value": 1.0, "n": 2},
                 note="SciPy's spearmanr gives p = nan for n = 2; fogline follows pearsonr (p = 1)")
        else:
            r = stats.spearmanr(xa, ya)
            case("spearman", name, args, {"r": fl(r.statistic), "p_value": fl(r.pvalue), "n": len(x)})


corr_cases("n2", [1.0, 2.0], [5.0, 3.0])
corr_cases("n3", [1.0, 2.0, 4.0], [2.0, 1.0, 5.0])
corr_cases("n4_ties", [1.0, 2.0, 2.0, 3.0], [4.0, 4.0, 1.0, 0.0])
corr_cases("normal_50_rho03", *corr_pair(50, 0.3))
corr_cases("int_ties_200_rho05", *corr_pair(200, 0.5, integer=True))
corr_cases("normal_500_rho08_tiny_p", *corr_pair(500, 0.8))
corr_cases("normal_1000_rho06_tiny_p", *corr_pair(1000, 0.6, decimals=2))
corr_cases("normal_800_rho09_p_1e-280", *corr_pair(800, 0.905, decimals=3))
corr_cases("constant_y", [1.0, 2.0, 3.0, 4.0], [2.0, 2.0, 2.0, 2.0])
xm = rounded(rng.normal(size=30), 3)
corr_cases("monotone_nonlinear_30", xm, [float(v) for v in np.exp(xm)], pearson=False)


def pb_case(name, flags, y):
    args = {"flags": flags, "y": y}
    if all(flags) or not any(flags) or all(v == y[0] for v in y):
        case("point_biserial", name, args)
        return
    r = stats.pointbiserialr(np.asarray(flags, dtype=bool), np.asarray(y))
    case("point_biserial", name, args, {"r": fl(r.statistic), "p_value": fl(r.pvalue), "n": len(y)})


f = rng.random(120) < 0.3
pb_case("flags_120", [bool(v) for v in f], rounded(rng.normal(size=120) + 0.6 * f, 3))
f = rng.random(600) < 0.5
pb_case("flags_600_tiny_p", [bool(v) for v in f], rounded(rng.normal(size=600) + 2.2 * f, 2))
pb_case("n2", [True, False], [1.0, 3.0])
pb_case("all_true", [True] * 5, [1.0, 2.0, 3.0, 4.0, 5.0])


# Mann-Whitney ---------------------------------------------------------------------------------
def mwu_case(name, x, y):
    args = {"x": x, "y": y}
    xy = np.concatenate([x, y])
    if np.all(xy == xy[0]):
        case("mann_whitney_u", name, args)
        return
    res = stats.mannwhitneyu(x, y, alternative="two-sided", use_continuity=True, method="asymptotic")
    # SciPy does not return z; recompute it exactly as scipy.stats._mannwhitneyu._get_mwu_z.
    n1, n2 = len(x), len(y)
    ranks = stats.rankdata(xy)
    _, t = np.unique(xy, return_counts=True)
    t = t.astype(float)
    u1 = ranks[:n1].sum() - n1 * (n1 + 1) / 2
    u = max(u1, n1 * n2 - u1)
    s = np.sqrt(n1 * n2 / 12 * ((n1 + n2 + 1) - (t**3 - t).sum() / ((n1 + n2) * (n1 + n2 - 1))))
    z = (u - n1 * n2 / 2 - 0.5) / s
    assert u1 == res.statistic
    case("mann_whitney_u", name, args,
         {"u": fl(res.statistic), "z": fl(z), "p_value": fl(res.pvalue), "n_x": n1, "n_y": n2})


mwu_case("n1_n1", [1.0], [2.0])
mwu_case("n1_n3", [2.0], [1.0, 3.0, 4.0])
mwu_case("n3_n4", [1.0, 2.5, 3.0], [4.0, 5.0, 0.5, 6.0])
mwu_case("ties_40_50", [float(v) for v in rng.integers(0, 6, 40)], [float(v) for v in rng.integers(1, 7, 50)])
mwu_case("normal_200_250", rounded(rng.normal(0, 1, 200), 3), rounded(rng.normal(0.3, 1, 250), 3))
mwu_case("equal_medians_60_60", rounded(rng.normal(0, 1, 60), 3), rounded(rng.normal(0, 1, 60), 3))
mwu_case("separated_900_900_p_1e-295", rounded(rng.uniform(0, 1, 900), 3), rounded(rng.uniform(2, 3, 900), 3))
mwu_case("separated_ties_300_200", [float(v) for v in rng.integers(0, 10, 300)],
         [float(v) for v in rng.integers(9, 20, 200)])
mwu_case("all_equal", [3.0, 3.0], [3.0, 3.0, 3.0])


# effect sizes ---------------------------------------------------------------------------------
def d_case(name, x, y):
    args = {"x": x, "y": y}
    nx, ny = len(x), len(y)
    if nx < 1 or ny < 1 or nx + ny < 3:
        case("cohens_d", name, args)
        return
    xa, ya = np.asarray(x), np.asarray(y)
    ssx = ((xa - xa.mean()) ** 2).sum()
    ssy = ((ya - ya.mean()) ** 2).sum()
    pooled = (ssx + ssy) / (nx + ny - 2)
    if pooled == 0:
        case("cohens_d", name, args)
        return
    case("cohens_d", name, args, {"value": fl((xa.mean() - ya.mean()) / np.sqrt(pooled))})


d_case("normal_80_90", rounded(rng.normal(1.0, 2.0, 80), 3), rounded(rng.normal(0.0, 1.5, 90), 3))
d_case("n1_n2", [1.0], [2.0, 4.0])
d_case("ties_30_30", [float(v) for v in rng.integers(0, 4, 30)], [float(v) for v in rng.integers(1, 5, 30)])
d_case("constant_both", [1.0, 1.0], [1.0, 1.0, 1.0])
d_case("n1_n1", [1.0], [2.0])

for d in [0.0, 0.2, 0.5, 1.2, -0.8, 3.0]:
    for nx, ny in [(1, 1), (10, 10), (64, 64), (30, 80), (1000, 5)]:
        for alpha in [0.05, 0.01, 0.2]:
            lam = abs(d) * math.sqrt(nx * ny / (nx + ny))
            z = stats.norm.ppf(1 - alpha / 2)
            power = stats.norm.cdf(lam - z) + stats.norm.cdf(-lam - z)
            case("two_sample_power", f"d{d}_n{nx}x{ny}_a{alpha}",
                 {"d": d, "n_x": nx, "n_y": ny, "alpha": alpha}, {"value": fl(power)})
case("two_sample_power", "alpha_1", {"d": 0.5, "n_x": 10, "n_y": 10, "alpha": 1.0})
case("two_sample_power", "n_zero", {"d": 0.5, "n_x": 0, "n_y": 10, "alpha": 0.05})


# contingency ----------------------------------------------------------------------------------
def chi2_case(name, table):
    args = {"table": table}
    t = np.asarray(table, dtype=float)
    t = t[t.sum(axis=1) > 0][:, t.sum(axis=0) > 0] if t.size else t
    if t.ndim != 2 or t.shape[0] < 2 or t.shape[1] < 2:
        case("chi2_contingency", name, args)
        return
    res = stats.chi2_contingency(t, correction=False)
    if np.all(t == np.round(t)):
        v = stats.contingency.association(t.astype(np.int64), method="cramer")
    else:
        v = math.sqrt(res.statistic / t.sum() / (min(t.shape) - 1))
    case("chi2_contingency", name, args,
         {"statistic": fl(res.statistic), "dof": int(res.dof), "p_value": fl(res.pvalue),
          "n": fl(t.sum()), "cramers_v": fl(v), "rows_used": t.shape[0], "cols_used": t.shape[1]},
         note="SciPy run on the table with zero rows/columns removed")


chi2_case("2x2", [[12.0, 5.0], [7.0, 15.0]])
chi2_case("3x4_random", [[float(v) for v in row] for row in rng.integers(0, 30, (3, 4))])
chi2_case("zero_row_and_col", [[10.0, 0.0, 4.0], [0.0, 0.0, 0.0], [3.0, 0.0, 9.0], [5.0, 0.0, 5.0]])
chi2_case("2x2_p_1e-270", [[660.0, 12.0], [14.0, 650.0]])
chi2_case("3x3_tiny_p", [[300.0, 20.0, 10.0], [15.0, 280.0, 30.0], [12.0, 25.0, 290.0]])
chi2_case("fractional_2x3", [[1.5, 2.25, 7.0], [4.0, 0.5, 3.75]])
chi2_case("one_nonempty_row", [[0.0, 0.0], [3.0, 4.0]])
chi2_case("independent_4x2", [[10.0, 20.0], [20.0, 40.0], [5.0, 10.0], [1.0, 2.0]])


# ICC ------------------------------------------------------------------------------------------
def icc_case(name, m):
    args = {"matrix": m}
    a = np.asarray(m, dtype=float)
    n, k = a.shape
    if n < 2 or k < 2 or np.all(a == a.flat[0]):
        case("icc", name, args)
        return
    g = a.mean()
    rm = a.mean(axis=1)
    cm = a.mean(axis=0)
    msr = k * ((rm - g) ** 2).sum() / (n - 1)
    msc = n * ((cm - g) ** 2).sum() / (k - 1)
    mse = ((a - rm[:, None] - cm[None, :] + g) ** 2).sum() / ((n - 1) * (k - 1))
    icc2 = (msr - mse) / (msr + (k - 1) * mse + k * (msc - mse) / n)
    icc3 = (msr - mse) / (msr + (k - 1) * mse)
    case("icc", name, args,
         {"icc2_1": fl(icc2), "icc3_1": fl(icc3), "n_targets": n, "n_raters": k,
          "ms_rows": fl(msr), "ms_cols": fl(msc), "ms_error": fl(mse)})


targets = rng.normal(0, 2, 20)
icc_case("20x4_rater_offsets",
         [rounded(targets[i] + np.array([0.0, 0.5, -0.3, 1.0]) + rng.normal(0, 0.7, 4), 3) for i in range(20)])
targets = rng.normal(0, 1, 10)
icc_case("10x2", [rounded(targets[i] + rng.normal(0, 0.3, 2), 3) for i in range(10)])
icc_case("2x2", [[1.0, 2.0], [3.0, 5.0]])
icc_case("noise_only_15x3", [rounded(rng.normal(0, 1, 3), 3) for _ in range(15)])
icc_case("constant", [[2.0, 2.0], [2.0, 2.0], [2.0, 2.0]])
icc_case("one_row", [[1.0, 2.0, 3.0]])

out = {
    "meta": {
        "generator": "crates/stats/tests/golden/make_golden.py",
        "seed": SEED,
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "mpmath": mp.__version__,
    },
    "special": special,
    "cases": cases,
}
path = Path(__file__).with_name("stats.json")
path.write_text(json.dumps(out, indent=None, separators=(",", ":")) + "\n")
print(f"wrote {path} ({path.stat().st_size} bytes, {len(special)} special points, {len(cases)} cases)")
