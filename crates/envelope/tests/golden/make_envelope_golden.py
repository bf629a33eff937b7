#!/usr/bin/env python3
"""Golden values of the whole envelope analysis on tests/data/small.csv, from the Python peer.

Writes tests/golden/envelope_small.json (next to this script) for tests/it/golden.rs. The
values come from the independent pandas / SciPy / scikit-learn implementation in
crates/bench/python/envelope_peer.py, run with the bootstrap off and 5 GMM restarts
(random_state 0..4); every other parameter is fogline's default.

small.csv is the synthetic corpus with 240 clips and seed 3 (1,920 pairs), as written by

    cargo run -p fogline-cli -- demo --clips 240 --seed 3 --out DIR     # DIR/pairs.csv

Stored (the Rust test says how closely each must agree):

  input        SHA-256 of small.csv, so a regenerated CSV cannot silently go stale
  corpus       pair, clip and changed counts, per-scenario counts and means
  dose_response  mean clean / attacked ADE and ΔADE per group, axis and level
  thresholds   σ* and right-censoring per group, axis, budget, for both rules
  statistics   every statistic that does not depend on the GMM
  gmm          modal k, the k chosen per restart, min BIC per k, the final bands
  per_scenario changed pairs per classified scenario
  gmm_dependent  high-severity counts and shares, the joint table, χ² and Cramér's V

Run from anywhere:  python3 crates/envelope/tests/golden/make_envelope_golden.py   (~2 s)
Needs numpy, scipy, scikit-learn and pandas.
"""

import hashlib
import json
import platform
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
CRATES = HERE.parents[2]
sys.path.insert(0, str(CRATES / "bench" / "python"))

import envelope_peer as peer  # noqa: E402  (sets the thread pools to 1 before numpy)
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import scipy  # noqa: E402
import sklearn  # noqa: E402

CSV = HERE.parent / "data" / "small.csv"
OUT = HERE / "envelope_small.json"
PARAMS = dict(bootstrap=0, restarts=5)

GMM_FREE_STATS = [
    "n_pairs", "n_changed", "change_rate", "point_biserial_r", "point_biserial_p", "cohens_d",
    "mean_l2_changed_m", "mean_l2_unchanged_m", "l2_ratio", "change_rate_vs_l2",
    "jaccard_l2_pearson", "jaccard_l2_spearman", "jaccard_l2", "mwu", "bimodality_coefficient",
    "icc", "never_flip_share", "always_flip_share",
]


def main():
    df = peer.read_pairs(str(CSV))
    res = peer.analyze(df, PARAMS)
    sev = res["severity"]
    st = res["statistics"]
    golden = dict(
        meta=dict(
            script="crates/envelope/tests/golden/make_envelope_golden.py",
            peer="crates/bench/python/envelope_peer.py",
            python=platform.python_version(), numpy=np.__version__, scipy=scipy.__version__,
            sklearn=sklearn.__version__, pandas=pd.__version__,
            parameters={k: res["parameters"][k] for k in
                        ("budgets", "bootstrap", "restarts", "k_max", "n_init", "seed",
                         "cv_folds", "per_scenario_k_max", "high_bands")},
        ),
        input=dict(path="crates/envelope/tests/data/small.csv",
                   sha256=hashlib.sha256(CSV.read_bytes()).hexdigest()),
        corpus=dict(
            n_pairs=res["corpus"]["n_pairs"],
            n_clips=res["corpus"]["n_clips"],
            n_changed=res["corpus"]["n_changed"],
            scenarios=[{k: s[k] for k in ("scenario", "n_clips", "n_pairs", "n_changed",
                                          "clean_ade_mean_m", "flip_rate")}
                       for s in res["corpus"]["scenarios"]],
        ),
        axes=[{k: a[k] for k in ("axis", "family", "levels", "conditions")} for a in res["axes"]],
        dose_response=[{k: d[k] for k in ("scenario", "axis", "level", "n_pairs",
                                          "mean_ade_clean_m", "mean_ade_attacked_m",
                                          "delta_ade_m")}
                       for d in res["dose_response"]],
        thresholds=[{k: t[k] for k in ("scenario", "axis", "budget", "rule", "n_clips",
                                       "sigma_star", "right_censored", "vs_aggregate")}
                    for t in res["thresholds"]],
        statistics={k: st[k] for k in GMM_FREE_STATS},
        gmm=dict(
            n_changed=sev["n_changed"],
            chosen_k=sev["chosen_k"],
            chosen_per_seed=sev["chosen_per_seed"],
            bic_min=[row["min"] for row in sev["bic"]],
            bands=[{k: b[k] for k in ("name", "mean_m", "std_m", "weight", "n")}
                   for b in sev["bands"]],
        ),
        per_scenario=[{k: m[k] for k in ("scenario", "n_changed")} for m in sev["per_scenario"]],
        gmm_dependent=dict(
            high_bands=res["high_severity"]["bands"],
            by_scenario=[{k: h[k] for k in ("group", "n_changed", "n_high", "share")}
                         for h in res["high_severity"]["by_scenario"]],
            by_condition=[{k: h[k] for k in ("group", "n_changed", "n_high", "share")}
                          for h in res["high_severity"]["by_condition"]],
            joint=res["joint"],
            chi2=st["chi2"],
            cramers_v=st["cramers_v"],
        ),
    )
    OUT.write_text(json.dumps(golden, indent=1) + "\n")
    print(f"wrote {OUT} (chosen k {sev['chosen_k']}, {res['corpus']['n_changed']} changed pairs)")


if __name__ == "__main__":
    main()
