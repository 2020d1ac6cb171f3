"""Euler-Bernoulli truth: variable-width cantilever, cubic Hermite elements (scikit-fem).

Strong form ``(E I w'')'' = rho A omega^2 w`` with ``I = b t^3 / 12``, ``A = b t``,
``b(x) = 2 w(x)``. With ``xi = x / L`` and ``beta = b / b_max`` it becomes

    (beta w'')'' = lambda beta w,   omega = omega_0 sqrt(lambda),   omega_0 = (t/L^2) sqrt(E/(12 rho)),

so the eigenproblem depends on the planform shape only: a 5 MPa rubber strip and a 205 GPa steel
panel of the same shape solve the same, well-scaled matrices (entries of order 1) and get the same
relative accuracy. Weak form, for every admissible v (v(0) = v'(0) = 0):

    a(w, v) = int beta w'' v'' dxi = lambda int beta w v dxi = lambda m(w, v).

Elements: cubic Hermite (C1, DOFs w and w' at each node), the conforming element for the
fourth-order beam operator, with the basis written in element-local coordinates
(:class:`prbdm.truth._hermite.LocalHermite`; scikit-fem's ``ElementLineHermite`` inverts a
global-monomial matrix that is singular for the 1e-4-long elements of a graded waist). The width
is linear inside every element (stations are nodes), so the 8th-order Gauss rule integrates both
forms exactly. The mesh comes from :func:`prbdm.truth._mesh.span_nodes`: a uniform spacing
``1 / elements`` that resolves the requested modes, plus geometric grading
``h <= kappa w / |w'|`` (kappa = 0.25) where the width changes quickly, never below
``h_min = 1e-4 L``. Eigenvalues: shift-invert Lanczos (``eigsh(sigma=0)``) on the
nondimensional, diagonally scaled matrices with an iteratively refined sparse LU, then each
eigenvalue recomputed as the Rayleigh quotient of its mode from the fields
(``int beta w''^2 / int beta w^2``, a sum of positive terms): together these keep the lowest
modes accurate however fine and graded the mesh (a dense generalized solve on dimensional
matrices loses them).
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import eigsh
from skfem import Basis, BilinearForm, LinearForm, MeshLine
from skfem.helpers import dd, ddot

from ._hermite import LocalHermite
from ._linalg import refined_inverse
from ._mesh import span_nodes

__all__ = ["stiffness", "mass", "load", "beam_nodes", "solve_beam", "DEFAULT_KAPPA"]

#: width grading: element size <= kappa * w / |w'| (see _mesh)
DEFAULT_KAPPA = 0.25


@BilinearForm
def stiffness(u, v, w):
    """a(u, v) = int beta u'' v''."""
    return w.beta * ddot(dd(u), dd(v))


@BilinearForm
def mass(u, v, w):
    """m(u, v) = int beta u v."""
    return w.beta * u * v


@LinearForm
def load(v, w):
    """f(v) = int beta v: the modal force of a uniform transverse acceleration."""
    return w.beta * v


def default_elements(modes: int) -> int:
    """Base number of elements along the span (before grading).

    With cubic Hermite elements the frequency error of mode n falls like (n h)^4; 8 elements per
    requested mode and at least 40 keep the first modes within ~1e-5 relative of the converged
    values (measured in docs/validation.md), ten times inside the 0.01 % requirement.
    """
    return max(40, 8 * int(modes))


def beam_nodes(beam, elements: int | None = None, grading: bool = True, modes: int = 5):
    """Nondimensional nodes of the beam mesh."""
    n0 = default_elements(modes) if elements is None else int(elements)
    L = beam.length
    return span_nodes(beam.x / L, beam.half_width / L, h0=1.0 / n0,
                      kappa=DEFAULT_KAPPA if grading else None)


def solve_beam(beam, modes: int, elements: int | None = None, grading: bool = True) -> dict:
    L = beam.length
    xs, ws = beam.x / L, beam.half_width / L
    nodes = beam_nodes(beam, elements, grading, modes)
    mesh = MeshLine(nodes)
    basis = Basis(mesh, LocalHermite(), intorder=8)
    xq = basis.mapping.F(basis.X)[0]                     # quadrature points, (elements, points)
    beta = np.interp(xq, xs, ws) / ws.max()
    K = stiffness.assemble(basis, beta=beta)
    M = mass.assemble(basis, beta=beta)
    f = load.assemble(basis, beta=beta)
    clamped = basis.get_dofs(lambda x: x[0] < 0.5 * nodes[1]).all()
    free = basis.complement_dofs(clamped)
    Kf, Mf = K[free][:, free], M[free][:, free]
    # symmetric diagonal scaling: graded meshes mix elements of very different sizes (and the
    # slope DOFs scale like 1/h), so K's entries span many orders of magnitude; D K D has a unit
    # diagonal and the same eigenvalues with D M D, and its LU stays accurate
    d = 1.0 / np.sqrt(Kf.diagonal())
    D = sp.diags(d)
    Kf, Mf = (D @ Kf @ D).tocsc(), (D @ Mf @ D).tocsc()
    k = int(modes)
    if k >= Kf.shape[0] - 1:
        raise ValueError(f"mesh too coarse for {k} modes ({Kf.shape[0]} DOFs)")
    # a fixed start vector: the same beam gives the same digits on every call and thread
    lam, vec = eigsh(Kf, k=k, M=Mf, sigma=0.0, which="LM", OPinv=refined_inverse(Kf),
                     v0=np.ones(Kf.shape[0]))
    order = np.argsort(lam)
    lam, vec = lam[order], vec[:, order] * d[:, None]
    phi = np.zeros((basis.N, k))
    phi[free] = vec
    # Rayleigh quotients from the fields, int beta w''^2 / int beta w^2 summed element by element
    # (positive terms, no cancellation): the assembled K of a graded mesh has entries 1e12 times
    # larger than lambda_1, and phi^T K phi loses ~1e-5 to rounding; the field form does not
    lam = _rayleigh(basis, beta, phi)
    order = np.argsort(lam, kind="stable")
    lam, phi, vec = lam[order], phi[:, order], vec[:, order]
    # transverse mass participation (phi^T M 1)^2 / (phi^T M phi * total mass); M 1 = f
    ones = np.zeros(basis.N)
    ones[basis.nodal_dofs[0]] = 1.0                        # the constant 1 in the Hermite basis
    total = float(f @ ones)                                # int beta = total (nondimensional) mass
    modal_mass = np.einsum("ik,ik->k", phi, M @ phi)
    participation = (f @ phi) ** 2 / (modal_mass * total)
    values = phi[basis.nodal_dofs[0]]                      # w at the nodes
    scale = values[np.argmax(np.abs(values), axis=0), np.arange(k)]   # largest value -> +1
    scale[scale == 0] = 1.0
    # modal mass of each shape as returned (largest value +1): int beta w^2 dxi, nondimensional;
    # times rho t b_max L it is the SI modal mass, which a modal superposition needs
    return {"lam": lam, "participation": participation,
            "shapes": {"kind": "beam", "x": nodes, "w": (values / scale).T,
                       "modal_mass": modal_mass / scale ** 2},
            "mesh": {"element": "cubic Hermite (C1), local basis", "elements": int(len(nodes) - 1),
                     "dofs": int(len(free)), "min_element": float(np.diff(nodes).min()),
                     "graded": bool(grading)}}


def _rayleigh(basis, beta, phi):
    """``int beta w''^2 / int beta w^2`` for every column of ``phi``, from the fields."""
    F = np.stack([np.concatenate([np.asarray(basis.basis[j][0]), basis.basis[j][0].hess[0, 0]],
                                 axis=1) for j in range(basis.Nbfun)], axis=1)  # (nel, 4, 2q)
    coef = np.transpose(phi[basis.element_dofs], (1, 2, 0))                     # (nel, k, 4)
    fields = coef @ F
    q = basis.dx.shape[1]
    w = (beta * basis.dx)[:, None, :]
    value, curvature = fields[:, :, :q], fields[:, :, q:]
    return (curvature ** 2 * w).sum(axis=(0, 2)) / (value ** 2 * w).sum(axis=(0, 2))
