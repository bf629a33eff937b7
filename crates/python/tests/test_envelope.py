"""fogline.envelope.analyze on DataFrames against the CLI's envelope.json."""

import json
import math
import os
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd
import polars as pl
import pyarrow as pa
import pyarrow.csv
import pyarrow.parquet
import pytest

import fogline

ROOT = Path(__file__).resolve().parents[3]
BIN = Path(os.environ.get("FOGLINE_BIN", ROOT / "target" / "debug" / "fogline"))
SMALL = ROOT / "crates" / "envelope" / "tests" / "data" / "small.csv"


def cli_envelope(tmp_path, pairs, *args):
    out = tmp_path / "cli"
    subprocess.run([str(BIN), "-q", "envelope", str(pairs), "--out", str(out), *args],
                   check=True, stdout=subprocess.DEVNULL)
    return json.loads((out / "envelope.json").read_text()), (out / "envelope.md").read_text()


def without_input(d):
    return {k: v for k, v in d.items() if k != "input"}


@pytest.mark.parametrize("reader", ["pandas", "polars", "pyarrow"])
def test_envelope_equals_the_cli_json_on_the_same_pairs(tmp_path, reader):
    cli, _ = cli_envelope(tmp_path, SMALL, "--bootstrap", "300", "--seed", "5", "--pi-star", "0.2")
    table = {
        "pandas": lambda: pd.read_csv(SMALL),
        "polars": lambda: pl.read_csv(SMALL),
        "pyarrow": lambda: pa.csv.read_csv(SMALL),
    }[reader]()
    env = fogline.envelope.analyze(table, bootstrap=300, seed=5, pi_star=0.2)
    assert without_input(env.data) == without_input(cli)
    assert env.data["input"]["format"] == "arrow" and env.data["input"]["n_rows"] == 1920
    # The tables come out as DataFrames.
    th = env.thresholds
    assert isinstance(th, pd.DataFrame) and len(th) == len(cli["thresholds"])
    assert set(env.odd["scenario"]) == {o["scenario"] for o in cli["odd"]}
    assert isinstance(env.frame("odd", library="polars"), pl.DataFrame)


def test_a_larger_synthetic_corpus_and_other_parameters_match_too(tmp_path):
    pairs = tmp_path / "pairs.csv"
    fogline.envelope.write_synthetic_csv(pairs, clips=400, seed=9)
    args = ["--bootstrap", "200", "--seed", "1", "--rule", "max-passing", "--bands", "3",
            "--budgets", "0.10,0.20", "--headline", "0.20", "--taxonomy", "data"]
    cli, md = cli_envelope(tmp_path, pairs, *args)
    env = fogline.envelope.analyze(
        pd.read_csv(pairs), bootstrap=200, seed=1, rule="max-passing", bands=3,
        budgets=[0.10, 0.20], headline_budget=0.20, taxonomy="data",
    )
    assert without_input(env.data) == without_input(cli)
    assert env.markdown.splitlines()[5:] == md.splitlines()[5:]
    assert json.loads(env.to_json()) == env.data


def test_the_same_rows_in_any_chunking_give_the_same_digest():
    df = pd.read_csv(SMALL)
    t = pa.Table.from_pandas(df, preserve_index=False)
    chunked = pa.Table.from_batches(t.to_batches(max_chunksize=100))
    a = fogline.envelope.analyze(t, bootstrap=0)
    b = fogline.envelope.analyze(chunked, bootstrap=0)
    assert a.data == b.data
    assert len(a.data["input"]["sha256"]) == 64


def test_bad_tables_raise_clear_exceptions():
    df = pd.read_csv(SMALL)
    nan = df.copy()
    nan.loc[7, "ade_attacked"] = math.nan
    with pytest.raises(ValueError) as e:
        fogline.envelope.analyze(nan)
    assert "row 8" in str(e.value) and "ade_attacked" in str(e.value)
    with pytest.raises(ValueError, match="l2"):
        fogline.envelope.analyze(df.drop(columns=["l2"]))
    with pytest.raises(TypeError, match="expected a pandas or polars DataFrame"):
        fogline.envelope.analyze([{"clip_id": "a"}])
    with pytest.raises(TypeError, match="unknown analysis parameter.*bootstrapp"):
        fogline.envelope.analyze(df, bootstrapp=10)
    with pytest.raises(ValueError, match="rule"):
        fogline.envelope.analyze(df, rule="fastest")
    with pytest.raises(ValueError, match="taxonomy"):
        fogline.envelope.analyze(df, taxonomy="mine")
    with pytest.raises(ValueError, match="headline"):
        fogline.envelope.analyze(df, headline_budget=0.5)
    with pytest.raises(TypeError, match="bands"):
        fogline.envelope.analyze(df, bands=2.5)
    with pytest.raises(ValueError, match="no data rows"):
        fogline.envelope.analyze(df.iloc[:0])


def test_defaults_are_the_papers():
    d = fogline.envelope.defaults()
    assert d["budgets"] == [0.10, 0.15, 0.20] and d["headline_budget"] == 0.15
    assert d["bootstrap"] == 10000 and d["rule"] == "first-violation"


@pytest.mark.parametrize("codec", ["zstd", "snappy", "gzip", "lz4", "brotli", "none"])
def test_parquet_written_by_pyarrow_in_every_codec_reads_as_the_csv(tmp_path, codec):
    pairs = tmp_path / f"pairs-{codec}.parquet"
    pa.parquet.write_table(pa.csv.read_csv(SMALL), pairs, compression=codec)
    cli, _ = cli_envelope(tmp_path, pairs, "--bootstrap", "50")
    csv, _ = cli_envelope(tmp_path / "csv", SMALL, "--bootstrap", "50")
    assert without_input(cli) == without_input(csv)
    assert cli["input"]["format"] == "parquet"


def test_parquet_written_by_polars_reads_and_pandas_reads_foglines(tmp_path):
    # polars writes zstd unless told otherwise.
    pairs = tmp_path / "pairs.parquet"
    pl.read_csv(SMALL).write_parquet(pairs)
    assert pa.parquet.ParquetFile(pairs).metadata.row_group(0).column(0).compression == "ZSTD"
    cli, _ = cli_envelope(tmp_path, pairs, "--bootstrap", "50")
    csv, _ = cli_envelope(tmp_path / "csv", SMALL, "--bootstrap", "50")
    assert without_input(cli) == without_input(csv)
    # fogline's own exports, in its default codec and another, read by pandas.
    cfg = tmp_path / "campaign.toml"
    cfg.write_text('[clips]\ncount = 4\nseed = 5\nwidth = 192\nheight = 108\n'
                   '[conditions]\nnames = ["noise_30"]\n')
    store = tmp_path / "c.sqlite"
    subprocess.run([str(BIN), "-q", "campaign", "run", str(cfg), "--store", str(store)],
                   check=True, stdout=subprocess.DEVNULL)
    for fmt in ["csv,parquet", "csv,parquet:brotli"]:
        out = tmp_path / fmt.replace(",", "-").replace(":", "-")
        subprocess.run([str(BIN), "-q", "campaign", "export", str(store), "--out", str(out),
                        "--format", fmt], check=True, stdout=subprocess.DEVNULL)
        codec = "BROTLI" if fmt.endswith("brotli") else "ZSTD"
        for table in ["runs", "pairs"]:
            meta = pa.parquet.ParquetFile(out / f"{table}.parquet").metadata
            assert meta.row_group(0).column(0).compression == codec
            from_parquet = pd.read_parquet(out / f"{table}.parquet")
            from_csv = pd.read_csv(out / f"{table}.csv")
            assert len(from_parquet) == len(from_csv) > 0
            assert list(from_parquet.columns) == list(from_csv.columns)
            pd.testing.assert_frame_equal(from_parquet, from_csv, check_dtype=False)
