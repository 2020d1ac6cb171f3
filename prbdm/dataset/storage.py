"""The data set folder: manifest, Parquet parts, the folder lock, provenance, and the summary.

Records are written by the parent process only, as whole part files (a temporary file, then a
rename), so a kill -9 at any moment never leaves a half-written part; the ``index`` column of the
parts is what a resumed run reads to know what is done.
"""
from __future__ import annotations

import datetime as _dt
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from .. import __version__, files
from ..errors import BadInput
from .schema import (
    COLUMNS,
    DEFAULT_FIT_BATCH,
    DEFAULT_OBJECTIVE,
    DEFAULT_TARGET,
    FLAGS,
    FORMAT,
    FORMAT_VERSION,
    MANIFEST,
    OLD_TARGET,
    arrow_schema,
    flatten,
    manifest_columns,
    spec_difference,
)


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


def set_columns(manifest: dict) -> list[str]:
    """The columns of a set's parts: the ones its manifest lists (a set made before a column
    was added keeps writing parts without it, so all its parts share one schema)."""
    return list(manifest.get("columns") or COLUMNS)


def atomic_write(path: Path, data: bytes | str) -> None:
    """Whole or not at all, flushed to disk before the rename (:func:`prbdm.files.atomic_write`)."""
    files.atomic_write(path, data, make_parents=False, sync=True)


def write_manifest(out: Path, manifest: dict) -> None:
    atomic_write(out / MANIFEST, json.dumps(manifest, indent=1, allow_nan=False) + "\n")


def part_files(out) -> list[Path]:
    return sorted(Path(out).glob("part-*.parquet"))


def next_part_number(out: Path) -> int:
    return 1 + max((int(p.stem.split("-")[1]) for p in part_files(out)), default=-1)


def write_part(out: Path, number: int, records: list[dict], metadata: dict,
               columns=None) -> Path:
    """Write ``records`` (sorted by index) as ``part-NNNNNN.parquet`` with the given columns
    (keys of a record that are not among them are left out), whole or not at all."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    records = sorted(records, key=lambda r: r["index"])
    table = pa.Table.from_pylist(records, schema=arrow_schema(columns, metadata))
    sink = pa.BufferOutputStream()
    pq.write_table(table, sink, compression="zstd")
    path = out / f"part-{number:06d}.parquet"
    atomic_write(path, sink.getvalue().to_pybytes())
    return path


def existing_indices(out: Path) -> np.ndarray:
    """Every ``index`` stored in the part files (duplicates kept, so they can be counted)."""
    import pyarrow.parquet as pq

    found = [pq.read_table(p, columns=["index"]).column("index").to_numpy()
             for p in part_files(out)]
    return np.concatenate(found) if found else np.zeros(0, dtype=np.int64)


def read_table(out, columns=None, status: str | None = None):
    """The whole data set as one pyarrow Table sorted by index (duplicates, if any, dropped).

    A set that draws Poisson's ratio per beam (the smooth family: a ``nu`` column) gives ``nu``
    whenever the beams' ``thickness`` is read: without it a beam would be read as another one
    (:meth:`prbdm.chain.BeamBatch.from_table` takes it from there)."""
    import pyarrow as pa
    import pyarrow.compute as pc
    import pyarrow.parquet as pq

    manifest = read_manifest(out)
    if columns is not None and "index" not in columns:
        columns = ["index", *columns]
    if (columns is not None and "thickness" in columns and "nu" not in columns
            and "nu" in set_columns(manifest)):
        columns = [*columns, "nu"]
    if status is not None and columns is not None and "status" not in columns:
        columns = [*columns, "status"]
    parts = [pq.read_table(p, columns=columns) for p in part_files(out)]
    if not parts:
        return arrow_schema(set_columns(manifest)).empty_table().select(
            columns or set_columns(manifest))
    table = pa.concat_tables(parts).sort_by("index")
    idx = table.column("index").to_numpy()
    if idx.size > 1 and np.any(idx[1:] == idx[:-1]):
        table = table.take(np.flatnonzero(np.concatenate([[True], idx[1:] != idx[:-1]])))
    if status is not None:
        table = table.filter(pc.equal(table.column("status"), status))
    return table


class FolderLock:
    """An exclusive lock on DIR/.lock (released by the OS when the process dies, kill -9 too)."""

    def __init__(self, out: Path):
        self.path = Path(out) / ".lock"
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

def versions() -> dict:
    from importlib import metadata

    out = {"python": sys.version.split()[0], "prbdm": __version__}
    for dist in ("numpy", "scipy", "torch", "scikit-fem", "pyarrow", "dask", "distributed"):
        try:
            out[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            pass
    return out


def git_commit() -> str | None:
    """The commit of the prbdm checkout, with ``+dirty`` for uncommitted changes in the prbdm
    package; None outside a git checkout."""
    here = Path(__file__).resolve().parents[1]          # the prbdm package folder
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


def now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")


def open_set(out: Path, spec: dict, count: int, versions: dict, commit) -> tuple[dict, dict]:
    """The manifest of a new set (not written yet: the run writes it once the workers are
    ready), or the existing one, checked to have the same spec.

    Returns (manifest, the spec of this run). ``fit_batch`` or ``objective`` absent from ``spec``
    means the set's value; absent from a set's spec (made before they existed) means 1 and
    ``eigenvalue``. An existing manifest's spec is never rewritten, so an older prbdm can still
    resume the set."""
    defaults = {"fit_batch": 1, "objective": DEFAULT_OBJECTIVE, "target": OLD_TARGET}
    if (out / MANIFEST).exists():
        manifest = read_manifest(out)
        stored = {**defaults, **manifest["spec"]}
        spec = {**spec, **{k: spec.get(k, stored[k]) for k in defaults}}
        field = spec_difference(stored, spec)
        if field is not None:
            old, new = flatten(stored).get(field), flatten(spec).get(field)
            hint = (f" (leave {FLAGS[field]} out to use the set's)" if field in defaults else "")
            raise BadInput(f"{FLAGS.get(field, field)}: {out} holds a data set made with "
                           f"{field} = {json.dumps(old)}, this run asks for {json.dumps(new)}; "
                           f"use the same options{hint}, or another --out")
        return manifest, spec
    spec = {**spec, "fit_batch": spec.get("fit_batch", DEFAULT_FIT_BATCH),
            "objective": spec.get("objective", DEFAULT_OBJECTIVE),
            "target": spec.get("target", DEFAULT_TARGET)}
    others = [p.name for p in out.iterdir() if not p.name.startswith(".")]
    if others:
        raise BadInput(f"--out: {out} is not empty and not a prbdm data set (no {MANIFEST}); "
                       f"give a new or empty folder")
    manifest = {"format": FORMAT, "format_version": FORMAT_VERSION, "spec": spec,
                "count": count, "created": now(), "versions": versions, "git_commit": commit,
                "columns": manifest_columns(), "runs": []}
    return manifest, spec


def remove_temporaries(out: Path) -> None:
    # left by a run killed while writing; the lock guarantees no writer is alive
    for tmp in out.glob(".*.tmp"):
        tmp.unlink(missing_ok=True)


# ---------------------------------------------------------------------- summary

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
    has = set(set_columns(manifest))
    cols = [c for c in ("index", "status", "error", "loss_percent", "frequency_percent",
                        "gamma_spread", "time_s", "cpu_s", "truth_time_s", "fit_time_s")
            if c in has]
    parts = part_files(out)
    tables = [pq.read_table(p, columns=cols) for p in parts]
    table = (pa.concat_tables(tables) if tables
             else arrow_schema(set_columns(manifest)).empty_table().select(cols))
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
        "objective": manifest["spec"].get("objective", DEFAULT_OBJECTIVE),
        "records": int(idx.size), "unique": int(unique.size),
        "duplicated": int(idx.size - unique.size),
        "missing": int(count - np.count_nonzero(unique < count)),
        "complete": bool(np.count_nonzero(unique < count) == count),
        "ok": len(ok), "errors": int(idx.size - len(ok)),
        "error_kinds": dict(sorted(errors.items(), key=lambda kv: -kv[1])),
        "loss_percent": _quantiles(d["loss_percent"][i] for i in ok),
        "frequency_percent": (_quantiles(d["frequency_percent"][i] for i in ok)
                              if "frequency_percent" in d else None),
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
