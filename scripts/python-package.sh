#!/usr/bin/env bash
# Builds the Python package `fogline` (crates/python, PyO3 + maturin, an abi3 wheel for
# CPython >= 3.9) and installs it into the test environment target/pyenv, with what its
# pytest suite needs (pytest, Pillow, pandas, pyarrow, polars). Then, unless --no-test,
# runs that suite, which compares the package with the CLI binary (built here when missing).
#
#   scripts/python-package.sh             # build, install, pytest
#   scripts/python-package.sh --no-test   # build and install only; prints the env's python
#
# The wheel lands in target/wheels; its compiled crates are cached in target/release by
# cargo, so a rebuild without changes takes seconds. A user installs the package with
# `pip install ./crates/python` instead (see docs/python.md).
set -euo pipefail
cd "$(dirname "$0")/.."

venv=target/pyenv
python=${PYTHON:-python3}
if [ ! -x "$venv/bin/python" ]; then
    echo "creating $venv" >&2
    mkdir -p target
    "$python" -m venv "$venv" >&2
fi
py="$PWD/$venv/bin/python"
need=("maturin==1.16.0" "pytest==9.2.0" "pillow==13.0.0" "numpy==2.4.6" "pandas==3.1.1"
      "pyarrow==26.0.1" "polars==2.1.0")
missing=()
for pin in "${need[@]}"; do
    name=${pin%%==*}
    want=${pin#*==}
    have=$("$py" -c "import importlib.metadata as m; print(m.version('$name'))" 2>/dev/null || true)
    [ "$have" = "$want" ] || missing+=("$pin")
done
if [ ${#missing[@]} -gt 0 ]; then
    echo "installing ${missing[*]} into $venv" >&2
    "$py" -m pip install --quiet --disable-pip-version-check "${missing[@]}" >&2
fi

echo "building the fogline wheel (target/wheels)" >&2
rm -f target/wheels/fogline-*.whl
"$venv/bin/maturin" build --release --quiet -m crates/python/Cargo.toml --out target/wheels >&2
"$py" -m pip install --quiet --disable-pip-version-check --force-reinstall --no-deps \
    target/wheels/fogline-*.whl >&2

if [ "${1:-}" = "--no-test" ]; then
    echo "$py"
    exit 0
fi
cargo build --quiet -p fogline-cli
# From outside the source tree, so `import fogline` is the installed wheel.
cd crates/python/tests
FOGLINE_BIN="$OLDPWD/target/debug/fogline" PYTHONDONTWRITEBYTECODE=1 \
    exec "$py" -m pytest -p no:cacheprovider -q .
