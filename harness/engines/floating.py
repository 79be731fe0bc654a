"""A floating-base robot's inverse dynamics and mass matrix in each engine, in the harness's
convention (harness/model/floating.py): MuJoCo's free joint (mj_inverse, mj_fullM) and Pinocchio's
free-flyer (rnea, crba), each built from the spec (harness/model/mjspec.py, add_robot;
harness/engines/pinocchio.py, build_model), rigid bodies alone. External wrenches (`Wrench`) act on
bodies beside gravity: the base rows are then what the world must exert on the base besides them."""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
import pinocchio as pin

from harness.base.numerics import largest_relative_difference
from harness.model import floating
from harness.model.floating import BaseMotion
from harness.model.spec import RobotSpec

ENGINES = ("mujoco", "pinocchio")


@dataclass(frozen=True, eq=False)
class Wrench:
    """A wrench on a body (the base's name, or a spec body's): force F_W (N, 3) at its centre of mass
    and moment M_W (N, 3), world axes."""

    body: str
    F_W: np.ndarray
    M_W: np.ndarray


@dataclass(frozen=True, eq=False)
class FloatingDynamics:
    """base (N, 6) [F_W, M_W] the world's wrench on the base about its frame's origin; tau (N, n) the
    joints' torques, spec order."""

    base: np.ndarray
    tau: np.ndarray


def _check(spec: RobotSpec) -> None:
    if spec.floating is None:
        raise ValueError(f"{spec.name}: no floating base")
    if spec.loops:
        raise ValueError(f"{spec.name}: a floating base with loops is not judged free (its tree is)")


def _mujoco(spec: RobotSpec, gravity_W: np.ndarray):
    from harness.model.mjspec import add_robot, new_spec

    ms = new_spec(spec.name, gravity_W)
    ms.option.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    add_robot(ms, spec.rigid(), floating=True)
    model = ms.compile()
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in spec.joint_names]
    return model, mujoco.MjData(model), model.jnt_qposadr[ids], model.jnt_dofadr[ids]


def inverse_dynamics(spec: RobotSpec, gravity_W: np.ndarray, base: BaseMotion, q: np.ndarray, qd: np.ndarray,
                     qdd: np.ndarray, engine: str, wrenches: tuple[Wrench, ...] = ()) -> FloatingDynamics:
    """The engine's inverse dynamics at the states (base, q, q', q''), q each (N, n) spec order."""
    _check(spec)
    if engine == "mujoco":
        return _mujoco_inverse(spec, gravity_W, base, q, qd, qdd, wrenches)
    if engine == "pinocchio":
        return _pinocchio_inverse(spec, gravity_W, base, q, qd, qdd, wrenches)
    raise ValueError(f"no engine {engine!r}")


def _mujoco_inverse(spec, gravity_W, base, q, qd, qdd, wrenches) -> FloatingDynamics:
    model = _mujoco(spec, gravity_W)[0]
    return mujoco_inverse(model, spec.floating.joint, spec.joint_names, base, q, qd, qdd, wrenches)


def mujoco_inverse(model: mujoco.MjModel, free: str, joints: list[str], base: BaseMotion, q: np.ndarray,
                   qd: np.ndarray, qdd: np.ndarray, wrenches: tuple[Wrench, ...] = ()) -> FloatingDynamics:
    """MuJoCo's inverse dynamics (mj_inverse) of `model`, its free joint named `free` and the joints
    `joints` (q's columns), at the states (base, q, q', q''), less the generalised force of `wrenches`."""
    from harness.engines.mujoco_file import Coordinates

    data = mujoco.MjData(model)
    f = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, free)
    qf, vf = model.jnt_qposadr[f], model.jnt_dofadr[f]
    at = Coordinates(model, joints, q, qd, qdd, "the robot")  # a file's ball joint from its three hinges
    qpos, qvel, qacc = floating.to_mujoco(base)
    body_ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, w.body) for w in wrenches]
    out, applied = np.empty((len(q), model.nv)), np.zeros(model.nv)
    for k in range(len(q)):
        data.qpos[qf:qf + 7], data.qvel[vf:vf + 6], data.qacc[vf:vf + 6] = qpos[k], qvel[k], qacc[k]
        at.put(data, k)
        mujoco.mj_inverse(model, data)  # the generalised force of everything but gravity and inertia
        out[k] = data.qfrc_inverse
        for w, b in zip(wrenches, body_ids, strict=True):  # J^T of each wrench, at its body's centre of mass
            applied[:] = 0.0
            mujoco.mj_applyFT(model, data, w.F_W[k], w.M_W[k], data.xipos[b], b, applied)
            out[k] -= applied
    return FloatingDynamics(floating.base_rows_from_mujoco(base, out[:, vf:vf + 6]), at.torques(out))


def _pinocchio_inverse(spec, gravity_W, base, q, qd, qdd, wrenches) -> FloatingDynamics:
    from harness.engines.pinocchio import build_model, states

    pm = build_model(spec.rigid(), gravity_W, floating=True)
    model, data = pm.model, pm.model.createData()
    Q, V, A, vi = states(pm, q, qd, qdd, base)
    at = [1 if w.body == spec.floating.body.name else pm.joint_ids[spec.joint_names.index(
        spec.inner_joint(w.body).name)] for w in wrenches]
    out = np.empty((len(q), model.nv))
    for k in range(len(q)):
        qq, vv, aa = Q[k], V[k], A[k]
        if not wrenches:
            out[k] = pin.rnea(model, data, qq, vv, aa)
            continue
        pin.forwardKinematics(model, data, qq)
        fext = pin.StdVec_Force()
        for _ in range(model.njoints):
            fext.append(pin.Force.Zero())
        for w, j in zip(wrenches, at, strict=True):  # about the world's origin, then in the joint's frame
            c_W = data.oMi[j].act(model.inertias[j].lever)
            fext[j] = fext[j] + data.oMi[j].actInv(pin.Force(w.F_W[k], w.M_W[k] + np.cross(c_W, w.F_W[k])))
        out[k] = pin.rnea(model, data, qq, vv, aa, fext)
    return FloatingDynamics(floating.base_rows_from_pinocchio(base, out[:, :6]), out[:, vi])


def mass_matrix(spec: RobotSpec, base: BaseMotion, q: np.ndarray, engine: str) -> np.ndarray:
    """(N, 6 + n, 6 + n) the engine's mass matrix in the harness's velocities (base twist in world axes,
    then the joints in spec order): T^T M T (harness/model/floating.py, velocity_map)."""
    _check(spec)
    g = np.zeros(3)
    n = len(spec.joints)
    M = np.empty((len(q), 6 + n, 6 + n))
    if engine == "mujoco":
        model, data, qadr, vadr = _mujoco(spec, g)
        qpos = floating.to_mujoco(base)[0]
        order = np.r_[0:6, vadr]
        full = np.empty((model.nv, model.nv))
        for k in range(len(q)):
            data.qpos[:7], data.qpos[qadr] = qpos[k], q[k]
            mujoco.mj_forward(model, data)
            mujoco.mj_fullM(model, data, full)
            M[k] = full[np.ix_(order, order)]
    elif engine == "pinocchio":
        from harness.engines.pinocchio import build_model, full_crba

        pm = build_model(spec.rigid(), g, floating=True)
        model, data = pm.model, pm.model.createData()
        qi = [model.joints[i].idx_q for i in pm.joint_ids]
        order = np.r_[0:6, [model.joints[i].idx_v for i in pm.joint_ids]]
        q_ff = floating.to_pinocchio(base)[0]
        for k in range(len(q)):
            qq = np.empty(model.nq)
            qq[:7], qq[qi] = q_ff[k], q[k]
            M[k] = full_crba(model, data, qq)[np.ix_(order, order)]
    else:
        raise ValueError(f"no engine {engine!r}")
    T = floating.velocity_map(base, engine, n)
    return np.swapaxes(T, 1, 2) @ M @ T


def engines_agreement(spec: RobotSpec, gravity_W: np.ndarray, base: BaseMotion, q: np.ndarray, qd: np.ndarray,
                      qdd: np.ndarray, seed: int) -> dict[str, float]:
    """MuJoCo's free joint against Pinocchio's free-flyer at the states (base, q, q', q''), with a wrench on
    the base and on the outermost body (uniform within +-10 N and +-1 N m, drawn with `seed`): the largest
    relative difference of the base rows and of the joints' torques (each row's or joint's over its
    largest |value|), and of the mass matrices (over its largest entry)."""
    N = len(q)
    rng = np.random.default_rng(seed)
    outer = spec.massive_bodies[-1].name if spec.massive_bodies else spec.floating.body.name
    wrenches = tuple(Wrench(b, rng.uniform(-10, 10, (N, 3)), rng.uniform(-1, 1, (N, 3)))
                     for b in dict.fromkeys((spec.floating.body.name, outer)))
    mj, pn = (inverse_dynamics(spec, gravity_W, base, q, qd, qdd, e, wrenches) for e in ENGINES)
    M_mj, M_pn = (mass_matrix(spec, base, q, e) for e in ENGINES)
    return {"engines": max(largest_relative_difference(mj.base, pn.base), largest_relative_difference(mj.tau, pn.tau)),
            "mass_matrix": float(np.max(np.abs(M_mj - M_pn)) / np.max(np.abs(M_pn)))}
