"""A cheap, mesh-free estimate of a panel's plate modes: Rayleigh-Ritz on the planform.

Reissner-Mindlin plate (the fields of :mod:`prbdm.truth.mindlin`: deflection ``W`` and rotations
``beta_x``, ``beta_y``), symmetric half, clamped at the root, on the planform itself mapped to a
strip: ``xi = x / L`` in ``[0, 1]`` and ``eta = y / w(x)`` in ``[0, 1]`` (``w`` the half-width,
piecewise linear between the stations). In those coordinates

    d/dx = d/dxi - eta (w' / w) d/deta,   d/dy = (1 / w) d/deta,   dA = w dxi deta,

and every term of the energies is a sum of products of a span-wise integral (weights ``w``,
``w'``, ``w'^2 / w``, ``1 / w``: exact pieces of the planform, no mesh) and a chord-wise one.
Trial functions: span-wise, continuous piecewise polynomials of degree ``degree`` on elements
that end at the planform's stations (no element straddles a kink) and are at most
``max_element`` long, zero at the root; chord-wise, the first ``chord_terms`` even Legendre
polynomials of ``eta`` for ``W`` and ``beta_x`` and odd ones for ``beta_y`` (the symmetric
family). The stiffness and mass matrices are sums of Kronecker products, solved densely.

What it is for: a physical estimate of the symmetric modes and their section fractions
(:mod:`prbdm.truth.modes`; here the chord average of ``W`` is exactly its ``P_0`` part), hence of
the bending spectrum, in milliseconds instead of the FEM's second: the plate networks correct it
(``FeatureSpec.ritz``). What it is not: a truth. A neck narrower than its neighbours bends the
chord-wise field in a way a few polynomials of ``eta`` cannot follow, so on the paper's jagged
panels it reads stiff by a few per cent (measured against ``solve_mindlin``, docs/validation.md);
on a rectangle it converges to the Kirchhoff and Mindlin references (tests/test_planform_ritz.py).
NumPy only: ``prbdm predict`` may run it.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.polynomial import legendre as npleg

from .modes import bending_spectrum

__all__ = ["planform_ritz", "ritz_bending_spectrum", "RITZ_DEFAULTS"]

#: the estimate the plate networks read: span-wise cubic elements at most 0.2 L long, three
#: chord-wise terms per field (~350 unknowns, ~15 ms a panel)
RITZ_DEFAULTS = {"degree": 3, "chord_terms": 3, "max_element": 0.2}
#: Gauss points per element (span) and on the half chord
SPAN_POINTS, CHORD_POINTS = 8, 12
SHEAR_FACTOR = 5.0 / 6.0
#: stations closer than this (in units of the length) are read as a step of the half-width
STEP = 1e-4


def _span_basis(nodes: np.ndarray, degree: int):
    """Quadrature points, weights and the span-wise functions' values and derivatives there:
    hats on the nodes but the root (clamped) and the integrated-Legendre bubbles of each
    element. Returns ``xq (Q,)``, ``wq (Q,)``, ``V (Q, n)``, ``D (Q, n)``."""
    s, ws = npleg.leggauss(SPAN_POINTS)
    E, nb = len(nodes) - 1, degree - 1
    n = E * (1 + nb)
    h = np.diff(nodes)
    xq = (nodes[:-1, None] + 0.5 * h[:, None] * (s + 1.0)).ravel()
    wq = (0.5 * h[:, None] * ws).ravel()
    V = np.zeros((E, SPAN_POINTS, n))
    D = np.zeros((E, SPAN_POINTS, n))
    e = np.arange(E)
    # hat of node e + 1 (column e): rising on element e, falling on element e + 1
    V[e, :, e] = 0.5 * (1.0 + s)
    D[e, :, e] = (1.0 / h)[:, None]
    V[e[1:], :, e[:-1]] = 0.5 * (1.0 - s)
    D[e[1:], :, e[:-1]] = -(1.0 / h[1:])[:, None]
    for m in range(2, degree + 1):
        c = np.zeros(m + 1)
        c[m], c[m - 2] = 1.0, -1.0                     # P_m - P_{m-2}: zero at both ends
        col = E + e * nb + (m - 2)
        V[e, :, col] = npleg.legval(s, c)
        D[e, :, col] = npleg.legval(s, npleg.legder(c))[None, :] * (2.0 / h)[:, None]
    return xq, wq, V.reshape(-1, n), D.reshape(-1, n)


@lru_cache(maxsize=8)
def _chord_basis(terms: int, odd: bool):
    """Legendre polynomials of eta on the half chord [0, 1], even or odd: values, derivatives
    and eta times the derivatives at the Gauss points, with the weights (the same for every
    panel: computed once; read only)."""
    t, wt = npleg.leggauss(2 * CHORD_POINTS)
    eta, we = t[t > 0], wt[t > 0]
    Y, Yd = [], []
    for j in range(terms):
        c = np.zeros(2 * j + 2)
        c[2 * j + int(odd)] = 1.0
        Y.append(npleg.legval(eta, c))
        Yd.append(npleg.legval(eta, npleg.legder(c)))
    Y, Yd = np.stack(Y, 1), np.stack(Yd, 1)
    return {"v": Y, "d": Yd, "ed": eta[:, None] * Yd}, we


# strains as sums of (coefficient, field, span factor, chord factor): span factors v = X,
# d = X', g = (w'/w) X, iw = X / w; chord factors v = Y, d = Y', ed = eta Y'
_KAPPA_XX = [(1, "bx", "d", "v"), (-1, "bx", "g", "ed")]                 # d beta_x / dx
_KAPPA_YY = [(1, "by", "iw", "d")]                                       # d beta_y / dy
_KAPPA_XY = [(1, "bx", "iw", "d"), (1, "by", "d", "v"), (-1, "by", "g", "ed")]
_SHEAR_X = [(1, "W", "d", "v"), (-1, "W", "g", "ed"), (-1, "bx", "v", "v")]   # W_x - beta_x
_SHEAR_Y = [(1, "W", "iw", "d"), (-1, "by", "v", "v")]                        # W_y - beta_y


def _nodes(x: np.ndarray, max_element: float) -> np.ndarray:
    out = [x[0]]
    for a, b in zip(x[:-1], x[1:]):
        if b - a <= 1e-12:
            continue
        m = int(np.ceil((b - a) / max_element - 1e-9))
        out.extend(a + (b - a) * np.arange(1, m + 1) / m)
    return np.asarray(out)


def planform_ritz(x, w, tau: float, nu: float, degree: int = 3, chord_terms: int = 3,
                  max_element: float = 0.2, shear_factor: float = SHEAR_FACTOR):
    """Every symmetric mode of the Ritz basis: ``(lam, section_fraction)``, ascending.

    ``x``, ``w``: the planform's stations and half-widths in units of the length (``x[0] = 0``,
    ``x[-1] = 1``, ``w > 0``); ``tau = t / L``; ``nu`` Poisson's ratio. ``lam`` is the
    nondimensional eigenvalue of :mod:`prbdm.truth.mindlin` (``omega = omega_p sqrt(lam)``,
    ``omega_p = sqrt(D / (rho t)) / L^2``); the Ritz values bound the model's from above, the
    upper ones loosely (only the lowest ~third of them are meaningful)."""
    x, w = np.array(x, dtype=np.float64), np.asarray(w, dtype=np.float64)
    # stations closer than STEP apart are one step of the half-width: an element (or a Gauss
    # point) in a sliver between them would read a slope of ~w / 1e-6 and spoil the estimate
    for i in range(1, len(x)):
        if x[i] - x[i - 1] < STEP:
            x[i] = x[i - 1]
    xq, wq, X, Xd = _span_basis(_nodes(x, max_element), int(degree))
    seg = np.clip(np.searchsorted(x, xq, side="right") - 1, 0, len(x) - 2)
    wx = np.interp(xq, x, w)
    slope = (w[seg + 1] - w[seg]) / (x[seg + 1] - x[seg])
    span = {"v": X, "d": Xd, "g": (slope / wx)[:, None] * X, "iw": X / wx[:, None]}
    weight = wq * wx                                             # dA = w dxi deta
    cache = {}

    def A(a, b):
        if (a, b) not in cache:
            cache[a, b] = (span[a] * weight[:, None]).T @ span[b]
        return cache[a, b]

    even, we = _chord_basis(chord_terms, odd=False)
    odd, _ = _chord_basis(chord_terms, odd=True)
    chord = {"W": even, "bx": even, "by": odd}
    n = X.shape[1] * chord_terms
    at = {"W": slice(0, n), "bx": slice(n, 2 * n), "by": slice(2 * n, 3 * n)}
    K = np.zeros((3 * n, 3 * n))

    def add(P, Q, factor):
        for ca, fa, xa, ya in P:
            for cb, fb, xb, yb in Q:
                By = (chord[fa][ya] * we[:, None]).T @ chord[fb][yb]
                K[at[fa], at[fb]] += factor * ca * cb * np.kron(A(xa, xb), By)

    alpha = 6.0 * shear_factor * (1.0 - nu) / tau ** 2           # shear / bending stiffness
    for P, Q, f in ((_KAPPA_XX, _KAPPA_XX, 1.0), (_KAPPA_YY, _KAPPA_YY, 1.0),
                    (_KAPPA_XX, _KAPPA_YY, nu), (_KAPPA_YY, _KAPPA_XX, nu),
                    (_KAPPA_XY, _KAPPA_XY, 0.5 * (1.0 - nu)),
                    (_SHEAR_X, _SHEAR_X, alpha), (_SHEAR_Y, _SHEAR_Y, alpha)):
        add(P, Q, f)
    Mw = np.kron(A("v", "v"), (even["v"] * we[:, None]).T @ even["v"])
    Mb = np.kron(A("v", "v"), (odd["v"] * we[:, None]).T @ odd["v"])
    r = tau ** 2 / 12.0                                          # rotary inertia
    # K and M scaled to a unit diagonal of K, then K^-1 M's eigenproblem in K's Cholesky factor:
    # mu = 1 / lam, so that the lowest modes are the largest mu, as accurate as the largest
    # eigenvalue of a symmetric matrix is (in M's Cholesky factor they were the smallest of a
    # matrix spanning ~12 decades: 0.4 % apart between two BLAS kernels on the narrower panels)
    d = 1.0 / np.sqrt(np.diag(K))
    Ks = d[:, None] * K * d[None, :]
    Ms = np.zeros_like(K)
    for b_, f, Mb_ in (("W", 1.0, Mw), ("bx", r, Mw), ("by", r, Mb)):
        Ms[at[b_], at[b_]] = f * d[at[b_], None] * Mb_ * d[None, at[b_]]
    Lki = np.linalg.inv(np.linalg.cholesky(Ks))
    mu, U = np.linalg.eigh(Lki @ Ms @ Lki.T)
    lam, U = 1.0 / mu[::-1], U[:, ::-1]
    a = d[at["W"], None] * (Lki[:, at["W"]].T @ U)             # W's coefficients, (n, modes)
    mass_w = np.einsum("ik,ik->k", a, Mw @ a)
    a0 = a.reshape(X.shape[1], chord_terms, -1)[:, 0, :]        # the chord average's (P_0)
    section = np.einsum("ik,ik->k", a0, A("v", "v") @ a0)
    return lam, np.clip(section / mass_w, 0.0, 1.0)


def ritz_bending_spectrum(x, w, tau: float, nu: float, modes: int, **options) -> np.ndarray:
    """The bending spectrum (../SPEC §2.1, :func:`prbdm.truth.modes.bending_spectrum`) of
    :func:`planform_ritz`'s modes: (modes,) nondimensional eigenvalues, ``omega = omega_p
    sqrt(lam)``. Only the lower third of the Ritz modes enter (the rest are too coarse to
    count); should they not hold ``modes`` units of bending, the missing eigenvalues continue
    the last one's ratio to the one below it."""
    lam, frac = planform_ritz(x, w, tau, nu, **{**RITZ_DEFAULTS, **options})
    use = max(len(lam) // 3, 4)
    out, _, _ = bending_spectrum(lam[:use], frac[:use], modes)
    for j in range(len(out)):
        if not np.isfinite(out[j]):
            out[j] = (lam[0] if j == 0 else
                      out[j - 1] * (out[j - 1] / out[j - 2] if j >= 2 else 4.0))
    return out
