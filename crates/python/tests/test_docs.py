"""docs/python.md's examples run, in order, in one namespace (as a reader would paste them)."""

import re
from pathlib import Path

import fogline.bench

DOC = Path(__file__).resolve().parents[3] / "docs" / "python.md"


def test_the_examples_of_docs_python_md_run():
    blocks = re.findall(r"```python\n(.*?)```", DOC.read_text(), flags=re.S)
    assert len(blocks) >= 6, "docs/python.md lost its examples"
    namespace = {}
    for i, block in enumerate(blocks):
        code = compile(block, f"{DOC.name} example {i + 1}", "exec")
        exec(code, namespace)


def test_the_benchmark_runs_and_reports_ratios():
    r = fogline.bench.run(width=64, height=48, sigma=30, repeat=2)
    assert r["ms"]["fogline"] > 0 and r["ms"]["numpy"] > 0
    assert r["speedup"]["numpy"] == r["ms"]["numpy"] / r["ms"]["fogline"]
    assert r["cpu"] and r["kernel"]
    assert fogline.bench.main(["--width", "32", "--height", "16", "--repeat", "1",
                               "--envelope-clips", "0"]) == 0


def test_the_envelope_benchmark_times_python_against_the_cli():
    import os

    r = fogline.bench.run_envelope(clips=60, repeat=1, cli=os.environ.get("FOGLINE_BIN"))
    assert r["rows"] == 480
    assert r["seconds"]["python analyze(DataFrame)"] > 0
    assert r["seconds"]["cli fogline envelope"] > 0
    assert r["python_over_cli"] > 0
