"""``prbdm compare BEAM --joints N``: truth vs surrogate vs optimised fit vs surrogate-then-refined.

Four ways to get the PRBDM of one beam, side by side:

- ``truth``: the truth frequencies (``--truth``, FEM; what the others are measured against; by
  default ``auto`` as in ``prbdm predict``: the plate for a panel wider than 0.05 L (the Mindlin
  plate for a thick or necked one), with that truth's network when the panel is wider than 0.1 L
  and one is found that can answer it, else the next (Mindlin, Kirchhoff plate, beam; for a thin
  panel Kirchhoff plate, Mindlin, beam) measured
  against that truth (the beam's on purpose up to 0.1 L, said in ``truth.reason``; otherwise said
  in ``warnings``);
- ``network``: the surrogate's PRBDM (:mod:`prbdm.surrogate`, no FEM), and ``network (direct)``:
  the network's own prediction of the truth frequencies;
- ``fit``: the optimised PRBDM (multistart, :func:`prbdm.fit.fit_prbdm`, ``--starts``), minimising
  the checkpoint's objective (``--objective`` picks the checkpoint: the paper's eigenvalue loss by
  default, or the frequency objective);
- ``refined``: the fit started from the network's best candidate gammas (``REFINE_CANDIDATES``)
  and the fit's four fixed starts (:func:`prbdm.fit.refine_starts`), ``--refine-iter``
  iterations (:func:`prbdm.fit.fit_many` with ``init_gamma``).

For each: the loss (docs/conventions.md §3, %), the per-mode frequency error (worst over the poses, %) and the
time (the computation itself; start-up and imports excluded; ``refined`` excludes the network's
own time, given on its row).

JSON (``--json``): ``truth`` (model, reason, omega, freq_hz, time_s), ``network``, ``network_direct``,
``fit``, ``refined`` (each with gamma, k, omega per pose, loss_percent, freq_error per mode,
time_s; ``network_direct``: omega, freq_error per mode), ``joints``, ``modes``, ``checkpoint``,
``warnings``.
"""
from __future__ import annotations

import math
import sys
import time

import numpy as np

from ..constants import REFINE_ITER
from ._common import (
    add_beam_argument,
    beam_from_file,
    positive_int,
    print_json,
    progress_bar,
    read_beam,
    table,
)
from .predict import add_extrapolation_argument, add_objective_argument


def add_arguments(parser):
    add_beam_argument(parser)
    parser.add_argument("--joints", "-n", type=positive_int(1, 39), required=True,
                        help="number of revolute joints n (a checkpoint must exist for it)")
    parser.add_argument("--truth", choices=("beam", "plate", "mindlin", "auto"), default=None,
                        help="truth model and network (default: auto, as prbdm predict: the "
                             "plate, or the Mindlin plate for a thick or necked one, for a panel "
                             "wider than 0.05 L, with that truth's network above 0.1 L when one "
                             "is found and covers it, else the next one's, measured against "
                             "that truth)")
    parser.add_argument("--checkpoint", metavar="PATH", default=None,
                        help="surrogate checkpoint (default: the packaged one for --joints, "
                             "--truth)")
    parser.add_argument("--starts", type=positive_int(1, 100000), default=None,
                        help="start points of the optimised fit (default: prbdm fit's)")
    parser.add_argument("--seed", type=positive_int(0), default=0,
                        help="seed of the fit's start points (default 0)")
    parser.add_argument("--refine-iter", type=positive_int(1, 10000), default=REFINE_ITER,
                        help="iterations of the refinement from the network's best candidates and "
                             f"the fit's fixed starts (default {REFINE_ITER})")
    add_objective_argument(parser)
    add_extrapolation_argument(parser)
    parser.add_argument("--json", action="store_true", help="print one JSON object on stdout")


def _errors(omega_pose, omega_truth, r):
    """Per-mode relative frequency error, worst over the poses: (r,)."""
    return (np.abs(omega_pose[:, :r] / omega_truth[None, :r] - 1)).max(0)


def _loss(omega_pose, omega_truth, r):
    lam, ref = omega_pose[:, :r] ** 2, omega_truth[:r] ** 2
    return float(100 * np.mean(np.linalg.norm(lam - ref, axis=-1) / np.linalg.norm(ref)))


def run(args) -> int:
    import warnings as _w

    from .. import surrogate
    from ..surrogate import selection
    from ..truth.choice import shear_caveat, width_ratio

    # `--truth auto` (the default): the truth the panel needs, and that truth's network when one
    # is found and can answer this panel; otherwise the beam network, measured against it. The
    # beam is read once, checked against the limits of the truth it is measured against.
    request = selection.Request.from_args(args)
    beam = beam_from_file(args)
    plan = selection.plan(beam, request)
    beam, info = read_beam(args, "compare", model=plan.model, beam=beam)

    def network_prediction(sur):
        with _w.catch_warnings():
            _w.simplefilter("ignore", surrogate.OutOfDistributionWarning)
            _w.simplefilter("ignore", surrogate.ImplausiblePredictionWarning)
            _w.simplefilter("ignore", surrogate.LowAccuracyWarning)  # in the JSON, below
            t0 = time.perf_counter()
            pred = sur.predict(beam, frequencies=True,
                               allow_extrapolation=request.allow_extrapolation)
            return pred, time.perf_counter() - t0

    chosen = selection.answer(plan, beam, network_prediction)
    sur, (pred, t_net) = chosen.surrogate, chosen.answer
    model, reason, notes = selection.measured_against(plan, chosen)
    n, r = sur.joints, sur.modes
    R = len(sur.norm["freq_mean"])
    width = width_ratio(beam)
    notes += [w for w in (sur.accuracy_warning(width),
                          selection.wrong_truth_note(plan, chosen, reason)) if w]

    from ..truth import bending_frequencies

    truth = bending_frequencies(beam, model=model, modes=max(R, n))
    omega_t = np.asarray(truth.omega, dtype=np.float64)
    caveat = shear_caveat(beam, truth.model)
    if caveat:
        notes.append(caveat)

    import torch

    # one process, small batched problems: one thread is fastest (as `prbdm fit`; docs/choices.md,
    # "Threads"); with the default threads a lone fit took 5.7 s instead of 0.64 s on a busy
    # 2-core machine
    torch.set_num_threads(1)

    from ..fit import REFINE_CANDIDATES, FitProblem, StopRules, fit_many, fit_prbdm, refine_starts

    poses = sur.poses.tolist()
    progress, close = progress_bar("prbdm compare: fit")
    try:
        fit = fit_prbdm(beam, omega_t, joints=n, modes=r, law=sur.law, poses=poses,
                        starts=args.starts, seed=args.seed, objective=sur.objective,
                        progress=progress)
    finally:
        close()
    progress, close = progress_bar("prbdm compare: refined")
    t0 = time.perf_counter()
    try:
        starts = refine_starts(pred.ranked_candidates(REFINE_CANDIDATES))
        ref = fit_many(FitProblem([beam], omega_t[None, :], n, r, sur.law, poses, sur.objective),
                       init_gamma=starts, stop=StopRules(max_iter=args.refine_iter),
                       progress=progress)[0]
    finally:
        close()
    t_ref = time.perf_counter() - t0

    def method(gamma, k, omega, t):
        om = np.asarray(omega)
        return {"gamma": np.asarray(gamma).tolist(), "k": np.asarray(k).tolist(),
                "omega": om.tolist(), "freq_hz": (om / (2 * math.pi)).tolist(),
                "loss_percent": _loss(om, omega_t, r),
                "freq_error": _errors(om, omega_t, r).tolist(), "time_s": t}

    Rd = min(R, len(omega_t))
    direct = pred.omega_truth[0][:Rd]
    out = {
        "joints": n, "modes": r, "objective": sur.objective, "pose_target": sur.pose_target,
        "checkpoint": sur.describe(),
        "held_out_accuracy_at_this_width": sur.held_out_accuracy(width),
        "truth": {"model": truth.model, "reason": reason, "omega": omega_t.tolist(),
                  "freq_hz": (omega_t / (2 * math.pi)).tolist(), "time_s": truth.time_s},
        "network": method(pred.gamma[0], pred.k[0], pred.omega[0], t_net),
        "network_direct": {"omega": direct.tolist(),
                           "freq_hz": (direct / (2 * math.pi)).tolist(),
                           "freq_error": np.abs(direct / omega_t[:Rd] - 1).tolist(),
                           "time_s": t_net},
        "fit": {**method(fit.gamma, fit.k, fit.omega, fit.time_s), "starts": fit.n_starts},
        "refined": {**method(ref.gamma, ref.k, ref.omega, t_ref),
                    "max_iter": args.refine_iter},
        # an implausible network prediction is shown beside the others here, and said so
        "warnings": [w.replace("beam 0: ", "") for w in pred.warnings + pred.problems] + notes,
        "input": info,
    }
    # every answer checks itself against the truth it is compared with, by its objective's measure
    from ..preflight import check_answer

    for key, label in (("network", "the network's PRBDM"), ("fit", "the fit"),
                       ("refined", "the refined fit")):
        out[key]["self_check"], off = check_answer(
            out[key]["omega"], omega_t, r, pred.poses, truth_source=f"the {truth.model} truth",
            remedy="the fit is the faithful route where the network is off"
            if key == "network" else "`prbdm fit --objective frequency` keeps every mode close",
            objective=sur.objective)
        out["warnings"] += [f"{label}: {w}" for w in off]
    for w in out["warnings"]:
        sys.stderr.write(f"prbdm compare: warning: {w}\n")
    if args.json:
        print_json(out)
    else:
        print(render(out, beam))
    return 0


def render(o: dict, beam) -> str:
    r = o["modes"]
    Rd = len(o["network_direct"]["freq_error"])
    cols = max(r, Rd)
    t = o["truth"]
    lines = [f"beam: {beam.name or '(unnamed)'}; {o['joints']}R-PRBDM mapping {r} modes; "
             f"checkpoint {o['checkpoint']['name']}; {o['objective']} objective; "
             + ("at rest (the shape pose target: its stiffness held at deflected poses)"
                if o.get("pose_target") == "shape" else "the paper's poses"), ""]
    rows = [["truth (" + t["model"] + ")", "", *(f"{f:.5g} Hz" for f in t["freq_hz"][:cols]),
             f"{t['time_s']:.3g}"]]
    for key, label in (("network", "network"), ("network_direct", "network (direct)"),
                       ("fit", f"fit ({o['fit']['starts']} starts)"),
                       ("refined", f"refined ({o['refined']['max_iter']} it.)")):
        m = o[key]
        errs = [f"{e * 100:.3f} %" for e in m["freq_error"]]
        errs += [""] * (cols - len(errs))
        loss = f"{m['loss_percent']:.4f}" if "loss_percent" in m else ""
        rows.append([label, loss, *errs, f"{m['time_s']:.3g}"])
    lines.append(table(rows, ["method", "loss %", *(f"mode {j + 1}" for j in range(cols)),
                              "time s"]))
    lines.append("\n(mode columns: truth frequency on the truth row, relative frequency error "
                 "elsewhere, worst over the poses for the PRBDMs)")
    return "\n".join(lines)
