"""fogline.monitor: estimates on numpy frames, the monitor's steps, the CLI's JSON lines."""

import json
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import fogline
import fogline.monitor

ROOT = Path(__file__).resolve().parents[3]
BIN = Path(os.environ.get("FOGLINE_BIN", ROOT / "target" / "debug" / "fogline"))


def scene(h=240, w=320):
    """A textured frame over most of the range (a ramp and a sinusoid, channels apart)."""
    y, x = np.mgrid[0:h, 0:w]
    base = 30 + 190 * x / w + 25 * np.sin(2 * np.pi * y / 40)
    return np.clip(np.stack([base, base + 8, base - 8], axis=-1), 0, 255).round().astype(np.uint8)


def axis(name, sigma, descending=False, identity=0.0):
    return {
        "axis": name, "family": "brightness" if name in ("darken", "brighten") else name,
        "descending": descending, "identity_level": identity, "levels": [], "sigma_star": sigma,
        "right_censored": False, "ci95": None, "threshold_group": "match",
    }


def odd(noise_star=30.0):
    entry = {
        "scenario": "LANE_KEEPING", "rank": 1, "n_clips": 40, "n_changed": 5, "pilot": False,
        "axis": "gaussian_noise", "budget": 0.15, "sigma_star": noise_star,
        "right_censored": False, "ci95": None, "p_high": 0.2, "threshold_group": "match",
        "severity_group": "mild", "quadrant": "match + mild", "accepted": None,
        "acceptance_reason": None,
        "thresholds": [axis("gaussian_noise", noise_star), axis("darken", 0.4, True, 1.0),
                       axis("brighten", 1.6, False, 1.0), axis("fog", 0.7)],
    }
    return {
        "schema_version": 1, "kind": "fogline.odd", "generated_by": "test", "input_sha256": "00",
        "axis": "gaussian_noise", "budget": 0.15, "rule": "first-violation", "high_bands": [],
        "pi_star": None, "sigma_op": None, "entries": [entry],
    }


def test_estimate_reads_the_noise_fogline_added():
    clean = scene()
    assert fogline.monitor.estimate(clean)["noise_sigma"] < 0.5
    for sigma in (10, 30, 50):
        e = fogline.monitor.estimate(fogline.perturb(clean, f"noise_{sigma}", seed=3))
        assert abs(e["noise_sigma"] - sigma) < 0.05 * sigma + 0.5, e
        assert 0 < e["noise_sigma_se"] < 0.05 * sigma
        assert set(e) == {"noise_sigma", "noise_sigma_se", "gain", "gain_se", "fog", "fog_se",
                          "clipped_share"}


def test_estimate_refuses_what_is_not_one_rgb_frame():
    with pytest.raises(TypeError, match="uint8"):
        fogline.monitor.estimate(scene().astype(np.float32))
    with pytest.raises(ValueError, match="one frame"):
        fogline.monitor.estimate(np.zeros((2, 8, 8, 3), np.uint8))
    with pytest.raises(ValueError, match="3 channels"):
        fogline.monitor.estimate(np.zeros((8, 8), np.uint8).reshape(8, 8, 1))
    with pytest.raises(TypeError):
        fogline.monitor.estimate([[1, 2, 3]])


def test_the_monitor_leaves_with_the_noise_and_holds_with_its_dwell():
    clean = scene()
    m = fogline.monitor.Monitor(odd(), "LANE_KEEPING", min_dwell_steps=3, axes=["gaussian_noise"])
    assert m.in_envelope is None and m.watched_axes == ["gaussian_noise"]
    records = [m.step(fogline.perturb(clean, f"noise_{s}", seed=1, key=i))
               for i, s in enumerate([10, 10, 60, 60, 60, 60, 5, 5, 5, 5, 5, 5, 5])]
    inside = [r["in_envelope"] for r in records]
    assert inside[0] and inside[1]
    assert not all(inside[2:6])            # the noise took it out
    first_out = inside.index(False)
    assert records[first_out]["switched"]
    assert inside[-1]                      # and it came back once the dwell allowed it
    back = len(inside) - 1 - inside[::-1].index(False) + 1
    assert back - first_out >= 3           # at least the minimum dwell out
    r = records[first_out]
    assert r["quadrant"] == "match + mild" and "gaussian_noise" in r["reason"]
    assert r["axes"][0]["axis"] == "gaussian_noise" and r["axes"][0]["limit"] == 30.0


def test_the_monitor_steps_on_estimates_and_names_bad_input(tmp_path):
    path = tmp_path / "odd.json"
    path.write_text(json.dumps(odd(None)))
    m = fogline.monitor.Monitor(path, "LANE_KEEPING", min_dwell_steps=1, z=0.0, ewma_alpha=1.0)
    assert m.watched_axes == list(fogline.monitor.ESTIMATED_AXES)
    clean = {"noise_sigma": 0.0, "noise_sigma_se": 0.0, "gain": 1.0, "gain_se": 0.0,
             "fog": 0.0, "fog_se": 0.0}
    assert m.step(clean)["in_envelope"]                       # sigma* none: only sigma 0
    assert not m.step(dict(clean, noise_sigma=4.0))["in_envelope"]
    m.reset()
    assert m.in_envelope is None
    assert not m.step(dict(clean, gain=0.3))["in_envelope"]   # darker than 0.4
    with pytest.raises(ValueError, match="missing fog_se"):
        m.step({k: v for k, v in clean.items() if k != "fog_se"})
    with pytest.raises(ValueError, match='no entry for scenario "PARKING"'):
        fogline.monitor.Monitor(path, "PARKING")
    with pytest.raises(ValueError, match="unknown field"):
        fogline.monitor.Monitor(path, "LANE_KEEPING", dwell=3)
    with pytest.raises(ValueError, match="ewma_alpha"):
        fogline.monitor.Monitor(path, "LANE_KEEPING", ewma_alpha=0)
    with pytest.raises(ValueError, match="kind"):
        fogline.monitor.Monitor({"kind": "fogline.envelope"}, "LANE_KEEPING")
    assert fogline.monitor.defaults()["min_dwell_steps"] >= 1


def test_records_equal_the_cli_json_lines(tmp_path):
    if not BIN.exists():
        pytest.skip(f"no CLI binary at {BIN}")
    (tmp_path / "odd.json").write_text(json.dumps(odd()))
    clean = scene()
    frames = [fogline.perturb(clean, f"noise_{s}", seed=2, key=i) for i, s in enumerate([5, 45, 45])]
    files = []
    for i, f in enumerate(frames):
        p = tmp_path / f"f{i}.png"
        Image.fromarray(f).save(p)
        files.append(str(p))
    out = subprocess.run([str(BIN), "monitor", "run", *files, "--odd", str(tmp_path / "odd.json"),
                          "--scenario", "LANE_KEEPING"], capture_output=True, text=True, check=True)
    cli = [json.loads(line) for line in out.stdout.splitlines()]
    m = fogline.monitor.Monitor(tmp_path / "odd.json", "LANE_KEEPING")
    ours = [m.step(f) for f in frames]
    for c, o, p in zip(cli, ours, files):
        assert c.pop("source") == p and o.pop("source") is None
        assert c == o
    e = fogline.monitor.estimate(frames[1])
    est = json.loads(subprocess.run([str(BIN), "monitor", "estimate", files[1], "--json"],
                                    capture_output=True, text=True, check=True).stdout)
    assert est["noise_sigma"] == e["noise_sigma"] and est["gain"] == e["gain"]
