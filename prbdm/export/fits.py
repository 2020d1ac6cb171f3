"""Where an exported PRBDM comes from: a fit run here (:func:`run_fit`) or a fit file read
(:func:`load_fit`, what ``prbdm fit --json`` or ``prbdm predict --json`` print), checked
(:func:`check_fit`) and matched against the beam it is applied to (:func:`check_fit_links`)."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ..errors import BadInput

GAMMA_SUM_TOL = 1e-6
#: relative tolerance on a FIT.json's link positions against the beam they are applied to
LINK_MATCH_RTOL = 1e-6


def run_fit(beam, joints: int, *, modes: int | None = None, law: str = "beam", poses="paper",
            starts: int | None = None, seed: int = 0, truth: str = "auto") -> dict:
    """Fit a PRBDM to ``beam`` (truth + multistart fit) and return what ``prbdm fit --json``
    prints: :meth:`prbdm.fit.FitResult.to_dict` plus ``truth`` and ``links``. ``truth``: a truth
    model, or ``auto`` (:func:`prbdm.truth.choice.choose_truth`: the plate for a wide panel)."""
    import torch

    from ..fingerprint import beam_fingerprint
    from ..fit import fit_prbdm
    from ..model import BeamTensors, links_from_gamma
    from ..truth import bending_frequencies, modes_for_fit
    from ..truth.choice import choose_truth

    r = modes or joints
    model, reason = choose_truth(beam, truth)
    tr = bending_frequencies(beam, model=model, modes=modes_for_fit(model, joints, r))
    res = fit_prbdm(beam, tr.omega, joints=joints, modes=r, law=law, poses=poses,
                    starts=starts, seed=seed)
    bt = BeamTensors.from_beams(beam)
    with torch.no_grad():
        links = links_from_gamma(bt, torch.as_tensor(res.gamma)).physical(bt)
    out = res.to_dict()
    out["truth"] = {"model": tr.model, "time_s": tr.time_s, "reason": reason}
    out["links"] = {key: v.tolist() for key, v in links.items()}
    out["beam_fingerprint"] = beam_fingerprint(beam)
    return out


def load_fit(source) -> dict:
    """A fit dictionary from a path (the JSON that ``prbdm fit --json`` prints), ``'-'`` for
    standard input, or a dict (returned as is)."""
    if isinstance(source, dict):
        return source
    if str(source) == "-":
        import sys

        text, label = sys.stdin.read(), "standard input"
    else:
        path = Path(source)
        if not path.is_file():
            raise BadInput(f"--from: no such file {str(source)!r}")
        try:
            text = path.read_text()
        except (OSError, UnicodeDecodeError) as exc:
            raise BadInput(f"--from: cannot read {str(source)!r} ({exc})") from None
        label = str(source)
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise BadInput(f"--from: {label} is not valid JSON ({exc.msg} at line {exc.lineno})") \
            from None
    if not isinstance(data, dict):
        raise BadInput(f"--from: {label} must hold a JSON object (the output of prbdm fit --json)")
    return data


def _numbers(value, name, ndim):
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise BadInput(f"fit: {name} must be {'a list' if ndim == 1 else 'a list of lists'} "
                       "of numbers") from None
    if arr.ndim != ndim or arr.size == 0:
        raise BadInput(f"fit: {name} must be {'a list' if ndim == 1 else 'a list of lists'} "
                       f"of numbers, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise BadInput(f"fit: all values of {name} must be finite")
    return arr


def check_fit(fit: dict):
    """(gamma, k, law, poses) of a fit dictionary, validated; BadInput naming the key."""
    from ..chain import LAWS
    from ..constants import GAMMA_MAX, GAMMA_MIN

    if not isinstance(fit, dict):
        raise BadInput("fit: must be a dict with keys gamma, k, law, poses")
    missing = [key for key in ("gamma", "k", "poses") if key not in fit]
    if missing:
        raise BadInput(f"fit: missing key {missing[0]!r} (need gamma, k, law, poses, as printed by "
                       "prbdm fit --json)")
    gamma = _numbers(fit["gamma"], "gamma", 1)
    n = gamma.size - 1
    if n < 1:
        raise BadInput(f"fit: gamma needs n + 1 >= 2 link fractions, got {gamma.size}")
    if np.any(gamma <= 0):
        raise BadInput("fit: every gamma must be > 0")
    total = math.fsum(gamma)
    if abs(total - 1.0) > GAMMA_SUM_TOL:
        raise BadInput(f"fit: gamma must sum to 1 (within {GAMMA_SUM_TOL:g}), got {total:.9g}")
    gamma = gamma / total
    if np.any(gamma < GAMMA_MIN * (1 - 1e-9)) or np.any(gamma > GAMMA_MAX * (1 + 1e-9)):
        raise BadInput(f"fit: every gamma must lie in [{GAMMA_MIN}, {GAMMA_MAX}] (Eq. 13)")
    law = fit.get("law", "beam")
    if law not in LAWS:
        raise BadInput(f"fit: law must be one of {', '.join(LAWS)}, got {law!r}")
    poses = _numbers(fit["poses"], "poses", 2)
    if poses.shape[1] != n:
        raise BadInput(f"fit: poses must be m lists of n = {n} angles (one per joint), got "
                       f"shape {poses.shape}")
    k = _numbers(fit["k"], "k", 1)
    if k.size != poses.shape[0]:
        raise BadInput(f"fit: k needs one SCF per pose ({poses.shape[0]}), got {k.size}")
    if np.any(k <= 0):
        raise BadInput("fit: every SCF k must be > 0")
    return gamma, k, law, poses


def check_fit_links(beam, fit: dict) -> None:
    """BadInput unless the ``links.joint_x`` a fit dict carries (as ``prbdm fit --json`` prints)
    are this beam's cuts at its gamma: a FIT.json applied to a different panel."""
    from ..chain import BeamBatch, link_table

    gamma = check_fit(fit)[0]
    table = link_table(BeamBatch.from_beams(beam), gamma[None])
    check_links_match(fit, {key: table[key][0] for key in ("joint_x", "length")})


def check_links_match(fit, phys):
    """BadInput unless the fit's ``links.joint_x`` (if it carries them) are ``phys["joint_x"]``
    [m] within ``LINK_MATCH_RTOL`` of the beam's length (the sum of ``phys["length"]``)."""
    links = fit.get("links")
    if not isinstance(links, dict) or "joint_x" not in links:
        return
    try:
        given = np.asarray(links["joint_x"], dtype=float)
    except (TypeError, ValueError):
        raise BadInput("fit: links.joint_x must be a list of numbers") from None
    ours = phys["joint_x"]
    L = float(phys["length"].sum())
    if given.shape != ours.shape or not np.allclose(given, ours, rtol=0, atol=LINK_MATCH_RTOL * L):
        raise BadInput("fit: its links.joint_x do not match this beam's cuts at gamma (the fit "
                       "was made for a different beam?)")
