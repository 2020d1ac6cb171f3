"""A numerically robust cubic Hermite line element for scikit-fem.

scikit-fem's ``ElementLineHermite`` is an ``ElementGlobal``: it builds each element's basis by
inverting the 4 x 4 matrix of its DOFs applied to ``1, x, x^2, x^3`` in global coordinates, which
is singular to working precision for an element 1e-5 long at x = 0.5 (the graded meshes at sharp
waists have such elements) and inaccurate well before that: the basis stops being C1 and the
eigenvalues pick up errors of 1e-4. :class:`LocalHermite` spans the same space with the same DOFs
(w and w' at each node) from the classical shape functions in the local coordinate
``s = (x - x0) / h``:

    N1 = 1 - 3 s^2 + 2 s^3,  N2 = h (s - 2 s^2 + s^3),  N3 = 3 s^2 - 2 s^3,  N4 = h (s^3 - s^2),

with ``d/dx = (1/h) d/ds``.
"""
from __future__ import annotations

import numpy as np
from skfem import ElementLineHermite
from skfem.element.discrete_field import DiscreteField

__all__ = ["LocalHermite"]


def _shape(i, s):
    """Value, d/ds and d2/ds2 of local shape function i (without the factor h of N2, N4)."""
    if i == 0:
        return 1 - 3 * s ** 2 + 2 * s ** 3, -6 * s + 6 * s ** 2, -6 + 12 * s
    if i == 1:
        return s - 2 * s ** 2 + s ** 3, 1 - 4 * s + 3 * s ** 2, -4 + 6 * s
    if i == 2:
        return 3 * s ** 2 - 2 * s ** 3, 6 * s - 6 * s ** 2, 6 - 12 * s
    return s ** 3 - s ** 2, 3 * s ** 2 - 2 * s, 6 * s - 2


class LocalHermite(ElementLineHermite):
    """``ElementLineHermite`` with the basis in element-local coordinates."""

    def gbasis(self, mapping, X, i, tind=None):
        mesh = mapping.mesh
        if tind is None:
            tind = np.arange(mesh.t.shape[1])
        h = (mesh.p[0, mesh.t[1, tind]] - mesh.p[0, mesh.t[0, tind]])[:, None]   # signed
        s = np.asarray(X, dtype=float)[0]
        if s.ndim == 1:
            s = np.broadcast_to(s[None, :], (len(tind), s.shape[0]))
        v, ds, dss = _shape(i, s)
        scale = h if i in (1, 3) else 1.0
        value = scale * v
        grad = (scale * ds / h)[None]
        hess = (scale * dss / h ** 2)[None, None]
        return (DiscreteField(value=value, grad=grad, hess=hess),)
