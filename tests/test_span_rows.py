"""A span's regressor made where it is read (harness/identify/span_rows.py): the rows of the whole,
bit for bit, in any row range; its products those of the whole; a log's run the same with it as with
the regressor held whole; and a fit on it allocating a small part of the whole's size."""

from __future__ import annotations

import json
import tracemalloc

import numpy as np
import pytest

from harness.base import numerics
from harness.base.numerics import SideBySide
from harness.cli import main
from harness.engines.pinocchio import build_model
from harness.identify import lstsq, span_rows
from harness.identify.span_rows import RowsOnDemand, span_regressor
from harness.identify.torque_id import fit_base, put_coulomb, regressor, structural_base
from harness.model.load import load_spec
from tests.conftest import MODELS, numbers_of


def _states(n: int, N: int, seed: int = 2):
    rng = np.random.default_rng(seed)
    return tuple(rng.uniform(-1, 1, (N, n)) for _ in range(3))


@pytest.mark.parametrize("model", ["ur5_friction.toml", "tx40.toml", "panda_arm.toml"])
def test_rows_on_demand_are_the_whole_regressors_rows_in_any_range_and_its_products(model, monkeypatch):
    """At 700 random states, made 64 samples at a time: every row range (starting and ending inside a
    sample's rows too) equals the whole regressor's rows bit for bit, with Coulomb columns of its own
    put in (through the TX40's coupled wrist as well), and W @ x equals the whole's to 1e-13 of
    |W| |x| (the products' sums split by chunk)."""
    monkeypatch.setattr(span_rows, "SAMPLES_AT_A_TIME", 64)
    spec = load_spec(MODELS / model)
    pm = build_model(spec, np.array([0.0, 0.0, -9.81]))
    n = len(spec.joint_names)
    q, qd, qdd = _states(n, 700)
    S = np.random.default_rng(3).uniform(-1, 1, (700, spec.transmission.N.shape[0] if spec.transmission else n))
    whole = regressor(pm, q, qd, qdd, with_friction=True)
    put_coulomb(whole.reshape(700, n, -1), S, spec.transmission)
    lazy = RowsOnDemand(pm, q, qd, qdd, S)
    assert lazy.shape == whole.shape
    for a, b in ((0, whole.shape[0]), (3, 5), (n - 1, 65 * n + 2), (699 * n, 700 * n), (100 * n + 1, 100 * n + 1)):
        assert np.array_equal(lazy[a:b], whole[a:b]), (a, b)
    x = np.random.default_rng(5).standard_normal(whole.shape[1])
    scale = np.abs(whole).max() * np.abs(x).sum()
    assert np.max(np.abs(lazy @ x - whole @ x)) <= 1e-13 * scale
    assert np.array_equal(lazy.whole(), whole)


def test_a_span_regressor_over_the_size_held_whole_is_made_on_demand(monkeypatch):
    spec = load_spec(MODELS / "ur5_friction.toml")
    pm = build_model(spec, np.array([0.0, 0.0, -9.81]))
    q, qd, qdd = _states(6, 100)
    assert isinstance(span_regressor(pm, q, qd, qdd), np.ndarray)
    monkeypatch.setattr(span_rows, "WHOLE_BYTES", 100 * 6 * 84 * 8 - 1)
    assert isinstance(span_regressor(pm, q, qd, qdd), RowsOnDemand)


@pytest.mark.slow  # a long regressor's memory traced (1.6 s)
def test_a_least_squares_fit_on_rows_on_demand_is_the_fit_on_the_whole_and_its_memory_does_not_grow_with_it(
        monkeypatch):
    """The UR5 with friction at 2,500 and 5,000 random samples (10 and 20 MiB of regressor), its rows
    made 512 samples and read 4,096 rows at a time (the shipped chunks, 8,192 and 32,768, scaled down
    with the spans, so that each span is many chunks): the base parameters and their standard deviations
    on demand equal those on the whole regressor to 1e-9; what the fit on demand allocates at its peak
    (traced) is the same for both lengths within 10 % (a few chunks of rows), where the whole regressor
    doubles."""
    monkeypatch.setattr(span_rows, "SAMPLES_AT_A_TIME", 512)
    monkeypatch.setattr(lstsq, "ROWS_AT_A_TIME", 4096)
    monkeypatch.setattr(numerics, "ROWS_AT_A_TIME", 4096)
    spec = load_spec(MODELS / "ur5_friction.toml")
    pm = build_model(spec, np.array([0.0, 0.0, -9.81]))
    base = structural_base(pm, spec.limits, with_friction=True)
    x = np.random.default_rng(8).standard_normal(84)
    peaks = []
    for N in (2_500, 5_000):
        q, qd, qdd = _states(6, N, seed=7)
        lazy = SideBySide(((RowsOnDemand(pm, q, qd, qdd), base.independent),))
        tau = (lazy @ x[base.independent]).reshape(N, 6) + 0.01 * np.random.default_rng(9).standard_normal((N, 6))
        tracemalloc.start()
        try:
            made = fit_base(lazy, tau, base.of(x))
            peaks.append(tracemalloc.get_traced_memory()[1])
        finally:
            tracemalloc.stop()
        if N == 2_500:
            held = fit_base(SideBySide(((regressor(pm, q, qd, qdd, with_friction=True), base.independent),)), tau,
                            base.of(x))
            np.testing.assert_allclose(made.beta, held.beta, rtol=1e-9, atol=1e-9 * np.abs(held.beta).max())
            np.testing.assert_allclose(made.std, held.std, rtol=1e-9)
    assert peaks[1] <= 1.1 * peaks[0], peaks
    assert peaks[1] < 0.5 * 5_000 * 6 * 84 * 8, peaks  # and well under the whole regressor's size


def _numbers(out, *paths, leave_out: tuple[str, ...] = ()) -> list[float]:
    """Every number of results.json under `paths`, the run's record, every `seconds` and the sections
    `leave_out` of its log_identification left out."""
    def untimed(tree):
        if isinstance(tree, dict):
            return {k: untimed(v) for k, v in tree.items() if k not in ("run", "seconds")}
        return [untimed(v) for v in tree] if isinstance(tree, list) else tree

    results = untimed(json.loads((out / "results.json").read_text()))
    if "log_identification" in results:
        results["log_identification"] = {k: v for k, v in results["log_identification"].items() if k not in leave_out}
    for key in paths:
        results = results[key]
    return numbers_of(results)


# what results.json reads off the consistent fit's parameters one by one: the directions the data leave flat rest
# on its pull towards the model alone, which its solver's tolerance bounds loosely (a held and a made run move
# them by up to 1.8 % on tx40_motion; its torques, errors and gates by 1e-8)
PARAMETERS_OF_THE_CONSISTENT_FIT = ("consistent", "plausibility", "consistent_costs", "series")


@pytest.mark.slow  # two runs of each scenario: 8 and 20 s
@pytest.mark.parametrize("scenario", ["tx40_motion", "panda_gaz2019"])
def test_a_log_run_with_its_regressors_made_on_demand_is_the_run_with_them_held(scenario, tmp_path, monkeypatch):
    """Its regressors made 256 samples at a time (the delays', the fit's, the consistent fit's and the
    judging's; through the TX40's coupled wrist, and on the Panda's filtered log): the least squares'
    held-out error the same to 1e-9 relative (the products' sums split by chunk: 1e-13 measured), every
    other number of results.json but the run's and the seconds, the gates' values among them, to 1e-6, but
    the consistent fit's parameters and what is read off them one by one (PARAMETERS_OF_THE_CONSISTENT_FIT).
    What the consistent fit gives is an interior-point solver's, within its tolerances (1e-7 of an objective
    that is 1 at the least squares' optimum: consistent.SOLVER_TOLERANCES), and round-off moves it within
    them: its held-out error by 1.9e-8 on tx40_motion, the parameters the data leave flat by up to 1.8 %
    (measured on a 2-core Intel Xeon; 3e-8 on an AMD EPYC, where the round-off is another)."""
    assert main(["run", scenario, "--out", str(tmp_path / "held"), "--quiet"]) == 0
    monkeypatch.setattr(span_rows, "WHOLE_BYTES", 0)
    monkeypatch.setattr(span_rows, "SAMPLES_AT_A_TIME", 256)
    assert main(["run", scenario, "--out", str(tmp_path / "made"), "--quiet"]) == 0
    for paths, rtol in ((("log_identification", "validation_rel_error", "least squares"), 1e-9), ((), 1e-6)):
        held, made = (_numbers(tmp_path / run, *paths, leave_out=PARAMETERS_OF_THE_CONSISTENT_FIT)
                      for run in ("held", "made"))
        assert len(held) == len(made) > 0
        np.testing.assert_allclose(made, held, rtol=rtol, atol=1e-12 if rtol > 1e-9 else 0, err_msg=str(paths))
