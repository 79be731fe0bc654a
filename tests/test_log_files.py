"""A log as a robot's tools publish it (harness/sources/log/join.py, read.py): one file per quantity,
each with its own time column, joined on time to the positions' file; times in the unit the tools
write; the column names of a PlotJuggler export read as written. The reference for every join is the
same rows read from one file: the joined log must be those rows, to the bit."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from harness.api import load_scenario
from harness.base.tomlio import InputError
from harness.sources.log import read
from tests.conftest import BUILTIN, SCENARIOS, write_frame

LOG = BUILTIN / "logs" / "ur5_bench" / "log.csv"
MODEL = SCENARIOS.parent / "models" / "ur5.toml"
NAMES = ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint", "wrist_3_joint")
ROWS = 600


def _log() -> pd.DataFrame:
    return pd.read_csv(LOG, nrows=ROWS)


def _scenario(folder, file: str, columns: str, units: str = ""):
    (folder / "s.toml").write_text(
        f'[scenario]\nmodel = "{MODEL}"\n[data]\nfile = {file}\ncolumns = {columns}\n{units}'
        '[[gates]]\nmetric = "log_identification.validation_rel_error.consistent"\nlimit = 1\n')
    return load_scenario(folder / "s.toml")


PUBLISHED = '{ t = "t", q = "- {name}_position", qd = "- {name}_velocity", tau = "- {name}_effort" }'


def _published(folder, log: pd.DataFrame, stamps=None, rows=None) -> None:
    """The log as three files, positions, velocities and efforts, each with its own `t` and the
    columns a maker's tool names `- <joint>_position` and so on; `stamps` {file: its times} and
    `rows` {file: the log's rows it holds} where they differ from the positions'."""
    stamps, rows = stamps or {}, rows or {}
    for quantity, prefix in (("position", "q"), ("velocity", "qd"), ("effort", "tau")):
        kept = rows.get(quantity, np.arange(len(log)))
        frame = pd.DataFrame({"t": stamps.get(quantity, log["t"].to_numpy())[kept]}
                             | {f"- {name}_{quantity}": log[f"{prefix}{j + 1}"].to_numpy()[kept]
                                for j, name in enumerate(NAMES)})
        write_frame(frame, folder / f"{quantity}.csv")


THREE = '["position.csv", "velocity.csv", "effort.csv"]'


def _single(folder, log: pd.DataFrame):
    write_frame(log, folder / "one.csv")
    columns = '{ t = "t", q = "q{j}", qd = "qd{j}", tau = "tau{j}" }'
    return read.read_raw(*_data(_scenario(folder, '"one.csv"', columns)))


def _data(sc):
    return sc.data, sc.robot


def _same(a, b) -> None:
    for kind in ("t", "q", "qd", "tau"):
        assert np.array_equal(getattr(a, kind), getattr(b, kind)), kind


def test_three_files_with_their_own_times_and_rows_are_the_log_of_their_common_rows(tmp_path):
    """Velocities from row 5 on, efforts missing rows 100-119 and their last 30: the joined log is the
    one-file log of the rows all three hold, to the bit, and the read step's record says so."""
    log = _log()
    common = np.r_[5:100, 120:ROWS - 30]
    _published(tmp_path, log, rows={"velocity": np.arange(5, ROWS),
                                    "effort": np.r_[0:100, 120:ROWS - 30]})
    joined = read.read_raw(*_data(_scenario(tmp_path, THREE, PUBLISHED)))
    _same(joined, _single(tmp_path, log.iloc[common]))
    record = joined.read["joined_on_time"]
    assert record["reference"].endswith("position.csv") and record["rows_kept"] == len(common)
    assert all(f["nearest"] == 0 for f in record["files"].values())
    said = joined.read["warnings"]
    assert len(said) == 1 and said[0].startswith(f"{ROWS - len(common)} of {ROWS} rows of position.csv have no row")


@pytest.mark.parametrize("offset", [0.3, -0.45])  # of a step: the nearest row within half a step
def test_a_file_stamped_a_little_apart_is_joined_to_its_nearest_rows_and_the_offset_said(tmp_path, offset):
    log = _log()
    h = float(np.median(np.diff(log["t"])))
    _published(tmp_path, log, stamps={"effort": log["t"].to_numpy() + offset * h})
    joined = read.read_raw(*_data(_scenario(tmp_path, THREE, PUBLISHED)))
    _same(joined, _single(tmp_path, log))
    effort = next(v for k, v in joined.read["joined_on_time"]["files"].items() if k.endswith("effort.csv"))
    assert effort["nearest"] == ROWS and effort["exact"] == 0
    assert effort["largest_offset_s"] == pytest.approx(abs(offset) * h, rel=1e-6)
    assert any(f"largest offset {abs(offset) * h * 1e3:.3g} ms" in w for w in joined.read["warnings"])


@pytest.mark.parametrize("stamps", [lambda t: t * 1e3, lambda t: t + 1000.0])  # in ms; from another origin
def test_files_of_another_clock_are_refused_naming_the_file_and_its_time_column(tmp_path, stamps):
    log = _log()
    _published(tmp_path, log, stamps={"effort": stamps(log["t"].to_numpy())})
    with pytest.raises(InputError) as caught:
        read.read_raw(*_data(_scenario(tmp_path, THREE, PUBLISHED)))
    assert caught.value.file.endswith("effort.csv") and caught.value.key == "t"
    assert "not of one clock" in str(caught.value)


def test_times_in_nanoseconds_are_read_in_seconds(tmp_path):
    """A ROS export's stamps (integer nanoseconds since the epoch) with units.t = "ns": the one-file
    log's times moved to that origin, to the float's resolution there (2.4e-7 s at 1.7e9 s)."""
    log = _log()
    origin = 1_700_000_000_000_000_000
    stamped = log.assign(t=(origin + np.round(log["t"].to_numpy() * 1e9)).astype(np.int64))
    _published(tmp_path, stamped)
    joined = read.read_raw(*_data(_scenario(tmp_path, THREE, PUBLISHED, 'units = { t = "ns" }\n')))
    assert np.allclose(joined.t - origin * 1e-9, log["t"].to_numpy(), rtol=0.0, atol=5e-7)
    assert "in ns" in joined.read["time"]


@pytest.mark.parametrize(("file", "edit", "key", "said"), [
    ("velocity.csv", lambda f: f.rename(columns={"t": "stamp"}), "t", "column missing"),
    ("effort.csv", lambda f: f.drop(columns=["- elbow_joint_effort"]), "- elbow_joint_effort", "column missing"),
    ("velocity.csv", lambda f: f.assign(**{"- elbow_joint_effort": 0.0}), "- elbow_joint_effort",
     "in velocity.csv too"),
    ("velocity.csv", lambda f: f.assign(**{f"- {n}_position": 0.0 for n in NAMES}), "- shoulder_pan_joint_position",
     "in position.csv too"),
    ("effort.csv", lambda f: f.assign(t=f["t"].to_numpy()[::-1]), "t", "goes back in time"),
])
def test_a_log_in_several_files_that_cannot_be_joined_is_refused_naming_file_and_column(tmp_path, file, edit, key,
                                                                                        said):
    """A time column missing, a torque column missing, a column in two files (which to read?), a file
    out of time order: refused, the column and the file named, when the scenario loads or the log is read."""
    _published(tmp_path, _log())
    write_frame(edit(pd.read_csv(tmp_path / file)), tmp_path / file)
    with pytest.raises(InputError) as caught:
        sc = _scenario(tmp_path, THREE, PUBLISHED)
        read.read_raw(sc.data, sc.robot)
    assert said in str(caught.value) and caught.value.key == key, str(caught.value)


def test_a_file_holding_none_of_the_logs_columns_is_refused(tmp_path):
    _published(tmp_path, _log())
    pd.DataFrame({"t": [0.0, 1.0], "temperature": [20.0, 21.0]}).to_csv(tmp_path / "extra.csv", index=False)
    with pytest.raises(InputError) as caught:
        _scenario(tmp_path, THREE[:-1] + ', "extra.csv"]', PUBLISHED)
    assert caught.value.file.endswith("extra.csv") and "holds none of the log's columns" in str(caught.value)


def test_a_plotjuggler_export_is_read_as_written(tmp_path):
    """PlotJuggler's CSV export: `__time` in seconds since the epoch, one column per topic path
    (`/joint_states/<joint>/position`): read with those names as the columns' templates."""
    log = _log()
    frame = pd.DataFrame({"__time": 1.7e9 + log["t"].to_numpy()}
                         | {f"/joint_states/{n}/{field}": log[f"{p}{j + 1}"].to_numpy()
                            for j, n in enumerate(NAMES) for field, p in (("position", "q"), ("velocity", "qd"),
                                                                         ("effort", "tau"))})
    write_frame(frame, tmp_path / "plotjuggler.csv")
    columns = ('{ t = "__time", q = "/joint_states/{name}/position", qd = "/joint_states/{name}/velocity", '
               'tau = "/joint_states/{name}/effort" }')
    series = read.read_raw(*_data(_scenario(tmp_path, '"plotjuggler.csv"', columns)))
    one = _single(tmp_path, log)
    for kind in ("q", "qd", "tau"):
        assert np.array_equal(getattr(series, kind), getattr(one, kind)), kind
    assert np.allclose(series.t - 1.7e9, one.t, rtol=0.0, atol=5e-7)


ROSTOPIC = ('{ t = "%time", names = "field.name{index}", q = "field.position{index}", qd = "field.velocity{index}", '
            'tau = "field.effort{index}" }')
ORDER = (3, 0, 5, 1, 4, 2)  # the messages' joint order: the model's joint ORDER[k] at place k


def _rostopic(folder, log: pd.DataFrame, names=None) -> None:
    """The log as `rostopic echo -p /joint_states` writes it: %time in integer nanoseconds since the epoch,
    the header's fields, then each message's joint names and values in its own order (ORDER)."""
    names = names if names is not None else [[NAMES[j] for j in ORDER]] * len(log)
    frame = {"%time": (1_700_000_000_000_000_000 + np.round(log["t"].to_numpy() * 1e9)).astype(np.int64),
             "field.header.seq": np.arange(len(log)), "field.header.frame_id": ""}
    frame |= {f"field.name{k}": [row[k] for row in names] for k in range(6)}
    for field, prefix in (("position", "q"), ("velocity", "qd"), ("effort", "tau")):
        frame |= {f"field.{field}{k}": log[f"{prefix}{j + 1}"].to_numpy() for k, j in enumerate(ORDER)}
    pd.DataFrame(frame).to_csv(folder / "joint_states.csv", index=False, float_format="%.17g")  # names: text


def test_a_ros_joint_states_export_is_read_as_written_whatever_its_joint_order(tmp_path):
    """Its names read from its own columns and each model joint found among them: q, q', tau the one-file
    log's to the bit, t in seconds from its nanoseconds (to the float's 2.4e-7 s at 1.7e9 s)."""
    log = _log()
    _rostopic(tmp_path, log)
    series = read.read_raw(*_data(_scenario(tmp_path, '"joint_states.csv"', ROSTOPIC, 'units = { t = "ns" }\n')))
    one = _single(tmp_path, log)
    for kind in ("q", "qd", "tau"):
        assert np.array_equal(getattr(series, kind), getattr(one, kind)), kind
    assert np.allclose(series.t - 1.7e9, one.t, rtol=0.0, atol=5e-7)


@pytest.mark.parametrize(("names", "said"), [
    (lambda rows: rows[:40] + [list(reversed(rows[40]))] + rows[41:], "row 42 names its joints"),
    (lambda rows: [["other_joint", *row[1:]] for row in rows], "no message names joint 'wrist_1_joint'"),
])
def test_a_joint_states_export_whose_names_change_or_miss_a_joint_is_refused_naming_the_row(tmp_path, names, said):
    log = _log()
    _rostopic(tmp_path, log, names([[NAMES[j] for j in ORDER] for _ in range(len(log))]))
    with pytest.raises(InputError) as caught:
        _scenario(tmp_path, '"joint_states.csv"', ROSTOPIC, 'units = { t = "ns" }\n')
    assert said in str(caught.value) and caught.value.key == "field.name0", str(caught.value)
