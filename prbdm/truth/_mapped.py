"""A structured triangulation mapped from the half planform, for benign planforms.

When every free-edge segment is within 45 degrees of the span (``|w'| <= 1``) and no two stations
are much closer than an element, the half planform maps column by column onto a rectangle: the
span-wise node lines of :func:`prbdm.truth._mesh.span_nodes` (every station, a uniform spacing,
geometric grading where the width changes quickly, and a few extra lines graded toward the
clamped root, whose corner with the free edge is a singular point of the plate solution) and, on
each line, the same number of chord-wise nodes ``y = eta_j w(x)`` graded toward the free edge.
Between two stations the free edge is straight, so the mesh reproduces the planform exactly, and
the elements of a slender strip are long along the span and right-angled (the maximum-angle
condition holds at any aspect ratio), which an isotropic mesher cannot give cheaply.
"""
from __future__ import annotations

import math

import numpy as np

from ._mesh import span_nodes

__all__ = ["is_benign", "mapped_half_mesh"]


def is_benign(xs, ws, h0, max_slope: float = 1.0) -> bool:
    """True when the mapped mesh is suitable (see the module docstring)."""
    dx = np.diff(xs)
    slope = np.abs(np.diff(ws)) / dx
    return bool(np.all(slope <= max_slope) and np.all(dx >= 0.25 * h0))


def mapped_half_mesh(xs, ws, h0, kappa=0.6, root_levels=2, root_ratio=0.3, edge_ratio=0.55,
                     chord_elements=None):
    """Points ``p`` (2, N), triangles ``t`` (3, M) and a description."""
    xs = np.asarray(xs, float)
    ws = np.asarray(ws, float)
    xn = span_nodes(xs, ws, h0=h0, kappa=kappa)
    if root_levels > 0:           # geometric columns toward the clamped root
        first = xn[1]
        extra = first * root_ratio ** np.arange(1, root_levels + 1)
        xn = np.unique(np.concatenate([xn, extra]))
    nx = round(1.0 / h0)
    if chord_elements is None:    # about square elements at the widest station
        ny = int(min(max(2, math.ceil(nx * float(ws.max()))), max(2, nx)))
    else:
        ny = int(chord_elements)
    sizes = np.linspace(1.0, edge_ratio, ny) if ny > 1 else np.ones(1)
    eta = np.concatenate([[0.0], np.cumsum(sizes) / sizes.sum()])
    wn = np.interp(xn, xs, ws)
    X = np.repeat(xn[:, None], ny + 1, axis=1)
    Y = wn[:, None] * eta[None, :]
    p = np.vstack([X.ravel(), Y.ravel()])
    idx = np.arange(len(xn) * (ny + 1)).reshape(len(xn), ny + 1)
    a, b = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel()
    c, d = idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    t = np.hstack([np.vstack([a, b, c]), np.vstack([a, c, d])])
    return p, t, {"mesher": "mapped", "span_lines": int(len(xn)), "chord_elements": ny}
