"""A floating base's figures in the torques stage (harness/stages/torques.py): the robot judged with its base
free, and, where the bench moved the base (a scenario's [base_motion]) or stood it on contacts ([[contacts]]),
the world's wrench on it and the contacts' figures (docs/floating_base.md)."""

from __future__ import annotations

import numpy as np

from harness.base.plugins import call, column_maps
from harness.model.floating import BaseMotion

FLOATING_DEFINITION = (
    "the robot with its floating base free (harness/engines/floating.py): MuJoCo's free joint against Pinocchio's "
    "free-flyer, both built from the model, at the recording's joint states at the mass-matrix rows, the base "
    "where [base_motion] puts it at those times (else a random state, its orientation uniform on SO(3)), with a "
    "wrench on the base and on the outermost body: the largest difference of the base's six rows and of the "
    "joints' torques over each one's largest |value|, and of the mass matrices over their largest entry. "
    "Without [base_motion] the simulation and every other figure take the base fixed at the file's pose; with it the "
    "bench moves the base and every figure is of the moving robot (moved_definition)")


def floating_figures(sc, t: np.ndarray, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, seed: int,
              recorded: BaseMotion | None = None) -> dict | None:
    """A floating base's figures with the base free (FLOATING_DEFINITION), None without one; the base
    where the recording has it (`recorded`), else where [base_motion] puts it, else at random."""
    if sc.robot.floating is None:
        return None
    from harness.engines.floating import engines_agreement
    from harness.model.floating import random_base_motion

    base = recorded if recorded is not None else (
        sc.base_motion.evaluate(t) if sc.base_motion is not None else random_base_motion(len(q), seed))
    figures = engines_agreement(sc.robot, sc.gravity_W, base, q, qd, qdd, seed)
    return {"base": sc.robot.floating.body.name, "joint": sc.robot.floating.joint, "states": len(q),
            "base_motion": ("recorded (moved by the bench along [base_motion])" if recorded is not None else
                            "[base_motion]" if sc.base_motion is not None else "random"),
            "engines_max_rel_error": figures["engines"], "mass_matrix_max_rel_error": figures["mass_matrix"],
            **floating_models(sc, base, q, qd, qdd), "definition": FLOATING_DEFINITION}


MOVED_DEFINITION = (
    "the bench moved the floating base along [base_motion] (harness/engines/free_base.py): base_tracking_* the "
    "largest distance of the base frame's origin from where [base_motion] puts it (m) and the largest angle between "
    "the two orientations (rad); base_wrench_*_vs_mujoco the largest difference of the world's wrench on the base "
    "(each of its six components over its largest |value| over the run) between the model's inverse dynamics with "
    "the base free at the recorded states and what the bench applied; the joints' torques are compared likewise "
    "(the pairs above), a model's joint rows with the robot's drives' rotor inertia and friction added")


def free_rows(entry, base: BaseMotion, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray,
               joints: list[str]) -> np.ndarray:
    """(N, 6 + n) a model's `floating_inverse_dynamics` (rigid bodies) in the robot's joint order, its joint
    rows with the drives' rotor inertia and friction of the robot (harness/model/drives.py) added."""
    from harness.model import drives

    to_model, back = column_maps(entry.instance.joint_names, joints)
    out = call(entry.reference, "floating_inverse_dynamics", entry.instance.floating_inverse_dynamics, base,
               q[:, to_model], qd[:, to_model], qdd[:, to_model], shape=(len(q), 6 + q.shape[1]))
    tau = out[:, 6:][:, back]
    spec = entry.robot
    return np.concatenate([out[:, :6], tau + drives.torque(spec.frictions, spec.transmission, qd, qdd, tau, q)],
                          axis=1)


def moved(sc, rec, base: BaseMotion, pinocchio_base: np.ndarray, models: tuple,
           on_feet: np.ndarray | None = None) -> dict:
    """A moving base's figures (MOVED_DEFINITION), each model's base rows as `_model_torques` found them; standing
    on contacts (`on_feet`, their generalised force), the world's whole wrench on the base is compared
    (theirs and what the bench applied besides), and its contacts' figures added (`_standing`)."""
    from harness.base.numerics import largest_relative_difference
    from harness.model.floating import tracking_error

    feet = 0.0 if on_feet is None else on_feet[:, :6]
    whole = rec.base_wrench_W + feet
    position, angle = tracking_error(base, sc.base_motion.evaluate(rec.t))
    out = {"base_tracking_position_m": float(np.max(position)), "base_tracking_angle_rad": float(np.max(angle)),
           "base_wrench_pinocchio_vs_mujoco_max_rel_error": largest_relative_difference(pinocchio_base + feet, whole)}
    for m in models:
        out[f"base_wrench_{m.name}_vs_mujoco_max_rel_error"] = largest_relative_difference(m.base_W, whole)
    if on_feet is not None:
        out.update(standing(rec, whole, sc.gravity_W))
    return {**out, "moved_definition": MOVED_DEFINITION}


def standing_contacts(sc, rec, base: BaseMotion | None, q: np.ndarray) -> tuple[tuple, np.ndarray | None]:
    """Standing on contacts: each recorded contact wrench as a force on its body for Pinocchio's RNEA, and their
    generalised force in the harness's rows (harness/model/contacts.py); ((), None) otherwise."""
    if not rec.contacts:
        return (), None
    from harness.engines.pinocchio import PointForce
    from harness.model.contacts import generalised_force

    names = sc.robot.joint_names
    feet = tuple(PointForce(names.index(sc.robot.inner_joint(c.body).name), rec.contact_x_W[:, k],
                            rec.contact_F_W[:, k], rec.contact_M_W[:, k]) for k, c in enumerate(sc.contacts))
    return feet, generalised_force(sc.robot, sc.contacts, base, q, rec.contact_F_W, rec.contact_M_W, rec.contact_x_W)


def standing(rec, whole: np.ndarray, gravity_W: np.ndarray) -> dict:
    """A standing robot's figures (STANDING_DEFINITION)."""
    held = rec.contact_held
    ground = rec.contact_x_W[0]
    slip = np.where(held, np.linalg.norm(rec.contact_x_W - ground, axis=-1), 0.0)
    scale = np.max(np.abs(whole), axis=0)
    up = -np.asarray(gravity_W, dtype=float) / max(float(np.linalg.norm(gravity_W)), 1e-300)
    normal = rec.contact_F_W @ up  # (N, k) the force along the ground's normal (against gravity)
    across = np.linalg.norm(rec.contact_F_W - normal[..., None] * up, axis=-1)
    pushing = held & (normal > 0.0)
    # a sole's centre of pressure from its moment about its point: r = (n x M) / F_n (the pressure's moment r x F_n n)
    cop = np.linalg.norm(np.cross(up, rec.contact_M_W), axis=-1) / np.where(pushing, normal, np.inf)
    return {"contacts": list(rec.contacts), "contacts_held_rows": held.sum(axis=0).tolist(),
            "base_wrench_besides_contacts_max_rel": float(np.max(np.max(np.abs(rec.base_wrench_W), axis=0) / scale)),
            "contact_slip_m": float(np.max(slip)),
            "contact_least_normal_force_N": float(np.min(normal[held])) if held.any() else None,
            "contact_friction_needed": float(np.max(across[pushing] / normal[pushing])) if pushing.any() else None,
            "contact_centre_of_pressure_m": float(np.max(cop[pushing])) if pushing.any() else None,
            "standing_definition": STANDING_DEFINITION}


STANDING_DEFINITION = (
    "the floating base stood on [[contacts]] (harness/model/contacts.py), each a point held on the ground by a stiff "
    "connect constraint while it holds (a sole: its frame, by a weld): the base wrenches above are the world's whole "
    "wrench on the base, the contacts' included (the recorded contact wrenches' and what the bench applied besides "
    "them); the joints' torques are the motors' (a model's joint rows less the contacts' J^T [F; M]); "
    "base_wrench_besides_contacts_max_rel "
    "the largest wrench the world applied to the base besides the contacts, each component over its largest "
    "whole value; contact_slip_m the largest distance of a held contact's point from where it stood at t = 0; "
    "contact_least_normal_force_N the least force a held contact pressed on the ground with, along the ground's "
    "normal (against gravity: negative where the motion had a foot pull, which a real foot cannot), and "
    "contact_friction_needed the largest ratio of its force across the normal to its force along it (the "
    "friction coefficient the motion needs not to slip); contact_centre_of_pressure_m the largest distance from a "
    "pressing contact's point to its centre of pressure, |n x M| / F_n (n the normal, M its moment about the point: "
    "a point's is zero; a sole stands only while it lies within the sole)")


def floating_models(sc, base, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> dict[str, float]:
    """Each model under test that answers with the base free (an optional `floating_inverse_dynamics(base, q,
    q', q'')`: the base's six rows, then its joints' torques, rigid bodies) against Pinocchio's free-flyer:
    `<name>_vs_pinocchio_max_rel_error`, each row and joint over its largest |value|."""
    from harness.base.numerics import largest_relative_difference
    from harness.engines.floating import inverse_dynamics

    ref = inverse_dynamics(sc.robot, sc.gravity_W, base, q, qd, qdd, "pinocchio")
    reference = np.concatenate([ref.base, ref.tau], axis=1)
    out = {}
    for e in sc.models:
        if not callable(getattr(e.instance, "floating_inverse_dynamics", None)):
            continue
        to_model, back = column_maps(e.instance.joint_names, sc.robot.joint_names)
        theirs = call(e.reference, "floating_inverse_dynamics", e.instance.floating_inverse_dynamics, base,
                      q[:, to_model], qd[:, to_model], qdd[:, to_model], shape=(len(q), 6 + q.shape[1]))
        theirs = np.concatenate([theirs[:, :6], theirs[:, 6:][:, back]], axis=1)
        out[f"{e.name}_vs_pinocchio_max_rel_error"] = largest_relative_difference(theirs, reference)
    return out
