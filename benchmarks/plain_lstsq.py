"""The floor a log run is timed against: a plain least-squares identification of the Panda's log
written directly with numpy, scipy and Pinocchio, as a user would without the harness. It reads the
log, drops the rows its driver repeated whole, splits it at 70 % of its duration, conditions each
part on its own as the data's README does (1 kHz grid, 10 Hz zero-phase Butterworth of order 4,
accelerations from the filtered velocities, 0.3 s trimmed at each end, every 10th sample), builds
Pinocchio's joint-torque regressor with each joint's rotor inertia, viscous, smooth Coulomb
(tanh(q'/0.03)) and offset columns, fits by least squares and prints its held-out relative torque
error ||tau_pred - tau|| / ||tau|| on the last 30 %.

    .venv/bin/python benchmarks/plain_lstsq.py

Nothing of the harness is imported but the path of the robot's URDF (example-robot-data's Panda),
so that its time is the work itself: benchmarks/bench.py runs it and `harness run panda_gaz2019`
in turns, each in a fresh process (`log_run_panda_over_plain_lstsq`).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
from scipy.signal import butter, sosfiltfilt

LOG = Path(__file__).resolve().parents[1] / "harness" / "data" / "logs" / "panda_gaz2019" / "log.csv"
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


def main() -> float:
    log = np.loadtxt(LOG, delimiter=",", skiprows=1)
    log = log[np.r_[True, np.any(log[1:, 1:] != log[:-1, 1:], axis=1)]]  # a row repeated whole: held
    t, q, qd, tau = log[:, 0], log[:, 1:8], log[:, 8:15], log[:, 15:22]
    split = t[0] + 0.7 * (t[-1] - t[0])
    full = pin.buildModelFromUrdf(urdf())
    locked = [full.getJointId(name) for name in ("panda_finger_joint1", "panda_finger_joint2")]
    model = pin.buildReducedModel(full, locked, pin.neutral(full))
    data = model.createData()
    spans = [conditioned(t[side], q[side], qd[side], tau[side]) for side in (t < split, t >= split)]
    (q1, qd1, qdd1, tau1), (q2, qd2, qdd2, tau2) = spans
    theta = np.linalg.lstsq(regressor(model, data, q1, qd1, qdd1), tau1.ravel(), rcond=None)[0]
    predicted = regressor(model, data, q2, qd2, qdd2) @ theta
    error = float(np.linalg.norm(predicted - tau2.ravel()) / np.linalg.norm(tau2))
    print(f"plain least squares, Panda, held-out relative torque error: {100 * error:.2f} %")
    return error


if __name__ == "__main__":
    sys.exit(0 if main() < 1 else 1)
