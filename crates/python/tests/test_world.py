"""fogline.world and fogline.planner: the CLI's clips, the planner on frames."""

import json
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import fogline

ROOT = Path(__file__).resolve().parents[3]
BIN = Path(os.environ.get("FOGLINE_BIN", ROOT / "target" / "debug" / "fogline"))
DIRS = {"cross_left": "camera_cross_left_120fov", "front_wide": "camera_front_wide_120fov",
        "cross_right": "camera_cross_right_120fov", "front_tele": "camera_front_tele_30fov"}


def test_a_clip_has_the_pixels_the_cli_writes(tmp_path):
    out = tmp_path / "corpus"
    subprocess.run([str(BIN), "-q", "world", "generate", "--clips", "8", "--seed", "3",
                    "--out", str(out)], check=True, stdout=subprocess.DEVNULL)
    for index in (1, 5, 7):
        clip = fogline.world.clip(index, clips=8, seed=3)
        d = out / clip.id
        assert d.is_dir(), f"{clip.id} not written by the CLI"
        meta = json.loads((d / "clip.json").read_text())
        assert meta["scenario"] == clip.scenario
        for cam, sub in DIRS.items():
            for k in range(4):
                png = np.asarray(Image.open(d / sub / f"frame_{k}.png").convert("RGB"))
                np.testing.assert_array_equal(clip.frames[cam][k], png)
        assert clip.frames["front_wide"].shape == (4, 320, 576, 3)
        assert clip.depth["front_wide"].dtype == np.float32
        assert clip.ego_history.shape == (16, 5) and clip.ground_truth.shape == (64, 2)


def test_the_planner_agrees_with_the_expert_on_clean_clips_and_is_deterministic():
    agree, ades = 0, []
    for i in range(48):
        clip = fogline.world.clip(i, clips=48, seed=21, cameras=["front_wide", "front_tele"])
        assert set(clip.frames) == {"front_wide", "front_tele"}
        out = fogline.planner.plan(clip)
        agree += out.decision == clip.decision
        ades.append(out.ade(clip.ground_truth))
        assert out.trajectory.shape == (64, 2) and out.explanation
    # docs/world.md: 95.5 % agreement and 0.57 m mean ADE on 1,996 clean clips.
    assert agree / 48 >= 0.85, agree
    assert np.mean(ades) < 1.5, np.mean(ades)
    clip = fogline.world.clip(3, clips=48, seed=21)
    a, b = fogline.planner.plan(clip), fogline.planner.plan(clip)
    np.testing.assert_array_equal(a.trajectory, b.trajectory)


def test_noise_on_the_frames_moves_the_plan():
    clip = fogline.world.clip(10, clips=48, seed=21, cameras=["front_wide", "front_tele"])
    clean = fogline.planner.plan(clip)
    noisy = {cam: fogline.perturb(f, "noise_70", seed=1, key=[f"{clip.id}/{cam}/{k}" for k in range(4)])
             for cam, f in clip.frames.items()}
    out = fogline.planner.plan(noisy, clip.ego_history, clip.calibs)
    assert not np.array_equal(out.trajectory, clean.trajectory)
    # Without calibrations the standard rig at the frames' size is used: the same here.
    same = fogline.planner.plan(dict(clip.frames), clip.ego_history)
    np.testing.assert_array_equal(same.trajectory, clean.trajectory)


@pytest.mark.parametrize(
    "call, error, message",
    [
        (lambda: fogline.world.clip(8, clips=8), ValueError, "index: 8 is not below clips=8"),
        (lambda: fogline.world.clip(0, clips=0), ValueError, "clips: must be at least 1"),
        (lambda: fogline.world.clip(0, mix="mine"), ValueError, "mix"),
        (lambda: fogline.world.clip(0, scenario="FLYING"), ValueError, "scenario"),
        (lambda: fogline.world.clip(0, width=8), ValueError, "width"),
        (lambda: fogline.world.clip(0, cameras=["rear"]), ValueError, "unknown camera"),
        (lambda: fogline.planner.plan({"front_wide": np.zeros((4, 32, 32, 3), np.uint8)}), ValueError, "ego_history"),
        (lambda: fogline.planner.plan({"front_wide": np.zeros((4, 32, 32), np.uint8)}, np.zeros((16, 5))), ValueError, "expected shape (T, H, W, 3)"),
        (lambda: fogline.planner.plan({"front_wide": np.zeros((4, 32, 32, 3), np.uint8)}, np.zeros((16, 4))), ValueError, "expected shape (N, 5)"),
        (lambda: fogline.planner.plan({"front_wide": np.zeros((4, 32, 32, 3), np.uint8)}, np.full((16, 5), np.nan)), ValueError, "finite"),
        (lambda: fogline.planner.plan({"cross_left": np.zeros((4, 32, 32, 3), np.uint8)}, np.zeros((16, 5))), ValueError, "front"),
        (lambda: fogline.planner.plan("frames", np.zeros((16, 5))), TypeError, "expected a Clip or a dict"),
    ],
)
def test_bad_input_raises_a_clear_exception(call, error, message):
    with pytest.raises(error) as e:
        call()
    assert message in str(e.value)
