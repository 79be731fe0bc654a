"""Shared fixtures: the paper's scenario is simulated once per session, in memory and via the CLI."""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import pytest
from threadpoolctl import threadpool_limits

from harness.base.series import TimeSeries, read_csv
from harness.cli import main
from harness.runner.scenario import Scenario, load_scenario
from harness.sources.bench import record, write_log

ROOT = Path(__file__).resolve().parents[1]
BUILTIN = ROOT / "harness" / "data"  # the built-in models, scenarios and gate sets (package data)
SCENARIOS = BUILTIN / "scenarios"
MODELS = BUILTIN / "models"

# The suite runs on two worker processes (README: `pytest`, `-n 2` in pyproject.toml), one per core: each
# does its linear algebra on one BLAS thread, as the harness's own trial workers do (harness/base/workers.py).
# Two threads in each oversubscribe the cores, and OpenBLAS's threads spin waiting for each other: the
# pivoted QR and SVD of a structural base (1,400 x 98) took ten times as long so.
BLAS_THREADS = threadpool_limits(1, user_api="blas")
os.environ["OPENBLAS_NUM_THREADS"] = "1"  # and the processes a test starts (`harness` run fresh), from their start


# The modules that take longest (over 1 s each, measured), started first: each of the two workers takes
# the next module when it is done with its own, and one of a few seconds taken last leaves the other idle
# at the end (6 s of 63 by the count of tests, xdist's own order). A scheduling hint: the rest keep
# their order, and a module named here and gone changes nothing.
LONGEST_FIRST = ("test_floating_log.py", "test_log_inputs.py", "test_suite_and_gates.py", "test_verdict.py",
                 "test_closed_chains.py", "test_drives.py", "test_contacts.py", "test_log_guards.py",
                 "test_run_folder.py", "test_friction_law.py", "test_plugins.py", "test_torques.py", "test_urdf.py",
                 "test_robustness.py", "test_log_read.py", "test_bad_input_catalogue.py", "test_workers.py",
                 "test_closed_chain_log_laws.py", "test_cli.py", "test_lagrange.py", "test_identification.py",
                 "test_floating.py", "test_estimators.py", "test_ball_joints.py")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    rank = {name: k for k, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))  # stable: each module's own order kept


@pytest.fixture(scope="session")
def kr500_rail() -> Scenario:
    return load_scenario(SCENARIOS / "kr500_rail.toml")


@pytest.fixture(scope="session")
def kr500_recording(kr500_rail: Scenario) -> TimeSeries:
    """The recording as the engine returned it (with MuJoCo's own orientation matrices)."""
    return record(kr500_rail)


@pytest.fixture(scope="session")
def kr500_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """`harness run` on the paper's scenario: the folder it wrote."""
    out = tmp_path_factory.mktemp("run") / "kr500_rail"
    assert main(["run", str(SCENARIOS / "kr500_rail.toml"), "--out", str(out)]) == 0
    return out


@pytest.fixture(scope="session")
def kr500_csv(kr500_run: Path) -> TimeSeries:
    """The recording read back from recording.csv: what a user of the file has, nothing more."""
    return read_csv(kr500_run / "recording.csv")


DATA = ROOT / "tests" / "data"
# a log scenario's [data] line for tests that read the fit alone: no forward simulation of the models
NO_PREDICTION = "prediction = { starts = 0 }"


@pytest.fixture(scope="session")
def run_scenario():
    """The whole pipeline on a scenario file, once per session and file."""
    from harness.runner.pipeline import run

    cache = {}

    def _run(path):
        if path not in cache:
            cache[path] = run(load_scenario(path))
        return cache[path]

    return _run


@pytest.fixture(scope="session")
def fast_run(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("fast") / "kr500_rail_7digits"
    assert main(["run", str(SCENARIOS / "kr500_rail_7digits.toml"), "--out", str(out), "--quiet"]) == 0
    return out


def results_of(out, when: str | None = None) -> dict:
    """results.json of a pipeline run, with its verdict."""
    from harness.runner.gates import verdict
    from harness.runner.results import build_results

    return verdict(out.scenario.gates, build_results(out, when), out.scenario.source)


def readings(out):
    """The graph-theory study's readings of a run's recording (its Cardano angles, gimbal flags and
    joint-point accelerations, exact)."""
    from harness.papers.graph_theory_2021.readings import exact

    return exact(out.recording, out.scenario.robot.inner_joint_arms_B())


def graph_model(out):
    """The graph-theory model of a run's robot (the study's model when the scenario names none)."""
    from harness.papers.graph_theory_2021.dynamics import build_graph_model

    return build_graph_model(out.scenario.robot, out.scenario.gravity_W)


def copy_gate_sets(scenarios_folder: Path) -> None:
    """The shared gate sets beside a scenario copied into a temporary folder."""
    import shutil

    shutil.copytree(SCENARIOS / "gates", scenarios_folder / "gates", dirs_exist_ok=True)


def late_log(scenario, lags, duration: float = 8.0, steps: int = 4000):
    """A bench log (DataFrame of t, q{k}, qd{k}, tau{k}) whose torque channels lag the encoders by
    lags[k] s: each read from the recording's torques that much earlier, by interpolation."""
    import numpy as np
    import pandas as pd

    rec = record(dataclasses.replace(scenario, duration=duration, output_steps=steps))
    cols = {"t": rec.t}
    for k, j in enumerate(scenario.robot.joint_names):
        c = rec.joint_index(j)
        cols[f"q{k + 1}"], cols[f"qd{k + 1}"] = rec.q[:, c], rec.qd[:, c]
        cols[f"tau{k + 1}"] = np.interp(rec.t - lags[k], rec.t, rec.tau[:, c])
    return pd.DataFrame(cols)


def bench_log(scenario, folder, duration: float, steps: int) -> None:
    """The scenario's bench recording, shortened, written as a log of t, q, q', tau."""
    rec = record(dataclasses.replace(scenario, duration=duration, output_steps=steps))
    write_log(rec, scenario.robot.joint_names, folder / "log.csv")


def write_frame(frame, path) -> None:
    """`frame.to_csv(path, index=False, float_format="%.17g")`, the same bytes, written by the harness's own
    writer (harness/base/csvtext.py; pandas' formats each value through a Python call of its own): numeric
    columns only, a NaN an empty cell as pandas writes it."""
    from harness.base.csvtext import csv_text

    kinds = {name: frame[name].dtype.kind for name in frame.columns}
    if frame.columns.duplicated().any() or any(k not in "fiu" for k in kinds.values()):
        raise TypeError(f"write_frame writes distinct numeric columns only: {kinds}")
    Path(path).write_text(csv_text({name: frame[name].to_numpy() for name in frame.columns}, missing=""),
                          newline="")


def log_scenario(folder, model, gates: str) -> None:
    """folder/s.toml: a [data] scenario of folder/log.csv on `model`, validated on its last 30 %."""
    (folder / "s.toml").write_text(
        f'[scenario]\nmodel = "{model}"\n[data]\nfile = "log.csv"\n'
        'columns = { t = "t", q = "q{j}", qd = "qd{j}", tau = "tau{j}" }\nvalidation = { from = 0.7 }\n' + gates)


def pinocchio_rnea(pm, q, qd, qdd):
    """(N, n) Pinocchio's own rnea, state by state, in the spec's joint order: the rigid bodies' torques with
    no harness code but the model's coordinate index (one coordinate per hinge or slide: q's index is v's)."""
    import numpy as np
    import pinocchio as pin

    data, x, out = pm.model.createData(), np.zeros((3, pm.model.nq)), np.empty_like(q)
    for k in range(len(q)):
        x[:, pm.q_index] = q[k], qd[k], qdd[k]
        out[k] = pin.rnea(pm.model, data, x[0], x[1], x[2])[pm.q_index]
    return out


def mujoco_inverse(model, q, qd, qdd, cols=None):
    """(N, n) MuJoCo's own inverse dynamics (mj_inverse's qfrc_inverse) of a compiled model, state by state:
    the file's own reference, no harness code; `cols`, the joints' coordinates (one per hinge or slide:
    qpos's index is qvel's), every one where None."""
    import mujoco
    import numpy as np

    data, out = mujoco.MjData(model), np.empty_like(q)
    cols = slice(None) if cols is None else cols
    for k in range(len(q)):
        data.qpos[cols], data.qvel[cols], data.qacc[cols] = q[k], qd[k], qdd[k]
        mujoco.mj_inverse(model, data)
        out[k] = data.qfrc_inverse[cols]
    return out


def viscous_coulomb(frictions, qd, qdd):
    """(N, n) each joint's drive law written out here: I q'' + f_v q' + f_c tanh(q' / v_c) + f_o."""
    import numpy as np

    return np.column_stack([f.armature * qdd[:, k] + f.viscous * qd[:, k]
                            + f.coulomb * np.tanh(qd[:, k] / f.coulomb_velocity) + f.offset
                            for k, f in enumerate(frictions)])


KINOVA_JOINTS = [f"j2s6s200_joint_{k}" for k in range(1, 7)]
KINOVA_MIDDLE = [0.0, 3.141592653589793, 3.141592653589793, 0.0, 3.141592653589793, 0.0]  # away from its limits


def kinova_files(folder: Path) -> tuple[str, str]:
    """example-robot-data's Kinova Jaco2 as shipped (folder/shipped.urdf: rotations by pi written with
    12 digits) and with every pi exact (folder/exact.urdf)."""
    import numpy as np

    from harness.model.urdf import example_robot_data_path

    shipped = example_robot_data_path("kinova").read_text()
    exact = shipped.replace("3.14159265359", repr(np.pi)).replace("1.57079632679", repr(np.pi / 2))
    (folder / "shipped.urdf").write_text(shipped)
    (folder / "exact.urdf").write_text(exact)
    return shipped, exact


def kinova_model(folder: Path, name: str, urdf: str, coulomb_velocity: float | None) -> None:
    """folder/{name}.toml: the Kinova of `urdf` with drives on every joint (v_c declared or not), each
    joint's values its own (a joint read for another shows)."""
    (folder / f"{name}.toml").write_text(
        f'[model]\nname = "{name}"\n[urdf]\nfile = "{urdf}"\n'
        + "".join(f"[joints.{j}]\narmature = {0.1 - 0.012 * k:.3f}\nviscous = {0.5 - 0.05 * k:.2f}\n"
                  f"coulomb = {1.0 - 0.11 * k:.2f}\noffset = {0.1 - 0.035 * k:.3f}\n"
                  + (f"coulomb_velocity = {coulomb_velocity}\n" if coulomb_velocity is not None else "")
                  for k, j in enumerate(KINOVA_JOINTS)))


def kinova_bench(folder: Path, name: str, truth: str, seconds: float, seed: int) -> Scenario:
    """folder/{name}.toml: a bench scenario of the Kinova model `truth` (a file in folder), every joint
    on two random sinusoids about KINOVA_MIDDLE, recorded at 250 Hz (RK4, 0.5 ms)."""
    import numpy as np

    rng = np.random.default_rng(seed)
    motion = "".join(f'[motion.{j}]\ntype = "sinusoids"\noffset = {m}\n'
                     f"sin = [[{rng.uniform(0.4, 0.8):.3f}, {rng.uniform(0.5, 1.5):.3f}]]\n"
                     f"cos = [[{rng.uniform(0.1, 0.3):.3f}, {rng.uniform(1.5, 3.0):.3f}]]\n"
                     for j, m in zip(KINOVA_JOINTS, KINOVA_MIDDLE, strict=True))
    (folder / f"{name}.toml").write_text(
        f'[scenario]\nmodel = "{truth}"\nduration = {seconds}\noutput_steps = {int(seconds * 250)}\n'
        '[simulation]\nintegrator = "RK4"\ntimestep = 0.0005\n' + motion
        + '[[gates]]\nmetric = "torques.pinocchio_vs_mujoco.max_rel_error"\nlimit = 1e-9\n')
    return load_scenario(folder / f"{name}.toml")


def numbers_of(tree) -> list[float]:
    """Every number of a results.json subtree, in order."""
    if isinstance(tree, dict):
        return [x for v in tree.values() for x in numbers_of(v)]
    if isinstance(tree, list):
        return [x for v in tree for x in numbers_of(v)]
    return [float(tree)] if isinstance(tree, int | float) and not isinstance(tree, bool) else []


TWO_LINK_MOTION = ('[motion.shoulder]\ntype = "sinusoids"\noffset = -0.3\nsin = [[0.9, 2.1], [0.3, 5.3]]\n'
                   '[motion.elbow]\ntype = "sinusoids"\nsin = [[1.0, 3.0], [0.2, 6.7]]\n')


def two_link_bench(folder: Path, model: str, duration: float, output_steps: int) -> Scenario:
    """folder/bench.toml: the example two-link arm's `model` (examples/two_link_arm's URDF with drives of
    the test's own) on two sinusoids a joint, MuJoCo against Pinocchio as its gate; loaded."""
    (folder / "bench.toml").write_text(
        f'[scenario]\nmodel = "{model}"\nduration = {duration!r}\noutput_steps = {output_steps}\n' + TWO_LINK_MOTION
        + '[[gates]]\nmetric = "torques.pinocchio_vs_mujoco.max_rel_error"\nlimit = 1e-9\n')
    return load_scenario(folder / "bench.toml")



HUMANOID = """<mujoco model="biped">
  <!-- A humanoid as makers publish them: a floating pelvis (free joint), two legs and two arms, meshes in
       a folder of their own, a keyframe, and a second body at the root on a hinge (a door beside it). -->
  <compiler angle="radian" meshdir="assets"/>
  <asset>
    <mesh name="pelvis" file="pelvis.STL"/><mesh name="thigh" file="thigh.STL"/><mesh name="shin" file="shin.STL"/>
    <mesh name="torso" file="torso.STL"/><mesh name="arm" file="arm.STL"/>
  </asset>
  <worldbody>
    <body name="pelvis" pos="0 0 1.05">
      <freejoint name="floating_base_joint"/>
      <inertial pos="-0.0002 0 -0.04" mass="5.39" diaginertia="0.044 0.035 0.016"/>
      <geom type="mesh" mesh="pelvis"/>
      LEGS
      <body name="torso_link" pos="0 0 0.1">
        <inertial pos="0 0 0.2" mass="17.8" diaginertia="0.49 0.41 0.14"/>
        <joint name="torso_joint" axis="0 0 1" range="-2.35 2.35"/>
        <geom type="mesh" mesh="torso"/>
        <body name="left_arm_link" pos="0 0.2 0.4" quat="0.9659 0.2588 0 0">
          <inertial pos="0 0.02 -0.1" mass="1.0" diaginertia="0.004 0.004 0.001"/>
          <joint name="left_shoulder_joint" axis="0 1 0" range="-2.87 2.87"/>
          <geom type="mesh" mesh="arm"/>
        </body>
        <body name="right_arm_link" pos="0 -0.2 0.4" quat="0.9659 -0.2588 0 0">
          <inertial pos="0 -0.02 -0.1" mass="1.1" diaginertia="0.005 0.004 0.001"/>
          <joint name="right_shoulder_joint" axis="0 1 0" range="-2.87 2.87"/>
          <geom type="mesh" mesh="arm"/>
        </body>
      </body>
    </body>
    <body name="door" pos="2 0 1">
      <inertial pos="0.3 0 0" mass="3.0" diaginertia="0.1 0.2 0.12"/>
      <joint name="door_hinge" axis="0 0 1" range="-1.5 1.5"/>
      <geom type="box" size="0.3 0.02 0.5" pos="0.3 0 0"/>
    </body>
  </worldbody>
  <keyframe>
    <key name="home" qpos="0 0 1.05 1 0 0 0  0 -0.4 0.8  0 -0.4 0.8  0 0.3 -0.3  0.2"/>
  </keyframe>
</mujoco>
"""
LEG = """<body name="SIDE_hip_link" pos="0 Y -0.1742">
        <inertial pos="-0.0498 Y4 0" quat="0.53 0.53 0.46 0.47" mass="2.24" diaginertia="0.0055 0.0043 0.0030"/>
        <joint name="SIDE_hip_yaw_joint" axis="0 0 1" range="-0.43 0.43"/>
        <geom type="mesh" mesh="thigh"/>
        <body name="SIDE_thigh_link" pos="0 0 -0.1">
          <inertial pos="0 0 -0.15" mass="4.15" diaginertia="0.11 0.11 0.008"/>
          <joint name="SIDE_hip_pitch_joint" axis="0 1 0" range="-1.57 1.57"/>
          <geom type="mesh" mesh="thigh"/>
          <body name="SIDE_knee_link" pos="0 0 -0.4">
            <inertial pos="0 0 -0.14" mass="1.72" diaginertia="0.012 0.012 0.002"/>
            <joint name="SIDE_knee_joint" axis="0 1 0" range="-0.26 2.05"/>
            <geom type="mesh" mesh="shin"/>
          </body>
        </body>
      </body>"""


def _box_stl(path: Path, size) -> None:
    """A box of `size` (m) as a binary STL mesh: 12 triangles."""
    import struct

    import numpy as np

    v = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * np.asarray(size) / 2
    faces = [(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1), (2, 3, 7), (2, 7, 6), (0, 2, 6),
             (0, 6, 4), (1, 5, 7), (1, 7, 3)]
    out = bytearray(80) + struct.pack("<I", len(faces))
    for f in faces:
        a, b, c = v[list(f)]
        n = np.cross(b - a, c - a)
        out += struct.pack("<12fH", *(n / np.linalg.norm(n)), *a, *b, *c, 0)
    path.write_bytes(bytes(out))


def humanoid_mjcf(folder: Path) -> Path:
    """folder/biped.xml and its meshes in folder/assets/: a humanoid with a free joint, a keyframe and a
    second root body on a hinge, written the way humanoid makers publish MJCF (H1-like masses)."""
    (folder / "assets").mkdir(parents=True, exist_ok=True)
    for name, size in {"pelvis": (0.2, 0.3, 0.15), "thigh": (0.1, 0.1, 0.4), "shin": (0.08, 0.08, 0.4),
                       "torso": (0.25, 0.35, 0.45), "arm": (0.07, 0.07, 0.3)}.items():
        _box_stl(folder / "assets" / f"{name}.STL", size)
    legs = "\n      ".join(LEG.replace("SIDE", side).replace("Y4", y4).replace(" Y ", f" {y} ")
                           for side, y, y4 in (("left", "0.0875", "0.0039"), ("right", "-0.0875", "-0.0039")))
    path = folder / "biped.xml"
    path.write_text(HUMANOID.replace("LEGS", legs))
    return path
