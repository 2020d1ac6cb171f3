"""A mesh-free reference for the beam model: shooting on the Euler-Bernoulli ODE.

``(b w'')'' = lambda b w`` on ``0 <= xi <= 1`` (nondimensional, ``b`` the width relative to its
largest value), ``w(0) = w'(0) = 0``, ``M(1) = b w''(1) = 0``, ``V(1) = (b w'')'(1) = 0``. The
state ``(w, w', M, V)`` is integrated from the root with scipy's DOP853 (rtol 1e-12), station
interval by station interval (``b`` is linear on each, so the integrator never steps over a
kink), for the two solutions that start with ``M = 1`` and ``V = 1``; an eigenvalue makes the 2x2
matrix of their tip moments and shears singular. The two solutions are re-orthonormalised (QR
with a positive diagonal, which keeps the determinant's sign) every ``chunk`` of span, so that
they stay independent however fast they grow. No mesh, no finite elements: an independent check
of :mod:`prbdm.truth.beam`, used by the tests and the benchmark. Slow (about 0.1 s per
eigenvalue); not a production solver.
"""
from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

__all__ = ["tip_determinant", "shooting_eigenvalues"]


def tip_determinant(lam: float, xs, bs, chunk: float = 0.02) -> float:
    """Sign-faithful determinant of the tip conditions at the eigenvalue candidate ``lam``."""
    Y = np.array([[0, 0, 1.0, 0], [0, 0, 0, 1.0]]).T
    for a in range(len(xs) - 1):
        x0, x1, b0, b1 = xs[a], xs[a + 1], bs[a], bs[a + 1]
        if x1 <= x0:
            continue

        def rhs(x, y, x0=x0, x1=x1, b0=b0, b1=b1):
            b = b0 + (b1 - b0) * (x - x0) / (x1 - x0)
            y = y.reshape(4, 2)
            return np.array([y[1], y[2] / b, y[3], lam * b * y[0]]).ravel()

        edges = np.linspace(x0, x1, max(1, int(np.ceil((x1 - x0) / chunk))) + 1)
        for s0, s1 in zip(edges[:-1], edges[1:]):
            sol = solve_ivp(rhs, (s0, s1), Y.ravel(), method="DOP853", rtol=1e-12, atol=1e-14)
            Q, R = np.linalg.qr(sol.y[:, -1].reshape(4, 2))
            Y = Q * np.sign(np.diag(R))[None, :]
    return float(Y[2, 0] * Y[3, 1] - Y[2, 1] * Y[3, 0])


def shooting_eigenvalues(beam, guesses, rel: float = 3e-4) -> np.ndarray:
    """The exact nondimensional eigenvalues of ``beam`` next to ``guesses`` (e.g. the FEM ones),
    by Brent's method on the tip determinant in ``[g (1 - rel), g (1 + rel)]``."""
    xs = beam.x / beam.length
    bs = beam.half_width / beam.half_width.max()
    return np.array([brentq(tip_determinant, g * (1 - rel), g * (1 + rel), args=(xs, bs),
                            xtol=1e-14 * g, rtol=1e-13) for g in guesses])
