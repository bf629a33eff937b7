#!/usr/bin/env bash
# The tests, set-up included (the README's test command; .ci/run runs it):
#   1. the Python peers (scripts/python-peers.sh) in target/pyenv, once: carla-driver-interface
#      (an independent implementation of AlpaSim's egodriver contract) for the interop tests,
#      llama-cpp-python's server and the Gemma 3 270M GGUF for the structured output test
#      (llama-cpp-python is compiled once into target/wheels, about 10 min on two cores);
#   2. Debian's chromium for the report's browser test (scripts/browser-deps.sh), once;
#   3. every test of the workspace with cargo-nextest (extra arguments are passed on);
#   4. the Python package: wheel built and installed into target/pyenv, its pytest suite
#      (scripts/python-package.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/python-peers.sh >/dev/null
scripts/browser-deps.sh >/dev/null
cargo nextest run "$@"
scripts/python-package.sh
