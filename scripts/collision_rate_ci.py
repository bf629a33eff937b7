#!/usr/bin/env python3
"""Collisions per km with and without the override, from `fogline sim run` records.

For each deficit, pairs the `<deficit>/no_rco` and `<deficit>/rco` runs by seed and route
and prints the pooled collision rates (vehicle, pedestrian and layout collisions over the
kilometres of route completed, as `tables.md` counts them), their difference and its 95 %
percentile bootstrap interval over the route pairs (10,000 resamples, fixed seed), per
seed and pooled. `fogline sim run` prints the paired ΔDS interval itself; this adds the
interval of the collision-rate difference, and what the deficit costs the baseline: the
mean driving score without a deficit minus the mean without the override under it, paired
by seed and route, with its bootstrap interval (an override that only ever slows the car
wins back at most this, plus the baseline's own failures it prevents while in control),
and the collision rate with the override against the baseline's without any deficit (the
same routes, seeds and bootstrap).
Standard library only.

    python3 scripts/collision_rate_ci.py DIR/records.jsonl [MORE/records.jsonl ...]
"""

import json
import random
import sys
from collections import defaultdict


def interval(stat, items):
    """The 2.5 % and 97.5 % points of `stat` over 10,000 resamples of `items` (fixed seed)."""
    rng = random.Random(7)
    boot = sorted(
        stat([items[rng.randrange(len(items))] for _ in items]) for _ in range(10_000)
    )
    return boot[250], boot[9749]


def rate(runs, keys):
    """Collisions per km completed over the runs `keys` of one configuration."""
    return sum(runs[k][0] for k in keys) / max(sum(runs[k][1] for k in keys), 1e-9)


def rate_difference(base, other, keys):
    """Both pooled rates over `keys` and the interval of their difference (other - base)."""
    lo, hi = interval(lambda ks: rate(other, ks) - rate(base, ks), keys)
    return rate(base, keys), rate(other, keys), lo, hi


def main(paths):
    # config -> (seed, route) -> (collisions, km completed, driving score)
    runs = defaultdict(dict)
    for path in paths:
        try:
            f = open(path, encoding="utf-8")
        except OSError as e:
            sys.exit(f"{path}: cannot read the run records ({e.strerror})")
        with f:
            for n, line in enumerate(f, 1):
                try:
                    r = json.loads(line)
                    km = r["score"]["route_completion"] / 100 * r["length_m"] / 1000
                    hits = sum(1 for e in r["events"] if e["kind"].startswith("collision"))
                    ds = float(r["score"]["driving_score"])
                    runs[r["config"]][(r["seed"], r["route"])] = (hits, km, ds)
                except (ValueError, KeyError, TypeError) as e:
                    sys.exit(f"{path}: line {n}: not a run record ({e})")
    for deficit in ("traffic_light", "stop_sign", "pedestrian", "bicycle"):
        a, b = runs.get(deficit + "/no_rco"), runs.get(deficit + "/rco")
        if not a or not b:
            continue
        pairs = sorted(set(a) & set(b))
        for seed in sorted({k[0] for k in pairs}):
            keys = [k for k in pairs if k[0] == seed]
            print(f"{deficit} seed {seed}: collisions {sum(a[k][0] for k in keys)} -> "
                  f"{sum(b[k][0] for k in keys)}")
        ra, rb, lo, hi = rate_difference(a, b, pairs)
        print(f"{deficit}: {len(pairs)} pairs, {ra:.3f} -> {rb:.3f} per km, difference "
              f"{rb - ra:+.3f} [{lo:+.3f}, {hi:+.3f}]")
        clear = runs.get("no_deficit", {})
        both = [k for k in pairs if k in clear]
        if both:
            cost = [clear[k][2] - a[k][2] for k in both]
            lo, hi = interval(lambda c: sum(c) / len(c), cost)
            print(f"{deficit}: cost to the baseline (DS no deficit - no RCO), {len(cost)} "
                  f"pairs: {sum(cost) / len(cost):+.2f} [{lo:+.2f}, {hi:+.2f}]")
            rc, rb, lo, hi = rate_difference(clear, b, both)
            print(f"{deficit}: RCO against no deficit, {len(both)} pairs: {rc:.3f} -> "
                  f"{rb:.3f} per km, difference {rb - rc:+.3f} [{lo:+.3f}, {hi:+.3f}]")

if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    main(sys.argv[1:])
