"""The start checkpoint of a fine-tune (``train_surrogate.py --init_from C``): it must have this
run's network and feature settings, so that its weights mean the same here (e.g. the Kirchhoff
plate's network started on Mindlin labels, whose features are a superset of its own)."""
from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np


class StartError(ValueError):
    """A start checkpoint this run cannot start from: the message says why."""


def read_start(path, feature_names: list, settings: dict, truth: str) -> tuple[dict, dict, str]:
    """(weights, metadata, sha256 of the file) of the start checkpoint at ``path``, checked
    against this run: ``feature_names`` (its features must be a subset) and ``settings``, the
    values its metadata must equal (joints, width, depth, k_mode, hypotheses, poses as a list,
    truth_modes, cells, rfe_segments, rfe_coarse, spread, ritz_basis), ``truth`` this run's truth (for the
    message). StartError otherwise."""
    from prbdm.errors import BadInput
    from prbdm.surrogate.checkpoint import read_checkpoint

    try:
        weights, meta = read_checkpoint(path)
        sha256 = hashlib.sha256(Path(path).read_bytes()).hexdigest()
        net, fs = meta["network"], meta["features"]["spec"]
        have = {"joints": meta["joints"], "width": net["width"],
                "freq_width": net.get("freq_width", 0), "depth": net["depth"],
                "k_mode": net["k_mode"], "hypotheses": net["hypotheses"],
                "poses": meta["poses"], "truth_modes": meta["truth_modes"],
                # spread and ritz_basis are absent from checkpoints made before them (then off,
                # the default basis)
                **{k: (fs.get(k, False) if k == "spread" else fs[k])
                   for k in ("cells", "rfe_segments", "rfe_coarse", "spread")},
                "ritz_basis": tuple(fs.get("ritz_basis", ()))}
        lost = [f for f in meta["features"]["names"] if f not in feature_names]
        for k in ("feature_mean", "feature_std", "logk_mean", "logk_std", "freq_mean",
                  "freq_std", "gamma_mean", "gamma_std"):
            meta["normalisation"][k]
    except BadInput as exc:
        raise StartError(str(exc)) from None
    except (KeyError, TypeError) as exc:
        raise StartError(f"{path} lacks {exc} in its metadata; a start checkpoint must be one "
                         "that training/train_surrogate.py wrote") from None
    for k, want in settings.items():
        if k == "ritz_basis" and not fs.get("ritz"):
            continue                 # a start without the Ritz features: any basis may follow
        got = have[k]
        if (not (np.shape(got) == np.shape(want) and np.allclose(got, want, rtol=0, atol=1e-12))
                if k == "poses" else got != want):
            got, want = ((f"{np.round(got, 4).tolist()}", f"{np.round(want, 4).tolist()}")
                         if k == "poses" else (repr(got), repr(want)))
            raise StartError(f"{path} has {k} = {got}, this run {want}; a start checkpoint must "
                             "have this run's network and feature settings")
    if lost:
        raise StartError(f"{path} uses features this run's truth ({truth}) does not have "
                         f"({', '.join(lost[:3])}); a start must use a subset of this run's")
    return weights, meta, sha256
