"""Error against run time for every way prbdm (and the classical alternatives) produces a model.

:func:`run_report` evaluates on held-out beams and returns the numbers; :func:`write_report`
renders them as ``report.md`` + PNG plots (+ ``report.json``), every file written atomically and
only after everything has been computed, so a failed run leaves no half-written file.

Methods (SPEC §3 model, n = 4, 4 modes, paper poses, ``beam`` law unless noted):

==================  ==========================================================================
plate truth         Kirchhoff plate FEM (:mod:`prbdm.truth`), the issue's reference
beam truth          Euler-Bernoulli FEM, what the fits and the network target
RFE chain           rigid-finite-element chain: ``gamma = [1/2, 1, 1, 1, 1/2]/4``, k = 1, no fit
Howell 1R, Su 3R    classical static PRBMs with their own springs (:mod:`prbdm.classical`)
fit, S starts       :func:`prbdm.fit.fit_many` to the beam truth (S = 8, 16, 32, 64)
fit to plate        the same, 64 starts, to the plate truth
network             :func:`prbdm.surrogate.Surrogate.predict` (checkpoint ``beam-n4``)
network + refined   ``fit_many`` from the network's best 4 candidate gammas and the fit's four
                    fixed starts, 15 iterations, the best kept (``prbdm.fit.REFINE_*``)
network (direct)    the network's own prediction of the beam-truth frequencies
==================  ==========================================================================

Errors of a model against a reference truth: the SPEC §3 loss over the first
``r = min(n, 4)`` modes (mean over the model's poses of the relative eigenvalue error norm) and
the worst per-mode relative frequency error over those modes and poses. A truth or the direct
prediction is one "pose" with k = 1. Time per beam: wall time of the method alone, per beam; a
batched method (network, RFE chain, classical models, fits: all beams in one call) is timed as the
batch divided by the number of beams; truths are solved one beam at a time. "From geometry" adds
the truth a method needs (fits, refinement).
"""
from __future__ import annotations

import datetime as _dt
import io
import json
import math
import os
import platform
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import BadInput

__all__ = ["ReportConfig", "run_report", "write_report", "render_markdown", "held_out_beams"]

JOINTS, MODES = 4, 4
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
    command: str = ""
    progress: object = None          # callable(str) or None

    def say(self, text: str) -> None:
        if self.progress is not None:
            self.progress(text)


# ============================================================================ held-out beams
def held_out_beams(cfg: ReportConfig, sur) -> tuple[list, dict]:
    """The beams to evaluate and a description of where they come from."""
    from .geometry import random_beam

    train_seed = sur.metadata.get("dataset", {}).get("spec", {}).get("seed")
    if cfg.data is None:
        if train_seed is not None and cfg.seed == train_seed:
            raise BadInput(f"--seed {cfg.seed}: that is the seed of the checkpoint's training "
                           f"data; held-out beams need another seed (>= 0, != {train_seed})")
        beams = [random_beam(cfg.seed, i) for i in range(cfg.beams)]
        return beams, {"source": "generated", "generator": "prbdm.random_beam(seed, index), "
                       "paper generator p = 10", "seed": cfg.seed,
                       "indices": f"0..{cfg.beams - 1}", "checkpoint_training_seed": train_seed}
    from . import dataset as ds

    manifest = ds.read_manifest(cfg.data)
    spec = manifest["spec"]
    table = ds.read_table(cfg.data, columns=["index"], status="ok").to_pandas()
    idx = np.sort(table["index"].to_numpy())
    meta_ds = sur.metadata.get("dataset", {})
    same = (ds.spec_difference(spec.get("beam", {}), meta_ds.get("spec", {}).get("beam", {}))
            is None and spec.get("seed") == train_seed)
    if same:
        max_index = int(meta_ds.get("max_index", -1))
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
    """Loss (SPEC §3, %) and worst per-mode frequency error (fraction) per beam.

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
    from . import classical as cl
    from . import surrogate as sg
    from .fit import REFINE_CANDIDATES, REFINE_ITER, fit_many, refine_starts
    from .model import eigenvalues, uniform_gamma
    from .truth import bending_frequencies

    started = time.time()
    load0 = _load()
    sur = sg.load_checkpoint(cfg.checkpoint or sg.default_checkpoint(JOINTS, "beam"))
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
    om_plate, t_plate = np.full((B, r), np.nan), np.full(B, np.nan)
    plate_fail = []
    from .geometry import Beam
    bending_frequencies(Beam(x=[0, 1], half_width=[0.1, 0.1], thickness=0.01), model="plate",
                        modes=r)                                   # warm-up (imports, caches)
    for i, b in enumerate(beams):
        t0 = time.perf_counter()
        try:
            om_plate[i] = bending_frequencies(b, model="plate", modes=r).omega
        except BadInput as exc:
            plate_fail.append({"beam": i, "error": str(exc)})
        t_plate[i] = time.perf_counter() - t0
        if (i + 1) % 10 == 0:
            cfg.say(f"plate truth: {i + 1}/{B} beams, {np.nanmean(t_plate):.2f} s/beam")
    ok_plate = np.isfinite(om_plate).all(1)

    methods = []

    def add(key, label, omega, time_s, n, needs=None, note="", single_s=None, extra=None):
        methods.append({"key": key, "label": label, "omega": np.asarray(omega, dtype=np.float64),
                        "time_s": float(time_s), "joints": n, "needs": needs, "note": note,
                        "single_s": single_s, **(extra or {})})

    add("plate_truth", "plate truth", om_plate, np.nanmean(t_plate), None,
        note="Kirchhoff plate, Argyris FEM (reference)",
        extra={"time_median_s": _q(t_plate, 50)})
    add("beam_truth", "beam truth", om_beam, t_beam.mean(), None,
        note="Euler-Bernoulli, Hermite FEM", extra={"time_median_s": _q(t_beam, 50)})

    # ---------------------------------------------------------------- models without a truth
    with torch.no_grad():
        g_rfe = uniform_gamma(JOINTS).expand(B, JOINTS + 1)
        from .model import BeamTensors
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
        res = fit_many(beams, om_beam, joints=JOINTS, modes=r, poses=poses, starts=S,
                       seed=cfg.fit_seed)
        t = (time.perf_counter() - t0) / B
        ts = []
        for i in range(single):
            t0 = time.perf_counter()
            fit_many([beams[i]], om_beam[i:i + 1], joints=JOINTS, modes=r, poses=poses,
                     starts=S, seed=cfg.fit_seed)
            ts.append(time.perf_counter() - t0)
        fit_beams[S] = res
        add(f"fit_{S}", f"fit, {S} starts", np.stack([x.omega for x in res]), t, JOINTS,
            needs="beam", note="fit_many to the beam truth, all beams in one batch",
            single_s=float(np.mean(ts)) if ts else None)
        cfg.say(f"fit {S} starts: {t:.3f} s/beam batched")
    S_plate = max(starts)
    keep = np.flatnonzero(ok_plate)
    if keep.size:
        t0 = time.perf_counter()
        res = fit_many([beams[i] for i in keep], om_plate[keep], joints=JOINTS, modes=r,
                       poses=poses, starts=S_plate, seed=cfg.fit_seed)
        t = (time.perf_counter() - t0) / keep.size
        om = np.full((B, len(poses), JOINTS), np.nan)
        om[keep] = np.stack([x.omega for x in res])
        add("fit_plate", f"fit to plate truth, {S_plate} starts", om, t, JOINTS, needs="plate",
            note="fit_many to the plate truth, all beams in one batch")

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
    best = fit_many(beams, om_beam, joints=JOINTS, modes=r, poses=poses, init_gamma=init,
                    max_iter=REFINE_ITER)
    t_ref = (time.perf_counter() - t0) / B
    ts = []
    for i in range(single):
        t0 = time.perf_counter()
        fit_many([beams[i]], om_beam[i:i + 1], joints=JOINTS, modes=r, poses=poses,
                 init_gamma=init[i:i + 1], max_iter=REFINE_ITER)
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

    # ---------------------------------------------------------------- errors against both truths
    for m in methods:
        m["errors"] = {}
        for ref_key, ref, ok in (("plate", om_plate, ok_plate),
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
        need = {"beam": t_beam.mean(), "plate": np.nanmean(t_plate), None: 0.0}[m["needs"]]
        m["total_s"] = m["time_s"] + need
        del m["omega"]

    # ---------------------------------------------------------------- scaling
    scaling = _scaling(cfg, beams, sur, torch)
    return {
        "config": {"beams": B, "seed": cfg.seed, "data": cfg.data, "quick": cfg.quick,
                   "starts": list(starts), "single": single, "scale_beams": cfg.scale_beams,
                   "fit_seed": cfg.fit_seed, "joints": JOINTS, "modes": r,
                   "poses": [p[0] for p in poses], "law": "beam", "refine_iter": REFINE_ITER,
                   "command": cfg.command},
        "source": source,
        "checkpoint": {**sur.describe(),
                       "dataset_max_index": sur.metadata.get("dataset", {}).get("max_index"),
                       "dataset_seed": sur.metadata.get("dataset", {}).get("spec", {}).get("seed"),
                       "candidates": sur.hypotheses},
        "plate_failures": plate_fail,
        "methods": methods,
        "scaling": scaling,
        "environment": _environment(load0),
        "elapsed_s": time.time() - started,
    }


def _scaling(cfg: ReportConfig, beams, sur, torch) -> dict:
    from . import surrogate as sg
    from .fit import fit_many
    from .geometry import random_beam
    from .truth import bending_frequencies

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
        res = fit_many(sb, om, joints=n, modes=n, starts=S_n, seed=cfg.fit_seed)
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
        res = fit_many(sb, om[:, :MODES], joints=JOINTS, modes=MODES, starts=S,
                       seed=cfg.fit_seed)
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

    from .dataset import _git_commit, _versions

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


# ============================================================================ rendering
def _fmt_t(s):
    if s is None or not math.isfinite(s):
        return ""
    if s < 1e-3:
        return f"{s * 1e6:.3g} µs"
    if s < 1:
        return f"{s * 1e3:.3g} ms"
    return f"{s:.3g} s"


def _fmt_int(v):
    return "" if v is None else f"{v:.0f}"


def _fmt_p(v, pct=True):
    if v is None or not math.isfinite(v):
        return ""
    return f"{v * 100:.3g} %" if pct else f"{v:.3g} %"


def method_table(res: dict, ref: str) -> str:
    hdr = ("| method | n | modes | loss median | loss p95 | worst freq. error median | p95 | "
           "time per beam | from geometry | one beam at a time |")
    lines = [hdr, "|" + "---|" * 10]
    for m in res["methods"]:
        e = m["errors"][ref]
        n = "" if m["joints"] is None else str(m["joints"])
        if e.get("reference"):
            lines.append(f"| **{m['label']}** (reference) | | | 0 | 0 | 0 | 0 | "
                         f"{_fmt_t(m['time_s'])} | {_fmt_t(m['total_s'])} | |")
            continue
        lines.append(
            f"| {m['label']} | {n} | {e['modes']} | {_fmt_p(e['loss_median'], False)} | "
            f"{_fmt_p(e['loss_p95'], False)} | {_fmt_p(e['worst_median'])} | "
            f"{_fmt_p(e['worst_p95'])} | {_fmt_t(m['time_s'])} | {_fmt_t(m['total_s'])} | "
            f"{_fmt_t(m.get('single_s'))} |")
    return "\n".join(lines)


def per_mode_table(res: dict, ref: str) -> str:
    lines = ["| method | " + " | ".join(f"mode {j + 1}" for j in range(MODES)) + " |",
             "|---|" + "---|" * MODES]
    for m in res["methods"]:
        e = m["errors"][ref]
        if e.get("reference"):
            continue
        vals = [_fmt_p(v) for v in e["per_mode_median"]] + [""] * (MODES - e["modes"])
        lines.append(f"| {m['label']} | " + " | ".join(vals) + " |")
    return "\n".join(lines)


def render_markdown(res: dict, stability_md: str | None = None, stability_note: str = "") -> str:
    c, env, ck, src = res["config"], res["environment"], res["checkpoint"], res["source"]
    sc = res["scaling"]
    n_plate = next(m for m in res["methods"] if m["key"] == "beam_truth")["errors"]["plate"]
    lines = [
        "# Error against run time",
        "",
        f"Made by `{c['command']}` on {env['date']}, prbdm commit `{env['git_commit']}`, "
        f"{res['elapsed_s']:.0f} s in all.",
        "",
        f"- **Held-out beams:** {c['beams']} beams, " + (
            f"`random_beam({src['seed']}, i)`, i = {src['indices']} (paper generator, p = 10); "
            f"the checkpoint was trained on seed {src.get('checkpoint_training_seed')}, so none "
            "of these beams was seen in training."
            if src["source"] == "generated" else
            f"from the data set `{src['path']}` (seed {src['seed']}), rule: {src['rule']}; "
            f"indices {src['indices'][:5]}{' ...' if len(src['indices']) > 5 else ''}."),
        f"- **Checkpoint:** `{ck['name']}` ({ck['training_mode']} mode, {ck['candidates']} "
        f"candidates), trained on {ck['dataset_size']} beams of seed {ck['dataset_seed']} "
        f"(dataset max_index {ck['dataset_max_index']}).",
        f"- **Model:** n = {c['joints']} joints, {c['modes']} modes, paper poses "
        f"({', '.join(f'{p:.2f}' for p in c['poses'])} rad), `{c['law']}` law; fits: "
        f"`fit_many(seed={c['fit_seed']})`; refinement {c['refine_iter']} iterations from the "
        f"network's candidates and the fit's four fixed starts.",
        f"- **Machine:** {env['cores']} cores ({env['system']} {env['machine']}), load average "
        f"{env['load_average_start']:.2f} at the start and {env['load_average_end']:.2f} at the "
        f"end (other jobs were running); torch on {env['torch_threads']} thread.",
        "- **Versions:** " + ", ".join(f"{k} {v}" for k, v in env["versions"].items()) + ".",
        f"- **Random draws:** held-out beams as above; fit start points seeded with "
        f"{c['fit_seed']}; network-throughput beams `{sc['network_throughput']['beams']}`.",
        "",
        "![error against time per beam](error_vs_time.png)",
        "",
        "## Against the plate truth (the reference)",
        "",
        f"Every model against the Kirchhoff plate's frequencies ({n_plate.get('beams', 0)} beams; "
        f"{len(res['plate_failures'])} where the plate could not be solved are left out). "
        "The fits, the network and the refinement were made for the *beam* truth; "
        "`fit to plate truth` was fitted to the plate itself.",
        "",
        method_table(res, "plate"),
        "",
        "Median over the beams of each mode's frequency error (worst over the poses) against "
        "the plate truth:",
        "",
        per_mode_table(res, "plate"),
        "",
        "## Against the beam truth (what the fits and the network target)",
        "",
        method_table(res, "beam"),
        "",
        "Median per-mode frequency error (worst over the poses) against the beam truth:",
        "",
        per_mode_table(res, "beam"),
        "",
        "Columns: `modes` — how many modes the error compares (`min(n, 4)`; the classical "
        "models have only 1 or 3); `loss` — SPEC §3, mean over the model's poses of "
        "`||lambda[:r] - lambda_ref[:r]|| / ||lambda_ref[:r]||`, in %; `worst freq. error` — the "
        "largest `|omega / omega_ref - 1|` over those modes and poses, per beam; median and 95th "
        "percentile over the beams. `time per beam` — wall time of the method alone, mean per "
        "beam; batched methods (RFE chain, classical models, fits, network, refinement) are "
        "timed on all beams in one call and divided by their number (the cheap ones best of 3); "
        "truths are solved one beam at a time. `from geometry` adds the mean time of the truth "
        "the method needs (beam truth for fits and refinement, plate truth for the plate fit). "
        f"`one beam at a time` — the same method called for each of the first {c['single']} "
        "beams alone (what `prbdm fit`/`predict` cost), mean.",
        "",
        "Classical PRBMs: cut from the real planform like any prbdm chain (exact link masses and "
        "inertias), with their own springs `K_j = c_j EI / L` where, on a tapered beam, EI is "
        "the tip-load equivalent `L^3 / (3 ∫ (L-x)^2 / EI(x) dx)` (the uniform beam with the same "
        "tip-force compliance; `prbdm/classical.py`), evaluated at the paper poses of their own "
        "n (30 poses for n = 1, 9 for n = 3).",
        "",
        "## How the cost grows",
        "",
        f"Scaling studies on the first {sc['beams']} held-out beams (fits batched over them, "
        "time per beam).",
        "",
        "![fit time against n](fit_time_vs_n.png) ![fit time against starts](fit_time_vs_starts.png)",
        "",
        "![truth time against mesh size](truth_time_vs_mesh.png) "
        "![network throughput](network_throughput.png)",
        "",
        f"Fit time against n ({sc['fit_vs_n']['starts']} starts, modes mapped = n, paper poses):",
        "",
        "| n | poses | time per beam | median loss |",
        "|---|---|---|---|",
        *[f"| {r['n']} | {r['poses']} | {_fmt_t(r['time_s'])} | {r['loss_median']:.3g} % |"
          for r in sc["fit_vs_n"]["rows"]],
        "",
        "Fit time against starts (n = 4, 4 modes):",
        "",
        "| starts | time per beam | median loss |",
        "|---|---|---|",
        *[f"| {r['starts']} | {_fmt_t(r['time_s'])} | {r['loss_median']:.4g} % |"
          for r in sc["fit_vs_starts"]["rows"]],
        "",
        "Truth time against mesh size (median over the beams; `elements` option → actual "
        "elements):",
        "",
        "| truth | `elements` | elements (triangles) | DOFs | time per beam |",
        "|---|---|---|---|---|",
        *[f"| {r['model']} | {r['elements_option']} | {r['elements']:.0f} | "
          f"{_fmt_int(r['dofs'])} | {_fmt_t(r['time_s'])} |"
          for r in sc["truth_vs_mesh"]["rows"]],
        "",
        "Network throughput (`Surrogate.predict` on Beam objects: features, network, candidate "
        "choice, k, PRBDM frequencies at every pose, truth frequencies; best of several):",
        "",
        "| batch | beams/s |",
        "|---|---|",
        *[f"| {r['batch']} | {r['beams_per_s']:.4g} |" for r in sc["network_throughput"]["rows"]],
    ]
    if res["plate_failures"]:
        lines += ["", "Plate truth failures: " + "; ".join(
            f"beam {f['beam']}: {f['error']}" for f in res["plate_failures"])]
    # the stability suite's Markdown brings its own heading
    if not (stability_md or "").lstrip().startswith("#"):
        lines += ["", "## Stability on stiff and extreme cases"]
    lines += ["", stability_md if stability_md else stability_note]
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------------- plots
def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _png(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100, bbox_inches="tight")
    import matplotlib.pyplot as plt

    plt.close(fig)
    return buf.getvalue()


_MARKERS = {"plate_truth": "s", "beam_truth": "D", "rfe": "v", "howell-1r": "<", "su-3r": ">",
            "fit_plate": "P", "network": "*", "refined": "X", "direct": "h"}


def _colors(methods, plt) -> dict:
    """Distinct colours; the fits at several start counts in shades of one hue."""
    fits = [m["key"] for m in methods if m["key"].startswith("fit_") and m["key"] != "fit_plate"]
    greens = plt.get_cmap("Greens")
    out = {k: greens(0.4 + 0.55 * i / max(len(fits) - 1, 1)) for i, k in enumerate(fits)}
    others = [m["key"] for m in methods if m["key"] not in out]
    tab = plt.get_cmap("tab10")
    palette = [tab(i) for i in (0, 1, 3, 4, 5, 6, 7, 8, 9, 2)]
    out.update({k: palette[i % len(palette)] for i, k in enumerate(others)})
    return out


def plot_error_vs_time(res: dict) -> bytes:
    plt = _pyplot()
    fig, axes = plt.subplots(2, 2, figsize=(12, 9))
    colors = _colors(res["methods"], plt)
    for row, ref in enumerate(("plate", "beam")):
        for col, (stat, label) in enumerate((("loss", "loss (SPEC §3) [%]"),
                                             ("worst", "worst per-mode frequency error [%]"))):
            ax = axes[row, col]
            for i, m in enumerate(res["methods"]):
                e = m["errors"][ref]
                color = colors[m["key"]]
                if e.get("reference"):
                    ax.axvline(m["time_s"], color=color, ls="--", lw=1,
                               label=f"{m['label']} (reference)")
                    continue
                scale = 1.0 if stat == "loss" else 100.0
                med, p95 = e[f"{stat}_median"] * scale, e[f"{stat}_p95"] * scale
                if not (math.isfinite(med) and med > 0):
                    continue
                mk = _MARKERS.get(m["key"], "o")
                ax.errorbar([m["time_s"]], [med], yerr=[[0], [max(p95 - med, 0)]], fmt=mk,
                            color=color, ms=8, capsize=3, label=m["label"])
                if m["total_s"] > m["time_s"] * 1.01:
                    ax.plot([m["time_s"], m["total_s"]], [med, med], color=color, lw=0.8,
                            ls=":")
                    ax.plot([m["total_s"]], [med], marker="|", color=color, ms=10)
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.grid(True, which="both", alpha=0.3)
            ax.set_xlabel("time per beam [s]")
            ax.set_ylabel(label)
            ax.set_title(f"against the {ref} truth" + (" (reference)" if ref == "plate" else ""))
    handles = {}
    for ax in axes.flat:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(lab.replace(" (reference)", ""), h)
    fig.legend(list(handles.values()), list(handles), loc="lower center", ncol=4, fontsize=8,
               frameon=False)
    fig.suptitle("Error against time per beam: marker = median, whisker up to the 95th "
                 "percentile; dotted line to '|' = with the truth the method needs", fontsize=10)
    fig.tight_layout(rect=(0, 0.1, 1, 0.97))
    return _png(fig)


def plot_scaling(res: dict) -> dict:
    plt = _pyplot()
    sc = res["scaling"]
    out = {}
    fig, ax = plt.subplots(figsize=(6, 4.2))
    rows = sc["fit_vs_n"]["rows"]
    ax.loglog([r["n"] for r in rows], [r["time_s"] for r in rows], "o-")
    ax.set_xlabel("joints n (modes mapped = n)")
    ax.set_ylabel("fit time per beam [s]")
    ax.set_title(f"fit time against n ({sc['fit_vs_n']['starts']} starts, {sc['beams']} beams)")
    ax.set_xticks([r["n"] for r in rows])
    ax.set_xticklabels([str(r["n"]) for r in rows])
    ax.grid(True, which="both", alpha=0.3)
    out["fit_time_vs_n.png"] = _png(fig)

    fig, ax = plt.subplots(figsize=(6, 4.2))
    rows = sc["fit_vs_starts"]["rows"]
    ax.loglog([r["starts"] for r in rows], [r["time_s"] for r in rows], "o-", label="time")
    ax.set_xlabel("start points")
    ax.set_ylabel("fit time per beam [s]")
    ax2 = ax.twinx()
    ax2.semilogx([r["starts"] for r in rows], [r["loss_median"] for r in rows], "s--", color="C1",
                 label="median loss")
    ax2.set_ylabel("median loss [%]", color="C1")
    ax.set_title(f"fit time against starts (n = 4, {sc['beams']} beams)")
    ax.grid(True, which="both", alpha=0.3)
    out["fit_time_vs_starts.png"] = _png(fig)

    fig, ax = plt.subplots(figsize=(6, 4.2))
    for model, mk in (("beam", "o-"), ("plate", "s-")):
        rows = [r for r in sc["truth_vs_mesh"]["rows"] if r["model"] == model]
        if rows:
            ax.loglog([r["elements"] for r in rows], [r["time_s"] for r in rows], mk,
                      label=f"{model} truth")
    ax.set_xlabel("elements (beam: Hermite elements; plate: Argyris triangles, half model)")
    ax.set_ylabel("time per beam [s]")
    ax.set_title("truth time against mesh size")
    ax.legend()
    ax.grid(True, which="both", alpha=0.3)
    out["truth_time_vs_mesh.png"] = _png(fig)

    fig, ax = plt.subplots(figsize=(6, 4.2))
    rows = sc["network_throughput"]["rows"]
    ax.loglog([r["batch"] for r in rows], [r["beams_per_s"] for r in rows], "o-")
    ax.set_xlabel("batch size [beams]")
    ax.set_ylabel("beams per second")
    ax.set_title("network throughput against batch size")
    ax.grid(True, which="both", alpha=0.3)
    out["network_throughput.png"] = _png(fig)
    return out


# ---------------------------------------------------------------------------- stability section
def _stability_script() -> Path | None:
    """``benchmarks/stability.py`` of the source checkout this package runs from, else None: the
    stability suite is evidence kept in the repository (its cases are tests), not installed."""
    root = Path(__file__).resolve().parents[1]
    script = root / "benchmarks" / "stability.py"
    return script if (root / "pyproject.toml").is_file() and script.is_file() else None


def stability_section(cfg: ReportConfig) -> tuple[str | None, str]:
    """The stability suite's Markdown, or None and a note saying why it is absent."""
    if not cfg.stability:
        return None, "Skipped (`--no-stability`)."
    script = _stability_script()
    if script is None:
        return None, ("Not included: the stability suite (`benchmarks/stability.py`, cases in "
                      "`tests/stability_cases.py`) is part of the prbdm repository, not of the "
                      "installed package; run `prbdm report` from a source checkout to append "
                      "it, or see docs/stability.md.")
    import importlib.util

    try:
        spec = importlib.util.spec_from_file_location("_prbdm_stability_writer", script)
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        return mod.section(quick=cfg.quick), ""
    except Exception as exc:          # the report stands on its own; say what failed
        return None, f"Not included: the stability suite failed ({type(exc).__name__}: {exc})."


def write_report(cfg: ReportConfig, out) -> dict:
    """Run everything, then write ``out``/report.md, report.json and the PNGs (atomically)."""
    from .commands._common import atomic_write

    res = run_report(cfg)
    stab_md, stab_note = stability_section(cfg)
    res["stability"] = {"included": stab_md is not None, "note": stab_note, "markdown": stab_md}
    files = {"error_vs_time.png": plot_error_vs_time(res), **plot_scaling(res)}
    files["report.md"] = render_markdown(res, stab_md, stab_note)
    files["report.json"] = json.dumps(res, indent=1, default=_jsonable) + "\n"
    out = Path(out)
    for name, data in files.items():
        atomic_write(out / name, data)
    return res


def _jsonable(v):
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, np.ndarray):
        return v.tolist()
    return str(v)
