"""Labelling: a beam index and a spec in, a record out. Runs in the workers (torch is imported
here lazily, only when a fit runs).

:func:`label_beam` ``(index, spec) -> dict`` is a pure, picklable, module-level function: rebuild
beam ``index``, compute its truth, fit the PRBDM. Any exception becomes a record with ``status =
"error"`` and the message, so one bad beam never stops a run. :func:`label_beams` labels a chunk
of beams with one batched fit (``fit_many``, each beam with its own seed), which costs less CPU
per beam; if the batched fit fails it fits the chunk's beams one at a time, so one bad beam is
still one error record. A task is a chunk of ``spec["fit_batch"]`` consecutive indices with fixed
boundaries (:func:`chunks`).
"""
from __future__ import annotations

import math
import os
import socket
import time

import numpy as np

from .schema import DEFAULT_OBJECTIVE, beam_for


def fit_seed(spec: dict, index: int) -> int:
    """A 32-bit seed for the fit of beam ``index``, independent of every other beam's."""
    return int(np.random.SeedSequence([spec["seed"], index, 0x5EED]).generate_state(1)[0])


def torch_one_thread() -> None:
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
               thickness=beam.thickness, nu=beam.material.nu, length=beam.length,
               mass=beam.mass)
    stage[0] = "truth"
    from ..truth import bending_frequencies

    options = ({"selection": spec.get("target", "section")}
               if spec["truth"] in ("plate", "mindlin") else {})
    tr = bending_frequencies(beam, model=spec["truth"], modes=spec["truth_modes"], **options)
    omega = np.asarray(tr.omega, dtype=np.float64)
    rec.update(omega_truth=_floats(omega), truth_time_s=float(tr.time_s))
    # plate, mindlin: every symmetric mode, so that targets need no FEM later (null otherwise)
    sym = [m for m in tr.all_modes if m["symmetry"] == "symmetric" and "section_fraction" in m]
    rec.update({f"symmetric_{k}": (_floats([m[key] for m in sym]) if sym else None)
                for k, key in (("lambda", "lambda"), ("section_fraction", "section_fraction"),
                               ("participation", "participation"))})
    if omega.size < spec["modes"] or not np.all(np.isfinite(omega)):
        raise ValueError(f"{omega.size} finite modes, the fit maps {spec['modes']}")
    stage[0] = "fit"
    return beam, omega


def _fit_fields(rec: dict, fr, seed: int) -> None:
    """Copy a FitResult into the record; a non-finite loss raises (the record is an error)."""
    freq_error = np.abs(np.asarray(fr.freq_error, dtype=np.float64))
    worst = freq_error.reshape(-1, freq_error.shape[-1]).max(axis=0)
    rec.update(gamma=_floats(fr.gamma), k=_floats(fr.k), loss_percent=float(fr.loss_percent),
               gamma_spread=float(fr.gamma_spread), n_near_best=int(fr.n_near_best),
               freq_error_max=_floats(worst), frequency_percent=100.0 * float(worst.max()),
               fit_time_s=float(fr.time_s), fit_seed=seed)
    if not math.isfinite(rec["loss_percent"]):
        raise ValueError(f"non-finite loss {rec['loss_percent']!r}")
    rec["status"] = "ok"


def _problem(spec: dict) -> dict:
    """What the spec fits: the fields of :class:`prbdm.fit.FitProblem` past the beams and truth."""
    return dict(joints=spec["joints"], modes=spec["modes"], law=spec["law"],
                poses=spec["poses"], objective=spec.get("objective", DEFAULT_OBJECTIVE))


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
        torch_one_thread()
        from ..fit import fit_prbdm

        seed = fit_seed(spec, int(index))
        fr = fit_prbdm(beam, omega, starts=spec["starts"], seed=seed, **_problem(spec))
        _fit_fields(rec, fr, seed)
    except Exception as exc:  # noqa: BLE001 - failure isolation: record it, go on
        rec["error"] = error_text(stage[0], exc)
    return _timed(rec, t0, c0)


def _timed(rec: dict, t0: float, c0: float) -> dict:
    rec["time_s"] = time.perf_counter() - t0
    rec["cpu_s"] = time.thread_time() - c0
    return rec


def label_beams(indices, spec: dict) -> list[dict]:
    """Label several beams with one batched fit: the records of :func:`label_beam`, in order.

    Geometry and truth are computed beam by beam; the beams whose truth succeeded are fitted
    together by one :func:`prbdm.fit.fit_many` call, each with its own seed ``fit_seed(spec,
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
            rec["error"] = error_text(stage[0], exc)
        rec["time_s"] = time.perf_counter() - t0
        rec["cpu_s"] = time.thread_time() - c0
        records.append(rec)
    if not ready:
        return records
    torch_one_thread()
    from ..fit import FitProblem, fit_many, fit_prbdm

    seeds = [fit_seed(spec, rec["index"]) for rec, _, _ in ready]
    t0, c0 = time.perf_counter(), time.thread_time()
    try:
        r = spec["modes"]
        omega = np.stack([o[:r] for _, _, o in ready])
        problem = FitProblem([b for _, b, _ in ready], omega, **_problem(spec))
        results = fit_many(problem, starts=spec["starts"], seed=seeds)
    except Exception:  # noqa: BLE001 - fall back to one fit per beam, below
        results = None
    wall, cpu = time.perf_counter() - t0, time.thread_time() - c0
    for (rec, beam, omega), seed, j in zip(ready, seeds, range(len(ready))):
        rec["time_s"] += wall / len(ready)
        rec["cpu_s"] += cpu / len(ready)
        t1, c1 = time.perf_counter(), time.thread_time()
        try:
            fr = (results[j] if results is not None else
                  fit_prbdm(beam, omega, starts=spec["starts"], seed=seed, **_problem(spec)))
            _fit_fields(rec, fr, seed)
        except Exception as exc:  # noqa: BLE001 - failure isolation
            rec["error"] = error_text("fit", exc)
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


def error_text(stage: str, exc: BaseException) -> str:
    text = f"{stage}: {type(exc).__name__}: {exc}".replace("\n", " ")
    return text if len(text) <= 500 else text[:497] + "..."


def chunk_failure(chunk, exc: BaseException) -> list[dict]:
    """The records of a task that died outside the labeller (a lost worker, an unpicklable
    result): one error record per index."""
    return [{"index": int(i), "status": "error", "error": error_text("worker", exc)}
            for i in chunk]
