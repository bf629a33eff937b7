#!/usr/bin/env bash
# Installs the independent Python peers of fogline into the test environment target/pyenv.
#
# Creates (once) the virtual environment target/pyenv and installs, pinned:
# - carla-driver-interface 2.3.1: a serving and driving implementation of AlpaSim's egodriver
#   gRPC contract, written independently of fogline. The interoperability tests
#   (`cargo nextest run -p fogline-cli interop`) run against it.
# - scikit-image 0.26.0 with PyWavelets 1.9.0: `skimage.restoration.estimate_sigma` and the
#   bundled photographs, the peer of `fogline bench monitor`.
# Idempotent and quiet; prints the environment's python on stdout.
#
#   scripts/python-peers.sh
#   FOGLINE_TEST_PYTHON=$(scripts/python-peers.sh) cargo nextest run -p fogline-cli interop
#   FOGLINE_PYTHON=$(scripts/python-peers.sh) fogline bench monitor
#
# PYTHON=/path/to/python3 picks the interpreter that creates the environment.
set -euo pipefail
cd "$(dirname "$0")/.."

venv=target/pyenv
python=${PYTHON:-python3}
need=("carla-driver-interface==2.3.1" "scikit-image==0.26.0" "PyWavelets==1.9.0")
if [ ! -x "$venv/bin/python" ]; then
    echo "creating $venv" >&2
    mkdir -p target
    "$python" -m venv "$venv" >&2
fi
missing=()
for pin in "${need[@]}"; do
    name=${pin%%==*}
    want=${pin#*==}
    have=$("$venv/bin/python" -c "import importlib.metadata as m; print(m.version('$name'))" 2>/dev/null || true)
    [ "$have" = "$want" ] || missing+=("$pin")
done
if [ ${#missing[@]} -gt 0 ]; then
    echo "installing ${missing[*]} into $venv" >&2
    "$venv/bin/python" -m pip install --quiet --disable-pip-version-check "${missing[@]}" >&2
fi
"$venv/bin/python" -c "import carla_driver_interface, skimage.restoration, pywt" >&2
echo "$PWD/$venv/bin/python"
