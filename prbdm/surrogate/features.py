"""Features: a fixed-size, invariant description of a planform (:func:`features`).

With the Euler-Bernoulli ``beam`` truth and the ``beam`` stiffness law, gamma, k and the
nondimensional frequencies ``omega / sqrt(E t^2 / (rho L^4))`` depend on the shape
``w(x) / max(w)`` on ``x / L`` only (scaling the widths, the thickness, the length or the material
changes nothing), so the features are built from that shape alone:

- ``log_mean[i]``: log of the mean of ``w / max(w)`` over cell i of ``x / L`` (``cells`` equal
  cells; mass and inertia are integrals of w),
- ``log_hmean[i]``: log of the harmonic mean of ``w / max(w)`` over cell i (the ``beam`` law and
  the bending compliance are integrals of ``1 / w``),
- ``log_omega_rfe[r]``: log of the nondimensional frequencies of a rigid-finite-element model of
  the beam with ``rfe_segments`` links (``k = 1``, straight pose): a cheap physical estimate of the
  truth frequencies, which the network corrects (:func:`rfe_log_omega`).

The plate truth also depends on the absolute aspect ratio and Poisson's ratio: its features add
``log_aspect = log(2 max(w) / L)`` and ``nu``. (The Kirchhoff plate's frequencies scale with ``t``
exactly, so ``t / L`` does not enter either.)
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import BadInput
from .numpy_model import (BeamBatch, links_from_gamma, span_integrals, straight_mass_matrix,
                          straight_projected_mass)

#: beams per piece in features() and Surrogate.forward(): bounds the memory of large batches
CHUNK = 2048


def uniform_gamma(n: int) -> np.ndarray:
    """Link fractions of the equal-link chain with n joints: [1/2, 1, ..., 1, 1/2] / n."""
    g = np.ones(n + 1)
    g[0] = g[-1] = 0.5
    return g / n


def _rfe_straight(batch_x, w, n: int):
    """Links of the n-joint rigid-finite-element chain and its diagonal joint stiffness."""
    gamma = np.broadcast_to(uniform_gamma(n), (len(batch_x), n + 1))
    links = links_from_gamma(batch_x, w, gamma)
    return links, 1.0 / (6.0 * links["tributary_compliance"])            # beam law, k = 1


def rfe_log_omega(batch: BeamBatch, segments: int, modes: int, coarse: int = 0) -> np.ndarray:
    """log of the nondimensional frequencies ``omega / sqrt(E t^2 / (rho L^4))`` of the
    rigid-finite-element model (``segments - 1`` joints at [1/2, 1, ..., 1, 1/2] / (segments - 1),
    ``beam`` law, k = 1, straight pose): (B, modes).

    ``coarse > 0``: the same frequencies by Rayleigh-Ritz, cheaply. The lowest modes of a
    ``coarse``-link chain, solved exactly, give their joint moments (smooth in x, unlike the joint
    angles, which follow the planform's kinks); interpolated to the fine chain's joints and divided
    by its joint stiffness they span a subspace in which the fine chain's K and M are projected in
    O(n q^2) (M is semiseparable, never formed). Ritz values bound the fine chain's eigenvalues
    from above; on random beams they agree with the exact fine chain to about 1e-4
    (tests/test_surrogate.py), at the cost of the coarse chain.
    """
    n = segments - 1
    if modes > n:
        raise BadInput(f"rfe_modes: at most rfe_segments - 1 = {n}, got {modes}")
    if coarse <= 0:
        links, kd = _rfe_straight(batch.x, batch.w, n)
        d = 1.0 / np.sqrt(kd)                                            # K^-1/2
        A = d[..., :, None] * straight_mass_matrix(links) * d[..., None, :]
        lam = 1.0 / np.linalg.eigvalsh(A)[:, ::-1][:, :modes]
        return 0.5 * np.log(lam)
    nc = coarse - 1
    q = min(nc, modes + 3)
    if modes > nc:
        raise BadInput(f"rfe_coarse: at least rfe_modes + 1 = {modes + 1} links, got {coarse}")
    links_c, kc = _rfe_straight(batch.x, batch.w, nc)
    d = 1.0 / np.sqrt(kc)
    A = d[..., :, None] * straight_mass_matrix(links_c) * d[..., None, :]
    _, Y = np.linalg.eigh(A)
    moment = (kc * d)[..., :, None] * Y[..., :, ::-1][..., :, :q]       # K theta, theta = K^-1/2 y
    # linear interpolation in x / L of the moments, with M = 0 at the free end
    xc = np.append((np.arange(nc) + 0.5) / nc, 1.0)
    xf = (np.arange(n) + 0.5) / n
    j = np.clip(np.searchsorted(xc, xf) - 1, 0, nc - 1)
    t = (xf - xc[j]) / (xc[j + 1] - xc[j])
    W = np.zeros((n, nc + 1))
    W[np.arange(n), j] += 1.0 - t
    W[np.arange(n), j + 1] += t
    moment = np.concatenate([moment, np.zeros_like(moment[..., :1, :])], axis=-2)
    links_f, kf = _rfe_straight(batch.x, batch.w, n)
    V = (W @ moment) / kf[..., :, None]                                  # fine joint angles
    Kr = np.swapaxes(V, -1, -2) @ (kf[..., :, None] * V)
    Mr = straight_projected_mass(links_f, V)
    Li = np.linalg.inv(np.linalg.cholesky(Kr))
    mu = np.linalg.eigvalsh(Li @ Mr @ np.swapaxes(Li, -1, -2))
    return 0.5 * np.log(1.0 / mu[:, ::-1][:, :modes])



@dataclass(frozen=True)
class FeatureSpec:
    """What the features are: ``cells`` equal cells of x / L for the width means,
    ``rfe_segments`` links of the rigid-finite-element estimate and ``rfe_modes`` of its
    frequencies, and the truth model (``plate`` adds the aspect ratio and nu)."""

    cells: int = 16
    rfe_segments: int = 24
    rfe_modes: int = 5
    truth: str = "beam"
    rfe_coarse: int = 0          # > 0: Rayleigh-Ritz from a chain of this many links

    def to_dict(self) -> dict:
        return {"cells": self.cells, "rfe_segments": self.rfe_segments,
                "rfe_modes": self.rfe_modes, "truth": self.truth, "rfe_coarse": self.rfe_coarse}


def feature_names(spec: FeatureSpec) -> list[str]:
    names = [f"log_mean[{i}]" for i in range(spec.cells)]
    names += [f"log_hmean[{i}]" for i in range(spec.cells)]
    names += [f"log_omega_rfe[{r}]" for r in range(spec.rfe_modes)]
    if spec.truth == "plate":
        names += ["log_aspect", "nu"]
    return names


def features(batch: BeamBatch, spec: FeatureSpec = FeatureSpec()) -> np.ndarray:
    """(B, F) features of the planforms (see the module docstring; names: :func:`feature_names`).

    Invariant to scaling all half-widths, the thickness, the length, E and rho (beam truth);
    the plate truth adds ``log_aspect`` and ``nu``.
    """
    if len(batch) > CHUNK:      # the Ritz arrays are (B, 95, 8): bounded pieces
        return np.concatenate([features(batch.take(slice(i, i + CHUNK)), spec)
                               for i in range(0, len(batch), CHUNK)])
    wmax = batch.w.max(axis=-1)
    wn = batch.w / wmax[:, None]
    edges = np.linspace(0.0, 1.0, spec.cells + 1)
    a = np.broadcast_to(edges[:-1], (len(batch), spec.cells))
    b = np.broadcast_to(edges[1:], (len(batch), spec.cells))
    area, _, _, comp = span_integrals(batch.x, wn, a, b)
    h = edges[1] - edges[0]
    cols = [np.log(area / (2 * h)), np.log(h / comp),
            rfe_log_omega(BeamBatch(batch.x, wn, batch.length, batch.thickness, batch.E,
                                    batch.rho, batch.nu), spec.rfe_segments, spec.rfe_modes,
                          spec.rfe_coarse)]
    if spec.truth == "plate":
        cols += [np.log(2 * wmax)[:, None], batch.nu[:, None]]
    return np.concatenate(cols, axis=1)

