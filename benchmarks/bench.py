"""Benchmark: run from the project root with `.venv/bin/python benchmarks/bench.py`.

Measures on the machine at hand, in one run, so that the ratios hold on a noisy machine (two timed
things are measured alternately, the best of several rounds of each):
- joint torques for 10,000 states of kr500: the graph model batched, Pinocchio `rnea` and MuJoCo
  `mj_inverse` called per state from Python (microseconds per state, ratio graph / Pinocchio);
- identification on the force path (the graph model, 10,000 samples) and on the joint-torque path
  with friction and rotor inertia (Panda, 7 joints, block by block: harness/identify/streaming.py) at 1e4,
  1e5 and 9e5 samples; at 9e5, in a process of its own, its time over that of Pinocchio's
  joint-torque regressor alone evaluated once on the same samples from Python, and the peak memory;
- `harness run` end to end in a fresh process: kr500_rail (seconds, its stages, and its floor: a fresh
  interpreter importing the engines, and MuJoCo's steps without the drive law), and the same
  kind of scenario (graph model, torques, torque identification) on robots of 6, 7, 7 and 20 joints;
- `harness sweep` throughput on kr500_noise in 1 and 2 processes and on a local Dask cluster (trials per
  second).
Writes reports/benchmark.json and prints a table.
"""

from __future__ import annotations

import dataclasses
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

N = 10_000
LONG = 900_000
ROUNDS = 7
TURNS = 5  # 1000-trial sweeps, 2 processes against Dask


def alternately(*fs, rounds: int = ROUNDS) -> list[float]:
    """The best time of each function over `rounds` rounds, the functions taking turns."""
    best = [np.inf] * len(fs)
    for _ in range(rounds):
        for k, f in enumerate(fs):
            t0 = time.perf_counter()
            f()
            best[k] = min(best[k], time.perf_counter() - t0)
    return best


def joint_motion(n: int, samples: int, rate: float = 1000.0, seed: int = 0):
    """Three sines a joint (0.1 to 0.5 Hz) sampled at `rate`: q, q', q'' (samples, n), closed form."""
    rng = np.random.default_rng(seed)
    t = np.arange(samples) / rate
    w, amp, phase = rng.uniform(0.6, 3.0, (3, n)), rng.uniform(0.2, 0.8, (3, n)), rng.uniform(0, 6, (3, n))
    q, qd, qdd = (np.zeros((samples, n)) for _ in range(3))
    for k in range(3):  # one sine at a time: no (3, samples, n) temporaries
        arg = w[k] * t[:, None] + phase[k]
        q += amp[k] * np.sin(arg)
        qd += amp[k] * w[k] * np.cos(arg)
        qdd -= amp[k] * w[k] ** 2 * np.sin(arg)
    return q, qd, qdd


def _in_pinocchio_order(pm, q, qd, qdd):
    """(q, q', q'') of the spec's joints (N, n) as Pinocchio's configuration vectors (N, nq), zero elsewhere."""
    out = tuple(np.zeros((len(q), pm.model.nq)) for _ in range(3))
    for x, y in zip(out, (q, qd, qdd), strict=True):
        x[:, pm.q_index] = y
    return out


def torques(figures: dict) -> None:
    import mujoco
    import pinocchio as pin

    from harness.engines.mujoco import build_model as build_mujoco
    from harness.engines.pinocchio import build_model as build_pinocchio
    from harness.papers.graph_theory_2021.dynamics import build_graph_model
    from harness.papers.graph_theory_2021.inverse import inverse_dynamics
    from harness.papers.graph_theory_2021.model import make as make_graph_model
    from harness.papers.graph_theory_2021.readings import exact
    from harness.runner.scenario import load_scenario
    from harness.sources.bench import record

    # 10,000 states of kr500 with every joint moving: their body kinematics come from MuJoCo
    sc = load_scenario(ROOT / "harness" / "data" / "scenarios" / "kr500_all_joints.toml")
    sc = dataclasses.replace(sc, duration=20.0, output_steps=N - 1, sample_times=np.linspace(0, 20.0, N))
    spec = sc.robot
    rec = exact(record(sc), spec.inner_joint_arms_B())  # the graph model reads the body motion as angles
    model = build_graph_model(spec, sc.gravity_W)
    cols = [rec.joint_index(j) for j in spec.joint_names]
    q, qd, qdd = rec.q[:, cols], rec.qd[:, cols], rec.qdd[:, cols]
    plugin = make_graph_model(spec, sc.gravity_W)  # as a model under test: (q, q', q'') in, kinematics its own
    pm = build_pinocchio(spec, sc.gravity_W)
    data = pm.model.createData()
    qq, vv, aa = _in_pinocchio_order(pm, q, qd, qdd)

    def pinocchio_loop():
        for k in range(N):
            pin.rnea(pm.model, data, qq[k], vv[k], aa[k])

    mm = build_mujoco(sc.robot, sc.gravity_W, sc.simulation)
    md = mujoco.MjData(mm)
    qadr = [mm.joint(j).qposadr[0] for j in spec.joint_names]
    vadr = [mm.joint(j).dofadr[0] for j in spec.joint_names]

    def mujoco_loop():
        for k in range(N):
            md.qpos[qadr], md.qvel[vadr], md.qacc[vadr] = q[k], qd[k], qdd[k]
            mujoco.mj_inverse(mm, md)

    t_graph, t_pin = alternately(lambda: inverse_dynamics(spec, model, rec), pinocchio_loop)
    t_plugin, t_mj = alternately(lambda: plugin.inverse_dynamics(q, qd, qdd), mujoco_loop, rounds=3)
    figures["torques_us_per_state"] = {
        "graph_batched": 1e6 * t_graph / N,
        "graph_plugin_with_kinematics": 1e6 * t_plugin / N,
        "pinocchio_rnea": 1e6 * t_pin / N,
        "mujoco_mj_inverse": 1e6 * t_mj / N,
    }
    figures["torques_ratio_graph_over_pinocchio"] = t_graph / t_pin

    from harness.papers.graph_theory_2021.solve import identify
    from harness.sources.measurement import Measurement

    rows = np.arange(N)
    figures["identification_10000_samples_s"] = alternately(
        lambda: identify(model, rec, rows, Measurement(), with_system=False), rounds=2)[0]


ROBOTS = (("panda", "panda_sines"), ("ur5", "ur5_sines"), ("kr500", "kr500_all_joints"))
SCALING = (1_000, 10_000, 100_000, 1_000_000)


def _like_for_like(scenario: str) -> dict:
    import pinocchio as pin

    from harness.engines.pinocchio import build_model
    from harness.papers.graph_theory_2021.model import make
    from harness.runner.scenario import load_scenario

    sc = load_scenario(ROOT / "harness" / "data" / "scenarios" / f"{scenario}.toml")
    n = len(sc.robot.joints)
    graph, pm = make(sc.robot, sc.gravity_W), build_model(sc.robot, sc.gravity_W)
    q, qd, qdd = joint_motion(n, N)
    qq, vv, aa = _in_pinocchio_order(pm, q, qd, qdd)
    data = pm.model.createData()
    pool = pin.ModelPool(pm.model, 1)
    Q, V, A = (np.asfortranarray(x.T) for x in (qq, vv, aa))
    tau = np.empty((pm.model.nv, N), order="F")

    def loop():
        for k in range(N):
            pin.rnea(pm.model, data, qq[k], vv[k], aa[k])

    t_graph, t_loop, t_batch = alternately(lambda: graph.solve(q, qd, qdd), loop,
                                           lambda: pin.rneaInParallel(1, pool, Q, V, A, tau))
    check = graph.solve(q[:50], qd[:50], qdd[:50]).tau
    ref = np.array([pin.rnea(pm.model, data, qq[k], vv[k], aa[k]) for k in range(50)])[:, pm.q_index]
    return {"joints": n, "states": N, "graph_us": 1e6 * t_graph / N, "pinocchio_loop_us": 1e6 * t_loop / N,
            "pinocchio_batch_1_thread_us": 1e6 * t_batch / N, "over_loop": t_graph / t_loop,
            "over_batch": t_graph / t_batch,
            "max_rel_difference": float(np.max(np.abs(check - ref)) / np.max(np.abs(ref)))}


def _graph_at(graph, n: int, states: int) -> dict:
    q, qd, qdd = joint_motion(n, states)
    seconds = alternately(lambda: graph.solve(q, qd, qdd), rounds=2 if states > N else 3)[0]
    tracemalloc.start()
    out = graph.solve(q, qd, qdd)
    peak = tracemalloc.get_traced_memory()[1] - (out.tau.nbytes + out.F_W.nbytes + out.M_W.nbytes)
    tracemalloc.stop()
    return {"us_per_state": 1e6 * seconds / states, "scratch_mib": peak / 2**20}


def graph_from_joint_coordinates(figures: dict) -> None:
    """Joint torques from (q, q', q'') alone, like for like: the graph model (its own forward kinematics
    and Newton-Euler, harness/papers/graph_theory_2021/inverse.py) against Pinocchio's rnea called per
    state from Python and against Pinocchio's C++ batch rneaInParallel on 1 thread, both on the same
    states, no friction on either side; then the graph model's time per state over 1e3 to 1e6 states
    of the Panda (the log-log slope of time against states) and its peak scratch memory (numpy's
    allocations, its outputs left out)."""
    from harness.papers.graph_theory_2021.model import make
    from harness.runner.scenario import load_scenario

    per_robot = {name: _like_for_like(scenario) for name, scenario in ROBOTS}
    figures["torques_graph_from_q"] = per_robot
    figures["torques_graph_from_q_over_pinocchio_loop"] = max(v["over_loop"] for v in per_robot.values())
    figures["torques_graph_from_q_over_pinocchio_batch"] = max(v["over_batch"] for v in per_robot.values())
    sc = load_scenario(ROOT / "harness" / "data" / "scenarios" / "panda_sines.toml")
    graph = make(sc.robot, sc.gravity_W)
    scaling = {str(states): _graph_at(graph, len(sc.robot.joints), states) for states in SCALING}
    x = np.log([float(k) for k in scaling])
    y = np.log([v["us_per_state"] * float(k) for k, v in scaling.items()])
    figures["torques_graph_from_q_scaling_panda"] = scaling
    figures["torques_graph_from_q_slope"] = float(np.polyfit(x, y, 1)[0])
    figures["torques_graph_from_q_scratch_mib_max"] = max(v["scratch_mib"] for v in scaling.values())


def _panda():
    from harness.engines.pinocchio import build_model
    from harness.identify.torque_id import structural_base
    from harness.model.load import load_spec

    spec = load_spec(ROOT / "harness" / "data" / "models" / "panda_arm.toml")
    pm = build_model(spec, np.array([0.0, 0.0, -9.80665]))
    return pm, structural_base(pm, spec.limits, with_friction=True)


def _torques(pm, q, qd, qdd) -> np.ndarray:
    """Joint torques of the motion with the drives' friction (Pinocchio's rnea, sample by sample)."""
    import pinocchio as pin

    from harness.model import friction

    data = pm.model.createData()
    tau = friction.torque(pm.frictions, qd, qdd, q=q)
    for k in range(len(q)):
        tau[k] += pin.rnea(pm.model, data, q[k], qd[k], qdd[k])
    return tau


def identification_scaling(figures: dict) -> None:
    from harness.identify.streaming import fit_long

    pm, base = _panda()
    out = {}
    for samples in (10_000, 100_000):
        q, qd, qdd = joint_motion(7, samples)
        tau = _torques(pm, q, qd, qdd)
        out[str(samples)] = alternately(lambda q=q, qd=qd, qdd=qdd, tau=tau: fit_long(pm, base, q, qd, qdd, tau, True),
                                        rounds=2)[0]
    # 900,000 samples in a process of its own: its peak memory is the identification's
    long = json.loads(subprocess.run([sys.executable, __file__, "--long"], check=True, capture_output=True,
                                     text=True).stdout)
    out[str(LONG)] = long["identification_s"]
    figures["identification_torque_path_s"] = out
    figures["identification_900k_s"] = long["identification_s"]
    figures["identification_900k_regressor_only_s"] = long["regressor_s"]
    figures["identification_900k_over_regressor"] = long["identification_s"] / long["regressor_s"]
    solving = json.loads(subprocess.run([sys.executable, __file__, "--long-baseline"], check=True,
                                        capture_output=True, text=True).stdout)
    figures["identification_900k_regressor_and_lstsq_s"] = solving["seconds"]
    figures["identification_900k_regressor_and_lstsq_peak_rss_mib"] = solving["peak_rss_mib"]
    figures["identification_900k_over_regressor_and_lstsq"] = long["identification_s"] / solving["seconds"]
    figures["identification_900k_peak_rss_mib"] = long["peak_rss_mib"]
    figures["identification_900k_allocated_mib"] = long["identification_allocated_mib"]
    figures["identification_900k_log_arrays_mib"] = long["log_arrays_mib"]
    figures["identification_900k_max_rel_error"] = long["max_rel_error"]


def long_identification() -> None:
    """--long: the 900,000-sample log alone (its motion, torques, then the two timed runs)."""
    import pinocchio as pin

    from harness.identify.streaming import fit_long
    from harness.identify.torque_id import true_parameters

    pm, base = _panda()
    q, qd, qdd = joint_motion(7, LONG)
    tau = _torques(pm, q, qd, qdd)
    data = pm.model.createData()

    def regressor_only():
        for k in range(LONG):
            pin.computeJointTorqueRegressor(pm.model, data, q[k], qd[k], qdd[k])

    fit = []
    t_fit, t_reg = alternately(lambda: fit.append(fit_long(pm, base, q, qd, qdd, tau, True)), regressor_only,
                               rounds=2)
    truth = base.of(true_parameters(pm, True))
    err = np.max(np.abs(fit[-1].beta - truth) / np.maximum(np.abs(truth), 1e-6 * np.abs(truth).max()))
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # the log's arrays included
    tracemalloc.start()  # what the identification itself allocates (numpy reports to tracemalloc)
    fit_long(pm, base, q, qd, qdd, tau, True)
    own = tracemalloc.get_traced_memory()[1] / 2**20
    tracemalloc.stop()
    print(json.dumps({"identification_s": t_fit, "regressor_s": t_reg, "max_rel_error": float(err),
                      "peak_rss_mib": rss, "identification_allocated_mib": own,
                      "log_arrays_mib": 4 * q.nbytes / 2**20}))


def long_baseline() -> None:
    """--long-baseline: what a Pinocchio user writes to identify the same 900,000 samples: the joint-torque
    regressor state by state into one matrix with the drives' columns (q'', q', sign q', 1 per joint),
    then numpy's least squares on the same base columns the harness solves for. Its time (the
    regressor and the solve) and peak memory, in a process of its own."""
    import pinocchio as pin

    pm, base = _panda()
    q, qd, qdd = joint_motion(7, LONG)
    tau = _torques(pm, q, qd, qdd)
    data = pm.model.createData()
    n, p = 7, 10 * 7
    t0 = time.perf_counter()
    W = np.zeros((LONG * n, p + 4 * n))
    for k in range(LONG):
        W[k * n:(k + 1) * n, :p] = pin.computeJointTorqueRegressor(pm.model, data, q[k], qd[k], qdd[k])
    rows = np.arange(LONG) * n
    for j in range(n):
        W[rows + j, p + 4 * j: p + 4 * j + 4] = np.column_stack([qdd[:, j], qd[:, j], np.sign(qd[:, j]),
                                                                  np.ones(LONG)])
    beta = np.linalg.lstsq(W[:, base.independent], tau.reshape(-1), rcond=None)[0]
    seconds = time.perf_counter() - t0
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(json.dumps({"seconds": seconds, "peak_rss_mib": rss, "unknowns": len(beta)}))


# A command's start as on an installed harness: Python's bytecode cache written and read (an
# environment that sets PYTHONDONTWRITEBYTECODE would compile every module of the harness at every
# start, about 0.18 s of `harness run kr500_rail` on a 2-core Intel Xeon)
AS_INSTALLED = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def import_time(figures: dict) -> None:
    """`import harness` over a bare interpreter: Python's own account (`-X importtime`, the cumulative
    microseconds of the `harness` line: what the import adds, the interpreter's start left out), best
    of 7; and the wall time of `python -c "import harness"` over `python -c pass`, best of 15 each in
    turns (that difference is within the noise of starting a process)."""
    def importtime() -> float:
        err = subprocess.run([sys.executable, "-X", "importtime", "-c", "import harness"], check=True, cwd=ROOT,
                             capture_output=True, text=True, env=AS_INSTALLED).stderr
        line = next(x for x in err.splitlines() if x.rstrip().endswith("| harness"))
        return int(line.split("|")[1]) / 1e3

    figures["import_ms_over_bare"] = min(importtime() for _ in range(7))

    def start(code: str):
        return lambda: subprocess.run([sys.executable, "-c", code], check=True, cwd=ROOT, env=AS_INSTALLED)

    t_import, t_bare = alternately(start("import harness"), start("pass"), rounds=15)
    figures["import_ms"] = 1e3 * t_import
    figures["import_wall_ms_over_bare"] = 1e3 * (t_import - t_bare)


CHAIN = 20


def chain_scenario(folder: Path) -> Path:
    """A 20-joint arm: aluminium cylinders end to end along x, joints alternately about z and y, every
    joint on a sum of sines; the same stages as ur5_sines (graph model, torques, identification
    validated on another motion)."""
    bodies, joints = [], []
    for k in range(CHAIN):
        x0, length = 0.3 * k, 0.3
        bodies.append(f'[[bodies]]\nname = "L{k}"\nshape = "cylinder"\nlength = {length}\nradius = 0.04\n'
                      f'density = 2700.0\ncom = [{x0 + length / 2}, 0.0, 0.0]\ne1 = [1.0, 0.0, 0.0]\n'
                      'e2 = [0.0, 1.0, 0.0]\n')
        axis = "[0.0, 0.0, 1.0]" if k % 2 == 0 else "[0.0, 1.0, 0.0]"
        parent = "world" if k == 0 else f"L{k - 1}"
        joints.append(f'[[joints]]\nname = "J{k}"\ntype = "revolute"\nparent = "{parent}"\nchild = "L{k}"\n'
                      f'point = [{x0}, 0.0, 0.0]\naxis = {axis}\n')
    (folder / "chain20.toml").write_text('[model]\nname = "chain20"\ndescription = "20 aluminium cylinders end to end"'
                                         '\n\n' + "\n".join(bodies) + "\n" + "\n".join(joints))

    def scenario(name: str, frequency: float, extra: str) -> Path:
        motion = "\n".join(f'[motion.J{k}]\ntype = "sinusoids"\noffset = 0.0\n'
                           f'sin = [[0.5, {frequency * (1.1 + 0.13 * k):.3f}]]\n'
                           f'cos = [[0.2, {frequency * (2.3 + 0.17 * k):.3f}]]\n' for k in range(CHAIN))
        path = folder / f"{name}.toml"
        path.write_text(
            f'[scenario]\ndescription = "A 20-joint arm on sums of sines"\nmodel = "chain20.toml"\n'
            'gravity = [0.0, 0.0, -9.80665]\nduration = 3.0\noutput_steps = 150\nsample_times = "all"\n\n'
            '[model_under_test]\nname = "graph"\nplugin = "graph_theory_2021"\n\n[studies.graph_theory_2021]\n\n'
            f'{extra}[simulation]\nintegrator = "RK4"\ntimestep = 0.0005\ntracking_bandwidth = 20.0\n\n{motion}'
            '\n[[gates]]\nmetric = "torques.pinocchio_vs_mujoco.max_rel_error"\nlimit = 1e-9\n'
            '\n[[gates]]\nmetric = "torques.graph_vs_pinocchio.max_rel_error"\nlimit = 1e-9\n')
        return path

    scenario("chain20_validation", 0.77, "")
    return scenario("chain20_sines", 1.0, '[torque_identification]\nvalidation = "chain20_validation.toml"\n\n')


def harness_run(scenario: Path | str, out: Path) -> tuple[float, dict]:
    t0 = time.perf_counter()
    subprocess.run([str(Path(sys.executable).with_name("harness")), "run", str(scenario), "--out", str(out),
                    "--quiet"], cwd=ROOT, check=True, capture_output=True, env=AS_INSTALLED)
    seconds = time.perf_counter() - t0
    return seconds, json.loads((out / "results.json").read_text())["run"]["timings"]


ENGINES = "import numpy, mujoco, pinocchio"  # what every run of the harness imports before its own code


def simulation_floor() -> dict:
    """kr500_rail's simulation in this process, best of ROUNDS in turns: the harness's `simulate`
    (MuJoCo's RK4 steps with the drive law called from Python at each of their 16,000 evaluations,
    and the recording's sensors), and MuJoCo's steps alone, on the same model from the same state
    with no callback (the arm then moves under gravity alone: the same arithmetic per step)."""
    import mujoco

    from harness.engines.mujoco import build_model, simulate
    from harness.runner.scenario import load_scenario

    sc = load_scenario(ROOT / "harness" / "data" / "scenarios" / "kr500_rail.toml")
    model = build_model(sc.robot, sc.gravity_W, sc.simulation)
    steps = sc.output_steps * sc.substeps

    def steps_alone():
        data = mujoco.MjData(model)
        mujoco.mj_step(model, data, steps)

    def with_drive_law():
        simulate(sc.robot, sc.gravity_W, sc.prescribed, sc.output_steps, sc.output_dt, sc.simulation)

    alone, driven = alternately(steps_alone, with_drive_law)
    return {"mujoco_steps": steps, "mujoco_steps_alone_s": alone, "simulate_with_drive_law_s": driven}


def runs(figures: dict) -> None:
    """`harness run kr500_rail` in a fresh process (best of 3, after a run that writes the bytecode
    cache), against its floor, what no code of the harness can take away: a fresh interpreter that
    imports the engines (best of 3, in turns with the runs) and MuJoCo's steps alone; and the
    simulation with the drive law, which the harness's run makes."""
    env = dict(AS_INSTALLED, MUJOCO_GL="disable")  # as the command sets it (no OpenGL context)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        best, stages, engines = np.inf, {}, np.inf
        harness_run("kr500_rail", tmp / "kr500_warm")  # the bytecode cache written, as at installation
        for k in range(3):
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-c", ENGINES], check=True, cwd=ROOT, env=env)
            engines = min(engines, time.perf_counter() - t0)
            seconds, timings = harness_run("kr500_rail", tmp / f"kr500_{k}")
            if seconds < best:
                best, stages = seconds, timings
        figures["harness_run_kr500_rail_s"] = best
        figures["harness_run_kr500_s"] = best
        figures["harness_run_kr500_rail_stages_s"] = stages
        floor = {"interpreter_and_engine_imports_s": engines, **simulation_floor()}
        figures["harness_run_kr500_floor"] = floor
        figures["harness_run_kr500_over_floor"] = best / (engines + floor["mujoco_steps_alone_s"])
        figures["harness_run_kr500_own_work_s"] = best - engines - floor["simulate_with_drive_law_s"]
        by_joints = {}
        for name, scenario, joints in (("kr500_rail", "kr500_rail", 7), ("ur5_sines", "ur5_sines", 6),
                                       ("panda_sines", "panda_sines", 7),
                                       ("chain20_sines", chain_scenario(tmp), CHAIN)):
            seconds = min(harness_run(scenario, tmp / f"{name}_{k}")[0] for k in range(2))
            by_joints[name] = {"joints": joints, "seconds": seconds}
        figures["harness_run_s_by_joints"] = by_joints


def _nothing(state, task):
    return task


def sweeps(figures: dict) -> None:
    """Trials per second of `harness sweep kr500_noise` (at the scenario's noise, the simulation
    included): 200 trials in this process; 1000 in 2 forked processes and on a Dask cluster started on
    this machine, as `harness sweep --trials 1000 --dask` runs it (its start and stop included),
    in TURNS turns, each going first in every other turn, the median of each and of their ratios
    (one run moves by 10 to 20 % on a shared 2-core machine); the cluster's start and stop alone,
    measured on trials that do nothing."""
    from harness.base.workers import LOCAL, Workers
    from harness.papers.graph_theory_2021.sweep import run_sweep
    from harness.runner.scenario import load_scenario

    noise = load_scenario(ROOT / "harness" / "data" / "scenarios" / "kr500_noise.toml")

    def rate(workers: Workers, trials: int) -> float:
        t0 = time.perf_counter()
        with workers.opened():
            run_sweep(noise, trials, workers, levels=(1.0,))
        return trials / (time.perf_counter() - t0)

    figures["sweep_trials_per_s_1_process"] = rate(Workers(1), 200)
    turns = []
    for k in range(TURNS):  # which goes first alternates, so that a drift of the machine favours neither
        if k % 2:
            b, a = rate(Workers(dask=LOCAL), 1000), rate(Workers(2), 1000)
        else:
            a, b = rate(Workers(2), 1000), rate(Workers(dask=LOCAL), 1000)
        turns.append((a, b))
    figures["sweep_trials_per_s_2_process"] = float(np.median([a for a, _ in turns]))
    figures["sweep_trials_per_s_dask_local"] = float(np.median([b for _, b in turns]))
    figures["sweep_dask_over_jobs2_turns"] = [b / a for a, b in turns]
    t0 = time.perf_counter()
    Workers(dask=LOCAL).map(dict, (), _nothing, range(2))
    figures["dask_local_cluster_start_and_stop_s"] = time.perf_counter() - t0
    figures["sweep_dask_over_jobs2"] = (figures["sweep_trials_per_s_dask_local"]
                                        / figures["sweep_trials_per_s_2_process"])
    figures["sweep_dask_over_jobs2_median_of_turns"] = float(np.median(figures["sweep_dask_over_jobs2_turns"]))


LOG_RUNS = {"panda": "panda_gaz2019", "tx40": "tx40", "solo12": "solo12_standing_log"}  # plain_lstsq.py's robot
# -> the built-in scenario


def log_runs(figures: dict, rounds: int = 3) -> None:
    """`harness run panda_gaz2019` and `harness run tx40` as shipped, each against a plain least-squares
    script on the same log (benchmarks/plain_lstsq.py: read, condition, regressor, least squares,
    held-out error), each in a fresh process, in turns, best of `rounds` (after a run that writes the
    bytecode cache); the run's stages from its best run, both held-out figures, and the peak resident
    memory of each (the largest of its turns)."""
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for robot, scenario in LOG_RUNS.items():
            harness_run(scenario, tmp / f"{robot}_warm")
            best, plain, stages, said, peak, plain_peak = np.inf, np.inf, {}, "", 0, 0
            for k in range(rounds):
                seconds, timings, rss = harness_run_measured(scenario, tmp / f"{robot}_{k}")
                peak = max(peak, rss)
                if seconds < best:
                    best, stages = seconds, timings
                seconds, said, rss = _timed([sys.executable, str(ROOT / "benchmarks" / "plain_lstsq.py"), robot])
                plain, plain_peak = min(plain, seconds), max(plain_peak, rss)
            held_out = _held_out(json.loads((tmp / f"{robot}_0" / "results.json").read_text()))
            figures[f"log_run_{robot}_s"] = best
            figures[f"log_run_{robot}_stages_s"] = stages
            figures[f"log_run_{robot}_held_out"] = held_out
            figures[f"log_run_{robot}_peak_rss_mib"] = peak
            figures[f"log_run_{robot}_plain_lstsq_s"] = plain
            figures[f"log_run_{robot}_plain_lstsq_said"] = said
            figures[f"log_run_{robot}_plain_lstsq_peak_rss_mib"] = plain_peak
            figures[f"log_run_{robot}_over_plain_lstsq"] = best / plain


def _held_out(results: dict) -> dict[str, float]:
    """A log run's held-out errors by fit: a fixed base's relative torque errors; a floating base's log's RMS of
    its rows' relative errors (harness/stages/floating_log.py)."""
    if "log_identification" in results:
        return results["log_identification"]["validation_rel_error"]
    judged = results["floating_log"]["judged"]
    return {"least squares": judged["least_squares"]["measured"]["rms_rel_error"],
            "consistent": judged["consistent"]["measured"]["rms_rel_error"]}


def _descendants(pid: int) -> list[int]:
    """pid and every process it started that still runs (/proc/<pid>/task/<tid>/children)."""
    out, todo = [], [pid]
    while todo:
        p = todo.pop()
        out.append(p)
        for task in Path(f"/proc/{p}/task").glob("*/children"):
            try:
                todo.extend(int(c) for c in task.read_text().split())
            except OSError:
                pass
    return out


def _high_water_mib(pid: int) -> float:
    try:
        line = next(x for x in Path(f"/proc/{pid}/status").read_text().splitlines() if x.startswith("VmHWM"))
    except (OSError, StopIteration):  # the process is ending
        return 0.0
    return int(line.split()[1]) / 1024


def _timed(command: list[str]) -> tuple[float, str, float]:
    """A command in a fresh process: its wall seconds, its output, and its peak resident memory (MiB):
    the largest high-water mark (VmHWM) of the command's process and of each process it starts (`harness
    run` works in a process it forks), read from /proc every 5 ms while they run. (The kernel's
    ru_maxrss of a child counts the parent's pages at the fork: this process's, which has grown by the
    benchmarks before.)"""
    t0 = time.perf_counter()
    with tempfile.TemporaryFile("w+") as out:
        child = subprocess.Popen(command, cwd=ROOT, stdout=out, stderr=subprocess.DEVNULL, text=True,
                                 env=AS_INSTALLED)
        peak = 0.0
        while child.poll() is None:
            peak = max([peak, *(_high_water_mib(p) for p in _descendants(child.pid))])
            time.sleep(0.005)
        seconds = time.perf_counter() - t0
        out.seek(0)
        said = out.read().strip()
    if child.returncode:
        raise subprocess.CalledProcessError(child.returncode, command, said)
    return seconds, said, peak


def harness_run_measured(scenario: Path | str, out: Path) -> tuple[float, dict, float]:
    """`harness run` in a fresh process: its wall seconds, its stages' (`run.timings`) and its peak
    resident memory (MiB)."""
    seconds, _, peak = _timed([str(Path(sys.executable).with_name("harness")), "run", str(scenario), "--out",
                               str(out), "--quiet"])
    return seconds, json.loads((out / "results.json").read_text())["run"]["timings"], peak


def long_log_run(figures: dict, hours: float) -> None:
    """`harness run` of `hours` of a 7-joint arm at 1 kHz (benchmarks/long_log.py: panda_gaz2019's
    conditioning and split, without FIGAROH and the refinement) in a fresh process: seconds, stages and
    peak resident memory (`log_run_<hours>h_*`)."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import long_log

    with tempfile.TemporaryDirectory() as tmp:
        scenario = long_log.write(Path(tmp), hours)
        rows = int(hours * 3600 * long_log.RATE)
        seconds, timings, peak = harness_run_measured(scenario, Path(tmp) / "out")
    key = f"log_run_{hours:g}h"
    figures[f"{key}_rows"] = rows
    figures[f"{key}_s"] = seconds
    figures[f"{key}_stages_s"] = timings
    figures[f"{key}_peak_rss_mib"] = peak
    print(f"harness run of {hours:g} h at 1 kHz ({rows} rows, 7 joints): {seconds:.1f} s, peak {peak:.0f} MiB")
    for k, v in timings.items():
        print(f"    {k:<80} {v:6.2f} s")


def added_to_benchmark(figures: dict) -> None:
    """`figures` written into reports/benchmark.json beside what the last full run wrote there (a run on
    another machine is not mixed in: the file is started again)."""
    out = ROOT / "reports" / "benchmark.json"
    machine = _machine()
    previous = json.loads(out.read_text()) if out.exists() else {}
    merged = previous if previous.get("machine") == machine else {"machine": machine}
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps({**merged, **figures}, indent=2) + "\n")
    print(f"added {', '.join(figures)} to {out}")


def main() -> None:
    figures: dict = {"machine": _machine()}
    torques(figures)
    graph_from_joint_coordinates(figures)
    identification_scaling(figures)
    import_time(figures)
    runs(figures)
    log_runs(figures)
    sweeps(figures)
    out = ROOT / "reports" / "benchmark.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(figures, indent=2) + "\n")
    t = figures["torques_us_per_state"]
    print(f"machine: {figures['machine']}")
    print(f"joint torques, {N} states of kr500 (us per state): graph model batched {t['graph_batched']:.2f} "
          f"(as a plugin, with its forward kinematics: {t['graph_plugin_with_kinematics']:.2f}), "
          f"Pinocchio rnea {t['pinocchio_rnea']:.2f}, MuJoCo mj_inverse {t['mujoco_mj_inverse']:.2f}; "
          f"graph / Pinocchio {figures['torques_ratio_graph_over_pinocchio']:.2f}")
    print(f"joint torques from (q, q', q'') alone, {N} states, like for like (us per state; ratios: the graph "
          "model over Pinocchio's rnea per state from Python, over Pinocchio's C++ rneaInParallel on 1 thread):")
    for name, v in figures["torques_graph_from_q"].items():
        print(f"    {name:<6} ({v['joints']} joints): graph {v['graph_us']:.2f}, Pinocchio loop "
              f"{v['pinocchio_loop_us']:.2f}, Pinocchio batch {v['pinocchio_batch_1_thread_us']:.2f}; "
              f"{v['over_loop']:.2f} x loop, "
              f"{v['over_batch']:.2f} x batch (agree to {v['max_rel_difference']:.1e})")
    sc = figures["torques_graph_from_q_scaling_panda"]
    print("    graph model, Panda, us per state by states: " + ", ".join(
        f"{k}: {v['us_per_state']:.2f} ({v['scratch_mib']:.0f} MiB scratch)" for k, v in sc.items())
        + f"; log-log slope {figures['torques_graph_from_q_slope']:.3f}")
    print(f"force-path identification of {N} samples: {figures['identification_10000_samples_s']:.3f} s")
    print("joint-torque identification with friction, Panda (s): "
          + ", ".join(f"{k} samples {v:.2f}" for k, v in figures["identification_torque_path_s"].items())
          + f"; at {LONG}: {figures['identification_900k_over_regressor']:.2f} x Pinocchio's regressor alone "
            f"({figures['identification_900k_regressor_only_s']:.2f} s), peak memory "
            f"{figures['identification_900k_peak_rss_mib']:.0f} MiB (the log's arrays "
            f"{figures['identification_900k_log_arrays_mib']:.0f} MiB, the identification's own "
            f"{figures['identification_900k_allocated_mib']:.0f} MiB); "
            f"{figures['identification_900k_over_regressor_and_lstsq']:.3f} x a Pinocchio user's regressor loop and "
            f"least squares ({figures['identification_900k_regressor_and_lstsq_s']:.1f} s, peak "
            f"{figures['identification_900k_regressor_and_lstsq_peak_rss_mib']:.0f} MiB)")
    print(f"import harness: {figures['import_ms_over_bare']:.1f} ms over a bare interpreter (-X importtime; "
          f"a process that imports it: {figures['import_ms']:.0f} ms in all)")
    print(f"harness run kr500_rail, fresh process: {figures['harness_run_kr500_rail_s']:.2f} s")
    for k, v in figures["harness_run_kr500_rail_stages_s"].items():
        print(f"    {k:<55} {v:6.2f} s")
    fl = figures["harness_run_kr500_floor"]
    print("    its floor: a fresh interpreter importing numpy, mujoco and pinocchio "
          f"{fl['interpreter_and_engine_imports_s']:.2f} s, MuJoCo's {fl['mujoco_steps']} steps alone "
          f"{fl['mujoco_steps_alone_s']:.3f} s: the run is "
          f"{figures['harness_run_kr500_over_floor']:.2f} x its floor; with the drive law the simulation takes "
          f"{fl['simulate_with_drive_law_s']:.3f} s, and the rest of the run "
          f"{figures['harness_run_kr500_own_work_s']:.2f} s")
    for k, v in figures["harness_run_s_by_joints"].items():
        print(f"harness run {k} ({v['joints']} joints): {v['seconds']:.2f} s")
    print_log_runs(figures)
    print(f"sweep kr500_noise: {figures['sweep_trials_per_s_1_process']:.1f} trials/s with 1 process, "
          f"{figures['sweep_trials_per_s_2_process']:.1f} with 2, {figures['sweep_trials_per_s_dask_local']:.1f} on a "
          f"local Dask cluster (which takes {figures['dask_local_cluster_start_and_stop_s']:.1f} s to start and stop); "
          f"Dask over 2 processes {figures['sweep_dask_over_jobs2']:.2f} (turn by turn: "
          + " / ".join(f"{r:.2f}" for r in figures["sweep_dask_over_jobs2_turns"])
          + f"; their median {figures['sweep_dask_over_jobs2_median_of_turns']:.2f})")
    print(f"wrote {out}")


def print_log_runs(figures: dict) -> None:
    for robot, scenario in LOG_RUNS.items():
        held = figures[f"log_run_{robot}_held_out"]
        print(f"harness run {scenario}, fresh process: {figures[f'log_run_{robot}_s']:.2f} s, peak "
              f"{figures[f'log_run_{robot}_peak_rss_mib']:.0f} MiB (held out: least squares "
              f"{100 * held['least squares']:.2f} %, consistent {100 * held['consistent']:.2f} %); a plain "
              f"least-squares script {figures[f'log_run_{robot}_plain_lstsq_s']:.2f} s, peak "
              f"{figures[f'log_run_{robot}_plain_lstsq_peak_rss_mib']:.0f} MiB "
              f"({figures[f'log_run_{robot}_plain_lstsq_said']}): {figures[f'log_run_{robot}_over_plain_lstsq']:.1f} x")
        stages = figures[f"log_run_{robot}_stages_s"]
        total = sum(stages.values())
        for k, v in stages.items():
            print(f"    {k:<80} {v:6.2f} s {100 * v / total:5.1f} %")


def _machine() -> str:
    import os
    import platform

    cpu = next((line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                if line.startswith("model name")), platform.processor()) if Path("/proc/cpuinfo").exists() else ""
    return f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}"


if __name__ == "__main__":
    if "--long" in sys.argv:
        long_identification()
    elif "--long-baseline" in sys.argv:
        long_baseline()
    elif "--long-log" in sys.argv:  # hours of a 7-joint arm's log: time and peak memory, added to benchmark.json
        long_figures: dict = {}
        long_log_run(long_figures, float(sys.argv[sys.argv.index("--long-log") + 1]))
        added_to_benchmark(long_figures)
    elif "--log-runs" in sys.argv:  # the log run against its plain script alone (reports/benchmark.json untouched)
        log_figures: dict = {"machine": _machine()}
        log_runs(log_figures)
        print_log_runs(log_figures)
    else:
        main()
