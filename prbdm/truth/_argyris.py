"""A numerically robust (and fast) Argyris triangle for scikit-fem.

scikit-fem's ``ElementTriArgyris`` (an ``ElementGlobal``) builds each element's basis by inverting
the 21 x 21 matrix of its degrees of freedom applied to the monomials ``x^i y^j`` (i + j <= 5) in
*global* coordinates. For a small element far from the origin, or a long thin one, that matrix is
so ill-conditioned that its inverse is garbage: the basis stops being C1, the method stops being
conforming and spurious low eigenvalues appear (on a refined random planform the first plate
frequency fell by 5 % below its converged value).

:class:`LocalArgyris` has the same degrees of freedom, in the same order, and spans the same
global space, but writes the monomials in each element's own affine coordinates ``(s, t)``
(``x = v0 + s (v1 - v0) + t (v2 - v0)``), where the DOF matrix is well-conditioned whatever the
element's size, position or shape; global first and second derivatives follow from the chain rule
with the inverse Jacobian ``B``: ``grad = B^T grad_st``, ``hess = B^T hess_st B``. Because the
local coordinates of the quadrature points are the reference points themselves, the monomials are
evaluated once, not once per element, which also makes the basis an order of magnitude cheaper to
build than the stock element's.

Edge normals (the ``u_n`` DOFs) are oriented canonically from the lower to the higher global vertex
index (interior edges: both neighbours agree) and outward on the boundary, as scikit-fem does.

An instance caches its per-element data for the mesh it was first used with: use a new instance
per mesh (and per thread).

:class:`ArgyrisSpace` is what the plate solver uses: the same element, but the element matrices
are built for all elements at once with batched numpy, exactly (closed-form monomial integrals on
the reference triangle), instead of by scikit-fem's per-form quadrature and Python-level
assembly, which took most of a plate solve. :class:`LocalArgyris` stays as the scikit-fem element
the tests compare it with.
"""
from __future__ import annotations

from math import factorial

import numpy as np
import scipy.sparse as sp
from skfem import ElementTriArgyris
from skfem.assembly import Dofs
from skfem.element.discrete_field import DiscreteField
from skfem.quadrature import get_quadrature
from skfem.refdom import RefTri

__all__ = ["LocalArgyris", "ArgyrisSpace"]

# exponents (i, j) of the monomials s^i t^j, i + j <= 5
_EXP = np.array([(i, j) for i in range(6) for j in range(6) if i + j <= 5])
_VERTS = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
_MIDS = np.array([[0.5, 0.0], [0.5, 0.5], [0.0, 0.5]])          # edges v0v1, v1v2, v2v0
_EDGES = ((0, 1), (1, 2), (2, 0))


def _pow(x, e):
    """x**e for integer e >= 0 with 0**0 = 1 and 0 where e < 0 (only multiplied by 0 coefs)."""
    return np.where(e >= 0, np.power(x, np.maximum(e, 0)), 0.0)


def _monomials(s, t):
    """Values and local derivatives of the 21 monomials at points (s, t) (any equal shapes).

    Returns arrays of shape (21,) + s.shape: P, P_s, P_t, P_ss, P_st, P_tt.
    """
    s = np.asarray(s, dtype=float)[None]
    t = np.asarray(t, dtype=float)[None]
    shape = (-1,) + (1,) * (s.ndim - 1)
    i = _EXP[:, 0].reshape(shape)
    j = _EXP[:, 1].reshape(shape)
    P = _pow(s, i) * _pow(t, j)
    Ps = i * _pow(s, i - 1) * _pow(t, j)
    Pt = j * _pow(s, i) * _pow(t, j - 1)
    Pss = i * (i - 1) * _pow(s, i - 2) * _pow(t, j)
    Pst = i * j * _pow(s, i - 1) * _pow(t, j - 1)
    Ptt = j * (j - 1) * _pow(s, i) * _pow(t, j - 2)
    return P, Ps, Pt, Pss, Pst, Ptt




def _element_basis(mesh):
    """Per-element data of the local construction: ``C`` (elements, 21, 21), basis function i =
    sum_n C[e, n, i] * monomial n in the element's coordinates; ``B`` (elements, 2, 2) with
    local = B @ (x - v0); ``A`` (elements, 2, 2), the affine map's Jacobian (columns v1 - v0,
    v2 - v0)."""
    p = mesh.p[:, mesh.t]                                  # (2, 3, nel)
    A = np.moveaxis(np.stack([p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]], axis=1), 2, 0)
    B = np.linalg.inv(A)                                   # (nel, 2, 2)
    nel = B.shape[0]
    # global derivative functionals of every monomial at the local points
    V = np.zeros((nel, 21, 21))
    P, Ps, Pt, Pss, Pst, Ptt = _monomials(_VERTS[:, 0], _VERTS[:, 1])   # (21, 3)
    b00, b01, b10, b11 = B[:, 0, 0], B[:, 0, 1], B[:, 1, 0], B[:, 1, 1]
    for k in range(3):
        # rows 6k..6k+5: u, u_x, u_y, u_xx, u_xy, u_yy at vertex k
        V[:, 6 * k + 0, :] = P[:, k][None, :]
        V[:, 6 * k + 1, :] = b00[:, None] * Ps[:, k] + b10[:, None] * Pt[:, k]
        V[:, 6 * k + 2, :] = b01[:, None] * Ps[:, k] + b11[:, None] * Pt[:, k]
        V[:, 6 * k + 3, :] = ((b00 * b00)[:, None] * Pss[:, k]
                              + (2 * b00 * b10)[:, None] * Pst[:, k]
                              + (b10 * b10)[:, None] * Ptt[:, k])
        V[:, 6 * k + 4, :] = ((b00 * b01)[:, None] * Pss[:, k]
                              + (b00 * b11 + b10 * b01)[:, None] * Pst[:, k]
                              + (b10 * b11)[:, None] * Ptt[:, k])
        V[:, 6 * k + 5, :] = ((b01 * b01)[:, None] * Pss[:, k]
                              + (2 * b01 * b11)[:, None] * Pst[:, k]
                              + (b11 * b11)[:, None] * Ptt[:, k])
    normals = _normals(mesh, p)                            # (3, 2, nel)
    _, Ps, Pt, _, _, _ = _monomials(_MIDS[:, 0], _MIDS[:, 1])
    for k in range(3):
        gx = b00[:, None] * Ps[:, k] + b10[:, None] * Pt[:, k]
        gy = b01[:, None] * Ps[:, k] + b11[:, None] * Pt[:, k]
        V[:, 18 + k, :] = normals[k, 0][:, None] * gx + normals[k, 1][:, None] * gy
    # invert with the DOF rows scaled by powers of the element size h (u, h u_x, h^2 u_xx,
    # h u_n): the scaled matrix is well conditioned even for long thin elements, and
    # inv(S V) S = inv(V) exactly
    h = np.sqrt(np.abs(np.linalg.det(A)))                  # ~ element size
    powers = np.array([0, 1, 1, 2, 2, 2] * 3 + [1, 1, 1])
    S = h[:, None] ** powers[None, :]                      # (nel, 21)
    C = np.linalg.inv(S[:, :, None] * V) * S[:, None, :]
    return C, B, A


def _normals(mesh, p):
    """Unit normals of the three edges of every element: rot90(v_lo - v_hi) with lo < hi the
    global vertex numbers (both neighbours of an interior edge agree), and outward on the
    boundary."""
    t = mesh.t
    out = np.zeros((3, 2, t.shape[1]))
    boundary = np.zeros(mesh.facets.shape[1], dtype=bool)
    boundary[mesh.boundary_facets()] = True
    for k, (a, b) in enumerate(_EDGES):
        swap = t[a] > t[b]
        lo = np.where(swap, p[:, b], p[:, a])
        hi = np.where(swap, p[:, a], p[:, b])
        d = lo - hi
        n = np.array([d[1], -d[0]])
        n /= np.linalg.norm(n, axis=0)
        on_boundary = boundary[mesh.t2f[k]]
        opposite = p[:, 3 - a - b]
        mid = 0.5 * (p[:, a] + p[:, b])
        inward = np.sum(n * (opposite - mid), axis=0) > 0
        flip = on_boundary & inward
        n[:, flip] *= -1.0
        out[k] = n
    return out


def _hessian_map(B):
    """``R`` (elements, 3, 3): global (u_xx, u_xy, u_yy) = R @ local (u_ss, u_st, u_tt), from
    ``hess_x = B^T hess_st B``."""
    b00, b01, b10, b11 = B[:, 0, 0], B[:, 0, 1], B[:, 1, 0], B[:, 1, 1]
    return np.stack([np.stack([b00 * b00, 2 * b00 * b10, b10 * b10], -1),
                     np.stack([b00 * b01, b00 * b11 + b10 * b01, b10 * b11], -1),
                     np.stack([b01 * b01, 2 * b01 * b11, b11 * b11], -1)], axis=1)


def _reference_integrals():
    """Exact integrals over the reference triangle of products of the monomials and of their
    second derivatives: ``G[n, m] = int P_n P_m``, ``I[a, b, n, m] = int D_a P_n D_b P_m`` with
    ``D = (d_ss, d_st, d_tt)``, and ``g[n] = int P_n`` (``int s^i t^j = i! j! / (i + j + 2)!``)."""
    def tri(i, j):
        return factorial(i) * factorial(j) / factorial(i + j + 2)

    i, j = _EXP[:, 0], _EXP[:, 1]
    g = np.array([tri(a, b) for a, b in zip(i, j)])
    G = np.array([[tri(a + c, b + d) for c, d in zip(i, j)] for a, b in zip(i, j)])
    # second derivatives as (coefficient, exponents) of a single monomial each
    ders = [(i * (i - 1), i - 2, j), (i * j, i - 1, j - 1), (j * (j - 1), i, j - 2)]
    I = np.zeros((3, 3, 21, 21))
    for a, (ca, ia, ja) in enumerate(ders):
        for b, (cb, ib, jb) in enumerate(ders):
            for n in range(21):
                if ca[n] == 0:
                    continue
                for m in range(21):
                    if cb[m] != 0:
                        I[a, b, n, m] = ca[n] * cb[m] * tri(ia[n] + ib[m], ja[n] + jb[m])
    return g, G, I


_G1, _GMASS, _IHESS = _reference_integrals()
#: the Kirchhoff energy density in (u_xx, u_xy, u_yy): (1 - nu) u_,ij u_,ij + nu lap(u)^2
_E_ONE = np.array([[1.0, 0, 0], [0, 2.0, 0], [0, 0, 1.0]])      # coefficient of (1 - nu)
_E_NU = np.array([[1.0, 0, 1.0], [0, 0, 0], [1.0, 0, 1.0]])     # coefficient of nu


class ArgyrisSpace:
    """The Argyris space of a triangle mesh, with its matrices built element-batched.

    Same degrees of freedom, numbering and edge-normal convention as ``Basis(mesh,
    LocalArgyris())`` (hence as scikit-fem's ``ElementTriArgyris``): ``element_dofs`` (21,
    elements), ``nodal_dofs`` (6, vertices), ``get_dofs(facets).all(names)``. The element
    matrices are exact polynomial integrals, the fields at the points of the degree-10 rule that
    ``Basis`` uses by default.
    """

    def __init__(self, mesh, intorder: int = 10):
        self.mesh = mesh
        self.element = ElementTriArgyris()
        self.dofs = Dofs(mesh, self.element)
        self.N = int(self.dofs.N)
        self.element_dofs = self.dofs.element_dofs
        self.nodal_dofs = self.dofs.nodal_dofs
        self.C, self.B, A = _element_basis(mesh)
        self.absdet = np.abs(A[:, 0, 0] * A[:, 1, 1] - A[:, 0, 1] * A[:, 1, 0])
        self.R = _hessian_map(self.B)
        X, W = get_quadrature(RefTri, intorder)
        v0 = mesh.p[:, mesh.t[0]]                            # (2, nel)
        self.xq = v0[0][:, None] + A[:, 0, 0][:, None] * X[0] + A[:, 0, 1][:, None] * X[1]
        self.dx = self.absdet[:, None] * W[None, :]          # (elements, points)
        P, _, _, Pss, Pst, Ptt = _monomials(X[0], X[1])      # (21, points)
        self._P = P
        # value and local second derivatives side by side: one matrix product gives all four
        self._Pall = np.hstack([P, Pss, Pst, Ptt])           # (21, 4 * points)

    def get_dofs(self, facets):
        return self.dofs.get_facet_dofs(facets)

    # ------------------------------------------------------------------ element matrices
    def element_stiffness(self, nu: float) -> np.ndarray:
        """(elements, 21, 21): ``int (1 - nu) u_,ij v_,ij + nu lap(u) lap(v)`` per element."""
        # Q = R^T E R: the energy density as a quadratic form in the local second derivatives
        E = (1.0 - nu) * _E_ONE + nu * _E_NU
        Q = np.einsum("eia,ij,ejb->eab", self.R, E, self.R) * self.absdet[:, None, None]
        X = np.einsum("eab,abnm->enm", Q, _IHESS)          # in the monomial basis
        return np.matmul(np.transpose(self.C, (0, 2, 1)), X @ self.C)

    def element_mass(self) -> np.ndarray:
        """(elements, 21, 21): ``int u v`` per element."""
        Ct = np.transpose(self.C, (0, 2, 1))
        return self.absdet[:, None, None] * np.matmul(Ct, _GMASS @ self.C)

    def load(self) -> np.ndarray:
        """``int v`` for every basis function: the modal force of a uniform acceleration."""
        fe = self.absdet[:, None] * np.einsum("n,eni->ei", _G1, self.C)
        return np.bincount(self.element_dofs.T.ravel(), fe.ravel(), minlength=self.N)

    def assemble(self, mats, keep=None):
        """The global matrices (CSR) of the element matrices in ``mats`` (a list of (elements,
        21, 21) arrays), restricted to the DOFs ``keep`` (in their order; all by default)."""
        dofs = self.element_dofs.T                           # (elements, 21)
        n = self.N
        if keep is not None:
            local = -np.ones(self.N, dtype=np.int64)
            local[keep] = np.arange(len(keep))
            dofs = local[dofs]
            n = len(keep)
        shape = (dofs.shape[0], 21, 21)
        rows = np.broadcast_to(dofs[:, :, None], shape)
        cols = np.broadcast_to(dofs[:, None, :], shape)
        ok = (rows >= 0) & (cols >= 0)
        rows, cols = rows[ok], cols[ok]
        if len(mats) == 2:
            # two matrices of one sparsity pattern in one conversion (as the real and imaginary
            # parts of a complex one: the same sums in the same order as two conversions)
            A = sp.csr_matrix((mats[0][ok] + 1j * mats[1][ok], (rows, cols)), shape=(n, n))
            return [sp.csr_matrix((part, A.indices, A.indptr), shape=(n, n))
                    for part in (A.data.real.copy(), A.data.imag.copy())]
        return [sp.csr_matrix((Ke[ok], (rows, cols)), shape=(n, n)) for Ke in mats]

    # ------------------------------------------------------------------ fields
    def fields(self, phi):
        """Value and global second derivatives of every column of ``phi`` (N, modes) at the
        quadrature points: ``val`` (elements, modes, points) and ``hess`` (3, elements, modes,
        points) as (u_xx, u_xy, u_yy)."""
        coef = np.transpose(phi[self.element_dofs], (1, 0, 2))   # (elements, 21, modes)
        mono = np.transpose(self.C @ coef, (0, 2, 1))             # monomial coefficients
        nel, modes, _ = mono.shape
        nq = self._P.shape[1]
        f = (mono.reshape(-1, 21) @ self._Pall).reshape(nel, modes, 4, nq)
        hess = np.matmul(self.R[:, None], f[:, :, 1:])            # (elements, modes, 3, points)
        return f[:, :, 0], np.moveaxis(hess, 2, 0)


class LocalArgyris(ElementTriArgyris):
    """``ElementTriArgyris`` with the basis built in element-local affine coordinates."""

    def __init__(self):
        super().__init__()
        self._C = None      # (elements, 21, 21): basis i = sum_n C[e, n, i] * monomial n
        self._B = None      # (elements, 2, 2): local = B @ (x - v0)

    def _setup(self, mesh):
        self._C, self._B, _ = _element_basis(mesh)

    # ------------------------------------------------------------------ scikit-fem interface
    def gbasis(self, mapping, X, i, tind=None):
        if self._C is None:
            self._setup(mapping.mesh)
        if tind is None:
            tind = np.arange(mapping.mesh.t.shape[1])
        C = self._C[tind][:, :, i]                             # (nel, 21)
        B = self._B[tind]                                      # (nel, 2, 2)
        X = np.asarray(X, dtype=float)
        P, Ps, Pt, Pss, Pst, Ptt = _monomials(X[0], X[1])      # (21, nqp) or (21, nel, nqp)
        if X.ndim == 2:
            comb = lambda M: C @ M                             # noqa: E731  (nel, nqp)
        else:
            comb = lambda M: np.einsum("en,neq->eq", C, M)     # noqa: E731
        u, us, ut = comb(P), comb(Ps), comb(Pt)
        uss, ust, utt = comb(Pss), comb(Pst), comb(Ptt)
        b00, b01 = B[:, 0, 0][:, None], B[:, 0, 1][:, None]
        b10, b11 = B[:, 1, 0][:, None], B[:, 1, 1][:, None]
        grad = np.array([b00 * us + b10 * ut, b01 * us + b11 * ut])
        hxx = b00 * b00 * uss + 2 * b00 * b10 * ust + b10 * b10 * utt
        hxy = b00 * b01 * uss + (b00 * b11 + b10 * b01) * ust + b10 * b11 * utt
        hyy = b01 * b01 * uss + 2 * b01 * b11 * ust + b11 * b11 * utt
        hess = np.array([[hxx, hxy], [hxy, hyy]])
        return (DiscreteField(value=u, grad=grad, hess=hess),)
