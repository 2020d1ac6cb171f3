"""What a PRBDM matches away from rest (SPEC §3, "What a pose is matched to").

- ``straight`` (the paper's, Eqs. 7-13): every pose is matched to the straight panel's
  frequencies, with one stiffness correction factor per pose absorbing the difference.
- ``shape``: the chain is fitted at rest (theta = 0, where the panel's shape is the straight one)
  and keeps that stiffness at every pose: its inertia changes with the pose as the panel's does
  in that shape, so its frequencies follow the panel bent into the pose (stress-free), which the
  geometrically exact rod (:mod:`prbdm.truth.rod`) gives independently of the chain.

Measured on 100 random beams (``python benchmarks/pose_targets.py``; the numbers are in
docs/method.md, "Poses"): against the panel in each pose's shape the constant-stiffness chain is
a few percent off on its worst mode, the paper's fit tens of percent; the straight panel is not
what a bent panel vibrates like.
"""
from __future__ import annotations

import dataclasses

import numpy as np

__all__ = ["POSE_TARGETS", "DEFAULT_POSE_TARGET", "hold_stiffness", "hold_prediction",
           "shape_truths"]

POSE_TARGETS = ("straight", "shape")
#: what ``prbdm fit`` matches away from rest unless told (``--pose-target``): the measurement
#: above supports the panel in the pose's shape; the paper's target is one flag away
DEFAULT_POSE_TARGET = "shape"


def hold_stiffness(beam, rest, poses):
    """The rest fit ``rest`` (a :class:`prbdm.fit.FitResult` with the single pose theta = 0) at
    ``poses`` (m, n) [rad] with its stiffness held: a FitResult whose ``k`` repeats the rest SCF,
    ``omega`` (m, n) the chain's frequencies at each pose, ``poses`` those poses; its loss,
    frequency objective and ``freq_error`` stay those at rest, where it was fitted."""
    import torch

    from .model import eigenvalues

    poses = np.atleast_2d(np.asarray(poses, dtype=np.float64))
    k = np.full(poses.shape[0], float(rest.k[0]))
    with torch.no_grad():
        lam = eigenvalues(beam, torch.as_tensor(rest.gamma), torch.as_tensor(k),
                          torch.as_tensor(poses), rest.law)
    return dataclasses.replace(rest, k=k, omega=lam.sqrt().numpy(), poses=poses,
                               extra={**rest.extra, "pose_target": "shape",
                                      "fitted_at": "rest (theta = 0)"})


def hold_prediction(batch, gamma, k_rest, poses):
    """NumPy twin of :func:`hold_stiffness` for a network's answer at rest: ``batch`` a
    :class:`prbdm.chain.BeamBatch` of B beams, ``gamma`` (B, n+1), ``k_rest`` (B,) the SCF at rest,
    ``poses`` (m, n) [rad] -> ``k`` (B, m), the rest SCF at every pose, and ``omega`` (B, m, n)
    [rad/s], the chain's frequencies there (no torch, no solver)."""
    from .chain import prbdm_eigenvalues

    poses = np.atleast_2d(np.asarray(poses, dtype=np.float64))
    mu = prbdm_eigenvalues(batch.x, batch.w, np.asarray(gamma, dtype=np.float64), poses)
    k = np.repeat(np.asarray(k_rest, dtype=np.float64).reshape(-1, 1), poses.shape[0], axis=1)
    omega = np.sqrt(mu * k[..., None] * np.asarray(batch.lambda0, dtype=np.float64)[:, None, None])
    return k, omega


def shape_truths(beam, gamma, poses, modes: int) -> np.ndarray:
    """(m, modes) [rad/s]: the geometrically exact rod (the panel as a strip) bent stress-free into
    each pose's shape, the chain's own (its links straight, bent at its joints)."""
    from .truth.rod import chain_shape, rod_frequencies

    # degree 4 on the width-graded elements: within 2e-6 of a fine beam FEM at rest on the
    # paper's jagged planforms, a fraction of the default's time
    return np.stack([rod_frequencies(beam, about=chain_shape(beam, gamma, pose),
                                     modes=int(modes), degree=4).omega
                     for pose in np.atleast_2d(np.asarray(poses, dtype=np.float64))])
