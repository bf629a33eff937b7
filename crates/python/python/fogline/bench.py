"""Times fogline's Gaussian noise against numpy and albumentations, and the envelope analysis
of a DataFrame against the CLI on the same rows, in one process.

    python -m fogline.bench                 # 1080p frame, sigma 30, 30 repetitions; 16k-row envelope
    python -m fogline.bench --sigma 70 --repeat 50 --json
    python -m fogline.bench --cli target/release/fogline --envelope-clips 4000

Every contender runs on one thread on the same uint8 frame (a 1920 x 1080 RGB gradient with
texture); each figure is the median wall time of ``--repeat`` calls after a warm-up call.
albumentations (``pip install albumentations``) is optional: without it, its line says so.
The machine (CPU model, kernel) is printed with the figures, since ratios are what carry
over between machines.

The envelope part writes the synthetic pairs table (``--envelope-clips`` clips x 8
conditions; 2,000 clips = 16,000 rows) to a temporary CSV, reads it into a pandas DataFrame
once, then times ``fogline.envelope.analyze(df)`` against ``fogline envelope pairs.csv``
(the CLI binary from ``--cli``, ``$FOGLINE_BIN`` or ``PATH``; it reads the CSV and writes its
outputs too), median of ``--envelope-repeat`` runs each, default parameters (10,000
bootstrap resamples). It is skipped, saying why, without pandas or the binary.
"""

import argparse
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ._fogline import perturb
from . import envelope as _envelope


def _cpu_model():
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def _frame(width, height):
    rng = np.random.default_rng(0)
    y, x = np.mgrid[0:height, 0:width]
    base = np.stack([x * 255 // width, y * 255 // height, (x + y) * 255 // (width + height)], -1)
    return np.clip(base + rng.integers(-20, 21, base.shape), 0, 255).astype(np.uint8)


def _median_ms(fn, repeat):
    fn()  # warm-up: tables, caches, lazy imports
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append((time.perf_counter() - t0) * 1e3)
    return statistics.median(times)


def run(width=1920, height=1080, sigma=30.0, repeat=30):
    """The figures as a dict: milliseconds per frame for each contender and the ratios."""
    frame = _frame(width, height)
    out = np.empty_like(frame)
    condition = f"noise_{sigma:g}"
    results = {
        "frame": f"{width}x{height} RGB uint8",
        "sigma": sigma,
        "repeat": repeat,
        "cpu": _cpu_model(),
        "kernel": platform.release(),
        "python": platform.python_version(),
        "numpy_version": np.__version__,
        "ms": {},
    }
    calls = iter(range(10**9))
    results["ms"]["fogline"] = _median_ms(
        lambda: perturb(frame, condition, key=next(calls), threads=1), repeat
    )
    results["ms"]["fogline (out=)"] = _median_ms(
        lambda: perturb(frame, condition, key=next(calls), out=out, threads=1), repeat
    )
    rng = np.random.default_rng(0)

    def numpy_noise():
        noise = rng.standard_normal(frame.shape, dtype=np.float32)
        noise *= np.float32(sigma)
        noise += frame
        np.rint(noise, out=noise)
        return np.clip(noise, 0, 255).astype(np.uint8)

    results["ms"]["numpy"] = _median_ms(numpy_noise, repeat)
    os.environ.setdefault("NO_ALBUMENTATIONS_UPDATE", "1")  # no network check at import
    try:
        import cv2

        cv2.setNumThreads(1)
        import albumentations as A

        results["albumentations_version"] = A.__version__
        s = sigma / 255.0
        gauss = A.GaussNoise(std_range=(s, s), mean_range=(0.0, 0.0), per_channel=True, p=1.0)
        results["ms"]["albumentations GaussNoise"] = _median_ms(
            lambda: gauss(image=frame)["image"], repeat
        )
    except ImportError as e:
        results["albumentations_missing"] = str(e)
    base = results["ms"]["fogline"]
    results["speedup"] = {
        name: ms / base for name, ms in results["ms"].items() if not name.startswith("fogline")
    }
    return results


def _find_cli(cli):
    for c in (cli, os.environ.get("FOGLINE_BIN"), shutil.which("fogline")):
        if c and Path(c).is_file():
            return str(c)
    return None


def run_envelope(clips=2000, repeat=3, cli=None):
    """The envelope figures as a dict: seconds per analysis in Python and in the CLI."""
    r = {"clips": clips, "rows": clips * 8, "repeat": repeat, "seconds": {}}
    try:
        import pandas
    except ImportError as e:
        r["skipped"] = f"pandas is not installed ({e})"
        return r
    binary = _find_cli(cli)
    with tempfile.TemporaryDirectory() as tmp:
        pairs = Path(tmp) / "pairs.csv"
        _envelope.write_synthetic_csv(pairs, clips=clips, seed=0)
        df = pandas.read_csv(pairs)
        r["seconds"]["python analyze(DataFrame)"] = _median_ms(lambda: _envelope.analyze(df), repeat) / 1e3
        if binary is None:
            r["skipped_cli"] = "no fogline binary: pass --cli PATH or set FOGLINE_BIN"
            return r
        r["cli"] = binary
        out = Path(tmp) / "out"
        cmd = [binary, "-q", "envelope", str(pairs), "--out", str(out)]
        r["seconds"]["cli fogline envelope"] = _median_ms(
            lambda: subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL), repeat
        ) / 1e3
        r["python_over_cli"] = (
            r["seconds"]["python analyze(DataFrame)"] / r["seconds"]["cli fogline envelope"]
        )
    return r


def main(argv=None):
    p = argparse.ArgumentParser(prog="python -m fogline.bench", description=__doc__.splitlines()[0])
    p.add_argument("--width", type=int, default=1920)
    p.add_argument("--height", type=int, default=1080)
    p.add_argument("--sigma", type=float, default=30.0)
    p.add_argument("--repeat", type=int, default=30)
    p.add_argument("--envelope-clips", type=int, default=2000,
                   help="clips of the envelope part (x 8 rows; 0 skips it)")
    p.add_argument("--envelope-repeat", type=int, default=3)
    p.add_argument("--cli", help="the fogline binary the envelope part compares with")
    p.add_argument("--json", action="store_true", help="print the figures as one JSON object")
    a = p.parse_args(argv)
    if a.repeat < 1 or a.width < 1 or a.height < 1 or not a.sigma >= 0:
        p.error("--repeat, --width and --height must be positive, --sigma non-negative")
    r = run(a.width, a.height, a.sigma, a.repeat)
    env = None
    if a.envelope_clips > 0:
        env = run_envelope(a.envelope_clips, max(1, a.envelope_repeat), a.cli)
        r["envelope"] = env
    if a.json:
        print(json.dumps(r, indent=2))
        return 0
    print(f"Gaussian noise sigma {r['sigma']:g} on a {r['frame']} frame, one thread, "
          f"median of {r['repeat']} calls")
    print(f"{r['cpu']}, Linux {r['kernel']}, Python {r['python']}, numpy {r['numpy_version']}"
          + (f", albumentations {r['albumentations_version']}" if "albumentations_version" in r else ""))
    for name, ms in r["ms"].items():
        ratio = r["speedup"].get(name)
        suffix = f"   fogline is {ratio:.1f}x faster" if ratio is not None else ""
        print(f"  {name:<28} {ms:8.2f} ms{suffix}")
    if "albumentations_missing" in r:
        print(f"  albumentations GaussNoise    not installed ({r['albumentations_missing']}): "
              "pip install albumentations")
    if env is not None:
        print(f"Envelope analysis of {env['rows']:,} rows ({env['clips']:,} clips), default "
              f"parameters, median of {env['repeat']} runs")
        if "skipped" in env:
            print(f"  skipped: {env['skipped']}")
        for name, sec in env["seconds"].items():
            print(f"  {name:<28} {sec:8.3f} s")
        if "skipped_cli" in env:
            print(f"  cli fogline envelope         skipped: {env['skipped_cli']}")
        if "python_over_cli" in env:
            print(f"  Python takes {env['python_over_cli']:.2f}x the CLI's time "
                  f"({env['cli']})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
