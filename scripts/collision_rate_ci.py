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
wins back at most this, plus the baseline's own failures it prevents while in control).
Standard library only.

    python3 scripts/collision_rate_ci.py DIR/records.jsonl [MORE/records.jsonl ...]
"""

import json
import random
import sys
from collections import defaultdict


def main(paths):
    runs = defaultdict(dict)
    scores = defaultdict(dict)
    for path in paths:
        with open(path, encoding="utf-8") as f:
            for n, line in enumerate(f, 1):
                try:
                    r = json.loads(line)
                    km = r["score"]["route_completion"] / 100 * r["length_m"] / 1000
                    hits = sum(1 for e in r["events"] if e["kind"].startswith("collision"))
                    ds = r["score"]["driving_score"]
                    runs[r["config"]][(r["seed"], r["route"])] = (hits, km)
                    scores[r["config"]][(r["seed"], r["route"])] = float(ds)
                except (ValueError, KeyError, TypeError) as e:
                    sys.exit(f"{path}: line {n}: not a run record ({e})")
    for deficit in ("traffic_light", "stop_sign", "pedestrian", "bicycle"):
        a, b = runs.get(deficit + "/no_rco"), runs.get(deficit + "/rco")
        if not a or not b:
            continue
        pairs = sorted(set(a) & set(b))

        def rates(keys):
            ra = sum(a[k][0] for k in keys) / max(sum(a[k][1] for k in keys), 1e-9)
            rb = sum(b[k][0] for k in keys) / max(sum(b[k][1] for k in keys), 1e-9)
            return ra, rb

        for seed in sorted({k[0] for k in pairs}):
            keys = [k for k in pairs if k[0] == seed]
            print(f"{deficit} seed {seed}: collisions {sum(a[k][0] for k in keys)} -> "
                  f"{sum(b[k][0] for k in keys)}")
        ra, rb = rates(pairs)
        rng = random.Random(7)
        boot = sorted(
            (lambda r: r[1] - r[0])(rates([pairs[rng.randrange(len(pairs))] for _ in pairs]))
            for _ in range(10_000)
        )
        print(f"{deficit}: {len(pairs)} pairs, {ra:.3f} -> {rb:.3f} per km, difference "
              f"{rb - ra:+.3f} [{boot[250]:+.3f}, {boot[9749]:+.3f}]")
        clear = scores.get("no_deficit", {})
        cost = [clear[k] - scores[deficit + "/no_rco"][k] for k in pairs if k in clear]
        if cost:
            mean = sum(cost) / len(cost)
            rng = random.Random(7)
            boot = sorted(
                sum(cost[rng.randrange(len(cost))] for _ in cost) / len(cost)
                for _ in range(10_000)
            )
            print(f"{deficit}: cost to the baseline (DS no deficit - no RCO), {len(cost)} "
                  f"pairs: {mean:+.2f} [{boot[250]:+.2f}, {boot[9749]:+.2f}]")


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    main(sys.argv[1:])
