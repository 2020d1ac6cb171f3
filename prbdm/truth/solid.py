"""A 3-D linear-elasticity check of the plate truth (issue 16 item 2): what Kirchhoff leaves out.

Not a truth model of its own (``prbdm truth`` does not offer it): an independent reference that
keeps what the Kirchhoff plate neglects (transverse shear, rotary inertia, through-thickness
stress), used by ``benchmarks/plate_vs_solid.py`` and docs/validation.md.

Model: isotropic linear elasticity, ``div sigma = -rho omega^2 u``, on the half panel
``0 <= x <= L``, ``0 <= y <= w(x)``, ``|z| <= t / 2``; clamped root (``u = 0`` on ``x = 0``),
free elsewhere, and ``u_y = 0`` on the symmetry plane ``y = 0``: the symmetric family, which holds
every out-of-plane bending mode (the antisymmetric family, torsion and in-plane sway, has no
transverse participation).

Mesh: a structured box ``[0, 1] x [0, 1] x [-1/2, 1/2]`` of trilinear hexahedra mapped node by
node to ``(x, r w(x), z t)``. Every station of the planform is a node line in x, so w(x) is linear
inside each element and the trilinear map is exact: the discrete geometry is the planform itself.
Element: 27-node triquadratic Lagrange (scikit-fem ``ElementHex2``, vector-valued), which bends
without the shear locking of linear hexahedra even at element aspect ratios of tens to one.

Nondimensional (float64): lengths by L, stresses by E, mass by rho, so
``lambda = omega^2 rho L^2 / E`` and the matrices have entries of order one for any material.
Eigenvalues: shift-invert Lanczos at sigma = 0 (the clamped problem is positive definite).

Mode selection, as in :mod:`prbdm.truth.modes` for the plate: a mode is a bending mode when more
than half its modal mass (all three components) is carried by the transverse translation ``u_z``
of its chord sections (``section_fraction >= 1/2``); the whole-body participation of ``u_z`` is
reported beside it. Axial and chordwise in-plane modes of the symmetric family carry almost no
``u_z`` and are never kept.
"""
from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import LinearOperator, eigsh, splu
from skfem import Basis, BilinearForm, ElementHex2, ElementVector, LinearForm, MeshHex
from skfem.helpers import ddot, sym_grad, trace

from .modes import SECTION_THRESHOLD, section_fraction, select_bending
from .plate import DEFAULT_ELEMENTS

__all__ = ["solid_mesh", "solve_solid", "solid_frequencies", "DEFAULT_LEVEL"]

#: mesh level of :func:`solid_mesh` (0: coarsest); the benchmark compares it with level + 1
DEFAULT_LEVEL = 0
#: quadrature order of the element matrices (see solve_solid)
INTORDER = 5
#: the symmetric family is searched up to this many modes for the requested bending modes
MAX_MODES_COMPUTED = 120


def _span_nodes(xs: np.ndarray, h: float) -> np.ndarray:
    """Node coordinates along the span: every station, and each station interval cut into
    ``ceil(length / h)`` equal elements (at least one)."""
    parts = [xs[:1]]
    for a, b in zip(xs[:-1], xs[1:]):
        n = max(1, int(math.ceil((b - a) / h - 1e-9)))
        parts.append(np.linspace(a, b, n + 1)[1:])
    return np.concatenate(parts)


def solid_mesh(beam, level: int = DEFAULT_LEVEL):
    """The mapped hexahedral mesh of the half panel (nondimensional) and its description.

    Each ``level`` halves the element size in every direction of the box:

    * span: element size ``1 / (16 2^level)``, every station a node, and the first element cut
      geometrically toward the clamp ``4 + level`` times (the 3-D solution is singular along
      the clamped edge, where the clamp stops the Poisson contraction; without this grading the
      first frequency came out 0.2 % high);
    * chord: ``4 2^level`` elements, clustered toward the free edge (cosine spacing), where the
      3-D field has a boundary layer about a thickness wide that Kirchhoff theory leaves out;
    * thickness: ``2 + level`` elements.
    """
    level = int(level)
    if level < 0:
        raise ValueError("level must be >= 0")
    L = beam.length
    xs, ws, tt = beam.x / L, beam.half_width / L, beam.thickness / L
    sx = _span_nodes(xs, 1.0 / (16 * 2 ** level))
    sx = np.unique(np.concatenate([sx, sx[1] * 0.5 ** np.arange(1, 5 + level)]))
    ny = 4 * 2 ** level
    nz = 2 + level
    sy = np.sin(0.5 * np.pi * np.linspace(0.0, 1.0, ny + 1))
    sy[-1] = 1.0
    sz = np.linspace(-0.5, 0.5, nz + 1)
    box = MeshHex.init_tensor(sx, sy, sz)
    p = box.p.copy()
    p[1] = p[1] * np.interp(p[0], xs, ws)
    p[2] = p[2] * tt
    mesh = MeshHex(p, box.t)
    info = {"level": level, "span_elements": len(sx) - 1, "chord_elements": ny,
            "thickness_elements": nz, "hexahedra": int(mesh.t.shape[1])}
    return mesh, info


@BilinearForm
def _stiffness(u, v, w):
    """int sigma(u) : eps(v), E = 1."""
    eu, ev = sym_grad(u), sym_grad(v)
    lam = w.nu / ((1 + w.nu) * (1 - 2 * w.nu))
    mu = 0.5 / (1 + w.nu)
    return 2 * mu * ddot(eu, ev) + lam * trace(eu) * trace(ev)


@BilinearForm
def _mass(u, v, w):
    """int u . v, rho = 1."""
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


@LinearForm
def _transverse(v, w):
    """int v_z: the modal force of a uniform transverse acceleration."""
    return v[2]


def _section_operators(basis, nodes):
    """``B[i, j] = int hat_i(x) (phi_j)_z dV`` and the Gram matrix ``G[i, k] = int hat_i hat_k
    dV`` of the span-wise hat functions on ``nodes``: the transverse section projection of
    :func:`prbdm.truth.modes.section_fraction`, by the basis's own quadrature."""
    xq = basis.mapping.F(basis.X)[0]
    wq = basis.dx
    nel, nqp = xq.shape
    q = np.arange(nel * nqp)
    x = xq.ravel()
    k = np.clip(np.searchsorted(nodes, x, side="right") - 1, 0, len(nodes) - 2)
    tpar = (x - nodes[k]) / (nodes[k + 1] - nodes[k])
    H = sp.csr_matrix((np.concatenate([1 - tpar, tpar]),
                       (np.concatenate([k, k + 1]), np.concatenate([q, q]))),
                      shape=(len(nodes), nel * nqp))
    Hw = H @ sp.diags(wq.ravel())
    rows, cols, vals = [], [], []
    for j in range(basis.Nbfun):
        rows.append(q)
        cols.append(np.repeat(basis.element_dofs[j], nqp))
        vals.append(np.asarray(basis.basis[j][0])[2].ravel())
    Phi = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                        shape=(nel * nqp, basis.N))
    return (Hw @ Phi).tocsr(), (Hw @ H.T).tocsc()


def solve_solid(beam, modes: int, level: int = DEFAULT_LEVEL) -> dict:
    """The first ``modes`` symmetric bending modes of the 3-D half panel.

    Returns ``lam`` (nondimensional ``omega^2 rho L^2 / E``), ``omega`` [rad/s], ``freq_hz``,
    ``participation`` and ``section_fraction`` of the kept modes, ``entries`` (every computed
    symmetric mode), ``mesh`` (its description and DOF count).
    """
    want = int(modes)
    mesh, info = solid_mesh(beam, level)
    # 3 Gauss points per direction: exact for the Q2 x Q2 products on an affine element (the
    # default rule, 7 per direction, costs 12x as much and changes nothing measurable)
    basis = Basis(mesh, ElementVector(ElementHex2()), intorder=INTORDER)
    nu = beam.material.nu
    K = _stiffness.assemble(basis, nu=nu)
    M = _mass.assemble(basis)
    f = _transverse.assemble(basis)
    root = basis.get_dofs(lambda x: x[0] < 1e-12).all()
    ymax = float(mesh.p[1].max())
    axis = basis.get_dofs(lambda x: x[1] < 1e-12 * max(ymax, 1.0)).all("u^2")
    fixed = np.union1d(root, axis)
    free = np.setdiff1d(np.arange(basis.N), fixed)
    volume = float(basis.dx.sum())                 # nondimensional half volume (= half mass)
    # the same span-wise hats as the plate truth, so both pick modes by the same measure
    hats = np.linspace(0.0, 1.0, 4 * DEFAULT_ELEMENTS + 1)
    B, G = _section_operators(basis, hats)
    G_lu = splu(G)

    Kf, Mf = K[free][:, free].tocsc(), M[free][:, free].tocsc()
    lu = splu(Kf)
    op = LinearOperator(Kf.shape, matvec=lu.solve, dtype=np.float64)
    n = Kf.shape[0]
    cap = min(n - 2, MAX_MODES_COMPUTED)
    k = min(cap, max(3 * want + 6, 16))
    while True:
        lam, vec = eigsh(Kf, k=k, M=Mf, sigma=0.0, which="LM", OPinv=op,
                         v0=np.ones(n))
        order = np.argsort(lam)
        lam, vec = lam[order], vec[:, order]
        phi = np.zeros((basis.N, k))
        phi[free] = vec
        modal_mass = np.einsum("ik,ik->k", phi, M @ phi)
        part = (f @ phi) ** 2 / (modal_mass * volume)
        frac = section_fraction(B @ phi, G_lu, modal_mass)
        kept, complete = select_bending(part, frac, want, "section")
        if complete or k >= cap:
            break
        k = min(cap, 2 * k)
    idx = np.flatnonzero(kept)
    if len(idx) < want:
        raise ValueError(f"found only {len(idx)} bending modes among {k} symmetric modes")
    m = beam.material
    scale = math.sqrt(m.E / m.rho) / beam.length
    omega = scale * np.sqrt(lam[idx])
    entries = [{"lambda": float(lam[i]), "freq_hz": float(scale * math.sqrt(max(lam[i], 0))
                                                          / (2 * math.pi)),
                "participation": float(part[i]), "section_fraction": float(frac[i]),
                "kept": bool(kept[i])} for i in range(k)]
    info.update({"element": "27-node hexahedron (Q2), half model, u_y = 0 on y = 0",
                 "dofs": int(basis.N), "free_dofs": int(n), "symmetric_modes_computed": int(k),
                 "below_threshold_kept": int(np.sum(frac[idx] < SECTION_THRESHOLD))})
    return {"lam": lam[idx], "omega": omega, "freq_hz": omega / (2 * math.pi),
            "participation": part[idx], "section_fraction": frac[idx], "entries": entries,
            "mesh": info}


def solid_frequencies(beam, modes: int = 4, level: int = DEFAULT_LEVEL) -> np.ndarray:
    """The first ``modes`` symmetric bending frequencies [Hz] of the 3-D model."""
    return solve_solid(beam, modes, level)["freq_hz"]
