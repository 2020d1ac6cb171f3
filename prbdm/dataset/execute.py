"""Execution: one loop over a ``concurrent.futures.Executor``, whichever runs the tasks.

Three executors share the interface (``submit`` returns a ``concurrent.futures.Future``):

- :class:`InlineExecutor`: this process, each task run at ``submit`` (``--workers 0``);
- ``ProcessPoolExecutor``: a local pool of spawned workers, one thread each, torch only in them;
- ``distributed.Client.get_executor()``: a Dask cluster (an address, or ``"local"`` for a
  LocalCluster).

:func:`open_backend` starts one and checks its workers can run prbdm (a failure raises before the
run writes anything); :func:`run_tasks` keeps a window of tasks in flight and yields the records
as tasks finish. The records come back to the parent, which alone writes the folder, so workers
need no shared file system.
"""
from __future__ import annotations

import contextlib
import os
import signal
import socket
import threading
import time
from concurrent.futures import FIRST_COMPLETED, Executor, Future, wait
from concurrent.futures.process import BrokenProcessPool

from .. import __version__
from ..errors import BadInput
from .label import chunk_failure, label_beam, label_chunk, torch_one_thread

_THREAD_VARS = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")
#: how long to try to reach a Dask scheduler address before refusing the run [s]
CONNECT_TIMEOUT_S = 20
#: tasks in flight per worker: one running, one queued, so a worker never waits for the parent
TASKS_PER_WORKER = 2
#: a Dask cluster's size is asked again after this many finished tasks (workers join and leave)
RESIZE_EVERY = 16


@contextlib.contextmanager
def one_thread_children():
    """Children started inside this block see one-thread BLAS/OpenMP (unless the user chose)."""
    saved = {k: os.environ.get(k) for k in _THREAD_VARS}
    for k in _THREAD_VARS:
        os.environ.setdefault(k, "1")
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _init_worker() -> None:
    """In each pool worker: leave Ctrl-C to the parent, and exit when the parent dies (a
    kill -9 of the parent would otherwise leave the worker blocked on its queue forever)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    parent = os.getppid()

    def watch():
        while os.getppid() == parent:
            time.sleep(0.5)
        os._exit(1)

    threading.Thread(target=watch, name="prbdm-parent-watch", daemon=True).start()


def worker_ready(warm: bool = False) -> dict:
    """Start-up probe; ``warm`` imports the truth and fit (torch) now, so that start-up time is
    not charged to the first beams."""
    if warm:
        from .. import fit, truth  # noqa: F401

        torch_one_thread()
    return {"pid": os.getpid(), "host": socket.gethostname(), "prbdm": __version__}


class InlineExecutor(Executor):
    """Runs each task in this process when it is submitted; the future comes back done."""

    def submit(self, fn, /, *args, **kwargs):
        f = Future()
        f.set_running_or_notify_cancel()
        try:
            f.set_result(fn(*args, **kwargs))
        except Exception as exc:  # noqa: BLE001 - delivered through the future, like a pool's
            f.set_exception(exc)
        return f


class Backend:
    """An executor, how many tasks it runs at once, where it runs, and how to close it."""

    def __init__(self, executor: Executor, where: str, threads, close=None, window=None):
        self.executor, self.where, self._threads = executor, where, threads
        self._close, self._window = close, window

    def threads(self) -> int:
        return self._threads()

    def window(self) -> int:
        """Tasks to keep in flight."""
        return self._window or TASKS_PER_WORKER * self.threads()

    def close(self) -> None:
        """Stop without waiting: an interrupted run must not wait for tasks nobody will read."""
        if self._close is not None:
            self._close()


def open_backend(workers: int, scheduler=None, warm: bool = True) -> Backend:
    """The executor for ``workers`` (0: this process) or a Dask ``scheduler`` (an address,
    ``"local"``, or a ``distributed.Client``), its workers started and checked."""
    if scheduler is not None:
        return _dask_backend(workers, scheduler, warm)
    if workers < 1:
        # one task at a time: records are written as soon as they exist, as a pool's are
        return Backend(InlineExecutor(), "in-process", lambda: 1, window=1)
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    with one_thread_children():
        pool = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"),
                                   initializer=_init_worker)
        try:
            for f in [pool.submit(worker_ready, warm) for _ in range(workers)]:
                f.result()
        except BaseException:
            pool.shutdown(wait=False, cancel_futures=True)
            raise
    return Backend(pool, "process pool", lambda: workers,
                   close=lambda: pool.shutdown(wait=False, cancel_futures=True))


def _dask_backend(workers: int, scheduler, warm: bool) -> Backend:
    import logging

    from dask.distributed import Client, LocalCluster

    owned = []
    if isinstance(scheduler, Client):
        client = scheduler
    elif scheduler == "local":
        with one_thread_children():
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                   dashboard_address=None, silence_logs=logging.ERROR)
        client = Client(cluster)
        owned = [client.close, cluster.close]      # a user's client is left open
    else:
        try:
            client = Client(scheduler, timeout=f"{CONNECT_TIMEOUT_S}s")
        except (OSError, TimeoutError, ValueError) as exc:
            raise BadInput(f"--scheduler: cannot connect to {scheduler!r} "
                           f"({type(exc).__name__}: {exc})") from None
    executor = client.get_executor(pure=False)
    try:
        client.wait_for_workers(1, timeout=120)
        executor.submit(worker_ready, warm).result(timeout=300)
    except BaseException as exc:
        for close in owned:
            close()
        if not isinstance(exc, Exception):     # Ctrl-C
            raise
        raise BadInput(f"--scheduler: the cluster cannot run prbdm tasks ({type(exc).__name__}: "
                       f"{exc}); are workers up, with prbdm installed?") from None
    threads = lambda: max(1, sum(client.nthreads().values()))  # noqa: E731

    def close():
        executor.shutdown(wait=False)                   # cancels the tasks still in flight
        for thing in owned:
            thing()

    return Backend(executor, f"dask {client.scheduler_info()['address']}", threads, close)


def run_tasks(backend: Backend, tasks, spec: dict, labeller=label_beam):
    """Yield the records of ``tasks`` (chunks of indices) as they are labelled: at most
    ``backend.window()`` tasks in flight; a task that fails outside the labeller becomes one
    error record per index, except a dead local worker, which stops the run (RuntimeError)."""
    todo, pending, finished = iter(tasks), {}, 0
    window = backend.window()
    try:
        while True:
            while len(pending) < window and (c := next(todo, None)) is not None:
                pending[backend.executor.submit(label_chunk, c, spec, labeller)] = c
            if not pending:
                return
            done, _ = wait(pending, return_when=FIRST_COMPLETED)
            for f in sorted(done, key=lambda f: pending[f][0]):
                c = pending.pop(f)
                try:
                    records = f.result()
                except BrokenProcessPool:
                    raise RuntimeError("a worker process died (out of memory? killed?); the "
                                       "records written so far are kept: run the same command "
                                       "again to go on") from None
                except Exception as exc:  # noqa: BLE001 - e.g. Dask's KilledWorker
                    records = chunk_failure(c, exc)
                yield from records
                finished += 1
                if finished % RESIZE_EVERY == 0:
                    window = backend.window()
    finally:
        for f in pending:
            f.cancel()
