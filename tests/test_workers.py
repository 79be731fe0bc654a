"""Where a sweep's trials run (harness/base/workers.py): this process, forked processes, a Dask cluster
started here, or a Dask scheduler at an address. The claim is the same everywhere: the same
numbers, to the bit, in the order of the tasks; only sweep.json's "run" (where, how long) and the
estimators' seconds per fit differ."""

from __future__ import annotations

import itertools
import json
import os
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from harness.base.workers import IN_PROCESS, LOCAL, Workers
from tests.conftest import SCENARIOS


def _random_problem(seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return rng.standard_normal((3000, 60)), rng.standard_normal(3000)


def _toy_setup(offset: int) -> dict:
    return {"offset": offset, "setups": os.getpid()}


def _toy_trial(state: dict, task: int) -> tuple[int, np.ndarray, int]:
    """A least-squares fit whose matrix products are long enough to be split over BLAS threads."""
    from threadpoolctl import threadpool_info

    A, b = _random_problem(task)
    x = np.linalg.solve(A.T @ A, A.T @ b)
    blas_threads = max(i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas")
    return task + state["offset"], x, blas_threads


def test_trials_come_back_in_task_order_with_the_same_bits_in_this_process_and_forked_ones():
    tasks = list(range(40))
    here = IN_PROCESS.map(_toy_setup, (1000,), _toy_trial, tasks)
    forked = Workers(processes=2).map(_toy_setup, (1000,), _toy_trial, tasks)
    assert [r[0] for r in here] == [r[0] for r in forked] == [t + 1000 for t in tasks]
    for (_, a, _), (_, b, _) in zip(here, forked, strict=True):
        assert np.array_equal(a, b)


def test_every_trial_runs_with_one_blas_thread_and_the_caller_keeps_its_own():
    """One BLAS thread per trial is what makes the bits independent of where the trial ran (a
    product's partial sums follow its split over threads); the caller's setting is restored."""
    from threadpoolctl import threadpool_info, threadpool_limits

    progress = []
    with threadpool_limits(2, user_api="blas"):  # the caller's own (the suite runs on one: tests/conftest.py)
        before = [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]
        assert max(before) == 2
        out = IN_PROCESS.map(_toy_setup, (0,), _toy_trial, range(3), lambda done, total: progress.append((done, total)))
        assert [r[2] for r in out] == [1, 1, 1]
        assert [r[2] for r in Workers(processes=2).map(_toy_setup, (0,), _toy_trial, range(3))] == [1, 1, 1]
        assert [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"] == before
    assert progress == [(1, 3), (2, 3), (3, 3)]


@pytest.fixture(scope="module")
def scheduler(tmp_path_factory):
    """A Dask scheduler and two single-threaded workers started as a user would on a cluster's
    nodes (`dask scheduler`, `dask worker`), here as local processes; yields the address."""
    dask = shutil.which("dask", path=str(Path(sys.executable).parent)) or shutil.which("dask")
    if dask is None:
        pytest.fail("the dask command line is not installed (pip install 'dask[distributed]')")
    folder = tmp_path_factory.mktemp("dask")
    file = folder / "scheduler.json"
    quiet = {"cwd": folder, "stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL}
    procs = [subprocess.Popen([dask, "scheduler", "--port", "0", "--dashboard-address", ":0",
                               "--scheduler-file", str(file)], **quiet)]
    try:
        deadline = time.monotonic() + 60
        while not file.exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        address = json.loads(file.read_text())["address"]
        procs.append(subprocess.Popen([dask, "worker", address, "--nworkers", "2", "--nthreads", "1",
                                       "--no-dashboard"], **quiet))
        from distributed import Client

        with Client(address, timeout="30s") as client:
            client.wait_for_workers(2, timeout=60)
        yield address
    finally:
        for p in reversed(procs):
            p.terminate()
            p.wait(timeout=30)


@pytest.mark.slow  # a Dask cluster and three sweeps of kr500_noise: about 20 s
def test_a_force_path_sweep_is_the_same_in_this_process_in_forked_processes_and_on_dask(scheduler):
    from harness.papers.graph_theory_2021.sweep import run_sweep
    from harness.runner.scenario import load_scenario

    sc = load_scenario(SCENARIOS / "kr500_noise.toml")
    runs = {w.describe(): run_sweep(sc, 6, w, levels=(1.0, 2.0))
            for w in (IN_PROCESS, Workers(processes=2), Workers(dask=LOCAL), Workers(dask=scheduler))}
    where = [r.pop("run")["workers"] for r in runs.values()]
    assert where == list(runs) and len(set(where)) == 4
    first = next(iter(runs.values()))
    assert all(r == first for r in runs.values())


def _two_estimators(path: Path) -> None:
    """ur5_estimators with two of its four estimators, written to `path`."""
    source = (SCENARIOS / "ur5_estimators.toml").read_text()
    path.write_text(source.replace('"../models/', f'"{SCENARIOS.parent / "models"}/')
                    .replace('"ur5_friction_validation.toml"', f'"{SCENARIOS / "ur5_friction_validation.toml"}"')
                    .replace('methods = ["ols", "wls", "irls", "iv"]', 'methods = ["ols", "iv"]'))


@pytest.mark.slow  # ur5_estimators twice over 4 trials: about 15 s
def test_harness_sweep_runs_the_estimators_on_a_dask_scheduler_with_the_same_results(scheduler, tmp_path):
    """`harness sweep SCENARIO --dask ADDRESS` against `--jobs 1`: the same sweep.json apart from
    where and how long ("run") and the seconds per fit."""
    from harness.cli import main

    _two_estimators(tmp_path / "s.toml")
    sweeps = {}
    for name, flags in (("here", ["--jobs", "1"]), ("dask", ["--dask", scheduler])):
        out = tmp_path / name
        assert main(["sweep", str(tmp_path / "s.toml"), "--trials", "4", "--out", str(out), *flags]) == 0
        sweeps[name] = json.loads((out / "sweep.json").read_text())
    assert sweeps["dask"]["run"]["workers"] == f"dask, scheduler {scheduler}"
    for s in sweeps.values():
        del s["run"]
        for m in s["estimators"]["methods"].values():
            del m["seconds_per_fit"]
    assert sweeps["here"] == sweeps["dask"]


def test_without_dask_installed_a_dask_sweep_is_refused_in_one_line(monkeypatch, tmp_path, capsys):
    """`--dask` where dask.distributed cannot be imported: exit 2, one line naming the flag and what
    to install, nothing written."""
    from harness.cli import main

    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed now raises ImportError
    out = tmp_path / "out"
    assert main(["sweep", str(SCENARIOS / "kr500_noise.toml"), "--trials", "2", "--dask", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--dask" in err and "pip install" in err, err
    assert not out.exists()


def _made_at_run_time(state: dict, task: int) -> tuple:
    """A trial whose result holds a function and a class that exist only at run time, which plain
    pickle cannot send back and Dask can."""
    scale = state["offset"] + task
    return (lambda x: scale * x), type(f"Made{task}", (), {"k": task}), np.full(3, float(task))


@pytest.mark.slow  # a dask cluster started (2.7 s)
def test_a_dask_trial_may_return_functions_and_classes_made_at_run_time_and_arrays_come_back_equal():
    """A chunk's results go back pickled whole, from the trial's thread (harness/base/workers.py,
    _dask_chunk): what Dask itself would have sent, a function or class made at run time included,
    comes back, in the tasks' order."""
    out = Workers(dask=LOCAL).map(_toy_setup, (10,), _made_at_run_time, range(20))
    assert [f(2) for f, _, _ in out] == [2 * (10 + t) for t in range(20)]
    assert [c.k for _, c, _ in out] == list(range(20))
    assert all(np.array_equal(a, np.full(3, float(t))) for t, (_, _, a) in enumerate(out))


def _pid_setup(shared: np.ndarray) -> int:
    return int(shared.sum())


def _pid_trial(state: int, task: int) -> tuple[int, int]:
    time.sleep(0.01)  # long enough for every worker to take a share
    return os.getpid(), state + task


@pytest.mark.slow  # a dask cluster started (1.1 s)
def test_within_an_opened_block_every_map_runs_on_the_same_workers_and_shared_data_is_sent_once(monkeypatch):
    """`Workers.opened()`: the local cluster started once for two maps (the worker processes of the
    second are those of the first) and an object both maps share scattered once; after the block,
    a map starts a cluster of its own (new processes)."""
    from distributed import Client

    scattered = []
    original = Client.scatter
    monkeypatch.setattr(Client, "scatter", lambda self, data, **kw: scattered.append(1) or original(self, data, **kw))
    shared = np.arange(4.0)
    workers = Workers(dask=LOCAL)
    with workers.opened():
        first = workers.map(_pid_setup, (shared,), _pid_trial, range(32))
        second = workers.map(_pid_setup, (shared,), _pid_trial, range(32))
    after = workers.map(_pid_setup, (shared,), _pid_trial, range(32))
    assert [r[1] for r in first] == [r[1] for r in second] == [r[1] for r in after] == [6 + t for t in range(32)]
    assert {r[0] for r in second} <= {r[0] for r in first}
    assert not {r[0] for r in after} & {r[0] for r in first}
    assert len(scattered) == 2  # once in the block, once for the map after it


def _without_where_and_when(results: dict) -> dict:
    run = results.pop("run")
    results.pop("report", None)
    for m in results["estimators"]["methods"].values():
        del m["seconds_per_fit"]
    return {**results, "versions": run["versions"], "scenario_text": run["scenario_text"]}


@pytest.mark.slow  # ur5_estimators twice over its trials, two methods: about 20 s
def test_harness_run_runs_the_estimators_monte_carlo_on_the_workers_it_is_given(tmp_path):
    """`harness run SCENARIO --jobs 2` against `harness run SCENARIO`: the estimators' Monte Carlo on two
    forked processes gives the same results.json apart from when, how long and where (`run`) and the
    seconds per fit, and `run.workers` says where it ran."""
    from harness.cli import main

    _two_estimators(tmp_path / "s.toml")
    runs = {}
    for name, flags in (("here", []), ("forked", ["--jobs", "2"])):
        out = tmp_path / name
        assert main(["run", str(tmp_path / "s.toml"), "--out", str(out), "--quiet", *flags]) == 0
        runs[name] = json.loads((out / "results.json").read_text())
    assert runs["here"]["run"]["workers"] == "this process"
    assert runs["forked"]["run"]["workers"] == "2 forked processes"
    assert _without_where_and_when(runs["here"]) == _without_where_and_when(runs["forked"])


@pytest.mark.parametrize(("n", "slots"), [(1, 1), (7, 2), (1000, 2), (100_003, 64)])
def test_dask_chunks_cover_every_task_once_in_order_and_shrink_as_the_tasks_run_out(n, slots):
    from harness.base.workers import CHUNK, MAX_DASK_CHUNK, guided_chunks

    bounds = guided_chunks(n, slots)
    assert bounds[0][0] == 0 and bounds[-1][1] == n
    assert all(a[1] == b[0] for a, b in itertools.pairwise(bounds))  # contiguous: each task once, in order
    sizes = [b - a for a, b in bounds]
    assert all(CHUNK <= s <= MAX_DASK_CHUNK for s in sizes[:-1]) and 0 < sizes[-1] <= MAX_DASK_CHUNK
    assert sizes == sorted(sizes, reverse=True)


def _ends_its_process(state: dict, task: int) -> int:
    """A trial whose code ends the process it runs in, as a plugin may: sys.exit, or os._exit."""
    if task == 5:
        if state["offset"] == 0:
            sys.exit(0)
        os._exit(0)
    return task


_RUN_ENDING = """
import sys
from harness.base.workers import LOCAL, Workers
from tests.test_workers import _ends_its_process, _toy_setup
workers = Workers(dask=LOCAL) if sys.argv[1] == "dask" else Workers(processes=2)
try:
    workers.map(_toy_setup, (int(sys.argv[2]),), _ends_its_process, range(20))
except BaseException as exc:
    print(type(exc).__name__, exc)
"""


@pytest.mark.parametrize("where", ["fork", pytest.param("dask", marks=pytest.mark.slow)])  # a local cluster: seconds
def test_a_trial_that_ends_its_worker_process_ends_the_map_with_an_error_not_a_wait(where):
    """sys.exit in a trial is raised in the caller as it would be in this process (the CLI reports
    it, exit 2); os._exit, which no worker can report, is a RuntimeError saying so (exit 3). Both
    once waited for the lost trials forever: the map runs in a child with a deadline."""
    def ended(code: int) -> str:
        run = subprocess.run([sys.executable, "-c", _RUN_ENDING, where, str(code)], capture_output=True, text=True,
                             timeout=120, cwd=Path(__file__).resolve().parent.parent)
        return run.stdout.strip()

    assert ended(0) == "SystemExit 0"
    assert ended(1).startswith("RuntimeError a worker process ended without handing back its trials")



_HELD = threading.Lock()  # held by the process that starts a local cluster, in the test below


def _takes_the_held_lock(state: dict, task: int) -> bool:
    """Whether the worker can take _HELD: a worker forked from a process holding it would inherit it held."""
    taken = _HELD.acquire(timeout=5)
    if taken:
        _HELD.release()
    return taken


@pytest.mark.slow  # a local dask cluster started (3 s)
def test_a_local_clusters_workers_do_not_inherit_the_locks_this_process_holds():
    """The local cluster's workers start from a process without threads (multiprocessing's fork
    server), not as forks of this one: a fork copies every lock as it is at that instant, and a
    worker forked while another thread of this process held sys.stderr's buffer lock waited for it for
    ever at its first write (seen once in the slow checks). Here a lock is held while the cluster
    starts and its trials take it, each waiting at most 5 s."""
    with _HELD:
        taken = Workers(dask=LOCAL).map(_toy_setup, (0,), _takes_the_held_lock, range(4))
    assert taken == [True] * 4
