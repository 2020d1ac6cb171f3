"""The panels a network was trained on, kept as a reference for every answer (issue 35).

A feature-by-feature range check (:meth:`prbdm.surrogate.Surrogate.check_range`) passes a panel
whose every feature lies inside its training range even when their combination is unlike any
training panel (a wide root with a thin tip where training only saw the reverse, say). So a
checkpoint may carry a sample of its training panels' normalised features (the tensor
:data:`NEIGHBOURS_TENSOR`, (N, F) float32, a seeded random subset of the training split) and,
in its metadata ``neighbours``, the distribution of the held-out (test split) panels' distances
to their nearest one of them. An answer whose input is further from every reference panel than
``neighbours.limit`` (the held-out :data:`LIMIT_QUANTILE` quantile: panels drawn like the
training ones pass 999 times in 1000) is flagged: no training panel is like it.

Distances are Euclidean in the network's normalised features ((f - feature_mean) / feature_std,
as the network sees them). ``training/add_neighbours.py`` adds the reference to a checkpoint
from the data sets its metadata records (weights unchanged).
"""
from __future__ import annotations

import hashlib
import json

import numpy as np

from ..errors import BadInput

#: name of the reference tensor in a checkpoint file (not a weight: ``weights_sha256`` leaves it
#: out, ``neighbours.sha256`` covers it)
NEIGHBOURS_TENSOR = "neighbours.features"
#: training panels kept by default (nearest neighbour among 4096 60-dimensional vectors: ~1 ms)
REFERENCE_COUNT = 4096
#: the held-out quantile [%] beyond which a panel is unlike the training ones
LIMIT_QUANTILE = 99.9
#: query rows per block of the distance matrix (bounded memory for large batches)
BLOCK = 1024


def reference_sha256(reference: np.ndarray) -> str:
    """sha256 of the reference (its dtype, shape, then its little-endian bytes)."""
    a = np.asarray(reference)
    a = np.ascontiguousarray(a, dtype=a.dtype.newbyteorder("<"))
    h = hashlib.sha256()
    h.update(json.dumps([NEIGHBOURS_TENSOR, a.dtype.str, list(a.shape)]).encode())
    h.update(a.tobytes())
    return h.hexdigest()


def nearest_distance(query: np.ndarray, reference: np.ndarray,
                     reference_sq: np.ndarray | None = None) -> np.ndarray:
    """(B,) Euclidean distance of each row of ``query`` (B, F) to its nearest row of
    ``reference`` (N, F), in float64; NaN for a non-finite query row."""
    q = np.asarray(query, dtype=np.float64)
    r = np.asarray(reference, dtype=np.float64)
    r_sq = (r * r).sum(1) if reference_sq is None else reference_sq
    out = np.empty(q.shape[0])
    for i in range(0, q.shape[0], BLOCK):
        qb = q[i:i + BLOCK]
        d2 = (qb * qb).sum(1)[:, None] - 2.0 * (qb @ r.T) + r_sq[None, :]
        out[i:i + BLOCK] = np.sqrt(np.maximum(d2.min(1), 0.0))
    out[~np.all(np.isfinite(q), axis=1)] = np.nan
    return out


def reference_rows(train: int, count: int = REFERENCE_COUNT, seed: int = 0) -> np.ndarray:
    """Which of ``train`` training rows :func:`build_reference` keeps (ascending): ``count``
    drawn at random with ``seed``, all when fewer."""
    rng = np.random.default_rng(seed)
    return np.sort(rng.choice(train, size=min(count, train), replace=False))


def build_reference(train: np.ndarray, held_out: np.ndarray, count: int = REFERENCE_COUNT,
                    seed: int = 0) -> tuple[np.ndarray, dict]:
    """(reference, record) from the normalised features of the training panels ``train``
    (B_train, F) and of the held-out ones ``held_out`` (B_test, F): ``count`` training rows drawn
    at random (``seed``; all when fewer), as float32, and the metadata ``neighbours`` record:
    how they were drawn, the held-out panels' nearest distances (quantiles) and the ``limit``
    beyond which an answer is warned about (the held-out :data:`LIMIT_QUANTILE` quantile)."""
    train = np.asarray(train, dtype=np.float64)
    held_out = np.asarray(held_out, dtype=np.float64)
    if train.ndim != 2 or held_out.ndim != 2 or train.shape[1] != held_out.shape[1]:
        raise BadInput(f"neighbours: feature arrays of shapes {train.shape} and "
                       f"{held_out.shape} do not match")
    if len(held_out) < 100:
        raise BadInput(f"neighbours: {len(held_out)} held-out panels are too few to place a "
                       "limit (need 100)")
    rows = reference_rows(len(train), count, seed)
    reference = np.ascontiguousarray(train[rows], dtype=np.float32)
    dist = nearest_distance(held_out, reference)
    q = {name: float(np.percentile(dist, p)) for name, p in
         (("p50", 50), ("p90", 90), ("p99", 99), ("p99.9", 99.9))}
    record = {"count": int(len(reference)), "drawn_from": int(len(train)), "seed": int(seed),
              "space": "normalised features (f - feature_mean) / feature_std, Euclidean",
              "held_out": {"beams": int(len(held_out)), **q, "max": float(dist.max())},
              "limit_quantile": LIMIT_QUANTILE,
              "limit": float(np.percentile(dist, LIMIT_QUANTILE))}
    return reference, record


def check_reference(tensors: dict, metadata: dict, features: int) -> None:
    """BadInput (without the file name) unless the reference tensor and the metadata
    ``neighbours`` agree: both or neither, (N, F) finite floating point, a finite positive
    limit and held-out p99."""
    rec = metadata.get("neighbours")
    ref = tensors.get(NEIGHBOURS_TENSOR)
    if rec is None and ref is None:
        return
    if rec is None:
        raise BadInput(f"tensor {NEIGHBOURS_TENSOR} without its metadata 'neighbours'")
    if ref is None:
        raise BadInput(f"metadata 'neighbours' without its tensor {NEIGHBOURS_TENSOR}")
    if ref.ndim != 2 or ref.shape[1] != features or ref.shape[0] < 1 or ref.dtype.kind != "f":
        raise BadInput(f"{NEIGHBOURS_TENSOR} has shape {ref.shape} and dtype {ref.dtype}; "
                       f"expected (N, {features}) floating point")
    if not np.all(np.isfinite(ref)):
        raise BadInput(f"{NEIGHBOURS_TENSOR} has non-finite values")
    try:
        values = [float(rec["limit"]), float(rec["held_out"]["p99"])]
    except (KeyError, TypeError, ValueError):
        raise BadInput("incomplete metadata 'neighbours' (need limit and held_out.p99)") from None
    if not all(np.isfinite(v) and v > 0 for v in values):
        raise BadInput(f"metadata 'neighbours': limit and held_out.p99 must be finite and "
                       f"positive, got {values}")
