"""The `harness` command. It only wires the data flow: scenario -> recording -> results."""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np

from harness.results import RECORDING_FILE, RESULTS_FILE, build_results, write_results
from harness.tomlio import InputError

EXIT_OK, EXIT_BAD_INPUT = 0, 2


def _resolve_scenario(arg: str) -> Path:
    """A path to a scenario file, or a bare name looked up in ./scenarios/."""
    path = Path(arg)
    if not path.exists() and path.suffix == "" and len(path.parts) == 1:
        named = Path("scenarios") / f"{arg}.toml"
        if named.exists():
            return named
    return path


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="harness",
        description="Validate a robot's dynamic model against reference engines (MuJoCo, Pinocchio).")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    run = sub.add_parser(
        "run", help="simulate a scenario in MuJoCo and write its recording and results",
        description="Replay a scenario in MuJoCo: every joint is driven along its prescribed "
                    "motion, and forces, accelerations and Cardano angles are recorded. Writes "
                    f"DIR/{RECORDING_FILE} (one row per output step) and DIR/{RESULTS_FILE}.")
    run.add_argument("scenario", metavar="SCENARIO",
                     help="scenario file, or the name of one in ./scenarios/ (e.g. kr500_rail)")
    run.add_argument("--out", metavar="DIR", type=Path, default=None,
                     help="output folder (default: reports/<scenario name>)")
    return parser


def _write_atomically(out: Path, files: dict[str, callable]) -> None:
    """Write every file into a temporary folder beside `out`, then move them in: a failure leaves
    nothing half-written in `out`."""
    out = out.resolve()
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        for name, write in files.items():
            write(tmp / name)
        out.mkdir(exist_ok=True)
        for name in files:
            (tmp / name).replace(out / name)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def cmd_run(args: argparse.Namespace) -> int:
    from harness.pipeline import run
    from harness.scenario import load_scenario

    scenario = load_scenario(_resolve_scenario(args.scenario))
    out = args.out if args.out is not None else Path("reports") / scenario.name
    output = run(scenario)
    results = build_results(output)
    try:
        _write_atomically(out, {
            RECORDING_FILE: output.recording.write_csv,
            RESULTS_FILE: lambda p: write_results(p, results),
        })
    except OSError as exc:
        raise InputError(out, "--out", f"cannot write output ({exc.strerror or exc})") from None
    _print_summary(results, out)
    return EXIT_OK


def _print_summary(results: dict, out: Path) -> None:
    rec = results["recording"]
    track = rec["tracking_error"]
    q_err = max(v["q_max_abs_error"] for v in track.values())
    print(f"{results['scenario']['name']}: {rec['rows']} rows over {rec['t_end']:g} s, "
          f"MuJoCo {rec['engine_version']} {rec['integrator']} dt={rec['timestep']:g} s")
    print(f"  largest tracking error of the prescribed motion: {q_err:.2e} (rad or m)")
    for body, times in rec["gimbal_lock_rows"].items():
        shown = ", ".join(f"{t:g}" for t in np.asarray(times)[:8]) + (" ..." if len(times) > 8 else "")
        print(f"  {body} near Cardano gimbal lock at {len(times)} rows: t = {shown} s")
    res = results["graph"]["unconstrained_residual"]
    print(f"  graph model vs MuJoCo, |A q'' - B| / |B|: {res['max_translational']:.1e} (forces), "
          f"{res['max_rotational']:.1e} (moments) over {res['rows_evaluated']} body-rows; "
          f"{len(res['rows_not_evaluated'])} body-rows near gimbal lock not evaluated")
    lg = results["lagrange"]
    normal = lg["formulations"]["normal"]
    print(f"  constrained dynamics (Eq. 111) vs MuJoCo: accelerations "
          f"{normal['acceleration_check_max_rel_error']:.1e}, joint reactions "
          f"{normal['reaction_check_max_rel_error']:.1e} over {lg['rows_evaluated']} rows; the paper's "
          f"axis constraints leave Phi_q rank {lg['formulations']['paper']['rank_Phi_q_min']} of "
          f"{lg['formulations']['paper']['rows']}")
    if lg["forward_simulation"]:
        fw = lg["forward_simulation"]
        print(f"  constrained model integrated over the run: largest joint deviation from MuJoCo "
              f"{max(fw['max_joint_deviation'].values()):.1e}, position {fw['max_position_deviation']:.1e} m")
    tq = results["torques"]
    pairs = ", ".join(f"{k.replace('_vs_', ' vs ')} {tq[k]['max_rel_error']:.1e}"
                      for k in ("graph_vs_pinocchio", "graph_vs_mujoco", "pinocchio_vs_mujoco"))
    print(f"  joint torques, largest relative error (of the joint's load): {pairs}")
    ident = results["identification"]
    digits = ident["significant_digits"]
    print(f"  identification from {len(ident['sample_times'])} samples"
          f"{f' at {digits} significant digits' if digits else ' (ideal measurements)'}: "
          f"largest relative error {ident['max_abs_rel_error']:.1e}; not identifiable: "
          f"{', '.join(ident['not_identifiable']) or 'none'}")
    print(f"  wrote {out / RECORDING_FILE} and {out / RESULTS_FILE}")


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        return {"run": cmd_run}[args.command](args)
    except InputError as exc:
        print(f"harness: error: {exc.one_line()}", file=sys.stderr)
        return EXIT_BAD_INPUT


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
