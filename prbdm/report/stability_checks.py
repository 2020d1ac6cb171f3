"""Harness and independent references of the stability suite (cases: ``stability_cases.py``).

A case fills a :class:`Row` with checks: ``row.check(name, value, tol)`` passes when ``value`` is
finite and ``value <= tol``, or when ``ok`` is given, on ``ok``; ``key=True`` marks the accuracy
the case is summarised by. :func:`run_case` turns a :class:`Case` into one dict (checks,
condition numbers, gradient finiteness, time); an unexpected exception is a failed row, never a
crash. Used by ``tests/test_stability.py`` (one pytest case per suite case) and by
:mod:`prbdm.report.stability` (the table in docs/stability.md, ``prbdm report``,
``benchmarks/stability.py``).

The references here are independent of the code under test: the analytic Euler-Bernoulli
cantilever (``cos a cosh a = -1``), the mesh-free shooting solution of the variable-width beam
ODE, the rigid-finite-element chain's convergence bound. Condition numbers are those of the
matrices actually used: ``M`` (nondimensional, largest over the poses), ``K = diag(s)`` (joint
stiffnesses, nondimensional), ``A = K^-1/2 M K^-1/2`` (the symmetric problem that
:func:`prbdm.model.eigenvalues_unit_k` hands to ``eigvalsh``), and for cases with a beam truth
the FEM stiffness before and after the diagonal scaling that :mod:`prbdm.truth.beam` applies
before its LU.
"""
from __future__ import annotations

import math
import time
import traceback
from dataclasses import dataclass, field

import numpy as np

from prbdm.errors import BadInput
from prbdm.geometry import STEEL, Beam, Material

EPS32 = float(np.finfo(np.float32).eps)
ALUMINIUM = Material(E=70e9, rho=2700.0, nu=0.33)
TITANIUM = Material(E=114e9, rho=4430.0, nu=0.34)
ELASTOMER = Material(E=5e6, rho=1100.0, nu=0.49)
#: a link layout away from every symmetry, inside the bounds
GAMMA4 = [0.3, 0.15, 0.2, 0.2, 0.15]
#: |omega_RFE / omega_EB - 1| * n^2 for the uniform cantilever tends to 0.2294, 0.7971, 1.3078
#: (modes 1-3) from above; mode 1 stays below 0.25 for every n >= 2 (0.2433 at n = 2), modes 2-3
#: below 0.85 and 1.35 from n = 4 on (measured, benchmarks/bench_model.py --convergence)
RFE_BOUND = (0.25, 0.85, 1.35)


# ============================================================================ bookkeeping
@dataclass
class Row:
    checks: list = field(default_factory=list)
    cond: dict = field(default_factory=dict)
    grad_finite: bool | None = None
    note: str = ""
    key: dict | None = None
    extra: dict = field(default_factory=dict)

    def check(self, name: str, value, tol=None, ok=None, key=False):
        """``value <= tol`` (finite) unless ``ok`` is given; value may be None for yes/no.
        ``key``: the accuracy this case is summarised by in the table."""
        if ok is None:
            ok = value is not None and math.isfinite(value) and value <= tol
        c = {"check": name, "value": None if value is None else float(value),
             "tol": None if tol is None else float(tol), "passed": bool(ok)}
        self.checks.append(c)
        if key:
            self.key = c
        return ok

    def conds(self, **kw):
        for k, v in kw.items():
            if v is not None:
                self.cond[k] = max(self.cond.get(k, 0.0), float(v))

    def grads(self, ok: bool):
        self.grad_finite = bool(ok) if self.grad_finite is None else self.grad_finite and bool(ok)


@dataclass(frozen=True)
class Case:
    name: str
    varied: str
    fn: object
    kwargs: dict
    quick: bool = True          # part of the quick suite (the tests); else full suite only
    #: why the case is known to fail (the test is an xfail with this reason); "" if it passes
    known_failure: str = ""


# ============================================================================ helpers
def torch1():
    import torch
    torch.set_num_threads(1)
    return torch


def prbdm_lam(row: Row, beam: Beam, gamma, poses="paper", law="beam", dtype=None, grad=True):
    """Nondimensional eigenvalues (m, n) as float64 NumPy, with the condition numbers of M, K and
    A = K^-1/2 M K^-1/2 and the finiteness of d(sum log lam)/d(gamma, widths, thickness)."""
    torch = torch1()
    from prbdm import model
    dtype = dtype or torch.float64
    bt = model.BeamTensors.from_beams(beam, dtype=dtype)
    g_free = torch.tensor(np.asarray(gamma, dtype=np.float64)[:-1], dtype=dtype,
                          requires_grad=grad)
    w = bt.w.clone().requires_grad_(grad)
    t = bt.thickness.clone().requires_grad_(grad)
    b2 = model.BeamTensors(bt.x, w, bt.length, t, bt.E, bt.rho)
    gam = torch.cat([g_free, 1 - g_free.sum(-1, keepdim=True)])
    P = model.make_poses(poses, len(gamma) - 1, dtype)
    lam = model.eigenvalues_unit_k(b2, gam, P, law)
    with torch.no_grad():
        links = model.links_from_gamma(b2, gam)
        s = model.base_stiffness(b2, links, law)
        M = model.mass_matrix(model._expand_links(links), P)
        d = torch.rsqrt(s)[..., None, :]
        A = d[..., :, None] * M * d[..., None, :]
        row.conds(M=np.linalg.cond(M.double().numpy()).max(),
                  K=float(s.max() / s.min()),
                  A=np.linalg.cond(A.double().numpy()).max())
    if grad:
        gs = torch.autograd.grad(lam.log().sum(), [g_free, w, t], allow_unused=True)
        row.grads(all(g is None or bool(torch.isfinite(g).all()) for g in gs))
    return lam.detach().double().numpy()


def is_sane(lam) -> bool:
    """Finite, positive and ascending per pose."""
    lam = np.asarray(lam, dtype=np.float64)
    return bool(np.all(np.isfinite(lam)) and np.all(lam > 0) and np.all(np.diff(lam, axis=-1) >= 0))


def rfe_omega(row, beam, n, grad=False):
    """Rigid-finite-element model (beam law, k = 1, [1/2, 1, ..., 1/2]/n, straight), its
    frequencies in units of omega_0 = (t/L^2) sqrt(E/(12 rho)), the beam truth's unit."""
    g = np.full(n + 1, 1.0 / n)
    g[0] = g[-1] = 0.5 / n
    lam = prbdm_lam(row, beam, g, "linear", grad=grad)[0]
    return np.sqrt(12.0 * lam)


def beam_truth(row, beam, modes=5):
    """Beam truth frequencies in units of omega_0 (the nondimensional sqrt(lambda)), and the
    condition numbers of its FEM stiffness before / after diagonal scaling."""
    from prbdm.truth import bending_frequencies
    res = bending_frequencies(beam, model="beam", modes=modes)
    raw, scaled = fem_cond(beam, modes)
    row.conds(fem_raw=raw, fem=scaled)
    return res.omega / res.omega_scale


def fem_cond(beam, modes=5):
    """cond of the beam truth's free-DOF stiffness as assembled (nondimensional, graded mesh) and
    after the symmetric diagonal scaling D K D that solve_beam factorises."""
    from skfem import Basis, MeshLine

    from prbdm.truth._hermite import LocalHermite
    from prbdm.truth.beam import beam_nodes, stiffness
    L = beam.length
    xs, ws = beam.x / L, beam.half_width / L
    nodes = beam_nodes(beam, None, True, modes)
    basis = Basis(MeshLine(nodes), LocalHermite(), intorder=8)
    beta = np.interp(basis.mapping.F(basis.X)[0], xs, ws) / ws.max()
    K = stiffness.assemble(basis, beta=beta)
    free = basis.complement_dofs(basis.get_dofs(lambda x: x[0] < 0.5 * nodes[1]).all())
    Kf = K[free][:, free].toarray()
    d = 1.0 / np.sqrt(np.diag(Kf))
    return np.linalg.cond(Kf), np.linalg.cond(d[:, None] * Kf * d[None, :])


def shooting_error(beam, omega_hat, modes):
    """Relative frequency error of the FEM against the mesh-free shooting solution."""
    from prbdm.truth.shooting import shooting_eigenvalues
    lam = shooting_eigenvalues(beam, omega_hat[:modes] ** 2)
    return float(np.max(np.abs(omega_hat[:modes] / np.sqrt(lam) - 1)))


def analytic_omega(modes):
    from prbdm.truth.analytic import cantilever_roots
    return cantilever_roots(modes) ** 2


def rel_err(a, b) -> float:
    return float(np.max(np.abs(np.asarray(a) / np.asarray(b) - 1)))


def refused(fn, field_name) -> tuple[bool, str]:
    try:
        fn()
    except BadInput as exc:
        return field_name in str(exc), str(exc)
    except Exception as exc:                                        # noqa: BLE001
        return False, f"{type(exc).__name__}: {exc}"
    return False, "accepted"


def uniform_panel(half_width=0.18, thickness=0.02, material=STEEL, length=1.0) -> Beam:
    return Beam(x=[0.0, length], half_width=[half_width, half_width], thickness=thickness,
                material=material)


def tapered_panel(material=STEEL, thickness=0.03, scale=1.0) -> Beam:
    """The README's tapered panel (three stations, a kink at 0.35 L)."""
    return Beam(x=[0.0, 0.35, 1.0], half_width=[0.18 * scale, 0.12 * scale, 0.05 * scale],
                thickness=thickness, material=material)


# ============================================================================ running
def run_case(case: Case) -> dict:
    """One row: the case's checks, condition numbers, gradient finiteness and time. An
    unexpected exception is a failed row carrying its message (the suite never crashes)."""
    row = Row()
    t0 = time.perf_counter()
    try:
        case.fn(row, **case.kwargs)
    except Exception as exc:                                         # noqa: BLE001
        tb = traceback.format_exception_only(type(exc), exc)[-1].strip()
        row.check("ran without an unexpected exception", None, ok=False)
        row.note = tb[:200]
    elapsed = time.perf_counter() - t0
    failed = [c["check"] for c in row.checks if not c["passed"]]
    # the accuracy shown: the case's key check, else the one nearest (or furthest past) its
    # tolerance
    graded = [c for c in row.checks if c["tol"] is not None and c["value"] is not None
              and c["tol"] > 0]
    bad = [c for c in graded if not c["passed"]]
    worst = (max(bad, key=lambda c: c["value"] / c["tol"]) if bad else row.key
             or max(graded, key=lambda c: c["value"] / c["tol"], default=None))
    return {
        "name": case.name, "varied": case.varied,
        "passed": not failed, "n_checks": len(row.checks), "failed": failed,
        "checks": row.checks,
        "accuracy": None if worst is None else worst["value"],
        "tolerance": None if worst is None else worst["tol"],
        "accuracy_check": None if worst is None else worst["check"],
        "cond_M": row.cond.get("M"), "cond_K": row.cond.get("K"), "cond_A": row.cond.get("A"),
        "cond_fem_raw": row.cond.get("fem_raw"), "cond_fem": row.cond.get("fem"),
        "grad_finite": row.grad_finite, "time_s": elapsed, "note": row.note,
        "extra": row.extra, "known_failure": case.known_failure,
    }
