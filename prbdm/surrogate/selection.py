"""Which shipped network answers a panel: one home for the policy of ``--truth auto`` that
``prbdm predict``, ``compare`` and ``export`` follow (the commands parse and print; this decides).

:func:`plan` takes a beam (read, not yet checked against a truth's limits) and a
:class:`Request` (joints, truth or auto, checkpoint, objective, allow_extrapolation) and picks
the first network: for ``--truth auto`` the truth the panel needs
(:func:`prbdm.truth.choice.choose_truth`) and, where that truth's network is shipped
(:func:`network_truths`: a Mindlin panel a Mindlin network, else the Kirchhoff plate's; a
Kirchhoff plate panel the Kirchhoff plate's, else the Mindlin plate's), that network; the beam
network otherwise. The caller checks the beam against the limits of the truth
it answers for (:attr:`Plan.model`) and then :func:`answer` asks the network, falls back to the
next one where the chosen network cannot answer this panel (outside its training range, a
feature it never saw vary, an implausible answer): Mindlin -> Kirchhoff plate -> beam and
Kirchhoff plate -> Mindlin -> beam, a plate
panel no wider than PLATE_NETWORK_MIN_WIDTH going to the beam network on purpose
(:data:`NARROW_PLATE`); and says why (``reason``) and what the answer leaves out (``warnings``:
the shear caveat of the network's physics, the wrong-physics warning of a network other than the
panel's truth).

:func:`network_answer` is one network's checked answer for one beam, as ``prbdm predict``
prints it (:func:`checked_prediction` turns an implausible prediction into an error).

Importing this module imports NumPy only (the truth's width rule is imported when used), so
``prbdm predict`` stays lean.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from ..constants import OBJECTIVES
from ..errors import BadInput

#: the truths a shipped network may have learned
TRUTHS = ("beam", "plate", "mindlin")
#: ``declined`` when `--truth auto` gives a plate panel narrower than PLATE_NETWORK_MIN_WIDTH to
#: the beam network on purpose (measured closer to the plate there): a reason, not a warning
NARROW_PLATE = "narrow plate"


class PredictionError(RuntimeError):
    """The checkpoint gave an implausible prediction for a beam inside its training range."""


@dataclass(frozen=True)
class Request:
    """What was asked: ``joints``; ``truth`` (None: auto); ``checkpoint`` (a path, or None for
    the shipped one); ``objective`` (None: the checkpoint's, 'eigenvalue' to pick the default);
    ``allow_extrapolation``."""

    joints: int
    truth: str | None = None
    checkpoint: str | None = None
    objective: str | None = None
    allow_extrapolation: bool = False

    @classmethod
    def from_args(cls, args) -> "Request":
        """From a command's parsed arguments (``--truth auto`` is None)."""
        truth = getattr(args, "truth", None)
        return cls(joints=args.joints, truth=None if truth == "auto" else truth,
                   checkpoint=getattr(args, "checkpoint", None),
                   objective=getattr(args, "objective", None),
                   allow_extrapolation=bool(getattr(args, "allow_extrapolation", False)))


@dataclass
class Plan:
    """The first network for a panel: ``choice`` ((truth, reason) of `--truth auto`, None when
    a truth was given), ``chosen`` (the truth whose network `auto` picked; None: the network
    asked for, or the beam's), ``surrogate`` (that network, loaded)."""

    request: Request
    choice: tuple | None
    chosen: str | None
    surrogate: object

    @property
    def model(self) -> str:
        """The truth the answer is measured against (``prbdm compare``): `auto`'s choice, or
        the checkpoint's truth when a truth or checkpoint was given."""
        if self.choice is not None and self.request.checkpoint is None:
            return self.choice[0]
        return self.surrogate.truth


@dataclass
class Selection:
    """What :func:`answer` gives: the network that answered (``surrogate``), its ``answer``,
    why another declined (``declined``; :data:`NARROW_PLATE` for a narrow plate panel given to
    the beam network on purpose), why this network answers (``reason``) and the warnings about
    the physics it follows (``warnings``: its shear caveat, then the wrong-physics warning)."""

    surrogate: object
    answer: object
    declined: str | None
    reason: str
    warnings: list = field(default_factory=list)


# ---------------------------------------------------------------------------- the networks
def load_surrogate(request: Request, auto_truth: str | None = None):
    """The checkpoint asked for, checked against the request's joints, truth and objective
    (BadInput otherwise). ``auto_truth``: the truth `--truth auto` chose, used to look up the
    default checkpoint when neither a checkpoint nor a truth is given."""
    from .checkpoint import default_checkpoint
    from .prediction import load_checkpoint

    if request.checkpoint is not None:
        sur = load_checkpoint(request.checkpoint)
    else:
        sur = load_checkpoint(default_checkpoint(
            request.joints, request.truth or auto_truth or "beam",
            request.objective or "eigenvalue"))
    if sur.joints != request.joints:
        raise BadInput(f"--joints {request.joints}: checkpoint {sur.name} was trained for "
                       f"{sur.joints} joints")
    if request.truth is not None and sur.truth != request.truth:
        raise BadInput(f"--truth {request.truth}: checkpoint {sur.name} was trained on the "
                       f"{sur.truth!r} truth")
    # a network trained at rest (the shape pose target) serves either objective: at rest both
    # have one optimum, every mapped mode exact for n <= 4 (n + 1 parameters; for n = 5 they
    # weigh the fifth mode differently); such networks are trained on the frequency objective,
    # which keeps every mode of their approximate answer close, and answer either request
    if request.objective is not None and sur.objective != request.objective \
            and sur.pose_target != "shape":
        raise BadInput(f"--objective {request.objective}: checkpoint {sur.name} was trained for "
                       f"the {sur.objective!r} objective (choices: {', '.join(OBJECTIVES)}; each "
                       "checkpoint serves the one it was trained for)")
    return sur


def has_network(request: Request, truth: str) -> bool:
    """Whether a default network of ``truth`` for these joints (and objective) is shipped."""
    from .checkpoint import default_checkpoint

    try:
        default_checkpoint(request.joints, truth, request.objective or "eigenvalue")
        return True
    except BadInput:
        return False


def auto_choice(beam, request: Request) -> tuple[str, str] | None:
    """(truth, reason) that `--truth auto` gives this panel (:func:`prbdm.truth.choice.
    choose_truth`: the plate for a panel wider than 0.05 L), or None when a truth is given or
    there is no beam (an unreadable file: reading it reports that). Decided once per command
    from the panel's width."""
    if request.truth is not None or beam is None:
        return None
    from ..truth.choice import choose_truth

    return choose_truth(beam, "auto")


def network_truths(model: str) -> tuple[str, ...]:
    """The networks that may answer a panel of truth ``model``, in order: a Mindlin panel a
    Mindlin network when one is found, else the Kirchhoff plate's, the nearest physics (the shear
    caveat says how near); a Kirchhoff plate panel the Kirchhoff plate's, else the Mindlin
    plate's, the same physics in its thin limit (its networks learned t/L down to 0.002 and
    Poisson's ratios 0.2-0.45, where the Kirchhoff networks know 0.28 alone)."""
    return {"mindlin": ("mindlin", "plate"), "plate": ("plate", "mindlin")}.get(model, (model,))


def network_truth(request: Request, choice) -> str | None:
    """The truth whose default network answers: the one `--truth auto` chose when such a network
    is found (and no checkpoint is given), else None (the beam network answers, with a warning
    from :func:`truth_reason`)."""
    if request.checkpoint is not None or choice is None or choice[0] == "beam":
        return None
    for truth in network_truths(choice[0]):
        if has_network(request, truth):
            return truth
    return None                # no default network for that truth: the beam network, warned


def plan(beam, request: Request) -> Plan:
    """The first network for ``beam`` (read; its truth's limits are checked by the caller
    against :attr:`Plan.model` or the network's truth): `--truth auto`'s choice from the panel's
    width, the network of that truth when one is shipped, loaded and checked against the
    request."""
    choice = auto_choice(beam, request)
    chosen = network_truth(request, choice)
    return Plan(request, choice, chosen, load_surrogate(request, chosen))


# ------------------------------------------------------------------------------- answering
def answer_or_fall_back(plan: Plan, answer, beam, check_beam=None):
    """(network, answer(network), declined): the answer of the network `--truth auto` chose
    (``plan.chosen``); when this panel lies outside that network's training range, or the
    network refuses it (BadInput: a feature it never saw vary, such as nu, or an implausible
    answer), the next network's answer instead (for a Mindlin network the Kirchhoff plate's,
    the nearer physics, for a Kirchhoff plate network the Mindlin plate's, then the beam's),
    with ``declined`` saying why: an extrapolating plate
    network was measured worse than the beam network (the earlier plate-n4, commit e6a900f,
    trained on 0.4-1 L wide panels only, on the 0.05-0.1 L panels of
    datasets/plate-n4-narrow-seed3: loss 5.9 % against beam-n4's 0.40 %).

    A Kirchhoff plate panel no wider than PLATE_NETWORK_MIN_WIDTH goes to the beam network on
    purpose (``declined`` = NARROW_PLATE): measured closer to the plate there than the plate
    network (docs/surrogate.md). A Mindlin panel that narrow goes to the Mindlin network,
    measured closer to its truth than both, and when that declines, to the beam network. A
    network that was asked for (a truth, a checkpoint) or the beam network itself: its answer or
    refusal stands. Each network that takes over checks the beam against its truth's limits
    (``check_beam``, default :func:`prbdm.geometry.check_beam`) before it answers."""
    from ..constants import PLATE_NETWORK_MIN_WIDTH
    from ..truth.choice import width_ratio

    if check_beam is None:
        from ..geometry import check_beam
    request, chosen, sur = plan.request, plan.chosen, plan.surrogate
    narrow = width_ratio(beam) <= PLATE_NETWORK_MIN_WIDTH
    if chosen == "plate" and narrow:
        # the plate is this panel's truth, but the beam network was measured closer to it than
        # the Kirchhoff plate's network (a Mindlin network was measured closer than both)
        beam_net = load_surrogate(request, "beam")
        check_beam(beam, beam_net.truth)
        return beam_net, answer(beam_net), NARROW_PLATE
    if chosen is None:          # asked for (or the beam network): its answer or refusal stands
        return sur, answer(sur), None
    # the chosen network, then the nearer physics' (a Mindlin panel: the Kirchhoff plate's),
    # then the beam network, which answers or refuses as asked
    declined = []
    nearer = [t for t in network_truths(chosen)[1:]
              if has_network(request, t) and not (t == "plate" and narrow)]
    for fallback in (*nearer, "beam"):
        try:
            bad, texts = sur.check_range(sur.features([beam]))
            if bad.any():
                raise BadInput(texts[0].replace("beam 0: ", "").replace(
                    "the prediction is an extrapolation", "it would extrapolate"))
            return sur, answer(sur), "; ".join(declined) or None
        except (BadInput, PredictionError) as exc:
            declined.append(f"{sur.name} cannot answer this panel ({exc})")
        sur = load_surrogate(request, fallback)
        check_beam(beam, sur.truth)     # the beam was read (and warned about) once already
        if fallback == "beam":
            return sur, answer(sur), "; ".join(declined)
    raise AssertionError("unreachable: the beam network ends the chain")


def answer(plan: Plan, beam, answer_fn, check_beam=None) -> Selection:
    """The answer for ``beam`` (checked against the first network's truth by the caller):
    ``answer_fn(network)`` of the network :func:`answer_or_fall_back` settles on, with its
    reason and the warnings about the physics it follows (:func:`truth_reason`,
    :func:`answer_caveat`)."""
    request = plan.request
    sur, result, declined = answer_or_fall_back(plan, answer_fn, beam, check_beam)
    reason, wrong_physics = truth_reason(beam, sur, request.truth, plan.choice, declined,
                                         request.checkpoint is not None)
    warnings = [w for w in (answer_caveat(beam, sur.truth, plan.choice, request.truth),
                            wrong_physics) if w]
    return Selection(sur, result, declined, reason, warnings)


def measured_against(plan: Plan, selection: Selection) -> tuple[str, str, list[str]]:
    """(truth model, reason, notes) of ``prbdm compare``, which measures the network that
    answered against the truth the panel needs (:attr:`Plan.model`): why that truth, and
    warnings where the network is not that truth's own."""
    request, sur, declined = plan.request, selection.surrogate, selection.declined
    model = plan.model
    if plan.choice is not None and request.checkpoint is None:
        reason = plan.choice[1]
    else:
        reason = f"--truth {request.truth} as asked" if request.truth else "the checkpoint's truth"
    notes = []
    if declined and declined != NARROW_PLATE:
        notes.append(f"{declined}; {sur.name} is measured instead")
    if declined == NARROW_PLATE:          # the reason, as predict's truth_reason (no warning)
        reason += f"; {narrow_plate_reason(sur)}"
    return model, reason, notes


def wrong_truth_note(plan: Plan, selection: Selection, reason: str) -> str | None:
    """``prbdm compare``'s warning when the network that answered learned another truth than
    the one it is measured against (a narrow plate panel's beam network excepted: chosen)."""
    sur = selection.surrogate
    if sur.truth != plan.model and selection.declined != NARROW_PLATE:
        return (f"the {sur.truth} network {sur.name} is measured against the {plan.model} "
                f"truth this panel needs (`--truth auto`: {reason})")
    return None


# --------------------------------------------------------------------------- the wording
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
    from ..truth.choice import band_gap_words, width_ratio

    if asked is not None or choice is None:
        return f"--truth {asked} as asked (checkpoint {sur.name})", None
    model, why = choice
    if model == sur.truth:
        return f"{why}; checkpoint {sur.name}", None
    if model == "mindlin" and sur.truth == "plate":
        # the shear caveat of the network's physics goes with it (answer); a Mindlin network
        # that was found and declined is worth a warning of its own
        if declined:
            return (f"{why}; checkpoint {sur.name}, a Kirchhoff-plate network",
                    f"{declined}, so this answer follows the Kirchhoff plate, the nearer "
                    f"physics (the shear caveat says how near); for the shear-deformable plate "
                    f"use `prbdm fit BEAM --joints {sur.joints} --truth mindlin`")
        return (f"{why}; checkpoint {sur.name}, a Kirchhoff-plate network: no mindlin network "
                f"for {sur.joints} joints is shipped"), None
    if model == "plate" and sur.truth == "mindlin":
        # the Mindlin plate holds the Kirchhoff plate as its thin limit: no physics is lost
        return (f"{why}; " + (f"{declined}, so" if declined else
                              f"no plate network for {sur.joints} joints is shipped, so")
                + f" the Mindlin plate's network {sur.name} answers (the Kirchhoff plate is its "
                  "thin limit)"), None
    if declined == NARROW_PLATE:
        return f"{why}; {narrow_plate_reason(sur)}", None
    net_model = " or ".join(network_truths(model))
    label = "shear-deformable (mindlin) plate" if model == "mindlin" else model
    missing = declined or (f"--checkpoint {sur.name} was given" if given
                           else f"no {net_model} network for {sur.joints} joints is shipped")
    return (f"checkpoint {sur.name} is a {sur.truth} network; {why}",
            f"this panel is {width_ratio(beam):.3g} L wide: its "
            f"faithful truth is the {label} (`--truth auto`), but {missing}, "
            f"so this answer follows the {sur.truth} physics ({band_gap_words(beam)}); "
            f"for the {label} use `prbdm fit BEAM --joints {sur.joints} --truth {model}`")


def narrow_plate_reason(sur) -> str:
    """Why the beam network ``sur`` answers a narrow plate panel (predict's ``truth_reason``,
    compare's ``truth.reason``)."""
    from ..constants import PLATE_NETWORK_MIN_WIDTH

    return (f"the beam network {sur.name} answers: on plate panels up to "
            f"{PLATE_NETWORK_MIN_WIDTH:g} L wide its PRBDM was measured closer to the plate than "
            "the plate network's (docs/surrogate.md)")


def self_check_remedy(sur) -> str:
    """What to do about a network's answer that misses its own predicted truth."""
    fit = f"`prbdm fit BEAM --joints {sur.joints} --truth {sur.truth}`"
    return f"for a faithful model fit this panel with {fit}"


# ------------------------------------------------------------------- one network's answer
def checked_prediction(sur, beam, allow_extrapolation: bool = False):
    """The surrogate's prediction for one beam, or an error: BadInput (exit 2) for an
    extrapolation the checkpoint cannot make or an implausible prediction for a beam outside the
    training range (a feature out of its range, or unlike every training panel the checkpoint
    keeps), PredictionError (exit 1) for an implausible one inside it."""
    import warnings as _w

    from .prediction import (
        ImplausiblePredictionWarning,
        LowAccuracyWarning,
        OutOfDistributionWarning,
    )

    with _w.catch_warnings():
        _w.simplefilter("ignore", OutOfDistributionWarning)
        _w.simplefilter("ignore", ImplausiblePredictionWarning)
        _w.simplefilter("ignore", LowAccuracyWarning)    # said once, by network_answer
        pred = sur.predict(beam, frequencies=True, allow_extrapolation=allow_extrapolation)
    outside = bool(pred.ood[0].any()) or bool(pred.unlike is not None and pred.unlike[0])
    if pred.implausible[0]:
        problem = pred.problems[0].replace("implausible prediction: ", "")
        if outside:
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


def network_answer(sur, beam, allow_extrapolation: bool = False) -> dict:
    """One network's checked answer for one beam, JSON-ready (what ``prbdm predict`` prints,
    less ``input`` and ``truth_reason``)."""
    from ..chain import BeamBatch, link_table
    from ..fingerprint import beam_fingerprint
    from ..pose_target import hold_prediction
    from ..poses import pose_set
    from ..preflight import check_answer
    from ..truth.choice import width_ratio

    pred = checked_prediction(sur, beam, allow_extrapolation)
    width = width_ratio(beam)
    batch = BeamBatch.from_beams(beam)
    omega_t = pred.omega_truth[0]
    # every answer checks itself: the PRBDM against the truth the same network predicted, at
    # the poses it was trained on
    check, off = check_answer(
        pred.omega[0], omega_t, sur.modes, pred.poses,
        truth_source="the truth the network predicted",
        remedy=self_check_remedy(sur), objective=sur.objective)
    k, poses, omega, rest = pred.k, pred.poses, pred.omega[0], None
    if sur.pose_target == "shape":
        # its answer at rest, where it was trained and where the self-check measured it
        rest = {"k": float(pred.k[0, 0]), "omega": pred.omega[0][0].tolist(),
                "freq_hz": (pred.omega[0][0] / (2 * math.pi)).tolist()}
        check["at"] = "rest"
        # trained at rest: the stiffness is held at the paper's poses, where the chain follows
        # the panel bent into each pose's shape (prbdm.pose_target); predict runs no solver, so
        # those poses are not checked here
        poses = pose_set("paper", sur.joints)
        k, omega = hold_prediction(batch, pred.gamma, pred.k[:, 0], poses)
        omega = omega[0]
        check["poses"] = {"checked": False, "why": "predict runs no solver; `prbdm fit "
                          "--pose-target shape` checks every pose against the geometrically "
                          "exact rod bent into its shape"}
    links = link_table(batch, pred.gamma, k)
    return {
        "beam": {"name": beam.name, "length": beam.length, "thickness": beam.thickness,
                 "mass": beam.mass, "stations": len(beam.x)},
        "joints": sur.joints, "modes": sur.modes, "truth": sur.truth, "law": pred.law,
        "checkpoint": sur.describe(),
        # the checkpoint's test on panels of this one's width, where it recorded the band
        "held_out_accuracy_at_this_width": sur.held_out_accuracy(width),
        "source": f"network {sur.name}",     # what `prbdm export --from` records as the source
        "gamma": pred.gamma[0].tolist(), "k": k[0].tolist(),
        "poses": poses.tolist(), "pose_target": sur.pose_target,
        **({"rest": rest} if rest else {}),
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
