#!/usr/bin/env python3
"""Golden values for fogline-stats' 1-D Gaussian mixture (src/gmm.rs).

Writes tests/golden/gmm.json (next to this script). For each data set (deterministic
numpy data, rounded to 4 decimals so the JSON holds the exact values fitted) it runs

    GaussianMixture(k, covariance_type="full", n_init=3, reg_covar=1e-6, tol=1e-3,
                    max_iter=200, random_state=s).fit(X)

for k = 1..8 and s = 0..19 (the paper's 20 restarts), and stores the BIC table, the
minimum BIC per k, the k chosen by BIC per seed, the modal k (ties -> smaller k), and the
lowest-BIC fit at the true k and at the modal k (components sorted by mean).

Run:  python3 tests/golden/make_gmm_golden.py     (about 30 s)
"""

import json
import os
import platform
import warnings

import numpy as np
import scipy
import sklearn
from sklearn.exceptions import ConvergenceWarning
from sklearn.mixture import GaussianMixture

K_MAX = 8
SEEDS = list(range(20))
N_INIT = 3
REG_COVAR = 1e-6
TOL = 1e-3
MAX_ITER = 200


def mixture(seed, n, means, sds, shares):
    """n points: component j gets floor(share_j * n) points (the first takes the rest)."""
    rng = np.random.default_rng(seed)
    w = np.asarray(shares, float)
    w /= w.sum()
    counts = np.floor(w * n).astype(int)
    counts[0] += n - counts.sum()
    x = np.concatenate([rng.normal(m, s, c) for m, s, c in zip(means, sds, counts)])
    rng.shuffle(x)
    return x


def data_sets():
    sets = []
    sets.append(dict(name="two_300", true_k=2,
                     x=mixture(101, 300, [0.0, 6.0], [1.0, 0.8], [0.7, 0.3])))
    sets.append(dict(name="three_1500", true_k=3,
                     x=mixture(102, 1500, [-4.0, 2.0, 9.0], [1.0, 0.6, 1.5], [0.5, 0.3, 0.2])))
    sets.append(dict(name="six_6000", true_k=6,
                     x=mixture(103, 6000, [0.0, 10.0, 20.0, 30.0, 40.0, 50.0],
                               [1.0, 1.2, 0.8, 1.5, 1.0, 0.9],
                               [0.30, 0.20, 0.15, 0.15, 0.12, 0.08])))
    # Skewed, positive, like trajectory L2 distances in metres (paper, Table 3): spread grows
    # with the mean, shares 35/31/17/11/4/1 %.
    l2 = mixture(104, 5443, [5.3, 16.0, 29.4, 47.2, 76.0, 124.2],
                 [1.6, 3.0, 4.2, 5.5, 8.0, 12.0], [35, 31, 17, 11, 4, 1])
    sets.append(dict(name="l2_skewed_5443", true_k=6, x=np.abs(l2)))
    for s in sets:
        s["x"] = np.round(s["x"], 4)
    return sets


def sorted_fit(g):
    order = np.argsort(g.means_[:, 0], kind="stable")
    return dict(
        means=[float(v) for v in g.means_[order, 0]],
        weights=[float(v) for v in g.weights_[order]],
        stds=[float(np.sqrt(v)) for v in g.covariances_[order, 0, 0]],
        lower_bound=float(g.lower_bound_),
        n_iter=int(g.n_iter_),
    )


def run(ds):
    x = ds["x"]
    X = x.reshape(-1, 1)
    bic = np.zeros((len(SEEDS), K_MAX))
    fits = {}
    for i, s in enumerate(SEEDS):
        for k in range(1, K_MAX + 1):
            g = GaussianMixture(k, covariance_type="full", n_init=N_INIT, reg_covar=REG_COVAR,
                                tol=TOL, max_iter=MAX_ITER, random_state=s).fit(X)
            bic[i, k - 1] = g.bic(X)
            if k not in fits or bic[i, k - 1] < fits[k][0]:
                fits[k] = (bic[i, k - 1], g)
    chosen = [int(v) + 1 for v in bic.argmin(axis=1)]
    counts = [chosen.count(k) for k in range(1, K_MAX + 1)]
    modal = int(np.argmax(counts)) + 1  # argmax takes the first maximum: ties -> smaller k
    g1 = fits[1][1]
    return dict(
        name=ds["name"],
        true_k=ds["true_k"],
        n=int(len(x)),
        x=[float(v) for v in x],
        k_values=list(range(1, K_MAX + 1)),
        bic=[[float(v) for v in row] for row in bic],
        bic_min=[float(v) for v in bic.min(axis=0)],
        chosen_per_seed=chosen,
        chosen_count=counts,
        modal_k=modal,
        k1=dict(mean=float(g1.means_[0, 0]), variance=float(g1.covariances_[0, 0, 0]),
                score=float(g1.score(X)), bic=float(g1.bic(X))),
        fit_true_k=sorted_fit(fits[ds["true_k"]][1]),
        fit_modal_k=sorted_fit(fits[modal][1]),
    )


def main():
    warnings.filterwarnings("ignore", category=ConvergenceWarning)
    out = dict(
        generator="tests/golden/make_gmm_golden.py",
        versions=dict(python=platform.python_version(), numpy=np.__version__,
                      scipy=scipy.__version__, sklearn=sklearn.__version__),
        call=("GaussianMixture(k, covariance_type='full', n_init=3, reg_covar=1e-6, "
              "tol=1e-3, max_iter=200, random_state=s).fit(x.reshape(-1, 1))"),
        seeds=SEEDS,
        n_init=N_INIT,
        reg_covar=REG_COVAR,
        tol=TOL,
        max_iter=MAX_ITER,
        sets=[run(ds) for ds in data_sets()],
    )
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "gmm.json")
    with open(path, "w") as f:
        json.dump(out, f, separators=(",", ":"))
        f.write("\n")
    for s in out["sets"]:
        print(s["name"], "modal k", s["modal_k"], "chosen", s["chosen_count"],
              "bic_min", [round(v, 1) for v in s["bic_min"]])


if __name__ == "__main__":
    main()
