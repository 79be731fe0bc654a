"""RawLog: a log as read (harness/sources/log/read.py), before its checks: the model's joints'
channels in SI units at the joints, one row per sample as the file has it, and the file it came from.

Its rows are not yet a time series: a logger may repeat a row or a time, or write one out of order,
and the checks (harness/sources/log/checks.py) judge that and name the row. What holds on
construction: one finite time per row, q and tau (and q' where the log has it) one finite value per
joint and row. Accelerations are not measured (`qdd` None): they come from the conditioning."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from harness.base.series import rows_checked


@dataclass(frozen=True, eq=False)
class RawLog:
    t: np.ndarray  # (N,) s, as logged
    joints: tuple[str, ...]
    q: np.ndarray  # (N, nj) rad or m
    qd: np.ndarray | None  # (N, nj), None where the log has no velocities
    tau: np.ndarray  # (N, nj) N m or N along each joint's axis
    file: Path  # the log (a validation or payload log: that file)
    sha256: str = ""  # of the file's bytes (a torque file's after them)
    read: dict = field(default_factory=dict)  # the read step's record: the files, units, warnings
    extra: dict = field(default_factory=dict)  # a floating base's channels, row by row, the harness's convention
    # (harness/sources/log/floating.py: base_pose, base_twist_W, contact_F_W, contact_M_W)

    qdd = None  # a raw log measures no accelerations

    def __post_init__(self) -> None:
        rows_checked(self.t, {"q": self.q, "qd": self.qd, "tau": self.tau, **self.extra}, len(self.joints),
                     increasing=False)

    def joint_index(self, name: str) -> int:
        return self.joints.index(name)

    def span(self, rows: np.ndarray | slice) -> RawLog:
        """The rows `rows` (indices, a boolean mask or a slice); the file and the record kept."""
        return dataclasses.replace(self, t=self.t[rows], q=self.q[rows], tau=self.tau[rows],
                                   qd=None if self.qd is None else self.qd[rows],
                                   extra={k: x[rows] for k, x in self.extra.items()})
