"""The Staubli TX40 (harness/data/logs/staubli_tx40: FIGAROH's published log of a real arm, motor side,
coupled wrist, quantised encoders) judged on an independent conditioning: run from the project root with
`.venv/bin/python benchmarks/tx40.py` (about a minute; it reads the published config with PyYAML and
fits FIGAROH: `pip install -e ".[figaroh]"`, which brings both).

1. `harness run` of the built-in scenarios, each timed in a fresh process: tx40 (the whole run, its
   conditioning tuned by hand), the same at the harness's conditioning defaults (no cutoff, trim or
   decimation given: a copy of tx40.toml without them), the same with each motor's friction law chosen
   by the data (its [friction_law] removed), and tx40_motion (the motion alone, 0.1-7.5 s, every choice
   the data's).
2. An independent conditioning of the published files, sharing no code with the harness's: motor
   angles and torques mapped to the joints by hand (the log's README: q_m = N q, N = diag(32, 32, 45,
   -48, 45, 32) with N[6, 5] = 32; q2 -= pi/2, q3 += pi/2; tau = N^T tau_m), smoothed by a 40 ms cubic
   Savitzky-Golay filter (scipy.signal.savgol_filter, derivatives from it) over the whole file, kept at
   500 Hz, 40 ms from either end. Two test sets, as the scenarios split: the whole run's last 30 %
   (t >= 6.3 s) and the motion's (0.1-7.5 s: t >= 5.28 s).
3. On those rows, the relative torque error ||tau_model - tau_measured|| / ||tau_measured|| over all
   samples and joints of:
   - each harness run's exported model, through `harness.identified_model` (joint side, drives included);
   - a plain least squares fitted on the same conditioning's training rows (t before the split, less the
     filter's 20 ms reach): Pinocchio's joint-torque regressor of the URDF (60 columns) and, per motor,
     rotor inertia N q'', viscous N q', Coulomb tanh(N q' / (0.02 |N_kk|)) and offset, each reaching the
     joints through N^T (24 columns: the same columns as the harness's model);
   - the published drive parameters (source/TX40_config.yaml) with the URDF's rigid bodies, as FIGAROH
     writes their torques (figaroh/tools/randomdata.py: per joint fv q' + fs sign(q') + Ia q'' + off;
     motor 6's Iam6, fvm6 times the other wrist joint's velocity and fsm6 sign(q5' + q6')), and the same
     with each sign(v) made tanh(v / 0.02 rad/s) (a sharp sign chatters on the velocity's noise at
     rest); and as published, on every row of the run (the log's README: 15 %);
   - FIGAROH's least squares (its base parameters, per-joint friction and rotor inertia) and its physical
     fit on the same training rows, through harness/adapters/figaroh.py.
Writes reports/tx40.json and prints a table.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from judging import figaroh_fits, rel  # noqa: E402

LOG = ROOT / "harness" / "data" / "logs" / "staubli_tx40"
SCENARIOS = ROOT / "harness" / "data" / "scenarios"
RATE = 5000.0  # Hz, the config's ts = 0.0002 s
N = np.diag([32.0, 32.0, 45.0, -48.0, 45.0, 32.0])
N[5, 4] = 32.0  # motor 6 turns with q5 + q6
ZERO = np.array([0.0, -np.pi / 2, np.pi / 2, 0.0, 0.0, 0.0])  # q = N^-1 q_m + ZERO is the URDF's zero
GRAVITY = 9.80665  # m/s^2 along -z of base_link, as the scenarios
SG_WINDOW = 201  # samples: 40 ms at 5 kHz
KEEP_EVERY = 10  # 500 Hz
V_C = 0.02  # rad/s at the joints: the plain least squares' Coulomb smoothing (the model file's)
SPLITS = {"whole": (0.0, 6.3, 9.0), "motion": (0.1, 5.28, 7.5)}  # (start, split, end) s


def conditioned():
    """The independent conditioning (the module's docstring, 2): t, q, q', q'', tau at the joints."""
    import pandas as pd
    from scipy.signal import savgol_filter

    q_m = pd.read_csv(LOG / "data" / "pos_read_data.csv").to_numpy(float)
    tau_m = pd.read_csv(LOG / "data" / "curr_data.csv").to_numpy(float)
    q = q_m @ np.linalg.inv(N).T + ZERO
    tau = tau_m @ N

    def sg(x, deriv):
        return savgol_filter(x, SG_WINDOW, 3, deriv=deriv, delta=1 / RATE, axis=0)

    rows = np.arange(SG_WINDOW, len(q) - SG_WINDOW, KEEP_EVERY)
    t = np.arange(len(q))[rows] / RATE
    return t, sg(q, 0)[rows], sg(q, 1)[rows], sg(q, 2)[rows], sg(tau, 0)[rows]


def rigid_regressor(q, qd, qdd) -> np.ndarray:
    """Pinocchio's joint-torque regressor of the published URDF, (samples, 6, 60)."""
    import pinocchio as pin

    model = pin.buildModelFromUrdf(str(LOG / "urdf" / "tx40_mdh_modified.urdf"))
    model.gravity.linear = np.array([0.0, 0.0, -GRAVITY])
    data = model.createData()
    return np.stack([pin.computeJointTorqueRegressor(model, data, q[k], qd[k], qdd[k]).copy()
                     for k in range(len(q))])


def plain_columns(Y_rigid, qd, qdd) -> np.ndarray:
    """The rigid regressor and each motor's four drive columns through N^T: (samples * 6, 84)."""
    qd_m, qdd_m = qd @ N.T, qdd @ N.T
    motor = np.stack([qdd_m, qd_m, np.tanh(qd_m / (V_C * np.abs(np.diag(N)))), np.ones_like(qd_m)], -1)
    drive = np.einsum("kj,tkc->tjkc", N, motor).reshape(len(qd), 6, 24)  # column (k, c) at joint j: N_kj
    return np.concatenate([Y_rigid, drive], axis=2).reshape(-1, 84)


def published(Y_rigid, qd, qdd, coulomb=np.sign) -> np.ndarray:
    """The published drive parameters' torques, as FIGAROH writes them (the module's docstring); `coulomb`
    the law of their Coulomb terms (FIGAROH's: a sign)."""
    import yaml

    p = yaml.safe_load((LOG / "source" / "TX40_config.yaml").read_text())["identification"]["robot_params"][0]
    import pinocchio as pin

    model = pin.buildModelFromUrdf(str(LOG / "urdf" / "tx40_mdh_modified.urdf"))
    theta = np.concatenate([model.inertias[j].toDynamicParameters() for j in range(1, model.njoints)])
    tau = Y_rigid @ theta
    tau += np.asarray(p["fv"]) * qd + np.asarray(p["fs"]) * coulomb(qd) + np.asarray(p["Ia"]) * qdd
    tau += np.asarray(p["offset"])
    wrist = p["fsm6"] * coulomb(qd[:, 4] + qd[:, 5])
    tau[:, 4] += (p["Iam6"] + p["fvm6"]) * qd[:, 5] + wrist
    tau[:, 5] += (p["Iam6"] + p["fvm6"]) * qd[:, 4] + wrist
    return tau


def drive_terms(model) -> dict:
    """Each motor's identified law reflected to its own joint (rotor inertia I N_kk^2, viscous f_v N_kk^2,
    Coulomb f_c |N_kk|), beside the published per-joint values; motor 6's own (its coupling's) beside
    the published Iam6, fvm6 and fsm6 (at the joints, through N_66 = 32)."""
    import yaml

    p = yaml.safe_load((LOG / "source" / "TX40_config.yaml").read_text())["identification"]["robot_params"][0]
    r = np.diag(N)
    out = {}
    for k, f in enumerate(model.spec.frictions):
        out[model.spec.transmission.motors[k]] = {
            "rotor_inertia": [f.armature * r[k] ** 2, p["Ia"][k]], "viscous": [f.viscous * r[k] ** 2, p["fv"][k]],
            "coulomb": [f.coulomb * abs(r[k]), p["fs"][k]]}
    out["motor_6 on the coupling"] = {"rotor_inertia": [out["motor_6"]["rotor_inertia"][0], p["Iam6"]],
                                      "viscous": [out["motor_6"]["viscous"][0], p["fvm6"]],
                                      "coulomb": [out["motor_6"]["coulomb"][0], p["fsm6"]]}
    return out


def harness_runs(folder: Path) -> dict:
    """The three runs (the module's docstring, 1), each `harness run` in a fresh process: output folder,
    exit status, wall seconds, and the run's own held-out figure."""
    tuned = tomllib.loads((SCENARIOS / "tx40.toml").read_text())
    defaults = folder / "tx40_defaults.toml"
    text = (SCENARIOS / "tx40.toml").read_text().replace('"../', f'"{SCENARIOS.parent}/')
    for key in ("cutoff", "trim", "decimate"):
        assert key in tuned["data"]
        text = "\n".join(line for line in text.splitlines() if not line.startswith(f"{key} = "))
    defaults.write_text(text + "\n")
    law = folder / "tx40_law_chosen.toml"  # the tuned conditioning, each motor's law chosen by the data
    law.write_text((SCENARIOS / "tx40.toml").read_text().replace('"../', f'"{SCENARIOS.parent}/')
                   .replace("[friction_law]\nchoose = false\n", ""))
    out = {}
    for name, scenario in (("tuned", SCENARIOS / "tx40.toml"), ("defaults", defaults), ("law_chosen", law),
                           ("motion", SCENARIOS / "tx40_motion.toml")):
        t0 = time.perf_counter()
        status = subprocess.run([str(Path(sys.executable).parent / "harness"), "run", str(scenario), "--out",
                                 str(folder / name), "--quiet"], cwd=ROOT).returncode
        seconds = time.perf_counter() - t0
        results = json.loads((folder / name / "results.json").read_text())
        out[name] = {"folder": folder / name, "exit": status, "seconds": seconds,
                     "own_validation_rel_error": results["log_identification"]["validation_rel_error"]["consistent"],
                     "conditioning_defaults": results["data"]["conditioning"]["defaults"]}
    return out


def main() -> None:
    import harness

    t, q, qd, qdd, tau = conditioned()
    Y = rigid_regressor(q, qd, qdd)
    reach = SG_WINDOW // 2 / RATE
    table: dict[str, dict] = {}
    with tempfile.TemporaryDirectory() as tmp:
        runs = harness_runs(Path(tmp))
        for split, (start, at, end) in SPLITS.items():
            train = (t >= start) & (t < at - reach)
            test = (t >= at) & (t <= end)
            row = table.setdefault(split, {"test_rows": int(test.sum()), "t_test": [at, end]})
            for name, run in runs.items():
                model = harness.identified_model(run["folder"])
                row[f"harness_{name}"] = rel(model.inverse_dynamics(q[test], qd[test], qdd[test]), tau[test])
            x = np.linalg.lstsq(plain_columns(Y[train], qd[train], qdd[train]), tau[train].ravel(), rcond=None)[0]
            row["plain_least_squares"] = rel((plain_columns(Y[test], qd[test], qdd[test]) @ x).reshape(-1, 6),
                                             tau[test])
            row["published_drive_parameters"] = rel(published(Y[test], qd[test], qdd[test]), tau[test])
            row["published_drive_parameters_smooth_coulomb"] = rel(
                published(Y[test], qd[test], qdd[test], lambda v: np.tanh(v / V_C)), tau[test])
            fits = figaroh_fits(ROOT / "harness" / "data" / "models" / "tx40.toml", GRAVITY, q[train], qd[train],
                                qdd[train], tau[train])
            for kind, fitted in fits.items():
                row[f"figaroh_{kind}"] = fitted if isinstance(fitted, str) else \
                    rel(fitted.inverse_dynamics(q[test], qd[test], qdd[test]), tau[test])
        figures = {"splits": table, "published_drive_parameters_every_row": rel(published(Y, qd, qdd), tau),
                   "drive_terms": drive_terms(harness.identified_model(runs["tuned"]["folder"])),
                   "runs": {name: {k: v for k, v in run.items() if k != "folder"} for name, run in runs.items()}}
    (ROOT / "reports").mkdir(exist_ok=True)
    (ROOT / "reports" / "tx40.json").write_text(json.dumps(figures, indent=2, default=float) + "\n")
    columns = [k for k in table["whole"] if k not in ("test_rows", "t_test")]
    print(f"{'held-out relative torque error':40s}" + "".join(f"{s:>22s}" for s in table))
    for c in columns:
        print(f"{c:40s}" + "".join(f"{table[s][c]:22.2%}" if isinstance(table[s][c], float) else
                                   f"{'failed':>22s}" for s in table))
    for c in columns:
        if isinstance(table["whole"][c], str):
            print(f"{c}: {table['whole'][c]}")
    print("drive terms at the joints, harness (tx40) / published:")
    for motor, terms in figures["drive_terms"].items():
        print(f"  {motor:24s}" + "".join(f"{k} {a:.3g} / {b:.3g}   " for k, (a, b) in terms.items()))
    print(f"published drive parameters on every row of the run (not fitted to a split): "
          f"{figures['published_drive_parameters_every_row']:.2%}")
    for name, run in figures["runs"].items():
        print(f"harness run {name}: exit {run['exit']}, {run['seconds']:.1f} s, its own held-out figure "
              f"{run['own_validation_rel_error']:.2%}")


if __name__ == "__main__":
    main()
