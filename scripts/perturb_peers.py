#!/usr/bin/env python3
"""The Python peers of `fogline bench perturb`: the same corruptions with numpy, OpenCV,
albumentations and imagecorruptions, timed on the same frame, one thread.

`fogline bench perturb --peers` writes its synthetic frame (raw RGB, uint8, H x W x 3), its
depth map (raw float32 metres, H x W) and its 10 object boxes (JSON) to a temporary
directory, runs this script on them and prints every ratio. Run alone, the script makes a
random frame and prints the same JSON:

    python3 scripts/perturb_peers.py --width 1920 --height 1080 --runs 5

Output (stdout): one JSON object, {"python", "versions", "threads", "results": [{"op",
"peer", "fogline", "ms", "min_ms", "runs", "note"}], "skipped": [{"peer", "why"}]}. `fogline` names the
fogline condition the peer is compared with. Each timing is the median over `--runs` runs
after one warm-up, each run preceded by a 64 MiB sweep that evicts the caches (the same
protocol as the Rust side: a cold frame every time). Peers missing from the interpreter are
reported under "skipped", never fatal.

Conventions of the peers, kept as they are (see ../shared/reference/corruptions.md): they
floor rather than round; albumentations' GaussNoise truncates its noise; imagecorruptions
draws from numpy's global generator. imagecorruptions 1.1.2 still calls `np.float_`, removed
in numpy 2, so the script restores that alias before importing it.
"""

import argparse
import json
import os
import sys
import time

# One thread everywhere, before numpy/OpenCV load their thread pools.
for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
    os.environ[var] = "1"

import numpy as np  # noqa: E402

if not hasattr(np, "float_"):
    np.float_ = np.float64  # imagecorruptions 1.1.2 with numpy 2

FLUSH = np.ones(64 << 20, dtype=np.uint8)


def flush():
    """Evicts the caches: read and write a 64 MiB buffer."""
    FLUSH[::64] += 1


def timed(fn, runs):
    fn()  # warm-up
    times = []
    for _ in range(runs):
        flush()
        t0 = time.perf_counter_ns()
        fn()
        times.append((time.perf_counter_ns() - t0) / 1e6)
    times.sort()
    return times[len(times) // 2], times[0]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--width", type=int, default=1920)
    ap.add_argument("--height", type=int, default=1080)
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--slow-runs", type=int, default=3, help="runs of peers slower than 200 ms")
    ap.add_argument("--frame", help="raw RGB uint8 frame (H x W x 3)")
    ap.add_argument("--depth", help="raw float32 depth in metres (H x W)")
    ap.add_argument("--boxes", help="JSON list of [x, y, w, h] boxes in pixels")
    args = ap.parse_args()
    h, w = args.height, args.width

    if args.frame:
        img = np.fromfile(args.frame, dtype=np.uint8).reshape(h, w, 3)
    else:
        img = np.random.default_rng(0).integers(0, 256, (h, w, 3), dtype=np.uint8)
    if args.depth:
        depth = np.fromfile(args.depth, dtype=np.float32).reshape(h, w)
    else:
        depth = np.full((h, w), 30.0, dtype=np.float32)
    if args.boxes:
        with open(args.boxes) as f:
            boxes = json.load(f)
    else:
        boxes = [[100 + 150 * i, 500, 80, 120] for i in range(10)]

    versions = {"numpy": np.__version__}
    results, skipped = [], []

    def add(op, peer, fogline, fn, runs=None, note=""):
        runs = runs or args.runs
        try:
            ms, min_ms = timed(fn, runs)
        except Exception as e:  # a broken peer is reported, not fatal
            skipped.append({"peer": peer, "why": f"{type(e).__name__}: {e}"})
            return
        results.append(
            {"op": op, "peer": peer, "fogline": fogline, "ms": ms, "min_ms": min_ms,
             "runs": runs, "note": note}
        )

    # --- memory floor
    dst = np.empty_like(img)
    add("copy", "numpy np.copyto", "copy", lambda: np.copyto(dst, img))

    # --- Gaussian noise, numpy reference (float normals, clip, floor)
    rng = np.random.default_rng(0)
    for sigma in (10, 30, 50, 70):
        add(
            f"gaussian noise σ={sigma}",
            "numpy default_rng().normal + clip + astype",
            f"noise_{sigma}",
            lambda s=sigma: np.clip(img + rng.normal(0, s, img.shape), 0, 255).astype(np.uint8),
        )

    # --- gain
    for g, name in ((0.4, "dark"), (1.6, "bright")):
        add(
            f"gain {g}",
            "numpy float32 multiply + clip + astype",
            name,
            lambda g=g: np.clip(img.astype(np.float32) * g, 0, 255).astype(np.uint8),
        )

    # --- homogeneous fog, depth fog (numpy float32)
    airlight = 204.0
    for alpha, name in ((0.3, "fog_03"), (0.7, "fog_07")):
        add(
            f"uniform fog α={alpha}",
            "numpy float32 blend",
            name,
            lambda a=alpha: ((1 - a) * img.astype(np.float32) + a * airlight + 0.5).astype(np.uint8),
        )
    beta = -np.log(1 - 0.7) / 50.0

    def depth_fog():
        t = np.exp(-beta * depth)[..., None]
        return (airlight + (img.astype(np.float32) - airlight) * t + 0.5).astype(np.uint8)

    add("depth fog β=0.024", "numpy float32 exp + blend", "fog_07@depth", depth_fog)

    # --- 10 black boxes with a red outline
    def boxes_np():
        out = img.copy()
        for x, y, bw, bh in boxes:
            out[y : y + bh, x : x + bw] = 0
            out[y : y + 2, x : x + bw] = (255, 0, 0)
            out[y + bh - 2 : y + bh, x : x + bw] = (255, 0, 0)
            out[y : y + bh, x : x + 2] = (255, 0, 0)
            out[y : y + bh, x + bw - 2 : x + bw] = (255, 0, 0)
        return out

    add("10 black boxes + red outline", "numpy slices", "mask_all@boxes", boxes_np)

    # --- OpenCV
    try:
        import cv2

        cv2.setNumThreads(1)
        versions["opencv"] = cv2.__version__
        for g, name in ((0.4, "dark"), (1.6, "bright")):
            lut = np.clip(np.floor(np.arange(256) * g + 0.5), 0, 255).astype(np.uint8)
            add(f"gain {g}", "OpenCV cv2.LUT", name, lambda lut=lut: cv2.LUT(img, lut))
        for alpha, name in ((0.3, "fog_03"), (0.7, "fog_07")):
            lut = np.floor((1 - alpha) * np.arange(256) + alpha * airlight + 0.5).astype(np.uint8)
            add(f"uniform fog α={alpha}", "OpenCV cv2.LUT", name, lambda lut=lut: cv2.LUT(img, lut))
            grey = np.full_like(img, int(airlight))
            add(
                f"uniform fog α={alpha}",
                "OpenCV cv2.addWeighted",
                name,
                lambda a=alpha, grey=grey: cv2.addWeighted(img, 1 - a, grey, a, 0),
            )
    except ImportError as e:
        skipped.append({"peer": "OpenCV", "why": str(e)})

    # --- albumentations
    try:
        import albumentations as A

        versions["albumentations"] = A.__version__
        for sigma in (10, 30, 50, 70):
            t = A.GaussNoise(std_range=(sigma / 255, sigma / 255), mean_range=(0, 0), p=1.0)
            add(
                f"gaussian noise σ={sigma}",
                "albumentations GaussNoise",
                f"noise_{sigma}",
                lambda t=t: t(image=img)["image"],
            )
        for g, name in ((0.4, "dark"), (1.6, "bright")):
            t = A.RandomBrightnessContrast(
                brightness_limit=(0, 0), contrast_limit=(g - 1, g - 1), p=1.0
            )
            add(f"gain {g}", "albumentations RandomBrightnessContrast", name, lambda t=t: t(image=img)["image"])
        for alpha, name in ((0.3, "fog_03"), (0.7, "fog_07")):
            t = A.RandomFog(fog_coef_range=(alpha, alpha), p=1.0)
            add(
                f"fog α={alpha}",
                "albumentations RandomFog",
                name,
                lambda t=t: t(image=img)["image"],
                runs=args.slow_runs,
                note="translucent discs + blur, not the same model",
            )
    except ImportError as e:
        skipped.append({"peer": "albumentations", "why": str(e)})

    # --- imagecorruptions (severity s: the σ, c, … of its tables)
    try:
        import imagecorruptions
        from imagecorruptions import corruptions as C

        versions["imagecorruptions"] = getattr(imagecorruptions, "__version__", "1.1.2")
        for sev, sigma in ((1, "20.4"), (2, "30.6"), (4, "66.3")):
            add(
                f"gaussian noise σ={sigma}",
                f"imagecorruptions gaussian_noise (severity {sev})",
                f"noise_{sigma}",
                lambda s=sev: C.gaussian_noise(img, s),
            )
        add("shot noise c=60", "imagecorruptions shot_noise (severity 1)", "shot_4.25",
            lambda: C.shot_noise(img, 1))
        add("impulse noise 3 %", "imagecorruptions impulse_noise (severity 1)", "impulse_0.03",
            lambda: C.impulse_noise(img, 1))
        add("contrast 0.4", "imagecorruptions contrast (severity 1)", "contrast_0.4",
            lambda: C.contrast(img, 1), note="per-channel means")
        add("defocus r=3", "imagecorruptions defocus_blur (severity 1)", "defocus_3",
            lambda: C.defocus_blur(img, 1), runs=args.slow_runs, note="disk + Gaussian alias")
        from PIL import Image

        add("JPEG q=25", "imagecorruptions jpeg_compression (severity 1)", "jpeg_25",
            lambda: np.asarray(C.jpeg_compression(Image.fromarray(img), 1)),
            note="PIL encode + decode")
        add("fog", "imagecorruptions fog (severity 3)", "fog_07",
            lambda: C.fog(img, 3), runs=args.slow_runs, note="plasma fractal airlight")
    except ImportError as e:
        skipped.append({"peer": "imagecorruptions", "why": str(e)})

    json.dump(
        {
            "python": sys.version.split()[0],
            "versions": versions,
            "threads": 1,
            "width": w,
            "height": h,
            "results": results,
            "skipped": skipped,
        },
        sys.stdout,
    )
    print()


if __name__ == "__main__":
    main()
