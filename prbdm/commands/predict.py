"""``prbdm predict BEAM --joints N``: the PRBDM of a beam from the trained surrogate, no FEM.

A network (:mod:`prbdm.surrogate`) maps the planform to the link fractions gamma, one stiffness
correction factor per pose, and the beam's own truth frequencies; the PRBDM built from gamma and k
then gives the frequencies per pose. Neither torch nor scikit-fem is imported: the network and the
PRBDM run in NumPy, so the command answers in well under a second.

The checkpoint is ``--checkpoint PATH``, or the default one for (``--joints``, ``--truth``)
(:func:`prbdm.surrogate.default_checkpoint`), checked on load (exit 2 naming the file if it is
corrupt or inconsistent). A beam whose features fall outside the range seen in training gets a
warning naming the feature (stderr; also in ``warnings`` of the JSON); a feature that did not vary
in training at all (e.g. nu for a plate network trained on one material) is refused (exit 2)
unless ``--allow-extrapolation``; when ``--truth auto`` (the default) chose that network, the next
one answers instead (a Mindlin network's panel goes to the Kirchhoff plate's, the nearer physics,
then to the beam's) and the warning says why. A prediction that is non-finite or outside physical ranges
(:func:`prbdm.surrogate.physical_problems`) is an error: exit 2 when the beam lies outside the
training range, exit 1 otherwise (the checkpoint's fault), one line on stderr, never a number.
Any other failure is one line and exit 1 too, with or without ``--json``.

JSON (``--json``): ``gamma``, ``k`` (one per pose), ``law``, ``poses``, ``omega`` and ``freq_hz``
(the PRBDM's frequencies per pose), ``omega_truth_predicted`` and ``freq_hz_truth_predicted`` (the
network's direct prediction of the truth frequencies), ``links`` (the SI link table: ``joint_x``,
``length``, ``mass``, ``com``, ``inertia``, ``area_moment``, ``base_stiffness`` s_j and
``stiffness`` k_i s_j per pose [N m/rad]), ``checkpoint`` (path, name, truth, joints, data set
size, ``held_out_accuracy``: its whole test), ``held_out_accuracy_at_this_width`` (its test panels
of this panel's width band, ``full_width``; the whole test, ``full_width`` null, where it recorded
no such band: what the rough-estimate warning judges by), ``truth``, ``joints``, ``modes``,
``beam``, ``source`` (``network CHECKPOINT``), ``warnings``, ``time_s`` (the prediction itself, start-up excluded). The output is a valid
``prbdm export BEAM --from PREDICT.json`` input, like ``prbdm fit --json``'s.
"""
from __future__ import annotations

import math
import sys

from ..constants import OBJECTIVES
from ..errors import BadInput
from ._common import add_beam_argument, peek_beam, positive_int, print_json, read_beam, table

TRUTHS = ("beam", "plate", "mindlin")


def add_arguments(parser):
    add_beam_argument(parser)
    parser.add_argument("--joints", "-n", type=positive_int(1, 39), required=True,
                        help="number of revolute joints n (a checkpoint must exist for it)")
    parser.add_argument("--truth", choices=(*TRUTHS, "auto"), default=None,
                        help="truth model the network was trained on (default auto: for a "
                             "panel wider than 0.1 L the network of the truth it needs, the "
                             "Mindlin plate's (thick or necked) or the Kirchhoff plate's, when "
                             "one is found and covers it, else the next: Mindlin, plate, beam; "
                             "the beam's for a strip, and on plate panels 0.05-0.1 L wide, "
                             "where its PRBDM is the closer to the plate; with --checkpoint, "
                             "the checkpoint's)")
    parser.add_argument("--checkpoint", metavar="PATH", default=None,
                        help="surrogate checkpoint (.safetensors); default: the packaged one for "
                             "--joints and --truth")
    add_objective_argument(parser)
    add_extrapolation_argument(parser)
    parser.add_argument("--json", action="store_true", help="print one JSON object on stdout")


def add_objective_argument(parser):
    parser.add_argument("--objective", choices=OBJECTIVES, default=None,
                        help="what the network was trained to minimise: the paper's eigenvalue "
                             "loss, or the worst frequency error per pose (every mode right); "
                             "default: the checkpoint's, or 'eigenvalue' to pick the default "
                             "checkpoint (TRUTH-nJOINTS[-frequency])")


def add_extrapolation_argument(parser):
    parser.add_argument("--allow-extrapolation", action="store_true",
                        help="predict even for a beam outside the range of a feature that did "
                             "not vary in training (a warning is printed); refused by default")


class PredictionError(RuntimeError):
    """The checkpoint gave an implausible prediction for a beam inside its training range."""


def load_surrogate(args, auto_truth: str | None = None):
    """The checkpoint asked for, checked against --joints and --truth (BadInput otherwise).
    ``auto_truth``: the truth `--truth auto` chose, used to look up the default checkpoint when
    neither --checkpoint nor --truth is given."""
    from .. import surrogate

    if args.checkpoint is not None:
        sur = surrogate.load_checkpoint(args.checkpoint)
    else:
        sur = surrogate.load_checkpoint(surrogate.default_checkpoint(
            args.joints, args.truth or auto_truth or "beam",
            getattr(args, "objective", None) or "eigenvalue"))
    if sur.joints != args.joints:
        raise BadInput(f"--joints {args.joints}: checkpoint {sur.name} was trained for "
                       f"{sur.joints} joints")
    if args.truth is not None and sur.truth != args.truth:
        raise BadInput(f"--truth {args.truth}: checkpoint {sur.name} was trained on the "
                       f"{sur.truth!r} truth")
    objective = getattr(args, "objective", None)
    if objective is not None and sur.objective != objective:
        raise BadInput(f"--objective {objective}: checkpoint {sur.name} was trained for the "
                       f"{sur.objective!r} objective (choices: {', '.join(OBJECTIVES)}; each "
                       "checkpoint serves the one it was trained for)")
    return sur


def checked_prediction(sur, beam, allow_extrapolation: bool = False):
    """The surrogate's prediction for one beam, or an error: BadInput (exit 2) for an
    extrapolation the checkpoint cannot make or an implausible prediction for a beam outside the
    training range, PredictionError (exit 1) for an implausible one inside it."""
    import warnings as _w

    from .. import surrogate

    with _w.catch_warnings():
        _w.simplefilter("ignore", surrogate.OutOfDistributionWarning)
        _w.simplefilter("ignore", surrogate.ImplausiblePredictionWarning)
        _w.simplefilter("ignore", surrogate.LowAccuracyWarning)    # said once, by predict_one
        pred = sur.predict(beam, frequencies=True, allow_extrapolation=allow_extrapolation)
    if pred.implausible[0]:
        problem = pred.problems[0].replace("implausible prediction: ", "")
        if pred.ood[0].any():
            raise BadInput(f"checkpoint {sur.name} gave an implausible prediction for this beam, "
                           f"which lies outside its training range: {problem}; "
                           f"{pred.warnings[0].replace('beam 0: ', '')}; use `prbdm fit`")
        raise PredictionError(f"checkpoint {sur.name} gave an implausible prediction for this "
                              f"beam, inside its training range: {problem}; the network is wrong "
                              "here (or the checkpoint is damaged): use `prbdm fit` for this beam")
    if allow_extrapolation and pred.ood[0].any():
        pred.warnings.append("--allow-extrapolation: the prediction extrapolates beyond the "
                             f"training range of checkpoint {sur.name}; check it with "
                             "`prbdm compare`")
    return pred


def predict_one(sur, beam, allow_extrapolation: bool = False) -> dict:
    """Everything the command prints, as a JSON-ready dict."""
    from .. import surrogate
    from ..fingerprint import beam_fingerprint
    from ..truth.choice import width_ratio

    pred = checked_prediction(sur, beam, allow_extrapolation)
    width = width_ratio(beam)
    batch = surrogate.BeamBatch.from_beams(beam)
    links = surrogate.link_table(batch, pred.gamma, pred.k)
    omega = pred.omega[0]
    omega_t = pred.omega_truth[0]
    from ..preflight import check_answer

    # every answer checks itself: the PRBDM against the truth the same network predicted
    check, off = check_answer(
        pred.omega[0], omega_t, sur.modes, pred.poses,
        truth_source="the truth the network predicted",
        remedy=self_check_remedy(sur))
    return {
        "beam": {"name": beam.name, "length": beam.length, "thickness": beam.thickness,
                 "mass": beam.mass, "stations": len(beam.x)},
        "joints": sur.joints, "modes": sur.modes, "truth": sur.truth, "law": pred.law,
        "checkpoint": sur.describe(),
        # the checkpoint's test on panels of this one's width, where it recorded the band
        "held_out_accuracy_at_this_width": sur.held_out_accuracy(width),
        "source": f"network {sur.name}",     # what `prbdm export --from` records as the source
        "gamma": pred.gamma[0].tolist(), "k": pred.k[0].tolist(),
        "poses": pred.poses.tolist(),
        "omega": omega.tolist(), "freq_hz": (omega / (2 * math.pi)).tolist(),
        "omega_truth_predicted": omega_t.tolist(),
        "freq_hz_truth_predicted": (omega_t / (2 * math.pi)).tolist(),
        "links": {key: v[0].tolist() for key, v in links.items()},
        "self_check": check,
        "warnings": [w.replace("beam 0: ", "") for w in pred.warnings] + off
        + [w for w in (sur.accuracy_warning(width),) if w],
        "beam_fingerprint": beam_fingerprint(beam),   # export/simulate --from check it
        "time_s": pred.time_s,
    }


def self_check_remedy(sur) -> str:
    """What to do about a network's answer that misses its own predicted truth."""
    fit = f"`prbdm fit BEAM --joints {sur.joints} --truth {sur.truth}`"
    if sur.objective == "eigenvalue":
        return ("the paper's eigenvalue loss lets the low modes drift at deflected poses: "
                "`--objective frequency` balances the modes (where such a network is shipped), "
                f"or fit this panel with {fit} (add `--poses linear` for small vibrations)")
    return f"fit this panel with {fit}"


def run(args) -> int:
    """The command, with every failure turned into one line: BadInput goes on to the CLI (exit
    2); anything else, even with --json, is one line here and exit 1, never a traceback."""
    try:
        return predict_command(args)
    except (BadInput, KeyboardInterrupt, BrokenPipeError):
        raise
    except Exception as exc:            # noqa: BLE001 - the command boundary
        text = " ".join(str(exc).split())[:500]
        kind = ("" if isinstance(exc, PredictionError)
                else f"internal error ({type(exc).__name__}): ")
        sys.stderr.write(f"prbdm predict: error: {kind}{text}\n")
        return 1


def auto_choice(args) -> tuple[str, str] | None:
    """(truth, reason) that `--truth auto` gives this panel (:func:`prbdm.truth.choice.choose_truth`:
    the plate for a panel wider than 0.05 L), or None when --truth is given or the beam file cannot
    be read (read_beam then reports it). Decided once per command from the panel's width."""
    if args.truth is not None:
        return None
    from ..truth.choice import choose_truth

    beam = peek_beam(args)
    return None if beam is None else choose_truth(beam, "auto")


def network_truth(args, choice) -> str | None:
    """The truth whose default network answers: the one `--truth auto` chose when such a network
    is found (and no --checkpoint is given), else None (the beam network answers, with a warning
    from :func:`truth_reason`)."""
    if args.checkpoint is not None or choice is None or choice[0] == "beam":
        return None
    for truth in network_truths(choice[0]):
        if has_network(args, truth):
            return truth
    return None                # no default network for that truth: the beam network, warned


def network_truths(model: str) -> tuple[str, ...]:
    """The networks that may answer a panel of truth ``model``, in order: a Mindlin panel a
    Mindlin network when one is found, else the Kirchhoff plate's, the nearest physics (the shear
    caveat says how near)."""
    return ("mindlin", "plate") if model == "mindlin" else (model,)


def answer_caveat(beam, network_truth: str, choice, asked) -> str | None:
    """The shear caveat of an answer that follows ``network_truth`` (the physics its network
    learned): that truth's own (:func:`prbdm.truth.choice.shear_caveat`), or, when `--truth auto`
    (``asked`` None) chose the Mindlin plate and the network has not learned it, the plate's (a
    narrow panel's beam network included, whose own caveat starts only at t/L ~ 0.02)."""
    from ..truth.choice import shear_caveat

    caveat = shear_caveat(beam, network_truth)
    if (caveat is None and network_truth != "mindlin" and asked is None and choice is not None
            and choice[0] == "mindlin"):
        caveat = shear_caveat(beam, "plate")
    return caveat


def truth_reason(beam, sur, asked, choice, declined=None,
                 given=False) -> tuple[str, str | None]:
    """Why the prediction follows its checkpoint's truth, and a warning when ``--truth auto``
    (the default; ``choice`` is its (truth, reason)) would take another for this panel: a beam
    network's answer for a panel wider than 0.05 L follows the beam's physics, which the
    plate's differs from (issue 16). ``declined``: why the network of the chosen truth did not
    answer (it was found but refused this panel); ``given``: the network was named by
    --checkpoint."""
    from ..truth.choice import width_ratio

    if asked is not None or choice is None:
        return f"--truth {asked} as asked (checkpoint {sur.name})", None
    model, why = choice
    if model == sur.truth:
        return f"{why}; checkpoint {sur.name}", None
    if model == "mindlin" and sur.truth == "plate":
        # the shear caveat of the network's physics goes with it (predict_command); a Mindlin
        # network that was found and declined is worth a warning of its own
        if declined:
            return (f"{why}; checkpoint {sur.name}, a Kirchhoff-plate network",
                    f"{declined}, so this answer follows the Kirchhoff plate, the nearer "
                    f"physics (the shear caveat says how near); for the shear-deformable plate "
                    f"use `prbdm fit BEAM --joints {sur.joints} --truth mindlin`")
        return (f"{why}; checkpoint {sur.name}, a Kirchhoff-plate network: no mindlin network "
                f"for {sur.joints} joints is shipped"), None
    if declined == NARROW_PLATE:
        return f"{why}; {narrow_plate_reason(sur)}", None
    net_model = network_truths(model)[-1]
    label = "shear-deformable (mindlin) plate" if model == "mindlin" else model
    missing = declined or (f"--checkpoint {sur.name} was given" if given
                           else f"no {net_model} network for {sur.joints} joints is shipped")
    return (f"checkpoint {sur.name} is a {sur.truth} network; {why}",
            f"this panel is {width_ratio(beam):.3g} L wide: its "
            f"faithful truth is the {label} (`--truth auto`), but {missing}, "
            f"so this answer follows the {sur.truth} physics (the beam is a median 1-5 % off "
            "the plate on modes 1-4 for panels 0.1-0.5 L wide and 13-50 % at 0.5-1 L, "
            "docs/truth.md); "
            f"for the {label} use `prbdm fit BEAM --joints {sur.joints} --truth {model}`")


#: ``declined`` when `--truth auto` gives a plate panel narrower than PLATE_NETWORK_MIN_WIDTH to
#: the beam network on purpose (measured closer to the plate there): a reason, not a warning
NARROW_PLATE = "narrow plate"


def narrow_plate_reason(sur) -> str:
    """Why the beam network ``sur`` answers a narrow plate panel (predict's ``truth_reason``,
    compare's ``truth.reason``)."""
    from ..constants import PLATE_NETWORK_MIN_WIDTH

    return (f"the beam network {sur.name} answers: on plate panels up to "
            f"{PLATE_NETWORK_MIN_WIDTH:g} L wide its PRBDM was measured closer to the plate than "
            "the plate network's (docs/surrogate.md)")


def answer_or_fall_back(args, sur, chosen, answer, beam):
    """(network, answer(network), declined): the answer of the network `--truth auto` chose
    (``chosen``, from :func:`network_truth`); when this panel lies outside that network's
    training range, or the network refuses it (BadInput: a feature it never saw vary, such as
    nu, or an implausible answer), the next network's answer instead (for a Mindlin network the
    Kirchhoff plate's, the nearer physics, then the beam's), with ``declined`` saying why: an
    extrapolating plate network was measured worse than the beam network (the earlier plate-n4,
    commit e6a900f, trained on 0.4-1 L wide panels only, on the 0.05-0.1 L panels of
    datasets/plate-n4-narrow-seed3: loss 5.9 % against beam-n4's 0.40 %).

    A Kirchhoff plate panel no wider than PLATE_NETWORK_MIN_WIDTH goes to the beam network on
    purpose (``declined`` = NARROW_PLATE): measured closer to the plate there than the plate
    network (docs/surrogate.md). A Mindlin panel that narrow goes to the Mindlin network,
    measured closer to its truth than both, and when that declines, to the beam network. A
    network that was asked for (``--truth``, ``--checkpoint``) or the beam network itself: its
    answer or refusal stands."""
    from ..constants import PLATE_NETWORK_MIN_WIDTH
    from ..geometry import check_beam
    from ..truth.choice import width_ratio

    narrow = width_ratio(beam) <= PLATE_NETWORK_MIN_WIDTH
    if chosen == "plate" and narrow:
        # the plate is this panel's truth, but the beam network was measured closer to it than
        # the Kirchhoff plate's network (a Mindlin network was measured closer than both)
        beam_net = load_surrogate(args, "beam")
        check_beam(beam, beam_net.truth)
        return beam_net, answer(beam_net), NARROW_PLATE
    if chosen is None:          # asked for (or the beam network): its answer or refusal stands
        return sur, answer(sur), None
    # the chosen network, then the nearer physics' (a Mindlin panel: the Kirchhoff plate's),
    # then the beam network, which answers or refuses as asked
    declined = []
    nearer = [t for t in network_truths(chosen)[1:]
              if has_network(args, t) and not (t == "plate" and narrow)]
    for fallback in (*nearer, "beam"):
        try:
            bad, texts = sur.check_range(sur.features([beam]))
            if bad.any():
                raise BadInput(texts[0].replace("beam 0: ", "").replace(
                    "the prediction is an extrapolation", "it would extrapolate"))
            return sur, answer(sur), "; ".join(declined) or None
        except (BadInput, PredictionError) as exc:
            declined.append(f"{sur.name} cannot answer this panel ({exc})")
        sur = load_surrogate(args, fallback)
        check_beam(beam, sur.truth)     # the beam was read (and warned about) once already
        if fallback == "beam":
            return sur, answer(sur), "; ".join(declined)
    raise AssertionError("unreachable: the beam network ends the chain")


def has_network(args, truth: str) -> bool:
    """Whether a default network of ``truth`` for these joints (and objective) is shipped."""
    from .. import surrogate

    try:
        surrogate.default_checkpoint(args.joints, truth,
                                     getattr(args, "objective", None) or "eigenvalue")
        return True
    except BadInput:
        return False


def predict_command(args) -> int:
    import time

    if args.truth == "auto":          # the default, spelled out
        args.truth = None
    choice = auto_choice(args)
    chosen = network_truth(args, choice)
    sur = load_surrogate(args, chosen)
    # refuses what `prbdm truth --model TRUTH` refuses, with the same message
    beam, info = read_beam(args, "predict", model=sur.truth)
    t0 = time.perf_counter()
    # `--truth auto` may have chosen a network that cannot answer this panel (a feature it never
    # saw vary, such as nu): the beam network answers then, and says which physics it follows
    sur, out, declined = answer_or_fall_back(
        args, sur, chosen, lambda s: predict_one(s, beam, args.allow_extrapolation), beam)
    out["time_s"] = time.perf_counter() - t0
    out["input"] = info
    out["truth_reason"], wrong_physics = truth_reason(beam, sur, args.truth, choice, declined,
                                                      args.checkpoint is not None)
    caveat = answer_caveat(beam, sur.truth, choice, args.truth)
    if caveat:
        out["warnings"].append(caveat)
    if wrong_physics:
        out["warnings"].append(wrong_physics)
    for w in out["warnings"]:
        sys.stderr.write(f"prbdm predict: warning: {w}\n")
    if args.json:
        print_json(out)
    else:
        print(render(out))
    return 0


def render(r: dict) -> str:
    b, L, c = r["beam"], r["links"], r["checkpoint"]
    n = r["joints"]
    lines = [f"beam: {b['name'] or '(unnamed)'}  L = {b['length']:.6g} m, "
             f"t = {b['thickness']:.6g} m, mass = {b['mass']:.6g} kg",
             f"{n}R-PRBDM predicted by checkpoint {c['name']} (truth {r['truth']}, law "
             f"{r['law']}, trained on {c['dataset_size']} beams); no FEM was run",
             f"gamma: {', '.join(f'{g:.4f}' for g in r['gamma'])}", "",
             "links (SI; centre of mass measured from the link's joint):"]
    rows = [["0", "-", f"{L['length'][0]:.5g}", "(clamped)", "", "", ""]]
    for j in range(n):
        rows.append([str(j + 1), f"{L['joint_x'][j]:.5g}", f"{L['length'][j + 1]:.5g}",
                     f"{L['mass'][j]:.5g}", f"{L['com'][j]:.5g}", f"{L['inertia'][j]:.5g}",
                     f"{L['base_stiffness'][j]:.5g}"])
    lines.append(table(rows, ["link", "joint x [m]", "length [m]", "mass [kg]", "com [m]",
                              "J [kg m^2]", "s [N m/rad]"]))
    lines += ["", "per pose: SCF k, joint stiffness k s_j [N m/rad], PRBDM frequencies [Hz]:"]
    rows = []
    for i, (pose, k, f, ks) in enumerate(zip(r["poses"], r["k"], r["freq_hz"],
                                             L["stiffness"])):
        rows.append([str(i), f"{pose[0]:.4g}", f"{k:.5g}", " ".join(f"{v:.4g}" for v in ks),
                     *(f"{v:.5g}" for v in f)])
    lines.append(table(rows, ["pose", "theta [rad]", "k", "stiffness [N m/rad]",
                              *(f"f{j + 1}" for j in range(n))]))
    ft = r["freq_hz_truth_predicted"]
    lines.append(f"\ntruth frequencies predicted by the network [Hz]: "
                 f"{', '.join(f'{v:.5g}' for v in ft)}")
    lines.append(f"({r['time_s'] * 1e3:.1f} ms)")
    return "\n".join(lines)
