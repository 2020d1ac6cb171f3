"""A run: lock the folder, find what is missing, label it through an executor, write the parts.

:func:`generate` takes a lock on the folder, reads the ``index`` column of every part, and labels
only the missing indices of ``range(count)``; records are buffered here and written as a part
every ``part_size`` records or ``flush_s`` seconds, and on the way out (Ctrl-C, SIGTERM, a dead
worker). No index is computed twice or lost.
"""
from __future__ import annotations

import math
import os
import socket
import sys
import time
import uuid
from pathlib import Path

import numpy as np

from .. import __version__
from ..errors import BadInput
from . import execute, storage
from .label import chunks, label_beam
from .schema import FLUSH_S, PART_SIZE


def _fmt_duration(seconds: float) -> str:
    if not math.isfinite(seconds):
        return "?"
    seconds = int(round(seconds))
    h, rest = divmod(seconds, 3600)
    m, s = divmod(rest, 60)
    return f"{h}h{m:02d}m" if h else (f"{m}m{s:02d}s" if m else f"{s}s")


class Progress:
    """tqdm bar (rate, ETA) on a terminal; a quiet line every ``every`` seconds otherwise."""

    def __init__(self, mode: str, total: int, initial: int, stream=None, every: float = 30.0):
        self.stream = stream or sys.stderr
        if mode == "auto":
            mode = "bar" if getattr(self.stream, "isatty", lambda: False)() else "log"
        self.mode, self.total, self.initial, self.n, self.errors = mode, total, initial, 0, 0
        self.every, self.t0, self.last = every, time.monotonic(), time.monotonic()
        self.bar = None

    def start(self) -> None:
        """The workers are ready: rates and ETA count from now."""
        self.t0 = self.last = time.monotonic()
        if self.mode == "bar":
            from tqdm import tqdm

            self.bar = tqdm(total=self.total, initial=self.initial, unit="beam",
                            file=self.stream, dynamic_ncols=True, smoothing=0.05)

    def log(self, text: str) -> None:
        if self.mode == "none":
            return
        if self.bar is not None:
            self.bar.write(text, file=self.stream)
        else:
            self.stream.write(f"prbdm dataset: {text}\n")
            self.stream.flush()

    def update(self, rec: dict) -> None:
        self.n += 1
        self.errors += rec.get("status") != "ok"
        if self.bar is not None:
            self.bar.update(1)
            if rec.get("status") != "ok":
                self.bar.set_postfix(errors=self.errors, refresh=False)
        elif self.mode == "log" and time.monotonic() - self.last >= self.every:
            self.last = time.monotonic()
            self.log(self.status())

    def status(self) -> str:
        elapsed = max(time.monotonic() - self.t0, 1e-9)
        rate = self.n / elapsed
        left = self.total - self.initial - self.n
        eta = left / rate if rate > 0 else float("nan")
        return (f"{self.initial + self.n}/{self.total} beams ({self.errors} errors this run), "
                f"{rate:.2f} beams/s, ETA {_fmt_duration(eta)}")

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def _check_args(count, workers, scheduler, part_size):
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 0:
        raise BadInput(f"--count: must be an integer >= 0, got {count!r}")
    if workers is None:
        workers = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (
            os.cpu_count() or 1)
    if isinstance(workers, bool) or not isinstance(workers, (int, np.integer)) or workers < 0:
        raise BadInput(f"--workers: must be an integer >= 0, got {workers!r}")
    if scheduler == "local" and workers < 1:
        raise BadInput("--workers: a local Dask cluster needs at least 1 worker")
    if part_size < 1:
        raise BadInput(f"--part-size: must be an integer >= 1, got {part_size!r}")
    return int(workers)


def generate(out, count: int, spec: dict, workers: int | None = None, scheduler=None,
             part_size: int = PART_SIZE, flush_s: float = FLUSH_S, progress: str = "auto",
             labeller=label_beam, stream=None) -> dict:
    """Label beams ``0 .. count-1`` of ``spec`` into folder ``out``, resuming what is there.

    ``workers``: processes of the local pool (default: the usable cores); ``0`` labels in this
    process (debugging). ``scheduler``: None (local pool), ``"local"`` (a Dask LocalCluster of
    ``workers`` processes), a Dask scheduler address such as ``"tcp://host:8786"``, or a
    ``dask.distributed.Client``. ``progress``: auto, bar, log or none. ``labeller`` must be a
    picklable ``(index, spec) -> record`` (default :func:`label_beam`, whose chunks are fitted
    in one batch by :func:`label_beams`; a custom labeller is called once per index).

    Tasks are chunks of ``spec["fit_batch"]`` consecutive indices (see :func:`chunks`); the
    value, and the ``objective``, come from the set when ``spec`` has none (1 and eigenvalue for
    a set made before they existed, :data:`DEFAULT_FIT_BATCH` and eigenvalue for a new set).

    Returns a summary dict (see ``prbdm dataset generate --json``). Raises BadInput for a spec that
    differs from the folder's, RuntimeError when a worker process dies (what was done is kept).
    """
    workers = _check_args(count, workers, scheduler, part_size)
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise BadInput(f"--out: {out} exists and is not a folder")
    out.mkdir(parents=True, exist_ok=True)
    t_start = time.monotonic()
    versions, commit = storage.versions(), storage.git_commit()

    with storage.FolderLock(out):
        manifest, spec = storage.open_set(out, spec, int(count), versions, commit)
        storage.remove_temporaries(out)
        existing = storage.existing_indices(out)
        done = np.zeros(count, dtype=bool)
        done[existing[existing < count]] = True
        todo = np.flatnonzero(~done).tolist()
        fit_batch = int(spec["fit_batch"])
        tasks = chunks(todo, fit_batch)
        columns = storage.set_columns(manifest)
        next_part = storage.next_part_number(out)
        run = {"id": uuid.uuid4().hex[:12], "started": storage.now(), "finished": None,
               "count": int(count), "todo": len(todo), "written": 0, "errors": 0,
               "fit_batch": fit_batch, "workers": None,
               "scheduler": None if scheduler is None else (
                   scheduler if isinstance(scheduler, str) else "dask client"),
               "host": socket.gethostname(), "versions": versions, "git_commit": commit}
        if (manifest["versions"] != versions or manifest["git_commit"] != commit) and todo:
            _say(progress, stream, "note: this run's package versions or git commit differ "
                 "from the set's creation (each run is recorded in the manifest)")
        metadata = {"prbdm.version": __version__, "prbdm.git_commit": str(commit),
                    "prbdm.run": run["id"]}
        buffer: list[dict] = []
        meter = Progress(progress, total=int(count), initial=int(count) - len(todo),
                         stream=stream)
        # only a pool keeps torch out of this process (a Dask client may hold in-process workers)
        restore_threads = _torch_threads() if scheduler is not None or workers == 0 else None
        # start the backend first: a scheduler that is refused or a pool that fails to start
        # raises here, before the manifest is written, so it is left as it was
        backend = (execute.open_backend(workers, scheduler, warm=labeller is label_beam)
                   if todo else None)
        t_ready = time.monotonic()
        last_flush = time.monotonic()

        def flush():
            nonlocal next_part, last_flush
            if buffer:
                # idempotent if interrupted anywhere: until the buffer is cleared, a second call
                # rewrites the same part number with the same records
                storage.write_part(out, next_part, buffer, metadata, columns)
                written = len(buffer)
                errors = sum(r.get("status") != "ok" for r in buffer)
                buffer.clear()
                next_part += 1
                run["written"] += written
                run["errors"] += errors
                storage.write_manifest(out, manifest)  # the run's progress, for `info` after a crash
            last_flush = time.monotonic()

        records = (execute.run_tasks(backend, tasks, spec, labeller) if backend is not None
                   else iter(()))
        try:
            if backend is not None:
                run["workers"] = backend.threads()
                if scheduler is not None:
                    run["scheduler"] = backend.where
            manifest["count"] = max(int(manifest["count"]), int(count))
            manifest["runs"].append(run)
            storage.write_manifest(out, manifest)
            if backend is not None:
                meter.log(f"{len(todo)} beams to label ({int(count) - len(todo)} already in "
                          f"{out}) in {len(tasks)} tasks of up to {fit_batch}, "
                          f"{run['workers']} workers ({backend.where}, ready in "
                          f"{t_ready - t_start:.1f} s)")
                meter.start()
            for rec in records:
                buffer.append(rec)
                meter.update(rec)
                if len(buffer) >= part_size or time.monotonic() - last_flush >= flush_s:
                    flush()
            flush()
        finally:
            try:
                flush()  # Ctrl-C or a dead worker: keep what is done
            finally:
                if hasattr(records, "close"):
                    records.close()
                if backend is not None:
                    backend.close()
                meter.close()
                if restore_threads is not None:
                    restore_threads()
        run["finished"] = storage.now()
        run["wall_s"] = round(time.monotonic() - t_start, 3)
        storage.write_manifest(out, manifest)
        idx = storage.existing_indices(out)

    labelled = time.monotonic() - t_ready
    summary = {"out": str(out), "count": int(count), "records": int(np.unique(idx).size),
               "new": run["written"], "new_errors": run["errors"],
               "missing": int(count - np.unique(idx[idx < count]).size),
               "parts": len(storage.part_files(out)), "fit_batch": fit_batch,
               "objective": spec["objective"], "workers": run["workers"],
               "scheduler": run["scheduler"], "wall_s": run["wall_s"],
               "startup_s": round(t_ready - t_start, 3), "labelling_s": round(labelled, 3),
               "beams_per_s": (run["written"] / labelled) if run["written"] and labelled > 0
               else None}
    meter.log(f"done: {summary['new']} new records ({summary['new_errors']} errors) in "
              f"{summary['wall_s']:.1f} s; {summary['records']} in the set")
    return summary


def _say(progress: str, stream, text: str) -> None:
    if progress != "none":
        (stream or sys.stderr).write(f"prbdm dataset: {text}\n")


def _torch_threads():
    """In-process labelling sets torch to one thread; give the caller its setting back after."""
    if "torch" not in sys.modules:
        return None
    import torch

    n = torch.get_num_threads()
    return lambda: torch.set_num_threads(n)
