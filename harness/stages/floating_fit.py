"""`[torque_identification]` where the bench moves a floating base (a scenario's `[base_motion]`): the
floating-base identification (harness/identify/floating_id.py) from the world's wrench on the base alone
(`rows = "base"`: no joint torque read) or with the joints' torques (`"all"`), judged on the validation
scenario's motion (its own `[base_motion]`). Not a stage: the joint-torque identification stage
(harness/stages/identification.py) calls it."""

from __future__ import annotations

import numpy as np

from harness.engines.pinocchio import build_model
from harness.identify import consistent as sdp
from harness.identify import floating_id
from harness.identify.torque_id import COEFFICIENT_FLOOR, TorqueIdentification
from harness.identify.torque_id import structural_base as fixed_structural_base
from harness.model.floating import BaseMotion
from harness.stages.metrics import joint_load_scale


def whole_rows(robot, contacts: tuple, rec) -> tuple:
    """(base, q, q', q'', the world's whole wrench on the base, the joints' rows) of a recording or a log of a
    moving base: with contacts (each with its `body`), their generalised force (harness/model/contacts.py)
    added to what the world applied to the base besides them (none in a log) and to the motors' torques, so
    that the rows are the robot's M q'' + h."""
    q, qd, qdd, tau = rec.joint_data(robot.joint_names)
    base = BaseMotion.from_rows(rec.base_pose, rec.base_twist_W, rec.base_rate_W)
    wrench = rec.base_wrench_W if rec.base_wrench_W is not None else np.zeros((len(q), 6))
    if rec.contacts:
        from harness.model.contacts import generalised_force

        feet = generalised_force(robot, contacts, base, q, rec.contact_F_W, rec.contact_M_W, rec.contact_x_W)
        wrench, tau = wrench + feet[:, :6], tau + feet[:, 6:]
    return base, q, qd, qdd, wrench, tau


def _whole(sc, rec) -> tuple:
    """`whole_rows` of a scenario's recording."""
    return whole_rows(sc.robot, sc.contacts, rec)


def _data(sc, rec, rows: str) -> tuple:
    """(base, q, q', q'', measured rows) of a recording of a moving base (`_whole`)."""
    base, q, qd, qdd, wrench, tau = _whole(sc, rec)
    return base, q, qd, qdd, floating_id.measured(wrench, tau, rows)


def _scale(sc, rec, rows: str) -> np.ndarray:
    """Each measured row's scale: the largest |F_W| (force rows) and |M_W| (moment rows) of the world's
    whole wrench on the base over the recording, then each joint's load L_J."""
    wrench = _whole(sc, rec)[4]
    F, M = (float(np.max(np.linalg.norm(wrench[:, s], axis=1))) for s in (slice(0, 3), slice(3, 6)))
    wrench = np.array([F, F, F, M, M, M])
    return wrench if rows == "base" else np.concatenate([wrench, joint_load_scale(sc.robot, rec)])


def identify(ctx, config) -> tuple[TorqueIdentification, dict, dict[str, str]]:
    """The fit (as the fixed base's TorqueIdentification, its rows named), what the results add of a
    floating base (which rows it read, its base parameters against the same robot's bolted down, the
    consistent fit where asked) and the files of the consistent fit's export ({path: text}, else none)."""
    sc, rows = ctx.scenario, config.rows
    joints = sc.robot.joint_names
    pm = build_model(sc.robot, sc.gravity_W, floating=True)
    structure = ctx.once(("floating-base structural base parameters", rows, config.friction),
                         lambda: floating_id.structural_base(pm, sc.robot.limits, rows, with_friction=config.friction))
    val = ctx.recorded(config.validation)
    training, validation = _data(sc, ctx.training, rows), _data(config.validation, val, rows)
    fit, beta_true, err = floating_id.identify(pm, structure, rows, training, validation)  # the base parameters
    names = floating_id.parameter_names(sc.robot, pm, config.friction)
    ti = TorqueIdentification(names, structure, beta_true, fit.beta, fit.condition_number, fit.std,
                              fit.ci_half_width, fit.sensitivity, fit.weak, err, _scale(config.validation, val, rows),
                              list(floating_id.BASE_ROWS) + ([] if rows == "base" else joints))
    fixed = fixed_structural_base(build_model(sc.robot, sc.gravity_W), sc.robot.limits, with_friction=config.friction)
    holding, unseen = seen(structure, names, sc.robot)
    extra = {"rows": rows, "fixed_base_parameters": len(fixed.independent), "base_body_in": holding,
             "unseen": unseen, "unseen_definition": UNSEEN,
             "method": _method(rows, len(fixed.independent), holding, bool(ctx.training.contacts))}
    files = {}
    if config.consistent:
        extra["consistent"], files = _consistent(ctx, config, pm, training, validation, ti.validation_scale)
    return ti, extra, files


UNSEEN = "the parameters these rows cannot see: in no base parameter"


def seen(structure, names: list[str], robot) -> tuple[int, list[str]]:
    """How many of the base parameters `structure` hold the floating base body's own parameters, and the
    parameters (`names`) in none of them: what the rows cannot see."""
    own = [name.startswith(f"{robot.floating.body.name}.") for name in names]  # the base body's parameters
    holding = sum(own[structure.independent[k]] or any(own[j] for j, c in zip(structure.dependent, row, strict=True)
                                                       if abs(c) > COEFFICIENT_FLOOR)
                  for k, row in enumerate(structure.combination))
    held = np.any(np.abs(structure.combination) > COEFFICIENT_FLOOR, axis=0)  # each dependent in some base parameter
    return int(holding), [names[j] for j, h in zip(structure.dependent, held, strict=True) if not h]


def _method(rows: str, fixed: int, holding: int, standing: bool = False) -> str:
    wrench = "the contacts' wrenches (the world's whole wrench on the base)" if standing else \
        "the world's wrench on the base"
    read = f"{wrench} alone (no joint torque)" if rows == "base" else f"{wrench} and the joints' torques"
    return ("floating base: Pinocchio's joint torque regressor of the robot on its free-flyer, the base's six rows "
            f"turned to world axes (harness/identify/floating_id.py), read on {read}; base parameters by QR with "
            "column pivoting at random states, the base's pose uniform on SO(3); least squares. The same robot "
            f"bolted down has {fixed}; {holding} of these hold the base body's own parameters")


def _consistent(ctx, config, pm, training: tuple, validation: tuple, scale: np.ndarray) -> tuple[dict, dict]:
    """The physically consistent fit on the same rows (harness/identify/floating_id.py, consistent), judged on
    the validation motion as the least squares is, and exported: an MJCF file of the robot on its free joint
    with the identified bodies, the base's included, and drives (identified/robot.xml), and where the robot
    comes from a URDF, that URDF with the identified inertials and a floating joint (identified/robot.urdf)."""
    import dataclasses

    from harness.model.export import MJCF_FILE, URDF_FILE, identified_floating_spec, write_urdf
    from harness.model.mjcf import write_mjcf

    rows, sc = config.rows, ctx.scenario
    physical, links = floating_id.consistent(pm, sc.robot, rows, training, config.friction)
    predicted = floating_id.consistent_rows(pm, physical, rows, validation, config.friction)
    err_c = np.abs(predicted - validation[-1]) / scale
    model = floating_id.link_parameters(pm)  # the links' parameters in the model, in the fit's order
    consistent = {"method": "every body's pseudo-inertia positive definite, the base's included, what the data cannot "
                            "see pulled to the model's values (harness/identify/consistent.py) on the same rows",
                  "status": physical.status, "solver": physical.solver, "fallback": physical.fallback,
                  "training_relative_residual": physical.relative_residual,
                  "validation": {"max_rel_error": float(err_c.max()),
                                 "rms_rel_error": float(np.sqrt(np.mean(err_c ** 2)))},
                  "inconsistent_links": [b for k, b in enumerate(links)
                                         if not sdp.consistency(physical.theta[k])["consistent"]],
                  "masses": {b: {"identified": float(physical.theta[k, 0]), "model": float(model[k, 0])}
                             for k, b in enumerate(links)},
                  "exported": [f"identified/{MJCF_FILE}"] + ([f"identified/{URDF_FILE}"] if sc.robot.urdf else [])}
    frictions = tuple(dataclasses.replace(f, armature=a, viscous=v, coulomb=c, offset=o) if config.friction else f
                      for f, (a, v, c, o) in zip(sc.robot.frictions, physical.friction[1:], strict=True))
    spec = identified_floating_spec(sc.robot, physical.theta, frictions)
    text = write_mjcf(spec, sc.gravity_W, f"{sc.robot.name}: identified by the harness from a moving floating base's "
                                          f"{'base rows' if rows == 'base' else 'base rows and joint torques'} "
                                          "(its physically consistent fit)", floating=True)
    files = {f"identified/{MJCF_FILE}": text}
    if sc.robot.urdf is not None:  # the robot's own URDF with the identified inertials and a floating joint
        files[f"identified/{URDF_FILE}"] = write_urdf(sc.robot, physical.theta[1:], frictions, physical.theta[0])
    return consistent, files

