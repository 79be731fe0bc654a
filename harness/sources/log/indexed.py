"""A log whose messages name their joints: a ROS joint_states export (`rostopic echo -p`) writes each
message's joint names in columns `field.name0`, `field.name1`, ... and its values in `field.position0`,
`field.velocity0`, `field.effort0`, ... in the message's own order, which need not be the model's.

A scenario reads it as written: `columns.names = "field.name{index}"` and `q = "field.position{index}"`
(and so for qd and tau), {index} the place of a joint's name among the names. The file's names are read
(every row's, as text), each model joint (its log name, `joint_map`) found among them, and the templates
made the explicit column lists the rest of the reading takes; a row that names its joints otherwise than
the first is refused, naming it (its values would be read against the first row's order)."""

from __future__ import annotations

import csv
import dataclasses
from pathlib import Path

import numpy as np

from harness.base.tomlio import InputError
from harness.model.spec import RobotSpec
from harness.sources.log.schema import DataSource


def resolved(source: DataSource, robot: RobotSpec, path: Path) -> DataSource:
    """`source` with its {index} templates made the column lists of the file at `path` (module
    docstring); a source without `names` as it is."""
    if "names" not in source.columns:
        return source
    import pandas as pd

    template = str(source.columns["names"])
    try:
        with open(path, newline="", encoding="utf-8-sig") as f:
            header = [name.strip() for name in next(csv.reader(f), [])]
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(path, "", f"cannot read ({exc})") from None
    count = 0
    while template.format(index=count) in header:
        count += 1
    if not count:
        raise InputError(path, template.format(index=0), "column missing: the messages' joint names (columns.names)")
    name_columns = [template.format(index=k) for k in range(count)]
    try:
        names = pd.read_csv(path, usecols=name_columns, dtype=str, keep_default_na=False)[name_columns].to_numpy()
    except (ValueError, pd.errors.ParserError) as exc:
        raise InputError(path, name_columns[0], f"not a CSV log ({str(exc).splitlines()[0]})") from None
    if not len(names):
        raise InputError(path, "", "the log has no rows")
    names = np.char.strip(names.astype(str))
    first = list(names[0])
    other = np.flatnonzero(~np.all(names == names[0], axis=1))
    if other.size:
        raise InputError(path, name_columns[0], f"row {other[0] + 2} names its joints {list(names[other[0]])}, the "
                                                f"first row {first}: the messages' order changes, and their values "
                                                "would be read against the first's")
    index = []
    for joint, log_name in zip(robot.joint_names, source.log_names(robot.joint_names), strict=True):
        if log_name not in first:
            raise InputError(path, name_columns[0], f"no message names joint {joint!r}"
                                                    + (f" (as {log_name!r})" if log_name != joint else "")
                                                    + f": they name {', '.join(first)}")
        index.append(first.index(log_name))
    columns = {k: v if k == "t" else tuple(str(v).format(index=i) for i in index)
               for k, v in source.columns.items() if k != "names"}
    return dataclasses.replace(source, columns=columns)
