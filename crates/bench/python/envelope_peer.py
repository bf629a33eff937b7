#!/usr/bin/env python3
"""The Python peer of fogline's envelope analysis: an independent implementation with
pandas / NumPy / SciPy / scikit-learn, used as the benchmark baseline and as a cross-check.

It follows fogline's documented conventions (`fogline_envelope::conventions`, `text.rs`,
`threshold.rs`); it shares no code with fogline and draws its random numbers from NumPy, so
quantities that depend on random draws (bootstrap shares, GMM fits beyond clear structure)
agree only statistically.

    envelope_peer.py PAIRS.csv [--bootstrap 10000] [--restarts 20] [--k-max 8]
                     [--n-init 3] [--seed 0] [--json OUT.json]

Prints one line of JSON on stdout, `{"seconds": S, "phases": {...}}`, timed inside the
script (CSV reading included, interpreter start-up and imports excluded); with --json also
writes every result. Thread pools are pinned to one thread.

Conventions, in short:

- coc_changed: texts compared after whitespace normalisation (`" ".join(s.split())`);
  case and punctuation count.
- tokens: maximal runs of Unicode alphanumerics (regex `[^\\W_]+`), lower-cased; Jaccard over
  token sets, two token-less texts have Jaccard 1. (Python's and Rust's notions of
  "whitespace" and "alphanumeric" differ on a few exotic code points; ASCII agrees exactly.)
- axes: gaussian_noise (noise_<sigma>), fog (fog_XX -> alpha = XX/10), brightness split into
  darken (gain < 1, descending gain) and brighten (gain > 1); identity levels are skipped;
  gaussian_noise first, then alphabetical.
- groups: the paper's seven classified scenarios present (rank order), AGGREGATE_CLASSIFIED,
  AGGREGATE_ALL. Per group and level, mean clean and attacked ADE over the group's pairs at
  that level. A level passes budget b when mean_attacked < (1 + b) * mean_clean.
- first-violation: the largest level before the first failing one (none if the smallest
  fails; right-censored if none fails). max-passing: the largest passing level (none if none
  passes; right-censored if it is the largest level).
- bootstrap: clips resampled with replacement within each scenario label
  (numpy default_rng(seed)); aggregates are sums of their strata.
- GMM: GaussianMixture(k, covariance_type='full', n_init, reg_covar=1e-6, tol=1e-3,
  max_iter=200, random_state=r) for r in 0..restarts, k in 1..k_max on L2 of changed pairs;
  modal BIC-optimal k (ties -> smaller); final model = lowest-BIC fit at that k; bands sorted
  by mean; the top min(2, k-1) bands are high severity.
"""

import os

# Pin every thread pool before NumPy / SciPy / scikit-learn are imported.
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
             "BLIS_NUM_THREADS", "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import re  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from scipy import stats  # noqa: E402
from sklearn.exceptions import ConvergenceWarning  # noqa: E402
from sklearn.mixture import GaussianMixture  # noqa: E402
from sklearn.model_selection import KFold  # noqa: E402

PAPER_CLASSES = ["LANE_KEEPING", "NUDGE_RIGHT", "FOLLOW_VEHICLE", "PASSING", "TURN_RIGHT",
                 "STOP_SIGNAL", "INTERSECTION"]
OTHER = "OTHER"
AGG_CLASSIFIED = "AGGREGATE_CLASSIFIED"
AGG_ALL = "AGGREGATE_ALL"
RULES = ("first-violation", "max-passing")
TOKEN_RE = re.compile(r"[^\W_]+")

DEFAULTS = dict(
    budgets=(0.10, 0.15, 0.20),
    bootstrap=10_000,
    restarts=20,
    k_max=8,
    n_init=3,
    seed=0,
    cv_folds=5,
    per_scenario_k_max=6,
    high_bands=2,
    reg_covar=1e-6,
    tol=1e-3,
    max_iter=200,
    jaccard_low=0.10,
    jaccard_high=0.90,
    power_effect_size=0.10,
    alpha=0.05,
)


# ----------------------------------------------------------------------------------------
# Reading


COLUMN_ALIASES = {
    "condition": "attack",
    "ade_clean_m": "ade_clean",
    "ade_attacked_m": "ade_attacked",
    "l2_m": "l2",
}
TEXT_COLUMNS = ["clip_id", "scenario", "attack", "coc_clean", "coc_attacked"]
NUM_COLUMNS = ["ade_clean", "ade_attacked", "l2"]


def parse_condition(name):
    """(family, level) of a condition name of the paper's grid."""
    if name == "dark":
        return "brightness", 0.4
    if name == "bright":
        return "brightness", 1.6
    if name.startswith("noise_"):
        return "gaussian_noise", float(name[len("noise_"):])
    if name.startswith("fog_") and len(name) == 6 and name[4:].isdigit():
        return "fog", int(name[4:]) / 10
    raise ValueError(f"condition {name!r} is not one of the paper's grid")


def identity_level(family):
    return 1.0 if family == "brightness" else 0.0


def normalise_ws(text):
    return " ".join(text.split())


def token_set(text):
    return frozenset(t.lower() for t in TOKEN_RE.findall(text))


def jaccard(a, b):
    if not a and not b:
        return 1.0
    return len(a & b) / len(a | b)


def read_pairs(path):
    """Reads a pairs CSV into a DataFrame with `changed` and `jaccard` columns added."""
    head = pd.read_csv(path, nrows=0).columns
    rename = {c: COLUMN_ALIASES[c.strip()] for c in head if c.strip() in COLUMN_ALIASES}
    df = pd.read_csv(
        path,
        dtype={c: str for c in list(head)},
        keep_default_na=False,
        na_filter=False,
    )
    df.columns = [c.strip() for c in df.columns]
    df = df.rename(columns=rename)
    missing = [c for c in TEXT_COLUMNS + NUM_COLUMNS if c not in df.columns]
    if missing:
        raise SystemExit(f"{path}: missing columns {missing}")
    for c in NUM_COLUMNS:
        df[c] = df[c].astype(float)
    df["scenario"] = df["scenario"].str.strip()
    df["attack"] = df["attack"].str.strip()
    add_text_features(df)
    return df


def add_text_features(df):
    """coc_changed and token Jaccard, computed once per distinct text / text pair."""
    texts = pd.unique(pd.concat([df["coc_clean"], df["coc_attacked"]], ignore_index=True))
    norm = {t: normalise_ws(t) for t in texts}
    toks = {t: token_set(t) for t in texts}
    df["changed"] = df["coc_clean"].map(norm).to_numpy() != df["coc_attacked"].map(norm).to_numpy()
    pairs = df[["coc_clean", "coc_attacked"]].drop_duplicates()
    jac = {(a, b): jaccard(toks[a], toks[b])
           for a, b in zip(pairs["coc_clean"], pairs["coc_attacked"])}
    df["jaccard"] = [jac[(a, b)] for a, b in zip(df["coc_clean"], df["coc_attacked"])]


# ----------------------------------------------------------------------------------------
# Axes, groups, dose-response and thresholds


def level_key(x):
    """A level as Rust's `format!("{}", x)` prints it (70.0 -> "70", 0.4 -> "0.4")."""
    x = float(x)
    if x == int(x) and abs(x) < 1e15:
        return str(int(x))
    return repr(x)


def build_axes(df):
    """Ordered axes and the (axis index, level index) of every condition (None: identity)."""
    conds = list(pd.unique(df["attack"]))
    if "family" in df.columns and "level" in df.columns:
        fam_level = (df.drop_duplicates("attack").set_index("attack")[["family", "level"]])
    else:
        fam_level = None
    keyed = []
    for c in conds:
        if fam_level is not None and str(fam_level.loc[c, "family"]).strip():
            family = str(fam_level.loc[c, "family"]).strip()
            family = {"noise": "gaussian_noise", "photometric": "brightness"}.get(family, family)
            level = float(fam_level.loc[c, "level"])
        else:
            family, level = parse_condition(c)
        ident = identity_level(family)
        if family == "brightness":
            if level < ident:
                keyed.append(("darken", family, ident - level, level, c))
            elif level > ident:
                keyed.append(("brighten", family, level - ident, level, c))
        elif level != ident:
            keyed.append((family, family, level, level, c))
    keyed.sort(key=lambda t: (t[0], t[2]))
    axes = {}
    for axis, family, _, level, c in keyed:
        a = axes.setdefault(axis, dict(axis=axis, family=family, levels=[], conditions=[]))
        if level not in a["levels"]:
            a["levels"].append(level)
            a["conditions"].append([])
        a["conditions"][a["levels"].index(level)].append(c)
    order = sorted(axes, key=lambda n: (n != "gaussian_noise", n))
    axes = [axes[n] for n in order]
    slot_of = {}
    for ai, a in enumerate(axes):
        for li, cs in enumerate(a["conditions"]):
            for c in cs:
                slot_of[c] = (ai, li)
    return axes, slot_of


def build_groups(scenarios):
    """Taxonomy, classified scenarios present (rank order) and the group -> strata map."""
    present = list(scenarios)
    if any(s in PAPER_CLASSES for s in present):
        taxonomy = list(PAPER_CLASSES)
    else:
        taxonomy = sorted(set(s for s in present if s != OTHER))
    classified = [c for c in taxonomy if c in present]
    names = classified + [AGG_CLASSIFIED, AGG_ALL]
    strata = [[s] for s in classified] + [list(classified), present]
    return taxonomy, classified, names, strata


def threshold_outcome(mc, ma, cnt, budget, rule):
    """Index of the threshold level (None = none) and right-censoring, for one curve."""
    present = [i for i in range(len(mc)) if cnt[i] > 0]
    passes = [ma[i] < (1.0 + budget) * mc[i] for i in range(len(mc))]
    if rule == "first-violation":
        last_ok = None
        for i in present:
            if not passes[i]:
                return last_ok, False
            last_ok = i
        return last_ok, last_ok is not None
    best = None
    for i in reversed(present):
        if passes[i]:
            best = i
            break
    return best, best is not None and best == present[-1]


def threshold_ranks(mc, ma, cnt, budget, rule):
    """Vectorised `threshold_outcome` over resamples (rows): rank 0 = none, i + 1 = level i."""
    m = mc.shape[1]
    idx = np.arange(m)
    present = cnt > 0
    passes = ma < (1.0 + budget) * mc
    if rule == "first-violation":
        fail = present & ~passes
        first_fail = np.where(fail.any(axis=1), fail.argmax(axis=1), m)
        cand = present & (idx[None, :] < first_fail[:, None])
    else:
        cand = present & passes
    last = np.where(cand, idx[None, :], -1).max(axis=1)
    return last + 1


def ordinal_quantile(counts, q):
    """Smallest rank whose cumulative share reaches q (fogline's inverse-CDF convention)."""
    total = sum(counts)
    if total == 0:
        return None
    cum = 0
    for r, c in enumerate(counts):
        cum += c
        if cum >= q * total - 1e-9 * total:
            return r
    return len(counts) - 1


def clip_slot_matrix(df, axes, slot_of):
    """Per clip: [clean sums | attacked sums | counts] over the flattened (axis, level) slots."""
    offsets = np.cumsum([0] + [len(a["levels"]) for a in axes])
    ns = int(offsets[-1])
    clips, clip_idx = np.unique(df["clip_id"].to_numpy(), return_inverse=True)
    slot = np.array([offsets[slot_of[c][0]] + slot_of[c][1] if c in slot_of else -1
                     for c in df["attack"]])
    keep = slot >= 0
    v = np.zeros((len(clips), 3 * ns))
    ci, si = clip_idx[keep], slot[keep]
    np.add.at(v, (ci, si), df["ade_clean"].to_numpy()[keep])
    np.add.at(v, (ci, ns + si), df["ade_attacked"].to_numpy()[keep])
    np.add.at(v, (ci, 2 * ns + si), 1.0)
    clip_scen = df.groupby("clip_id", sort=True)["scenario"].first().reindex(clips).to_numpy()
    return v, clips, clip_scen, offsets, ns


def dose_and_thresholds(df, p, axes, slot_of, names, strata, classified):
    """Dose-response points and thresholds (both rules) per group, axis and budget."""
    offsets = np.cumsum([0] + [len(a["levels"]) for a in axes])
    clips_of = df.groupby("scenario")["clip_id"].nunique().to_dict()
    df = df[df["attack"].isin(list(slot_of))]
    slot = np.array([offsets[slot_of[c][0]] + slot_of[c][1] for c in df["attack"]])
    dose, thresholds, outcomes = [], [], {}
    for g, (name, ss) in enumerate(zip(names, strata)):
        sub = df[df["scenario"].isin(ss)]
        sl = slot[df["scenario"].isin(ss).to_numpy()]
        agg = (pd.DataFrame({"slot": sl, "c": sub["ade_clean"].to_numpy(),
                             "a": sub["ade_attacked"].to_numpy()})
               .groupby("slot").agg(n=("c", "size"), mc=("c", "mean"), ma=("a", "mean")))
        n_clips = int(sum(clips_of.get(s, 0) for s in ss))
        for ai, a in enumerate(axes):
            m = len(a["levels"])
            mc = np.zeros(m)
            ma = np.zeros(m)
            cnt = np.zeros(m)
            for li, level in enumerate(a["levels"]):
                s = offsets[ai] + li
                if s in agg.index:
                    mc[li], ma[li], cnt[li] = agg.loc[s, "mc"], agg.loc[s, "ma"], agg.loc[s, "n"]
                    dose.append(dict(
                        scenario=name, axis=a["axis"], level=level, n_pairs=int(cnt[li]),
                        mean_ade_clean_m=float(mc[li]), mean_ade_attacked_m=float(ma[li]),
                        delta_ade_m=float(ma[li] - mc[li]),
                        ratio=float(ma[li] / mc[li]) if mc[li] != 0 else None,
                        within_budget={repr(b): bool(ma[li] < (1 + b) * mc[li])
                                       for b in p["budgets"]},
                    ))
            for b in p["budgets"]:
                for rule in RULES:
                    li, censored = threshold_outcome(mc, ma, cnt, b, rule)
                    outcomes[(g, ai, b, rule)] = li
                    thresholds.append(dict(
                        scenario=name,
                        kind="scenario" if g < len(classified) else "aggregate",
                        axis=a["axis"], budget=b, rule=rule, n_clips=n_clips,
                        sigma_star=None if li is None else a["levels"][li],
                        right_censored=bool(censored),
                    ))
    g_all = len(names) - 1
    for t in thresholds:
        g = names.index(t["scenario"])
        ai = [a["axis"] for a in axes].index(t["axis"])
        if g < len(classified):
            mine = rank_of(outcomes[(g, ai, t["budget"], t["rule"])])
            agg = rank_of(outcomes[(g_all, ai, t["budget"], t["rule"])])
            t["vs_aggregate"] = "tighter" if mine < agg else ("matches" if mine == agg else "looser")
        else:
            t["vs_aggregate"] = None
    return dose, thresholds


def rank_of(level_index):
    return 0 if level_index is None else level_index + 1


def bootstrap(df, p, axes, slot_of, names, strata):
    """Stratified clip-level bootstrap: per (group, axis, budget, rule) the count of
    resamples at each rank, and per (group, slot) the resampled ΔADE values."""
    v, _, clip_scen, offsets, ns = clip_slot_matrix(df, axes, slot_of)
    n_boot = p["bootstrap"]
    rng = np.random.default_rng(p["seed"])
    labels = list(pd.unique(df["scenario"]))
    stratum_sums = {}
    for s in labels:
        vs = v[clip_scen == s]
        n_s = len(vs)
        draws = rng.integers(0, n_s, size=(n_boot, n_s))
        flat = (draws + n_s * np.arange(n_boot)[:, None]).ravel()
        weights = np.bincount(flat, minlength=n_boot * n_s).reshape(n_boot, n_s)
        stratum_sums[s] = weights.astype(float) @ vs
    counts, deltas = {}, {}
    for g, ss in enumerate(strata):
        tot = np.zeros((n_boot, 3 * ns))
        for s in ss:
            tot += stratum_sums[s]
        clean, att, cnt = tot[:, :ns], tot[:, ns:2 * ns], tot[:, 2 * ns:]
        with np.errstate(invalid="ignore", divide="ignore"):
            mc = np.where(cnt > 0, clean / cnt, 0.0)
            ma = np.where(cnt > 0, att / cnt, 0.0)
        for i in range(ns):
            deltas[(g, i)] = np.sort((ma - mc)[cnt[:, i] > 0, i])
        for ai, a in enumerate(axes):
            o, m = offsets[ai], len(a["levels"])
            for b in p["budgets"]:
                for rule in RULES:
                    r = threshold_ranks(mc[:, o:o + m], ma[:, o:o + m], cnt[:, o:o + m], b, rule)
                    counts[(g, ai, b, rule)] = np.bincount(r, minlength=m + 1).tolist()
    return counts, deltas, offsets


def attach_bootstrap(dose, thresholds, boot, p, axes, names):
    counts, deltas, offsets = boot
    axis_ix = {a["axis"]: i for i, a in enumerate(axes)}
    for d in dose:
        g, ai = names.index(d["scenario"]), axis_ix[d["axis"]]
        i = offsets[ai] + axes[ai]["levels"].index(d["level"])
        x = deltas[(g, i)]
        d["delta_ade_ci95_m"] = ([float(np.percentile(x, 2.5)), float(np.percentile(x, 97.5))]
                                 if len(x) else None)
    for t in thresholds:
        g, ai = names.index(t["scenario"]), axis_ix[t["axis"]]
        c = counts[(g, ai, t["budget"], t["rule"])]
        levels = axes[ai]["levels"]

        def value(r):
            return None if r is None or r == 0 else levels[r - 1]

        t["ci95"] = [value(ordinal_quantile(c, 0.025)), value(ordinal_quantile(c, 0.975))]
        t["bootstrap_share"] = {("none" if r == 0 else level_key(levels[r - 1])): n / p["bootstrap"]
                                for r, n in enumerate(c)}


# ----------------------------------------------------------------------------------------
# GMM severity bands


def gmm(k, p, random_state):
    return GaussianMixture(n_components=k, covariance_type="full", n_init=p["n_init"],
                           reg_covar=p["reg_covar"], tol=p["tol"], max_iter=p["max_iter"],
                           random_state=random_state)


def sorted_params(g):
    order = np.argsort(g.means_[:, 0], kind="stable")
    return order, g.means_[order, 0], np.sqrt(g.covariances_[order, 0, 0]), g.weights_[order]


def bic_study(x, p):
    """The paper's BIC study: restarts x k fits, modal k, lowest-BIC fit at that k."""
    X = x[:, None]
    n_distinct = len(np.unique(x))
    k_values = list(range(1, min(p["k_max"], n_distinct, len(x)) + 1))
    bic = np.zeros((p["restarts"], len(k_values)))
    fits = {}
    for r in range(p["restarts"]):
        for ki, k in enumerate(k_values):
            g = gmm(k, p, r).fit(X)
            bic[r, ki] = g.bic(X)
            fits[(r, k)] = g
    chosen = [k_values[int(np.argmin(row))] for row in bic]
    chosen_count = [chosen.count(k) for k in k_values]
    modal = k_values[int(np.argmax(chosen_count))]  # argmax: first maximum -> smaller k
    r_best = int(np.argmin(bic[:, modal - 1]))
    bic_min = bic.min(axis=0)
    rows = []
    for ki, k in enumerate(k_values):
        gain = float(bic_min[ki - 1] - bic_min[ki]) if ki > 0 else None
        rows.append(dict(k=k, per_seed=bic[:, ki].tolist(), min=float(bic_min[ki]),
                         chosen_count=chosen_count[ki], gain=gain))
    return dict(k_values=k_values, rows=rows, chosen_per_seed=chosen, chosen_k=modal,
                best_restart=r_best, model=fits[(r_best, modal)])


def cross_validate(x, k_values, p):
    """Held-out mean log-likelihood per k and fold (KFold(shuffle=True, random_state=seed))."""
    folds = p["cv_folds"]
    if folds < 2 or len(x) < 2 * folds:
        return None
    X = x[:, None]
    splits = list(KFold(n_splits=folds, shuffle=True, random_state=p["seed"]).split(X))
    if any(len(np.unique(x[tr])) < k_values[-1] for tr, _ in splits):
        return None
    ll = np.zeros((len(k_values), folds))
    for ki, k in enumerate(k_values):
        for f, (tr, te) in enumerate(splits):
            ll[ki, f] = gmm(k, p, p["seed"]).fit(X[tr]).score(X[te])
    return [dict(k=k, folds=ll[ki].tolist(), mean=float(ll[ki].mean()),
                 folds_beating_previous=0 if ki == 0 else int((ll[ki] > ll[ki - 1]).sum()))
            for ki, k in enumerate(k_values)]


def per_scenario_mixtures(x, scen, classified, p):
    out = []
    for s in classified:
        xs = x[scen == s]
        row = dict(scenario=s, n_changed=int(len(xs)), bic=[], chosen_k=None, reason=None)
        if len(xs) < 2:
            row["reason"] = f"{len(xs)} changed pairs; a mixture needs at least 2"
        else:
            X = xs[:, None]
            top = min(p["per_scenario_k_max"], len(np.unique(xs)), len(xs))
            bics = [(k, float(gmm(k, p, p["seed"]).fit(X).bic(X))) for k in range(1, top + 1)]
            row["bic"] = bics
            row["chosen_k"] = min(bics, key=lambda kb: kb[1])[0]
        out.append(row)
    return out


def bands_and_high(df, x, model, classified, names, strata, p):
    """Hard band assignment, band summary, high-severity shares and the joint table."""
    order, means, stds, weights = sorted_params(model)
    k = len(means)
    rank = np.empty(k, dtype=int)
    rank[order] = np.arange(k)
    band = rank[model.predict(x[:, None])]
    n_band = np.bincount(band, minlength=k)
    bands = [dict(name=f"C{j}", mean_m=float(means[j]), std_m=float(stds[j]),
                  weight=float(weights[j]), share=float(n_band[j] / len(x)), n=int(n_band[j]))
             for j in range(k)]
    n_high_bands = min(p["high_bands"], k - 1) if k >= 2 else 0
    high = band >= k - n_high_bands if n_high_bands > 0 else np.zeros(len(x), bool)
    ch = df[df["changed"]]
    scen, cond = ch["scenario"].to_numpy(), ch["attack"].to_numpy()

    def row(group, mask):
        n = int(mask.sum())
        h = int(high[mask].sum())
        return dict(group=group, n_changed=n, n_high=h,
                    share=(h / n) if n > 0 and n_high_bands > 0 else None,
                    mean_l2_changed_m=float(x[mask].mean()) if n > 0 else None)

    by_scenario = [row(name, np.isin(scen, ss)) for name, ss in zip(names, strata)]
    by_condition = [row(c, cond == c) for c in pd.unique(df["attack"])]
    counts = [[int(((scen == s) & (band == j)).sum()) for j in range(k)] for s in classified]
    return dict(
        bands=bands,
        high_severity=dict(bands=[f"C{j}" for j in range(k - n_high_bands, k)],
                           by_scenario=by_scenario, by_condition=by_condition),
        joint=dict(scenarios=list(classified), bands=[f"C{j}" for j in range(k)], counts=counts),
    )


def chi2_cramer(counts):
    """chi2_contingency(correction=False) and Cramér's V on the table without empty rows/cols."""
    t = np.asarray(counts, dtype=float)
    if t.size == 0:
        return None
    t = t[t.sum(axis=1) > 0][:, t.sum(axis=0) > 0]
    if t.shape[0] < 2 or t.shape[1] < 2:
        return None
    res = stats.chi2_contingency(t, correction=False)
    n = t.sum()
    v = math.sqrt(res.statistic / (n * (min(t.shape) - 1)))
    return dict(statistic=float(res.statistic), dof=int(res.dof), p_value=float(res.pvalue),
                cramers_v=float(v))


# ----------------------------------------------------------------------------------------
# Statistics


def finite_or_none(v):
    v = float(v)
    return v if math.isfinite(v) else None


def corr_dict(res, n):
    r, pv = finite_or_none(res[0]), finite_or_none(res[1])
    return None if r is None or pv is None else dict(r=r, p_value=pv, n=int(n))


def cohens_d(x, y):
    nx, ny = len(x), len(y)
    if nx < 1 or ny < 1 or nx + ny < 3:
        return None
    ss = (np.var(x, ddof=0) * nx) + (np.var(y, ddof=0) * ny)
    pooled = ss / (nx + ny - 2)
    if pooled <= 0:
        return None
    return float((np.mean(x) - np.mean(y)) / math.sqrt(pooled))


def power_normal(d, n1, n2, alpha):
    lam = abs(d) * math.sqrt(n1 * n2 / (n1 + n2))
    z = stats.norm.ppf(1 - alpha / 2)
    return float(min(1.0, stats.norm.cdf(lam - z) + stats.norm.cdf(-lam - z)))


def mwu_z(x, y):
    """SciPy's standardised two-sided statistic with tie and continuity correction."""
    n1, n2 = len(x), len(y)
    ranks = stats.rankdata(np.concatenate([x, y]))
    u1 = ranks[:n1].sum() - n1 * (n1 + 1) / 2
    u = max(u1, n1 * n2 - u1)
    _, t = np.unique(np.concatenate([x, y]), return_counts=True)
    n = n1 + n2
    tie = (t.astype(float) ** 3 - t).sum()
    s = math.sqrt(n1 * n2 / 12 * ((n + 1) - tie / (n * (n - 1))))
    return (u - n1 * n2 / 2 - 0.5) / s


def bimodality(x):
    n = len(x)
    if n < 4:
        return None
    g1 = stats.skew(x, bias=False)
    g2 = stats.kurtosis(x, fisher=True, bias=False)
    return finite_or_none((g1 ** 2 + 1) / (g2 + 3 * (n - 1) ** 2 / ((n - 2) * (n - 3))))


def icc(m):
    """ICC(2,1) and ICC(3,1) (Shrout & Fleiss) of a complete targets x raters matrix."""
    n, k = m.shape
    if n < 2 or k < 2 or m.min() == m.max():
        return None
    grand = m.mean()
    rm, cm = m.mean(axis=1), m.mean(axis=0)
    msr = k * ((rm - grand) ** 2).sum() / (n - 1)
    msc = n * ((cm - grand) ** 2).sum() / (k - 1)
    mse = ((m - rm[:, None] - cm[None, :] + grand) ** 2).sum() / ((n - 1) * (k - 1))
    icc2 = (msr - mse) / (msr + (k - 1) * mse + k * (msc - mse) / n)
    icc3 = (msr - mse) / (msr + (k - 1) * mse)
    return dict(icc2_1=float(icc2), icc3_1=float(icc3), n_clips=int(n), n_conditions=int(k))


def statistics(df, p, slot_of):
    changed = df["changed"].to_numpy()
    l2 = df["l2"].to_numpy()
    jac = df["jaccard"].to_numpy()
    l2c, l2u = l2[changed], l2[~changed]
    out = dict(n_pairs=int(len(df)), n_changed=int(changed.sum()),
               change_rate=float(changed.mean()))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if 0 < changed.sum() < len(df):
            pb = stats.pointbiserialr(changed, l2)
            out["point_biserial_r"] = finite_or_none(pb.statistic)
            out["point_biserial_p"] = finite_or_none(pb.pvalue)
        else:
            out["point_biserial_r"] = out["point_biserial_p"] = None
        out["cohens_d"] = cohens_d(l2c, l2u)
        out["mean_l2_changed_m"] = float(l2c.mean()) if len(l2c) else None
        out["mean_l2_unchanged_m"] = float(l2u.mean()) if len(l2u) else None
        out["l2_ratio"] = (out["mean_l2_changed_m"] / out["mean_l2_unchanged_m"]
                           if len(l2c) and len(l2u) and l2u.mean() > 0 else None)

        per_cond = (df[df["attack"].isin(list(slot_of))]
                    .groupby("attack").agg(rate=("changed", "mean"), l2=("l2", "mean")))
        out["change_rate_vs_l2"] = (corr_dict(stats.pearsonr(per_cond["rate"], per_cond["l2"]),
                                              len(per_cond)) if len(per_cond) >= 2 else None)

        jc = jac[changed]
        if len(jc) >= 2:
            jp = corr_dict(stats.pearsonr(jc, l2c), len(jc))
            js = corr_dict(stats.spearmanr(jc, l2c), len(jc))
        else:
            jp = js = None
        out["jaccard_l2_pearson"] = jp["r"] if jp else None
        out["jaccard_l2_spearman"] = js["r"] if js else None
        out["jaccard_l2"] = [jp, js] if jp and js else None

        low = l2c[jc < p["jaccard_low"]]
        mid = l2c[(jc >= p["jaccard_low"]) & (jc <= p["jaccard_high"])]
        mwu = None
        if len(low) and len(mid) and len(np.unique(np.concatenate([low, mid]))) > 1:
            m = stats.mannwhitneyu(low, mid, alternative="two-sided", use_continuity=True,
                                   method="asymptotic")
            d = cohens_d(low, mid)
            if d is not None:
                mwu = dict(u=float(m.statistic), z=float(mwu_z(low, mid)), p_value=float(m.pvalue),
                           cohens_d=d, n_low=int(len(low)), n_mid=int(len(mid)),
                           power_effect_size=p["power_effect_size"],
                           power=power_normal(p["power_effect_size"], len(low), len(mid),
                                              p["alpha"]))
        out["mwu"] = mwu
        out["bimodality_coefficient"] = bimodality(l2c)

    flips = (df.assign(flip=df["changed"].astype(float))
             .pivot(index="clip_id", columns="attack", values="flip"))
    # Over the conditions each clip has: never = all 0, always = all 1.
    out["never_flip_share"] = float((flips.fillna(0.0) == 0.0).all(axis=1).mean())
    out["always_flip_share"] = float((flips.fillna(1.0) == 1.0).all(axis=1).mean())
    out["icc"] = icc(flips.dropna().to_numpy())
    return out


# ----------------------------------------------------------------------------------------
# The whole analysis


def analyze(df, params=None, phases=None):
    """Runs the analysis on a DataFrame from `read_pairs`; returns a JSON-ready dict.
    `phases`, if given, receives the seconds spent per phase."""
    p = dict(DEFAULTS)
    p.update(params or {})
    p["budgets"] = [float(b) for b in p["budgets"]]
    phases = {} if phases is None else phases
    clock = [time.perf_counter()]

    def lap(name):
        now = time.perf_counter()
        phases[name] = phases.get(name, 0.0) + now - clock[0]
        clock[0] = now

    scen_order = list(pd.unique(df["scenario"]))
    taxonomy, classified, names, strata = build_groups(scen_order)
    axes, slot_of = build_axes(df)
    if not axes:
        raise SystemExit("no perturbed condition in the data")
    dose, thresholds = dose_and_thresholds(df, p, axes, slot_of, names, strata, classified)

    per_scen = df.groupby("scenario", sort=False).agg(
        n_clips=("clip_id", "nunique"), n_pairs=("clip_id", "size"),
        n_changed=("changed", "sum"), clean_ade_mean_m=("ade_clean", "mean"),
        flip_rate=("changed", "mean"))
    scenarios = [dict(scenario=s, rank=(taxonomy.index(s) + 1 if s in taxonomy else None),
                      classified=s in classified, n_clips=int(r.n_clips), n_pairs=int(r.n_pairs),
                      n_changed=int(r.n_changed), clean_ade_mean_m=float(r.clean_ade_mean_m),
                      flip_rate=float(r.flip_rate))
                 for s, r in per_scen.iterrows()]
    cell = df.assign(d=df["ade_attacked"] - df["ade_clean"])
    delta_map = []
    for name, ss in [(s, [s]) for s in scen_order] + [(AGG_CLASSIFIED, classified),
                                                      (AGG_ALL, scen_order)]:
        sub = cell[cell["scenario"].isin(ss)].groupby("attack", sort=False)["d"].agg(["size", "mean"])
        delta_map += [dict(scenario=name, condition=c, n_pairs=int(r["size"]),
                           delta_ade_m=float(r["mean"])) for c, r in sub.iterrows()]
    lap("dose_thresholds")

    if p["bootstrap"] > 0:
        boot = bootstrap(df, p, axes, slot_of, names, strata)
        attach_bootstrap(dose, thresholds, boot, p, axes, names)
    else:
        for d in dose:
            d["delta_ade_ci95_m"] = None
        for t in thresholds:
            t["ci95"] = None
            t["bootstrap_share"] = {}
    lap("bootstrap")

    changed = df["changed"].to_numpy()
    x = df["l2"].to_numpy()[changed]
    scen_changed = df["scenario"].to_numpy()[changed]
    severity = dict(defined=False, n_changed=int(len(x)))
    bands = None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        if len(x) >= 2:
            study = bic_study(x, p)
            lap("gmm_bic")
            cv = cross_validate(x, study["k_values"], p)
            lap("gmm_cv")
            per_scenario = per_scenario_mixtures(x, scen_changed, classified, p)
            lap("gmm_per_scenario")
            bands = bands_and_high(df, x, study["model"], classified, names, strata, p)
            severity = dict(defined=True, n_changed=int(len(x)), bic=study["rows"],
                            chosen_per_seed=study["chosen_per_seed"], chosen_k=study["chosen_k"],
                            best_restart=study["best_restart"], cv_loglik=cv,
                            bands=bands["bands"],
                            lower_bound=float(study["model"].lower_bound_),
                            per_scenario=per_scenario)
            lap("bands")

    st = statistics(df, p, slot_of)
    chi = chi2_cramer(bands["joint"]["counts"]) if bands else None
    st["chi2"] = None if chi is None else {k: chi[k] for k in ("statistic", "dof", "p_value")}
    st["cramers_v"] = None if chi is None else chi["cramers_v"]
    lap("statistics")

    return dict(
        generated_by="envelope_peer.py",
        parameters=p,
        corpus=dict(n_pairs=int(len(df)), n_clips=int(df["clip_id"].nunique()),
                    n_changed=int(changed.sum()), taxonomy=taxonomy, scenarios=scenarios),
        axes=axes,
        dose_response=dose,
        delta_ade_map=delta_map,
        thresholds=thresholds,
        severity=severity,
        high_severity=bands["high_severity"] if bands else None,
        joint=bands["joint"] if bands else None,
        statistics=st,
    )


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("pairs", help="pairs table (CSV)")
    ap.add_argument("--bootstrap", type=int, default=DEFAULTS["bootstrap"])
    ap.add_argument("--restarts", type=int, default=DEFAULTS["restarts"])
    ap.add_argument("--k-max", type=int, default=DEFAULTS["k_max"])
    ap.add_argument("--n-init", type=int, default=DEFAULTS["n_init"])
    ap.add_argument("--seed", type=int, default=DEFAULTS["seed"])
    ap.add_argument("--json", help="write every result to this file")
    a = ap.parse_args(argv)
    t0 = time.perf_counter()
    df = read_pairs(a.pairs)
    phases = {"read": time.perf_counter() - t0}
    result = analyze(df, dict(bootstrap=a.bootstrap, restarts=a.restarts, k_max=a.k_max,
                              n_init=a.n_init, seed=a.seed), phases)
    seconds = time.perf_counter() - t0
    if a.json:
        with open(a.json, "w") as f:
            json.dump(result, f, indent=1)
    print(json.dumps({"seconds": seconds, "phases": phases}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
