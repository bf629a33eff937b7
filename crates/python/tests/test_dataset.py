"""fogline.dataset: the builder's bytes (seeded, the CLI's), the rules backend's per-class
rows, the import of a log, and bad input named in the error."""

import json
import math
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import fogline
import fogline.dataset

ROOT = Path(__file__).resolve().parents[3]
BIN = Path(os.environ.get("FOGLINE_BIN", ROOT / "target" / "debug" / "fogline"))
CLASSES = ["traffic_light", "traffic_sign", "pedestrian", "bicycle"]


def files(d):
    """Every file under ``d`` (relative path -> bytes)."""
    d = Path(d)
    return {str(p.relative_to(d)): p.read_bytes() for p in sorted(d.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    """16 samples (4 towns), built once."""
    out = tmp_path_factory.mktemp("deficit") / "deficit"
    built = fogline.dataset.build_deficit(out, samples=16, seed=5, split=(0.5, 0.25, 0.25))
    return out, built


def test_the_same_seed_gives_the_same_bytes_on_any_thread_count_and_the_clis(data, tmp_path):
    out, built = data
    assert built.samples == 16 and built.dir == out
    assert built.counts["all"]["samples"] == 16
    assert (out / "samples.jsonl") in built.files
    again = fogline.dataset.build_deficit(tmp_path / "again", samples=16, seed=5,
                                          split=(0.5, 0.25, 0.25), threads=1)
    a, b = files(out), files(again.dir)
    assert len(a) == len(b) > 16 * 15
    assert a.keys() == b.keys()
    assert all(a[k] == b[k] for k in a), "the same seed gives the same bytes"
    cli = tmp_path / "cli"
    subprocess.run([str(BIN), "-q", "dataset", "deficit", "--samples", "16", "--seed", "5",
                    "--split", "0.5,0.25,0.25", "--out", str(cli)],
                   check=True, capture_output=True)
    assert files(cli) == a, "the package writes the CLI's bytes"
    other = fogline.dataset.build_deficit(tmp_path / "other", samples=16, seed=6,
                                          split=(0.5, 0.25, 0.25))
    assert files(other.dir)["samples.jsonl"] != a["samples.jsonl"]


def test_the_rules_backend_gives_a_row_per_class_with_intervals(data, tmp_path):
    out, _ = data
    ev = fogline.dataset.evaluate(out, backend="rules", split="all", jobs=2, out=tmp_path / "ev",
                                  gallery=4)
    assert ev.backend == "rules" and ev.split == "all" and ev.samples == 16
    assert list(ev.by_class) == CLASSES
    assert all(ev.by_class[c]["samples"] == 4 for c in CLASSES), "classes cycle"
    for key in ("object", "motion", "strategy", "plan_strategy", "invalid", "plan_invalid"):
        assert sum(ev.by_class[c][key]["hits"] for c in CLASSES) == ev.overall[key]["hits"], key
    for row in [*ev.by_class.values(), *ev.by_motion.values(), *ev.by_strategy.values()]:
        for key in ("object", "strategy", "plan_strategy"):
            r = row[key]
            if r["n"] == 0:
                continue
            assert 0 <= r["ci_low"] <= r["value"] <= r["ci_high"] <= 1, (row["group"], key)
            assert math.isclose(r["value"], r["hits"] / r["n"])
    assert ev.overall["invalid"]["hits"] == 0 and ev.overall["plan_invalid"]["hits"] == 0
    # Both prompts per sample, timed per prompt.
    assert ev.latency["hazard_inference"]["calls"] == 16
    assert ev.latency["move_plan"]["calls"] + ev.latency["stop_observe_move_plan"]["calls"] == 16
    for a in ev.answers:
        want = {"move": "move_plan", "stop-observe-move": "stop_observe_move_plan"}
        assert a["plan_prompt"] == want[a["answer_strategy"]]
    # The files, as the CLI writes them; its answers are the package's.
    names = [f.name for f in ev.files]
    assert names == ["eval.json", "eval.md", "report.html"]
    assert json.loads((tmp_path / "ev" / "eval.json").read_text())["answers"] == ev.answers
    assert "| pedestrian | 4 |" in ev.markdown
    html = (tmp_path / "ev" / "report.html").read_text()
    assert 'id="table-deficit-class"' in html
    assert 15 <= html.count('<img src="data:image/png;base64,') <= 4 * 15
    cli = subprocess.run([str(BIN), "-q", "rco", "eval", "--data", str(out), "--split", "all",
                          "--out", str(tmp_path / "cli")], check=True, capture_output=True)
    assert cli.returncode == 0
    theirs = json.loads((tmp_path / "cli" / "eval.json").read_text())
    strip = lambda answers: [{k: v for k, v in a.items() if "latency" not in k} for a in answers]  # noqa: E731
    assert strip(theirs["answers"]) == strip(ev.answers)
    assert "Evaluation('rules', split='all', samples=16" in repr(ev)


def write_log(logs, motion):
    """One log of six 48x36 grey frames on three views, a pedestrian walking right."""
    log = Path(logs) / "town-a"
    log.mkdir(parents=True)
    cams = {"cross_left": 1.047, "front_wide": 0.0, "cross_right": -1.047}
    grey = np.full((36, 48, 3), 120, np.uint8)
    frames = []
    for k in range(6):
        images = {}
        for cam in cams:
            name = f"{cam}_{k}.png"
            Image.fromarray(grey).save(log / name)
            images[cam] = name
        x = 10.0 + k
        frames.append({"t_s": float(k), "ego_speed_mps": 4.0, "brake": k == 4, "images": images,
                       "objects": [{"camera": "front_wide", "class": "pedestrian", "track_id": 7,
                                    "bbox": [x, 8.0, x + 6.0, 24.0], "motion": motion}]})
    cameras = [{"id": c, "width": 48, "height": 36, "fx": 24.0, "fy": 24.0, "cx": 24.0, "cy": 18.0,
                "x_m": 1.8, "y_m": 0.0, "z_m": 1.6, "yaw_rad": yaw, "pitch_rad": 0.0}
               for c, yaw in cams.items()]
    doc = {"format": "fogline-deficit-log", "version": 1, "cameras": cameras, "frames": frames}
    (log / "log.json").write_text(json.dumps(doc))


def test_a_log_is_imported_and_a_bad_one_named(tmp_path):
    write_log(tmp_path / "logs", "crossing")
    built = fogline.dataset.import_logs(tmp_path / "logs", tmp_path / "out")
    assert built.samples == 1
    s = json.loads((tmp_path / "out" / "samples.jsonl").read_text().splitlines()[0])
    assert (s["class"], s["motion"], s["strategy"]) == ("pedestrian", "crossing",
                                                        "stop-observe-move")
    assert s["frames"][4]["views"][1]["deficits"] == [[14, 8, 20, 24]]
    write_log(tmp_path / "bad", None)
    with pytest.raises(ValueError, match=r"log\.json.*frames\[0\]\.objects\[0\]\.motion"):
        fogline.dataset.import_logs(tmp_path / "bad", tmp_path / "out2")


def test_bad_input_is_named(data, tmp_path):
    out, _ = data
    with pytest.raises(ValueError, match="samples must be at least 1"):
        fogline.dataset.build_deficit(tmp_path / "x", samples=0)
    with pytest.raises(ValueError, match="split: expected three shares"):
        fogline.dataset.build_deficit(tmp_path / "x", samples=4, split=(0.5, 0.5))
    with pytest.raises(ValueError, match="must be >= 0 and sum to 1"):
        fogline.dataset.build_deficit(tmp_path / "x", samples=4, split=(0.5, 0.5, 0.5))
    with pytest.raises(ValueError, match="image: expected 'png' or 'jpeg'"):
        fogline.dataset.build_deficit(tmp_path / "x", samples=4, image="gif")
    with pytest.raises(OSError, match="manifest.json"):
        fogline.dataset.evaluate(tmp_path)
    with pytest.raises(ValueError, match="split: expected train, val, test or all"):
        fogline.dataset.evaluate(out, split="dev")
    with pytest.raises(ValueError, match="no sample in split"):
        fogline.dataset.evaluate(out, split="val", limit=0)
    with pytest.raises(ValueError, match='backend: expected "rules" or "openai"'):
        fogline.dataset.evaluate(out, backend="oracle")
    with pytest.raises(ValueError, match="settings of the openai backend"):
        fogline.dataset.evaluate(out, url="http://127.0.0.1:1")
    with pytest.raises(ValueError, match="jobs: must be at least 1"):
        fogline.dataset.evaluate(out, jobs=0)
    assert "dataset" in fogline.__all__
