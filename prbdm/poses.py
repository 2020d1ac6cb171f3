"""Pose sets: the joint angles at which a PRBDM is fitted and evaluated (SPEC §3, Eqs. 7-8).

NumPy only (``prbdm predict`` imports it without torch); :func:`prbdm.model.make_poses` is its
torch view. A pose is one angle per joint [rad]; a set is an (m, n) array.
"""
from __future__ import annotations

import math

import numpy as np

from .errors import BadInput

__all__ = ["paper_angles", "pose_set", "is_rest"]


def paper_angles(n: int) -> list[float]:
    """Eqs. 7-8 as the reference code builds them: pose i puts every joint at 0.1 + 0.05 i rad,
    i = 0..m-1, m the largest count with n theta <= pi/2 (one pose at pi/(2n) if that is < 0.1)."""
    limit = math.pi / (2 * n)
    if limit < 0.1:
        return [limit]
    m = int(math.floor((limit - 0.1) / 0.05 + 1e-9)) + 1
    return [0.1 + 0.05 * i for i in range(m)]


def pose_set(spec, n: int) -> np.ndarray:
    """Pose set (m, n) float64 from ``'paper'``, ``'linear'`` (the straight pose, theta = 0), a
    list of angles (each pose puts every joint at that angle), or an explicit (m, n) array."""
    if isinstance(spec, str):
        if spec == "paper":
            return np.repeat(np.asarray(paper_angles(n), dtype=np.float64)[:, None], n, axis=1)
        if spec == "linear":
            return np.zeros((1, n))
        raise BadInput(f"poses: must be 'paper', 'linear' or a list of angles, got {spec!r}")
    poses = np.array(spec, dtype=np.float64)
    if poses.ndim == 1:
        poses = np.repeat(poses[:, None], n, axis=1)
    if poses.ndim != 2 or poses.shape[-1] != n or poses.shape[0] < 1:
        raise BadInput(f"poses: must be a list of angles or an (m, {n}) array, got shape "
                       f"{tuple(poses.shape)}")
    if not np.isfinite(poses).all():
        raise BadInput("poses: all angles must be finite")
    return poses


def is_rest(poses) -> bool:
    """True for the single straight pose (the ``linear`` set: a fit at rest)."""
    poses = np.asarray(poses, dtype=np.float64)
    return poses.ndim == 2 and poses.shape[0] == 1 and not poses.any()
