"""Pinocchio's own parse of a robot file (harness/engines/pinocchio_file.py) evaluated at the harness's
joint coordinates, for `harness audit` (harness/runner/audit.py): its torques, mass matrix and regressor
rank, a spherical joint reached from the harness's three hinges of a ball (harness/model/cardano.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from harness.model.spec import RobotSpec


class PinocchioParse:
    """Pinocchio's own parse of the file (harness/engines/pinocchio_file.py: `notes`, what was done to
    let it read an MJCF file), evaluated at the harness's joint coordinates; `other_joints`, the names
    in one reading and not the other. A spherical joint of its parse is the harness's three hinges
    `<ball>_x .. _z` (harness/model/cardano.py)."""

    def __init__(self, path: Path, spec: RobotSpec, gravity_W: np.ndarray):
        import pinocchio as pin

        from harness.engines.pinocchio_file import parse
        from harness.model.mjcf import BALL_AXES

        self.pin = pin
        self.model, notes = parse(path)
        self.notes = [f"Pinocchio's parser given the file with: {n}" for n in notes]
        self.model.gravity.linear = gravity_W
        self.model.armature[:] = 0.0  # rigid bodies only
        names = [[f"{name}_{s}" for s in BALL_AXES] if self.model.joints[i].shortname() == "JointModelSpherical"
                 else [name] for i, name in enumerate(self.model.names) if i]
        self.other_joints = sorted(set(spec.joint_names) ^ {n for group in names for n in group})
        if not self.other_joints:
            self._place(spec.joint_names)
        self.data = self.model.createData()

    def _place(self, joints: list[str]) -> None:
        """Where each of `joints` is in the parse: its hinges' and slides' (index, joint model), and per
        spherical joint its model and the indices of its hinges x, y, z."""
        from harness.model.mjcf import BALL_AXES

        self.scalars, balls = [], {}
        for k, j in enumerate(joints):
            if self.model.existJointName(j):
                self.scalars.append((k, self.model.joints[self.model.getJointId(j)]))
            else:
                ball, axis = j.rsplit("_", 1)
                balls.setdefault(ball, [0, 0, 0])[BALL_AXES.index(axis)] = k
        self.balls = [(self.model.joints[self.model.getJointId(b)], ks) for b, ks in balls.items()]

    @classmethod
    def reduced(cls, parsed: PinocchioParse, model, joints: list[str]) -> PinocchioParse:
        """`parsed` with `model` (its mimic joints made) evaluated at `joints`' coordinates alone."""
        out = cls.__new__(cls)
        out.pin, out.model, out.notes, out.other_joints = parsed.pin, model, [], []
        out._place(joints)
        out.data = model.createData()
        return out

    def states(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> tuple[np.ndarray, ...]:
        """Pinocchio's configurations, velocities and accelerations (N, nq), (N, nv), (N, nv) at the harness's
        (q, q', q'') (N, n), and T (N, nv, n) with v = T q': a continuous joint (nq = 2) as (cos q, sin q); a
        spherical joint's quaternion (x, y, z, w) of its hinges' R(theta), its v the body's angular velocity
        D theta' and its a D theta'' + D' theta' (harness/model/cardano.py)."""
        from harness.model.cardano import ball_state

        N, n = q.shape
        cfg = np.tile(self.pin.neutral(self.model), (N, 1))
        v, a, T = np.zeros((N, self.model.nv)), np.zeros((N, self.model.nv)), np.zeros((N, self.model.nv, n))
        for k, jm in self.scalars:
            cfg[:, jm.idx_q: jm.idx_q + jm.nq] = np.column_stack([np.cos(q[:, k]), np.sin(q[:, k])]) if jm.nq == 2 \
                else q[:, k, None]
            v[:, jm.idx_v], a[:, jm.idx_v], T[:, jm.idx_v, k] = qd[:, k], qdd[:, k], 1.0
        for jm, ks in self.balls:
            quat, omega, omegadot, D = ball_state(q[:, ks], qd[:, ks], qdd[:, ks])
            cfg[:, jm.idx_q: jm.idx_q + 4] = quat[:, [1, 2, 3, 0]]
            v[:, jm.idx_v: jm.idx_v + 3], a[:, jm.idx_v: jm.idx_v + 3] = omega, omegadot
            T[:, jm.idx_v: jm.idx_v + 3, ks] = D
        return cfg, v, a, T

    def torques_and_mass(self, q, qd, qdd) -> tuple[np.ndarray, np.ndarray]:
        """The harness's joints' torques T^T tau (N, n) and mass matrix T^T M T (N, n, n) by Pinocchio's
        RNEA and CRBA of its parse."""
        from harness.engines.pinocchio import full_crba

        cfg, v, a, T = self.states(q, qd, qdd)
        tau, M = np.empty_like(q), np.empty((len(q), q.shape[1], q.shape[1]))
        for k in range(len(q)):
            tau[k] = T[k].T @ self.pin.rnea(self.model, self.data, cfg[k], v[k], a[k])
            M[k] = T[k].T @ full_crba(self.model, self.data, cfg[k]) @ T[k]
        return tau, M

    def regressor(self, q, qd, qdd) -> np.ndarray:
        """Pinocchio's joint torque regressor T^T Y at (q, q', q''), (N n, 10 per joint of its model)."""
        cfg, v, a, T = self.states(q, qd, qdd)
        return np.vstack([T[k].T @ self.pin.computeJointTorqueRegressor(self.model, self.data, cfg[k], v[k], a[k])
                          for k in range(len(q))])


def rank(W: np.ndarray) -> int:
    """The numerical rank of a regressor, its columns scaled to unit norm: singular values above
    max(shape) eps 1e3 of the largest."""
    from harness.base.numerics import column_scale

    W = W / column_scale(W)
    sv = np.linalg.svd(W, compute_uv=False)
    return int(np.sum(sv > sv[0] * max(W.shape) * np.finfo(float).eps * 1e3)) if sv.size else 0


def massive_ranks(pm, pin_model: PinocchioParse, W_pin: np.ndarray, states: tuple) -> tuple[int, int]:
    """The ranks of the harness's regressor (of `pm`, at `states`) and of Pinocchio's (`W_pin`, its parse's
    at the same states) over the columns of their bodies with mass: how a reading with massless bodies is
    compared with a parse that has other ones (a ball joint's two carriages, harness/model/mjcf.py, where
    Pinocchio's spherical joint has none). A massless body's ten columns are torque_id's known zeros."""
    from harness.identify.torque_id import known_zero, regressor

    ours = known_zero(pm.model, pm.joint_ids, regressor(pm, *states))
    theirs = known_zero(pin_model.model, range(1, pin_model.model.njoints), W_pin.copy())
    return rank(ours), rank(theirs)
