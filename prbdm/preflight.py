"""Checks before a PRBDM is used in a simulator (``prbdm export``, ``prbdm simulate``).

A fit result (``prbdm fit --json``) or a prediction (``prbdm predict --json``) is only right for
the beam and the poses it was made for. Before it is written into a simulator's file or
integrated in time, three things are checked here (docs/howto/export-and-simulate.md, "Checks before use"):

1. **Its beam** (:func:`check_fingerprint`): the result's ``beam_fingerprint``
   (:mod:`prbdm.fingerprint`) must equal the beam's; otherwise :class:`~prbdm.errors.BadInput`
   (exit 2) naming both, unless the caller says to ignore it. A result without a fingerprint
   (made by an older prbdm, or by hand) gets a warning.
2. **Its pose** (:func:`prepare`): a simulator starts the chain at rest, straight, so the model
   that matters is the small-vibration one about theta = 0 (``pose="rest"``, the default). A
   result fitted for the paper's deflected poses has no theta = 0 pose, and its SCFs, fitted for
   deflected poses, give wrong small-vibration frequencies at rest (on a necked panel the first
   mode 11-25 % off: docs/howto/export-and-simulate.md). It is refitted at theta = 0 (gamma and one SCF, the
   linear pose set) against its own truth frequencies (``omega_truth``, or a prediction's
   ``omega_truth_predicted``): no FEM, about a second; the caller reports it under ``refit``.
3. **Its frequencies** (:func:`check_frequencies`): the small-vibration frequencies of the model
   about to be used (about its spring reference) are compared with the truth, mode by mode, over
   the modes the result maps; beyond a tolerance (default :data:`DEFAULT_TOLERANCE`) a warning
   names the mode, the error and the remedy.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from .constants import SELF_CHECK_IMPLAUSIBLE, SELF_CHECK_LOSS_PERCENT, SELF_CHECK_TOLERANCE
from .errors import BadInput
from .fingerprint import beam_fingerprint

__all__ = ["DEFAULT_TOLERANCE", "REMEDY", "Prepared", "prepare", "check_fingerprint",
           "check_frequencies", "check_answer", "fit_truth", "refit_at_rest", "where_of"]

#: relative frequency error beyond which a model about to be used gets a warning (5 %)
DEFAULT_TOLERANCE = SELF_CHECK_TOLERANCE
#: what to do about a model whose small-vibration frequencies are off
REMEDY = ("use a small-vibration fit: --pose rest (the default; it refits a paper-pose result at "
          "theta = 0), or 'prbdm fit --poses linear'; or fit with the frequency objective "
          "('prbdm fit --objective frequency')")
#: the keys a result may carry its truth frequencies under, in order of preference
TRUTH_KEYS = ("omega_truth", "omega_truth_predicted")
REST_NAMES = ("rest",)


@dataclass
class Prepared:
    """A result made ready for use: ``fit`` (the given one, or its refit at rest), ``pose`` (for
    :func:`prbdm.export.prbdm_from_fit`), ``truth`` (R,) [rad/s] and where it came from
    (``truth_source``), ``modes`` (how many modes the result maps: those checked), ``refit`` (None
    or what the refit did), ``fingerprint`` and ``warnings``."""

    fit: dict
    pose: object
    truth: np.ndarray
    truth_source: str
    modes: int
    refit: dict | None = None
    fingerprint: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)


def check_fingerprint(beam, fit: dict, *, ignore: bool = False, label: str = "--from"):
    """(info, warnings): ``info`` holds ``beam`` (this beam's fingerprint), ``result`` (the
    result's, or None), ``match`` (True, False, or None when the result has none) and
    ``ignored``. A mismatch raises BadInput naming both fingerprints unless ``ignore``."""
    ours = beam_fingerprint(beam)
    theirs = fit.get("beam_fingerprint")
    info = {"beam": ours, "result": theirs, "match": None, "ignored": bool(ignore)}
    if theirs is None:
        return info, [f"{label}: the result carries no beam_fingerprint (made by an older prbdm "
                      "or by hand): it cannot be confirmed that it was made for this beam"]
    if not isinstance(theirs, str):
        raise BadInput(f"{label}: beam_fingerprint must be a string of hex digits, got "
                       f"{theirs!r}")
    info["match"] = theirs == ours
    if info["match"]:
        return info, []
    if not ignore:
        raise BadInput(f"{label}: the result was made for a different beam (its beam_fingerprint "
                       f"{theirs}, this beam's {ours}); refit this beam, or pass "
                       "--ignore-fingerprint to apply it anyway")
    return info, [f"{label}: the result was made for a different beam (beam_fingerprint {theirs}, "
                  f"this beam's {ours}); applied anyway (--ignore-fingerprint), checked against "
                  "this beam's own truth"]


def fit_truth(beam, fit: dict, *, own: bool = True, modes: int = 1):
    """(omega [rad/s], source): the result's own truth frequencies (``omega_truth``, or a
    prediction's ``omega_truth_predicted``) when ``own`` and present; otherwise this beam's
    Euler-Bernoulli truth, computed here (``modes`` modes)."""
    if own:
        for key in TRUTH_KEYS:
            if key in fit:
                try:
                    omega = np.asarray(fit[key], dtype=float)
                except (TypeError, ValueError):
                    raise BadInput(f"fit: {key} must be a list of numbers") from None
                if omega.ndim != 1 or omega.size == 0 or not np.all(np.isfinite(omega)) \
                        or np.any(omega <= 0) or np.any(np.diff(omega) < 0):
                    raise BadInput(f"fit: {key} must be a list of ascending frequencies > 0 "
                                   "[rad/s]")
                return omega, key
    from .truth import bending_frequencies

    return np.asarray(bending_frequencies(beam, model="beam", modes=modes).omega, float), \
        "beam (Euler-Bernoulli FEM, computed here)"


def mapped_modes(fit: dict, n: int, available: int) -> int:
    """How many modes the result maps (its ``modes``, at most n, default n), capped by the
    truth frequencies available."""
    r = fit.get("modes", n)
    if isinstance(r, bool) or not isinstance(r, (int, np.integer)) or r < 1:
        r = n
    return int(min(r, n, available))


def refit_at_rest(beam, fit: dict, truth: np.ndarray, truth_source: str, modes: int):
    """(new fit, refit info): gamma and the SCF of the single pose theta = 0, fitted against
    ``truth`` with the result's law and objective (``prbdm fit --poses linear``, no FEM)."""
    import torch

    from .export import check_fit
    from .fit import fit_prbdm
    from .model import BeamTensors, links_from_gamma

    gamma, _, law, poses = check_fit(fit)
    n = gamma.size - 1
    objective = fit.get("objective", "eigenvalue")
    if objective not in ("eigenvalue", "frequency"):
        objective = "eigenvalue"
    seed = fit.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        seed = 0
    t0 = time.perf_counter()
    # one small batched problem: one thread is fastest (docs/conventions.md §6, "Threads"); restored after
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        res = fit_prbdm(beam, truth, joints=n, modes=modes, law=law, poses="linear",
                        seed=int(seed), objective=objective)
    finally:
        torch.set_num_threads(threads)
    bt = BeamTensors.from_beams(beam)
    with torch.no_grad():
        links = links_from_gamma(bt, torch.as_tensor(res.gamma)).physical(bt)
    new = res.to_dict()
    new["links"] = {key: v.tolist() for key, v in links.items()}
    new["beam_fingerprint"] = beam_fingerprint(beam)
    if "source" in fit:
        new["source"] = f"{fit['source']}, refitted at theta = 0"
    info = {"reason": f"the result was fitted for {poses.shape[0]} pose(s), none at theta = 0 "
                      f"(largest first angle {float(np.abs(poses[:, 0]).max()):.4g} rad); its "
                      "SCFs do not describe small vibrations about the straight beam, so gamma "
                      "and k were refitted at theta = 0 against its truth frequencies (no FEM)",
            "truth": truth_source, "modes": int(modes), "law": law, "objective": objective,
            "poses_given": poses.tolist(), "gamma_given": gamma.tolist(),
            "gamma": res.gamma.tolist(), "k": res.k.tolist(),
            "loss_percent": float(res.loss_percent),
            "max_freq_error": float(res.freq_error.max()), "starts": int(res.n_starts),
            "time_s": time.perf_counter() - t0}
    return new, info


def prepare(beam, fit: dict, pose="rest", *, ignore_fingerprint: bool = False,
            label: str = "--from", check_beam: bool = True) -> Prepared:
    """Make ``fit`` ready for use at ``pose``: the fingerprint check (``check_beam``; off for a
    fit run here on this beam), its truth, and with ``pose="rest"`` the theta = 0 pose, refitted
    when the result has none. Other poses (an index, ``'linear'``) are passed on unchanged."""
    from .export import check_fit, check_fit_links
    from .springs import pose_target_of

    if not isinstance(fit, dict):
        raise BadInput("fit: must be a dict with keys gamma, k, law, poses")
    warnings = []
    if check_beam:
        fp, w = check_fingerprint(beam, fit, ignore=ignore_fingerprint, label=label)
        warnings += w
    else:
        fp = {"beam": beam_fingerprint(beam), "result": beam_fingerprint(beam), "match": True,
              "ignored": False}
    if fp["match"] is False:
        # applied to another beam on purpose: its link table is that beam's, not this one's
        fit = {key: v for key, v in fit.items() if key != "links"}
    gamma, _, _, poses = check_fit(fit)
    check_fit_links(beam, fit)        # before any refit, which replaces the links
    n = gamma.size - 1
    # a result made for another beam carries that beam's truth: check against this one's
    truth, source = fit_truth(beam, fit, own=fp["match"] is not False, modes=n)
    r = mapped_modes(fit, n, truth.size)
    refit = None
    if isinstance(pose, str) and pose.strip() in REST_NAMES:
        rest = np.flatnonzero(np.all(poses == 0.0, axis=1))
        if rest.size:
            pose = int(rest[0])
        elif pose_target_of(fit) == "shape":
            # fitted at rest, its one stiffness held at the poses: the theta = 0 model is the
            # result itself (gamma and that SCF), no refit
            k = np.atleast_1d(np.asarray(fit["k"], float))
            fit = {**{key: v for key, v in fit.items()
                      if key not in ("omega", "freq_hz", "freq_error", "links")},
                   "poses": [[0.0] * n], "k": [float(k[0])]}
            pose = 0
        else:
            fit, refit = refit_at_rest(beam, fit, truth, source, r)
            pose = 0
    return Prepared(fit=fit, pose=pose, truth=truth, truth_source=source, modes=r, refit=refit,
                    fingerprint=fp, warnings=warnings)


def check_frequencies(omega_model, truth, modes: int, *, tolerance: float = DEFAULT_TOLERANCE,
                      truth_source: str = "omega_truth", where: str = "at rest"):
    """(check, warnings): the model's small-vibration frequencies ``omega_model`` [rad/s]
    against ``truth`` over the first ``modes`` modes. ``check`` (JSON-ready) holds per mode the
    model's and the truth's frequency [Hz] and the relative error, the worst, the tolerance and
    ``ok``; one warning per mode beyond the tolerance, naming it, its error and the remedy."""
    if isinstance(tolerance, bool) or not isinstance(tolerance, (int, float)) \
            or not math.isfinite(tolerance) or tolerance <= 0:
        raise BadInput(f"--tolerance: must be a relative frequency error > 0, got {tolerance!r}")
    om = np.asarray(omega_model, float)
    tr = np.asarray(truth, float)
    r = int(min(modes, om.size, tr.size))
    err = om[:r] / tr[:r] - 1.0
    bad = np.flatnonzero(np.abs(err) > tolerance)
    check = {"where": where, "truth": truth_source, "modes": r, "tolerance": float(tolerance),
             "freq_hz_model": (om[:r] / (2 * math.pi)).tolist(),
             "freq_hz_truth": (tr[:r] / (2 * math.pi)).tolist(),
             "error": err.tolist(), "max_error": float(np.abs(err).max()),
             "worst_mode": int(np.argmax(np.abs(err))) + 1, "ok": bool(bad.size == 0)}
    warnings = [f"mode {j + 1}: the model's small-vibration frequency {om[j] / (2 * math.pi):.5g}"
                f" Hz {where} is {100 * abs(err[j]):.3g} % {'above' if err[j] > 0 else 'below'}"
                f" the truth's {tr[j] / (2 * math.pi):.5g} Hz (tolerance {100 * tolerance:g} %); "
                + REMEDY for j in bad]
    return check, warnings


def where_of(desc: dict) -> str:
    """Where the small vibrations of a description (:func:`prbdm.export.prbdm_from_fit`) are
    taken, in words for the check's warnings."""
    p = desc["pose"]
    if p["springref"] == "zero" or not any(p["theta"]):
        springs = "" if not any(p["theta"]) else f", springs of pose {p['index']}"
        return f"at rest (theta = 0{springs})"
    return f"about pose {p['index']} (theta_1 = {p['theta'][0]:.4g} rad)"


def check_answer(omega, truth, modes: int, poses, *, truth_source: str, remedy: str,
                 objective: str = "frequency", tolerance: float = SELF_CHECK_TOLERANCE,
                 loss_tolerance: float = SELF_CHECK_LOSS_PERCENT,
                 implausible: float = SELF_CHECK_IMPLAUSIBLE):
    """Every answer checks itself: (check, warnings) for a PRBDM's frequencies ``omega`` (m, n)
    [rad/s], one row per pose of ``poses`` (m, n) [rad], against the truth it was made for
    (``truth`` (R,) [rad/s], or (m, R): one per pose, named by ``truth_source``) over the first
    ``modes`` modes, by the measure of the ``objective`` it was made with.

    ``check`` (JSON-ready): per mode the worst relative error over the poses and the pose where it
    is, the worst mode, the paper's loss [%] over the poses, the measure and its tolerance, ``ok``
    and ``implausible`` (some mode further off than ``implausible``: not a model of this panel).
    Warnings name the mode, its error, the pose and ``remedy``: for the ``frequency`` objective
    one per mode beyond ``tolerance``; for the ``eigenvalue`` objective (which lets the low modes
    drift by design) one when its loss exceeds ``loss_tolerance`` [%]; for either, one per mode
    beyond ``implausible``."""
    om = np.atleast_2d(np.asarray(omega, float))
    tr = np.atleast_2d(np.asarray(truth, float))                # (1 or m, R)
    r = int(min(modes, om.shape[-1], tr.shape[-1]))
    err = om[:, :r] / tr[:, :r] - 1.0                           # (m, r)
    err = np.where(np.isfinite(err), err, np.inf)
    at = np.argmax(np.abs(err), axis=0)                        # worst pose per mode
    worst = err[at, np.arange(r)]
    lam, lam_t = om[:, :r] ** 2, tr[:, :r] ** 2
    loss = float(100 * np.mean(np.linalg.norm(lam - lam_t, axis=-1)
                               / np.linalg.norm(lam_t, axis=-1)))
    loss = loss if np.isfinite(loss) else math.inf
    poses = np.atleast_2d(np.asarray(poses, float))
    by_loss = objective == "eigenvalue"
    ok = loss <= loss_tolerance if by_loss else bool(np.all(np.abs(worst) <= tolerance))
    check = {"truth": truth_source, "modes": r, "objective": objective,
             "measure": "loss_percent" if by_loss else "error",
             "tolerance": float(loss_tolerance if by_loss else tolerance),
             "error": [float(v) for v in worst], "pose": [int(i) for i in at],
             "max_error": float(np.abs(worst).max()),
             "worst_mode": int(np.argmax(np.abs(worst))) + 1, "loss_percent": loss,
             "ok": bool(ok), "implausible": bool(np.any(~(np.abs(worst) <= implausible)))}

    def words(j):
        e, i = worst[j], int(at[j])
        where = ("" if om.shape[0] == 1 and not np.any(poses[i])
                 else f" at pose {i} (theta_1 = {poses[i][0]:.3g} rad)")
        size = f"{100 * abs(e):.3g} % {'above' if e > 0 else 'below'}" if np.isfinite(e) \
            else "not a finite multiple of"
        return f"mode {j + 1}: the PRBDM's frequency{where} is {size} {truth_source}"

    warnings = []
    far = np.flatnonzero(~(np.abs(worst) <= implausible))
    if by_loss and not ok:
        j = check["worst_mode"] - 1
        warnings.append(f"the PRBDM's loss against {truth_source} is {loss:.3g} % (tolerance "
                        f"{loss_tolerance:g} % for the eigenvalue objective); worst: "
                        f"{words(j)}; {remedy}")
    elif not by_loss:
        warnings += [f"{words(j)} (tolerance {100 * tolerance:g} %); {remedy}"
                     for j in np.flatnonzero(~(np.abs(worst) <= tolerance)) if j not in far]
    warnings += [f"{words(j)}: beyond {100 * implausible:g} % it is not a model of this panel; "
                 f"{remedy}" for j in far]
    return check, warnings
