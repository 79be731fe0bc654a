"""Where a sweep's trials run: in this process, in forked processes on this machine, or on a Dask
cluster (a local one, or a scheduler at an address).

A sweep is `setup(*shared) -> state` once per worker, then `trial(state, task)` for every task;
the results come back in the order of the tasks, so a sweep whose trials draw their noise from
seeds fixed by the task gives the same numbers wherever it runs. `setup` and `trial` must be
module-level functions (a worker imports them by name), and on a remote cluster every worker needs
the same harness installed.

Every trial runs with one BLAS thread, wherever it runs: a matrix product's sum is ordered by how
it is split over threads, and one thread makes the numbers the same bits in this process, in a
forked one and on a Dask worker with the same numpy (and the workers do not oversubscribe the
cores). BLAS's thread count belongs to a process, so Dask workers are started single-threaded
(`dask worker ADDRESS --nthreads 1`, as many processes as cores; the local cluster is made so).

Within `with workers.opened():` the workers are started once (the Dask cluster started, or the
scheduler reached) for every map in the block, and what the maps share (the scenario, its
recording) is sent to them once; outside such a block each map starts and stops its own. A local
cluster's workers import the main module of the process that starts it (`_start_method`), as
multiprocessing's do: a script starts one under `if __name__ == "__main__":`.
"""

from __future__ import annotations

import os
import pickle
import sys
import threading
import uuid
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

LOCAL = "local"  # --dask with no address: a cluster of processes on this machine
CHUNK = 8  # tasks sent to a worker at once: a trial takes tens of milliseconds, a round trip about one
# On Dask a chunk costs about 8 ms of the scheduler's and client's time in the calling process, which
# shares the cores with the workers: chunks there shrink as the tasks run out (guided scheduling),
# from MAX_DASK_CHUNK down to CHUNK, so that few chunks are sent and the workers still end together.
MAX_DASK_CHUNK = 64
WATCH_S = 1.0  # how often a Dask map that waits for its trials looks whether a local cluster has workers left


class WorkersError(Exception):
    """The workers cannot be reached or started (a bad address, dask.distributed not installed)."""


@dataclass(frozen=True)
class Workers:
    """`processes` forked worker processes on this machine (1: this process), or, when `dask` is
    set, the workers of a Dask cluster: LOCAL for one started on this machine (one single-threaded
    worker per core), otherwise a scheduler address such as "tcp://10.0.0.5:8786"."""

    processes: int = 1
    dask: str | None = None

    def describe(self) -> str:
        if self.dask == LOCAL:
            return "dask, local cluster"
        if self.dask:
            return f"dask, scheduler {self.dask}"
        return "this process" if self.processes == 1 else f"{self.processes} forked processes"

    @contextmanager
    def opened(self) -> Iterator[Workers]:
        """These workers started once for every map in the block: a Dask cluster started (or the
        scheduler reached) on entry and stopped (or left) on exit, each object the maps share sent
        to the workers once. Forked processes are cheap to start (ms) and are forked per map, with
        the shared objects inherited, not sent; this process needs nothing. Nested blocks share
        the outer one's."""
        if not self.dask or self.dask in _OPEN:
            yield self
            return
        _OPEN[self.dask] = connection = _Connection(self.dask)
        try:
            yield self
        finally:
            del _OPEN[self.dask]
            connection.close()

    def map(self, setup: Callable[..., Any], shared: tuple, trial: Callable[[Any, Any], Any], tasks: Sequence,
            progress: Callable[[int, int], None] | None = None) -> list:
        """[trial(setup(*shared), task) for task in tasks], setup run once per worker."""
        tasks = list(tasks)
        try:
            if self.dask:
                return _on_dask(self.dask, setup, shared, trial, tasks, progress)
            if self.processes > 1:
                return _on_fork_pool(self.processes, setup, shared, trial, tasks, progress)
        except Ended as exc:  # raised here as in this process, where the caller decides what it means
            raise exc.original() from None
        from threadpoolctl import threadpool_limits

        out = []
        with threadpool_limits(1, user_api="blas"):
            state = setup(*shared)
            for task in tasks:
                out.append(trial(state, task))
                if progress:
                    progress(len(out), len(tasks))
        return out


IN_PROCESS = Workers()  # the default: every trial in this process, one after the other


class Ended(Exception):
    """SystemExit or KeyboardInterrupt raised by the code of a setup or a trial in a worker process
    (a plugin calling sys.exit): carried back to the caller of `map` as an exception, where it is
    raised again as it was. In the worker it would end the process or its task thread, and the
    caller would wait for the trials forever."""

    def __init__(self, kind: str, code: object = None):
        super().__init__(kind, code)
        self.kind, self.code = kind, code

    def original(self) -> BaseException:
        return SystemExit(self.code) if self.kind == "SystemExit" else KeyboardInterrupt()


_WORKER_ENDED = ("a worker process ended without handing back its trials: code a trial ran (a plugin?) ended the "
                 "process or crashed it")


def _carried(f: Callable, *args):
    """f(*args) in a worker, SystemExit and KeyboardInterrupt turned into Ended."""
    try:
        return f(*args)
    except (SystemExit, KeyboardInterrupt) as exc:
        raise Ended(type(exc).__name__, getattr(exc, "code", None)) from None


# --- forked processes ---------------------------------------------------------------------------

_FORKED: dict = {}  # per forked worker: the sweep's setup, shared objects and trial, and its state once built


def _fork_init(setup, shared, trial) -> None:
    import signal

    from threadpoolctl import threadpool_limits

    # the harness's SIGTERM handler (harness/base/plugins.py, user_interrupts) is the calling
    # process's: a worker the pool stops ends quietly, without a KeyboardInterrupt on stderr
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    threadpool_limits(1, user_api="blas")  # for the life of the worker
    _FORKED.update(setup=setup, shared=shared, trial=trial)


def _fork_trial(task):
    """Runs in a forked worker: the state built by its first trial (so that whatever setup raises
    comes back as that trial's exception), the trial then run on it."""
    if "state" not in _FORKED:
        _FORKED["state"] = _carried(_FORKED["setup"], *_FORKED["shared"])
    return _carried(_FORKED["trial"], _FORKED["state"], task)


def _on_fork_pool(processes, setup, shared, trial, tasks, progress) -> list:
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor
    from concurrent.futures.process import BrokenProcessPool

    out = []
    pool = ProcessPoolExecutor(processes, mp_context=multiprocessing.get_context("fork"), initializer=_fork_init,
                               initargs=(setup, shared, trial))
    try:
        for r in pool.map(_fork_trial, tasks, chunksize=CHUNK):
            out.append(r)
            if progress:
                progress(len(out), len(tasks))
    except BrokenProcessPool:  # multiprocessing.Pool would have waited for the lost trials forever
        raise RuntimeError(_WORKER_ENDED) from None
    finally:  # on an exception, the trials not started are dropped, not run
        pool.shutdown(wait=True, cancel_futures=True)
    return out


# --- Dask ---------------------------------------------------------------------------------------

_STATES: dict = {}  # per Dask worker process: {sweep token: state}, the latest sweep only
_LOCK = threading.Lock()


def _dask_chunk(token: str, setup, trial, tasks: list, *shared) -> bytes:
    """Runs on a Dask worker: the sweep's state is built once per worker process (by the first
    chunk that reaches it) and kept for the sweep's other chunks. The chunk's results go back
    pickled whole, here, in the task's thread: left to Dask, each array of each trial's result
    would be serialised and framed on its own by the worker's event loop, whose thread shares
    the interpreter with the trials (a trial of kr500_noise returns three arrays: about 0.1 s of
    the event loop's time per 200 trials, which the trials waited for)."""
    import cloudpickle  # a dependency of dask.distributed, as this runs only there
    from threadpoolctl import threadpool_limits

    with threadpool_limits(1, user_api="blas"):
        with _LOCK:
            if token not in _STATES:
                _STATES.clear()
                _STATES[token] = _carried(setup, *shared)
            state = _STATES[token]
        # cloudpickle, as Dask itself would fall back to: a trial may return a function or a class
        # made at run time; the file is plain pickle, read back with pickle.loads
        return cloudpickle.dumps([_carried(trial, state, t) for t in tasks], protocol=pickle.HIGHEST_PROTOCOL)


class _Connection:
    """A Dask client, the local cluster it started (LOCAL) and what it has sent to the workers."""

    def __init__(self, address: str):
        self.client, self.cluster, self._config = _client(address)
        self._sent: dict[int, tuple[Any, Any]] = {}  # id(object) -> (the object, kept alive; its future)

    def send(self, obj):
        """obj on every worker, sent once per connection (a future the workers resolve to it)."""
        if id(obj) not in self._sent:
            self._sent[id(obj)] = (obj, self.client.scatter([obj], broadcast=True)[0])
        return self._sent[id(obj)][1]

    def close(self) -> None:
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()
        if self._config is not None:
            self._config.__exit__(None, None, None)  # Dask's configuration as it was before the cluster


_OPEN: dict[str, _Connection] = {}  # address -> the connection a `Workers.opened()` block holds


def _client(address: str):
    try:
        import dask
        from distributed import Client, LocalCluster
    except ImportError:
        raise WorkersError("needs dask.distributed: pip install 'dask[distributed]'") from None
    if address == LOCAL:
        import logging
        import multiprocessing

        # the workers start with this process's modules imported (`_start_method`). What serves only a
        # dashboard (none is served: bokeh is not required) is switched off, the memory watch slowed,
        # and the event loops' tick, which only watches for a loop held up (a warning after 3 s), taken
        # every second instead of every 20 ms. A worker's loop shares the interpreter with its trials:
        # idle, each worker's thread then takes 3 to 5 ms of CPU a second instead of 18 to 20, and the
        # scheduler and nannies in this process 8 to 10 instead of 45. The configuration holds while
        # the cluster runs, not only while it starts: a nanny reads it again when it restarts a worker
        # that died (started the same way).
        method = _start_method(multiprocessing)
        config = dask.config.set({"distributed.worker.multiprocessing-method": method,
                                  "distributed.worker.profile.enabled": False,
                                  "distributed.admin.system-monitor.interval": "5s",
                                  "distributed.admin.system-monitor.gil.enabled": False,
                                  "distributed.worker.memory.monitor-interval": "1s",
                                  "distributed.admin.tick.interval": "1s"})
        try:
            cluster = LocalCluster(n_workers=os.cpu_count() or 1, threads_per_worker=1, processes=True,
                                   dashboard_address=":0",  # any free port: clusters on one machine do not collide
                                   # its processes log nothing short of critical: a worker whose
                                   # heartbeat is under way while the cluster stops logs a traceback
                                   # (dask/distributed#7105), and a trial or worker that fails reaches
                                   # the harness as the task's exception, reported in one line
                                   silence_logs=logging.CRITICAL)
            return Client(cluster), cluster, config
        except BaseException:
            config.__exit__(None, None, None)
            raise
    try:
        return Client(address, timeout="10s"), None, None
    except (OSError, TimeoutError, ValueError) as exc:
        raise WorkersError(f"cannot reach a Dask scheduler at {address!r} ({exc})") from None


def _start_method(multiprocessing) -> str:
    """How the local cluster's nannies start their workers. Not by forking this process: it runs the
    cluster's event loop in a thread beside the caller's, and a fork copies every lock as it is at that
    instant, held by a thread that does not exist in the child. A worker forked while another thread
    held sys.stderr's buffer lock blocked for ever at its first write (seen once in the slow checks).
    Where it can, the workers are forked from multiprocessing's fork server instead: one process,
    without threads, started once per process that uses it, which has imported the harness's modules
    that this process has (and the libraries they import); the workers start with them imported (a
    cluster of two on 2 cores started and stopped in 0.97 s the first time, the fork server's start,
    then 0.25 s; forked from this process 0.43 and 0.14 s; spawned about 2 s, each worker importing
    numpy, MuJoCo, Pinocchio and the harness again). A fork server already running (started by an
    earlier cluster) is used as it is."""
    if "forkserver" not in multiprocessing.get_all_start_methods():
        return "spawn"
    from multiprocessing import forkserver

    # Dask's own choice of what the fork server imports (distributed and its libraries) is read when
    # it starts a worker: the server is started here, first, with those and the harness's
    preload = sorted(name for name in sys.modules if name == "harness" or name.startswith("harness."))
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(["distributed", "numpy", *preload])
    forkserver.ensure_running()
    return "forkserver"


def guided_chunks(n: int, slots: int) -> list[tuple[int, int]]:
    """[start, stop) of each chunk of n tasks for `slots` workers: a quarter of each worker's share of
    what is left, within CHUNK and MAX_DASK_CHUNK (the scheduler hands them out in this order)."""
    bounds, start = [], 0
    while start < n:
        size = min(MAX_DASK_CHUNK, max(CHUNK, -(-(n - start) // (4 * slots))))
        bounds.append((start, min(start + size, n)))
        start += size
    return bounds


def _on_dask(address, setup, shared, trial, tasks, progress) -> list:
    connection = _OPEN.get(address)
    temporary = connection is None
    if temporary:
        connection = _Connection(address)
    from concurrent.futures import CancelledError

    from distributed import KilledWorker, wait

    try:
        client = connection.client
        token = uuid.uuid4().hex
        shared_on_workers = [connection.send(x) for x in shared]
        chunks = [tasks[a:b] for a, b in guided_chunks(len(tasks), sum(client.nthreads().values()) or 1)]
        futures = {client.submit(_dask_chunk, token, setup, trial, chunk, *shared_on_workers, pure=False): i
                   for i, chunk in enumerate(chunks)}
        results: list = [None] * len(chunks)
        done, pending = 0, set(futures)
        while pending:
            try:
                finished, pending = wait(pending, timeout=WATCH_S, return_when="FIRST_COMPLETED")
            except TimeoutError:
                if connection.cluster is not None and not client.nthreads():
                    # a worker that exits with status 0 is not restarted: with none left, nothing
                    # would ever run the trials (a remote cluster's workers may come back)
                    raise RuntimeError(_WORKER_ENDED) from None
                continue
            except CancelledError:  # a chunk's inputs were lost with the workers that held them
                raise RuntimeError(_WORKER_ENDED) from None
            for future in finished:
                i = futures[future]
                try:
                    chunk = future.result()  # a trial's own exception raised here as it was
                except (KilledWorker, CancelledError):  # the workers running it died, or its inputs with them
                    raise RuntimeError(_WORKER_ENDED) from None
                results[i] = pickle.loads(chunk)  # what the workers return, as Dask itself would unpickle it
                done += len(chunks[i])
                if progress:
                    progress(done, len(tasks))
        return [r for chunk in results for r in chunk]
    finally:
        if temporary:
            connection.close()
