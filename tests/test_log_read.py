"""A CSV log read a chunk of rows at a time (harness/sources/log/read.py): the same columns as pandas
reading the file whole, the file's sha256, every malformed row refused naming it, and the memory of
the columns kept, not of the file's text and every column beside them."""

from __future__ import annotations

import hashlib
import tracemalloc

import numpy as np
import pandas as pd
import pytest

from harness.api import load_scenario
from harness.sources.log import read
from tests.conftest import BUILTIN, SCENARIOS

LOG = BUILTIN / "logs" / "panda_gaz2019" / "log.csv"
KINDS = {"q": "q{j}", "qd": "qd{j}", "tau": "tau{j}"}


def _scenario(folder, file: str = "log.csv"):
    (folder / "s.toml").write_text(
        f'[scenario]\nmodel = "{SCENARIOS.parent / "models" / "panda_arm.toml"}"\n[data]\nfile = "{file}"\n'
        'columns = { t = "t", q = "q{j}", qd = "qd{j}", tau = "tau{j}" }\n'
        '[[gates]]\nmetric = "log_identification.validation_rel_error.consistent"\nlimit = 1\n')
    return load_scenario(folder / "s.toml")


@pytest.mark.parametrize("chunk", [7, 1000, read.CHUNK_ROWS])
def test_a_log_read_in_chunks_has_pandas_whole_file_columns_and_the_files_sha256(tmp_path, monkeypatch, chunk):
    """Chunks of 7 rows (a bad cell's row counted across them), 1000 and the module's own: the columns
    bit for bit those of pandas' read of the whole file, and the digest the file's bytes'."""
    lines = LOG.read_text().splitlines()[:2001]
    (tmp_path / "log.csv").write_text("\n".join(lines) + "\n")
    sc = _scenario(tmp_path)
    monkeypatch.setattr(read, "CHUNK_ROWS", chunk)
    series = read.read_raw(sc.data, sc.robot)
    whole = pd.read_csv(tmp_path / "log.csv")
    assert np.array_equal(series.t, whole["t"].to_numpy())
    for kind, pattern in KINDS.items():
        expected = whole[[pattern.format(j=j) for j in range(1, 8)]].to_numpy()
        assert np.array_equal(getattr(series, kind), expected), kind
    assert series.meta["sha256"] == hashlib.sha256((tmp_path / "log.csv").read_bytes()).hexdigest()


@pytest.mark.parametrize("chunk", [7, read.CHUNK_ROWS])
def test_a_bad_cell_is_named_with_its_row_and_every_such_row_counted_across_chunks(tmp_path, monkeypatch, chunk):
    df = pd.read_csv(LOG, nrows=100)
    df["q3"] = df["q3"].astype(object)
    df.loc[[40, 41, 90], "q3"] = ["abc", "", "nan"]
    df.to_csv(tmp_path / "log.csv", index=False)
    sc = _scenario(tmp_path)
    monkeypatch.setattr(read, "CHUNK_ROWS", chunk)
    with pytest.raises(read.InputError) as caught:
        read.read_raw(sc.data, sc.robot)
    assert caught.value.key == "q3" and "row 42 is 'abc'" in str(caught.value) and "(3 such rows)" in str(caught.value)


ROWS = {
    "its first row longer than the header": (lambda rows: [rows[0] + ",7", *rows[1:]],
                                             "its first row has more fields than its header's 22"),
    "a later row longer than the header": (lambda rows: [*rows[:5], rows[5] + ",7", *rows[6:]],
                                           "Expected 22 fields in line 7, saw 23"),
    "its first row shorter than the header": (lambda rows: [rows[0].rsplit(",", 1)[0], *rows[1:]],
                                              "tau7: row 2 is empty"),
    "a later row shorter than the header": (lambda rows: [*rows[:5], rows[5].rsplit(",", 1)[0], *rows[6:]],
                                            "tau7: row 7 is empty"),
}


@pytest.mark.parametrize("case", list(ROWS))
def test_a_row_whose_fields_do_not_match_the_header_is_refused_naming_the_file(tmp_path, case):
    """A row longer than the header was once read with its fields shifted (pandas makes the first
    field an index) or its last dropped; a short one's missing fields are empty cells."""
    lines = LOG.read_text().splitlines()
    edit, message = ROWS[case]
    (tmp_path / "log.csv").write_text("\n".join([lines[0], *edit(lines[1:300])]) + "\n")
    sc = _scenario(tmp_path)
    with pytest.raises(read.InputError) as caught:
        read.read_raw(sc.data, sc.robot)
    assert message in str(caught.value) and "log.csv" in str(caught.value)


def test_a_header_without_rows_is_a_log_without_rows(tmp_path):
    (tmp_path / "log.csv").write_text(LOG.read_text().splitlines()[0] + "\n")
    sc = _scenario(tmp_path)
    with pytest.raises(read.InputError, match="the log has no rows"):
        read.read_raw(sc.data, sc.robot)


def test_reading_a_log_allocates_its_columns_and_little_more(tmp_path):
    """A log of 100,000 rows with 8 columns the scenario does not read beside its 22: what reading it
    allocates at its peak (traced) is at most 1.75 times the columns it keeps (1.45 measured: every
    column's pieces, then each kind's array). Reading the file's bytes whole, then pandas' table of
    every column, then the columns, as the reader once did, took 4.2 times."""
    df = pd.read_csv(LOG)
    df = pd.concat([df] * (100_000 // len(df) + 1), ignore_index=True).iloc[:100_000]
    df["t"] = np.arange(len(df)) * 1e-3
    for k in range(8):
        df[f"other{k}"] = df["q1"]
    df.to_csv(tmp_path / "log.csv", index=False)
    sc = _scenario(tmp_path)
    kept = 100_000 * 22 * 8
    tracemalloc.start()
    try:
        series = read.read_raw(sc.data, sc.robot)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert series.q.shape == (100_000, 7)
    assert peak <= 1.75 * kept, peak / kept
