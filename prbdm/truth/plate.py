"""Kirchhoff plate truth on the planform, clamped along the root edge (scikit-fem).

Strong form ``D lap^2 w = rho t omega^2 w`` with ``D = E t^3 / (12 (1 - nu^2))``, free edges
everywhere but ``x = 0``. With ``xi = x / L``, ``eta = y / L`` it becomes

    lap^2 w = lambda w,   omega = omega_p sqrt(lambda),   omega_p = (t/L^2) sqrt(E / (12 rho (1 - nu^2))),

and the weak form, for every v with v = dv/dn = 0 on the root edge, is

    a(w, v) = int (1 - nu) w_,ij v_,ij + nu lap(w) lap(v) dA = lambda int w v dA = lambda m(w, v).

Element: the Argyris triangle (quintic, C1, 21 DOFs: w and its first and second derivatives at
the vertices, the normal slope at the edge midpoints). It is conforming in H^2, so the discrete
eigenvalues are upper bounds that converge fast; the cheap nonconforming Morley triangle
(quadratic) converges at O(h^2) only. scikit-fem's own ``ElementTriArgyris`` loses its C1
property on small or thin elements (ill-conditioned global-monomial construction), so we use
the same element built in local coordinates, with all element matrices computed at once
(:class:`prbdm.truth._argyris.ArgyrisSpace`: exact integrals, batched numpy; scikit-fem's
per-form basis evaluation and assembly took about half of a solve).

Mesh (automatic, see :func:`plate_mesh`): a structured mesh mapped from the planform
(:mod:`prbdm.truth._mapped`) when the free edge stays within 45 degrees of the span, which gives
long right-angled elements on slender strips; otherwise an unstructured Delaunay triangulation
(:mod:`prbdm.truth._delaunay`) that conforms to every station exactly, graded toward the
clamped-free corner and the re-entrant free-edge corners (singular points of the plate solution),
toward short edges and across narrow parts. Eigenvalues: shift-invert Lanczos
(:class:`prbdm.truth._linalg.ShiftInvertLanczos`, a symmetric-mode LU without pivoting) on the
nondimensional, diagonally scaled matrices, then Rayleigh quotients from the fields.

Half model: the planform and the material are symmetric about the x axis, so every mode is
either symmetric (w(x, -y) = w(x, y)) or antisymmetric. Both families come from one half mesh
(y >= 0) and one pair of matrices, with different constraints on the symmetry line y = 0:

* symmetric: w_y = 0 and w_xy = 0 at the vertices, w_n = 0 at the edge midpoints;
* antisymmetric: w = w_x = w_xx = w_yy = 0 at the vertices.

These are exactly the even/odd subspaces of the Argyris space on the mirrored full mesh, so the
half model reproduces the full model's eigenvalues at a fraction of the cost. Antisymmetric
(torsional) modes have zero transverse participation by symmetry; they are solved only when asked
for (``--all-modes``). Mode selection: :mod:`prbdm.truth.modes`.
"""
from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu
from skfem import BilinearForm, LinearForm, MeshTri
from skfem.helpers import dd, ddot, trace

from ._argyris import ArgyrisSpace
from ._delaunay import half_planform_mesh
from ._linalg import ShiftInvertLanczos, grown, refined_inverse
from ._mapped import is_benign, mapped_half_mesh
from .modes import SECTION_HATS, SECTION_THRESHOLD, section_fraction, select_bending

__all__ = ["bending", "mass", "load", "plate_mesh", "solve_plate", "plate_omega_scale",
           "DEFAULT_ELEMENTS"]


@BilinearForm
def bending(u, v, w):
    """a(u, v) = int (1 - nu) u_,ij v_,ij + nu lap(u) lap(v)   (Kirchhoff, per unit D)."""
    return (1.0 - w.nu) * ddot(dd(u), dd(v)) + w.nu * trace(dd(u)) * trace(dd(v))


@BilinearForm
def mass(u, v, w):
    """m(u, v) = int u v   (per unit rho t)."""
    return u * v


@LinearForm
def load(v, w):
    """f(v) = int v: the modal force of a uniform transverse acceleration."""
    return v


#: default span-wise resolution: element size h0 = 1 / DEFAULT_ELEMENTS (nondimensional)
DEFAULT_ELEMENTS = 12
#: the symmetric family is searched up to this many modes for the requested bending modes
MAX_MODES_COMPUTED = 160
#: Lanczos convergence: ``||K^-1 M x - theta x||_M <= tol theta`` for every wanted pair. The
#: frequencies are Rayleigh quotients of the vectors, so their error is of the order of tol^2;
#: the vectors enter the participations and section fractions to about tol
LANCZOS_TOL = 1e-10


def plate_omega_scale(beam) -> float:
    """``omega_p = (t / L^2) sqrt(E / (12 rho (1 - nu^2)))`` = ``sqrt(D / (rho t)) / L^2``."""
    m = beam.material
    return beam.thickness / beam.length ** 2 * math.sqrt(m.E / (12.0 * m.rho * (1.0 - m.nu ** 2)))


def default_elements(modes: int) -> int:
    """Span-wise resolution for ``modes`` bending modes: the n-th bending mode has about n - 1/2
    half-waves along the span; the default resolves five with the accuracy measured in
    docs/validation.md, and grows with the number of modes asked for."""
    return DEFAULT_ELEMENTS + 2 * max(0, int(modes) - 5)


def plate_mesh(beam, elements: int | None = None, modes: int = 5, mesher: str = "auto",
               **kwargs):
    """The half-planform mesh (nondimensional coordinates) and a description of it.

    ``mesher``: ``"mapped"`` (structured, for planforms whose free edge stays within 45 degrees
    of the span and whose stations are not much closer than an element), ``"delaunay"``
    (unstructured, for anything) or ``"auto"`` (mapped when it is suitable).
    """
    n = default_elements(modes) if elements is None else int(elements)
    L = beam.length
    xs, ws = beam.x / L, beam.half_width / L
    if mesher == "auto":
        mesher = "mapped" if is_benign(xs, ws, 1.0 / n) else "delaunay"
    # each mesher takes its own options and ignores the other's
    mapped_keys = {"kappa", "root_levels", "root_ratio", "edge_ratio", "chord_elements"}
    if mesher == "mapped":
        p, t, info = mapped_half_mesh(xs, ws, h0=1.0 / n,
                                      **{k: v for k, v in kwargs.items() if k in mapped_keys})
    elif mesher == "delaunay":
        p, t, info = half_planform_mesh(xs, ws, h0=1.0 / n,
                                        **{k: v for k, v in kwargs.items()
                                           if k not in mapped_keys})
        info["mesher"] = "delaunay"
    else:
        raise ValueError(f"unknown mesher {mesher!r}")
    info["elements"] = n
    return MeshTri(p, t), info


def _section_operators(space, nodes):
    """``Hw[i, q] = hat_i(x_q) w_q`` and ``G[i, k] = int hat_i hat_k dA`` for the 1-D hat
    functions of x on ``nodes``, by the space's degree-10 quadrature (exact for the hats' products
    with the quintic basis on each element up to the quadrature order): ``Hw @ u(x_q)`` is
    ``int hat_i u dA`` for a field ``u`` given at the quadrature points."""
    xq, wq = space.xq, space.dx                              # (elements, points)
    nq = xq.size
    q = np.arange(nq)
    x = xq.ravel()
    k = np.clip(np.searchsorted(nodes, x, side="right") - 1, 0, len(nodes) - 2)
    tpar = (x - nodes[k]) / (nodes[k + 1] - nodes[k])
    H = sp.csr_matrix((np.concatenate([1 - tpar, tpar]), (np.concatenate([k, k + 1]),
                                                          np.concatenate([q, q]))),
                      shape=(len(nodes), nq))
    Hw = H @ sp.diags(wq.ravel())
    return Hw.tocsr(), (Hw @ H.T).tocsc()


def _rayleigh(space, phi, nu, Hw=None):
    """``a(phi, phi) / m(phi, phi)`` and ``m(phi, phi)`` for every column of ``phi``, from the
    fields at the quadrature points (a sum of positive terms: no cancellation); with ``Hw`` from
    :func:`_section_operators` also the section integrals ``int hat_i phi dA`` (hats, modes)."""
    val, (hxx, hxy, hyy) = space.fields(phi)                 # (elements, modes, points)
    w = space.dx[:, None, :]
    energy = ((1 - nu) * (hxx ** 2 + 2 * hxy ** 2 + hyy ** 2) + nu * (hxx + hyy) ** 2) * w
    m = (val ** 2 * w).sum(axis=(0, 2))
    sections = None
    if Hw is not None:
        sections = Hw @ np.transpose(val, (0, 2, 1)).reshape(-1, val.shape[1])
    return energy.sum(axis=(0, 2)) / m, m, sections


def _scaled(A, d):
    """``diag(d) A diag(d)`` of a CSR or CSC matrix (the same ``d`` on both sides, so the
    compressed and the stored index may be rows or columns), in place of its data."""
    rows = np.repeat(np.arange(A.shape[0]), np.diff(A.indptr))
    A.data *= d[rows] * d[A.indices]
    return A


def solve_plate(beam, modes: int, all_modes: bool = False, elements: int | None = None,
                selection: str = "section", **mesh_kwargs) -> dict:
    nu = beam.material.nu
    mesh, info = plate_mesh(beam, elements, modes, **mesh_kwargs)
    # element matrices built element-batched and exactly (prbdm.truth._argyris.ArgyrisSpace);
    # the same space as Basis(mesh, LocalArgyris()) with scikit-fem's assembly, at a fraction
    # of the cost
    space = ArgyrisSpace(mesh)
    Ke, Me = space.element_stiffness(nu), space.element_mass()
    f = space.load()
    ones = np.zeros(space.N)
    ones[space.nodal_dofs[0]] = 1.0                 # the constant 1 in the Argyris basis
    area = float(f @ ones)                          # nondimensional half area (= half mass)

    ymax = float(mesh.p[1].max())
    root = mesh.facets_satisfying(lambda x: x[0] < 1e-12)
    axis = mesh.facets_satisfying(lambda x: x[1] < 1e-12 * max(ymax, 1.0))
    clamped = space.get_dofs(root).all(["u", "u_x", "u_y", "u_xy", "u_yy", "u_n"])
    sym = space.get_dofs(axis).all(["u_y", "u_xy", "u_n"])
    anti = space.get_dofs(axis).all(["u", "u_x", "u_xx", "u_yy"])
    hats = np.linspace(0.0, 1.0, SECTION_HATS + 1)      # fixed: see prbdm.truth.modes
    Hw, G = _section_operators(space, hats)
    G_lu = splu(G)

    families = {"symmetric": np.setdiff1d(np.arange(space.N), np.union1d(clamped, sym))}
    if all_modes:
        families["antisymmetric"] = np.setdiff1d(np.arange(space.N), np.union1d(clamped, anti))
    want = int(modes)
    found = {}
    for name, free in families.items():
        Kf, Mf = space.assemble([Ke, Me], free)
        # symmetric diagonal scaling: the Argyris DOFs (w, slopes, curvatures) scale like
        # 1, h^-1, h^-2; D K D has a unit diagonal, the same eigenvalues with D M D, and a far
        # smaller condition number for the sparse LU
        d = 1.0 / np.sqrt(Kf.diagonal())
        Kf, Mf = _scaled(Kf, d), _scaled(Mf, d)
        # K is symmetric positive definite (clamped root): a symmetric-mode LU without pivoting
        op = refined_inverse(Kf, steps=0, spd=True)   # eigenvalues from the Rayleigh quotients
        n = Kf.shape[0]
        cap = min(n - 2, MAX_MODES_COMPUTED)
        k = min(cap, max(2 * want + 4, 12))
        # shift-invert Lanczos (prbdm.truth._linalg.ShiftInvertLanczos): ARPACK's criterion at
        # tol 1e-10, a fixed start vector; a second round (more modes) extends the same basis
        lanczos = ShiftInvertLanczos(op.matvec, Mf, np.ones(n), tol=LANCZOS_TOL)
        while True:
            lam, vec = lanczos.eigs(k)
            vec = vec * d[:, None]
            phi = np.zeros((space.N, k))
            phi[free] = vec
            # Rayleigh quotients from the fields (sums of positive terms, no cancellation)
            lam, modal_mass, sections = _rayleigh(space, phi, nu, Hw)
            order = np.argsort(lam, kind="stable")
            lam, phi, modal_mass = lam[order], phi[:, order], modal_mass[order]
            sections = sections[:, order]
            if name == "antisymmetric":
                zero = np.zeros(k)
                found[name] = (lam, phi, zero, zero, np.zeros(k, bool))
                break
            part = (f @ phi) ** 2 / (modal_mass * area)
            frac = section_fraction(sections, G_lu, modal_mass)
            kept, complete = select_bending(part, frac, want, selection)
            if complete or k >= cap:
                found[name] = (lam, phi, part, frac, kept)
                break
            k = min(cap, grown(k))

    lam_s, phi_s, part_s, frac_s, kept_s = found["symmetric"]
    kept_idx = np.flatnonzero(kept_s)
    if len(kept_idx) < want:
        raise ValueError(f"found only {len(kept_idx)} bending modes among the first "
                         f"{len(lam_s)} symmetric modes")
    entries = []
    for name, (lam, _phi, part, frac, kept) in found.items():
        for i in range(len(lam)):
            entries.append({"lambda": float(lam[i]), "participation": float(part[i]),
                            "section_fraction": float(frac[i]), "symmetry": name,
                            "kept": bool(kept[i]),
                            # within 0.1 of the threshold: mixed bending/chordwise, a choice
                            # that finer meshes or small planform changes may flip
                            "ambiguous": bool(name == "symmetric"
                                              and abs(frac[i] - SECTION_THRESHOLD) < 0.1)})
    entries.sort(key=lambda e: e["lambda"])
    if all_modes:
        # the two families were computed to different heights: list the modes up to the
        # highest eigenvalue both reached (and every kept one), so that no mode is missing
        top = min(found["symmetric"][0][-1], found["antisymmetric"][0][-1])
        entries = [e for e in entries if e["lambda"] <= top * (1 + 1e-12) or e["kept"]]
    values = phi_s[space.nodal_dofs[0]][:, kept_idx]
    scale = values[np.argmax(np.abs(values), axis=0), np.arange(len(kept_idx))]
    scale[scale == 0] = 1.0
    info["below_threshold_kept"] = int(np.sum(frac_s[kept_idx] < SECTION_THRESHOLD))
    info.update({"element": "Argyris triangle (C1 quintic), half model",
                 "dofs": int(space.N), "triangles": int(mesh.t.shape[1]),
                 "symmetric_modes_computed": int(len(lam_s)), "selection": selection})
    return {"lam": lam_s[kept_idx], "participation": part_s[kept_idx], "entries": entries,
            "shapes": {"kind": "plate", "p": mesh.p, "t": mesh.t, "w": (values / scale).T},
            "mesh": info}
