#!/usr/bin/env python3
"""The Python peer of `fogline bench monitor`: scikit-image's blind noise estimator.

Two steps, each printing one JSON document on stdout:

    monitor_peer.py export DIR [--width 1920] [--height 1080]
        Writes scikit-image's bundled colour photographs (astronaut, chelsea, coffee, rocket,
        immunohistochemistry), resized with skimage.transform.resize to HEIGHT x WIDTH
        (bilinear, anti-aliased, rounded to uint8), as raw RGB8 files DIR/photo_<name>.rgb.
        Prints {"python", "versions", "photos": [{"name", "file"}]}.

    monitor_peer.py estimate MANIFEST.json
        MANIFEST is a JSON list of {"file", "width", "height"} (raw RGB8 frames). Runs
        skimage.restoration.estimate_sigma(frame, channel_axis=-1, average_sigmas=True) on
        each (0-255 scale: the uint8 frame is passed as is), timing each call on one thread.
        Prints {"python", "versions", "results": [{"file", "sigma", "ms"}]}.

Exit status 3 with a one-line message on stderr when scikit-image or PyWavelets is missing.
"""

import argparse
import json
import os
import platform
import sys
import time

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

PHOTOS = ["astronaut", "chelsea", "coffee", "rocket", "immunohistochemistry"]


def versions():
    import importlib.metadata as m

    out = {}
    for name in ("scikit-image", "PyWavelets", "numpy"):
        try:
            out[name] = m.version(name)
        except m.PackageNotFoundError:
            pass
    return out


def export(args):
    import numpy as np
    import skimage.data
    import skimage.transform

    photos = []
    for name in PHOTOS:
        img = getattr(skimage.data, name)()[..., :3]
        big = skimage.transform.resize(
            img, (args.height, args.width), order=1, anti_aliasing=True
        )
        rgb = np.clip(np.rint(big * 255.0), 0, 255).astype(np.uint8)
        path = os.path.join(args.dir, f"photo_{name}.rgb")
        rgb.tofile(path)
        photos.append({"name": name, "file": path})
    return {"photos": photos}


def estimate(args):
    import numpy as np
    from skimage.restoration import estimate_sigma

    with open(args.manifest) as f:
        frames = json.load(f)
    results = []
    for fr in frames:
        rgb = np.fromfile(fr["file"], dtype=np.uint8).reshape(fr["height"], fr["width"], 3)
        t = time.perf_counter()
        sigma = estimate_sigma(rgb, channel_axis=-1, average_sigmas=True)
        ms = (time.perf_counter() - t) * 1e3
        results.append({"file": fr["file"], "sigma": float(sigma), "ms": ms})
    return {"results": results}


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    e = sub.add_parser("export")
    e.add_argument("dir")
    e.add_argument("--width", type=int, default=1920)
    e.add_argument("--height", type=int, default=1080)
    s = sub.add_parser("estimate")
    s.add_argument("manifest")
    args = p.parse_args()
    try:
        import pywt  # noqa: F401  (estimate_sigma needs it)
        import skimage  # noqa: F401
    except ImportError as err:
        print(f"missing Python package: {err.name} (scripts/python-peers.sh installs it)",
              file=sys.stderr)
        sys.exit(3)
    report = export(args) if args.cmd == "export" else estimate(args)
    report["python"] = platform.python_version()
    report["versions"] = versions()
    json.dump(report, sys.stdout)
    print()


if __name__ == "__main__":
    main()
