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
    assert series.sha256 == hashlib.sha256((tmp_path / "log.csv").read_bytes()).hexdigest()


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


@pytest.mark.slow  # a long log's memory traced (1.3 s)
def test_reading_a_log_allocates_its_columns_and_little_more(tmp_path):
    """A log of 100,000 rows with 8 columns the scenario does not read beside its 22: what reading it
    allocates at its peak (traced) is at most 1.75 times the columns it keeps (1.45 measured: every
    column's pieces, then each kind's array). Reading the file's bytes whole, then pandas' table of
    every column, then the columns, as the reader once did, took 4.2 times."""
    df = pd.read_csv(LOG)
    for k in range(8):
        df[f"other{k}"] = df["q1"]
    header, *rows = df.to_csv(index=False).splitlines()  # the log's rows repeated, each formatted once
    cells, at = [r.split(",") for r in rows], list(df.columns).index("t")
    lines = [header]
    for i in range(100_000):  # the time column 1 ms apart throughout
        row = cells[i % len(cells)]
        lines.append(",".join([*row[:at], repr(i * 1e-3), *row[at + 1:]]))
    (tmp_path / "log.csv").write_text("\n".join(lines) + "\n")
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


TX40 = BUILTIN / "logs" / "staubli_tx40" / "data"


def _tx40(folder, positions: str = str(TX40 / "pos_read_data.csv"), torques: str = str(TX40 / "curr_data.csv")):
    """folder/s.toml: the TX40's scenario as shipped (motor side, two files, no time column), on the
    files named (relative to `folder`)."""
    text = (SCENARIOS / "tx40.toml").read_text()
    text = text.replace('model = "../models/tx40.toml"', f'model = "{SCENARIOS.parent / "models" / "tx40.toml"}"')
    text = text.replace('"../logs/staubli_tx40/data/pos_read_data.csv"', f'"{positions}"')
    (folder / "s.toml").write_text(text.replace('"../logs/staubli_tx40/data/curr_data.csv"', f'"{torques}"'))


def _edited(folder, name: str, row: int, column: int, cell: str) -> str:
    """A copy of the TX40's file `name` in `folder` with one cell (data row `row`, 0-based) replaced."""
    lines = (TX40 / name).read_text().split("\n")
    fields = lines[row + 1].split(",")
    fields[column] = cell
    lines[row + 1] = ",".join(fields)
    (folder / f"edited_{name}").write_text("\n".join(lines))
    return f"edited_{name}"


@pytest.mark.parametrize(("name", "cell", "said"), [
    ("curr_data.csv", "1e300", "row 20001 is 1e+300 N m: over 1000 times the largest torque the model allows there "
                               "(5.01 N m)"),
    ("curr_data.csv", "-1e30", "row 20001 is -1e+30 N m"),
    ("pos_read_data.csv", "1e30", "row 20001 is 1e+30 rad: over 1000 times the largest position the model allows "
                                  "there (287 rad)"),
])
def test_a_value_no_robot_of_the_models_size_measures_is_refused_naming_file_row_and_column(tmp_path, name, cell,
                                                                                              said):
    """One cell of the TX40's published log made absurd (at its motors: the torque bound is the joints'
    through N^-T, 5.01 N m at motor 3 = 45 x less than joint 3's; the position's through |N|)."""
    edited = _edited(tmp_path, name, 19999, 2, cell)
    _tx40(tmp_path, **{"positions" if name.startswith("pos") else "torques": edited})
    sc = load_scenario(tmp_path / "s.toml")
    with pytest.raises(read.InputError) as caught:
        read.read_raw(sc.data, sc.robot)
    assert caught.value.file == str(tmp_path / edited) and caught.value.key == "Joint_3"
    assert caught.value.message.startswith(said)


def test_an_absurd_cell_ends_the_run_in_one_line_with_nothing_written_and_no_numpy_or_lapack_message(tmp_path, capfd):
    """`harness run` on the TX40's log with a torque cell of 1e300 (it ended in LAPACK's 'SVD did not
    converge', exit 3, with numpy's overflow warnings and LAPACK's own messages on the terminal)."""
    from harness.cli import main

    _tx40(tmp_path, torques=_edited(tmp_path, "curr_data.csv", 19999, 2, "1e300"))
    capfd.readouterr()
    assert main(["run", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    captured = capfd.readouterr()
    errors = [line for line in captured.err.splitlines() if not line.startswith("harness: warning:")]
    assert errors == [f"harness: error: {tmp_path / 'edited_curr_data.csv'}: Joint_3: row 20001 is 1e+300 N m: over "
                      "1000 times the largest torque the model allows there (5.01 N m), which no robot of its size "
                      "measures: a corrupt value (1 such value in the column)"]
    assert captured.out == "" and not (tmp_path / "out").exists()


@pytest.mark.parametrize("cut", [3, 9])  # the last number shortened; the last two fields gone
def test_a_last_line_cut_short_is_dropped_from_both_files_with_a_line_saying_so(tmp_path, cut):
    """The torque file's last line without its line end (a logger stopped mid-line): its row dropped
    from both files, which are read row by row, and said; every other row as pandas reads it."""
    text = (TX40 / "curr_data.csv").read_text().rstrip("\n")
    (tmp_path / "cut.csv").write_text(text[:-cut])
    _tx40(tmp_path, torques="cut.csv")
    sc = load_scenario(tmp_path / "s.toml")
    series = read.read_raw(sc.data, sc.robot)
    whole = pd.read_csv(TX40 / "curr_data.csv").to_numpy()[:-1]
    assert len(series.t) == len(whole) == 44999
    np.testing.assert_array_equal(series.tau, sc.robot.transmission.joint_torques(whole))
    assert series.read["warnings"] == ["cut.csv: the last line has no line end (the file cut short while "
                                               "written?): row 45001 dropped from both files"]


def test_a_log_that_ends_without_a_line_end_still_refuses_a_bad_cell_before_its_last_line(tmp_path):
    """The cut line is the last one only: an empty cell before it is refused as before."""
    lines = (TX40 / "curr_data.csv").read_text().rstrip("\n").split("\n")
    lines[100] = lines[100].split(",", 1)[1]
    (tmp_path / "cut.csv").write_text("\n".join(lines)[:-3])
    _tx40(tmp_path, torques="cut.csv")
    sc = load_scenario(tmp_path / "s.toml")
    with pytest.raises(read.InputError, match=r"Joint_6: row 101 is empty"):
        read.read_raw(sc.data, sc.robot)
