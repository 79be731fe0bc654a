"""A URDF's `<transmission>` elements (ros_control and ros2_control) as the model's drives
(harness/model/drives.py): the motors, N and the offsets that `[drives] urdf_transmissions = true`
reads in place of `gear_ratio`, `transmission` and `joint_offset`.

Two kinds are read, with ros2_control's conventions (transmission_interface's SimpleTransmission and
DifferentialTransmission; n a reduction, x_off a joint offset):

    simple:        x_a = n (x_j - x_off),                         tau_j = n tau_a
    differential:  x_a1 = n_a1 [n_j1 (x_j1 - x_off1) + n_j2 (x_j2 - x_off2)]
                   x_a2 = n_a2 [n_j1 (x_j1 - x_off1) - n_j2 (x_j2 - x_off2)],
                   tau_j1 = n_j1 (n_a1 tau_a1 + n_a2 tau_a2), tau_j2 = n_j2 (n_a1 tau_a1 - n_a2 tau_a2)

so q_m = N (q - x_off) with N's rows [n_a1 n_j1, n_a1 n_j2] and [n_a2 n_j1, -n_a2 n_j2] (tau_J = N^T tau_m:
virtual work, as drives.py writes it). A reduction is `mechanicalReduction` (ROS 1) or
`mechanical_reduction` (ROS 2), on the actuator (ROS 1's simple transmission) or on the joint (ROS 2's);
a role is a `<role>` element (ROS 1) or a `role` attribute (ROS 2), else the order written. Any other
kind (HalfDifferentialTransmission, a four-bar, a vendor's plugin) is refused in one line naming it."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from harness.base.tomlio import MAX_XML_BYTES, InputError, read_bounded

SIMPLE, DIFFERENTIAL = "transmission_interface/SimpleTransmission", "transmission_interface/DifferentialTransmission"


@dataclass(frozen=True)
class UrdfDrives:
    """The drives a URDF's transmissions state, in the order of the joints asked for: a motor per joint
    (its actuator's name), N (motors x joints) and each joint's offset, q = N^-1 q_m + joint_offset."""

    motors: tuple[str, ...]
    N: np.ndarray
    joint_offset: np.ndarray


def _text(element, *tags: str) -> str | None:
    for tag in tags:
        found = element.find(tag)
        if found is not None and found.text is not None and found.text.strip():
            return found.text.strip()
    return None


def _number(element, where: str, *tags: str) -> float | None:
    text = _text(element, *tags)
    if text is None:
        return None
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"{where}: {tags[0]} {text!r} is not a number") from None
    if not np.isfinite(value):
        raise ValueError(f"{where}: {tags[0]} {text!r} is not finite")
    return value


def _reduction(element, where: str) -> float | None:
    value = _number(element, where, "mechanicalReduction", "mechanical_reduction")
    if value == 0.0:
        raise ValueError(f"{where}: a mechanical reduction of 0 (no motion reaches the joint)")
    return value


def _ordered(elements: list, prefix: str) -> list:
    """The joints or actuators of a transmission in their roles' order (joint1, joint2), else as written."""
    roles = [e.get("role") or _text(e, "role") for e in elements]
    if all(roles) and sorted(roles) == [f"{prefix}{k + 1}" for k in range(len(elements))]:
        return [e for _, e in sorted(zip(roles, elements, strict=True), key=lambda pair: pair[0])]
    return elements


def _kind(element) -> str:
    """A transmission's kind: its <type> (ROS 1) or <plugin> (ROS 2), else the `type` attribute of the
    PR2's older form (named in the refusal: that form is not read)."""
    return _text(element, "type", "plugin") or element.get("type") or "(none stated)"


def _stated(root, joint_names: list[str]) -> list[tuple[str, list, list]]:
    """(kind, joints, actuators) of each transmission that drives one of `joint_names`."""
    out = []
    for tr in root.iter("transmission"):
        joints, actuators = tr.findall("joint"), tr.findall("actuator")
        if any(j.get("name") in joint_names for j in joints):
            out.append((tr, joints, actuators))
    return out


def read(path: Path, joint_names: list[str]) -> UrdfDrives:
    """The drives of the joints `joint_names` (the spec's moving joints, in its order) from the URDF at
    `path`. Raises ValueError with one line naming the transmission and what is wrong: a kind not read, a
    joint without a transmission or driven twice, a transmission reaching a joint the model does not
    move, a reduction of 0 or not a number, a transmission's joints and actuators not one to one."""
    try:
        root = ET.fromstring(read_bounded(path, MAX_XML_BYTES))
    except ET.ParseError as exc:
        raise InputError(path, "", f"cannot read URDF ({exc})") from None
    return _drives(root, joint_names)


def _drives(root, joint_names: list[str]) -> UrdfDrives:
    """`read` of a parsed URDF."""
    n = len(joint_names)
    N, joint_offset, motors = np.zeros((n, n)), np.zeros(n), [""] * n
    for tr, joints, actuators in _stated(root, joint_names):
        where = f"transmission {tr.get('name')!r}"
        kind = _kind(tr)
        if kind not in (SIMPLE, DIFFERENTIAL):
            raise ValueError(f"{where} is {kind}: {SIMPLE} and {DIFFERENTIAL} are read")
        size = 1 if kind == SIMPLE else 2
        if len(joints) != size or len(actuators) != size:
            raise ValueError(f"{where} ({kind}) has {len(joints)} joint(s) and {len(actuators)} actuator(s): "
                             f"{size} of each are read")
        joints, actuators = _ordered(joints, "joint"), _ordered(actuators, "actuator")
        names = [j.get("name") for j in joints]
        missing = [name for name in names if name not in joint_names]
        if missing:
            raise ValueError(f"{where} drives {missing[0]!r}, which the model does not move (a fixed joint?)")
        for name in names:
            if motors[joint_names.index(name)]:
                raise ValueError(f"{where}: joint {name!r} is driven by another transmission too")
        cols = [joint_names.index(name) for name in names]
        for c, j in zip(cols, joints, strict=True):
            joint_offset[c] = _number(j, f"{where} joint {j.get('name')!r}", "offset") or 0.0
        n_j = [_reduction(j, f"{where} joint {j.get('name')!r}") for j in joints]
        n_a = [_reduction(a, f"{where} actuator {a.get('name')!r}") for a in actuators]
        if kind == SIMPLE:
            if n_j[0] is not None and n_a[0] is not None and 1.0 not in (n_j[0], n_a[0]):
                raise ValueError(f"{where}: a reduction on both its joint ({n_j[0]:g}) and its actuator ({n_a[0]:g}); "
                                 "ROS 1 reads the actuator's and ROS 2 the joint's: give one")
            N[cols[0], cols[0]] = (n_a[0] if n_a[0] is not None else 1.0) * (n_j[0] if n_j[0] is not None else 1.0)
            motors[cols[0]] = actuators[0].get("name") or ""
        else:
            (a1, a2), (j1, j2) = ([1.0 if x is None else x for x in pair] for pair in (n_a, n_j))
            N[np.ix_(cols, cols)] = [[a1 * j1, a1 * j2], [a2 * j1, -a2 * j2]]
            for row, a in zip(cols, actuators, strict=True):  # motor k on the row of its joint k
                motors[row] = a.get("name") or ""
    undriven = [name for name, m in zip(joint_names, motors, strict=True) if not m]
    if undriven:
        raise ValueError(f"joint {undriven[0]!r} has no <transmission> (every moving joint needs its motor's)")
    if len(set(motors)) < n:
        raise ValueError(f"actuator {next(m for m in motors if motors.count(m) > 1)!r} drives two transmissions")
    return UrdfDrives(tuple(motors), N, joint_offset)


def unread_note(path: Path, joint_names: list[str]) -> str | None:
    """A URDF's note where its transmissions state more than each joint driven directly (a reduction other
    than 1, an offset, a differential) and the model does not read them. The file is read once more (after
    harness/model/urdf.py's reading) and parsed only where it holds a <transmission> element."""
    content = read_bounded(path, MAX_XML_BYTES)
    if b"<transmission" not in content:
        return None
    root = ET.fromstring(content)
    stated = _stated(root, joint_names)
    if not stated:
        return None
    try:
        drives = _drives(root, joint_names)
    except ValueError:
        drives = None
    if drives is not None and np.array_equal(drives.N, np.eye(len(joint_names))) and not drives.joint_offset.any():
        return None
    return (f"the URDF states {len(stated)} <transmission> element(s) (motors behind the joints): not read, each joint "
            "driven directly; [drives] urdf_transmissions = true reads them")
