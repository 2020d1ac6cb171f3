"""Span-wise node placement shared by the beam and plate models.

Everything here works in nondimensional coordinates: ``xi = x / L`` in [0, 1] and half-widths
``w / L``. The nodes

* include every planform station (the width is linear between stations, so each element sees a
  linear width and the element integrals are exact; a station closer than ``h_min`` to one
  already placed is merged with it),
* are no further apart than ``h0`` (resolves the waves: with a constant thickness the local
  bending wavenumber, ``k^4 = omega^2 rho A / (E I) = 12 rho omega^2 / (E t^2)``, does not depend
  on the width, so a uniform spacing resolves every part of the span equally well),
* are graded geometrically where the width changes quickly compared with itself:
  ``h(x) <= kappa * w(x) / |w'(x)|``. A 100:1 taper over 1 % of the span then gets
  ``ln(100) / ln(1 + kappa)`` elements (12 for ``kappa = 0.5``) instead of none, and a sharp waist
  or a near-zero width is refined automatically rather than missed,
* are never closer than ``h_min (w / w_max)^(1/3)`` (see :data:`H_MIN`).
"""
from __future__ import annotations

import math

import numpy as np

#: smallest element (nondimensional) where the width is the largest: the floor is
#: ``H_MIN * (w / w_max)^(1/3)``, so that no element is stiffer (``beta / h^3``) than
#: ``1 / H_MIN^3``. Stations closer than the floor are merged into one node (the width is still
#: integrated from the exact planform at the quadrature points) and the width grading stops
#: there. Stiffer elements only ruin the conditioning: a 1e-5 element at full width makes K
#: span 1e15 and the lowest modes drown in rounding.
H_MIN = 1e-4


def span_nodes(xs: np.ndarray, ws: np.ndarray, h0: float, kappa: float | None = 0.5,
               h_min: float | None = None) -> np.ndarray:
    """Node positions in [0, 1] (sorted, first 0, last 1) for stations ``xs`` (nondimensional,
    ``xs[0] = 0``, ``xs[-1] = 1``) and half-widths ``ws`` at them.

    ``kappa=None`` switches the width grading off (uniform spacing ``h0`` between stations).
    """
    xs = np.asarray(xs, dtype=float)
    ws = np.asarray(ws, dtype=float)
    h_min = min(H_MIN if h_min is None else h_min, h0)
    beta = ws / ws.max()
    # stations to honour: merge stations closer than the local floor (they would make tiny,
    # very stiff elements)
    keep = [0]
    for k in range(1, len(xs)):
        floor = h_min * max(beta[k], beta[keep[-1]]) ** (1.0 / 3.0)
        if xs[k] - xs[keep[-1]] >= floor:
            keep.append(k)
    if keep[-1] != len(xs) - 1:  # the tip always stays, replacing the last kept station
        keep[-1] = len(xs) - 1
    pieces = [np.array([0.0])]
    for a, b in zip(keep[:-1], keep[1:]):
        # the width is piecewise linear between the original stations a..b (merged ones inside)
        pieces.append(_segment_nodes(xs[a:b + 1], ws[a:b + 1], h0, kappa, h_min,
                                     float(ws.max()))[1:])
    nodes = np.concatenate(pieces)
    nodes[0], nodes[-1] = 0.0, 1.0
    return nodes


def _segment_nodes(xs, ws, h0, kappa, h_min, wmax):
    """Nodes on [xs[0], xs[-1]] with density max(1/h0, |w'| / (kappa w))."""
    xa, xb = float(xs[0]), float(xs[-1])
    length = xb - xa
    if kappa is None:
        n = max(1, math.ceil(length / h0 - 1e-9))
        return np.linspace(xa, xb, n + 1)
    # sample densely, geometrically in w on each linear piece so that the 1/w density integrates
    # accurately however small w gets
    samples = []
    for k in range(len(xs) - 1):
        x0, x1, w0, w1 = xs[k], xs[k + 1], ws[k], ws[k + 1]
        u = np.linspace(0.0, 1.0, 33)
        if w0 > 0 and w1 > 0 and abs(w1 - w0) > 1e-12 * max(w0, w1):
            g = (np.geomspace(w0, w1, 65) - w0) / (w1 - w0)
            u = np.union1d(u, np.clip(g, 0.0, 1.0))
        samples.append(x0 + u * (x1 - x0))
    x = np.unique(np.concatenate(samples))
    # elements needed on each sample interval: the larger of the uniform count dx / h0 and the
    # graded count, the exact integral of |w'| / (kappa w) over a linear piece, |ln(w1/w0)| / kappa
    # (sample intervals never straddle a station, so w is linear on each)
    w = np.maximum(np.interp(x, xs, ws), 1e-300)
    graded = np.abs(np.log(w[1:] / w[:-1])) / kappa
    # the floor scales like beta^(1/3): no element stiffer (beta / h^3) than 1 / h_min^3
    wmid = np.maximum(w[1:], w[:-1]) / wmax
    floor = h_min * wmid ** (1.0 / 3.0)
    count = np.maximum(np.diff(x) / h0, np.minimum(graded, np.diff(x) / floor))
    cum = np.concatenate([[0.0], np.cumsum(count)])
    n = max(1, math.ceil(cum[-1] - 1e-9))
    levels = np.linspace(0.0, cum[-1], n + 1)
    nodes = np.interp(levels, cum, x)
    nodes[0], nodes[-1] = xa, xb
    return nodes

