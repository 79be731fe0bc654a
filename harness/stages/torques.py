"""Joint torques of every model under test against the reference engines, on the recorded motion.

References: MuJoCo's torques (what drove the simulation) and Pinocchio's RNEA on a model built
from the same robot description. Each model under test (harness/base/plugins.py) gets the recorded
(q, q', q'') and returns its torques; the three are compared pairwise with one definition of
relative error (harness/stages/metrics.py). Its joint wrenches and mass matrix are compared too when
the model offers them.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from harness.base.numerics import RANGE_FLOOR, evenly_spaced, floats, range_scale, relative_error
from harness.base.plugins import PluginError, Stage, call, check_array, column_maps, inverse_dynamics, invoke
from harness.base.plugins import actuated_torques as plugin_actuated_torques
from harness.engines.pinocchio import build_model, crba, rnea
from harness.model.floating import BaseMotion
from harness.model.states import motion_scale, position_bounds, random_states
from harness.stages.metrics import DEFINITION, joint_load_scale, pair_metrics, wrench_metrics
from harness.stages.moving_base import floating_figures, free_rows, moved, standing_contacts

CLOSED_CHAIN_WRENCH_FLOOR = 1e-4  # round-off of a sum of wrenches ~1e-15 of the largest: 1e-11 of this floor
MASS_MATRIX_SAMPLES = 20  # configurations of the recording at which a model's M(q) is compared


@dataclass(frozen=True, eq=False)
class ModelTorques:
    name: str
    reference: str  # how the scenario named it
    model_file: str  # the robot description it was built from
    tau: np.ndarray  # (N, n) robot joint order
    F_W: np.ndarray | None  # (N, n, 3) joint forces, when the model gives them
    M_W: np.ndarray | None
    mass_matrix_rel_error: float | None  # largest |M - M_pin| / max |M_pin|, when given
    mass_matrix_worst: tuple[int, int, int] | None = None  # (comparison row, i, j) of that largest entry
    random_tau: np.ndarray | None = None  # (count, n) at the random states, robot joint order
    base_W: np.ndarray | None = None  # (N, 6) with the base moving: its world's wrench on the base [F_W, M_W]


@dataclass(frozen=True, eq=False)
class RandomStates:
    """Pinocchio's RNEA at random states (harness/model/states.py), what every model is also judged at."""

    q: np.ndarray  # (count, n) robot joint order
    qd: np.ndarray
    qdd: np.ndarray
    tau: np.ndarray  # Pinocchio's
    load_scale: np.ndarray  # (n,) the largest moment (revolute) or force (prismatic) each joint transmits
    seed: int


@dataclass(frozen=True, eq=False)
class TorqueComparison:
    joints: list[str]
    t: np.ndarray
    load_scale: np.ndarray  # L_J, from the recording
    mujoco: np.ndarray  # (N, n)
    pinocchio: np.ndarray
    F_pin: np.ndarray  # (N, n, 3) Pinocchio's joint wrenches, world components
    M_pin: np.ndarray
    F_rec: np.ndarray  # recorded joint wrenches
    M_rec: np.ndarray
    models: tuple[ModelTorques, ...]
    random: RandomStates | None = None  # when there is a model under test
    wrench_joints: list[str] | None = None  # the joints of F_pin .. M_rec where they are not `joints` (a closed chain)
    closed_chain: dict | None = None  # a closed chain's projection, its loops and their figures
    floating: dict | None = None  # a floating base's figures with the base free (`_floating`)

    def sources(self) -> dict[str, np.ndarray]:
        return {"mujoco": self.mujoco, "pinocchio": self.pinocchio, **{m.name: m.tau for m in self.models}}

    def serialise(self, ctx, config) -> dict:
        """results.json's `torques`: every source against the reference engines, the joint wrenches, the
        mass matrices and the random states."""
        sources, joints, t = self.sources(), self.joints, self.t
        pairs = [(m.name, ref) for m in self.models for ref in ("pinocchio", "mujoco")] + [("pinocchio", "mujoco")]
        wj = self.wrench_joints or joints
        fl = CLOSED_CHAIN_WRENCH_FLOOR if self.closed_chain is not None else 0.0
        reactions = {"pinocchio_vs_mujoco": {"force": wrench_metrics(self.F_pin, self.F_rec, t, wj, fl),
                                             "moment": wrench_metrics(self.M_pin, self.M_rec, t, wj, fl)}}
        for m in self.models:
            if m.F_W is not None:
                reactions[f"{m.name}_vs_mujoco"] = {"force": wrench_metrics(m.F_W, self.F_rec, t, wj, fl),
                                                    "moment": wrench_metrics(m.M_W, self.M_rec, t, wj, fl)}
        return {
            "joints": joints,
            **({"closed_chain": self.closed_chain} if self.closed_chain is not None else {}),
            **({"floating": self.floating} if self.floating is not None else {}),
            "definition": DEFINITION,
            "load_scale": dict(zip(joints, floats(self.load_scale), strict=True)),
            "models": {m.name: {"plugin": m.reference, "model_file": m.model_file,
                                "joint_wrenches": m.F_W is not None,
                                "mass_matrix": m.mass_matrix_rel_error is not None} for m in self.models},
            "parameter_differences": {e.name: parameter_differences(e.robot, ctx.scenario.robot)
                                      for e in ctx.scenario.models if e.robot is not ctx.scenario.robot},
            "samples": [{"t": float(ti), **{k: floats(v[i]) for k, v in sources.items()}} for i, ti in enumerate(t)],
            **{f"{a}_vs_{b}": pair_metrics(sources[a], sources[b], self.load_scale, t, joints) for a, b in pairs},
            "reactions": {
                "definition": "|a - b| / largest |b| of the joint over the run, b the recorded wrench "
                              "(force of the inner on the outer body, moment about the joint point)"
                              + (f"; of a closed chain, at least {CLOSED_CHAIN_WRENCH_FLOOR:g} of the largest any "
                                 "joint carries (a passive hinge of a planar loop carries no moment)"
                                 if self.closed_chain is not None else ""),
                **reactions,
            },
            **{f"{m.name}_random_vs_pinocchio": _random_metrics(m.random_tau, self.random, joints, self.wrench_joints)
               for m in self.models},
            "mass_matrix": {
                "definition": f"largest |M - M_pinocchio| / largest |M_pinocchio| at {MASS_MATRIX_SAMPLES} rows "
                              "of the recording (Pinocchio's CRBA)",
                **{f"{m.name}_vs_pinocchio": {"max_rel_error": m.mass_matrix_rel_error,
                                              "max_rel_entry": f"M[{joints[m.mass_matrix_worst[1]]}, "
                                                               f"{joints[m.mass_matrix_worst[2]]}]",
                                              "max_rel_t": float(t[m.mass_matrix_worst[0]])}
                   for m in self.models if m.mass_matrix_rel_error is not None},
            },
        }


def _model_torques(entry, q, qd, qdd, joints: list[str], M_pin_at, rows, base=None, on_feet=None) -> ModelTorques:
    """One model under test on the recorded motion, in its own column order, brought to the robot's; with
    the base moving (`base`), its joint rows with the base free (`free_rows`) less what the contacts exert
    on them (`on_feet`'s joint rows, where it stands), its joint wrenches not asked."""
    inst, plugin = entry.instance, entry.reference
    to_model, order = column_maps(inst.joint_names, joints)
    N, n = q.shape
    base_W = None
    if base is None:
        tau = inverse_dynamics(plugin, "inverse_dynamics", inst, joints, q, qd, qdd)
    else:
        free = free_rows(entry, base, q, qd, qdd, joints)
        base_W, tau = free[:, :6], free[:, 6:] - (0.0 if on_feet is None else on_feet[:, 6:])
    F = M = None
    if base is None and callable(getattr(inst, "joint_wrenches", None)):
        out = invoke(plugin, "joint_wrenches", inst.joint_wrenches, q[:, to_model], qd[:, to_model],
                     qdd[:, to_model])
        if not isinstance(out, tuple | list) or len(out) != 2:
            raise PluginError(plugin, "joint_wrenches must return (F_W, M_W)")
        F = check_array(plugin, "joint_wrenches (forces)", out[0], (N, n, 3))[:, order]
        M = check_array(plugin, "joint_wrenches (moments)", out[1], (N, n, 3))[:, order]
    mm = None
    if callable(getattr(inst, "mass_matrix", None)):
        Mq = call(plugin, "mass_matrix", inst.mass_matrix, q[rows][:, to_model], shape=(len(rows), n, n))
        Mq = Mq[:, order][:, :, order]
        ref = M_pin_at()
        diff = np.abs(Mq - ref)
        worst = np.unravel_index(np.argmax(diff), diff.shape)
        mm = float(diff[worst] / np.max(np.abs(ref)))
        return ModelTorques(entry.name, plugin, str(entry.robot.source), tau, F, M, mm,
                            (int(rows[worst[0]]), int(worst[1]), int(worst[2])), base_W=base_W)
    return ModelTorques(entry.name, plugin, str(entry.robot.source), tau, F, M, mm, base_W=base_W)


MAX_RANDOM_STATES = 100_000


@dataclass(frozen=True)
class RandomStatesConfig:
    """`[random_states]`: every model under test is also judged against Pinocchio at `count` random
    states (harness/model/states.py: q within the joint limits, q' and q'' within the largest of each
    joint over the scenario's motion), drawn with `seed`."""

    count: int = 200
    seed: int = 0


def configure(t, scenario) -> RandomStatesConfig:
    """`[random_states] count = 200, seed = 0`, validated (one-line errors naming the key)."""
    config = RandomStatesConfig(t.integer("count", default=RandomStatesConfig.count, minimum=1),
                                t.integer("seed", default=RandomStatesConfig.seed, minimum=0))
    if config.count > MAX_RANDOM_STATES:
        raise t.error("count", f"{config.count} states: at most {MAX_RANDOM_STATES:,}")
    return config


def _random_states(sc, pm, config: RandomStatesConfig) -> RandomStates:
    """Pinocchio at the scenario's random states: q within the limits, q' and q'' within the largest
    of each joint along the scenario's own motion."""
    _, qd_run, qdd_run = sc.prescribed(sc.t_out)
    lo, hi = position_bounds(sc.robot.joint_names, [j.revolute for j in sc.robot.joints], sc.robot.limits)
    q, qd, qdd = random_states(lo, hi, motion_scale(qd_run), motion_scale(qdd_run), config.count, config.seed)
    pin = rnea(pm, q, qd, qdd)
    wrench = np.stack([(pin.M_W if j.revolute else pin.F_W)[:, k] for k, j in enumerate(sc.robot.joints)], axis=1)
    return RandomStates(q, qd, qdd, pin.tau, np.max(np.linalg.norm(wrench, axis=-1), axis=0), config.seed)


def run(ctx, config: RandomStatesConfig | None) -> TorqueComparison:
    if ctx.scenario.robot.loops:
        return _closed_chain(ctx, config or RandomStatesConfig())
    sc, rec = ctx.scenario, ctx.truth
    joints = sc.robot.joint_names
    cols = [rec.joint_index(j) for j in joints]
    q, qd, qdd = rec.q[:, cols], rec.qd[:, cols], rec.qdd[:, cols]
    pm = build_model(sc.robot, sc.gravity_W)
    base = None if rec.base_pose is None else BaseMotion.from_rows(rec.base_pose, rec.base_twist_W, rec.base_rate_W)
    feet, on_feet = standing_contacts(sc, rec, base, q)
    pin = (rnea(pm, q, qd, qdd) if base is None
           else rnea(build_model(sc.robot, sc.gravity_W, floating=True), q, qd, qdd, feet, base=base))
    rows = evenly_spaced(len(rec.t), MASS_MATRIX_SAMPLES)

    def M_pin_at():  # Pinocchio's CRBA, computed once, only if a model offers a mass matrix
        return ctx.once("mass matrix (CRBA) at the comparison rows", lambda: crba(pm, q[rows]))

    models = tuple(_model_torques(e, q, qd, qdd, joints, M_pin_at, rows, base, on_feet) for e in sc.models)
    random = None
    if models:
        random = _random_states(sc, pm, config or RandomStatesConfig())
        models = tuple(dataclasses.replace(
            m, random_tau=inverse_dynamics(e.reference, "inverse_dynamics (random states)", e.instance, joints,
                                           random.q, random.qd, random.qdd))
            for m, e in zip(models, sc.models, strict=True))
    floating = floating_figures(sc, rec.t[rows], q[rows], qd[rows], qdd[rows], (config or RandomStatesConfig()).seed,
                         None if base is None else base.take(rows))
    if base is not None:
        floating = {**floating, **moved(sc, rec, base, pin.base, models, on_feet)}
    return TorqueComparison(joints, rec.t, joint_load_scale(sc.robot, rec), rec.tau[:, cols], pin.tau,
                            pin.F_W, pin.M_W, rec.F_W[:, cols], rec.M_W[:, cols], models, random, floating=floating)


PROJECTION = ("tau_a = G^T tau: the tree's joint torques tau (the open tree's inverse dynamics at every joint's "
              "q, q', q'') projected onto the actuated joints by G, q' = G q'_a (the loops solved for the passive "
              "joints: harness/model/closure.py). The engines' own torques at the actuated joints are the tree's, "
              "not the chain's: with the loop closed, part of what the motors give travels through the loop")


def _closed_chain(ctx, config: RandomStatesConfig) -> TorqueComparison:
    """A closed chain's actuated torques: MuJoCo's are what drove the simulation (its drive projects the
    computed torque through the loops: harness/engines/mujoco.py); Pinocchio's are G^T rnea at the recorded
    states; each model under test answers for the actuated joints. The loops' forces lambda, from
    J^T lambda = tau - S^T tau_a, are applied to Pinocchio's bodies for its joint wrenches (compared with
    MuJoCo's force sensors) and leave its passive joints' torques at zero; at random states, q_a, q'_a and
    q''_a are drawn and the passive joints follow from the loops."""
    from harness.engines.pinocchio import PointForce
    from harness.model.closure import (
        ClosedChain,
        actuated_torques,
        loop_wrenches,
        multipliers,
        projection,
        random_motion,
    )
    from harness.model.loops import bias, jacobian

    sc, rec = ctx.scenario, ctx.truth
    robot = sc.robot
    joints, actuated = robot.joint_names, list(robot.actuated)
    chain = ClosedChain.of(robot)
    cols = [rec.joint_index(j) for j in joints]
    q, qd, qdd = rec.q[:, cols], rec.qd[:, cols], rec.qdd[:, cols]
    pm = build_model(robot, sc.gravity_W)
    tree = rnea(pm, q, qd, qdd).tau
    J = jacobian(robot, chain.loops, q)
    G = projection(chain, q, J, where="recorded row", closed=False)
    tau_a = actuated_torques(G, tree)
    lam = multipliers(chain, J, tree, tau_a)
    forces = tuple(PointForce(joints.index(robot.inner_joint(b).name), x, f, m)
                   for b, x, f, m in loop_wrenches(chain, q, lam))
    pin = rnea(pm, q, qd, qdd, forces)
    # the joint reactions under the loop wrenches MuJoCo applied: where a loop over-constrains (a planar
    # loop's out-of-plane force), the rigid model leaves the loop force open and MuJoCo's soft constraint
    # chooses it; the loops' generalised force J^T lambda, what moves the robot, is compared on its own
    mj_forces = tuple(PointForce(joints.index(robot.inner_joint(b).name), rec.p_W[:, k], rec.loop_F_W[:, k],
                                 rec.loop_M_W[:, k]) for k, b in enumerate(rec.bodies))
    pin_mj = rnea(pm, q, qd, qdd, mj_forces)
    # a coupling's lambda acts within its two joints, on no body from outside (closure.loop_wrenches): J^T lambda
    coupled = np.concatenate([np.full(lp.rows, not lp.joins_points) for lp in chain.loops])
    within = np.einsum("nrj,nr->nj", J[:, coupled], lam[:, coupled])
    ours = tree - pin.tau + within
    # MuJoCo's own generalised constraint force where recorded; else through its loop wrenches on the bodies
    theirs = rec.loop_tau[:, [rec.joint_index(j) for j in joints]] if rec.loop_tau is not None else tree - pin_mj.tau
    generalised = float(np.max(np.abs(ours - theirs)) / np.max(np.abs(ours))) if np.any(ours) else 0.0
    a_cols = [joints.index(a) for a in actuated]
    passive = [j for j in joints if j not in actuated]
    p_cols = [joints.index(p) for p in passive]
    load = joint_load_scale(robot, rec)
    models = []
    for e in sc.models:
        tau_m = plugin_actuated_torques(e.reference, "inverse_dynamics", e.instance, joints, actuated, q, qd, qdd)
        models.append(ModelTorques(e.name, e.reference, str(e.robot.source), tau_m, None, None, None))
    random = None
    if models:
        _, qd_run, qdd_run = sc.prescribed(sc.t_out)
        lo, hi = position_bounds(actuated, [robot.joint(a).revolute for a in actuated], robot.limits)
        m = random_motion(chain, lo, hi, motion_scale(qd_run[:, a_cols]), motion_scale(qdd_run[:, a_cols]),
                          config.count, config.seed)
        r_tree = rnea(pm, m.q, m.qd, m.qdd)
        r_tau = actuated_torques(m.G, r_tree.tau)
        wrench = np.stack([(r_tree.M_W if robot.joint(a).revolute else r_tree.F_W)[:, joints.index(a)]
                           for a in actuated], axis=1)
        random = RandomStates(m.q, m.qd, m.qdd, r_tau, np.max(np.linalg.norm(wrench, axis=-1), axis=0), config.seed)
        models = [dataclasses.replace(mt, random_tau=plugin_actuated_torques(
                      e.reference, "inverse_dynamics (random states)", e.instance, joints, actuated, m.q, m.qd, m.qdd))
                  for mt, e in zip(models, sc.models, strict=True)]
    raw = relative_error(tree[:, a_cols], tau_a, load[a_cols])
    Jqdd = (J @ qdd[:, :, None])[:, :, 0]
    residual = np.abs(Jqdd + bias(robot, chain.loops, q, qd))
    reach = float(np.max(np.linalg.norm(J, axis=(1, 2)) * np.linalg.norm(qdd, axis=1)))
    gap = rec.loop_gap if rec.loop_gap is not None else np.zeros((len(rec.t), len(chain.loops)))
    info = {
        "actuated": actuated, "passive": passive,
        "mujoco_vs_rigid_loops": _against_rigid_loops(pm, robot, rec),
        "forward": _forward_of_models(ctx, pm, chain, rec),
        "loops": {lp.name: _loop_info(lp) for lp in chain.loops},
        "projection": PROJECTION,
        "raw_tree_vs_actuated_max_rel_error": float(np.max(raw)),
        "passive_torque_with_loop_forces_max": float(np.max(np.abs((pin.tau - within)[:, p_cols]))) if p_cols else 0.0,
        "loop_forces_vs_mujoco_max_rel_error": generalised,
        "loop_forces_definition": "the loops' generalised force J^T lambda (lambda from J^T lambda = tau - S^T "
                                  "tau_a, Pinocchio's tree torques; the point loops' forces applied to the bodies "
                                  "through Pinocchio's RNEA, a coupling's torque pair on its joints) against "
                                  "MuJoCo's generalised constraint force (qfrc_constraint): largest |difference| / "
                                  "largest |J^T lambda|",
        "loop_gap_max": float(np.max(gap)) if gap.size else 0.0,
        "loop_acceleration_residual_max_rel": float(residual.max() / reach) if reach > 0 else 0.0,
        "loop_acceleration_residual_definition": "largest |J q'' + b| over the recorded rows / largest |J| |q''| "
                                                 "(Frobenius and Euclidean norms): how far the recorded "
                                                 "accelerations are from the rigid loop's (MuJoCo's reference "
                                                 "acceleration, which pulls the soft loop closed)",
        "loop_gap_per_loop": {lp.name: float(np.max(gap[:, k])) for k, lp in enumerate(chain.loops)},
        "loop_settings": rec.meta.get("loop_settings"),
    }
    return TorqueComparison(actuated, rec.t, load[a_cols], rec.tau[:, [rec.joint_index(a) for a in actuated]], tau_a,
                            pin_mj.F_W, pin_mj.M_W, rec.F_W[:, cols], rec.M_W[:, cols], tuple(models), random,
                            wrench_joints=joints, closed_chain=info)


def _loop_info(loop) -> dict:
    """A loop as results.json states it: its type and the two bodies it joins, or a coupling's joints."""
    if loop.joins_points:
        return {"type": loop.kind, "body1": loop.body_a, "body2": loop.body_b}
    return {"type": loop.kind, "follower": loop.follower, "leader": loop.leader, "ratio": loop.ratio,
            "offset": loop.offset}


def _rk4_stages(rec) -> np.ndarray | None:
    """The torques the bench's drive gave at each of its RK4 steps' four stages, (steps, 4, n); None where
    it integrated otherwise (its recording keeps one torque per step)."""
    return None if rec.drive is None else rec.drive.rk4_stages()


def _against_rigid_loops(pm, robot, rec) -> dict | None:
    """The bench's simulation against rigid loops: Pinocchio's constraintDynamics integrated by RK4 at
    the bench's step under the torques MuJoCo was given at every stage (harness/engines/pinocchio.py,
    constrained_rollout), from the recording's first state; per joint the largest |q - q_MuJoCo| over
    the run relative to the joint's range of motion. None where the bench did not integrate by RK4."""
    from harness.engines.pinocchio import NotSimulated, constrained_rollout

    stages = _rk4_stages(rec)
    if stages is None:
        return None
    cols = [rec.joint_index(j) for j in robot.joint_names]
    q_rec = rec.q[:, cols]
    try:
        q, _ = constrained_rollout(pm, robot, q_rec[0], rec.qd[0, cols], stages, rec.drive.timestep,
                                   rec.drive.substeps)
    except NotSimulated as exc:  # friction that depends on the load
        return {"skipped": str(exc)}
    rel = relative_error(q, q_rec[: len(q)], range_scale(q_rec, [j.revolute for j in robot.joints])).max(axis=0)
    return {"max_rel_range": float(rel.max()), "max_rel_joint": robot.joint_names[int(np.argmax(rel))],
            "per_joint": dict(zip(robot.joint_names, floats(rel), strict=True)),
            "definition": "Pinocchio's rigid-loop forward dynamics (constraintDynamics, RK4 at the bench's step, "
                          "under the torques MuJoCo was given at every stage, from the recording's first state) "
                          "against the recording: largest |q - q_MuJoCo| / the joint's range of motion over the run "
                          f"(at least {RANGE_FLOOR:g} of its kind's largest and {RANGE_FLOOR:g} rad or m); "
                          "what MuJoCo's soft loops make of the motion"}


FORWARD_STEP = 1e-3  # s: the longest RK4 step of a closed chain's model's forward simulation: two RK4 schemes (in
# the actuated joints and in all) differ by their truncation errors, 3e-10 of the range on the built-in four-bar
# at 1 ms over SEGMENT (4.8e-9 at 2 ms, 7.7e-8 at 4 ms: as the step's fourth power), the gate being 1e-6
SEGMENT = 0.1  # s: each of the model's rollouts (below)


def coarser(stages: np.ndarray, m: int) -> np.ndarray:
    """A bench's RK4 stage torques (steps, 4, n) read at a step m times as long (m even, or 1): each long
    step's start, middle (twice) and end are a bench step's start (the drive's torque at that state) and
    the last bench step's end stage, (steps // m, 4, n)."""
    if m == 1:
        return stages
    k = np.arange(len(stages) // m) * m
    return np.stack([stages[k, 0], stages[k + m // 2, 0], stages[k + m // 2, 0], stages[k + m - 1, 3]], axis=1)


def _forward_of_models(ctx, pm, chain, rec) -> dict | None:
    """Each closed-chain model under test forward-simulated (harness/model/chain_forward.py: its actuated
    mass matrix and bias read off its own inverse dynamics, RK4 in the actuated coordinates, the loops
    closed at every stage) against Pinocchio's rigid loops (constraintDynamics, RK4) under the torques
    MuJoCo was given, both at the longest step within FORWARD_STEP that is an even multiple of the
    bench's (or the bench's). Pinocchio's run goes from the recording's first state (its loops closed)
    to the end; the model's runs go from its states every SEGMENT s, all at once, each over SEGMENT s
    (an open-loop run of a chain under gravity carries any difference on, growing: the built-in
    four-bar's grows about 5,000-fold over 1.5 s). Per joint the largest |q_model - q_Pinocchio| relative
    to the joint's range of motion over the run. None where no model is under test; where the bench did
    not integrate by RK4 (no stage torques to read) or the rigid loops cannot carry the robot's friction
    (a law that depends on the load), each model's entry says why (`skipped`: its gates are neither
    passed nor failed)."""
    from harness.engines.pinocchio import NotSimulated, constrained_rollout
    from harness.model import chain_forward
    from harness.model.closure import ClosureError, close, projection

    sc, robot = ctx.scenario, chain.spec
    if not sc.models:
        return None
    stages = _rk4_stages(rec)
    if stages is None:
        integrator = rec.drive.integrator if rec.drive is not None else "(not recorded)"
        why = (f"the bench integrated by {integrator}, not RK4: the torques at an RK4 step's "
               "stages, which the comparison drives both runs with, were not recorded")
        return {e.name: {"skipped": why} for e in sc.models}
    m = max(1, int(FORWARD_STEP / rec.drive.timestep + 1e-9) // 2 * 2)
    h, taus = m * rec.drive.timestep, coarser(stages, m)
    joints, actuated = robot.joint_names, list(robot.actuated)
    a_cols = [joints.index(a) for a in actuated]
    q0 = close(chain, rec.q[0, [rec.joint_index(j) for j in joints]], "the recording's first row", numbered=False)
    qd0 = projection(chain, q0)[0] @ rec.qd[0, [rec.joint_index(a) for a in actuated]]
    try:
        q_ref, v_ref = constrained_rollout(pm, robot, q0[0], qd0, taus, h, 1)
    except NotSimulated as exc:  # friction that depends on the load
        return {e.name: {"skipped": str(exc)} for e in sc.models}
    scale = range_scale(q_ref, [j.revolute for j in robot.joints])
    s = max(1, min(round(SEGMENT / h), len(taus)))
    starts = np.arange(0, len(taus) - s + 1, s)
    out = {"step_s": h, "segment_s": s * h, "segments": len(starts), "definition": (
        "the model's forward dynamics (its actuated mass matrix and bias read off its own inverse dynamics, "
        "RK4 in the actuated joints, the passive ones closing the loops at every stage) against Pinocchio's "
        f"rigid loops (constraintDynamics, RK4), both at a {h * 1e3:g} ms step under the torques MuJoCo was "
        f"given; the model from Pinocchio's state every {s * h:g} s over {s * h:g} s: largest |q_model - "
        f"q_Pinocchio| / the joint's range of motion over the run (at least {RANGE_FLOOR:g} of its kind's largest "
        f"and {RANGE_FLOOR:g} rad or m)")}
    window = starts[:, None] + np.arange(s + 1)
    for e in sc.models:
        def inverse(q, qd, qdd, e=e):
            return plugin_actuated_torques(e.reference, "inverse_dynamics (forward simulation)", e.instance, joints,
                                           actuated, q, qd, qdd)
        try:
            q = chain_forward.rollout(chain, inverse, q_ref[starts], v_ref[starts][:, a_cols],
                                      taus[window[:, :-1]][..., a_cols], h)
        except (chain_forward.ChainForwardError, ClosureError) as exc:
            out[e.name] = {"failed": str(exc)}
            continue
        rel = relative_error(q, q_ref[window], scale)
        b, k, j = np.unravel_index(int(np.argmax(rel)), rel.shape)
        out[e.name] = {"max_rel_range": float(rel[b, k, j]), "max_rel_range_joint": joints[j],
                       "max_rel_range_t": float(rec.t[0] + window[b, k] * h),
                       "per_joint": dict(zip(joints, floats(rel.max(axis=(0, 1))), strict=True))}
    return out


DIFFERENCE_TOL = 1e-12  # relative: parameters that differ by less are the same number written twice


def parameter_differences(model, robot) -> list[dict]:
    """Mass, centre of mass and principal moments of every body where a model's description
    differs from the robot's. `identification_name` is the name identification stages give it."""
    out = []
    for b_ref in robot.bodies:
        b = model.body(b_ref.name)
        values = [("mass", "m", b.mass, b_ref.mass)]
        values += [(f"J{k + 1}{k + 1}", f"J{k + 1}{k + 1}", b.principal_inertia[k], b_ref.principal_inertia[k])
                   for k in range(3)]
        values += [(f"com_{a}", f"com_{a}", b.p_W_com0[k], b_ref.p_W_com0[k]) for k, a in enumerate("xyz")]
        for label, ident, v, ref in values:
            size = max(abs(v), abs(ref))
            if size > 0 and abs(v - ref) > DIFFERENCE_TOL * size:
                out.append({"body": b.name, "parameter": label, "identification_name": ident, "model": float(v),
                            "reference": float(ref), "rel_difference": float((v - ref) / ref) if ref else None})
    return out


def _random_metrics(tau: np.ndarray, rs: RandomStates, joints: list[str],
                    state_joints: list[str] | None = None) -> dict:
    """`joints` the columns of the torques, `state_joints` those of the states (every joint of a closed
    chain, whose torques are its actuated joints')."""
    rel = relative_error(tau, rs.tau, rs.load_scale)
    sj = state_joints or joints
    k, j = np.unravel_index(np.argmax(rel), rel.shape)
    return {
        "max_rel_error": float(rel[k, j]), "max_rel_joint": joints[j], "max_rel_state": int(k),
        "max_rel_error_per_joint": dict(zip(joints, (float(x) for x in rel.max(axis=0)), strict=True)),
        "worst_state": {"q": dict(zip(sj, floats(rs.q[k]), strict=True)),
                        "qd": dict(zip(sj, floats(rs.qd[k]), strict=True)),
                        "qdd": dict(zip(sj, floats(rs.qdd[k]), strict=True))},
        "states": len(rs.q), "seed": rs.seed,
        "definition": "|tau - tau_pinocchio| / L_J at random states: q uniform within the joint limits (+-pi rad or "
                      "+-1 m without), q' and q'' uniform within the largest of each joint along the scenario's "
                      "motion; L_J the largest moment (revolute) or force (prismatic) joint J transmits at them "
                      "(Pinocchio's RNEA)",
    }


STAGE = Stage("torques", "joint torques: reference engines and models under test", run,
              TorqueComparison.serialise, "Torques", table="random_states", configure=configure)
