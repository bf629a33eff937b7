#!/usr/bin/env bash
# Benchmarks fogline's perturbation engine against its Python peers in one go.
#
# Creates (once) a virtual environment under target/perturb-peers-venv with numpy,
# albumentations, imagecorruptions and opencv-python-headless from PyPI, builds the fogline
# binary in release mode, and runs `fogline bench perturb --peers`, which times every family
# on a synthetic frame, runs scripts/perturb_peers.py on the same frame and prints every
# ratio. Extra arguments go to `fogline bench perturb` (e.g. --width 640 --height 360,
# --runs 5, --json).
#
#   scripts/perturb-peers.sh
#   scripts/perturb-peers.sh --json > bench-perturb.json
#
# PYTHON=/path/to/python3 picks the interpreter that creates the environment.
set -euo pipefail
cd "$(dirname "$0")/.."

venv=target/perturb-peers-venv
python=${PYTHON:-python3}
if [ ! -x "$venv/bin/python" ]; then
    echo "creating $venv" >&2
    mkdir -p target
    "$python" -m venv "$venv"
fi
if ! "$venv/bin/python" -c "import numpy, albumentations, imagecorruptions, cv2" 2>/dev/null; then
    echo "installing the peers into $venv" >&2
    "$venv/bin/python" -m pip install --quiet --upgrade pip >&2
    "$venv/bin/python" -m pip install --quiet numpy albumentations imagecorruptions \
        opencv-python-headless >&2
fi

exec cargo run --release --quiet -p fogline-cli -- \
    bench perturb --peers --python "$PWD/$venv/bin/python" "$@"
