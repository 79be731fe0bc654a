"""The Franka Emika Panda's real log (harness/data/logs/panda_gaz2019) judged on one conditioning of the same
rows for every model: run from the project root with `.venv/bin/python benchmarks/panda.py` (two to three
minutes; FIGAROH's rows need `pip install -e ".[figaroh]"`, else they say why not).

1. `harness run` of the built-in scenario, each in a fresh process: as shipped (panda_gaz2019: the data's
   README's conditioning, a 10 Hz low-pass and every 10th sample, set by hand), at the harness's
   defaults (a copy without `rate`, `cutoff`, `filter_order` and `decimate`: the data choose; the same with
   gravity as the scenario declares it, `tilt = "declared"`, where the defaults read its direction off the
   torques: harness/identify/gravity.py), and the
   shipped one at each cut-off of CUTOFFS, and the defaults with the logged velocities used as logged
   (`velocities = "used"`: the harness realigns a column whose lag behind the positions' rate of change
   explains their disagreement; the Panda's 2 to 9 ms lags do not, so this run is the defaults'): the hand tuning,
   the best of which is the "best hand tuning". The cut-off runs leave out FIGAROH's fits and the
   refinement, which change no exported model.
2. The judging conditioning, the data's README's (benchmarks/plain_lstsq.py, which imports nothing of
   the harness: whole rows repeated dropped, split at 70 % of the duration, each part resampled to
   1 kHz, a 10 Hz zero-phase Butterworth of order 4 on q, q' and tau, accelerations from the filtered
   velocities, 0.3 s trimmed, every 10th sample; plain_lstsq.panda_spans): its last 30 % are the test
   rows, its first 70 % the training rows of the fits made here.
3. On the test rows, the relative torque error ||tau_model - tau_measured|| / ||tau_measured|| over all
   samples and joints of: each run's exported models (`harness.identified_model`, its consistent fit
   and its least squares); the plain least squares of plain_lstsq.py (Pinocchio's regressor, per joint
   rotor inertia, viscous, tanh(q'/0.03) Coulomb and offset), at the declared gravity and again told the
   gravity the harness's defaults found; FIGAROH's least squares and physical fit
   through harness/adapters/figaroh.py on the same training rows.
Writes reports/panda.json and prints a table.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

import plain_lstsq  # noqa: E402  (the judging conditioning and the plain least squares, harness-free)
from judging import figaroh_fits, rel  # noqa: E402

SCENARIOS = ROOT / "harness" / "data" / "scenarios"
GRAVITY = 9.80665  # m/s^2 along -z of the base, as the scenario
CUTOFFS = (3.0, 5.0, 7.5, 15.0, 20.0)  # Hz: the hand tuning's other cut-offs beside the shipped 10 Hz
CONDITIONING_KEYS = ("rate", "cutoff", "filter_order", "decimate")  # what the defaults run leaves to the data


def variants(folder: Path) -> dict[str, Path]:
    """The scenarios of the module's docstring, 1, written into `folder` (their paths made absolute)."""
    shipped = (SCENARIOS / "panda_gaz2019.toml").read_text().replace('"../', f'"{SCENARIOS.parent}/')
    out = {"shipped (10 Hz)": SCENARIOS / "panda_gaz2019.toml"}
    defaults = [line for line in shipped.splitlines() if line.split(" = ")[0] not in CONDITIONING_KEYS]
    assert len(defaults) == len(shipped.splitlines()) - len(CONDITIONING_KEYS)
    (folder / "defaults.toml").write_text("\n".join(defaults) + "\n")
    out["defaults"] = folder / "defaults.toml"
    used = [line if not line.startswith("validation = ") else 'velocities = "used"\n' + line for line in defaults]
    (folder / "velocities_used.toml").write_text("\n".join(used) + "\n")
    out["defaults, velocities as logged"] = folder / "velocities_used.toml"
    level = [line if not line.startswith("validation = ") else 'tilt = "declared"\n' + line for line in defaults]
    (folder / "gravity_declared.toml").write_text("\n".join(level) + "\n")
    out["defaults, gravity as declared"] = folder / "gravity_declared.toml"
    head = shipped.split("[[identification]]")[0]  # [scenario] and [data]: no FIGAROH, no refinement
    gate = '[[gates]]\nname = "held out"\nmetric = "log_identification.validation_rel_error.consistent"\nlimit = 1\n'
    for cutoff in CUTOFFS:
        path = folder / f"cutoff_{cutoff:g}.toml"
        path.write_text(head.replace("cutoff = 10.0", f"cutoff = {cutoff}") + gate)
        out[f"cutoff {cutoff:g} Hz"] = path
    return out


def harness_runs(folder: Path) -> dict:
    """Each variant run in a fresh process: its folder, exit status, seconds and own held-out figure."""
    out = {}
    for name, scenario in variants(folder).items():
        into = folder / name.replace(" ", "_").replace("(", "").replace(")", "").replace(",", "")
        t0 = time.perf_counter()
        status = subprocess.run([str(Path(sys.executable).parent / "harness"), "run", str(scenario), "--out",
                                 str(into), "--quiet"], cwd=ROOT, capture_output=True).returncode
        results = json.loads((into / "results.json").read_text())
        out[name] = {"folder": into, "exit": status, "seconds": time.perf_counter() - t0,
                     "gravity": results["log_identification"]["gravity"]["used"],
                     "own_validation_rel_error": results["log_identification"]["validation_rel_error"]["consistent"],
                     "conditioning_defaults": {k: v for k, v in (results["data"]["conditioning"]["defaults"] or {})
                                               .items() if k in ("cutoff_hz", "decimate")} or None}
    return out


def main() -> None:
    import harness

    (q1, qd1, qdd1, tau1), (q2, qd2, qdd2, tau2) = plain_lstsq.panda_spans()
    rows: dict[str, float | str] = {}
    with tempfile.TemporaryDirectory() as tmp:
        runs = harness_runs(Path(tmp))
        for name, run in runs.items():
            for fit in ("consistent", "least squares"):
                model = harness.identified_model(run["folder"], fit=fit)
                rows[f"harness {name}, {fit}"] = rel(model.inverse_dynamics(q2, qd2, qdd2), tau2)
    model, data = plain_lstsq.panda_model()
    theta = np.linalg.lstsq(plain_lstsq.regressor(model, data, q1, qd1, qdd1), tau1.ravel(), rcond=None)[0]
    rows["plain least squares"] = rel((plain_lstsq.regressor(model, data, q2, qd2, qdd2) @ theta).reshape(-1, 7), tau2)
    model.gravity.linear = np.array(runs["defaults"]["gravity"])  # told the gravity the harness's defaults found
    theta = np.linalg.lstsq(plain_lstsq.regressor(model, data, q1, qd1, qdd1), tau1.ravel(), rcond=None)[0]
    rows["plain least squares at the defaults' gravity"] = rel(
        (plain_lstsq.regressor(model, data, q2, qd2, qdd2) @ theta).reshape(-1, 7), tau2)
    fits = figaroh_fits(ROOT / "harness" / "data" / "models" / "panda_arm.toml", GRAVITY, q1, qd1, qdd1, tau1)
    for kind, fitted in fits.items():
        rows[f"FIGAROH {kind}"] = fitted if isinstance(fitted, str) else \
            rel(fitted.inverse_dynamics(q2, qd2, qdd2), tau2)
    tuned = {k: v for k, v in rows.items() if k.startswith("harness ") and k.endswith(", consistent")
             and k != "harness defaults, consistent"}
    best = min(tuned, key=tuned.get)
    figures = {"test_rows": len(q2), "held_out_rel_error": rows, "best_hand_tuning": best,
               "defaults_over_best_hand_tuning": rows["harness defaults, consistent"] / tuned[best],
               "defaults_over_plain_least_squares": rows["harness defaults, consistent"] / rows["plain least squares"],
               "runs": {name: {k: v for k, v in run.items() if k != "folder"} for name, run in runs.items()}}
    (ROOT / "reports").mkdir(exist_ok=True)
    (ROOT / "reports" / "panda.json").write_text(json.dumps(figures, indent=2, default=float) + "\n")
    print(f"Panda, held-out relative torque error on {len(q2)} test rows (the data's README's conditioning):")
    for name, value in rows.items():
        print(f"  {name:48s} " + (f"{value:.2%}" if isinstance(value, float) else f"failed: {value}"))
    print(f"defaults / best hand tuning ({best}): {figures['defaults_over_best_hand_tuning']:.3f}; "
          f"defaults / plain least squares: {figures['defaults_over_plain_least_squares']:.3f}")
    for name, run in figures["runs"].items():
        print(f"harness run {name}: exit {run['exit']}, {run['seconds']:.1f} s, its own held-out figure "
              f"{run['own_validation_rel_error']:.2%}, the data's choice {run['conditioning_defaults']}")


if __name__ == "__main__":
    main()
