"""A mesh-free reference for the plate model: Rayleigh-Ritz on a rectangular cantilever plate.

Kirchhoff plate, clamped on ``x = 0``, free on the other three edges, length ``L`` (span) and
width ``b`` (chord). Lengths are scaled by ``L`` (``xi = x / L`` in ``[0, 1]``,
``eta = 2 y / b`` in ``[-1, 1]``, ``c = b / (2 L)``), so the eigenvalues are
``lambda = (omega L^2 sqrt(rho t / D))^2``, the same nondimensional eigenvalue as
:mod:`prbdm.truth.plate`. Trial functions ``xi^2 P_i(2 xi - 1) P_j(eta)`` (Legendre
polynomials ``P``; the factor ``xi^2`` enforces ``w = w_x = 0`` at the root, the free edges are
natural), ``0 <= i < nx``, ``0 <= j < ny``: the stiffness and mass matrices are Kronecker products
of 1-D Gauss-integrated matrices (exact for these polynomials), solved with
``scipy.linalg.eigh``. Even ``j`` give the modes symmetric about the span axis, odd ``j`` the
antisymmetric (torsional) ones. The Ritz values are upper bounds and decrease monotonically to the
exact ones as the basis grows. No mesh, no finite elements: an independent check of the plate
model, used by the tests and the benchmark (about 0.1 s for ``nx = ny = 16``).
"""
from __future__ import annotations

import numpy as np
from numpy.polynomial import legendre as npleg
from numpy.polynomial import polynomial as nppoly
from scipy.linalg import eigh

__all__ = ["ritz_cantilever_plate"]


def _span_basis(n, pts):
    """Values and first two derivatives of ``xi^2 P_i(2 xi - 1)`` at ``pts`` (shape (3, n, q))."""
    out = np.empty((3, n, pts.size))
    shift = nppoly.Polynomial([-1.0, 2.0])            # 2 xi - 1
    for i in range(n):
        c = np.zeros(i + 1)
        c[i] = 1.0
        p = nppoly.Polynomial(npleg.leg2poly(c))(shift) * nppoly.Polynomial([0.0, 0.0, 1.0])
        out[0, i], out[1, i], out[2, i] = p(pts), p.deriv(1)(pts), p.deriv(2)(pts)
    return out


def _chord_basis(n, pts):
    """Values and first two derivatives (in eta) of ``P_j(eta)`` at ``pts``."""
    out = np.empty((3, n, pts.size))
    for j in range(n):
        c = np.zeros(j + 1)
        c[j] = 1.0
        for d in range(3):
            out[d, j] = npleg.legval(pts, npleg.legder(c, d) if d else c)
    return out


def _gram(f, g, wts):
    return (f * wts) @ g.T


def ritz_cantilever_plate(aspect: float, nu: float = 0.3, nx: int = 14, ny: int = 14,
                          family: str = "all") -> np.ndarray:
    """Ascending frequency parameters ``omega L^2 sqrt(rho t / D)`` of a rectangular cantilever
    plate with span ``L`` (clamped edge at the root) and width ``b``, ``aspect = L / b``.

    ``family``: ``"all"``, ``"symmetric"`` (even in y) or ``"antisymmetric"``.
    """
    if not aspect > 0:
        raise ValueError(f"aspect: must be > 0, got {aspect!r}")
    c = 0.5 / aspect                        # half-width / L
    q = max(nx, ny) + 4                      # Gauss points: exact for degree <= 2q - 1
    gx, wx = npleg.leggauss(q)
    xi, wxi = 0.5 * (gx + 1.0), 0.5 * wx     # [0, 1]
    X = _span_basis(nx, xi)
    Y = _chord_basis(ny, gx)                 # eta in [-1, 1]; d/dy = (1 / c) d/deta
    Y = Y * np.array([1.0, 1.0 / c, 1.0 / c ** 2])[:, None, None]
    wy = wx * c                              # dy = c deta
    A = {(k, l): _gram(X[k], X[l], wxi) for k, l in ((0, 0), (1, 1), (2, 2), (2, 0), (0, 2))}
    B = {(k, l): _gram(Y[k], Y[l], wy) for k, l in ((0, 0), (1, 1), (2, 2), (2, 0), (0, 2))}
    if family == "all":
        keep = np.arange(ny)
    elif family == "symmetric":
        keep = np.arange(0, ny, 2)
    elif family == "antisymmetric":
        keep = np.arange(1, ny, 2)
    else:
        raise ValueError(f"family: must be all, symmetric or antisymmetric, got {family!r}")
    B = {k: v[np.ix_(keep, keep)] for k, v in B.items()}
    K = (np.kron(A[2, 2], B[0, 0]) + np.kron(A[0, 0], B[2, 2])
         + nu * (np.kron(A[2, 0], B[0, 2]) + np.kron(A[0, 2], B[2, 0]))
         + 2.0 * (1.0 - nu) * np.kron(A[1, 1], B[1, 1]))
    M = np.kron(A[0, 0], B[0, 0])
    # symmetric diagonal scaling: the polynomial basis spans many orders of magnitude
    s = 1.0 / np.sqrt(np.diag(M))
    lam = eigh(s[:, None] * K * s[None, :], s[:, None] * M * s[None, :], eigvals_only=True)
    return np.sqrt(np.maximum(lam, 0.0))
