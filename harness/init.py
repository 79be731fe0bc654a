"""What `harness init DIR` writes: a small project for a robot of the user's (harness/data/init/).

Without a robot file, the two-link arm with a closed-form model; with one (a URDF or an MJCF file,
told apart by their root element), that file, a motion of every joint within its limits (two
sinusoids of incommensurate frequencies about the middle of its range, together at most a third of
the way to the limits and at half its velocity limit, other frequencies for each joint and for the
validation trajectory), and a placeholder model (Pinocchio on the file: its URDF or its MJCF
parser). Both get the same identification method (least squares on Pinocchio's regressor), pytest file and CI job.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import tomli_w

from harness.base.builtin import DATA
from harness.base.tomlio import MAX_XML_BYTES, InputError, read_bounded

TEMPLATE = DATA / "init"
MODEL_GATES = [  # the model's round-off agreement (about 1e-15)
    ("torques.mine_vs_mujoco.max_rel_error", 1e-9), ("torques.mine_vs_pinocchio.max_rel_error", 1e-9),
    ("torques.mine_random_vs_pinocchio.max_rel_error", 1e-9),
    ("torques.mass_matrix.mine_vs_pinocchio.max_rel_error", 1e-9),
]
GATES = MODEL_GATES + [  # and the method's on noise-free torques (about 1e-12)
    ("identification_methods.ls.base_parameters.max_rel_error", 1e-6),
    ("identification_methods.ls.validation.max_rel_error", 1e-6),
]
RANGE_FRACTION = 1 / 3  # of the way from the middle of a joint's range to its limits
VELOCITY_FRACTION = 0.5  # of its velocity limit
DEFAULT_HALF_RANGE = {True: np.pi, False: 0.5}  # revolute (rad), prismatic (m): a joint without limits


FORMATS = {"robot": ("urdf", "robot.urdf", "URDF"), "mujoco": ("mjcf", "robot.xml", "MJCF")}  # by root element


def robot_format(path: Path, content: bytes, flag: str) -> tuple[str, str, str]:
    """(model file key, the project's file name, the format's name) of a robot file (`content` its
    bytes), told by its root element (<robot>: URDF, <mujoco>: MJCF), whatever its name or the flag that
    gave it."""
    import xml.etree.ElementTree as ET

    try:
        root = ET.fromstring(content).tag
    except ET.ParseError as exc:
        raise InputError(path, flag, f"not XML ({exc}): a URDF or an MJCF file is") from None
    if root not in FORMATS:
        raise InputError(path, flag, f"its root element is <{root}>: a URDF's is <robot>, an MJCF file's <mujoco>")
    return FORMATS[root]


def project(robot: Path | None = None, flag: str = "--robot", floating: bool = False) -> dict[str, str | Path]:
    """{file name: its text, or the file to copy} of the project; `robot` a URDF or an MJCF file (`flag`:
    the option that named it); `floating`: a URDF's root link is a floating base (`[urdf] floating = true`;
    an MJCF file states its own, a free joint, and is refused the flag)."""
    from harness.base.version import DISTRIBUTION

    files = {f.name: f.read_text() for f in sorted((TEMPLATE / "project").iterdir())}
    method = (TEMPLATE / "method.py").read_text()
    if robot is None:
        arm = TEMPLATE / "two_link_arm"
        files.update({f.name: f.read_text() for f in sorted(arm.iterdir()) if f.name != "model.py"})
        files["my_robot.py"] = (arm / "model.py").read_text() + method
    else:
        content = read_bounded(robot, MAX_XML_BYTES)
        key, name, kind = robot_format(robot, content, flag)
        files[name] = content.decode("utf-8", errors="replace")
        if key == "mjcf":  # the meshes, textures and included files it names: beside it, or where they are
            text, named = named_files(robot, flag)
            files[name] = text if text is not None else files[name]
            files.update(named)
        if floating and key != "urdf":
            raise InputError(robot, "--floating", "an MJCF file's floating base is its root body's free joint "
                                                  "(<freejoint/>): the file states it, the flag is a URDF's")
        root_floats = {"floating": True} if floating else {}
        head = f"# The robot the harness simulates (MuJoCo) and takes as the truth (Pinocchio): your {kind} file.\n"
        joints, mimic, floating = _joints(robot, key, flag, root_floats)
        if mimic:
            head += ("# Its <mimic> joints are read as joints of their own (the project moves every joint and runs\n"
                     "# your model and method, a tree's); remove `mimic` to read them as couplings\n"
                     "# (docs/closed_chains.md).\n")
        files["robot.toml"] = head + tomli_w.dumps({"model": {"name": "my_robot",
                                                              "description": f"My robot, from its {kind} file"},
                                                    key: {"file": name, **({"mimic": "independent"} if mimic else {}),
                                                          **root_floats}})
        files["scenario.toml"], files["validation.toml"] = scenarios(joints, floating)
        if floating:  # the base moved too, and judged in the project's own pytest and CI job
            files["floating.toml"] = floating_scenario(joints)
            files["test_my_robot.py"] += FLOATING_TEST
            files["ci-job.yml"] = files["ci-job.yml"].replace("harness run scenario.toml ",
                                                              "harness run scenario.toml floating.toml ")
        files["my_robot.py"] = ((TEMPLATE / "urdf" / "model.py").read_text() + method).replace(
            'ROBOT_FILE = "robot.urdf"', f'ROBOT_FILE = "{name}"')
    files["ci-job.yml"] = files["ci-job.yml"].replace("HARNESS_DISTRIBUTION", DISTRIBUTION)
    return dict(sorted(files.items()))


FLOATING_TEST = '''

def test_my_model_with_the_floating_base_moving_passes_its_gates(harness_run):
    result = harness_run("floating.toml")
    assert result.passed, [f"{g.name}: {g.value} (worst: {g.where})" for g in result.failed]
'''

ASSETS = {"mesh": "meshdir", "skin": "meshdir", "hfield": "meshdir", "texture": "texturedir"}  # MuJoCo's


def named_files(robot: Path, flag: str) -> tuple[str | None, dict[str, Path]]:
    """The files an MJCF file names (`<include>`, and the meshes, skins, height fields and textures
    under its compiler's meshdir, texturedir or assetdir), found as MuJoCo finds them (relative to the
    robot file's folder), {path in the project: the file}: each at the same place relative to the
    project's robot file, when it lies in the robot file's folder. One that lies elsewhere is named
    where it is (its absolute path written into the file that names it): then the robot file's new
    text (else None). A file named but missing is refused, naming it."""
    import xml.etree.ElementTree as ET

    base = robot.resolve().parent
    out: dict[str, Path] = {}
    pending, robot_text = [robot.resolve()], None
    dirs: dict[str, str] = {}
    while pending:
        xml = pending.pop(0)
        root = ET.fromstring(read_bounded(xml, MAX_XML_BYTES))
        for compiler in root.iter("compiler"):
            dirs.update({k: v for k, v in compiler.attrib.items() if k in ("meshdir", "texturedir", "assetdir")})
        moved = False
        for el in root.iter():
            if "file" not in el.attrib or el.tag not in (*ASSETS, "include"):
                continue
            folder = "" if el.tag == "include" else dirs.get(ASSETS[el.tag], dirs.get("assetdir", ""))
            path = (base / folder / el.get("file")).resolve()
            if not path.is_file():
                raise InputError(robot, flag, f"<{el.tag} file={el.get('file')!r}>: no such file ({path})")
            if path.is_relative_to(base):
                out[path.relative_to(base).as_posix()] = path
            else:
                el.set("file", str(path))
                moved = True
            if el.tag == "include":
                pending.append(path)
        if moved and xml == robot.resolve():
            robot_text = ET.tostring(root, encoding="unicode")
        elif moved:
            raise InputError(robot, flag, f"{xml.name} (an included file) names files outside {base}: copy them "
                                          "beside the robot file")
    return robot_text, out


def _joints(robot: Path, key: str, flag: str, extra: dict | None = None
            ) -> tuple[list[tuple[str, float, float, float | None]], bool, bool]:
    """(name, middle, half range, velocity limit) of every joint of the robot file (`key`: urdf or
    mjcf; `extra`, more of the model file's [key] table), read as the harness reads it, whether a URDF's
    <mimic> joints are read as joints of their own (the project moves every joint), and whether it has a
    floating base; a file it refuses is refused here, naming the file."""
    from harness.model.load import load_spec

    path = Path(robot).resolve()

    def read(table: dict):
        with tempfile.TemporaryDirectory() as tmp:
            (Path(tmp) / "robot.toml").write_text(tomli_w.dumps({"model": {"name": "my_robot"}, key: table}))
            try:
                return load_spec(Path(tmp) / "robot.toml")
            except InputError as exc:
                raise InputError(robot, flag, exc.message.removeprefix(f"{path}: ")) from None

    spec = read({"file": str(path), **(extra or {})})
    mimic = key == "urdf" and bool(spec.loops)  # a URDF's loops are its <mimic> couplings
    if mimic:
        spec = read({"file": str(path), "mimic": "independent", **(extra or {})})
    if spec.loops:
        raise InputError(robot, flag, f"a closed chain (loop {spec.loops[0].name!r}): the project written here moves "
                                      "every joint; start from the built-in fourbar, parallelogram or gripper "
                                      "scenario (docs/closed_chains.md)")
    out = []
    for j in spec.joints:
        lo, hi = (spec.limits or {}).get(j.name, (-np.inf, np.inf))
        if np.isfinite(lo) and np.isfinite(hi) and hi > lo:
            middle, half = (lo + hi) / 2, (hi - lo) / 2
        else:
            middle, half = 0.0, DEFAULT_HALF_RANGE[j.revolute]
        out.append((j.name, float(middle), float(half), (spec.drive_limits or {}).get(j.name, {}).get("velocity")))
    return out, mimic, spec.floating is not None


FLOATING_GATES = [  # a floating base judged free (docs/floating_base.md): round-off, about 1e-15
    ("torques.floating.engines_max_rel_error", 1e-9), ("torques.floating.mass_matrix_max_rel_error", 1e-9),
]
MOVED_GATES = [  # the bench moving the base: the world's wrench on it found from the recorded states (round-off),
    # and the base's tracking (the integrator's error, about 1e-12)
    ("torques.floating.base_wrench_pinocchio_vs_mujoco_max_rel_error", 1e-9),
    ("torques.floating.base_wrench_mine_vs_mujoco_max_rel_error", 1e-9),
    ("torques.floating.mine_vs_pinocchio_max_rel_error", 1e-9),
    ("torques.floating.base_tracking_position_m", 1e-6), ("torques.floating.base_tracking_angle_rad", 1e-6),
]
BASE_SWAY = {"z": (0.02, 1.9), "roll": (0.1, 1.3), "pitch": (0.1, 1.7), "yaw": (0.2, 0.9)}  # m or rad, rad/s


def _motion(joints: list[tuple[str, float, float, float | None]], base: float, step: float, shift: float) -> dict:
    """Every joint on two incommensurate harmonics about the middle of its range (`shift` of the half range
    off it), at most RANGE_FRACTION of the way to its limits and VELOCITY_FRACTION of its velocity limit."""
    table = {}
    for k, (name, middle, half, velocity) in enumerate(joints):
        w1, w2 = base + step * k, 2.7 * base + 1.3 * step * k + 0.4  # rad/s: two harmonics, incommensurate
        amplitude = RANGE_FRACTION * half / 1.5  # the two together reach RANGE_FRACTION at most
        if velocity:  # |q'| <= a w1 + a/2 w2
            amplitude = min(amplitude, VELOCITY_FRACTION * velocity / (w1 + w2 / 2))
        table[name] = {"type": "sinusoids", "offset": middle + shift * half,
                       "sin": [[amplitude, w1], [amplitude / 2, w2]]}
    return table


HEAD = {"model": "robot.toml", "duration": 2.0, "output_steps": 200}
NOTE = ("# Written by `harness init` from your robot file: every joint moves about the middle of its range, at\n"
        "# most a third of the way to its limits and at half its velocity limit. Change the motions to the ones\n"
        "# your robot runs.\n")


def scenarios(joints: list[tuple[str, float, float, float | None]], floating: bool = False) -> tuple[str, str]:
    """scenario.toml (the model, the method, the gates) and validation.toml, both moving every joint;
    with a `floating` base (which the bench fixes at the file's pose), the gates on it judged free."""
    main = {"scenario": {"description": "My robot: my model and my identification method against MuJoCo and "
                                        "Pinocchio", **HEAD},
            "motion": _motion(joints, 1.1, 0.3, 0.0),
            "model_under_test": {"name": "mine", "python": "my_robot:make_model"},
            "identification": {"name": "ls", "python": "my_robot:make_method", "validation": "validation.toml"},
            "gates": [{"metric": m, "limit": limit} for m, limit in GATES + (FLOATING_GATES if floating else [])]}
    validation = {"scenario": {"description": "Validation trajectory for my robot", **HEAD},
                  "motion": _motion(joints, 0.8, 0.25, 0.1),
                  "gates": [{"metric": "torques.pinocchio_vs_mujoco.max_rel_error", "limit": 1e-9}]}
    note = NOTE
    if floating:
        note += ("# Its floating base is fixed at the file's pose while the joints move; torques.floating judges the\n"
                 "# robot with the base free (docs/floating_base.md), and floating.toml moves the base.\n")
    return note + tomli_w.dumps(main), note + tomli_w.dumps(validation)


def floating_scenario(joints: list[tuple[str, float, float, float | None]]) -> str:
    """floating.toml: the joints as in scenario.toml while the bench moves the floating base (a gentle sway,
    BASE_SWAY), the model judged with its base free (its floating_inverse_dynamics) and the world's wrench
    on the base gated (docs/floating_base.md); no identification (it reads a fixed base)."""
    sway = {axis: {"type": "sinusoids", "offset": 0.0, "sin": [[a, w]]} for axis, (a, w) in BASE_SWAY.items()}
    moved = {"scenario": {"description": "My robot with its floating base moved: my model against MuJoCo and "
                                         "Pinocchio", **HEAD},
             "motion": _motion(joints, 1.1, 0.3, 0.0), "base_motion": sway,
             "model_under_test": {"name": "mine", "python": "my_robot:make_model"},
             "gates": [{"metric": m, "limit": limit} for m, limit in MODEL_GATES + FLOATING_GATES + MOVED_GATES]}
    return (NOTE + "# The bench moves the floating base on a gentle sway (no contact: the base is carried), the\n"
                   "# world's wrench on it recorded; your model answers through floating_inverse_dynamics.\n"
            + tomli_w.dumps(moved))
