"""The floor a log run is timed against: a plain least-squares identification of a built-in log
written directly with numpy, scipy and Pinocchio, as a user would without the harness.

`panda` (the default): the Panda's log (harness/data/logs/panda_gaz2019). It drops the rows its driver
repeated whole, splits the log at 70 % of its duration, conditions each part on its own as the data's
README does (1 kHz grid, 10 Hz zero-phase Butterworth of order 4, accelerations from the filtered
velocities, 0.3 s trimmed at each end, every 10th sample), builds Pinocchio's joint-torque regressor
with each joint's rotor inertia, viscous, smooth Coulomb (tanh(q'/0.03)) and offset columns.

`tx40`: the Staubli TX40's published files (harness/data/logs/staubli_tx40: motor angles and motor
torques in two files, no time column, 5 kHz), mapped to the joints by hand as its README gives the
coupled wrist (q_m = N q + offset, tau = N^T tau_m), split at 70 % of the run and each part conditioned
as the built-in scenario is (20 Hz zero-phase Butterworth of order 4, derivatives by central
differences of the filtered angles, 20 ms trimmed, every 10th sample); Pinocchio's regressor of the
published URDF with each motor's rotor inertia, viscous, smooth Coulomb (tanh(q'_m / (0.02 |N_kk|)))
and offset columns reaching the joints through N^T.

`solo12`: Solo12's standing bench log (harness/data/logs/solo12_standing_bench: a floating base, its feet's
forces): Pinocchio's free-flyer regressor, the feet's forces through their frames' Jacobians (`solo12`).

Each fits by least squares and prints its held-out relative torque error ||tau_pred - tau|| / ||tau||
on the last 30 %:

    .venv/bin/python benchmarks/plain_lstsq.py [panda | tx40]

Nothing of the harness is imported, so that its time is the work itself: benchmarks/bench.py runs it
and `harness run panda_gaz2019` (`harness run tx40`) in turns, each in a fresh process
(`log_run_panda_over_plain_lstsq`, `log_run_tx40_over_plain_lstsq`).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
from scipy.signal import butter, sosfiltfilt

LOGS = Path(__file__).resolve().parents[1] / "harness" / "data" / "logs"
LOG = LOGS / "panda_gaz2019" / "log.csv"
JOINTS = [f"panda_joint{k}" for k in range(1, 8)]
RATE, CUTOFF, ORDER, DECIMATE, TRIM, V_C = 1000.0, 10.0, 4, 10, 0.3, 0.03


def urdf() -> str:
    from importlib.metadata import distribution

    root = Path(distribution("example-robot-data").locate_file("cmeel.prefix/share/example-robot-data/robots"))
    return str(root / "panda_description" / "urdf" / "panda.urdf")


def conditioned(t, q, qd, tau):
    grid = np.arange(t[0], t[-1], 1.0 / RATE)
    q, qd, tau = (np.column_stack([np.interp(grid, t, x[:, j]) for j in range(x.shape[1])]) for x in (q, qd, tau))
    sos = butter(ORDER, CUTOFF, fs=RATE, output="sos")
    q, qd, tau = (sosfiltfilt(sos, x, axis=0) for x in (q, qd, tau))
    qdd = np.gradient(qd, 1.0 / RATE, axis=0)
    k = int(TRIM * RATE)
    rows = np.arange(k, len(grid) - k, DECIMATE)
    return q[rows], qd[rows], qdd[rows], tau[rows]


def regressor(model, data, q, qd, qdd):
    W = np.vstack([pin.computeJointTorqueRegressor(model, data, a, b, c) for a, b, c in zip(q, qd, qdd, strict=True)])
    N, n = qd.shape
    F = np.zeros((N, n, 4 * n))
    for j in range(n):
        F[:, j, 4 * j: 4 * j + 4] = np.column_stack([qdd[:, j], qd[:, j], np.tanh(qd[:, j] / V_C), np.ones(N)])
    return np.hstack([W, F.reshape(N * n, -1)])


def panda_spans():
    """The Panda's log, its rows repeated whole (held) dropped, split at 70 % of its duration, each part
    conditioned on its own: [(q, q', q'', tau) of the training part, of the held-out part]."""
    log = np.loadtxt(LOG, delimiter=",", skiprows=1)
    log = log[np.r_[True, np.any(log[1:, 1:] != log[:-1, 1:], axis=1)]]  # a row repeated whole: held
    t, q, qd, tau = log[:, 0], log[:, 1:8], log[:, 8:15], log[:, 15:22]
    split = t[0] + 0.7 * (t[-1] - t[0])
    return [conditioned(t[side], q[side], qd[side], tau[side]) for side in (t < split, t >= split)]


def panda_model():
    """Pinocchio's model of the Panda's URDF with its fingers locked, and its data."""
    full = pin.buildModelFromUrdf(urdf())
    locked = [full.getJointId(name) for name in ("panda_finger_joint1", "panda_finger_joint2")]
    model = pin.buildReducedModel(full, locked, pin.neutral(full))
    return model, model.createData()


def panda() -> float:
    model, data = panda_model()
    (q1, qd1, qdd1, tau1), (q2, qd2, qdd2, tau2) = panda_spans()
    theta = np.linalg.lstsq(regressor(model, data, q1, qd1, qdd1), tau1.ravel(), rcond=None)[0]
    predicted = regressor(model, data, q2, qd2, qdd2) @ theta
    error = float(np.linalg.norm(predicted - tau2.ravel()) / np.linalg.norm(tau2))
    print(f"plain least squares, Panda, held-out relative torque error: {100 * error:.2f} %")
    return error


TX40 = LOGS / "staubli_tx40"
TX40_RATE, TX40_CUTOFF, TX40_TRIM, TX40_V_C = 5000.0, 20.0, 0.02, 0.02
TX40_N = np.diag([32.0, 32.0, 45.0, -48.0, 45.0, 32.0])
TX40_N[5, 4] = 32.0  # motor 6 turns with q5 + q6
TX40_ZERO = np.array([0.0, -np.pi / 2, np.pi / 2, 0.0, 0.0, 0.0])  # q = N^-1 q_m + ZERO: the URDF's zero


def tx40() -> float:
    q_m = np.loadtxt(TX40 / "data" / "pos_read_data.csv", delimiter=",", skiprows=1)
    tau_m = np.loadtxt(TX40 / "data" / "curr_data.csv", delimiter=",", skiprows=1)
    q, tau = q_m @ np.linalg.inv(TX40_N).T + TX40_ZERO, tau_m @ TX40_N
    split = int(0.7 * len(q))
    sos = butter(ORDER, TX40_CUTOFF, fs=TX40_RATE, output="sos")
    model = pin.buildModelFromUrdf(str(TX40 / "urdf" / "tx40_mdh_modified.urdf"))
    model.gravity.linear = np.array([0.0, 0.0, -9.80665])
    data = model.createData()

    def part(rows):
        qf, tf = sosfiltfilt(sos, q[rows], axis=0), sosfiltfilt(sos, tau[rows], axis=0)
        qd = np.gradient(qf, 1 / TX40_RATE, axis=0)
        qdd = np.gradient(qd, 1 / TX40_RATE, axis=0)
        k = int(TX40_TRIM * TX40_RATE)
        keep = np.arange(k, len(qf) - k, DECIMATE)
        qk, qdk, qddk = qf[keep], qd[keep], qdd[keep]
        Y = np.stack([pin.computeJointTorqueRegressor(model, data, a, b, c).copy() for a, b, c in zip(qk, qdk, qddk,
                                                                                                     strict=True)])
        qd_m, qdd_m = qdk @ TX40_N.T, qddk @ TX40_N.T
        motor = np.stack([qdd_m, qd_m, np.tanh(qd_m / (TX40_V_C * np.abs(np.diag(TX40_N)))), np.ones_like(qd_m)], -1)
        drive = np.einsum("kj,tkc->tjkc", TX40_N, motor).reshape(len(keep), 6, 24)  # motor k at joint j: N_kj
        return np.concatenate([Y, drive], axis=2).reshape(-1, Y.shape[2] + 24), tf[keep]

    (W1, tau1), (W2, tau2) = part(slice(0, split)), part(slice(split, len(q)))
    theta = np.linalg.lstsq(W1, tau1.ravel(), rcond=None)[0]
    error = float(np.linalg.norm(W2 @ theta - tau2.ravel()) / np.linalg.norm(tau2))
    print(f"plain least squares, TX40, held-out relative torque error: {100 * error:.2f} %")
    return error


SOLO12_FEET = ("FL", "FR", "HL", "HR")


def solo12() -> float:
    """Solo12's standing bench log (harness/data/logs/solo12_standing_bench): Pinocchio's free-flyer model of
    its URDF; the log's base pose (x y z w: Pinocchio's own order) and base-axes twist are Pinocchio's q and v
    as they are, its acceleration the twist's central differences; each foot's world force reaches the rows
    through its frame's Jacobian (J^T f); the whole rows [0; tau] + sum J^T f fitted by least squares on the
    first 70 %, the held-out error ||pred - measured|| / ||measured|| of the motors' torques and the feet's
    wrench on the base on the last 30 %."""
    from importlib.metadata import distribution

    import pandas as pd

    robots = Path(distribution("example-robot-data").locate_file("cmeel.prefix/share/example-robot-data/robots"))
    urdf = robots / "solo_description" / "robots" / "solo12.urdf"
    model = pin.buildModelFromUrdf(str(urdf), pin.JointModelFreeFlyer())
    data = model.createData()
    log = pd.read_csv(LOGS / "solo12_standing_bench" / "log.csv")
    n, h = 12, float(log["t"].iloc[1] - log["t"].iloc[0])
    q = np.concatenate([log[["px", "py", "pz", "qx", "qy", "qz", "qw"]].to_numpy(),
                        log[[f"q{k}" for k in range(1, n + 1)]].to_numpy()], axis=1)
    v = np.concatenate([log[["vx", "vy", "vz", "wx", "wy", "wz"]].to_numpy(),
                        log[[f"qd{k}" for k in range(1, n + 1)]].to_numpy()], axis=1)
    a = np.gradient(v, h, axis=0)
    tau = log[[f"tau{k}" for k in range(1, n + 1)]].to_numpy()
    forces = [log[[f"{f}_foot_fx", f"{f}_foot_fy", f"{f}_foot_fz"]].to_numpy() for f in SOLO12_FEET]
    frames = [model.getFrameId(f"{f}_FOOT") for f in SOLO12_FEET]
    Y, y = [], []
    for k in range(1, len(q) - 1):  # the ends' one-sided differences left out
        Y.append(pin.computeJointTorqueRegressor(model, data, q[k], v[k], a[k]).copy())
        pin.computeJointJacobians(model, data, q[k])
        pin.updateFramePlacements(model, data)
        rows = np.concatenate([np.zeros(6), tau[k]])
        for fid, f in zip(frames, forces, strict=True):
            J = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)[:3]
            rows += J.T @ f[k]
        y.append(rows)
    Y, y = np.array(Y), np.array(y)
    split = int(0.7 * len(Y))
    theta = np.linalg.lstsq(Y[:split].reshape(-1, Y.shape[2]), y[:split].ravel(), rcond=None)[0]
    pred, meas = Y[split:] @ theta, y[split:]
    error = float(np.linalg.norm(pred - meas) / np.linalg.norm(meas))
    print(f"plain least squares, Solo12, held-out relative error (feet's wrench on the base and motor torques): "
          f"{100 * error:.2f} %")
    return error


ROBOTS = {"panda": panda, "tx40": tx40, "solo12": solo12}

if __name__ == "__main__":
    robot = sys.argv[1] if len(sys.argv) > 1 else "panda"
    if robot not in ROBOTS:
        sys.exit(f"plain_lstsq.py: no robot {robot!r} ({', '.join(ROBOTS)})")
    sys.exit(0 if ROBOTS[robot]() < 1 else 1)
