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
exactly, so ``t / L`` does not enter either.) The shear-deformable ``mindlin`` truth's do not: its
features add ``log_thickness = log(t / L)`` as well (the shear grows like (t / L)^2 and with the
narrowest neck over the thickness, which the width features and this one give together).

``spread`` (plate networks): ``log_omega_spread[r]``, the same chain with the bending stiffness of
the *load-spread* half-width ``w_s(x) = min_x' (w(x') + |x - x'|)`` (x, w in units of L) and the
mass of the real one. In a wide plate, bending stress leaves a narrow neck at about 45 degrees:
the flanges right beside a neck move with it but carry little of its moment, which the beam (full
width effective everywhere) misses. On 3,000 panels of the plate data set the scatter of
``log omega_plate - log omega_chain`` (std, modes 1-4) is 0.095 / 0.087 / 0.22 / 0.35 with the
beam's chain and 0.038 / 0.038 / 0.18 / 0.33 with the spread chain, as computed here (with the
exact 95-joint chain on an 801-point grid, slope 1 gives 0.035 / 0.037 on modes 1-2, slope 0.5
0.078 / 0.064, slope 2 0.037 / 0.050): a classical engineering rule that explains most of modes 1-2 and is
the network's base for the plate frequencies (:meth:`FeatureSpec.base_columns`). Modes 3-4 are
left to the network; many of them are mixed bending-chordwise modes (docs/surrogate.md §5).

``ritz`` (plate networks): ``log_omega_ritz[r]``, the plate's bending spectrum (../SPEC §2.1)
estimated by Rayleigh-Ritz on the planform itself (:mod:`prbdm.truth.planform_ritz`: a Mindlin
plate in ``eta = y / w(x)``, ~350 unknowns). It sees what the chains cannot, the chord-wise
modes and how they mix with bending, and is the base of a ``ritz`` network's frequencies. On
1,000 wide panels of the Mindlin spectrum set the scatter of ``log omega_plate - log omega_ritz``
(std, modes 1-5) is 0.061 / 0.044 / 0.058 / 0.076 / 0.072, against the spread chain's 0.030 /
0.037 / 0.114 / 0.170 / 0.164 (benchmarks/planform_ritz.py, docs/validation.md).

``profile = P`` (plate networks): ``log_profile[i]``, the log of ``w / max(w)`` at the midpoints
of P equal cells of x / L (floored at ``PROFILE_FLOOR``), and with ``spread``
``log_spread_profile[i]``, the same of the load-spread half-width (relative to the real width's
maximum). The cell means above average a neck away; the plate's frequencies feel where the
necks are and how narrow. A frequency-only MLP on the 58,000 training panels of the Mindlin set
learned modes 1-2 of the held-out wide panels to 0.31 / 0.45 % with 64 points, 0.48 / 0.60 %
without them (docs/surrogate.md §5).
"""
from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from ..chain import (
    BeamBatch,
    links_from_gamma,
    span_integrals,
    straight_mass_matrix,
    straight_projected_mass,
    uniform_gamma,
)
from ..errors import BadInput

#: beams per piece in features() and Surrogate.forward(): bounds the memory of large batches
CHUNK = 2048
#: slope of the load spread behind ``log_omega_spread``: half-width gained per span length
#: (1 = 45 degrees; the module text gives the measured scatter for 0.5, 1 and 2)
SPREAD_SLOPE = 1.0
#: points of x / L on which the load-spread half-width is tabulated (piecewise linear between)
SPREAD_POINTS = 193
#: floor of w / max(w) in the ``profile`` features: a neck narrower than 1 % of the widest
#: section reads as 1 %, so that a near-zero width is not an extrapolation of its log
PROFILE_FLOOR = 1e-2


def _rfe_straight(batch_x, w, n: int, stiffness=None):
    """Links of the n-joint rigid-finite-element chain and its diagonal joint stiffness; with
    ``stiffness`` = (x, w) another planform gives the joint stiffness (the links keep ``w``)."""
    gamma = np.broadcast_to(uniform_gamma(n), (len(batch_x), n + 1))
    links = links_from_gamma(batch_x, w, gamma)
    src = links if stiffness is None else links_from_gamma(*stiffness, gamma)
    return links, 1.0 / (6.0 * src["tributary_compliance"])              # beam law, k = 1


def half_width_at(x, w, xq):
    """The piecewise-linear half-widths of planforms with stations ``x`` (B, S) and half-widths
    ``w`` (B, S) at the points ``xq`` ((P,) for every row, or (B, P)), in units of L: (B, P)."""
    B, S = x.shape
    xq = np.broadcast_to(xq, (B, np.shape(xq)[-1]))
    # every row at once: the rows shifted apart (x in [0, 1]) so that one sorted search finds
    # each point's segment in its own row
    shift = 2.0 * np.arange(B)[:, None]
    j = np.searchsorted((x + shift).ravel(), (xq + shift).ravel(), side="right") - 1
    j = np.clip(j.reshape(xq.shape) - S * np.arange(B)[:, None], 0, S - 2)
    x0, x1 = np.take_along_axis(x, j, 1), np.take_along_axis(x, j + 1, 1)
    w0, w1 = np.take_along_axis(w, j, 1), np.take_along_axis(w, j + 1, 1)
    h = x1 - x0
    u = np.divide(xq - x0, h, out=np.zeros_like(h), where=h > 0)
    return w0 + np.clip(u, 0.0, 1.0) * (w1 - w0)


def spread_half_width(x, w, slope: float = SPREAD_SLOPE, points: int = SPREAD_POINTS):
    """The load-spread half-width ``w_s(x) = min_x' (w(x') + slope |x - x'|)`` of planforms with
    stations ``x`` (B, S) and half-widths ``w`` (B, S), both in units of L: (x_grid (B, P),
    w_s (B, P)). Exact at the grid points: for a piecewise-linear w the minimum over x' lies at a
    station or at x' = x. Between them the chain reads it as linear, which can exceed w at a
    neck narrower than the grid spacing (1 / (P - 1) L); the trained networks' features are
    defined with this grid, so it is part of the feature, not to be refined alone."""
    xg = np.linspace(0.0, 1.0, points)
    wg = half_width_at(x, w, xg)
    cone = (w[:, None, :] + slope * np.abs(xg[None, :, None] - x[:, None, :])).min(-1)
    return np.broadcast_to(xg, wg.shape), np.minimum(wg, cone)


def rfe_log_omega(batch: BeamBatch, segments: int, modes: int, coarse: int = 0,
                  stiffness=None) -> np.ndarray:
    """log of the nondimensional frequencies ``omega / sqrt(E t^2 / (rho L^4))`` of the
    rigid-finite-element model (``segments - 1`` joints at [1/2, 1, ..., 1, 1/2] / (segments - 1),
    ``beam`` law, k = 1, straight pose): (B, modes). ``stiffness`` = (x, w) arrays: the joint
    stiffness of that planform instead (:func:`spread_half_width`), the mass of ``batch``'s.

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
        links, kd = _rfe_straight(batch.x, batch.w, n, stiffness)
        d = 1.0 / np.sqrt(kd)                                            # K^-1/2
        A = d[..., :, None] * straight_mass_matrix(links) * d[..., None, :]
        lam = 1.0 / np.linalg.eigvalsh(A)[:, ::-1][:, :modes]
        return 0.5 * np.log(lam)
    nc = coarse - 1
    q = min(nc, modes + 3)
    if modes > nc:
        raise BadInput(f"rfe_coarse: at least rfe_modes + 1 = {modes + 1} links, got {coarse}")
    links_c, kc = _rfe_straight(batch.x, batch.w, nc, stiffness)
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
    links_f, kf = _rfe_straight(batch.x, batch.w, n, stiffness)
    V = (W @ moment) / kf[..., :, None]                                  # fine joint angles
    Kr = np.swapaxes(V, -1, -2) @ (kf[..., :, None] * V)
    Mr = straight_projected_mass(links_f, V)
    Li = np.linalg.inv(np.linalg.cholesky(Kr))
    mu = np.linalg.eigvalsh(Li @ Mr @ np.swapaxes(Li, -1, -2))
    return 0.5 * np.log(1.0 / mu[:, ::-1][:, :modes])



#: the largest span-wise degree and number of chord-wise terms of a Ritz basis (the dense solve
#: grows as the cube of their product)
RITZ_BASIS_MAX = 8


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
    spread: bool = False         # add log_omega_spread, the base of the predicted frequencies
    profile: int = 0             # > 0: add the width profile at this many points of x / L
    ritz: bool = False           # add log_omega_ritz, the plate's own estimate, and correct it
    ritz_basis: tuple = ()       # (degree, chord terms) of that estimate; () the default one

    def __post_init__(self):
        """``ritz_basis``: a checkpoint's JSON gives a list; the default basis is ``()``."""
        from ..truth.planform_ritz import RITZ_DEFAULTS
        try:
            basis = tuple(int(v) for v in self.ritz_basis)
        except (TypeError, ValueError):
            basis = None
        if basis is None or not (basis == () or (
                len(basis) == 2 and all(1 <= b <= RITZ_BASIS_MAX for b in basis))):
            raise ValueError(f"ritz_basis: DEGREE,CHORD_TERMS, two integers in "
                             f"[1, {RITZ_BASIS_MAX}]")
        if basis == (RITZ_DEFAULTS["degree"], RITZ_DEFAULTS["chord_terms"]):
            basis = ()
        object.__setattr__(self, "ritz_basis", basis)

    def to_dict(self) -> dict:
        out = {"cells": self.cells, "rfe_segments": self.rfe_segments,
               "rfe_modes": self.rfe_modes, "truth": self.truth, "rfe_coarse": self.rfe_coarse}
        if self.spread:          # absent from the checkpoints made before it existed
            out["spread"] = True
        if self.profile:         # the same
            out["profile"] = self.profile
        if self.ritz:            # the same
            out["ritz"] = True
        if self.ritz_basis:      # the same
            out["ritz_basis"] = list(self.ritz_basis)
        return out

    def base_columns(self, modes: int) -> slice:
        """The feature columns the predicted log frequencies are corrections of (``modes`` of
        them): log_omega_ritz with ``ritz`` (the last columns), else log_omega_spread with
        ``spread``, else log_omega_rfe."""
        if self.ritz:
            start = len(feature_names(self)) - self.rfe_modes
            return slice(start, start + modes)
        start = 2 * self.cells + (self.rfe_modes if self.spread else 0)
        return slice(start, start + modes)


def feature_names(spec: FeatureSpec) -> list[str]:
    names = [f"log_mean[{i}]" for i in range(spec.cells)]
    names += [f"log_hmean[{i}]" for i in range(spec.cells)]
    names += [f"log_omega_rfe[{r}]" for r in range(spec.rfe_modes)]
    if spec.spread:
        names += [f"log_omega_spread[{r}]" for r in range(spec.rfe_modes)]
    if spec.truth in ("plate", "mindlin"):
        names += ["log_aspect", "nu"]
    if spec.truth == "mindlin":
        names += ["log_thickness"]
    names += [f"log_profile[{i}]" for i in range(spec.profile)]
    if spec.spread:
        names += [f"log_spread_profile[{i}]" for i in range(spec.profile)]
    if spec.ritz:
        names += [f"log_omega_ritz[{r}]" for r in range(spec.rfe_modes)]
    return names


def width_profile(x, w, points: int) -> np.ndarray:
    """log of ``max(w / max(w), PROFILE_FLOOR)`` at the midpoints of ``points`` equal cells of
    x / L, for planforms with stations ``x`` (B, S) and half-widths ``w`` (B, S) (piecewise
    linear between stations): (B, points)."""
    wq = half_width_at(x, w, (np.arange(points) + 0.5) / points)
    return np.log(np.maximum(wq / w.max(axis=-1, keepdims=True), PROFILE_FLOOR))


def features(batch: BeamBatch, spec: FeatureSpec = FeatureSpec(),
             ritz_columns=None) -> np.ndarray:
    """(B, F) features of the planforms (see the module docstring; names: :func:`feature_names`).
    ``ritz_columns``: :func:`ritz_log_omega` of the batch where it was computed before (training
    keeps it, the costly part: training/_ritz_cache.py), else it is computed here.

    Invariant to scaling all half-widths, the thickness, the length, E and rho (beam truth);
    the plate truth adds ``log_aspect`` and ``nu``, and ``spread`` ``log_omega_spread``, which
    depends on ``w / L`` itself (not only on the shape ``w / max(w)``).
    """
    if len(batch) > CHUNK:      # the Ritz arrays are (B, 95, 8): bounded pieces
        return np.concatenate([features(batch.take(slice(i, i + CHUNK)), spec,
                                        None if ritz_columns is None
                                        else ritz_columns[i:i + CHUNK])
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
    if spec.spread:
        xs, ws = spread_half_width(batch.x, batch.w)
        cols.append(rfe_log_omega(BeamBatch(batch.x, wn, batch.length, batch.thickness, batch.E,
                                            batch.rho, batch.nu), spec.rfe_segments,
                                  spec.rfe_modes, spec.rfe_coarse, (xs, ws / wmax[:, None])))
    if spec.truth in ("plate", "mindlin"):
        cols += [np.log(2 * wmax)[:, None], batch.nu[:, None]]
    if spec.truth == "mindlin":
        cols.append(np.log(batch.thickness / batch.length)[:, None])
    if spec.profile:
        cols.append(width_profile(batch.x, batch.w, spec.profile))
        if spec.spread:
            # the spread width relative to the real one's maximum (its floor stays relative to
            # its own): where a neck cuts the load path
            cols.append(width_profile(xs, ws, spec.profile) + np.log(ws.max(-1) / wmax)[:, None])
    if spec.ritz:
        est = (ritz_log_omega(batch, spec.rfe_modes, spec.ritz_basis) if ritz_columns is None
               else np.asarray(ritz_columns))
        if est.shape != (len(batch), spec.rfe_modes):
            raise ValueError(f"ritz_columns: expected ({len(batch)}, {spec.rfe_modes}), got {est.shape}")
        cols.append(est)
    return np.concatenate(cols, axis=1)


def ritz_log_omega(batch: BeamBatch, modes: int, basis=()) -> np.ndarray:
    """log of the nondimensional frequencies ``omega / sqrt(E t^2 / (rho L^4))`` of the plate's
    bending spectrum estimated by Rayleigh-Ritz on the planform
    (:func:`prbdm.truth.planform_ritz.ritz_bending_spectrum`, ~20 ms a panel): (B, modes).
    ``basis``: ``(degree, chord_terms)`` of the Ritz basis, () its defaults (a richer one
    follows the paper's jagged panels closer: (4, 4) halves the scatter of modes 3-4, at ~4x the
    cost; benchmarks/planform_ritz.py)."""
    from ..truth.planform_ritz import ritz_bending_spectrum
    options = dict(zip(("degree", "chord_terms"), map(int, basis)))
    out = np.empty((len(batch), modes))

    def one(i):
        x, w = batch.x[i], batch.w[i]                        # in units of the length
        keep = np.concatenate([[True], np.diff(x) > 0])     # padded stations repeat the last
        lam = ritz_bending_spectrum(x[keep], w[keep],
                                    float(batch.thickness[i] / batch.length[i]),
                                    float(batch.nu[i]), modes, **options)
        if not (np.all(np.isfinite(lam)) and np.all(lam > 0)):
            raise ArithmeticError(f"log_omega_ritz: the planform estimate of beam {i} failed "
                                  f"({lam.tolist()})")
        out[i] = 0.5 * np.log(lam / (12.0 * (1.0 - float(batch.nu[i]) ** 2)))

    # LAPACK releases the GIL: large batches (training sets) on every core
    workers = min(os.cpu_count() or 1, 8) if len(batch) >= 256 else 1
    if workers > 1:
        with ThreadPoolExecutor(workers) as pool:
            list(pool.map(one, range(len(batch))))
    else:
        for i in range(len(batch)):
            one(i)
    return out

