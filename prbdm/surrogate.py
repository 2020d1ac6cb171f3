"""The surrogate: from a beam's planform straight to its PRBDM (gamma, k) and its truth frequencies.

A small network trained on a labelled data set (:mod:`prbdm.dataset`) replaces the truth solve and
the multistart fit: features of the planform in, the link fractions ``gamma``, one stiffness
correction factor ``k`` per pose and the beam's own truth frequencies out. See docs/surrogate.md.

Read in this order:

1. **Beams as arrays** (:class:`BeamBatch`): padded NumPy arrays of stations and half-widths
   divided by L, plus thickness, length and material.
2. **A NumPy PRBDM** (:func:`prbdm_eigenvalues`, :func:`link_table`): the same links, mass matrix,
   ``beam`` stiffness law and eigenvalues as :mod:`prbdm.model`, without torch, so that
   ``prbdm predict`` starts in a fraction of a second (importing torch alone takes about 2 s on a
   busy machine). ``tests/test_surrogate.py`` checks it against :mod:`prbdm.model`.
3. **Features** (:func:`features`): a fixed-size, invariant description of the planform.
   With the Euler-Bernoulli ``beam`` truth and the ``beam`` stiffness law, gamma, k and the
   nondimensional frequencies ``omega / sqrt(E t^2 / (rho L^4))`` depend on the shape
   ``w(x) / max(w)`` on ``x / L`` only (scaling the widths, the thickness, the length or the
   material changes nothing), so the features are built from that shape alone:

   - ``log_mean[i]``: log of the mean of ``w / max(w)`` over cell i of ``x / L`` (``cells`` equal
     cells; mass and inertia are integrals of w),
   - ``log_hmean[i]``: log of the harmonic mean of ``w / max(w)`` over cell i (the ``beam`` law
     and the bending compliance are integrals of ``1 / w``),
   - ``log_omega_rfe[r]``: log of the nondimensional frequencies of a rigid-finite-element model
     of the beam with ``rfe_segments`` links (``k = 1``, straight pose): a cheap physical
     estimate of the truth frequencies, which the network corrects.

   The plate truth also depends on the absolute aspect ratio and Poisson's ratio: its features add
   ``log_aspect = log(2 max(w) / L)`` and ``nu``. (The Kirchhoff plate's frequencies scale with
   ``t`` exactly, so ``t / L`` does not enter either.)
4. **The network** (:class:`SurrogateNet`, torch, for training): an MLP on standardised features
   with three heads whose outputs are valid by construction: ``gamma = g_min + (1 - (n+1) g_min)
   softmax(.)`` (on the bounded simplex: sum 1, each in [0.025, 0.975]), ``k = exp(.)`` (> 0),
   and ``log omega_hat = log_omega_rfe + correction``. Inference (:class:`Surrogate`) runs the same
   MLP in NumPy.
5. **Checkpoints** (:func:`save_checkpoint`, :func:`load_checkpoint`, :func:`default_checkpoint`):
   one safetensors file holding the weights and, in its header, the JSON metadata (data set spec,
   size and hash, seeds, versions, git commit, feature normalisation and ranges, metrics). Loading
   parses JSON and raw arrays only: no code is executed. A copy of the metadata is written beside
   it as ``NAME.json`` for people to read.
6. **Prediction** (:func:`predict`): batched, for beams or for precomputed features; inputs outside
   the feature ranges seen in training get a :class:`OutOfDistributionWarning` naming the feature.
"""
from __future__ import annotations

import copy
import hashlib
import json
import math
import os
import struct
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import BadInput
from .geometry import Beam, Material, check_prbdm_width_ratio

__all__ = ["BeamBatch", "FeatureSpec", "features", "feature_names", "prbdm_eigenvalues",
           "link_table", "Surrogate", "Prediction", "load_checkpoint", "save_checkpoint",
           "default_checkpoint", "available_checkpoints", "predict", "dataset_hash",
           "OutOfDistributionWarning", "CHECKPOINT_FORMAT", "GAMMA_MIN", "GAMMA_MAX",
           "SurrogateNet", "SurrogateEnsemble", "rfe_log_omega", "gauss_select_poses"]

GAMMA_MIN, GAMMA_MAX = 0.025, 0.975     # as prbdm.model (not imported: it imports torch)
CHECKPOINT_FORMAT = "prbdm-surrogate"
CHECKPOINT_VERSION = 2      # 2: several members (an ensemble) and the choice poses
#: fraction of a feature's training range by which an input may exceed it before a warning
OOD_MARGIN = 0.05
#: folders searched for default checkpoints: $PRBDM_CHECKPOINTS (os.pathsep-separated), then the
#: shipped ones: prbdm/checkpoints/ in an installed wheel (pyproject.toml maps the repository's
#: top-level checkpoints/ there), the repository's checkpoints/ in a source checkout or an
#: editable install
_HERE = Path(__file__).resolve().parent
PACKAGE_CHECKPOINTS = next((d for d in (_HERE / "checkpoints", _HERE.parent / "checkpoints")
                            if d.is_dir()), _HERE / "checkpoints")


class OutOfDistributionWarning(UserWarning):
    """An input lies outside the range of a feature seen in training."""


# ============================================================================ 1. beams as arrays
@dataclass(frozen=True)
class BeamBatch:
    """B beams as NumPy arrays. x, w: (B, S) stations and half-widths divided by L (x from 0 to
    1; beams with fewer stations are padded by repeating their tip); length, thickness [m],
    E [Pa], rho [kg/m^3], nu: (B,)."""

    x: np.ndarray
    w: np.ndarray
    length: np.ndarray
    thickness: np.ndarray
    E: np.ndarray
    rho: np.ndarray
    nu: np.ndarray

    def __len__(self):
        return self.x.shape[0]

    @classmethod
    def from_beams(cls, beams) -> "BeamBatch":
        if isinstance(beams, Beam):
            beams = [beams]
        beams = list(beams)
        if not beams:
            raise BadInput("beams: need at least one beam")
        for b in beams:
            if not isinstance(b, Beam):
                raise BadInput(f"beams: must be prbdm.geometry.Beam objects, got "
                               f"{type(b).__name__}")
            check_prbdm_width_ratio(b)
        return cls.from_arrays([b.x for b in beams], [b.half_width for b in beams],
                               [b.thickness for b in beams], [b.material for b in beams])

    @classmethod
    def from_arrays(cls, xs, half_widths, thickness, material=None) -> "BeamBatch":
        """From per-beam station and half-width lists [m] (a data set's ``x`` and ``half_width``
        columns), thicknesses [m] and one :class:`Material` or one per beam."""
        B = len(xs)
        S = max(len(x) for x in xs)
        X = np.empty((B, S))
        W = np.empty((B, S))
        for i, (x, w) in enumerate(zip(xs, half_widths)):
            n = len(x)
            X[i, :n], W[i, :n] = x, w
            X[i, n:], W[i, n:] = x[-1], w[-1]
        L = X[:, -1].copy()
        X /= L[:, None]
        W /= L[:, None]
        X[:, -1] = 1.0
        if material is None or isinstance(material, Material):
            m = material or Material()
            mats = np.tile([m.E, m.rho, m.nu], (B, 1))
        else:
            mats = np.array([[m.E, m.rho, m.nu] for m in material])
        return cls(X, W, L, np.asarray(thickness, dtype=np.float64).reshape(B),
                   mats[:, 0].copy(), mats[:, 1].copy(), mats[:, 2].copy())

    @classmethod
    def from_table(cls, table, material: Material | dict | None = None) -> "BeamBatch":
        """From a data set table (pyarrow Table or pandas DataFrame with columns ``x``,
        ``half_width``, ``thickness``); ``material`` is the data set's (``spec['beam']
        ['material']``)."""
        if isinstance(material, dict):
            material = Material(**material)
        if hasattr(table, "column"):                       # pyarrow
            xs = table.column("x").to_pylist()
            ws = table.column("half_width").to_pylist()
            t = table.column("thickness").to_numpy()
        else:                                              # pandas
            xs, ws, t = list(table["x"]), list(table["half_width"]), table["thickness"].to_numpy()
        return cls.from_arrays(xs, ws, t, material)

    @property
    def lambda0(self) -> np.ndarray:
        """Eigenvalue scale E t^2 / (rho L^4) [rad^2/s^2]."""
        return self.E * self.thickness ** 2 / (self.rho * self.length ** 4)

    def take(self, idx) -> "BeamBatch":
        return BeamBatch(*(getattr(self, f)[idx] for f in
                           ("x", "w", "length", "thickness", "E", "rho", "nu")))


# ============================================================================ 2. a NumPy PRBDM
def _inv_logmean(lo, hi):
    u = (hi - lo) / lo
    small = np.abs(u) < 1e-3
    u_safe = np.where(small, 1.0, u)
    exact = np.log1p(u_safe) / u_safe
    series = 1 - u / 2 + u * u / 3 - u * u * u / 4
    return np.where(small, series, exact) / lo


def _simpson(h, xa, xb, wa, wb, parts=(0, 1, 2, 3)):
    """Integrals over [xa, xb] (length h) of 2 w, 2 x w, 2 x^2 w (Simpson: exact for the cubic)
    and of 1 / w, for w linear from wa to wb: the ones named by ``parts`` (0..3), in order."""
    out = []
    if 1 in parts or 2 in parts:
        xm, wm = (xa + xb) / 2, (wa + wb) / 2
    for p in parts:
        if p == 0:
            out.append(h * (wa + wb))
        elif p == 1:
            out.append(h / 3 * (xa * wa + 4 * xm * wm + xb * wb))
        elif p == 2:
            out.append(h / 3 * (xa * xa * wa + 4 * xm * xm * wm + xb * xb * wb))
        else:
            out.append(h * _inv_logmean(wa, wb))
    return out


def _segments(x, q):
    """Index k (B, Q) of the planform segment [x_k, x_k+1] that holds each q: the number of
    stations x_0..x_{S-2} at or below q, less one, clipped to [0, S-2]. One sorted search over
    the rows laid end to end (each row shifted by twice its number; x, q lie in [0, 1])."""
    B, S = x.shape
    shift = 2.0 * np.arange(B)[:, None]
    flat = (x[:, :-1] + shift).ravel()
    pos = np.searchsorted(flat, (q + shift).ravel(), side="right").reshape(q.shape)
    return np.clip(pos - (S - 1) * np.arange(B)[:, None] - 1, 0, S - 2)


def _cumulative(x, w, q, parts=(0, 1, 2, 3)):
    """Integrals from 0 to q of 2 w, 2 x w, 2 x^2 w and 1 / w (``parts`` 0..3, the ones asked
    for, in order): x, w (B, S), q (B, Q) in [0, 1].

    Cost O(B (S + Q) log(B S)): whole segments by prefix sums, the part of q's own segment by
    Simpson's rule; this is what makes the batched prediction fast."""
    S = x.shape[-1]
    h = np.diff(x, axis=-1)
    full = _simpson(h, x[:, :-1], x[:, 1:], w[:, :-1], w[:, 1:], parts)
    cums = [np.concatenate([np.zeros((x.shape[0], 1)), np.cumsum(p, -1)], -1) for p in full]
    k = _segments(x, q)
    xk = np.take_along_axis(x, k, -1)
    wk = np.take_along_axis(w, k, -1)
    hk = np.take_along_axis(h, k, -1)
    wk1 = np.take_along_axis(w[:, 1:], k, -1)
    slope = np.where(hk > 0, (wk1 - wk) / np.where(hk > 0, hk, 1.0), 0.0)
    dq = np.clip(q - xk, 0.0, None)
    part = _simpson(dq, xk, xk + dq, wk, wk + slope * dq, parts)
    return [np.take_along_axis(c, k, -1) + p for c, p in zip(cums, part)]


def span_integrals(x, w, a, b):
    """NumPy twin of :func:`prbdm.sections.span_integrals` for x, w (B, S) and spans a, b
    (B, C): (area, first, second, compliance) (B, C), moments about each span's midpoint. Built
    from cumulative integrals (see :func:`_cumulative`); agrees with the torch version to about
    1e-12 relative for spans of at least 0.025 L."""
    C = a.shape[-1]
    F = _cumulative(x, w, np.concatenate([np.broadcast_to(a, b.shape), b], -1))
    m0, m1, m2, mc = (f[:, C:] - f[:, :C] for f in F)
    mid = (a + b) / 2
    first = m1 - mid * m0
    second = m2 - 2 * mid * m1 + mid * mid * m0
    return m0, first, second, mc


def _links(x, w, gamma):
    """NumPy twin of :func:`prbdm.model.links_from_gamma` (nondimensional): dict of cuts (...,
    n+2), length (..., n+1), mass, com, inertia, mean_half_width, tributary_compliance (..., n).

    The cumulative integrals are evaluated once at the 2n + 1 distinct points (the cuts and the
    centres of links 1..n-1); links and tributary spans are differences of them."""
    n = gamma.shape[-1] - 1
    inner = np.cumsum(gamma[..., :-1], axis=-1)
    zero = np.zeros_like(inner[..., :1])
    cuts = np.concatenate([zero, inner, zero + 1.0], axis=-1)          # (B, n+2)
    mids = (cuts[..., 2:-1] + cuts[..., 1:-2]) / 2                      # centres of links 1..n-1
    # the mass moments at the cuts, the compliance at the link centres and the free end
    m0, m1, m2 = (f[:, 1:] - f[:, :-1] for f in _cumulative(x, w, cuts[:, 1:], (0, 1, 2)))
    mid = (cuts[:, 2:] + cuts[:, 1:-1]) / 2
    first = m1 - mid * m0
    second = m2 - 2 * mid * m1 + mid * mid * m0
    # tributary spans: [0, c_1], [c_1, c_2], ..., [c_{n-1}, 1] with c_j the centre of link j
    (fc,) = _cumulative(x, w, np.concatenate([mids, cuts[:, -1:]], -1), (3,))
    ends = fc                                                           # c_1..c_{n-1}, then 1
    starts = np.concatenate([np.zeros_like(fc[:, :1]), fc[:, :-1]], -1)  # 0, then c_1..c_{n-1}
    length = cuts[..., 1:] - cuts[..., :-1]
    lj = length[..., 1:]
    return {"cuts": cuts, "length": length, "mass": m0, "com": lj / 2 + first / m0,
            "inertia": second - first ** 2 / m0, "mean_half_width": m0 / (2 * lj),
            "tributary_compliance": ends - starts}


def _mass_matrix(links, theta):
    """NumPy twin of :func:`prbdm.model.mass_matrix` for poses theta (m, n): (..., m, n, n)."""
    n = theta.shape[-1]
    q = np.cumsum(theta, axis=-1)                                        # (m, n)
    e = np.stack([np.cos(q), np.sin(q)], axis=-1)                        # (m, n, 2)
    ell = links["length"][..., None, 1:-1, None]                         # (..., 1, n-1, 1)
    steps = np.cumsum(ell * e[:, :-1, :], axis=-2)                       # (..., m, n-1, 2)
    pad = np.zeros(steps.shape[:-2] + (1, 2))
    steps = np.concatenate([pad, steps], axis=-2)                        # (..., m, n, 2)
    x1 = links["cuts"][..., 1]
    p1 = np.stack([x1, np.zeros_like(x1)], axis=-1)[..., None, None, :]
    p = p1 + steps
    rc = p + links["com"][..., None, :, None] * e                        # (..., m, n, 2)
    lower = np.tril(np.ones((n, n)))                                     # [j, k]: k <= j
    d = (rc[..., :, None, :] - p[..., None, :, :]) * lower[..., None]    # (..., m, j, k, 2)
    md = links["mass"][..., None, :, None, None] * d
    # M_kl = sum_j,d m_j d_jkd d_jld as one batched matrix product over (j, d)
    shape = d.shape[:-3] + (n, 2 * n)
    a = np.swapaxes(md, -3, -2).reshape(shape)
    M = a @ np.swapaxes(np.swapaxes(d, -3, -2).reshape(shape), -1, -2)
    tail = np.flip(np.cumsum(np.flip(links["inertia"], -1), -1), -1)
    idx = np.maximum(np.arange(n)[:, None], np.arange(n)[None, :])
    return M + tail[..., idx][..., None, :, :]


def _straight_generators(links):
    """Generators of M at theta = 0: ``M_kl = u_L + p_K v_L`` with ``K = min(k, l)``,
    ``L = max(k, l)`` (a semiseparable matrix). Every link lies on the x axis, so
    M_kl = sum_{j >= max(k,l)} m_j (c_j - p_k)(c_j - p_l) + J_j, with c_j the centres and p_k the
    joints, is a combination of suffix sums of m_j, m_j c_j, m_j c_j^2 and J_j."""
    def suffix(v):
        return np.flip(np.cumsum(np.flip(v, -1), -1), -1)

    m = links["mass"]
    p = links["cuts"][..., 1:-1]
    c = p + links["com"]
    t0, t1, t2 = suffix(m), suffix(m * c), suffix(m * c * c)
    tj = suffix(links["inertia"])
    return t2 + tj - p * t1, p, p * t0 - t1


def _straight_mass_matrix(links):
    """M at theta = 0 (..., n, n) in O(n^2) from its generators."""
    u, p, v = _straight_generators(links)
    n = u.shape[-1]
    hi = np.maximum.outer(np.arange(n), np.arange(n))
    lo = np.minimum.outer(np.arange(n), np.arange(n))
    return u[..., hi] + p[..., lo] * v[..., hi]


def _straight_projected_mass(links, V):
    """``V^T M V`` (..., q, q) at theta = 0 in O(n q^2), without forming M: with the generators,
    sum_{k <= l} V_k M_kl = u_l S0_l + v_l S1_l for the prefix sums S0 of V and S1 of p V."""
    u, p, v = _straight_generators(links)
    S0 = np.cumsum(V, axis=-2)
    S1 = np.cumsum(p[..., None] * V, axis=-2)
    incl = u[..., None] * S0 + v[..., None] * S1                          # k <= l
    strict = incl - (u + p * v)[..., None] * V                            # k < l
    return np.swapaxes(incl, -1, -2) @ V + np.swapaxes(V, -1, -2) @ strict


def prbdm_eigenvalues(x, w, gamma, poses, with_links: bool = False):
    """Nondimensional PRBDM eigenvalues with every SCF 1 and the ``beam`` law, (..., m, n)
    ascending: the NumPy twin of :func:`prbdm.model.eigenvalues_unit_k`. Multiply by ``k_i`` and
    by ``lambda0`` for SI values. x, w (..., S) / L; gamma (..., n+1); poses (m, n) [rad]."""
    links = _links(x, w, gamma)
    s = 1.0 / (6.0 * links["tributary_compliance"])                      # (..., n)
    M = _mass_matrix(links, np.asarray(poses, dtype=np.float64))
    d = (1.0 / np.sqrt(s))[..., None, :]
    A = d[..., :, None] * M * d[..., None, :]
    mu = np.linalg.eigvalsh(A)
    lam = np.flip(1.0 / mu, -1)
    return (lam, links) if with_links else lam


def link_table(batch: BeamBatch, gamma, k=None) -> dict:
    """SI link table of each beam's PRBDM: ``joint_x`` [m] (joints 1..n), ``length`` [m] (links
    0..n); for links 1..n ``mass`` [kg], ``com`` [m from the joint], ``inertia`` [kg m^2] about the
    centre of mass, ``area_moment`` [m^4]; ``base_stiffness`` s_j [N m/rad] (``beam`` law) and,
    with ``k`` (B, m), ``stiffness`` k_i s_j [N m/rad] per pose (B, m, n)."""
    gamma = np.asarray(gamma, dtype=np.float64)
    lk = _links(batch.x, batch.w, gamma)
    L, t, rho, E = (v[:, None] for v in (batch.length, batch.thickness, batch.rho, batch.E))
    s = E * t ** 3 / (6.0 * lk["tributary_compliance"])
    out = {"joint_x": lk["cuts"][..., 1:-1] * L, "length": lk["length"] * L,
           "mass": lk["mass"] * rho * t * L ** 2, "com": lk["com"] * L,
           "inertia": lk["inertia"] * rho * t * L ** 4,
           "area_moment": 2 * lk["mean_half_width"] * L * t ** 3 / 12, "base_stiffness": s}
    if k is not None:
        out["stiffness"] = np.asarray(k, dtype=np.float64)[:, :, None] * s[:, None, :]
    return out


def _uniform_gamma(n: int) -> np.ndarray:
    g = np.ones(n + 1)
    g[0] = g[-1] = 0.5
    return g / n


def _rfe_straight(batch_x, w, n: int):
    """Links of the n-joint rigid-finite-element chain and its diagonal joint stiffness."""
    gamma = np.broadcast_to(_uniform_gamma(n), (len(batch_x), n + 1))
    links = _links(batch_x, w, gamma)
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
        A = d[..., :, None] * _straight_mass_matrix(links) * d[..., None, :]
        lam = 1.0 / np.linalg.eigvalsh(A)[:, ::-1][:, :modes]
        return 0.5 * np.log(lam)
    nc = coarse - 1
    q = min(nc, modes + 3)
    if modes > nc:
        raise BadInput(f"rfe_coarse: at least rfe_modes + 1 = {modes + 1} links, got {coarse}")
    links_c, kc = _rfe_straight(batch.x, batch.w, nc)
    d = 1.0 / np.sqrt(kc)
    A = d[..., :, None] * _straight_mass_matrix(links_c) * d[..., None, :]
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
    Mr = _straight_projected_mass(links_f, V)
    Li = np.linalg.inv(np.linalg.cholesky(Kr))
    mu = np.linalg.eigvalsh(Li @ Mr @ np.swapaxes(Li, -1, -2))
    return 0.5 * np.log(1.0 / mu[:, ::-1][:, :modes])


# ============================================================================ 3. features
#: beams per piece in features() and Surrogate.forward(): bounds the memory of large batches
CHUNK = 2048
#: beams per piece (at most) in Surrogate.predict; the pieces are spread over threads
PIECE = 1024


def _concatenate_outputs(parts: list) -> dict:
    """Decoded outputs of consecutive pieces of a batch, joined along the beams (None stays
    None: those outputs need the geometry, which none of the pieces had)."""
    return {key: (None if parts[0][key] is None
                  else np.concatenate([part[key] for part in parts])) for key in parts[0]}


def default_threads() -> int:
    """Threads for batched prediction: ``$PRBDM_THREADS`` if set, else the usable cores."""
    env = os.environ.get("PRBDM_THREADS")
    if env:
        try:
            return max(1, int(env))
        except ValueError:
            raise BadInput(f"PRBDM_THREADS: must be an integer >= 1, got {env!r}") from None
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:          # not on Linux
        return os.cpu_count() or 1

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


# ============================================================================ 4. the network
def _silu(v):
    return v / (1.0 + np.exp(-v))


def gamma_from_logits_np(logits, g_min: float = GAMMA_MIN):
    z = logits - logits.max(-1, keepdims=True)
    e = np.exp(z)
    n1 = logits.shape[-1]
    return g_min + (1.0 - n1 * g_min) * e / e.sum(-1, keepdims=True)


K_MODES = ("projection", "direct")
#: the poses on which a checkpoint without ``network.select_poses`` (format 1) compares its
#: candidate segmentations: the first and last of the set
SELECT_POSES = [0, -1]


def gauss_select_poses(m: int) -> list:
    """Indices of the poses on which candidates are compared, for a set of m poses: the two
    nearest the 2-point Gauss-Legendre nodes of the pose index range (m = 6: poses 1 and 4). The
    choice estimates the mean loss over the poses, which two Gauss nodes integrate far better
    than the end points (docs/surrogate.md §2)."""
    if m <= 2:
        return list(range(m))
    c = (m - 1) / 2
    return sorted({int(round(c - c / math.sqrt(3))), int(round(c + c / math.sqrt(3)))})
#: scale of the k head in ``projection`` mode: an output of 1 changes k by a factor e^0.01
K_DELTA_SCALE = 0.01


def _project_k(mu, lam_pred):
    """Least-squares SCF per pose, <mu_i, lam> / <mu_i, mu_i> (> 0 for positive vectors)."""
    return (mu * lam_pred[..., None, :]).sum(-1) / (mu * mu).sum(-1)


def _candidate_losses(mu, lam):
    """Loss [%] (SPEC §3) of each candidate's PRBDM with its least-squares SCFs against ``lam``:
    mu (B, H, m, r), lam (B, r) -> k (B, H, m), loss (B, H). Works for NumPy and torch."""
    lam_c = lam[:, None, :]
    k = _project_k(mu, lam_c)
    res = k[..., None] * mu - lam_c[..., None, :]
    if isinstance(mu, np.ndarray):
        rel = np.linalg.norm(res, axis=-1) / np.linalg.norm(lam_c, axis=-1)[..., None]
    else:
        rel = res.norm(dim=-1) / lam_c.norm(dim=-1)[..., None]
    return k, 100.0 * rel.mean(-1)


def decode_numpy(out, norm: dict, joints: int, k_mode: str, rfe, x=None, w=None, poses=None,
                 r=None, hypotheses: int = 1, select_poses=SELECT_POSES) -> dict:
    """The network's raw head ``out`` (B, H (n+1) + m + R) -> a dict of gamma (B, n+1), logk
    (B, m), log_omega_hat (B, R), mu (B, m, n) unit-k PRBDM eigenvalues, and with H > 1 the
    candidates ``gamma_all`` (B, H, n+1) and the chosen one ``select`` (B,).

    - ``gamma = g_min + (1 - (n+1) g_min) softmax(logits)``: on the bounded simplex, for each of
      the H candidate segmentations (``hypotheses``);
    - ``log omega_hat = log_omega_rfe + out[:, -R:] * freq_std + freq_mean``: the truth
      frequencies / sqrt(E t^2 / (rho L^4)), as a correction of the rigid-finite-element estimate;
    - ``k``, per pose, in one of two ways (``k_mode``):
      ``direct``: ``log k = out * logk_std + logk_mean`` (H = 1 only);
      ``projection``: the least-squares SCF that matches the PRBDM's unit-k eigenvalues
      ``mu_i(gamma)`` to the network's own predicted truth eigenvalues ``omega_hat^2`` (the same
      variable projection as the fit, SPEC §3, with the prediction in place of the truth), times
      ``exp(K_DELTA_SCALE * out)``. It needs the geometry (x, w / L), the poses and r.
    - with H > 1 candidates, the one kept is the one whose PRBDM best matches the predicted truth
      frequencies (the SPEC §3 loss against ``omega_hat``, on the poses ``select_poses`` of the
      set): the network proposes, the physics chooses. Without geometry, candidate 0 is
      returned and logk is None.
    Every output is valid by construction: k > 0 because mu > 0 and omega_hat > 0.
    """
    n1 = joints + 1
    H = hypotheses
    m = len(norm["logk_mean"])
    B = out.shape[0]
    gamma_all = gamma_from_logits_np(out[:, :H * n1].reshape(B, H, n1))
    kh = out[:, H * n1:H * n1 + m]
    log_omega_hat = rfe + out[:, H * n1 + m:] * norm["freq_std"] + norm["freq_mean"]
    res = {"gamma": gamma_all[:, 0], "logk": None, "log_omega_hat": log_omega_hat, "mu": None,
           "gamma_all": gamma_all, "select": np.zeros(B, dtype=np.int64), "candidate_loss": None}
    if k_mode == "direct":
        res["logk"] = kh * norm["logk_std"] + norm["logk_mean"]
    elif x is not None:
        lam_p = np.exp(2 * log_omega_hat[:, :r])
        rows = np.arange(B)
        sel = np.zeros(B, dtype=np.int64)
        if H > 1:       # choose on a few poses (cheap), then solve the kept one on the others
            select_poses = [int(i) % len(poses) for i in select_poses]
            mu_all = prbdm_eigenvalues(np.repeat(x, H, 0), np.repeat(w, H, 0),
                                       gamma_all.reshape(B * H, n1), poses[select_poses])
            mu_all = mu_all.reshape(B, H, *mu_all.shape[1:])
            res["candidate_loss"] = _candidate_losses(mu_all[..., :r], lam_p)[1]
            sel = np.argmin(res["candidate_loss"], axis=1)
            gamma = gamma_all[rows, sel]
            rest = [i for i in range(len(poses)) if i not in select_poses]
            mu = np.empty((B, len(poses), joints))
            mu[:, select_poses] = mu_all[rows, sel]
            if rest:
                mu[:, rest] = prbdm_eigenvalues(x, w, gamma, poses[rest])
        else:
            gamma = gamma_all[rows, sel]
            mu = prbdm_eigenvalues(x, w, gamma, poses)
        kp = _project_k(mu[..., :r], lam_p)
        res.update(gamma=gamma, mu=mu, select=sel, logk=np.log(kp) + K_DELTA_SCALE * kh)
    return res


def combine_members(outs: list, hypotheses: int, joints: int):
    """One head output from the heads of an ensemble's members (each (B, H (n+1) + m + R)):
    every member's H candidate segmentations side by side (M H candidates; the physics chooses
    among all of them), the mean k correction and the mean frequency correction (averaging
    independent networks' frequency predictions lowers their error). NumPy or torch."""
    if len(outs) == 1:
        return outs[0]
    c = hypotheses * (joints + 1)
    if isinstance(outs[0], np.ndarray):
        return np.concatenate([o[:, :c] for o in outs]
                              + [np.mean([o[:, c:] for o in outs], axis=0)], axis=1)
    import torch
    return torch.cat([o[:, :c] for o in outs] + [torch.stack([o[:, c:] for o in outs]).mean(0)],
                     dim=1)


def decode_torch(out, norm: dict, joints: int, m: int, k_mode: str, rfe, x=None, w=None,
                 poses=None, r=None, hypotheses: int = 1, select_poses=None) -> dict:
    """Torch twin of :func:`decode_numpy` (differentiable; eigenvalues in float64). Also returns
    ``mu_all`` (B, H, m, n) for the training losses. By default (``select_poses=None``) the
    candidates are compared on every pose (all are solved for the training losses anyway): the
    rule that the Gauss poses of :func:`decode_numpy` approximate at a third of the cost."""
    import torch

    from . import model

    n1 = joints + 1
    H = hypotheses
    B = out.shape[0]
    gamma_all = GAMMA_MIN + (1 - n1 * GAMMA_MIN) * torch.softmax(
        out[:, :H * n1].reshape(B, H, n1), -1)
    kh = out[:, H * n1:H * n1 + m]
    log_omega_hat = rfe + out[:, H * n1 + m:] * norm["freq_std"] + norm["freq_mean"]
    res = {"gamma": gamma_all[:, 0], "logk": None, "log_omega_hat": log_omega_hat, "mu": None,
           "mu_all": None, "gamma_all": gamma_all,
           "select": torch.zeros(B, dtype=torch.long)}
    if k_mode == "direct":
        res["logk"] = kh * norm["logk_std"] + norm["logk_mean"]
    elif x is not None:
        ones = torch.ones(B, 1, dtype=torch.float64)
        bt = model.BeamTensors(x[:, None], w[:, None], ones, ones, ones, ones)
        mu_all = model.eigenvalues_unit_k(bt, gamma_all.double(), poses, "beam")
        lam_p = torch.exp(2 * log_omega_hat[:, :r].double())
        rows = torch.arange(B)
        # the choice on every pose, as the loss itself (the first and last poses alone chose a
        # worse candidate for many beams: docs/surrogate.md §5)
        on = mu_all if select_poses is None else mu_all[:, :, select_poses]
        sel = _candidate_losses(on[..., :r], lam_p)[1].detach().argmin(1)
        mu = mu_all[rows, sel]
        kp = _project_k(mu[..., :r], lam_p)
        res.update(gamma=gamma_all[rows, sel], mu=mu, mu_all=mu_all, select=sel,
                   logk=torch.log(kp) + K_DELTA_SCALE * kh.double())
    return res


def _torch_net_class():
    import torch
    from torch import nn

    class SurrogateNet(nn.Module):
        """MLP on standardised features -> (gamma logits, k head, standardised frequency
        correction). :meth:`outputs` maps them to valid gamma, k > 0 and log omega_hat (see
        :func:`decode_numpy`).

        layers: ``depth`` hidden Linear + SiLU layers of ``width`` units, then one linear head
        of H (n + 1) + m + R outputs (H candidate segmentations, ``hypotheses``)."""

        def __init__(self, n_in: int, joints: int, poses: int, modes: int, width: int = 256,
                     depth: int = 3, k_mode: str = "projection", hypotheses: int = 1):
            super().__init__()
            if k_mode not in K_MODES:
                raise BadInput(f"k_mode: must be one of {', '.join(K_MODES)}, got {k_mode!r}")
            if hypotheses > 1 and k_mode == "direct":
                raise BadInput("hypotheses > 1 needs k_mode 'projection'")
            self.joints, self.n_poses, self.modes, self.k_mode = joints, poses, modes, k_mode
            self.hypotheses = hypotheses
            dims = [n_in] + [width] * depth
            self.hidden = nn.ModuleList(nn.Linear(a, b) for a, b in zip(dims[:-1], dims[1:]))
            self.head = nn.Linear(width, hypotheses * (joints + 1) + poses + modes)

        def forward(self, f):
            h = f
            for layer in self.hidden:
                h = torch.nn.functional.silu(layer(h))
            return self.head(h)

        def outputs(self, f, norm: dict, rfe, x=None, w=None, poses=None, r=None,
                    select_poses=None) -> dict:
            """Decoded outputs for standardised features ``f`` (B, F), see
            :func:`decode_torch`: gamma (B, n+1), logk (B, m), log_omega_hat (B, R), mu
            (B, m, n) unit-k PRBDM eigenvalues (float64; None for ``k_mode = 'direct'``), ...
            ``norm``: torch tensors of the normalisation; ``rfe`` (B, R) the log_omega_rfe
            features; x, w (B, S) / L, poses (m, n) and the mapped mode count r are needed by
            ``k_mode = 'projection'``; candidates are compared on ``select_poses`` (all: None)."""
            return decode_torch(self(f), norm, self.joints, self.n_poses, self.k_mode, rfe, x, w,
                                poses, r, self.hypotheses, select_poses)

        def weights(self) -> dict:
            """The weights as the checkpoint stores them: layers.{i}.weight/bias, NumPy float32."""
            out = {}
            for i, layer in enumerate([*self.hidden, self.head]):
                out[f"layers.{i}.weight"] = layer.weight.detach().cpu().numpy().astype(np.float32)
                out[f"layers.{i}.bias"] = layer.bias.detach().cpu().numpy().astype(np.float32)
            return out

        def load_weights(self, weights: dict):
            import torch as _t
            for i, layer in enumerate([*self.hidden, self.head]):
                layer.weight.data.copy_(_t.as_tensor(weights[f"layers.{i}.weight"]))
                layer.bias.data.copy_(_t.as_tensor(weights[f"layers.{i}.bias"]))
            return self

    class SurrogateEnsemble(nn.Module):
        """Several :class:`SurrogateNet` members as one network: their candidates side by side
        and their k and frequency corrections averaged (:func:`combine_members`)."""

        def __init__(self, members):
            super().__init__()
            self.members = nn.ModuleList(members)
            first = members[0]
            self.joints, self.n_poses, self.modes = first.joints, first.n_poses, first.modes
            self.k_mode, self.member_hypotheses = first.k_mode, first.hypotheses
            self.hypotheses = first.hypotheses * len(members)

        def forward(self, f):
            return combine_members([net(f) for net in self.members], self.member_hypotheses,
                                   self.joints)

        def outputs(self, f, norm: dict, rfe, x=None, w=None, poses=None, r=None,
                    select_poses=None) -> dict:
            return decode_torch(self(f), norm, self.joints, self.n_poses, self.k_mode, rfe, x, w,
                                poses, r, self.hypotheses, select_poses)

        def weights(self) -> dict:
            """members.{j}.layers.{i}.weight/bias, NumPy float32."""
            return {f"members.{j}.{k}": v for j, net in enumerate(self.members)
                    for k, v in net.weights().items()}

    return SurrogateNet, SurrogateEnsemble


_NET = None


def __getattr__(name):
    # SurrogateNet is a torch module: built on first use, so that importing this module (and
    # ``prbdm predict``) never imports torch
    global _NET
    if name in ("SurrogateNet", "SurrogateEnsemble"):
        if _NET is None:
            _NET = _torch_net_class()
        return _NET[name == "SurrogateEnsemble"]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


# ============================================================================ 5. checkpoints
def dataset_hash(table) -> str:
    """sha256 of a data set's records that training uses, sorted by index: ``index``, ``x``,
    ``half_width``, ``thickness``, ``omega_truth``, ``gamma``, ``k`` (float64 values and the list
    lengths, little-endian). Equal hashes mean equal training data."""
    if hasattr(table, "to_pandas"):
        table = table.to_pandas()
    table = table.sort_values("index")
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(table["index"].to_numpy(), dtype="<i8").tobytes())
    for col in ("x", "half_width", "thickness", "omega_truth", "gamma", "k"):
        vals = table[col].to_list()
        if isinstance(vals[0], (list, tuple, np.ndarray)):
            h.update(np.array([len(v) for v in vals], dtype="<i8").tobytes())
            flat = np.concatenate([np.asarray(v, dtype=np.float64) for v in vals])
        else:
            flat = np.asarray(vals, dtype=np.float64)
        h.update(col.encode())
        h.update(np.ascontiguousarray(flat, dtype="<f8").tobytes())
    return h.hexdigest()


def save_checkpoint(path, weights: dict, metadata: dict) -> Path:
    """Write ``weights`` (name -> NumPy array) and ``metadata`` (JSON-able) as one safetensors
    file (metadata in its header, key ``prbdm``), and a readable copy ``PATH`` with ``.json``."""
    from safetensors.numpy import save_file

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    meta = {"format": CHECKPOINT_FORMAT, "format_version": CHECKPOINT_VERSION, **metadata}
    text = json.dumps(meta, allow_nan=False)
    tmp = path.with_name(f".{path.name}.tmp")
    save_file({k: np.ascontiguousarray(v) for k, v in weights.items()}, str(tmp),
              metadata={"prbdm": text})
    os.chmod(tmp, 0o644)
    os.replace(tmp, path)
    path.with_suffix(".json").write_text(json.dumps(meta, indent=1, allow_nan=False) + "\n")
    return path


_DTYPES = {"F32": np.float32, "F64": np.float64, "F16": np.float16, "I64": np.int64,
           "I32": np.int32}


def _read_safetensors(path: Path):
    """(tensors, metadata) of a safetensors file: an 8-byte header length, a JSON header, raw
    little-endian arrays. Parsed here with the standard library and NumPy only (no pickle, no
    code execution; no torch)."""
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise BadInput(f"checkpoint: cannot read {str(path)!r} ({exc.strerror})") from None
    bad = BadInput(f"checkpoint: {str(path)!r} is not a safetensors file")
    if len(data) < 8:
        raise bad
    (n,) = struct.unpack("<Q", data[:8])
    if n > len(data) - 8:
        raise bad
    try:
        header = json.loads(data[8:8 + n])
    except (UnicodeDecodeError, json.JSONDecodeError):
        raise bad from None
    if not isinstance(header, dict):
        raise bad
    meta = header.pop("__metadata__", {}) or {}
    body = memoryview(data)[8 + n:]
    tensors = {}
    for name, info in header.items():
        try:
            dtype = np.dtype(_DTYPES[info["dtype"]]).newbyteorder("<")
            start, stop = info["data_offsets"]
            arr = np.frombuffer(body[start:stop], dtype=dtype).reshape(info["shape"])
        except (KeyError, TypeError, ValueError):
            raise bad from None
        tensors[name] = arr.astype(arr.dtype.newbyteorder("="))
    return tensors, meta


def load_checkpoint(path) -> "Surrogate":
    """Load a surrogate checkpoint (a ``.safetensors`` file written by :func:`save_checkpoint`).

    Raises :class:`BadInput` naming the problem for a missing, corrupt or foreign file."""
    path = Path(path)
    if not path.is_file():
        raise BadInput(f"checkpoint: no such file {str(path)!r}")
    tensors, meta = _read_safetensors(path)
    try:
        metadata = json.loads(meta["prbdm"])
    except (KeyError, TypeError, json.JSONDecodeError):
        raise BadInput(f"checkpoint: {str(path)!r} has no prbdm surrogate metadata") from None
    if metadata.get("format") != CHECKPOINT_FORMAT:
        raise BadInput(f"checkpoint: {str(path)!r} is not a prbdm surrogate checkpoint")
    if metadata.get("format_version", 0) > CHECKPOINT_VERSION:
        raise BadInput(f"checkpoint: format version {metadata['format_version']} is newer than "
                       f"this prbdm understands ({CHECKPOINT_VERSION}); upgrade prbdm")
    return Surrogate(tensors, metadata, path)


def _checkpoint_dirs() -> list[Path]:
    dirs = [Path(p) for p in os.environ.get("PRBDM_CHECKPOINTS", "").split(os.pathsep) if p]
    return dirs + [PACKAGE_CHECKPOINTS]


def checkpoint_name(joints: int, truth: str) -> str:
    return f"{truth}-n{joints}.safetensors"


def available_checkpoints() -> list[Path]:
    """Every default checkpoint found (``TRUTH-nJOINTS.safetensors`` in the checkpoint folders)."""
    found = []
    for d in _checkpoint_dirs():
        found += sorted(d.glob("*-n*.safetensors")) if d.is_dir() else []
    return found


def default_checkpoint(joints: int, truth: str = "beam") -> Path:
    """The default checkpoint for ``joints`` joints and the ``truth`` model: the first
    ``TRUTH-nJOINTS.safetensors`` in $PRBDM_CHECKPOINTS (folders separated by os.pathsep), then in
    the shipped ``checkpoints/``. BadInput listing what exists when there is none."""
    name = checkpoint_name(joints, truth)
    for d in _checkpoint_dirs():
        if (d / name).is_file():
            return d / name
    have = ", ".join(p.stem for p in available_checkpoints()) or "none"
    raise BadInput(f"--joints {joints} --truth {truth}: no trained surrogate checkpoint "
                   f"{name!r} (available: {have}); train one with training/train_surrogate.py "
                   "or pass --checkpoint PATH")


# ============================================================================ 6. prediction
@dataclass
class Prediction:
    """What :meth:`Surrogate.predict` returns for B beams.

    gamma (B, n+1); k (B, m); log_omega_hat (B, R): the network's direct prediction of the truth
    frequencies in nondimensional form, log(omega / sqrt(E t^2 / (rho L^4))); with beams:
    omega_truth (B, R) [rad/s] (the same, in SI) and, when asked, omega (B, m, n) [rad/s], the
    PRBDM's own frequencies per pose; poses (m, n) [rad]; law; ood: (B, F) bool, True where a
    feature lies outside its training range (with the margin); warnings: one text per beam and
    offending feature (at most 20 listed); time_s: wall time of the prediction; extra:
    ``gamma_candidates`` (B, H, n+1), ``selected`` (B,) and ``candidate_loss`` (B, H) (each
    candidate's SPEC §3 loss [%] against the predicted truth frequencies, on the choice poses)
    for a network with H > 1 candidates; see :meth:`ranked_candidates`.

    From features alone (no geometry) only log_omega_hat is complete: k (``projection`` mode)
    and the choice among several candidate gammas need the beam's PRBDM, so they are None (with
    one candidate, gamma is given).
    """

    gamma: np.ndarray | None
    k: np.ndarray | None
    log_omega_hat: np.ndarray
    poses: np.ndarray
    law: str
    ood: np.ndarray
    warnings: list
    omega_truth: np.ndarray | None = None
    omega: np.ndarray | None = None
    time_s: float = 0.0
    extra: dict = field(default_factory=dict)

    def ranked_candidates(self, count: int | None = None) -> np.ndarray:
        """The candidate segmentations (B, count, n+1), best first by their loss against the
        predicted truth frequencies (the kept ``gamma`` is first): start points for a short
        refinement (:func:`prbdm.fit.refine_starts`). One candidate: ``gamma`` (B, 1, n+1)."""
        cand, loss = self.extra.get("gamma_candidates"), self.extra.get("candidate_loss")
        if cand is None or loss is None:
            return self.gamma[:, None, :]
        order = np.argsort(loss, axis=1, kind="stable")[:, :count]
        return np.take_along_axis(cand, order[..., None], axis=1)


class Surrogate:
    """A loaded checkpoint: NumPy weights, metadata, and :meth:`predict`."""

    def __init__(self, tensors: dict, metadata: dict, path: Path | None = None):
        self.metadata = metadata
        self.path = path
        try:
            self.joints = int(metadata["joints"])
            self.truth = str(metadata["truth"])
            self.law = str(metadata["law"])
            self.poses = np.asarray(metadata["poses"], dtype=np.float64)
            self.modes = int(metadata["modes"])
            self.feature_spec = FeatureSpec(**metadata["features"]["spec"])
            self.norm = {k: np.asarray(v, dtype=np.float64)
                         for k, v in metadata["normalisation"].items()}
            self.f_mean, self.f_std = self.norm["feature_mean"], self.norm["feature_std"]
            self.k_mode = str(metadata["network"].get("k_mode", "direct"))
            net = metadata["network"]
            self.member_hypotheses = int(net.get("hypotheses", 1))
            self.n_members = int(net.get("members", 1))
            self.hypotheses = self.member_hypotheses * self.n_members   # candidates in all
            self.select_poses = [int(i) for i in net.get("select_poses", SELECT_POSES)]
            self.f_min = np.asarray(metadata["features"]["min"], dtype=np.float64)
            self.f_max = np.asarray(metadata["features"]["max"], dtype=np.float64)
            self.names = list(metadata["features"]["names"])
            prefixes = ([""] if self.n_members == 1 else
                        [f"members.{j}." for j in range(self.n_members)])
            self.members = []
            for pre in prefixes:
                n_layers = len([k for k in tensors
                                if k.startswith(pre + "layers.") and k.endswith(".weight")])
                self.members.append(
                    [(np.ascontiguousarray(tensors[f"{pre}layers.{i}.weight"], np.float32),
                      np.ascontiguousarray(tensors[f"{pre}layers.{i}.bias"], np.float32))
                     for i in range(n_layers)])
            self.layers = self.members[0]
        except (KeyError, TypeError, ValueError) as exc:
            where = f" {str(path)!r}" if path else ""
            raise BadInput(f"checkpoint{where}: incomplete surrogate metadata or weights "
                           f"({type(exc).__name__}: {exc})") from None
        if self.law != "beam":
            raise BadInput(f"checkpoint: law {self.law!r} is not supported by the NumPy PRBDM "
                           "(only 'beam')")
        if self.k_mode not in K_MODES:
            raise BadInput(f"checkpoint: unknown k_mode {self.k_mode!r}")
        if self.poses.shape != (len(self.norm["logk_mean"]), self.joints):
            raise BadInput("checkpoint: poses and SCF normalisation disagree")

    @property
    def name(self) -> str:
        return self.path.name if self.path else "<in memory>"

    def describe(self) -> dict:
        """A short summary for command output: path, name, truth, joints, data set size."""
        ds = self.metadata.get("dataset", {})
        return {"path": str(self.path) if self.path else None, "name": self.name,
                "truth": self.truth, "joints": self.joints, "modes": self.modes, "law": self.law,
                "dataset_size": ds.get("size"), "dataset_sha256": ds.get("sha256"),
                "training_mode": self.metadata.get("training", {}).get("selected_mode")}

    # ---------------------------------------------------------------- the network in NumPy
    def features(self, beams) -> np.ndarray:
        batch = beams if isinstance(beams, BeamBatch) else BeamBatch.from_beams(beams)
        return features(batch, self.feature_spec)

    def with_members(self, count: int) -> "Surrogate":
        """The same checkpoint using only its first ``count`` ensemble members: fewer candidates
        to compare, faster, less accurate (docs/surrogate.md §5 measures both)."""
        if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or \
                not 1 <= count <= self.n_members:
            raise BadInput(f"members: must be an integer in [1, {self.n_members}], got {count!r}")
        other = copy.copy(self)
        other.members = self.members[:count]
        other.n_members = int(count)
        other.hypotheses = self.member_hypotheses * other.n_members
        return other

    def forward(self, feats: np.ndarray, batch: "BeamBatch | None" = None) -> dict:
        """The decoded outputs (see :func:`decode_numpy`: gamma, logk, log_omega_hat, mu, ...)
        from raw features (B, F). In ``projection`` k mode, k needs the beams (``batch``);
        without them logk and mu are None (and, with several candidates, gamma is the first)."""
        # the MLP in float32 (its weights are float32): twice as fast as float64, and its
        # round-off (1e-7) is far below the network's own error
        if feats.shape[0] > CHUNK:  # see features(): bounded pieces
            parts = [self.forward(feats[i:i + CHUNK],
                                  None if batch is None else batch.take(slice(i, i + CHUNK)))
                     for i in range(0, feats.shape[0], CHUNK)]
            return _concatenate_outputs(parts)
        f = ((feats - self.f_mean) / self.f_std).astype(np.float32)
        outs = []
        for layers in self.members:
            h = f
            for W, b in layers[:-1]:
                h = _silu(h @ W.T + b)
            W, b = layers[-1]
            outs.append((h @ W.T + b).astype(np.float64))
        out = combine_members(outs, self.member_hypotheses, self.joints)
        rfe0 = 2 * self.feature_spec.cells
        rfe = feats[:, rfe0:rfe0 + len(self.norm["freq_mean"])]
        x, w = (batch.x, batch.w) if batch is not None else (None, None)
        return decode_numpy(out, self.norm, self.joints, self.k_mode, rfe, x, w, self.poses,
                            self.modes, self.hypotheses, self.select_poses)

    def check_range(self, feats: np.ndarray):
        """(B, F) bool out-of-range mask and the warning texts (at most ``20``)."""
        span = self.f_max - self.f_min
        lo, hi = self.f_min - OOD_MARGIN * span, self.f_max + OOD_MARGIN * span
        bad = (feats < lo) | (feats > hi) | ~np.isfinite(feats)
        texts = []
        for i, j in zip(*np.nonzero(bad)):
            if len(texts) == 20:
                texts.append(f"... {int(bad.sum()) - 20} more out-of-range feature values")
                break
            prefix = f"beam {i}: " if feats.shape[0] > 1 else ""
            texts.append(f"{prefix}feature {self.names[j]} = {feats[i, j]:.4g} lies outside the "
                         f"training range [{self.f_min[j]:.4g}, {self.f_max[j]:.4g}] of checkpoint "
                         f"{self.name}; the prediction is an extrapolation")
        return bad, texts

    def ood_summary(self, bad: np.ndarray, texts: list) -> str:
        """One line for a batch: the offending features by name, and the first case in full."""
        if len(texts) == 1:
            return texts[0]
        cols = np.flatnonzero(bad.any(0))
        names = ", ".join(self.names[j] for j in cols[:12]) + (", ..." if len(cols) > 12 else "")
        return (f"{int(bad.any(1).sum())} of {bad.shape[0]} input(s) outside the training range "
                f"of checkpoint {self.name} in feature(s) {names}; first: {texts[0]}")

    def _features_and_outputs(self, batch: BeamBatch, threads: int | None):
        """features and decoded outputs of a batch of beams, in pieces of at most ``PIECE``
        beams spread over ``threads`` threads (NumPy releases the GIL in its array loops and
        LAPACK calls, so the pieces run side by side on a multi-core machine)."""
        B = len(batch)
        threads = default_threads() if threads is None else max(1, int(threads))
        # the pieces do not depend on the thread count, so neither do the results (the float32
        # MLP's round-off depends on the shape of its matrix products)
        pieces = max(-(-B // PIECE), 1)
        if pieces == 1:
            feats = features(batch, self.feature_spec)
            return feats, self.forward(feats, batch)
        size = -(-B // pieces)
        slices = [slice(i, min(i + size, B)) for i in range(0, B, size)]

        def work(sl):
            part = batch.take(sl)
            f = features(part, self.feature_spec)
            return f, self.forward(f, part)

        if threads > 1:
            from concurrent.futures import ThreadPoolExecutor

            with ThreadPoolExecutor(min(threads, len(slices))) as pool:
                done = list(pool.map(work, slices))
        else:
            done = [work(sl) for sl in slices]
        return (np.concatenate([f for f, _ in done]),
                _concatenate_outputs([d for _, d in done]))

    def predict(self, beams_or_features, frequencies: bool = True, warn: bool = True,
                threads: int | None = None) -> Prediction:
        """Predict for Beam(s), a :class:`BeamBatch`, or a (B, F) feature array.

        With beams: also the truth frequencies in rad/s and, if ``frequencies``, the PRBDM's
        frequencies per pose (B, m, n). Out-of-range features raise one
        :class:`OutOfDistributionWarning` (if ``warn``) and are flagged in ``ood``. Large
        batches run in pieces on ``threads`` threads (default: the usable cores, or
        ``$PRBDM_THREADS``); the result does not depend on the thread count."""
        t0 = time.perf_counter()
        batch = None
        if isinstance(beams_or_features, np.ndarray):
            feats = np.asarray(beams_or_features, dtype=np.float64)
            if feats.ndim == 1:
                feats = feats[None]
            if feats.ndim != 2 or feats.shape[1] != len(self.names):
                raise BadInput(f"features: need shape (B, {len(self.names)}), got "
                               f"{feats.shape}")
        else:
            batch = (beams_or_features if isinstance(beams_or_features, BeamBatch)
                     else BeamBatch.from_beams(beams_or_features))
        if batch is None:
            d = self.forward(feats, None)
        else:
            feats, d = self._features_and_outputs(batch, threads)
        bad, texts = self.check_range(feats)
        if warn and texts:
            warnings.warn(OutOfDistributionWarning(self.ood_summary(bad, texts)), stacklevel=2)
        gamma, logk, low, mu = d["gamma"], d["logk"], d["log_omega_hat"], d["mu"]
        pred = Prediction(gamma=gamma, k=None if logk is None else np.exp(logk),
                          log_omega_hat=low, poses=self.poses, law=self.law, ood=bad,
                          warnings=texts)
        if self.hypotheses > 1:
            pred.extra["gamma_candidates"] = d["gamma_all"]
            if batch is None:       # choosing a candidate needs the PRBDM, i.e. the geometry
                pred.gamma = None
            else:
                pred.extra["selected"] = d["select"]
                pred.extra["candidate_loss"] = d["candidate_loss"]
        if batch is not None:
            sq = np.sqrt(batch.lambda0)[:, None]
            pred.omega_truth = np.exp(low) * sq
            if frequencies:
                if mu is None:
                    mu = prbdm_eigenvalues(batch.x, batch.w, gamma, self.poses)
                pred.omega = np.sqrt(mu * pred.k[:, :, None]) * sq[:, :, None]
        pred.time_s = time.perf_counter() - t0
        return pred


_CACHE: dict = {}


def predict(beams_or_features, joints: int | None = None, truth: str = "beam", checkpoint=None,
            frequencies: bool = True, warn: bool = True, threads: int | None = None
            ) -> Prediction:
    """Batched prediction with a checkpoint: ``checkpoint`` (a path or a loaded
    :class:`Surrogate`), or the default one for (``joints``, ``truth``). See
    :meth:`Surrogate.predict`."""
    if isinstance(checkpoint, Surrogate):
        sur = checkpoint
    else:
        if checkpoint is None:
            if joints is None:
                raise BadInput("joints: give the number of joints or a checkpoint")
            checkpoint = default_checkpoint(joints, truth)
        key = str(Path(checkpoint).resolve())
        sur = _CACHE.get(key)
        if sur is None:
            sur = _CACHE[key] = load_checkpoint(checkpoint)
    if joints is not None and sur.joints != joints:
        raise BadInput(f"--joints {joints}: checkpoint {sur.name} was trained for "
                       f"{sur.joints} joints")
    return sur.predict(beams_or_features, frequencies=frequencies, warn=warn, threads=threads)


def loss_percent_np(omega_or_lam_pose, lam_truth, r: int, is_lambda: bool = True):
    """NumPy twin of :func:`prbdm.model.loss_percent`: (..., m, n) eigenvalues per pose against
    (..., R) truth eigenvalues, first r modes, in percent."""
    lam = omega_or_lam_pose if is_lambda else omega_or_lam_pose ** 2
    ref = lam_truth[..., None, :r]
    rel = np.linalg.norm(lam[..., :r] - ref, axis=-1) / np.linalg.norm(ref, axis=-1)
    return 100.0 * rel.mean(-1)
