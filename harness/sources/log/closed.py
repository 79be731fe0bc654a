"""A measured log of a closed chain (docs/closed_chains.md): its actuated joints' channels read as an
open chain's are (positions, velocities, torques; checked, cut at gaps, conditioned, split), then every
other joint's motion from the loops (harness/model/closure.py) at every conditioned row.

A closed chain's drives move its actuated joints; their encoders and torques are what its log holds.
The passive joints follow: q_p from Phi(q_a, q_p) = 0 (Newton's method, followed in sample order from
the model's q = 0, so that the log and the bench find the same assembly of the mechanism), q'_p =
-J_p^+ J_a q'_a and q''_p = -J_p^+ (J_a q''_a + b), from the conditioned actuated channels. A passive
joint has no drive: its torque column is zero."""

from __future__ import annotations

import dataclasses

import numpy as np

from harness.base.tomlio import InputError, Table
from harness.model.closure import ClosedChain, ClosureError, motion, positions
from harness.model.spec import RobotSpec
from harness.sources.log.condition import ConditionedLog, FilteredColumns
from harness.sources.log.schema import DataSource

# what a closed chain's log does not support yet (docs/closed_chains.md), with the one value that changes
# nothing
REFUSED = {"side": ("joint", "a closed chain's log is read at its actuated joints")}


def closed_chain_source(root: Table, dt: Table, robot: RobotSpec, source: DataSource) -> DataSource:
    """A closed chain's `[data]` (dt, read as `source`, in the scenario `root`): what its log path does
    not support refused in one line naming the key (only a value that changes nothing is accepted), as
    are the scenario's tables that read an open tree."""
    where = f"model {robot.name!r} is a closed chain (loop {robot.loops[0].name!r})"
    for table in (table for table in ("identification", "refinement") if root.has(table)):
        raise root.error(table, f"{where}: [{table}] on its log is not supported (it reads an open tree: "
                                "docs/closed_chains.md)")
    for key, (accepted, why) in REFUSED.items():
        if dt.has(key) and dt.data[key] != accepted:
            raise dt.error(key, f"{where}: not supported on a closed chain's log ({why})")
    return source


def logged(robot: RobotSpec) -> RobotSpec:
    """The robot as its log is read: of a closed chain, its actuated joints alone (in the chain's
    order, with their limits), whose channels the log holds; an open chain as it is."""
    if not robot.loops:
        return robot
    joints = tuple(robot.joint(name) for name in robot.actuated)
    limits = None if robot.limits is None else {j: v for j, v in robot.limits.items() if j in robot.actuated}
    return dataclasses.replace(robot, name=f"{robot.name} (its actuated joints)", joints=joints, limits=limits,
                               loops=(), actuated=())


def charted(training: ConditionedLog, robot: RobotSpec, file) -> RobotSpec:
    """The robot with its passive ball joints' charts turned to the training span's motion where it takes
    one near its file chart's lock (harness/model/charts.py): from the training span alone, as every choice
    the fit makes; the validation span is followed in that chart. A motion no chart frees is refused,
    naming the file."""
    if not robot.loops:
        return robot
    from harness.model.charts import fitted

    chain = ClosedChain.of(robot)
    try:
        return fitted(chain, training.q[:, [training.joint_index(name) for name in robot.actuated]]).spec
    except ClosureError as exc:
        raise _unfollowed(file, exc) from None


def _unfollowed(file, exc: Exception) -> InputError:
    """The logged motion its loops cannot follow (closure.ClosureError), as the log's bad input."""
    return InputError(file, "columns", f"the actuated joints' logged motion cannot be followed by the loops: {exc}")


def closed(series: ConditionedLog | None, robot: RobotSpec, file) -> ConditionedLog | None:
    """A conditioned span of the actuated joints' channels with every joint's (q, q', q'') from the
    loops, in the robot's joint order; the passive joints' torques zero. A row the loops cannot reach
    (or a motion across a singular configuration) is refused, naming the file."""
    if series is None or not robot.loops:
        return series
    chain = ClosedChain.of(robot)
    order = [series.joint_index(name) for name in robot.actuated]
    try:
        q = positions(chain, series.q[:, order], np.zeros(chain.n))
        m = motion(chain, q, series.qd[:, order], series.qdd[:, order])
    except ClosureError as exc:
        raise _unfollowed(file, exc) from None
    tau = np.zeros_like(m.q)
    tau[:, list(chain.actuated)] = series.tau[:, order]
    full_rate = None if series.full_rate is None else _every_joint(series.full_rate, order, m.G)
    meta = {**series.meta, "passive_joints": {
        "joints": [robot.joint_names[k] for k in chain.passive],
        "from": "the loops at every conditioned row (harness/sources/log/closed.py): q_p from Phi = 0 by Newton's "
                "method followed from q = 0, q'_p = -J_p^+ J_a q'_a, q''_p = -J_p^+ (J_a q''_a + b); torque 0"}}
    return dataclasses.replace(series, joints=tuple(robot.joint_names), q=m.q, qd=m.qd, qdd=m.qdd, tau=tau,
                               meta=meta, full_rate=full_rate)


def _every_joint(columns: FilteredColumns, order: list[int], G: np.ndarray) -> FilteredColumns:
    """A filtered span's full-rate velocities (harness/identify/filtered.py) of every joint: the passive
    joints' q' = G q'_a at every full-rate row, G (N, n, n_a) at the kept rows interpolated linearly
    between them (G is a smooth function of the configuration; held at the first and last kept row
    over the trimmed ends, the filter's guard band), so that every joint's friction columns are
    filtered as the torques were."""
    stretches, at = [], 0
    for qd_a, rows in columns.stretches:
        G_s, full = G[at: at + len(rows)], np.arange(len(qd_a))
        G_full = np.stack([np.interp(full, rows, g) for g in G_s.reshape(len(rows), -1).T], axis=-1)
        stretches.append((np.einsum("mja,ma->mj", G_full.reshape(len(full), *G.shape[1:]), qd_a[:, order]), rows))
        at += len(rows)
    if at != len(G):  # the span's rows are its stretches' kept rows (sources/log/condition.py): else a harness bug
        raise RuntimeError(f"the filtered columns hold {at} rows of a span of {len(G)}")
    return dataclasses.replace(columns, stretches=tuple(stretches))
