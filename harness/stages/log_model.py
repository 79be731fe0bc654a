"""The model as a log's fit reads it (harness/stages/log_identification.py): which joints' torques the
log holds, and every regressor's and prediction's rows as those torques read them.

The log's torques are S^T tau of the tree's joint torques tau = Y theta (plus each joint's drive terms):
of an open tree S selects its measured joints (every joint, or all but `[data] unmeasured`,
harness/sources/log/channels.py); of a closed chain S = G, its actuated joints' projection
(harness/model/closure.py, docs/closed_chains.md), or of its measured actuated joints, G's columns of
the channels the log holds. A joint whose torque is not read keeps its motion in
every row: its velocity and acceleration move the links outboard and inboard of it in the other joints'
rows, so those links are identified from them; the parameters only its own row sees (of an open tree,
its drive's friction and rotor inertia, and the combinations of its outer links that reach no measured
row) are not in the structural base and stay the model's.

A counterbalanced joint's channel (`[data] counterbalanced`: a spring or counterweight holds its weight)
carries the joint's torque less its gravity torque: its rows are the regressor's less the gravity
regressor's, Y(q, q', q'') - Y(q, 0, 0) on the links' columns (the gravity torque is Y(q, 0, 0) theta,
linear in the same parameters), and its predicted torque the model's less its gravity torque. A
counterweight's torque that is not the joint's gravity (a spring's) is not modelled beyond the constant
offset."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from harness.engines.pinocchio import PinocchioModel, build_model, joint_torques
from harness.identify.friction_law import drives_reaching
from harness.identify.laws import Law, extra_regressor
from harness.identify.span_rows import RowsOnDemand, span_regressor
from harness.identify.torque_id import (
    BaseParameters,
    chain_regressor,
    gravity_rows,
    regressor,
    selected_rows,
    structural_base,
    true_parameters,
    without_gravity,
)
from harness.model.closure import ClosedChain, actuated_torques, projection, random_within_limits


@dataclass(frozen=True, eq=False)
class LogModel:
    """The model as the fit reads it: its Pinocchio model, its structural base parameters with each
    joint's friction and rotor inertia, and its own values of all of them. Of a closed chain (`chain`,
    harness/model/closure.py) the log's torques are its actuated joints' and a regressor's rows are
    the tree's projected onto them, G^T Y (docs/closed_chains.md); with `channels`, its measured
    joints' rows alone (an open tree's joints', a closed chain's actuated joints')."""

    pm: PinocchioModel
    base: BaseParameters
    x_model: np.ndarray  # (14 n,) every link's ten parameters, then every joint's four drive terms
    link_part: tuple[np.ndarray, np.ndarray]  # BaseParameters.link_part at the model's values
    joints: list[str]  # every joint, in the spec's order
    chain: ClosedChain | None = None
    channels: tuple[int, ...] | None = None  # the measured ones among the joints (a chain's: actuated); None: all
    weightless: tuple[int, ...] = ()  # joints (an open tree's) whose channel carries no gravity: counterbalanced
    chain_reach: np.ndarray | None = None  # (n, m) of a closed chain with channels: `reached`

    @property
    def torque_joints(self) -> list[str]:
        """The joints whose torques the log holds: every joint, a closed chain's actuated ones, or an open
        tree's measured ones."""
        every = self.joints if self.chain is None else list(self.chain.spec.actuated)
        return every if self.channels is None else [every[k] for k in self.channels]

    @property
    def measured(self) -> np.ndarray:
        """(n,) bool: each joint whose drive terms reach a torque the log holds: an open tree's measured
        joints; of a closed chain, every joint whose torque G^T carries to a measured channel (all of
        them where every actuated channel is read)."""
        if self.chain is not None:
            return self.reach.any(axis=1)
        if self.channels is None:
            return np.ones(len(self.joints), dtype=bool)
        return np.isin(self.joints, self.torque_joints)

    @property
    def drives_reached(self) -> np.ndarray:
        """(drives,) bool: each drive whose terms reach a torque the log holds (its friction and rotor
        inertia identified; the others' stay the model's): a joint's own (`measured`), or with a
        transmission each motor that moves a measured joint."""
        if self.chain is not None:
            return self.measured
        return drives_reaching(self.measured, self.pm.transmission)

    @property
    def reach(self) -> np.ndarray | None:
        """(drives, torque channels) where each drive's terms reach a channel: a closed chain's every
        measured actuated torque through G^T (consistent.fit_with_laws), an open tree's measured joint its
        own channel, a transmission's motor k the measured joints j with N[k, j] != 0; None: every joint
        its own, or every joint's channel read through the model's drives (the fit reads its N)."""
        if self.chain is not None:
            return np.ones((len(self.joints), len(self.torque_joints)), dtype=bool) if self.chain_reach is None \
                else self.chain_reach
        if self.channels is None:
            return None
        if self.pm.transmission is not None:
            return self.pm.transmission.N[:, list(self.channels)] != 0
        return np.arange(len(self.joints))[:, None] == np.asarray(self.channels)[None, :]

    def data(self, series) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """A span's (q, q', q'') of every joint and its torques (N, torque joints)."""
        q, qd, qdd, tau = series.joint_data(self.joints)
        return q, qd, qdd, tau[:, [self.joints.index(j) for j in self.torque_joints]]

    def rows(self, pm: PinocchioModel, q, qd, qdd, coulomb=None) -> np.ndarray | RowsOnDemand:
        """The span's regressor with friction, (N m, 14 n) for the m torque channels: every joint's
        (a long span's made on demand), an open tree's measured joints', or a closed chain's G^T Y (its
        measured actuated joints')."""
        if self.chain is None:
            W = span_regressor(pm, q, qd, qdd, coulomb)
            if self.channels is None and not self.weightless:
                return W
            W = without_gravity(pm, q, W.whole() if isinstance(W, RowsOnDemand) else W, self.weightless)
            return self._selected(W, len(self.joints))
        return self._selected(chain_regressor(pm, self.chain, q, qd, qdd, with_friction=True, coulomb=coulomb),
                              len(self.chain.actuated))

    def joint_rows(self, pm: PinocchioModel, q, qd, qdd) -> np.ndarray:
        """(N, n, 14 n): every joint's rows with friction as its channel reads them: a counterbalanced
        joint's without gravity, an unmeasured joint's zero (they weigh nothing in a fit)."""
        W = without_gravity(pm, q, regressor(pm, q, qd, qdd, with_friction=True), self.weightless)
        return W.reshape(len(q), len(self.joints), -1) * self.measured[:, None]

    @property
    def plain(self) -> bool:
        """Every joint's channel read as its torque: an open tree, every joint measured, none counterbalanced."""
        return self.chain is None and self.channels is None and not self.weightless

    def _selected(self, rows: np.ndarray, per_sample: int) -> np.ndarray:
        """Rows (N per_sample, c) of each sample's joints or actuated joints: the measured channels' alone."""
        return rows if self.channels is None else selected_rows(rows, per_sample, self.channels)

    def projection(self, q: np.ndarray) -> np.ndarray:
        """A closed chain's G (N, n, m) at q: every joint's velocity per unit velocity of each actuated
        joint whose channel the log holds (its columns of closure.projection)."""
        G = projection(self.chain, q)
        return G if self.channels is None else G[:, :, list(self.channels)]

    def projected(self, q: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """Per-joint rows (N n, c) as the log's torques read them: an open tree's measured joints', a
        closed chain's projected onto its measured actuated joints by G^T, (N m, c)."""
        if self.chain is None:
            return self._selected(rows, len(self.joints))
        N, n = q.shape
        G = self.projection(q)
        return np.einsum("nja,njc->nac", G, rows.reshape(N, n, -1)).reshape(N * G.shape[2], -1)

    def torques(self, pm: PinocchioModel, q, qd, qdd) -> np.ndarray:
        """(N, torque joints): the model pm's joint torques at the states as the log reads them."""
        tau = joint_torques(pm, q, qd, qdd)
        if self.weightless:  # a counterbalanced joint's channel: less its gravity torque, Y(q, 0, 0) theta
            tau[:, list(self.weightless)] -= gravity_rows(pm, q, self.weightless) @ true_parameters(pm)
        if self.chain is not None:
            return actuated_torques(self.projection(q), tau)
        return tau if self.channels is None else tau[:, list(self.channels)]

    def every_joint(self, x: np.ndarray) -> np.ndarray:
        """(N, n): an open tree's per-channel x (N, m) at its joints, zero at an unmeasured joint's."""
        if self.channels is None or self.chain is not None:
            return x
        out = np.zeros((len(x), len(self.joints)))
        out[:, list(self.channels)] = x
        return out

    def families(self, laws: tuple[Law, ...], q, qd, rigid, transmission, columns, t) -> np.ndarray:
        """The families' columns (extra_regressor) on a span's rows; a closed chain's from every joint's
        law projected by G^T (no law of a closed chain reads the load: harness/model/load.py). `rigid`
        (N, m): the rigid-body torque of the channels, a load-dependent law's."""
        if self.chain is None:
            rigid = None if rigid is None else self.every_joint(rigid)
            return self._selected(extra_regressor(laws, qd, rigid, transmission, columns, t, q), len(self.joints))
        return self.projected(q, extra_regressor(laws, qd, None, None, columns, t, q))

    @property
    def n(self) -> int:
        return len(self.x_model) // 14

    @property
    def theta(self) -> np.ndarray:
        """(n, 10) the links' parameters."""
        return self.x_model[: 10 * self.n].reshape(self.n, 10)


def log_model(robot, gravity_W: np.ndarray, unmeasured: tuple[str, ...] = (),
              counterbalanced: tuple[str, ...] = ()) -> LogModel:
    """The robot's LogModel; `unmeasured`: joints whose torque the log does not hold (of a closed chain,
    actuated joints); `counterbalanced`: joints of an open tree whose channel carries no gravity."""
    pm = build_model(robot, gravity_W)
    chain = ClosedChain.of(robot) if robot.loops else None
    if counterbalanced and chain is not None:
        raise ValueError("counterbalanced channels are read on an open tree")
    logged = robot.joint_names if chain is None else list(robot.actuated)  # the joints with a channel
    if not set(unmeasured) <= set(logged):
        raise ValueError(f"unmeasured joints {sorted(set(unmeasured) - set(logged))} have no channel to leave out")
    channels = tuple(k for k, j in enumerate(logged) if j not in unmeasured) if unmeasured else None
    weightless = tuple(robot.joint_names.index(j) for j in counterbalanced)
    base = structural_base(pm, robot.limits, with_friction=True, chain=chain, channels=channels, weightless=weightless)
    x_model = true_parameters(pm, with_friction=True)
    chain_reach = None if chain is None or channels is None else reached(chain, robot, channels)
    return LogModel(pm, base, x_model, base.link_part(x_model, 10 * len(robot.joints)), robot.joint_names, chain,
                    channels, weightless, chain_reach)


REACH_STATES = 32  # random consistent states at which a closed chain's G is read for `reached`


def reached(chain: ClosedChain, robot, channels: tuple[int, ...]) -> np.ndarray:
    """(n, m) bool: whether joint j's torque reaches measured actuated channel k, G[j, k] != 0 (beyond
    1e-12 of |G|'s largest) at some of REACH_STATES random consistent states (closure.random_within_limits,
    as structural_base draws them). An unmeasured actuated joint's row is G's identity row: it reaches no
    measured channel, and its friction and rotor inertia stay the model's, as an open tree's unmeasured
    joint's do; a passive joint that moves with the measured joints reaches theirs."""
    G = random_within_limits(chain, robot.limits, REACH_STATES, seed=0).G[:, :, list(channels)]
    return np.abs(G).max(axis=0) > 1e-12 * max(float(np.abs(G).max()), 1.0)
