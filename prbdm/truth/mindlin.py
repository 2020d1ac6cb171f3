"""Reissner-Mindlin plate truth: the Kirchhoff plate plus transverse shear and rotary inertia.

Unknowns: the deflection ``w`` and the rotation vector ``beta = (beta_x, beta_y)``, written as
the slopes of the normal (``beta ~ grad w`` in the thin limit; ``beta_x`` tilts the normal in the
x-z plane). Energies per unit plate, with ``D = E t^3 / (12 (1 - nu^2))``, ``G = E / (2 (1 + nu))``
and the shear factor ``kappa = 5/6``:

    U = 1/2 int D [(1 - nu) eps(beta) : eps(beta) + nu div(beta)^2]
              + kappa G t |grad w - beta|^2 dA,             eps = sym grad beta,
    T = 1/2 omega^2 int rho t w^2 + rho t^3 / 12 |beta|^2 dA.

Nondimensional form: ``xi = x / L``, ``W = w / L``, frequencies by the Kirchhoff plate's own scale
``omega_p = sqrt(D / (rho t)) / L^2`` (:func:`prbdm.truth.plate.plate_omega_scale`), so that
``omega = omega_p sqrt(lambda)`` as for the plate and ``lambda`` is independent of E and rho:

    a_b(beta, beta) + alpha a_s(W, beta) = lambda [ m(W, W) + tau^2 / 12 m(beta, beta) ],
    tau = t / L,   alpha = kappa G t L^2 / D = 6 kappa (1 - nu) / tau^2.

Unlike the Kirchhoff plate, ``lambda`` depends on ``tau``: the shear term carries ``1 / tau^2``
(shear flexibility lowers the frequencies by a relative ``O(tau^2 n^2)`` for the n-th mode) and
the rotary inertia ``tau^2``. As ``tau -> 0`` the shear term forces ``beta = grad W`` and the
problem becomes the Kirchhoff plate's.

Element: equal-order Lagrange triangles of degree ``degree`` (default 4, scikit-fem's
``ElementTriP4``) for all three fields. Low-order equal interpolation locks (the constraint
``grad W = beta`` with continuous ``beta`` is satisfied only by C1 deflections, which low-degree
continuous piecewise polynomials contain few of), and its error falls quickly with the degree.
Measured at t/L = 0.001 on the default mesh (docs/validation.md, "``mindlin``: a shear-deformable
plate truth"; Kirchhoff is exact to ~1e-5 there), ``mindlin / plate - 1`` on modes 1-4: P2 +0.7
to +5 % (locked), P3 +0.02 to +0.11 %, P4 within 2e-5; the paper's panels (t/L 0.01-0.05) are
thicker, hence further from locking. Mesh convergence of P4, default (``elements`` 12) against
24: at most 1e-4 on modes 1-4 over the twelve panels of benchmarks/mindlin_vs_solid.py. Against
3-D elasticity on the Table-2 beam (t/L = 0.041): -0.08/-0.11/-0.15/-0.21 % (Kirchhoff
+0.29/+0.99/+2.27/+4.08 %). MITC/mixed elements would be locking-free at any thickness but need
an edge-element shear interpolation, which these numbers did not call for.

Mesh: the Kirchhoff plate's own half mesh (:func:`prbdm.truth.plate.plate_mesh`), with the same
options. Half model, symmetric (bending) family only: ``w(x, -y) = w(x, y)`` makes ``w`` and
``beta_x`` even in y and ``beta_y`` odd, so ``beta_y = 0`` on ``y = 0`` and ``w``, ``beta_x`` are
free there. Clamped root: ``w = beta_x = beta_y = 0`` on ``x = 0``. Eigenvalues: shift-invert
Lanczos (:class:`prbdm.truth._linalg.ShiftInvertLanczos`) on the diagonally scaled matrices;
bending modes selected on the deflection field by :mod:`prbdm.truth.modes`, as for the plate.
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu
from skfem import Basis, ElementTriP2, ElementTriP3, ElementTriP4

from ._linalg import CondensedInverse, ShiftInvertLanczos, grown
from .modes import SECTION_HATS, SECTION_THRESHOLD, section_fraction, select_bending
from .plate import _scaled, _section_operators, plate_mesh

__all__ = ["solve_mindlin", "shear_stiffness", "SHEAR_FACTOR", "DEFAULT_DEGREE", "DEGREES"]

#: Reissner's / Mindlin's shear correction factor for a homogeneous plate
SHEAR_FACTOR = 5.0 / 6.0
#: t / L from which the Lanczos's LU solves go without iterative refinement (solve_mindlin)
NO_REFINEMENT_FROM = 1e-3
#: polynomial degree of the Lagrange triangles (w, beta_x, beta_y)
DEFAULT_DEGREE = 4
DEGREES = {2: ElementTriP2, 3: ElementTriP3, 4: ElementTriP4}
#: as in prbdm.truth.plate
MAX_MODES_COMPUTED = 160
LANCZOS_TOL = 1e-10


def shear_stiffness(tau: float, nu: float, kappa: float = SHEAR_FACTOR) -> float:
    """``alpha = kappa G t L^2 / D = 6 kappa (1 - nu) / tau^2``, the nondimensional shear
    stiffness relative to the bending stiffness (``tau = t / L``)."""
    return 6.0 * kappa * (1.0 - nu) / tau ** 2


def _sparse(triplets, size: int, keep=None, fmt: str = "csr"):
    """The sum of element matrices into a ``size`` x ``size`` sparse matrix: ``triplets`` lists
    ``(values (E, a, b), row dofs (E, a), column dofs (E, b))``. With ``keep`` (ascending DOF
    numbers) only those rows and columns, renumbered in that order: the free DOFs' matrix without
    building and slicing the whole one."""
    rows = np.concatenate([np.broadcast_to(r[:, :, None], v.shape).ravel() for v, r, _ in triplets])
    cols = np.concatenate([np.broadcast_to(c[:, None, :], v.shape).ravel() for v, _, c in triplets])
    data = np.concatenate([v.ravel() for v, _, _ in triplets])
    if keep is not None:
        number = np.full(size, -1)
        number[keep] = np.arange(len(keep))
        rows, cols = number[rows], number[cols]
        inside = (rows >= 0) & (cols >= 0)
        rows, cols, data, size = rows[inside], cols[inside], data[inside], len(keep)
    return sp.coo_matrix((data, (rows, cols)), shape=(size, size)).asformat(fmt)


def _element_matrices(basis, nu: float, tau: float, kappa: float):
    """Every element's stiffness ``Ke`` (E, 3 B, 3 B), on ``[W, beta_x, beta_y]`` field-major
    (field ``a``, local function ``i`` at ``a B + i``), its one-field mass matrix ``MM``
    (E, B, B) and the load vector ``int W`` (N,) of a uniform transverse acceleration.

    All element matrices at once: each scalar integral below is one ``einsum`` over (element,
    test function, trial function) on the basis's own quadrature. scikit-fem's
    ``BilinearForm`` would loop over the 15 x 15 pairs of P4 functions once per form, seven
    forms: several times slower for the same matrix (tests/test_mindlin.py checks the two
    against each other)."""
    N = basis.N
    phi = np.stack([np.asarray(f[0]) for f in basis.basis])            # (B, E, Q)
    grad = np.stack([f[0].grad for f in basis.basis], axis=1)          # (2, B, E, Q)
    dX, dY, dx = grad[0], grad[1], basis.dx

    def gram(a, b):               # [e, i, j] = int a_i b_j over element e (i test, j trial)
        return np.einsum("ieq,jeq,eq->eij", a, b, dx, optimize=True)

    XX, YY, XY = gram(dX, dX), gram(dY, dY), gram(dX, dY)
    MM, GX, GY = gram(phi, phi), gram(phi, dX), gram(phi, dY)
    swap = (0, 2, 1)                                       # test <-> trial
    a = shear_stiffness(tau, nu, kappa)
    c = 0.5 * (1.0 - nu)
    # bending, per unit D: (1 - nu) eps:eps + nu div^2 with eps_xy = (bx_y + by_x) / 2;
    # block (test beta_y, trial beta_x) = int c bx_y by_x + nu bx_x by_y.
    # Shear, alpha |grad W - beta|^2: W-W alpha lap, beta-beta alpha mass, W-beta -alpha.
    # Rows: test field; columns: trial field; fields in the order W, beta_x, beta_y.
    yx = c * XY + nu * XY.transpose(swap)
    B = phi.shape[0]
    Ke = np.empty((XX.shape[0], 3 * B, 3 * B))                                    # (E, 3B, 3B)
    W, X, Y = slice(0, B), slice(B, 2 * B), slice(2 * B, 3 * B)
    np.multiply(a, XX + YY, out=Ke[:, W, W])
    np.multiply(-a, GX.transpose(swap), out=Ke[:, W, X])
    np.multiply(-a, GY.transpose(swap), out=Ke[:, W, Y])
    np.multiply(-a, GX, out=Ke[:, X, W])
    Ke[:, X, X] = XX + c * YY + a * MM
    Ke[:, X, Y] = yx.transpose(swap)
    np.multiply(-a, GY, out=Ke[:, Y, W])
    Ke[:, Y, X] = yx
    Ke[:, Y, Y] = YY + c * XX + a * MM
    el = basis.element_dofs.T                                                        # (E, B)
    load = np.bincount(el.ravel(), weights=np.einsum("ieq,eq->ei", phi, dx).ravel(),
                       minlength=N)
    return Ke, MM, load


def _matrices(basis, nu: float, tau: float, kappa: float, keep=None):
    """Stiffness ``K`` (CSC) and mass ``M`` (CSR) on the unknowns ``[W, beta_x, beta_y]`` (each
    ``basis.N``; with ``keep`` only those DOFs, as :func:`_sparse`), the load vector ``f``
    (``int W``, every DOF) of a uniform transverse acceleration and the mass matrix ``M0`` of one
    field (``N`` x ``N``, CSR): the assembled form of :func:`_element_matrices` (the solver
    itself condenses the element matrices instead, :class:`prbdm.truth._linalg.CondensedInverse`).
    """
    N = basis.N
    Ke, MM, load = _element_matrices(basis, nu, tau, kappa)
    el = basis.element_dofs.T
    dofs = np.concatenate([el + s * N for s in range(3)], axis=1)                    # (E, 3B)
    K = _sparse([(Ke, dofs, dofs)], 3 * N, keep, "csc")
    r = tau ** 2 / 12.0
    M = _sparse([(MM, el, el), (r * MM, el + N, el + N), (r * MM, el + 2 * N, el + 2 * N)],
                3 * N, keep)
    M0 = _sparse([(MM, el, el)], N)
    return K, M, np.concatenate([load, np.zeros(2 * N)]), M0


def _field_mass(M0, r: float, keep):
    """``diag(M0, r M0, r M0)`` (CSR), the rows and columns ``keep`` only: the three fields'
    mass matrix from the one-field ``M0`` without a second assembly."""
    M0 = M0.tocsr()
    nnz, N = M0.nnz, M0.shape[0]
    M = sp.csr_matrix((np.concatenate([M0.data, r * M0.data, r * M0.data]),
                       np.concatenate([M0.indices, M0.indices + N, M0.indices + 2 * N]),
                       np.concatenate([M0.indptr, M0.indptr[1:] + nnz,
                                       M0.indptr[1:] + 2 * nnz])), shape=(3 * N, 3 * N))
    return M[keep][:, keep]


def solve_mindlin(beam, modes: int, elements: int | None = None, selection: str = "section",
                  degree: int = DEFAULT_DEGREE, shear_factor: float = SHEAR_FACTOR,
                  refinement_steps: int | None = None, **mesh_kwargs) -> dict:
    """The kept symmetric bending modes: ``lam`` (nondimensional, ``omega = omega_p
    sqrt(lam)``), ``participation``, ``entries`` (every computed symmetric mode), ``shapes``
    and ``mesh``, as :func:`prbdm.truth.plate.solve_plate` returns them.

    ``refinement_steps``: iterative refinement of the LU solves inside the Lanczos; None: none
    from t/L = ``NO_REFINEMENT_FROM`` up, one below. The eigenvalues are Rayleigh quotients of the
    unfactored matrices, and one step changed them by at most 5e-8 at t/L = 0.001 and 5e-9 on
    the paper's panels while making the solve 1.33x slower (benchmarks/bench_mindlin.py); below
    t/L = 0.001 (the shear term ~ (L/t)^2 conditions K ever worse) it is kept, unmeasured."""
    if degree not in DEGREES:
        raise ValueError(f"degree must be one of {sorted(DEGREES)}, got {degree!r}")
    nu = beam.material.nu
    tau = beam.thickness / beam.length
    mesh, info = plate_mesh(beam, elements, modes, **mesh_kwargs)
    basis = Basis(mesh, DEGREES[degree]())
    N = basis.N

    ymax = float(mesh.p[1].max())
    root = mesh.facets_satisfying(lambda x: x[0] < 1e-12)
    axis = mesh.facets_satisfying(lambda x: x[1] < 1e-12 * max(ymax, 1.0))
    root_dofs = basis.get_dofs(root).flatten()
    axis_dofs = basis.get_dofs(axis).flatten()
    # clamped root: all three fields; symmetry line: beta_y (the odd field) only
    fixed = np.unique(np.concatenate([root_dofs, root_dofs + N, root_dofs + 2 * N,
                                      axis_dofs + 2 * N]))
    free = np.setdiff1d(np.arange(3 * N), fixed)
    n = len(free)
    Ke, MM, load = _element_matrices(basis, nu, tau, shear_factor)
    el = basis.element_dofs.T
    M0 = _sparse([(MM, el, el)], N)
    f = np.concatenate([load, np.zeros(2 * N)])
    area = float(f.sum())

    # section fractions of the deflection field, on the plate's span-wise hats
    xq = np.asarray(basis.global_coordinates())[0]
    shape_q = np.stack([np.asarray(fn[0]) for fn in basis.basis])     # (function, element, point)
    quad = SimpleNamespace(xq=xq, dx=basis.dx)
    hats = np.linspace(0.0, 1.0, SECTION_HATS + 1)      # fixed: see prbdm.truth.modes
    Hw, G = _section_operators(quad, hats)
    G_lu = splu(G)

    # diagonal scaling as in the plate: unit diagonal for K, a far better conditioned LU; the
    # fixed DOFs scaled by 0, which takes their rows and columns out of the element matrices
    E, B = el.shape
    dofs = (np.arange(3)[None, :, None] * N + el[:, None, :]).reshape(E, 3 * B)
    diag = np.bincount(dofs.ravel(), weights=np.einsum("eii->ei", Ke).ravel(), minlength=3 * N)
    dfull = np.zeros(3 * N)
    dfull[free] = 1.0 / np.sqrt(diag[free])
    d = dfull[free]
    ds = dfull[dofs]
    Ke *= ds[:, :, None] * ds[:, None, :]
    Mf = _scaled(_field_mass(M0, tau ** 2 / 12.0, free), d)
    number = np.full(3 * N, n)
    number[free] = np.arange(n)
    # no refinement of the solves by default (see refinement_steps): Rayleigh quotients of the
    # unfactored K and M below make the eigenvalues insensitive to the factorisation's rounding
    if refinement_steps is None:
        refinement_steps = 0 if tau >= NO_REFINEMENT_FROM else 1
    # K^-1 with the element-interior (bubble) DOFs condensed: exact, and the factorised matrix
    # has 2/3 of the DOFs (prbdm.truth._linalg.CondensedInverse)
    interior = np.arange(B - basis.elem.interior_dofs, B)
    op = CondensedInverse(Ke, el, N, interior, number, n, steps=int(refinement_steps))
    want = int(modes)
    cap = min(n - 2, MAX_MODES_COMPUTED)
    k = min(cap, max(2 * want + 4, 12))
    lanczos = ShiftInvertLanczos(op.solve, Mf, np.ones(n), tol=LANCZOS_TOL)
    while True:
        _, vec = lanczos.eigs(k)
        phi = np.zeros((3 * N, k))
        phi[free] = vec * d[:, None]
        # Rayleigh quotients of the unscaled fields (phi = 0 on the fixed DOFs: the free DOFs'
        # matrices, scaled by d, act on the scaled vectors)
        modal_mass = np.einsum("ik,ik->k", vec, Mf @ vec)
        lam = op.quadratic(vec) / modal_mass
        order = np.argsort(lam, kind="stable")
        lam, phi, modal_mass = lam[order], phi[:, order], modal_mass[order]
        # the deflections at the quadrature points, (element, point, mode)
        wq = np.einsum("ieq,iek->eqk", shape_q, phi[:N][basis.element_dofs], optimize=True)
        sections = Hw @ wq.reshape(-1, k)
        # the plate's selection measures, on the deflection's own (translational) modal mass:
        # with the rotary inertia in it, both would sit lower by about (t/L)^2/12 of the
        # rotations' share and could flip a close call near 1/2 that the plate keeps
        mass_w = np.einsum("ik,ik->k", phi[:N], M0 @ phi[:N])
        part = (f @ phi) ** 2 / (mass_w * area)
        frac = section_fraction(sections, G_lu, mass_w)
        kept, complete = select_bending(part, frac, want, selection)
        if complete or k >= cap:
            break
        k = min(cap, grown(k))

    kept_idx = np.flatnonzero(kept)
    if len(kept_idx) < want:
        raise ValueError(f"found only {len(kept_idx)} bending modes among the first "
                         f"{len(lam)} symmetric modes")
    entries = [{"lambda": float(lam[i]), "participation": float(part[i]),
                "section_fraction": float(frac[i]), "symmetry": "symmetric",
                "kept": bool(kept[i]),
                "ambiguous": bool(abs(frac[i] - SECTION_THRESHOLD) < 0.1)}
               for i in range(len(lam))]
    values = phi[basis.nodal_dofs[0]][:, kept_idx]        # W at the mesh vertices
    scale = values[np.argmax(np.abs(values), axis=0), np.arange(len(kept_idx))]
    scale[scale == 0] = 1.0
    info["below_threshold_kept"] = int(np.sum(frac[kept_idx] < SECTION_THRESHOLD))
    info.update({"element": f"Lagrange P{degree} triangles (w, beta_x, beta_y), Reissner-Mindlin,"
                            " half model",
                 "degree": int(degree), "dofs": int(3 * N), "triangles": int(mesh.t.shape[1]),
                 "thickness_ratio": float(tau), "shear_factor": float(shear_factor),
                 "symmetric_modes_computed": int(len(lam)), "selection": selection})
    return {"lam": lam[kept_idx], "participation": part[kept_idx], "entries": entries,
            "shapes": {"kind": "plate", "p": mesh.p, "t": mesh.t, "w": (values / scale).T},
            "mesh": info}
