"""``prbdm fit BEAM --joints N``: the optimised PRBDM of a beam (docs/conventions.md §3 Eq. 13, §4).

Computes the beam's truth frequencies (``--truth``; by default ``auto``: the Euler-Bernoulli FEM
for a strip up to 0.05 L wide, the Kirchhoff plate beyond, :mod:`prbdm.truth.choice`), then fits
gamma and the stiffness correction by batched multistart optimisation (:mod:`prbdm.fit`): at rest,
its stiffness then held at every pose (``--pose-target shape``, the default), or one SCF per pose
matched to the straight panel (``--pose-target straight``, the paper's).

JSON (``--json``): everything of :meth:`prbdm.fit.FitResult.to_dict` (``gamma``, ``k``, ``law``,
``poses``, ``omega_truth``, ``omega`` per pose, ``freq_hz``, ``freq_error`` per pose and mode,
``loss_percent``, ``starts``, ``n_near_best``, ``gamma_spread``, ``time_s``), plus ``truth``
(model and its time), ``links`` (the SI link table), ``pose_target`` and ``self_check``. With
``--pose-target shape``: ``rest`` (``k``, ``omega``, ``freq_hz``, ``freq_error`` of the fit at rest,
against the truth; ``loss_percent`` is the loss there), ``k`` that SCF at every pose, and
``freq_error`` per pose against the rod bent into the pose's shape, null where the poses are not
checked (a plate truth: ``self_check.poses`` says why).
"""
from __future__ import annotations

import math
import sys

import numpy as np

from ..errors import BadInput
from ..pose_target import DEFAULT_POSE_TARGET, POSE_TARGETS
from ._common import (
    add_beam_argument,
    check_plot_path,
    positive_int,
    print_json,
    progress_bar,
    read_beam,
    require,
    table,
)

TRUTHS = ("analytic", "beam", "plate", "mindlin")


def add_arguments(parser):
    add_beam_argument(parser)
    parser.add_argument("--joints", "-n", type=positive_int(1, 39), required=True,
                        help="number of revolute joints n (1..39: each link >= 0.025 L)")
    parser.add_argument("--modes", type=positive_int(1, 50), default=None,
                        help="truth modes to map, r = min(n, modes) (default n)")
    parser.add_argument("--truth", choices=(*TRUTHS, "auto"), default="auto",
                        help="truth model: 'analytic' (uniform beams), 'beam' Euler-Bernoulli FEM, "
                             "'plate' Kirchhoff FEM, 'mindlin' shear-deformable plate FEM (for "
                             "panels thicker than about 0.02 L; about 8x the plate's time), or "
                             "'auto' (default): the beam up to a full "
                             "width of 0.05 L, the plate beyond, where the beam would be more than "
                             "1 %% off (docs/howto/choose-a-truth.md)")
    parser.add_argument("--objective", choices=("eigenvalue", "frequency"), default="eigenvalue",
                        help="what the fit minimises: 'eigenvalue', the paper's loss (default), "
                             "or 'frequency', the worst relative frequency error per pose "
                             "(every mode right; docs/howto/fit.md). Both are reported")
    parser.add_argument("--law", choices=("beam", "paper"), default="beam",
                        help="base joint stiffness law (default 'beam')")
    parser.add_argument("--poses", default="paper", metavar="paper|linear|T1,T2,...",
                        help="pose set (default 'paper')")
    parser.add_argument("--pose-target", choices=POSE_TARGETS, default=DEFAULT_POSE_TARGET,
                        help="what the chain matches at a deflected pose: 'shape' (default), the "
                             "panel bent into the pose's shape: fitted at rest and its stiffness "
                             "held at every pose, each pose of a strip checked against the "
                             "geometrically exact rod in that shape; 'straight', the paper's: the "
                             "straight panel's frequencies at every pose, one SCF per pose "
                             "(docs/method.md, 'Poses')")
    parser.add_argument("--starts", type=positive_int(1, 100000), default=None,
                        help="start points of the multistart (default 64)")
    parser.add_argument("--seed", type=positive_int(0), default=0,
                        help="seed of the random start points (default 0)")
    parser.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    parser.add_argument("--plot", metavar="FILE", default=None,
                        help="write the planform cut into links and SCF vs angle (PNG/PDF/SVG)")


def run(args) -> int:
    from ..parsing import parse_poses
    from ..truth.choice import choose_truth
    from ._common import beam_from_file

    # read once; `auto` chooses from the panel, then the beam is checked against the chosen
    # truth's limits before anything is printed (a refusal is one line)
    beam = beam_from_file(args)
    model, reason = choose_truth(beam, args.truth)
    beam, info = read_beam(args, "fit", model=model, beam=beam)
    n = args.joints
    modes = args.modes or n
    poses, warnings = parse_poses(args.poses, n)
    if args.plot:
        check_plot_path(args.plot)
        require("matplotlib", purpose="--plot")

    from ..truth import bending_frequencies, modes_for_fit

    try:
        truth = bending_frequencies(beam, model=model, modes=modes_for_fit(model, n, modes))
    except BadInput as exc:
        # the truth library speaks of `prbdm truth --model`; here the flag is --truth
        raise BadInput(str(exc).replace(f"model {model!r}:", f"--truth {model}:")
                       .replace("--model", "--truth")) from None

    import torch

    # one process, small batched problems: one thread is fastest (docs/conventions.md §6, "Threads")
    torch.set_num_threads(1)

    from ..fingerprint import beam_fingerprint
    from ..fit import fit_prbdm
    from ..model import BeamTensors, links_from_gamma

    shape = args.pose_target == "shape"
    progress, close = progress_bar("prbdm fit")
    try:
        result = fit_prbdm(beam, truth.omega, joints=n, modes=modes, law=args.law,
                           poses="linear" if shape else poses, starts=args.starts,
                           seed=args.seed, objective=args.objective, progress=progress)
    finally:
        close()
    rest, shape_check, shape_warnings = result, None, []
    if shape:
        from ..model import make_poses
        from ..pose_target import hold_stiffness

        result = hold_stiffness(beam, rest, make_poses(poses, n).numpy())
        result, shape_check, shape_warnings = _shape_check(beam, result, truth.model)
    bt = BeamTensors.from_beams(beam)
    with torch.no_grad():
        links = links_from_gamma(bt, torch.as_tensor(result.gamma)).physical(bt)
    out = result.to_dict()
    out["pose_target"] = args.pose_target
    if shape:
        # fitted at rest: its answer there against the truth; the poses' errors are against the
        # rod bent into each pose's shape where that was checked (a strip), else null
        out["rest"] = {"k": float(rest.k[0]), "omega": rest.omega[0].tolist(),
                       "freq_hz": (rest.omega[0] / (2 * math.pi)).tolist(),
                       "freq_error": rest.freq_error[0].tolist()}
        if not shape_check["checked"]:
            out["freq_error"] = None
        out["max_freq_error"] = float(max(rest.freq_error.max(),
                                          result.freq_error.max() if shape_check["checked"]
                                          else 0.0))
        out["max_freq_error_at"] = ("rest and the poses (against the rod)"
                                    if shape_check["checked"] else "rest")
    out["truth"] = {"model": truth.model, "time_s": truth.time_s, "reason": reason}
    out["links"] = {key: v.tolist() for key, v in links.items()}
    from ..preflight import check_answer
    from ..truth.choice import shear_caveat

    # every answer checks itself: the fitted PRBDM at every pose against the truth it was fitted to
    out["self_check"], off = check_answer(
        rest.omega, truth.omega, rest.modes, rest.poses,
        truth_source=f"the {truth.model} truth", remedy=fit_remedy(args, n, modes),
        objective=args.objective)
    warnings += off
    if shape:
        out["self_check"]["poses"] = shape_check
        warnings += shape_warnings
    caveat = shear_caveat(beam, truth.model)
    if caveat:
        warnings.append(caveat)
    out["warnings"] = warnings
    out["input"] = info
    out["beam_fingerprint"] = beam_fingerprint(beam)   # export/simulate --from check it
    if args.plot:
        from ..plots import plot_fit

        plot_fit(beam, result, args.plot)
    if args.json:
        print_json(out)
        return 0
    for w in warnings:
        sys.stderr.write(f"warning: {w}\n")
    _print_report(beam, result, truth, links, rest if shape else None, shape_check)
    if args.plot:
        print(f"plot written to {args.plot}")
    return 0


def _shape_check(beam, result, model: str):
    """(result, check, warnings): a ``shape`` fit at its poses against the geometrically exact rod
    bent into each pose's shape, the reference it was made for away from rest (``freq_error``
    becomes the error against it, pose by pose). The rod is the panel as a strip; for a plate
    truth the poses are not checked (a bent wide panel is a shell), and the check says so."""
    import dataclasses

    from ..pose_target import shape_truths
    from ..preflight import check_answer

    if model not in ("beam", "analytic"):
        return result, {"checked": False, "why": f"the poses of a {model} fit are not checked: "
                        "the rod is the panel as a strip, and a bent wide panel is a shell"}, []
    ref = shape_truths(beam, result.gamma, result.poses, result.modes)
    # each pose against the rod in its own shape (check_answer takes a truth per pose)
    check, _ = check_answer(result.omega, ref, result.modes, result.poses,
                            truth_source="the rod in the pose's shape", remedy="",
                            objective="frequency")
    check["checked"] = True
    check.pop("loss_percent", None)     # checked by frequency: the loss is the rest fit's
    check["omega_reference"] = ref.tolist()
    err = result.omega[:, :result.modes] / ref - 1.0
    warnings = []
    if not check["ok"]:
        j = check["worst_mode"] - 1
        warnings.append(f"mode {j + 1}: held at the poses, the PRBDM is "
                        f"{100 * abs(check['error'][j]):.3g} % "
                        "off the panel bent into the pose's shape (the geometrically exact rod; "
                        f"tolerance {100 * check['tolerance']:g} %); more joints follow a bent "
                        "panel more closely")
    return dataclasses.replace(result, freq_error=np.abs(err)), check, warnings


def fit_remedy(args, n: int, modes: int) -> str:
    """What to try when a fitted mode misses the truth (the self-check's warning)."""
    tries = []
    if getattr(args, "objective", "eigenvalue") == "eigenvalue":
        tries.append("`--objective frequency` (the paper's eigenvalue loss lets the low modes "
                     "drift to fit the highest)")
    if getattr(args, "poses", "paper") != "linear" \
            and getattr(args, "pose_target", "straight") != "shape":
        tries.append("`--poses linear` for small vibrations about the straight panel")
    if n <= modes:
        tries.append(f"more joints than modes (`--joints {n + 1} --modes {modes}`)")
    tries.append("more start points (`--starts`)")
    return "try " + ", or ".join(tries)


def _print_report(beam, r, truth, links, rest=None, shape_check=None):
    n, m = r.joints, len(r.k)
    print(f"{n}R-PRBDM of {beam.name or 'beam'}: law={r.law}, {m} pose(s), "
          f"{r.modes} mode(s) mapped, truth={truth.model}")
    if rest is None:
        print(f"objective {r.objective}: frequency objective {r.frequency_percent:.4g} %, "
              f"worst mode error {100 * r.freq_error.max():.3g} %")
    else:
        poses_words = (f", at the poses against the bent rod {100 * r.freq_error.max():.3g} %"
                       if shape_check and shape_check.get("checked") else "")
        print(f"objective {r.objective}: fitted at rest, worst mode error there "
              f"{100 * rest.freq_error.max():.3g} %{poses_words}")
    print(f"loss {r.loss_percent:.5g} %   (best start's {r.objective} objective "
          f"{r.best_objective_percent:.5g} %; "
          f"{r.n_near_best}/{r.n_starts} starts within 1 %, gamma spread {r.gamma_spread:.3g}; "
          f"{r.time_s:.2f} s fit, {truth.time_s:.3f} s truth)")
    print()
    rows = [[j, f"{r.gamma[j]:.4f}", f"{links['length'][j]:.4g}",
             *(["", "", ""] if j == 0 else [f"{links['mass'][j - 1]:.4g}",
                                            f"{links['com'][j - 1]:.4g}",
                                            f"{links['inertia'][j - 1]:.4g}"])]
            for j in range(n + 1)]
    print(table(rows, ["link", "gamma", "length m", "mass kg", "com m", "J kg m^2"]))
    print()
    rows = []
    if rest is not None:
        # a shape fit: fitted at rest (its error against the truth there), the stiffness held at
        # the poses (their error against the rod bent into each pose's shape, where checked)
        rows.append(["rest", f"{0.0:.3f}", f"{rest.k[0]:.5g}",
                     *(f"{w / (2 * math.pi):.4g}" for w in rest.omega[0][:r.modes]),
                     f"{100 * max(rest.freq_error[0]):.3f}"])
    checked = rest is None or bool(shape_check and shape_check.get("checked"))
    for i in range(m):
        err = f"{100 * max(r.freq_error[i]):.3f}" if checked else "-"
        rows.append([i, f"{r.poses[i][0]:.3f}", f"{r.k[i]:.5g}",
                     *(f"{w / (2 * math.pi):.4g}" for w in r.omega[i][:r.modes]), err])
    rows.append(["truth", "", "", *(f"{w / (2 * math.pi):.4g}" for w in r.omega_truth[:r.modes]),
                 ""])
    print(table(rows, ["pose", "theta rad", "SCF k", *(f"f{j + 1} Hz" for j in range(r.modes)),
                       "max err %"]))
    if rest is not None:
        print("(truth: the straight panel; " + (
            "the poses' error is against the panel bent into the pose's shape, the "
            "geometrically exact rod)" if checked else f"{shape_check['why']})"))
