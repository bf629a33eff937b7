"""fogline.rco.Controller: a step loop, the CLI's replay, masks, bad input, the openai path."""

import http.server
import json
import os
import runpy
import subprocess
import threading
from pathlib import Path

import numpy as np
import pytest

import fogline
import fogline.rco

ROOT = Path(__file__).resolve().parents[3]
BIN = Path(os.environ.get("FOGLINE_BIN", ROOT / "target" / "debug" / "fogline"))
STORY = ROOT / "crates" / "rco" / "tests" / "data" / "observations.jsonl"
FRAME = np.full((320, 576, 3), 100, np.uint8)


def test_a_step_loop_stops_for_a_masked_pedestrian_then_moves_on():
    ctl = fogline.rco.Controller(views=("front_wide",))
    decisions = []
    for t in range(40):
        hidden = {"front_wide": [(300, 150, 30, 60)]} if 5 <= t < 20 else None
        decisions.append(ctl.step({"front_wide": FRAME}, hidden, speed=6.0 if t < 6 else 1.0))
    for d in decisions:
        assert 0 <= d.throttle <= 1 and 0 <= d.brake <= 1 and -1 <= d.steer <= 1
        assert d.fallback is None
    assert decisions[2].throttle > 0 and decisions[2].brake == 0          # drives before
    assert decisions[6].strategy == "stop-observe-move"                 # the mask appears
    assert all(d.brake > 0 for d in decisions[6:12])                    # it stops and observes
    assert decisions[-1].throttle > 0 and decisions[-1].strategy == "move"   # and moves on
    assert decisions[6].data["hazards"][0]["camera"] == "front_wide"
    assert "stop" in decisions[6].summary


def test_recorded_story_gives_the_cli_replays_decisions(tmp_path):
    out = subprocess.run([str(BIN), "-q", "rco", "replay", str(STORY), "--json"],
                         check=True, capture_output=True, text=True).stdout
    cli = [json.loads(line) for line in out.splitlines() if line.strip()]
    ctl = fogline.rco.Controller()
    ours = [ctl.step_observation(json.loads(line)).data
            for line in STORY.read_text().splitlines() if line.strip()]
    assert len(ours) == len(cli) == 80
    keys = ("tick", "control", "raw_control", "action", "condition", "source", "replanned",
            "replan_reason", "refusal", "fallback", "strategy", "hazards", "observed",
            "consistent", "constraints", "plan_remaining")
    for a, b in zip(ours, cli):
        assert {k: a[k] for k in keys} == {k: b[k] for k in keys}, a["tick"]


def test_a_mask_counts_as_its_regions_boxes():
    mask = np.zeros((320, 576), bool)
    mask[150:210, 300:330] = True
    mask[20:30, 10:20] = True
    assert fogline.rco.mask_boxes(mask) == [(10.0, 20.0, 10.0, 10.0), (300.0, 150.0, 30.0, 60.0)]
    by_mask = fogline.rco.Controller(views=("front_wide",))
    by_box = fogline.rco.Controller(views=("front_wide",))
    for t in range(12):
        a = by_mask.step({"front_wide": FRAME}, {"front_wide": mask}, speed=5.0)
        b = by_box.step({"front_wide": FRAME},
                        {"front_wide": [(10, 20, 10, 10), (300, 150, 30, 60)]}, speed=5.0)
        assert a.data["control"] == b.data["control"] and a.action == b.action


def test_a_missing_configured_camera_is_a_full_frame_deficit():
    # Three views configured, only the front one given: the side cameras count as lost.
    ctl = fogline.rco.Controller()
    d = ctl.step({"front_wide": FRAME}, speed=5.0)
    present = {o["camera"]: o["present"] for o in d.data["observed"]}
    assert present == {"cross_left": False, "front_wide": True, "cross_right": False}


@pytest.mark.parametrize(
    "kwargs, error, message",
    [
        ({"frames": {"front_wide": FRAME[:, :, :2]}}, ValueError, "expected an H x W x 3"),
        ({"frames": {"rear": FRAME}}, ValueError, "unknown camera 'rear'"),
        ({"frames": {"front_wide": FRAME.astype(np.float32)}}, TypeError, "expected a uint8 array"),
        ({"frames": {"front_wide": FRAME[:, ::2]}}, ValueError, "not C-contiguous"),
        ({"deficits": {"front_wide": [(1, 2, 3)]}, "image_size": (576, 320)}, TypeError, "expected (x, y, width, height)"),
        ({"deficits": {"front_wide": [(1, 2, 3, 4)]}}, ValueError, "no frame to take its size from"),
        ({"deficits": {"front_wide": [(1, 2, -3, 4)]}, "image_size": (576, 320)}, ValueError, "observation"),
        ({"frames": {"front_wide": FRAME}, "direction": "sideways"}, ValueError, "sideways"),
        ({"frames": {"front_wide": FRAME}, "speed": float("nan")}, ValueError, "observation"),
        ({"frames": ["not", "a", "dict"]}, TypeError, "expected a dict camera"),
    ],
)
def test_bad_input_raises_a_clear_exception(kwargs, error, message):
    ctl = fogline.rco.Controller(views=("front_wide",))
    with pytest.raises(error) as e:
        ctl.step(**kwargs)
    assert message in str(e.value)


def test_bad_settings_raise():
    with pytest.raises(ValueError, match="backend"):
        fogline.rco.Controller(backend="gpt")
    with pytest.raises(ValueError, match="unknown module 'xx'"):
        fogline.rco.Controller(modules="hi,xx")
    with pytest.raises(ValueError, match="settings of the openai backend"):
        fogline.rco.Controller(url="http://127.0.0.1:1")
    with pytest.raises(ValueError, match="views"):
        fogline.rco.Controller(views=("front",))
    with pytest.raises(ValueError, match="parameters"):
        fogline.rco.Controller(plan_limit="many")


class _Failing(http.server.BaseHTTPRequestHandler):
    def do_POST(self):
        self.rfile.read(int(self.headers.get("Content-Length", 0)))
        self.send_response(500)
        self.end_headers()
        self.wfile.write(b"model overloaded")

    def log_message(self, *args):
        pass


def test_the_openai_backend_falls_back_safely_when_its_server_fails():
    server = http.server.HTTPServer(("127.0.0.1", 0), _Failing)
    t = threading.Thread(target=server.serve_forever, daemon=True)
    t.start()
    try:
        ctl = fogline.rco.Controller(backend="openai", url=f"http://127.0.0.1:{server.server_port}",
                                     model="test", timeout_ms=2000, views=("front_wide",))
        assert "openai" in ctl.backend
        d = ctl.step({"front_wide": FRAME}, {"front_wide": [(300, 150, 30, 60)]}, speed=6.0)
        assert d.fallback is not None and d.source == "fallback"
        assert d.throttle == 0 and d.brake > 0
    finally:
        server.shutdown()


def test_the_example_agent_runs_and_brakes_for_the_masked_pedestrian():
    ns = runpy.run_path(str(ROOT / "docs" / "examples" / "rco_agent.py"), run_name="example")
    agent = ns["RcoAgent"]()
    agent.setup()
    assert len(agent.sensors()) == 4
    controls = [agent.run_step(ns["fake_input"](t, hidden=5 <= t < 15), t * 0.1) for t in range(25)]
    assert controls[3]["throttle"] > 0
    assert all(c["brake"] > 0 and c["throttle"] == 0 for c in controls[5:15])
    assert controls[-1]["throttle"] > 0
