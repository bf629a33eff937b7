#!/usr/bin/env bash
# Installs the independent Python peer of fogline's remote-planner protocols.
#
# Creates (once) the virtual environment target/pyenv and installs carla-driver-interface
# 2.3.1 from PyPI into it: a serving and driving implementation of AlpaSim's egodriver gRPC
# contract, written independently of fogline. The interoperability tests
# (`cargo nextest run -p fogline-cli interop`) run against it. Idempotent and quiet; prints
# the environment's python on stdout.
#
#   scripts/python-peers.sh
#   FOGLINE_TEST_PYTHON=$(scripts/python-peers.sh) cargo nextest run -p fogline-cli interop
#
# PYTHON=/path/to/python3 picks the interpreter that creates the environment.
set -euo pipefail
cd "$(dirname "$0")/.."

venv=target/pyenv
python=${PYTHON:-python3}
pin="carla-driver-interface==2.3.1"
if [ ! -x "$venv/bin/python" ]; then
    echo "creating $venv" >&2
    mkdir -p target
    "$python" -m venv "$venv" >&2
fi
have=$("$venv/bin/python" -c "import importlib.metadata as m; print(m.version('carla-driver-interface'))" 2>/dev/null || true)
if [ "$have" != "2.3.1" ]; then
    echo "installing $pin into $venv" >&2
    "$venv/bin/python" -m pip install --quiet --disable-pip-version-check "$pin" >&2
fi
"$venv/bin/python" -c "import carla_driver_interface" >&2
echo "$PWD/$venv/bin/python"
