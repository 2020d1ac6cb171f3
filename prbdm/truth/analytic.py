"""Analytic truth for uniform cantilevers (docs/conventions.md §2, the paper's Eqs. 18-20).

``omega_n = alpha_n^2 sqrt(E I / (rho A L^4))`` with ``cos(alpha) cosh(alpha) = -1``. For a
rectangular section ``E I / (rho A) = E t^2 / (12 rho)``, so the width drops out and
``omega_n = alpha_n^2 * omega_0`` with ``omega_0 = (t / L^2) sqrt(E / (12 rho))``, the frequency
scale the beam model shares; the nondimensional eigenvalue is ``lambda_n = alpha_n^4``.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq

from ..errors import BadInput

__all__ = ["cantilever_roots", "beam_omega_scale", "solve_analytic"]


def _char(a: float) -> float:
    # cos(a) cosh(a) + 1 = 0 divided by cosh(a): well scaled for every root
    return math.cos(a) + 2.0 * math.exp(-a) / (1.0 + math.exp(-2.0 * a))


def cantilever_roots(n: int) -> np.ndarray:
    """The first ``n`` roots of ``cos(a) cosh(a) = -1``: 1.8751, 4.6941, 7.8548, 10.9955, ...

    Root ``k`` (1-based) is the only one in ``[(k-1) pi, k pi]``, where the scaled characteristic
    function changes sign; it is refined by Brent's method to machine precision.
    """
    roots = np.empty(n)
    for k in range(1, n + 1):
        lo, hi = (k - 1) * math.pi, k * math.pi
        roots[k - 1] = brentq(_char, lo, hi, xtol=1e-15, rtol=4 * np.finfo(float).eps,
                              maxiter=200)
    return roots


def beam_omega_scale(beam) -> float:
    """``omega_0 = (t / L^2) sqrt(E / (12 rho))`` [rad/s]: Euler-Bernoulli frequencies of a
    constant-thickness beam are ``omega_0 sqrt(lambda)`` whatever the material and size."""
    m = beam.material
    return beam.thickness / beam.length ** 2 * math.sqrt(m.E / (12.0 * m.rho))


def _mode_shape(a: float, xi: np.ndarray) -> np.ndarray:
    """``phi = cosh - cos - s (sinh - sin)`` at ``a xi``, ``s = (cos a + cosh a)/(sin a + sinh a)``,
    written without the cancellation of ``cosh - s sinh`` at large ``a``; scaled to max |phi| = 1."""
    s = (math.cos(a) + math.cosh(a)) / (math.sin(a) + math.sinh(a))
    ax = a * xi
    # cosh(ax) - s sinh(ax) = ((1 - s) e^{ax} + (1 + s) e^{-ax}) / 2, with
    # (1 - s) e^{ax} = (sin a - cos a - e^{-a}) e^{ax} / (sinh a + sin a)
    e = math.exp(-a)
    grow = (math.sin(a) - math.cos(a) - e) * 2.0 * np.exp(a * (xi - 1.0)) / (1.0 - e * e + 2.0 * math.sin(a) * e)
    phi = 0.5 * (grow + (1.0 + s) * np.exp(-ax)) - np.cos(ax) + s * np.sin(ax)
    return phi / np.max(np.abs(phi))


def solve_analytic(beam, modes: int) -> dict:
    if not beam.is_uniform():
        w = beam.half_width
        raise BadInput(f"model 'analytic': applies to uniform beams only, but the half-width "
                       f"varies from {w.min():.6g} to {w.max():.6g} m; use --model beam or plate")
    alpha = cantilever_roots(modes)
    lam = alpha ** 4
    # the analytic mode shapes, for plots: w(x) = cosh - cos - s (sinh - sin), s from the BCs
    xi = np.linspace(0.0, 1.0, 201)
    shapes = []
    for a in alpha:
        shapes.append(_mode_shape(a, xi))
    # transverse mass participation of mode n: (int phi)^2 / (int phi^2 * L) with the exact
    # integrals int_0^1 phi = 2 s / a and int_0^1 phi^2 = 1 for this normalisation
    part = []
    for a in alpha:
        s = (math.cos(a) + math.cosh(a)) / (math.sin(a) + math.sinh(a))
        part.append((2.0 * s / a) ** 2)
    return {"lam": lam, "participation": np.array(part),
            "shapes": {"kind": "beam", "x": xi, "w": np.array(shapes)},
            "mesh": {"method": "closed form, cos(a) cosh(a) = -1", "roots": alpha}}
