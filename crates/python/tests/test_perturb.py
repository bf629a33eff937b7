"""The Python package against the CLI and against bad input.

Run by scripts/test.sh (the README's test command) after the wheel is built and installed;
FOGLINE_BIN names the CLI binary to compare with (default: target/debug/fogline).
"""

import os
import subprocess
import threading
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import fogline

ROOT = Path(__file__).resolve().parents[3]
BIN = Path(os.environ.get("FOGLINE_BIN", ROOT / "target" / "debug" / "fogline"))


def frames(n, h=37, w=53, seed=1):
    """A batch of textured frames (random, with saturated patches so clipping matters)."""
    rng = np.random.default_rng(seed)
    batch = rng.integers(0, 256, size=(n, h, w, 3), dtype=np.uint8)
    batch[:, :8, :8] = 255
    batch[:, -8:, -8:] = 0
    return batch


def run_cli(tmp_path, batch, condition, seed, boxes=None):
    """Writes the batch as clip/000i.png, runs `fogline perturb`, reads the outputs back."""
    src, dst = tmp_path / "in", tmp_path / "out"
    (src / "clip").mkdir(parents=True)
    rels = [f"clip/{i:04d}.png" for i in range(len(batch))]
    for rel, f in zip(rels, batch):
        Image.fromarray(f).save(src / rel)
    cmd = [str(BIN), "-q", "perturb", "--input", str(src), "--output", str(dst),
           "--condition", condition, "--seed", str(seed)]
    if boxes is not None:
        lines = []
        for rel, frame_boxes in zip(rels, boxes):
            for b in frame_boxes:
                lines.append(
                    '{"frame": "%s", "class": "%s", "x": %d, "y": %d, "width": %d, "height": %d}'
                    % (rel, b["class"], b["x"], b["y"], b["width"], b["height"])
                )
        (tmp_path / "boxes.jsonl").write_text("\n".join(lines) + "\n")
        cmd += ["--boxes", str(tmp_path / "boxes.jsonl")]
    subprocess.run(cmd, check=True)
    return rels, np.stack([np.asarray(Image.open(dst / rel).convert("RGB")) for rel in rels])


def test_the_cli_binary_is_there():
    assert BIN.is_file(), f"{BIN} is missing: build it with `cargo build -p fogline-cli`"


@pytest.mark.parametrize(
    "condition",
    ["noise_30", "noise_70", "dark", "fog_07", "noise_30+fog_03", "shot_4", "impulse_0.03",
     "jpeg_20", "defocus_2", "dead_0.01", "dirt_3", "drop_0.5", "freeze_1", "latency_1"],
)
def test_same_bytes_as_the_cli_for_a_seed_and_key(tmp_path, condition):
    batch = frames(3)
    rels, cli = run_cli(tmp_path, batch, condition, seed=11)
    # The batch with the CLI's keys (relative paths): one call, the same bytes.
    ours = fogline.perturb(batch, condition, seed=11, key=rels)
    assert ours.shape == cli.shape and ours.dtype == np.uint8
    np.testing.assert_array_equal(ours, cli)
    if not any(condition.startswith(t) for t in ("drop", "freeze", "latency")):
        # Frame by frame too (temporal faults need the whole clip).
        for i, rel in enumerate(rels):
            np.testing.assert_array_equal(fogline.perturb(batch[i], condition, seed=11, key=rel), cli[i])
    # The noise is real: another seed differs for the random families.
    if condition.startswith(("noise", "shot", "impulse")):
        changed = (fogline.perturb(batch, condition, seed=12, key=rels) != cli).mean()
        assert changed > (0.02 if condition.startswith("impulse") else 0.3)


def test_deficit_masks_from_boxes_match_the_cli(tmp_path):
    batch = frames(2)
    boxes = [
        [{"class": "pedestrian", "x": 4, "y": 6, "width": 12, "height": 20}],
        [{"class": "pedestrian", "x": 20, "y": 3, "width": 9, "height": 25},
         {"class": "car", "x": 30, "y": 10, "width": 15, "height": 10}],
    ]
    rels, cli = run_cli(tmp_path, batch, "mask_class_pedestrian", seed=0, boxes=boxes)
    ours, regions = fogline.perturb(batch, "mask_class_pedestrian", key=rels, boxes=boxes,
                                    return_regions=True)
    np.testing.assert_array_equal(ours, cli)
    assert [len(r) for r in regions] == [1, 1]
    r = regions[1][0]
    assert r["class"] == "pedestrian"
    inside = ours[1, r["y"] + 3 : r["y"] + r["height"] - 3, r["x"] + 3 : r["x"] + r["width"] - 3]
    assert (inside == 0).all()
    # Tuples work too, and the car is untouched.
    single = fogline.perturb(batch[1], "mask_class_pedestrian",
                             boxes=[("pedestrian", 20, 3, 9, 25), ("car", 30, 10, 15, 10)])
    np.testing.assert_array_equal(single[10:20, 33:42], batch[1, 10:20, 33:42])


def test_batch_results_do_not_depend_on_threads_and_out_is_filled_in_place():
    batch = frames(6, seed=3)
    one = fogline.perturb(batch, "noise_30+dark", seed=2, threads=1)
    for t in (0, 2, 3):
        np.testing.assert_array_equal(fogline.perturb(batch, "noise_30+dark", seed=2, threads=t), one)
    out = np.empty_like(batch)
    got = fogline.perturb(batch, "noise_30+dark", seed=2, out=out)
    assert got is out
    np.testing.assert_array_equal(out, one)
    # Frames of a batch get their own streams by default (key = index).
    assert (one[0] != one[1]).mean() > 0.3 or not (batch[0] == batch[1]).all()
    np.testing.assert_array_equal(fogline.perturb(batch[4], "noise_30+dark", seed=2, key=4), one[4])
    # The input is left alone.
    np.testing.assert_array_equal(batch, frames(6, seed=3))


def test_koschmieder_fog_uses_the_depth_map():
    f = np.full((10, 20, 3), 40, dtype=np.uint8)
    depth = np.tile(np.linspace(1.0, 400.0, 20, dtype=np.float32), (10, 1))
    out = fogline.perturb(f, "visibility_100", depth=depth)
    # Far pixels fade to the airlight (204), near ones keep their colour.
    assert out[0, 0, 0] < 60 and out[0, -1, 0] > 190
    depth[0, 0] = np.inf  # sky: pure airlight
    assert fogline.perturb(f, "visibility_100", depth=depth)[0, 0, 0] == 204


def test_the_gil_is_released_while_pixels_are_computed():
    big = frames(1, h=1080, w=1920)[0]
    ticks = []
    stop = threading.Event()

    def count():
        while not stop.is_set():
            ticks.append(1)

    t = threading.Thread(target=count)
    t.start()
    try:
        for _ in range(3):
            fogline.perturb(big, "noise_30")
    finally:
        stop.set()
        t.join()
    # A held GIL would let the counter run only between calls (a handful of switches).
    assert len(ticks) > 1000


@pytest.mark.parametrize(
    "image, condition, kwargs, error, message",
    [
        (np.zeros((8, 8, 3), np.float32), "noise_30", {}, TypeError, "expected a uint8 array, got dtype float32"),
        ([[[0, 0, 0]]], "noise_30", {}, TypeError, "expected a numpy uint8 array, got list"),
        (np.zeros((8, 16, 3), np.uint8)[:, ::2], "noise_30", {}, ValueError, "not C-contiguous"),
        (np.zeros((8, 8), np.uint8), "noise_30", {}, ValueError, "expected shape (H, W, 3) or (N, H, W, 3)"),
        (np.zeros((8, 8, 4), np.uint8), "noise_30", {}, ValueError, "expected 3 channels"),
        (np.zeros((0, 8, 3), np.uint8), "noise_30", {}, ValueError, "height must be"),
        (np.zeros((8, 8, 3), np.uint8), "nois_30", {}, ValueError, 'condition "nois_30": unknown condition'),
        (np.zeros((8, 8, 3), np.uint8), "noise_-3", {}, ValueError, 'condition "noise_-3"'),
        (np.zeros((8, 8, 3), np.uint8), "visibility_50", {}, ValueError, "needs a depth map"),
        (np.zeros((8, 8, 3), np.uint8), "mask_all", {}, ValueError, "pass boxes="),
        (np.zeros((8, 8, 3), np.uint8), "mask_all", {"boxes": [{"class": "car", "x": 1, "y": 1}]}, ValueError, 'boxes[0]: missing field "width"'),
        (np.zeros((8, 8, 3), np.uint8), "mask_all", {"boxes": [("car", 1, 1, 30, 2)]}, ValueError, "outside the 8×8 frame"),
        (np.zeros((8, 8, 3), np.uint8), "mask_all", {"boxes": [7]}, TypeError, "boxes[0]: expected a dict"),
        (np.zeros((2, 8, 8, 3), np.uint8), "noise_30", {"key": ["a.png"]}, ValueError, "key: 1 values for a batch of 2 frames"),
        (np.zeros((2, 8, 8, 3), np.uint8), "noise_30", {"key": "a.png"}, TypeError, "takes a list of 2 values"),
        (np.zeros((8, 8, 3), np.uint8), "noise_30", {"key": 1.5}, TypeError, "key: expected a str"),
        (np.zeros((8, 8, 3), np.uint8), "noise_30", {"out": np.zeros((8, 9, 3), np.uint8)}, ValueError, "out: expected the image's shape"),
        (np.zeros((8, 8, 3), np.uint8), "noise_30", {"out": np.zeros((8, 8, 3), np.int16)}, TypeError, "out: expected a uint8 array"),
        (np.zeros((8, 8, 3), np.uint8), "fog_07", {"depth": np.zeros((8, 7), np.float32)}, ValueError, "depth: expected shape [8, 8]"),
        (np.zeros((8, 8, 3), np.uint8), "fog_07", {"depth": np.full((8, 8), np.nan, np.float32)}, ValueError, "depth"),
    ],
)
def test_bad_input_raises_a_clear_exception(image, condition, kwargs, error, message):
    with pytest.raises(error) as e:
        fogline.perturb(image, condition, **kwargs)
    assert message in str(e.value)


def test_out_must_not_be_the_image_nor_read_only():
    f = frames(1)[0]
    with pytest.raises(ValueError, match="must not share memory with image"):
        fogline.perturb(f, "noise_30", out=f)
    ro = np.zeros_like(f)
    ro.setflags(write=False)
    with pytest.raises(ValueError, match="out: cannot write it"):
        fogline.perturb(f, "noise_30", out=ro)


def test_transforms_fit_torchvision_and_albumentations_pipelines():
    f = frames(1)[0]
    t = fogline.Perturb("noise_30", seed=4)
    a, b = t(f), t(f)
    # Successive calls draw fresh noise, reproducibly from the seed.
    assert (a != b).mean() > 0.3
    np.testing.assert_array_equal(a, fogline.perturb(f, "noise_30", seed=4, key=0))
    t.reseed(4)
    np.testing.assert_array_equal(t(f), a)
    # PIL in, PIL out.
    pil = t(Image.fromarray(f))
    assert isinstance(pil, Image.Image) and pil.size == (f.shape[1], f.shape[0])
    # Composes like a torchvision transform: a callable on one image.
    compose = [fogline.Perturb("dark"), fogline.Perturb("noise_10", seed=1)]
    x = f
    for step in compose:
        x = step(x)
    assert x.shape == f.shape and x.mean() < f.mean()
    with pytest.raises(ValueError, match="unknown condition"):
        fogline.Perturb("fogg_07")
    # albumentations style: keyword call, dict out, other keys pass through.
    mask = np.ones(f.shape[:2], np.uint8)
    r = fogline.AlbuPerturb("fog_07", p=1.0)(image=f, mask=mask)
    assert r["mask"] is mask and r["image"].mean() > f.mean() - 1
    r = fogline.AlbuPerturb("fog_07", p=0.0)(image=f)
    assert r["image"] is f
    with pytest.raises(TypeError, match="keyword arguments only"):
        fogline.AlbuPerturb("fog_07")(f)
