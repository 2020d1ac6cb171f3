"""Labelled data sets of random beams: generation, storage, resume, summary.

A data set is a folder::

    DIR/_manifest.json        the spec, seed, count, package versions, git commit, runs
    DIR/part-000000.parquet   records, one per beam index, flat columns (lists for arrays)
    DIR/part-000001.parquet   ...

Read it without prbdm: ``pandas.read_parquet(DIR)`` or ``pyarrow.parquet.read_table(DIR)`` (they
skip names starting with ``_`` or ``.``, which is why the manifest is ``_manifest.json``).

How it works, in the order of this file:

1. **Spec.** :func:`make_spec` fixes everything that decides a record: the random-beam generator
   and its seed (SPEC §1), the truth model and its mode count, the PRBDM (joints, modes, law,
   poses, starts). A later run on the same folder must ask for the same spec, or it is refused
   naming the first differing field. The count is not part of the spec: asking for more extends
   the set.
2. **Labelling.** :func:`label_beam` ``(index, spec) -> dict`` is a pure, picklable, module-level
   function: rebuild beam ``index``, compute its truth, fit the PRBDM. Any exception becomes a
   record with ``status = "error"`` and the message, so one bad beam never stops a run.
   :func:`label_beams` labels a chunk of beams with one batched fit (``fit_many``, each beam with
   its own seed), which costs less CPU per beam; if the batched fit fails it fits the chunk's
   beams one at a time, so one bad beam is still one error record. A task is a chunk of
   ``spec["fit_batch"]`` consecutive indices with fixed boundaries (chunk c holds
   ``[c B, (c + 1) B)``, less what is already stored).
3. **Storage.** Records are buffered by the parent process and written as a part file, atomically
   (temporary file, then rename), every ``part_size`` records or ``flush_s`` seconds. A kill -9 at
   any moment loses at most the buffered records, never leaves a half-written part.
4. **Execution.** A local process pool by default (spawned workers, one thread each, torch only in
   the workers); ``scheduler=`` sends the same tasks to a Dask distributed cluster (an address, or
   ``"local"`` for a LocalCluster). Results come back to the parent, which alone writes the folder,
   so the workers need no shared file system.
5. **Resume.** :func:`generate` takes a lock on the folder, reads the ``index`` column of every
   part, and labels only the missing indices of ``range(count)``. No index is computed twice or
   lost.
6. **Summary.** :func:`info` counts records, failures, the loss distribution and time per beam.
"""
from __future__ import annotations

import contextlib
import datetime as _dt
import json
import math
import os
import socket
import subprocess
import sys
import time
import uuid
from pathlib import Path

import numpy as np

from . import __version__
from .errors import BadInput
from .geometry import RANDOM_DEFAULTS, Material, random_beam

__all__ = ["make_spec", "label_beam", "label_beams", "generate", "info", "read_table", "read_manifest",
           "MANIFEST", "FORMAT_VERSION", "COLUMNS"]

MANIFEST = "_manifest.json"
FORMAT = "prbdm-dataset"
FORMAT_VERSION = 1
TRUTH_MODELS = ("beam", "plate")
LAWS = ("beam", "paper")
#: beams per batched fit (one task) for a new data set when --fit-batch is not given: measured
#: best on 2 cores (benchmarks/bench_dataset.py); a set without ``fit_batch`` in its spec (made
#: before chunking) is labelled one beam per task, as it was
DEFAULT_FIT_BATCH = 8
MAX_FIT_BATCH = 256
#: default number of records per part file, and the longest a record waits in memory [s]
PART_SIZE = 256
FLUSH_S = 60.0
#: fit multistart points when --starts is not given: prbdm.fit.DEFAULT_STARTS when this was
#: written (not imported, to keep torch out of the parent); a spec records the number it used
DEFAULT_STARTS = 64


# ====================================================================== 1. the spec

#: spec field -> the command-line flag that sets it (for error messages)
FLAGS = {"seed": "--seed", "joints": "--joints", "modes": "--modes", "truth": "--truth",
         "truth_modes": "--modes", "law": "--law", "poses": "--poses", "starts": "--starts",
         "beam.p": "--stations", "beam.min_half_width": "--min-half-width",
         "fit_batch": "--fit-batch"}


def make_spec(joints: int, modes: int | None = None, truth: str = "beam", law: str = "beam",
              poses="paper", starts: int | None = None, seed: int = 0, p: int | None = None,
              min_half_width: float | None = None, truth_modes: int | None = None,
              material: Material | None = None, fit_batch: int | None = None) -> dict:
    """The JSON-able description of a data set: everything that decides a record.

    ``modes`` (default ``joints``) is the number of truth modes the fit maps; the truth is computed
    with ``truth_modes = max(modes, joints) + 1`` modes (all stored). ``poses`` is ``"paper"``,
    ``"linear"`` or a list of joint angles [rad]. ``starts=None`` means :data:`DEFAULT_STARTS`;
    ``starts=0`` makes a *truth-only* set: geometry and truth frequencies, no fit (the fit columns
    are null). That is all the surrogate's physics training needs, at about 1/100 of the cost.
    ``fit_batch``: beams per batched fit; None (the key is then absent) means the folder's value
    for an existing set (1 if it has none) and :data:`DEFAULT_FIT_BATCH` for a new one.
    """
    def integer(name, v, lo):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < lo:
            raise BadInput(f"{FLAGS.get(name, name)}: must be an integer >= {lo}, got {v!r}")
        return int(v)

    joints = integer("joints", joints, 1)
    modes = joints if modes is None else integer("modes", modes, 1)
    truth_modes = (max(modes, joints) + 1 if truth_modes is None
                   else integer("truth_modes", truth_modes, max(modes, joints)))
    if truth not in TRUTH_MODELS:
        raise BadInput(f"--truth: must be one of {', '.join(TRUTH_MODELS)} for random beams, "
                       f"got {truth!r}")
    if law not in LAWS:
        raise BadInput(f"--law: must be one of {', '.join(LAWS)}, got {law!r}")
    if isinstance(poses, str):
        if poses not in ("paper", "linear"):
            raise BadInput(f"--poses: must be paper, linear or a list of angles, got {poses!r}")
    else:
        poses = [float(t) for t in poses]
        if not poses or not all(math.isfinite(t) for t in poses):
            raise BadInput("--poses: must be a non-empty list of finite angles [rad]")
    starts = DEFAULT_STARTS if starts is None else integer("starts", starts, 0)
    seed = integer("seed", seed, 0)
    gen = dict(RANDOM_DEFAULTS)
    if p is not None:
        gen["p"] = integer("beam.p", p, 0)
    if min_half_width is not None:
        if not (isinstance(min_half_width, (int, float)) and
                0 <= min_half_width < gen["max_half_width"]):
            raise BadInput(f"--min-half-width: must lie in [0, {gen['max_half_width']}) m, "
                           f"got {min_half_width!r}")
        gen["min_half_width"] = float(min_half_width)
    gen["material"] = (material or Material()).to_dict()
    spec = {"seed": seed, "beam": gen, "truth": truth, "truth_modes": truth_modes,
            "joints": joints, "modes": modes, "law": law, "poses": poses, "starts": starts}
    if fit_batch is not None:
        spec["fit_batch"] = _fit_batch(fit_batch)
    return spec


def _fit_batch(value) -> int:
    if (isinstance(value, bool) or not isinstance(value, (int, np.integer))
            or not 1 <= value <= MAX_FIT_BATCH):
        raise BadInput(f"--fit-batch: must be an integer in [1, {MAX_FIT_BATCH}], got {value!r}")
    return int(value)


def _flatten(d: dict, prefix: str = "") -> dict:
    out = {}
    for key, value in d.items():
        if isinstance(value, dict):
            out.update(_flatten(value, f"{prefix}{key}."))
        else:
            out[f"{prefix}{key}"] = value
    return out


def spec_difference(old: dict, new: dict) -> str | None:
    """The first field where two specs differ, as ``"name: old vs new"``; None when equal."""
    a, b = _flatten(old), _flatten(new)
    for key in sorted(set(a) | set(b)):
        if a.get(key, "<absent>") != b.get(key, "<absent>"):
            return key
    return None


def beam_for(spec: dict, index: int):
    """Beam ``index`` of a data set: a pure function of (spec seed, generator options, index)."""
    gen = dict(spec["beam"])
    material = Material(**gen.pop("material"))
    return random_beam(spec["seed"], index, material=material, **gen)


# ====================================================================== 2. labelling one beam

#: the record columns, in order: name -> (pyarrow type name, meaning)
COLUMNS = {
    "index": ("int64", "beam number; the beam is random_beam(seed, index, **spec.beam)"),
    "status": ("string", "ok, or error (then `error` says which stage failed and why)"),
    "error": ("string", "'stage: ExceptionType: message', null when ok"),
    "x": ("list<double>", "planform stations [m], x[0] = 0, x[-1] = L"),
    "half_width": ("list<double>", "half-width at each station [m]"),
    "thickness": ("double", "uniform thickness [m]"),
    "length": ("double", "L [m]"),
    "mass": ("double", "beam mass [kg]"),
    "omega_truth": ("list<double>", "truth bending frequencies, ascending [rad/s] (truth_modes)"),
    "truth_time_s": ("double", "wall time of the truth solve [s]"),
    "gamma": ("list<double>", "fitted link lengths / L (joints + 1), sum 1"),
    "k": ("list<double>", "fitted stiffness correction factor per pose"),
    "loss_percent": ("double", "fit loss, SPEC §3 [%]"),
    "gamma_spread": ("double", "spread of gamma among near-best starts (ambiguity of the label)"),
    "n_near_best": ("int64", "starts within 1 % of the best loss"),
    "freq_error_max": ("list<double>", "per mapped mode, worst relative frequency error of the "
                       "poses"),
    "fit_time_s": ("double", "wall time of the fit [s]"),
    "fit_seed": ("int64", "seed given to the fit's multistart"),
    "time_s": ("double", "wall time to label the beam, all stages [s]"),
    "cpu_s": ("double", "CPU time of the labelling thread [s]; 1 / cpu_s is the rate of a free "
              "core"),
    "worker": ("string", "host:pid that labelled it"),
}


def _arrow_schema(metadata: dict | None = None):
    import pyarrow as pa

    types = {"int64": pa.int64(), "string": pa.string(), "double": pa.float64(),
             "list<double>": pa.list_(pa.float64())}
    return pa.schema([pa.field(name, types[t]) for name, (t, _) in COLUMNS.items()],
                     metadata=metadata)


def _fit_seed(spec: dict, index: int) -> int:
    """A 32-bit seed for the fit of beam ``index``, independent of every other beam's."""
    return int(np.random.SeedSequence([spec["seed"], index, 0x5EED]).generate_state(1)[0])


def _torch_one_thread() -> None:
    import torch

    if torch.get_num_threads() != 1:
        torch.set_num_threads(1)


def _floats(values) -> list[float]:
    return [float(v) for v in np.asarray(values, dtype=np.float64).ravel()]


def _new_record(index: int) -> dict:
    return {"index": int(index), "status": "error", "error": None,
            "worker": f"{socket.gethostname()}:{os.getpid()}"}


def _beam_and_truth(rec: dict, spec: dict, stage: list):
    """The stages before the fit, into ``rec``: returns (beam, omega). ``stage[0]`` names the
    stage running (beam, truth, then fit once both are done), for the error of a failure."""
    stage[0] = "beam"
    beam = beam_for(spec, rec["index"])
    rec.update(x=beam.x.tolist(), half_width=beam.half_width.tolist(),
               thickness=beam.thickness, length=beam.length, mass=beam.mass)
    stage[0] = "truth"
    from .truth import bending_frequencies

    tr = bending_frequencies(beam, model=spec["truth"], modes=spec["truth_modes"])
    omega = np.asarray(tr.omega, dtype=np.float64)
    rec.update(omega_truth=_floats(omega), truth_time_s=float(tr.time_s))
    if omega.size < spec["modes"] or not np.all(np.isfinite(omega)):
        raise ValueError(f"{omega.size} finite modes, the fit maps {spec['modes']}")
    stage[0] = "fit"
    return beam, omega


def _fit_fields(rec: dict, fr, seed: int) -> None:
    """Copy a FitResult into the record; a non-finite loss raises (the record is an error)."""
    freq_error = np.abs(np.asarray(fr.freq_error, dtype=np.float64))
    rec.update(gamma=_floats(fr.gamma), k=_floats(fr.k), loss_percent=float(fr.loss_percent),
               gamma_spread=float(fr.gamma_spread), n_near_best=int(fr.n_near_best),
               freq_error_max=_floats(freq_error.reshape(-1, freq_error.shape[-1]).max(axis=0)),
               fit_time_s=float(fr.time_s), fit_seed=seed)
    if not math.isfinite(rec["loss_percent"]):
        raise ValueError(f"non-finite loss {rec['loss_percent']!r}")
    rec["status"] = "ok"


def _fit_kwargs(spec: dict) -> dict:
    return dict(joints=spec["joints"], modes=spec["modes"], law=spec["law"],
                poses=spec["poses"], starts=spec["starts"])


def label_beam(index: int, spec: dict) -> dict:
    """Label beam ``index``: geometry, truth frequencies, fitted PRBDM, timings, status.

    Never raises for a beam that fails: the record gets ``status = "error"`` and ``error`` set to
    ``"stage: ExceptionType: message"`` (stage is beam, truth or fit). Runs torch on one thread.
    """
    t0, c0 = time.perf_counter(), time.thread_time()
    rec, stage = _new_record(index), ["beam"]
    try:
        beam, omega = _beam_and_truth(rec, spec, stage)
        if spec["starts"] == 0:             # a truth-only set: no fit
            rec["status"] = "ok"
            return _timed(rec, t0, c0)
        _torch_one_thread()
        from .fit import fit_prbdm

        seed = _fit_seed(spec, int(index))
        fr = fit_prbdm(beam, omega, seed=seed, **_fit_kwargs(spec))
        _fit_fields(rec, fr, seed)
    except Exception as exc:  # noqa: BLE001 - failure isolation: record it, go on
        rec["error"] = _error_text(stage[0], exc)
    return _timed(rec, t0, c0)


def _timed(rec: dict, t0: float, c0: float) -> dict:
    rec["time_s"] = time.perf_counter() - t0
    rec["cpu_s"] = time.thread_time() - c0
    return rec


def label_beams(indices, spec: dict) -> list[dict]:
    """Label several beams with one batched fit: the records of :func:`label_beam`, in order.

    Geometry and truth are computed beam by beam; the beams whose truth succeeded are fitted
    together by one :func:`prbdm.fit.fit_many` call, each with its own seed ``_fit_seed(spec,
    index)`` (so its start points are the ones :func:`label_beam` uses). ``fit_time_s`` and the
    fit's share of ``time_s`` and ``cpu_s`` are the batch's time divided equally among its beams.
    If the batched fit raises, each of its beams is fitted alone, so a beam that breaks the fit is
    one error record. One index: exactly :func:`label_beam`.
    """
    indices = [int(i) for i in indices]
    if len(indices) == 1 or spec["starts"] == 0:
        return [label_beam(i, spec) for i in indices]
    records, ready = [], []          # ready: (record, beam, omega) of beams to fit
    for i in indices:
        t0, c0 = time.perf_counter(), time.thread_time()
        rec, stage = _new_record(i), ["beam"]
        try:
            beam, omega = _beam_and_truth(rec, spec, stage)
            ready.append((rec, beam, omega))
        except Exception as exc:  # noqa: BLE001 - failure isolation
            rec["error"] = _error_text(stage[0], exc)
        rec["time_s"] = time.perf_counter() - t0
        rec["cpu_s"] = time.thread_time() - c0
        records.append(rec)
    if not ready:
        return records
    _torch_one_thread()
    from .fit import fit_many, fit_prbdm

    seeds = [_fit_seed(spec, rec["index"]) for rec, _, _ in ready]
    t0, c0 = time.perf_counter(), time.thread_time()
    try:
        r = spec["modes"]
        omega = np.stack([o[:r] for _, _, o in ready])
        results = fit_many([b for _, b, _ in ready], omega, seed=seeds, **_fit_kwargs(spec))
    except Exception:  # noqa: BLE001 - fall back to one fit per beam, below
        results = None
    wall, cpu = time.perf_counter() - t0, time.thread_time() - c0
    for (rec, beam, omega), seed, j in zip(ready, seeds, range(len(ready))):
        rec["time_s"] += wall / len(ready)
        rec["cpu_s"] += cpu / len(ready)
        t1, c1 = time.perf_counter(), time.thread_time()
        try:
            fr = (results[j] if results is not None else
                  fit_prbdm(beam, omega, seed=seed, **_fit_kwargs(spec)))
            _fit_fields(rec, fr, seed)
        except Exception as exc:  # noqa: BLE001 - failure isolation
            rec["error"] = _error_text("fit", exc)
        rec["time_s"] += time.perf_counter() - t1
        rec["cpu_s"] += time.thread_time() - c1
    return records


def label_chunk(indices, spec: dict, labeller=None) -> list[dict]:
    """One task: the records of ``indices``. With the default labeller (:func:`label_beam`), one
    batched fit (:func:`label_beams`); a custom ``(index, spec) -> record`` labeller is called
    once per index."""
    if labeller is None or labeller is label_beam:
        return label_beams(indices, spec)
    return [labeller(int(i), spec) for i in indices]


def chunks(indices, size: int) -> list[list[int]]:
    """Group sorted ``indices`` into tasks with fixed boundaries: chunk c holds the given indices
    in ``[c size, (c + 1) size)``, so a resumed run fits a partly written chunk's missing beams
    together, and never mixes them with another chunk's."""
    out: list[list[int]] = []
    for i in indices:
        if out and out[-1][0] // size == i // size:
            out[-1].append(int(i))
        else:
            out.append([int(i)])
    return out


def _error_text(stage: str, exc: BaseException) -> str:
    text = f"{stage}: {type(exc).__name__}: {exc}".replace("\n", " ")
    return text if len(text) <= 500 else text[:497] + "..."


def _worker_failure(index: int, exc: BaseException) -> dict:
    """The record of a task that died outside label_beam (a lost worker, an unpicklable result)."""
    return {"index": int(index), "status": "error", "error": _error_text("worker", exc)}


def _chunk_failure(chunk, exc: BaseException) -> list[dict]:
    return [_worker_failure(i, exc) for i in chunk]


# ====================================================================== 3. storage

def read_manifest(out) -> dict:
    path = Path(out) / MANIFEST
    try:
        manifest = json.loads(path.read_text())
    except FileNotFoundError:
        raise BadInput(f"DIR: {str(out)!r} is not a prbdm data set (no {MANIFEST})") from None
    except json.JSONDecodeError as exc:
        raise BadInput(f"DIR: {path} is not valid JSON ({exc.msg})") from None
    if not isinstance(manifest, dict) or manifest.get("format") != FORMAT:
        raise BadInput(f"DIR: {path} is not a prbdm data set manifest")
    if manifest.get("format_version", 0) > FORMAT_VERSION:
        raise BadInput(f"DIR: format version {manifest['format_version']} is newer than this "
                       f"prbdm understands ({FORMAT_VERSION}); upgrade prbdm")
    return manifest


def _atomic_write(path: Path, data: bytes | str) -> None:
    """Whole or not at all: a hidden temporary file beside ``path`` (``.NAME.*.tmp``), flushed
    to disk, then renamed over ``path``; mode 0644 like any data file."""
    import tempfile

    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data.encode() if isinstance(data, str) else data)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _write_manifest(out: Path, manifest: dict) -> None:
    _atomic_write(out / MANIFEST, json.dumps(manifest, indent=1, allow_nan=False) + "\n")


def part_files(out) -> list[Path]:
    return sorted(Path(out).glob("part-*.parquet"))


def _write_part(out: Path, number: int, records: list[dict], metadata: dict) -> Path:
    """Write ``records`` (sorted by index) as ``part-NNNNNN.parquet``, whole or not at all."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    records = sorted(records, key=lambda r: r["index"])
    table = pa.Table.from_pylist(records, schema=_arrow_schema(metadata))
    sink = pa.BufferOutputStream()
    pq.write_table(table, sink, compression="zstd")
    path = out / f"part-{number:06d}.parquet"
    _atomic_write(path, sink.getvalue().to_pybytes())
    return path


def _existing_indices(out: Path) -> np.ndarray:
    """Every ``index`` stored in the part files (duplicates kept, so they can be counted)."""
    import pyarrow.parquet as pq

    chunks = [pq.read_table(p, columns=["index"]).column("index").to_numpy()
              for p in part_files(out)]
    return np.concatenate(chunks) if chunks else np.zeros(0, dtype=np.int64)


def read_table(out, columns=None, status: str | None = None):
    """The whole data set as one pyarrow Table sorted by index (duplicates, if any, dropped)."""
    import pyarrow as pa
    import pyarrow.compute as pc
    import pyarrow.parquet as pq

    read_manifest(out)
    if columns is not None and "index" not in columns:
        columns = ["index", *columns]
    if status is not None and columns is not None and "status" not in columns:
        columns = [*columns, "status"]
    parts = [pq.read_table(p, columns=columns) for p in part_files(out)]
    if not parts:
        return _arrow_schema().empty_table().select(columns or list(COLUMNS))
    table = pa.concat_tables(parts).sort_by("index")
    idx = table.column("index").to_numpy()
    if idx.size > 1 and np.any(idx[1:] == idx[:-1]):
        table = table.take(np.flatnonzero(np.concatenate([[True], idx[1:] != idx[:-1]])))
    if status is not None:
        table = table.filter(pc.equal(table.column("status"), status))
    return table


class _FolderLock:
    """An exclusive lock on DIR/.lock (released by the OS when the process dies, kill -9 too)."""

    def __init__(self, out: Path):
        self.path = out / ".lock"
        self.fd = None

    def __enter__(self):
        try:
            import fcntl
        except ImportError:  # no advisory locks on this platform: trust the user
            return self
        self.fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(self.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            holder = Path(self.path).read_text().strip() or "?"
            os.close(self.fd)
            self.fd = None
            raise BadInput(f"--out: {self.path.parent} is being written by another run "
                           f"(pid {holder}); wait for it or stop it first") from None
        os.ftruncate(self.fd, 0)
        os.write(self.fd, str(os.getpid()).encode())
        return self

    def __exit__(self, *exc):
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None


# ---------------------------------------------------------------------- provenance

def _versions() -> dict:
    from importlib import metadata

    out = {"python": sys.version.split()[0], "prbdm": __version__}
    for dist in ("numpy", "scipy", "torch", "scikit-fem", "pyarrow", "dask", "distributed"):
        try:
            out[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            pass
    return out


def _git_commit() -> str | None:
    """The commit of the prbdm checkout, with ``+dirty`` for uncommitted changes; None if none."""
    here = Path(__file__).resolve().parent
    try:
        head = subprocess.run(["git", "-C", str(here), "rev-parse", "HEAD"], capture_output=True,
                              text=True, timeout=10)
        if head.returncode != 0:
            return None
        dirty = subprocess.run(["git", "-C", str(here), "status", "--porcelain",
                                "--untracked-files=no", "--", "."],
                               capture_output=True, text=True, timeout=10)
        return head.stdout.strip() + ("+dirty" if dirty.stdout.strip() else "")
    except (OSError, subprocess.SubprocessError):
        return None


def _now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")


def _open_set(out: Path, spec: dict, count: int, versions: dict, commit) -> tuple[dict, dict]:
    """The manifest of a new set (not written yet: :func:`generate` writes it once the workers
    are ready), or the existing one, checked to have the same spec.

    Returns (manifest, the spec of this run). ``fit_batch`` absent from ``spec`` means the set's
    value, absent from a set's spec (made before chunking) means 1; an existing manifest's spec
    is never rewritten."""
    if (out / MANIFEST).exists():
        manifest = read_manifest(out)
        stored = dict(manifest["spec"])
        stored.setdefault("fit_batch", 1)
        spec = {**spec, "fit_batch": spec.get("fit_batch", stored["fit_batch"])}
        field = spec_difference(stored, spec)
        if field is not None:
            old, new = _flatten(stored).get(field), _flatten(spec).get(field)
            hint = (" (leave --fit-batch out to use the set's)" if field == "fit_batch" else "")
            raise BadInput(f"{FLAGS.get(field, field)}: {out} holds a data set made with "
                           f"{field} = {json.dumps(old)}, this run asks for {json.dumps(new)}; "
                           f"use the same options{hint}, or another --out")
        return manifest, spec
    spec = {**spec, "fit_batch": spec.get("fit_batch", DEFAULT_FIT_BATCH)}
    others = [p.name for p in out.iterdir() if not p.name.startswith(".")]
    if others:
        raise BadInput(f"--out: {out} is not empty and not a prbdm data set (no {MANIFEST}); "
                       f"give a new or empty folder")
    manifest = {"format": FORMAT, "format_version": FORMAT_VERSION, "spec": spec,
                "count": count, "created": _now(), "versions": versions, "git_commit": commit,
                "columns": {k: {"type": t, "meaning": m} for k, (t, m) in COLUMNS.items()},
                "runs": []}
    return manifest, spec


def _remove_temporaries(out: Path) -> None:
    # left by a run killed while writing; the lock guarantees no writer is alive
    for tmp in out.glob(".*.tmp"):
        tmp.unlink(missing_ok=True)


# ====================================================================== 4. execution

_THREAD_VARS = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")


@contextlib.contextmanager
def _one_thread_children():
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
    import signal
    import threading

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    parent = os.getppid()

    def watch():
        while os.getppid() == parent:
            time.sleep(0.5)
        os._exit(1)

    threading.Thread(target=watch, name="prbdm-parent-watch", daemon=True).start()


def _worker_ready(warm: bool = False) -> dict:
    """Start-up probe; ``warm`` imports the truth and fit (torch) now, so that start-up time is
    not charged to the first beams."""
    if warm:
        from . import fit, truth  # noqa: F401

        _torch_one_thread()
    return {"pid": os.getpid(), "host": socket.gethostname(), "prbdm": __version__}


def _run_inline(tasks, spec, labeller, workers, scheduler):
    yield {"workers": 1, "where": "in-process"}
    for chunk in tasks:
        yield from label_chunk(chunk, spec, labeller)


def _run_pool(tasks, spec, labeller, workers, scheduler):
    """A local pool of ``workers`` spawned processes; at most 2 tasks (chunks) per worker in
    flight."""
    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool

    with _one_thread_children():
        pool = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"),
                                   initializer=_init_worker)
        try:
            warm = labeller is label_beam
            for f in [pool.submit(_worker_ready, warm) for _ in range(workers)]:
                f.result()
        except BaseException:
            pool.shutdown(wait=False, cancel_futures=True)
            raise
    yield {"workers": workers, "where": "process pool"}
    todo, pending = iter(tasks), {}
    try:
        while True:
            while len(pending) < 2 * workers and (c := next(todo, None)) is not None:
                pending[pool.submit(label_chunk, c, spec, labeller)] = c
            if not pending:
                break
            done, _ = wait(pending, return_when=FIRST_COMPLETED)
            for f in sorted(done, key=pending.get):
                c = pending.pop(f)
                try:
                    records = f.result()
                except BrokenProcessPool:
                    raise RuntimeError("a worker process died (out of memory? killed?); the "
                                       "records written so far are kept: run the same command "
                                       "again to go on") from None
                except Exception as exc:  # noqa: BLE001
                    records = _chunk_failure(c, exc)
                yield from records
    finally:
        pool.shutdown(wait=False, cancel_futures=True)


#: how long to try to reach a Dask scheduler address before refusing the run [s]
CONNECT_TIMEOUT_S = 20


def _dask_client(workers: int, scheduler):
    """(client, things to close): ``"local"`` starts a LocalCluster, else connect to an address."""
    import logging

    from dask.distributed import Client, LocalCluster

    if isinstance(scheduler, Client):
        return scheduler, []
    if scheduler == "local":
        with _one_thread_children():
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                   dashboard_address=None, silence_logs=logging.ERROR)
        return Client(cluster), [cluster]
    try:
        client = Client(scheduler, timeout=f"{CONNECT_TIMEOUT_S}s")
    except (OSError, TimeoutError, ValueError) as exc:
        raise BadInput(f"--scheduler: cannot connect to {scheduler!r} ({type(exc).__name__}: "
                       f"{exc})") from None
    return client, []


def _run_dask(tasks, spec, labeller, workers, scheduler):
    """The same tasks (chunks) on a Dask cluster; 2 tasks per worker thread in flight."""
    from dask.distributed import as_completed

    client, owned = _dask_client(workers, scheduler)
    pending = {}  # future key -> (chunk, future)
    try:
        try:
            client.wait_for_workers(1, timeout=120)
            client.submit(_worker_ready, labeller is label_beam, pure=False).result(timeout=300)
        except Exception as exc:  # noqa: BLE001
            raise BadInput(f"--scheduler: the cluster cannot run prbdm tasks ({type(exc).__name__}:"
                           f" {exc}); are workers up, with prbdm installed?") from None
        threads = lambda: max(1, sum(client.nthreads().values()))  # noqa: E731
        yield {"workers": threads(), "where": f"dask {client.scheduler_info()['address']}"}
        run = uuid.uuid4().hex[:8]
        todo, window = iter(tasks), 2 * threads()
        flow = as_completed()

        def top_up():
            while len(pending) < window and (c := next(todo, None)) is not None:
                f = client.submit(label_chunk, c, spec, labeller, pure=False,
                                  key=f"prbdm-label-{run}-{c[0]}")
                pending[f.key] = (c, f)
                flow.add(f)

        top_up()
        seen = 0
        for f in flow:
            c, _ = pending.pop(f.key)
            try:
                records = f.result()
            except Exception as exc:  # noqa: BLE001 - e.g. KilledWorker: record and go on
                records = _chunk_failure(c, exc)
            f.release()
            yield from records
            seen += 1
            if seen % 16 == 0:  # workers may join or leave
                window = 2 * threads()
            top_up()
    finally:
        if pending:
            client.cancel([f for _, f in pending.values()])
        if owned:
            client.close()
            for thing in owned:
                thing.close()


# ---------------------------------------------------------------------- progress

def _fmt_duration(seconds: float) -> str:
    if not math.isfinite(seconds):
        return "?"
    seconds = int(round(seconds))
    h, rest = divmod(seconds, 3600)
    m, s = divmod(rest, 60)
    return f"{h}h{m:02d}m" if h else (f"{m}m{s:02d}s" if m else f"{s}s")


class _Progress:
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


# ====================================================================== 5. generate (and resume)

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
    value comes from the set when ``spec`` has none (1 for a set made before chunking,
    :data:`DEFAULT_FIT_BATCH` for a new set).

    Returns a summary dict (see ``prbdm dataset generate --json``). Raises BadInput for a spec that
    differs from the folder's, RuntimeError when a worker process dies (what was done is kept).
    """
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
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise BadInput(f"--out: {out} exists and is not a folder")
    out.mkdir(parents=True, exist_ok=True)
    t_start = time.monotonic()
    versions, commit = _versions(), _git_commit()

    with _FolderLock(out):
        manifest, spec = _open_set(out, spec, int(count), versions, commit)
        _remove_temporaries(out)
        existing = _existing_indices(out)
        done = np.zeros(count, dtype=bool)
        done[existing[existing < count]] = True
        todo = np.flatnonzero(~done).tolist()
        fit_batch = int(spec["fit_batch"])
        tasks = chunks(todo, fit_batch)
        parts = part_files(out)
        next_part = 1 + max((int(p.stem.split("-")[1]) for p in parts), default=-1)
        run = {"id": uuid.uuid4().hex[:12], "started": _now(), "finished": None,
               "count": int(count), "todo": len(todo), "written": 0, "errors": 0,
               "fit_batch": fit_batch, "workers": None,
               "scheduler": None if scheduler is None else (
                   scheduler if isinstance(scheduler, str) else "dask client"),
               "host": socket.gethostname(), "versions": versions, "git_commit": commit}
        if manifest["versions"] != versions or manifest["git_commit"] != commit:
            if todo:
                _say(progress, stream, "note: this run's package versions or git commit differ "
                     "from the set's creation (each run is recorded in the manifest)")
        metadata = {"prbdm.version": __version__, "prbdm.git_commit": str(commit),
                    "prbdm.run": run["id"]}

        buffer: list[dict] = []
        meter = _Progress(progress, total=int(count), initial=int(count) - len(todo),
                          stream=stream)
        backend = (_run_dask if scheduler is not None else
                   _run_pool if workers >= 1 else _run_inline)
        t_ready = time.monotonic()
        restore_threads = _torch_threads() if backend is not _run_pool else None
        results = backend(tasks, spec, labeller, workers, scheduler) if todo else iter(())
        last_flush = time.monotonic()

        def flush():
            nonlocal next_part, last_flush
            if buffer:
                # idempotent if interrupted anywhere: until the buffer is cleared, a second call
                # rewrites the same part number with the same records
                _write_part(out, next_part, buffer, metadata)
                written = len(buffer)
                errors = sum(r.get("status") != "ok" for r in buffer)
                buffer.clear()
                next_part += 1
                run["written"] += written
                run["errors"] += errors
                _write_manifest(out, manifest)  # the run's progress, for `info` after a crash
            last_flush = time.monotonic()

        try:
            # start the backend first: a scheduler that is refused or a pool that fails to
            # start raises here, before the manifest is written, so it is left as it was
            where = next(results, None) if todo else None
            t_ready = time.monotonic()
            if where is not None:
                run["workers"] = where["workers"]
                if scheduler is not None:
                    run["scheduler"] = where["where"]
            manifest["count"] = max(int(manifest["count"]), int(count))
            manifest["runs"].append(run)
            _write_manifest(out, manifest)
            if where is not None:
                meter.log(f"{len(todo)} beams to label ({int(count) - len(todo)} already in "
                          f"{out}) in {len(tasks)} tasks of up to {fit_batch}, "
                          f"{where['workers']} workers ({where['where']}, ready in "
                          f"{t_ready - t_start:.1f} s)")
                meter.start()
            for rec in results:
                buffer.append(rec)
                meter.update(rec)
                if len(buffer) >= part_size or time.monotonic() - last_flush >= flush_s:
                    flush()
            flush()
        finally:
            try:
                flush()  # Ctrl-C or a dead worker: keep what is done
            finally:
                if hasattr(results, "close"):
                    results.close()
                meter.close()
                if restore_threads is not None:
                    restore_threads()
        run["finished"] = _now()
        run["wall_s"] = round(time.monotonic() - t_start, 3)
        _write_manifest(out, manifest)
        idx = _existing_indices(out)

    labelled = time.monotonic() - t_ready
    summary = {"out": str(out), "count": int(count), "records": int(np.unique(idx).size),
               "new": run["written"], "new_errors": run["errors"],
               "missing": int(count - np.unique(idx[idx < count]).size),
               "parts": len(part_files(out)), "fit_batch": fit_batch,
               "workers": run["workers"],
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


# ====================================================================== 6. summary

def _quantiles(values) -> dict | None:
    v = np.asarray([x for x in values if x is not None and math.isfinite(x)], dtype=np.float64)
    if v.size == 0:
        return None
    return {"mean": float(v.mean()), "median": float(np.median(v)),
            "p95": float(np.percentile(v, 95)), "max": float(v.max())}


def info(out) -> dict:
    """Counts, failures, loss distribution and time per beam of the data set in ``out``."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    out = Path(out)
    if not out.is_dir():
        raise BadInput(f"DIR: no such folder {str(out)!r}")
    manifest = read_manifest(out)
    cols = ["index", "status", "error", "loss_percent", "gamma_spread", "time_s", "cpu_s",
            "truth_time_s", "fit_time_s"]
    parts = part_files(out)
    tables = [pq.read_table(p, columns=cols) for p in parts]
    table = pa.concat_tables(tables) if tables else _arrow_schema().empty_table().select(cols)
    d = table.to_pydict()
    idx = np.asarray(d["index"], dtype=np.int64)
    unique = np.unique(idx)
    count = int(manifest["count"])
    ok = [i for i, s in enumerate(d["status"]) if s == "ok"]
    errors: dict[str, int] = {}
    for s, e in zip(d["status"], d["error"]):
        if s != "ok":
            key = (e or "unknown").split(": ")
            key = ": ".join(key[:2])  # stage: ExceptionType
            errors[key] = errors.get(key, 0) + 1
    runs = manifest.get("runs", [])
    return {
        "dir": str(out), "spec": manifest["spec"], "count": count,
        "records": int(idx.size), "unique": int(unique.size),
        "duplicated": int(idx.size - unique.size),
        "missing": int(count - np.count_nonzero(unique < count)),
        "complete": bool(np.count_nonzero(unique < count) == count),
        "ok": len(ok), "errors": int(idx.size - len(ok)),
        "error_kinds": dict(sorted(errors.items(), key=lambda kv: -kv[1])),
        "loss_percent": _quantiles(d["loss_percent"][i] for i in ok),
        "gamma_spread": _quantiles(d["gamma_spread"][i] for i in ok),
        "time_per_beam_s": _quantiles(d["time_s"]),
        "cpu_per_beam_s": _quantiles(d["cpu_s"]),
        "truth_time_s": _quantiles(d["truth_time_s"]),
        "fit_time_s": _quantiles(d["fit_time_s"]),
        "parts": len(parts), "bytes": int(sum(p.stat().st_size for p in parts)),
        "created": manifest.get("created"), "git_commit": manifest.get("git_commit"),
        "versions": manifest.get("versions"),
        "runs": [{k: r.get(k) for k in ("started", "finished", "todo", "written", "errors",
                                        "workers", "scheduler", "host", "wall_s")}
                 for r in runs],
    }
