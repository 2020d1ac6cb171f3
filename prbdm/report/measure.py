"""The measurement of ``prbdm report``: held-out beams, every method timed and its errors against
the three truths (beam, Kirchhoff and Mindlin plate), the scaling studies; :func:`run_report`
returns all numbers as one dict (the methods and error definitions: :mod:`prbdm.report`)."""
from __future__ import annotations

import datetime as _dt
import math
import os
import platform
import time
import warnings
from dataclasses import dataclass

import numpy as np

from ..errors import BadInput

JOINTS, MODES = 4, 4
PANEL_TRUTHS = {"plate": "plate", "mindlin": "Mindlin"}    # panel truths: row labels
DEFAULT_STARTS = (8, 16, 32, 64)

@dataclass
class ReportConfig:
    beams: int = 40
    seed: int = 1
    data: str | None = None
    checkpoint: str | None = None
    quick: bool = False
    starts: tuple = DEFAULT_STARTS
    single: int = 10                 # beams also timed one at a time (fits, network, refine)
    scale_beams: int = 3             # beams of the scaling studies
    stability: bool = True
    fit_seed: int = 0
    objective: str = "eigenvalue"    # what the fits minimise and which network is measured
    command: str = ""
    progress: object = None          # callable(str) or None

    def say(self, text: str) -> None:
        if self.progress is not None:
            self.progress(text)


def _portable(described: dict) -> dict:
    """The checkpoint's description with its path relative to the working directory when it lies
    inside it: a committed report carries no machine paths."""
    from pathlib import Path

    path = described.get("path")
    if path:
        try:
            described = {**described,
                         "path": Path(path).resolve().relative_to(Path.cwd().resolve()).as_posix()}
        except ValueError:
            pass
    return described


# ============================================================================ held-out beams
def held_out_beams(cfg: ReportConfig, sur) -> tuple[list, dict]:
    """The beams to evaluate and a description of where they come from."""
    from ..geometry import random_beam
    from ..surrogate.checkpoint import training_sets

    seeds = [s.get("spec", {}).get("seed") for s in training_sets(sur.metadata)]
    train_seed = seeds[0]
    if cfg.data is None:
        # any training set's seed: a set drawn with other width bounds still shares the
        # stations, width fractions and thickness of the same (seed, index)
        if cfg.seed in seeds:
            raise BadInput(f"--seed {cfg.seed}: that is the seed of the checkpoint's training "
                           f"data; held-out beams need another seed (>= 0, not in "
                           f"{sorted(x for x in seeds if x is not None)})")
        beams = [random_beam(cfg.seed, i) for i in range(cfg.beams)]
        return beams, {"source": "generated", "generator": "prbdm.random_beam(seed, index), "
                       "paper generator p = 10", "seed": cfg.seed,
                       "indices": f"0..{cfg.beams - 1}", "checkpoint_training_seed": train_seed}
    from .. import dataset as ds

    manifest = ds.read_manifest(cfg.data)
    spec = manifest["spec"]
    table = ds.read_table(cfg.data, columns=["index"], status="ok").to_pandas()
    idx = np.sort(table["index"].to_numpy())
    same = next((s for s in training_sets(sur.metadata)
                 if ds.spec_difference(spec.get("beam", {}), s.get("spec", {}).get("beam", {}))
                 is None and spec.get("seed") == s.get("spec", {}).get("seed")), None)
    if same:
        max_index = int(same.get("max_index", -1))
        idx = idx[(idx > max_index) | (idx % 10 == 9)]
        rule = (f"index > {max_index} (generated after the checkpoint's snapshot) or "
                "index % 10 == 9 (its test split)")
    else:
        rule = "every beam (the data set's beams are not the checkpoint's training stream)"
    if idx.size == 0:
        raise BadInput(f"--data {cfg.data}: no held-out beams (rule: {rule})")
    idx = idx[:cfg.beams]
    beams = [ds.beam_for(spec, int(i)) for i in idx]
    return beams, {"source": "data set", "path": str(cfg.data), "seed": spec.get("seed"),
                   "rule": rule, "indices": [int(i) for i in idx]}


# ============================================================================ errors
def _errors(omega, omega_ref, r):
    """Loss (docs/conventions.md §3, %) and worst per-mode frequency error (fraction) per beam.

    omega (B, m, n) per pose or (B, R) for one 'pose'; omega_ref (B, R')."""
    omega = np.asarray(omega, dtype=np.float64)
    if omega.ndim == 2:
        omega = omega[:, None, :]
    r = min(r, omega.shape[-1], omega_ref.shape[-1])
    lam, ref = omega[..., :r] ** 2, omega_ref[:, None, :r] ** 2
    loss = 100 * np.mean(np.linalg.norm(lam - ref, axis=-1) / np.linalg.norm(ref, axis=-1), -1)
    per_mode = np.max(np.abs(omega[..., :r] / omega_ref[:, None, :r] - 1), axis=-2)
    return loss, per_mode.max(-1), r, per_mode


def _q(v, p):
    v = np.asarray(v, dtype=np.float64)
    v = v[np.isfinite(v)]
    return float(np.percentile(v, p)) if v.size else float("nan")


def _best_of(fn, repeats=3):
    best = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return out, best


# ============================================================================ the measurement
def run_report(cfg: ReportConfig) -> dict:
    """Run every method on the held-out beams and the scaling studies; returns all numbers."""
    import torch

    torch.set_num_threads(1)    # small batched problems: one thread is faster on this machine
    from .. import classical as cl
    from .. import surrogate as sg
    from ..fit import REFINE_CANDIDATES, REFINE_ITER, FitProblem, StopRules, fit_many, refine_starts
    from ..model import eigenvalues, uniform_gamma
    from ..truth import bending_frequencies

    started = time.time()
    load0 = _load()
    sur = sg.load_checkpoint(cfg.checkpoint
                             or sg.default_checkpoint(JOINTS, "beam", cfg.objective))
    if sur.joints != JOINTS or sur.truth != "beam":
        raise BadInput(f"--checkpoint: need a {JOINTS}-joint beam-truth checkpoint, got "
                       f"{sur.joints} joints, truth {sur.truth!r}")
    beams, source = held_out_beams(cfg, sur)
    B = len(beams)
    r = MODES
    poses = sur.poses.tolist()

    # ---------------------------------------------------------------- truths, one beam at a time
    warm = beams[0]
    bending_frequencies(warm, model="beam", modes=r)
    om_beam, t_beam = np.empty((B, r)), np.empty(B)
    for i, b in enumerate(beams):
        t0 = time.perf_counter()
        om_beam[i] = bending_frequencies(b, model="beam", modes=r).omega
        t_beam[i] = time.perf_counter() - t0
    cfg.say(f"beam truth: {B} beams, {t_beam.mean() * 1e3:.1f} ms/beam")
    om_plate, t_plate, plate_fail = _panel_truth(cfg, beams, "plate", r)
    ok_plate = np.isfinite(om_plate).all(1)
    om_mindlin, t_mindlin, mindlin_fail = _panel_truth(cfg, beams, "mindlin", r)
    ok_mindlin = np.isfinite(om_mindlin).all(1)

    methods = []

    def add(key, label, omega, time_s, n, needs=None, note="", single_s=None, extra=None):
        methods.append({"key": key, "label": label, "omega": np.asarray(omega, dtype=np.float64),
                        "time_s": float(time_s), "joints": n, "needs": needs, "note": note,
                        "single_s": single_s, **(extra or {})})

    add("plate_truth", "plate truth", om_plate, np.nanmean(t_plate), None,
        note="Kirchhoff plate, Argyris FEM (reference)",
        extra={"time_median_s": _q(t_plate, 50)})
    add("mindlin_truth", "Mindlin plate truth", om_mindlin, np.nanmean(t_mindlin), None,
        note="shear-deformable (Reissner-Mindlin) plate FEM, the faithful truth of thick or "
             "necked panels", extra={"time_median_s": _q(t_mindlin, 50)})
    add("beam_truth", "beam truth", om_beam, t_beam.mean(), None,
        note="Euler-Bernoulli, Hermite FEM", extra={"time_median_s": _q(t_beam, 50)})

    # ---------------------------------------------------------------- models without a truth
    with torch.no_grad():
        g_rfe = uniform_gamma(JOINTS).expand(B, JOINTS + 1)
        from ..model import BeamTensors
        bt = BeamTensors.from_beams(beams)
        eigenvalues(bt, g_rfe[:1].expand(B, -1), poses=poses)       # warm-up
        lam, t = _best_of(lambda: eigenvalues(BeamTensors.from_beams(beams), g_rfe, poses=poses))
    add("rfe", "RFE chain (equal links, k = 1)", np.sqrt(lam.numpy()), t / B, JOINTS,
        note="gamma = [1/2, 1, 1, 1, 1/2]/4, beam law, k = 1, paper poses; batched")
    for model in (cl.HOWELL_1R, cl.SU_3R):
        with torch.no_grad():
            cl.eigenvalues(beams[:1], model)
            lam, t = _best_of(lambda: cl.eigenvalues(beams, model))
        add(model.key, model.name, np.sqrt(lam.numpy()), t / B, model.joints,
            note=f"{model.reference}; EI: tip-load equivalent; paper poses for n = "
                 f"{model.joints}; batched")

    # ---------------------------------------------------------------- optimised fits
    starts = tuple(cfg.starts)
    single = min(cfg.single, B)
    fit_beams = {}
    for S in starts:
        t0 = time.perf_counter()
        res = fit_many(FitProblem(beams, om_beam, JOINTS, r, poses=poses,
                                  objective=cfg.objective), starts=S, seed=cfg.fit_seed)
        t = (time.perf_counter() - t0) / B
        ts = []
        for i in range(single):
            t0 = time.perf_counter()
            fit_many(FitProblem([beams[i]], om_beam[i:i + 1], JOINTS, r, poses=poses,
                                objective=cfg.objective), starts=S, seed=cfg.fit_seed)
            ts.append(time.perf_counter() - t0)
        fit_beams[S] = res
        add(f"fit_{S}", f"fit, {S} starts", np.stack([x.omega for x in res]), t, JOINTS,
            needs="beam", note="fit_many to the beam truth, all beams in one batch",
            single_s=float(np.mean(ts)) if ts else None)
        cfg.say(f"fit {S} starts: {t:.3f} s/beam batched")
    S_plate = max(starts)
    for truth, om_t, ok_t in (("plate", om_plate, ok_plate), ("mindlin", om_mindlin, ok_mindlin)):
        keep = np.flatnonzero(ok_t)
        if not keep.size:
            continue
        t0 = time.perf_counter()
        res = fit_many(FitProblem([beams[i] for i in keep], om_t[keep], JOINTS, r, poses=poses,
                                  objective=cfg.objective), starts=S_plate, seed=cfg.fit_seed)
        t = (time.perf_counter() - t0) / keep.size
        om = np.full((B, len(poses), JOINTS), np.nan)
        om[keep] = np.stack([x.omega for x in res])
        name = PANEL_TRUTHS[truth]
        add(f"fit_{truth}", f"fit to {name} truth, {S_plate} starts", om, t, JOINTS,
            needs=truth, note=f"fit_many to the {name} truth, all beams in one batch")

    # ---------------------------------------------------------------- network
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sg.OutOfDistributionWarning)
        sur.predict(beams[:2], warn=False)
        pred, t_net = _best_of(lambda: sur.predict(beams, frequencies=True, warn=False))
        ts = []
        for i in range(single):
            t0 = time.perf_counter()
            sur.predict(beams[i], frequencies=True, warn=False)
            ts.append(time.perf_counter() - t0)
    t_net /= B
    t_net_single = float(np.mean(ts)) if ts else None
    add("network", "network", pred.omega, t_net, JOINTS, note=f"{sur.name}, batched",
        single_s=t_net_single, extra={"ood_beams": int(pred.ood.any(1).sum())})
    init = refine_starts(pred.ranked_candidates(REFINE_CANDIDATES))     # (B, H, n + 1) gammas
    H = init.shape[1]
    t0 = time.perf_counter()
    best = fit_many(FitProblem(beams, om_beam, JOINTS, r, poses=poses, objective=cfg.objective),
                    init_gamma=init, stop=StopRules(max_iter=REFINE_ITER))
    t_ref = (time.perf_counter() - t0) / B
    ts = []
    for i in range(single):
        t0 = time.perf_counter()
        fit_many(FitProblem([beams[i]], om_beam[i:i + 1], JOINTS, r, poses=poses,
                            objective=cfg.objective),
                 init_gamma=init[i:i + 1], stop=StopRules(max_iter=REFINE_ITER))
        ts.append(time.perf_counter() - t0)
    add("refined", f"network + refined ({H} starts, {REFINE_ITER} it.)",
        np.stack([x.omega for x in best]), t_net + t_ref, JOINTS, needs="beam",
        note="fit_many from the network's best candidate gammas (REFINE_CANDIDATES) and the "
             "fit's four fixed starts (prbdm.fit.refine_starts); all beams in one batch; time = "
             "network + refinement",
        single_s=(t_net_single + float(np.mean(ts))) if ts else None)
    add("direct", "network (direct frequencies)", pred.omega_truth[:, :r], t_net, None,
        note="the network's prediction of the beam-truth frequencies (same call as network)",
        single_s=t_net_single)
    cfg.say("network done")
    _panel_network(cfg, beams, om_plate, ok_plate, poses, r, add, "plate")
    _panel_network(cfg, beams, om_mindlin, ok_mindlin, poses, r, add, "mindlin")

    # ---------------------------------------------------------------- errors against the truths
    for m in methods:
        m["errors"] = {}
        for ref_key, ref, ok in (("plate", om_plate, ok_plate),
                                 ("mindlin", om_mindlin, ok_mindlin),
                                 ("beam", om_beam, np.ones(B, dtype=bool))):
            valid = ok & np.isfinite(m["omega"].reshape(B, -1)).all(1)
            if m["key"] == f"{ref_key}_truth":
                m["errors"][ref_key] = {"reference": True}
                continue
            loss, worst, rr, per_mode = _errors(m["omega"][valid], ref[valid], r)
            m["errors"][ref_key] = {
                "beams": int(valid.sum()), "modes": rr,
                "loss_median": _q(loss, 50), "loss_p95": _q(loss, 95), "loss_max": _q(loss, 100),
                "worst_median": _q(worst, 50), "worst_p95": _q(worst, 95),
                "worst_max": _q(worst, 100),
                "per_mode_median": [_q(per_mode[:, j], 50) for j in range(rr)]}
        need = {"beam": t_beam.mean(), "plate": np.nanmean(t_plate),
                "mindlin": np.nanmean(t_mindlin), None: 0.0}[m["needs"]]
        m["total_s"] = m["time_s"] + need
        del m["omega"]

    # ---------------------------------------------------------------- scaling
    scaling = _scaling(cfg, beams, sur, torch)
    return {
        "config": {"beams": B, "seed": cfg.seed, "data": cfg.data, "quick": cfg.quick,
                   "starts": list(starts), "single": single, "scale_beams": cfg.scale_beams,
                   "fit_seed": cfg.fit_seed, "joints": JOINTS, "modes": r,
                   "poses": [p[0] for p in poses], "pose_target": sur.pose_target,
                   "law": "beam", "refine_iter": REFINE_ITER,
                   "objective": cfg.objective, "command": cfg.command},
        "source": source,
        "checkpoint": {**_portable(sur.describe()),
                       "dataset_max_index": sur.metadata.get("dataset", {}).get("max_index"),
                       "dataset_seed": sur.metadata.get("dataset", {}).get("spec", {}).get("seed"),
                       "candidates": sur.hypotheses},
        "plate_failures": plate_fail,
        "mindlin_failures": mindlin_fail,
        "methods": methods,
        "scaling": scaling,
        "environment": _environment(load0),
        "elapsed_s": time.time() - started,
    }


def _panel_network(cfg: ReportConfig, beams, om_truth, ok_truth, poses, r, add,
                   truth: str) -> None:
    """The rows of the network of a panel truth (``plate-n4`` or ``mindlin-n4`` for the
    objective), when one is found: its PRBDM, its own truth frequencies, and it refined against
    its truth like the beam network's refinement (issue 16 item 6). Row keys start with the
    truth's name; no such network: no rows, and the tables say so."""
    from .. import surrogate as sg
    from ..fit import REFINE_CANDIDATES, REFINE_ITER, FitProblem, StopRules, fit_many, refine_starts

    name = PANEL_TRUTHS[truth]
    try:
        path = sg.default_checkpoint(JOINTS, truth, cfg.objective)
    except BadInput:
        cfg.say(f"no {name} network: its rows are left out")
        return
    sur = sg.load_checkpoint(path)
    B = len(beams)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")      # the held-out accuracy is what the rows measure
        sur.predict(beams[:2], warn=False)
        pred, t_net = _best_of(lambda: sur.predict(beams, frequencies=True, warn=False))
    t_net /= B
    add(f"{truth}_network", f"{name} network ({sur.name})", pred.omega, t_net, JOINTS,
        note=f"{sur.name}, trained on the {name} truth, batched",
        extra={"ood_beams": int(pred.ood.any(1).sum())})
    keep = np.flatnonzero(ok_truth)
    if keep.size:
        init = refine_starts(pred.ranked_candidates(REFINE_CANDIDATES))[keep]
        t0 = time.perf_counter()
        best = fit_many(FitProblem([beams[i] for i in keep], om_truth[keep], JOINTS, r,
                                   poses=poses, objective=cfg.objective),
                        init_gamma=init, stop=StopRules(max_iter=REFINE_ITER))
        t_ref = (time.perf_counter() - t0) / keep.size
        om = np.full((B, len(poses), JOINTS), np.nan)
        om[keep] = np.stack([x.omega for x in best])
        add(f"{truth}_refined", f"{name} network + refined to the {name} "
            f"({init.shape[1]} starts, {REFINE_ITER} it.)", om, t_net + t_ref, JOINTS,
            needs=truth, note=f"fit_many to the {name} truth from the {name} network's "
                              "candidates and the fit's four fixed starts")
    add(f"{truth}_direct", f"{name} network (direct frequencies)", pred.omega_truth[:, :r],
        t_net, None, note=f"the {name} network's prediction of the {name}-truth frequencies")
    cfg.say(f"{name} network done")


def _panel_truth(cfg: ReportConfig, beams, model: str, r: int):
    """A panel truth (``plate`` or ``mindlin``) of every beam, one at a time: frequencies (NaN
    where the truth refuses the planform), seconds per beam, and the refusals."""
    from ..geometry import Beam
    from ..truth import bending_frequencies

    B = len(beams)
    om, t = np.full((B, r), np.nan), np.full(B, np.nan)
    fails = []
    bending_frequencies(Beam(x=[0, 1], half_width=[0.1, 0.1], thickness=0.01), model=model,
                        modes=r)                                   # warm-up (imports, caches)
    for i, b in enumerate(beams):
        t0 = time.perf_counter()
        try:
            om[i] = bending_frequencies(b, model=model, modes=r).omega
        except BadInput as exc:
            fails.append({"beam": i, "error": str(exc)})
        t[i] = time.perf_counter() - t0
        if (i + 1) % 10 == 0:
            cfg.say(f"{model} truth: {i + 1}/{B} beams, {np.nanmean(t):.2f} s/beam")
    return om, t, fails


def _scaling(cfg: ReportConfig, beams, sur, torch) -> dict:
    from .. import surrogate as sg
    from ..fit import FitProblem, fit_many
    from ..geometry import random_beam
    from ..truth import bending_frequencies

    q = cfg.quick
    sb = beams[:max(1, min(cfg.scale_beams, len(beams)))]
    out = {"beams": len(sb)}
    # fit time against n (modes mapped = n, fixed start count so only n changes)
    ns = [3, 4, 6] if q else [3, 4, 5, 6, 8, 10, 12, 15, 20]
    S_n = 8 if q else 64
    om = np.array([bending_frequencies(b, model="beam", modes=max(ns)).omega for b in sb])
    rows = []
    for n in ns:
        t0 = time.perf_counter()
        res = fit_many(FitProblem(sb, om, n, n, objective=cfg.objective), starts=S_n,
                       seed=cfg.fit_seed)
        rows.append({"n": n, "time_s": (time.perf_counter() - t0) / len(sb),
                     "loss_median": _q([x.loss_percent for x in res], 50),
                     "poses": int(res[0].poses.shape[0])})
        cfg.say(f"fit vs n: n = {n}, {rows[-1]['time_s']:.2f} s/beam")
    out["fit_vs_n"] = {"starts": S_n, "rows": rows}
    # fit time against starts (n = 4)
    Ss = [1, 4, 16] if q else [1, 2, 4, 8, 16, 32, 64, 128, 256]
    rows = []
    for S in Ss:
        t0 = time.perf_counter()
        res = fit_many(FitProblem(sb, om[:, :MODES], JOINTS, MODES, objective=cfg.objective),
                       starts=S, seed=cfg.fit_seed)
        rows.append({"starts": S, "time_s": (time.perf_counter() - t0) / len(sb),
                     "loss_median": _q([x.loss_percent for x in res], 50)})
    out["fit_vs_starts"] = {"rows": rows}
    cfg.say("fit vs starts done")
    # truth time against mesh size
    rows = []
    for e in ([10, 40] if q else [10, 20, 40, 80, 160, 320, 640]):
        ts, el = [], []
        for b in sb:
            t0 = time.perf_counter()
            res = bending_frequencies(b, model="beam", modes=MODES, elements=e)
            ts.append(time.perf_counter() - t0)
            el.append(res.mesh["elements"])
        rows.append({"model": "beam", "elements_option": e, "elements": float(np.median(el)),
                     "dofs": None, "time_s": float(np.median(ts)),
                     "omega_1": float(res.omega[0])})
    for e in ([4, 8] if q else [4, 8, 12, 16, 24, 32, 48]):
        ts, el, dof = [], [], []
        for b in sb:
            t0 = time.perf_counter()
            try:
                res = bending_frequencies(b, model="plate", modes=MODES, elements=e)
            except BadInput:
                continue
            ts.append(time.perf_counter() - t0)
            el.append(res.mesh["triangles"])
            dof.append(res.mesh["dofs"])
        if ts:
            rows.append({"model": "plate", "elements_option": e, "elements": float(np.median(el)),
                         "dofs": float(np.median(dof)), "time_s": float(np.median(ts))})
        cfg.say(f"plate mesh {e}: {rows[-1]['time_s']:.2f} s")
    out["truth_vs_mesh"] = {"rows": rows}
    # network throughput against batch size
    sizes = [1, 10, 100] if q else [1, 10, 100, 1000, 10000]
    pool = [random_beam(cfg.seed, 10 ** 6 + i) for i in range(max(sizes))]
    rows = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sg.OutOfDistributionWarning)
        sur.predict(pool[:10], warn=False)
        for s in sizes:
            _, t = _best_of(lambda: sur.predict(pool[:s], frequencies=True, warn=False),
                            repeats=5 if s <= 100 else 2)
            rows.append({"batch": s, "beams_per_s": s / t, "time_s": t})
    out["network_throughput"] = {"rows": rows, "beams": f"random_beam({cfg.seed}, 10**6 + i)"}
    return out


def _load():
    try:
        return os.getloadavg()[0]
    except OSError:
        return float("nan")


def _environment(load0) -> dict:
    from importlib import metadata

    from ..dataset import _git_commit, _versions

    v = _versions()
    for dist in ("matplotlib",):
        try:
            v[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            pass
    return {"versions": v, "git_commit": _git_commit(), "cores": os.cpu_count(),
            "machine": platform.machine(), "system": platform.system(),
            "load_average_start": load0, "load_average_end": _load(), "torch_threads": 1,
            "date": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")}
