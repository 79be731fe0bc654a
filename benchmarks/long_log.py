"""A long log for the memory benchmark: `hours` of a 7-joint arm (the Panda of models/panda_arm.toml) at
1 kHz, written as a measured log would be, and a scenario that identifies it as panda_gaz2019 does
(the same conditioning, the last 30 % held out) without FIGAROH's fits and the refinement, which
`harness run panda_gaz2019` times on the real log.

    .venv/bin/python benchmarks/long_log.py FOLDER [hours]

The motion: each joint a sum of five sines (periods 2 to 20 s) within 0.4 rad of the Panda's ready
pose; the torques Pinocchio's RNEA of the model with a drive law on every joint (rotor inertia,
viscous, Coulomb over 0.03 rad/s, offset), 0.5 % noise on each channel; t to the millisecond,
positions, velocities and torques to six significant digits, as a CSV of t, q1..q7, qd1..qd7,
tau1..tau7 (FOLDER/long.csv, about 200 bytes a row) and FOLDER/long.toml. benchmarks/bench.py runs it
(`log_run_1h_peak_rss_mib`).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
RATE = 1000.0
CHUNK = 200_000  # rows computed and written at a time


def write(folder: Path, hours: float = 1.0) -> Path:
    import pinocchio as pin

    from harness.engines.pinocchio import build_model
    from harness.model.load import load_spec

    spec = load_spec(ROOT / "harness" / "data" / "models" / "panda_arm.toml")
    pm = build_model(spec, np.array([0.0, 0.0, -9.81]))
    model, data = pm.model, pm.model.createData()
    n = len(spec.joints)
    assert np.array_equal(pm.q_index, np.arange(n))  # the spec's joint order is Pinocchio's
    rng = np.random.default_rng(0)
    middle = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])  # the Panda's ready pose
    w = 2 * np.pi / rng.uniform(2.0, 20.0, size=(5, n))
    a = rng.uniform(-1, 1, size=(5, n)) * 0.4 / 5  # within 0.4 rad of the ready pose
    phase = rng.uniform(0, 2 * np.pi, size=(5, n))
    law = np.array([[0.2, 0.5, 1.0, 0.1]] * n) * np.linspace(1.0, 0.4, n)[:, None]  # I_a, f_v, f_c, f_o
    rows = int(hours * 3600 * RATE)
    csv = folder / "long.csv"
    with csv.open("w") as out:
        out.write(",".join(["t", *(f"q{j}" for j in range(1, n + 1)), *(f"qd{j}" for j in range(1, n + 1)),
                            *(f"tau{j}" for j in range(1, n + 1))]) + "\n")
        for start in range(0, rows, CHUNK):
            t = np.arange(start, min(start + CHUNK, rows)) / RATE
            arg = w[None] * t[:, None, None] + phase[None]  # (N, 5, n)
            q = middle + np.sum(a * np.sin(arg), axis=1)
            qd = np.sum(a * w * np.cos(arg), axis=1)
            qdd = -np.sum(a * w**2 * np.sin(arg), axis=1)
            tau = np.array([pin.rnea(model, data, *x) for x in zip(q, qd, qdd, strict=True)])
            tau += law[:, 0] * qdd + law[:, 1] * qd + law[:, 2] * np.tanh(qd / 0.03) + law[:, 3]
            tau += 0.005 * np.std(tau, axis=0) * rng.normal(size=tau.shape)
            # t to the millisecond whatever its size (six significant digits would hold 10 ms past 1000 s, and
            # the rows sharing a time would be dropped as repeats)
            np.savetxt(out, np.column_stack([t, q, qd, tau]), fmt=["%.3f"] + ["%.6g"] * (3 * n), delimiter=",")
    scenario = folder / "long.toml"
    scenario.write_text(
        f'[scenario]\ndescription = "{hours:g} h of a 7-joint arm at 1 kHz (benchmarks/long_log.py)"\n'
        f'model = "{ROOT / "harness" / "data" / "models" / "panda_arm.toml"}"\n'
        '[data]\nfile = "long.csv"\ncolumns = { t = "t", q = "q{j}", qd = "qd{j}", tau = "tau{j}" }\n'
        'units = { q = "rad", qd = "rad/s", tau = "N m" }\nrate = 1000.0\ncutoff = 10.0\nfilter_order = 4\n'
        'decimate = 10\nvalidation = { from = 0.7 }\n'
        '[[gates]]\nmetric = "log_identification.validation_rel_error.consistent"\nlimit = 0.05\n')
    return scenario


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit("usage: long_log.py FOLDER [hours]")
    print(write(Path(sys.argv[1]), float(sys.argv[2]) if len(sys.argv) > 2 else 1.0))
