"""Benchmark: run from the project root with `.venv/bin/python benchmarks/bench.py`.

Measures on the machine at hand, in one run so that the ratios hold on a noisy machine:
- joint torques for 10,000 states of kr500: the graph model batched, Pinocchio `rnea` and MuJoCo
  `mj_inverse` called per state from Python (microseconds per state, ratios);
- identification, assembly and solve, for 10,000 samples (seconds);
- `harness run kr500_rail` end to end in a fresh process (seconds, and its stages);
- `harness sweep` throughput on kr500_noise with 1 and 2 processes (trials per second).
Writes reports/benchmark.json and prints a table.
"""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from harness.bench import record  # noqa: E402
from harness.engines.mujoco import build_model as build_mujoco  # noqa: E402
from harness.engines.pinocchio import build_model as build_pinocchio  # noqa: E402
from harness.measurement import Measurement  # noqa: E402
from harness.papers.graph_theory_2021.dynamics import build_graph_model  # noqa: E402
from harness.papers.graph_theory_2021.inverse import inverse_dynamics  # noqa: E402
from harness.papers.graph_theory_2021.model import make as make_graph_model  # noqa: E402
from harness.papers.graph_theory_2021.solve import identify  # noqa: E402
from harness.papers.graph_theory_2021.sweep import run_sweep  # noqa: E402
from harness.scenario import load_scenario  # noqa: E402

N = 10_000


def best_of(f, repeat=3):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        f()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    figures = {}
    # 10,000 states of kr500 with every joint moving: their body kinematics come from MuJoCo
    sc = load_scenario(ROOT / "scenarios" / "kr500_all_joints.toml")
    sc = dataclasses.replace(sc, duration=20.0, output_steps=N - 1, sample_times=np.linspace(0, 20.0, N))
    rec = record(sc)
    spec = sc.robot
    model = build_graph_model(spec, sc.gravity_W)
    cols = [rec.joint_index(j) for j in spec.joint_names]
    q, qd, qdd = rec.q[:, cols], rec.qd[:, cols], rec.qdd[:, cols]

    t_graph = best_of(lambda: inverse_dynamics(spec, model, rec))
    plugin = make_graph_model(spec, sc.gravity_W)  # as a model under test: (q, q', q'') in, kinematics its own
    t_plugin = best_of(lambda: plugin.inverse_dynamics(q, qd, qdd))
    pm = build_pinocchio(spec, sc.gravity_W)
    data = pm.model.createData()
    qq, vv, aa = (np.zeros((N, pm.model.nq)) for _ in range(3))
    qq[:, pm.q_index], vv[:, pm.q_index], aa[:, pm.q_index] = q, qd, qdd

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

    t_pin, t_mj = best_of(pinocchio_loop), best_of(mujoco_loop)
    figures["torques_us_per_state"] = {
        "graph_batched": 1e6 * t_graph / N,
        "graph_plugin_with_kinematics": 1e6 * t_plugin / N,
        "pinocchio_rnea": 1e6 * t_pin / N,
        "mujoco_mj_inverse": 1e6 * t_mj / N,
    }
    figures["torques_ratio_graph_over_pinocchio"] = t_graph / t_pin

    rows = np.arange(N)
    t_id = best_of(lambda: identify(model, rec, rows, Measurement(), with_system=False), repeat=2)
    figures["identification_10000_samples_s"] = t_id

    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        subprocess.run(
            [str(Path(sys.executable).with_name("harness")), "run", "kr500_rail", "--out", tmp, "--quiet"],
            cwd=ROOT,
            check=True,
            capture_output=True,
        )
        figures["harness_run_kr500_rail_s"] = time.perf_counter() - t0
        figures["harness_run_kr500_rail_stages_s"] = json.loads((Path(tmp) / "results.json").read_text())["run"][
            "timings"
        ]

    noise = load_scenario(ROOT / "scenarios" / "kr500_noise.toml")
    for jobs in (1, 2):
        t0 = time.perf_counter()
        run_sweep(noise, 100, jobs=jobs, levels=(1.0,))
        figures[f"sweep_trials_per_s_{jobs}_process"] = 100 / (time.perf_counter() - t0)

    out = ROOT / "reports" / "benchmark.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(figures, indent=2) + "\n")
    t = figures["torques_us_per_state"]
    print(
        f"joint torques, {N} states of kr500 (us per state): graph model batched {t['graph_batched']:.2f} "
        f"(as a plugin, with its forward kinematics: {t['graph_plugin_with_kinematics']:.2f}), "
        f"Pinocchio rnea {t['pinocchio_rnea']:.2f}, MuJoCo mj_inverse {t['mujoco_mj_inverse']:.2f}"
    )
    print(f"identification of {N} samples: {t_id:.3f} s")
    print(f"harness run kr500_rail, fresh process: {figures['harness_run_kr500_rail_s']:.2f} s")
    for k, v in figures["harness_run_kr500_rail_stages_s"].items():
        print(f"    {k:<55} {v:6.2f} s")
    print(
        f"sweep kr500_noise: {figures['sweep_trials_per_s_1_process']:.1f} trials/s with 1 process, "
        f"{figures['sweep_trials_per_s_2_process']:.1f} with 2"
    )
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
