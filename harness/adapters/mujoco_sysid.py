"""MuJoCo's system identification (`mujoco.sysid`, mujoco 4.x) as an identification method: the
robot's parameters adjusted until MuJoCo, driven by the measured joint torques, reproduces the
measured motion. Every link's ten inertial parameters (sysid's log-Cholesky pseudo-inertia, physical
by construction) and per joint the rotor inertia (armature), viscous friction (damping), dry
friction (frictionloss) and a torque offset (the motor's bias), from the model as given (a cold
start), by sysid's Gauss-Newton (`optimizer = "mujoco"`, finite differences).

A torque-driven rollout over the whole span drifts away from the log within a second, so the span is
cut into `chunks` pieces of `chunk_seconds`, each rolled out from its measured (q, q') (multiple
shooting), all in one batch of `mujoco.rollout`; the residual is sysid's, the measured q and q'
against the rolled-out ones, each signal divided by its size in the chunk.

What it cannot do, and says so in its notes: MuJoCo's dry friction is a sharp sign solved as a
constraint, not a smooth Coulomb law; the rollouts need the sample times (the method takes `t`).
Three things in mujoco.sysid 4.0 are worked around here: its inertia modifier recomputes the
inertia from geometry (the harness's bodies carry explicit inertials and no geometry); its residual
compiles the model once per chunk (here once per parameter vector, every chunk in one batch); its
default modifier leaves the inertia's frame undefined, which MuJoCo 4.0's compiler refuses.

    [identification]
    name = "sysid"
    plugin = "mujoco_sysid"     # pip install 'harness[sysid]'
    chunks = 20                 # rollouts per evaluation, spread evenly over the training span
                                # (default: as many as tile it, its length over chunk_seconds)
    chunk_seconds = 0.1         # each from a measured state
    timestep = 0.002            # s, semi-implicit Euler (damping implicit)
    iterations = 25             # Gauss-Newton iterations
"""

from __future__ import annotations

import contextlib
import io
import logging
import time
from types import SimpleNamespace

import mujoco
import numpy as np

from harness.base.numerics import sample_step, sampled
from harness.base.plugins import PluginError, ToolUnavailable
from harness.engines.mujoco import dynamics_spec
from harness.engines.pinocchio import build_model, rnea
from harness.identify.torque_id import true_parameters
from harness.model import friction
from harness.model.friction import JointFriction
from harness.model.load import spec_from_mjmodel

OPTIONS = {"chunks": (int, None), "chunk_seconds": (float, 0.1), "timestep": (float, 0.002), "iterations": (int, 25)}
# chunks None: as many as tile the training span (its length over chunk_seconds, rounded up)
MASS_FACTOR = 5.0  # a link's mass within this factor of the model's
STRETCH_FACTOR = 10.0  # its principal moments' scales within this factor
SHEAR = 1.0  # its pseudo-inertia's shear terms within this of the model's
COM_SHIFT = 0.3  # m: its centre of mass within this of the model's, along each axis


def _sysid():
    try:
        from mujoco import sysid
        from mujoco.sysid._src import model_modifier
        from mujoco.sysid._src.residual import model_residual
    except ImportError as exc:
        raise ToolUnavailable("mujoco_sysid", f"MuJoCo's sysid is not installed ({exc}); "
                                              "pip install 'harness[sysid]'") from None
    logging.getLogger("absl").setLevel(logging.ERROR)
    return SimpleNamespace(sysid=sysid, mm=model_modifier, model_residual=model_residual)


def _inertia_modifier(sy, body: str):
    """Writes a link's pseudo-inertia parameters theta (sysid's) into the spec as mass, centre of mass
    and full inertia about it, in the body's frame."""
    def apply(spec, p):
        pi = sy.mm.pi_from_theta(p.value)
        el = spec.body(body)
        el.mass, el.ipos = pi[0], pi[1:4] / pi[0]
        S = sy.mm.skew(el.ipos)
        inertia = pi[4:].reshape(3, 3) + pi[0] * S @ S  # about the centre of mass
        el.inertia[:], el.iquat[:] = 0.0, [1.0, 0.0, 0.0, 0.0]  # fullinertia in the body's own frame
        el.fullinertia[:] = [inertia[0, 0], inertia[1, 1], inertia[2, 2], inertia[0, 1], inertia[0, 2], inertia[1, 2]]
    return apply


def _setter(kind: str, joint: str):
    def apply(spec, p):
        if kind == "offset":  # the measured torque includes the offset: the motor applies tau - offset
            act = spec.actuator(f"drive_{joint}")
            act.biastype = mujoco.mjtBias.mjBIAS_AFFINE
            act.biasprm[0] = -p.value[0]
        elif kind == "damping":
            spec.joint(joint).damping[0] = p.value[0]
        else:
            setattr(spec.joint(joint), kind, p.value[0])
    return apply


class Sysid:
    def __init__(self, robot, gravity_W, parameters: dict):
        unknown = sorted(set(parameters) - set(OPTIONS))
        if unknown:
            raise PluginError("mujoco_sysid", f"unknown option(s) {', '.join(unknown)} (known: {', '.join(OPTIONS)})")
        self.options = {}
        for key, (kind, default) in OPTIONS.items():
            if key not in parameters and default is None:
                self.options[key] = None
                continue
            value = kind(parameters.get(key, default))
            if not value > 0:
                raise PluginError("mujoco_sysid", f"{key} = {value!r}: must be positive")
            self.options[key] = value
        self.sy = _sysid()
        self.robot, self.gravity_W = robot, np.asarray(gravity_W, float)
        self.joint_names = list(robot.joint_names)

    def _parameters(self, ms):
        sy = self.sy
        params = sy.sysid.ParameterDict()
        for body in self.robot.massive_bodies:
            el = ms.body(body.name)  # the harness's body frame: at the centre of mass, on the principal axes
            pi = np.concatenate([[el.mass], np.zeros(3), np.diag(el.inertia).ravel()])
            theta = sy.mm.theta_from_pseudoinertia(sy.mm.pseudoinertia_from_pi(pi))
            span = np.r_[0.5 * np.log(MASS_FACTOR), [0.5 * np.log(STRETCH_FACTOR)] * 3, [SHEAR] * 3, [COM_SHIFT] * 3]
            params.add(sy.sysid.Parameter(f"{body.name}_inertia", theta, theta - span, theta + span,
                                          modifier=_inertia_modifier(sy, body.name)))
        for j, f in zip(self.joint_names, self.robot.frictions, strict=True):
            for kind, value, upper in (("armature", f.armature, 5.0), ("damping", f.viscous, 50.0),
                                       ("frictionloss", f.coulomb, 50.0), ("offset", f.offset, 20.0)):
                lower = -upper if kind == "offset" else 0.0
                start = min(max(value, lower), upper)
                params.add(sy.sysid.Parameter(f"{j}_{kind}", start, lower, upper, modifier=_setter(kind, j)))
        return params

    def fit(self, q, qd, qdd, tau, t):
        sy, o = self.sy, self.options
        ms = dynamics_spec(self.robot, self.gravity_W, "Euler", o["timestep"])
        model = ms.compile()
        params = self._parameters(ms)
        dt = sample_step(t)
        steps = round(o["chunk_seconds"] / dt)
        times = np.arange(steps + 1) * dt  # every chunk on one grid: the batch needs equal lengths
        if steps < 1 or t[-1] - t[0] < times[-1]:
            raise ValueError(f"the training span ({t[-1] - t[0]:g} s) is shorter than one chunk ({times[-1]:g} s) or a "
                             "chunk is shorter than a sample")
        # each chunk starts at a measured sample (its initial state is read, not interpolated)
        last = int(np.searchsorted(t, t[-1] - times[-1], side="right")) - 1
        span = float(t[-1] - t[0])
        count = o["chunks"] or int(np.ceil(span / times[-1] - 1e-9))  # by default the chunks tile the span
        starts = t[np.unique(np.linspace(0, last, count).astype(int))]
        covered = min(len(starts) * times[-1], span) / span  # of the span, the chunks' union at most

        def at(x: np.ndarray, when: np.ndarray) -> np.ndarray:  # the log between its samples: linear
            return sampled(t, x, when)

        inits, controls, sensors = [], [], []
        for s in starts:
            qs, qds = at(q, s + times), at(qd, s + times)
            inits.append(sy.sysid.create_initial_state(model, qs[0], qds[0]))
            controls.append(sy.sysid.TimeSeries(times, at(tau, s + times)))
            sensors.append(sy.sysid.TimeSeries.from_names(times, np.stack([qs, qds], axis=-1).reshape(len(times), -1),
                                                          model))
        chunks = sy.sysid.ModelSequences("robot", ms, [f"chunk {k}" for k in range(len(starts))], inits, controls,
                                         sensors).measured_rollout
        evaluations = [0]

        def residual(x, p, **kwargs):
            res, pred, meas = sy.model_residual(x, p, lambda pp: sy.mm.apply_param_modifiers(pp, ms), chunks, **kwargs)
            if x.ndim == 2:  # the rollouts come chunk by chunk within each finite-difference column
                res = res.reshape(res.shape[0], x.shape[1], len(chunks)).transpose(2, 0, 1).reshape(-1, x.shape[1])
            evaluations[0] += 1 if x.ndim == 1 else x.shape[1]
            return [res], pred, meas

        start = time.perf_counter()
        with contextlib.redirect_stdout(io.StringIO()):  # its optimiser prints every iteration
            found, _ = sy.sysid.optimize(params, residual, optimizer="mujoco", verbose=False,
                                         max_iters=o["iterations"])
        seconds = time.perf_counter() - start
        final = sy.mm.apply_param_modifiers(found, ms)
        spec = spec_from_mjmodel(final, self.robot.source, self.robot.name)
        frictions = tuple(JointFriction(armature=float(found[f"{j}_armature"].value[0]),
                                        viscous=float(found[f"{j}_damping"].value[0]),
                                        coulomb=float(found[f"{j}_frictionloss"].value[0]),
                                        offset=float(found[f"{j}_offset"].value[0]))  # v_c = 0: a sharp sign
                          for j in self.joint_names)
        spec = spec.with_frictions(frictions)
        notes = (f"multiple shooting: {len(starts)} rollouts of {steps} samples ({times[-1]:g} s) from "
                 f"measured states, {len(starts) * times[-1]:g} s of the {span:g} s training span "
                 f"({100 * covered:.0f} % covered{'' if o['chunks'] else ', the default: the chunks tile it'}), "
                 f"{o['iterations']} Gauss-Newton iterations from the model as given; "
                 f"{evaluations[0]} parameter vectors rolled out in {seconds:.1f} s",
                 "dry friction as MuJoCo's frictionloss (a sharp sign), not a smooth Coulomb law")
        return Fitted(spec, self.gravity_W, notes, evaluations[0] * len(starts))


class Fitted:
    """The identified robot: inverse dynamics by Pinocchio's RNEA with its drives' friction; `rollouts`,
    the chunks it simulated in all."""

    def __init__(self, spec, gravity_W, notes, rollouts: int):
        self.spec, self.notes, self.rollouts = spec, notes, rollouts
        self.joint_names = list(spec.joint_names)
        self.pm = build_model(spec, gravity_W)
        self.parameters = true_parameters(self.pm).reshape(-1, 10)
        self.friction = friction.values(spec.frictions)

    def inverse_dynamics(self, q, qd, qdd):
        return rnea(self.pm, q, qd, qdd).tau


def make(robot, gravity_W, parameters) -> Sysid:
    return Sysid(robot, gravity_W, parameters)


