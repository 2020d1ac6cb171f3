"""Optimised PRBDM fits (docs/conventions.md §3, Eq. 13): batched multistart Levenberg-Marquardt in torch.

What is minimised is the paper's loss, ``100/m Σ_i ||lam_i(gamma, k_i)[:r] - lam_T|| / ||lam_T||``,
over the link fractions gamma and one SCF k_i per pose. Three facts about its structure make the
fit fast:

1. **k drops out.** K is proportional to k_i, so ``lam_i = k_i mu_i(gamma)``, and each pose's
   term depends on its own k_i only: the best k_i is the least-squares ratio
   ``<mu_i, lam_T> / <mu_i, mu_i>`` (variable projection). What is left is a function of gamma
   alone, n free parameters instead of n + m.
2. **Bounds by construction.** ``gamma = g_min + (1 - (n+1) g_min) z^2 / |z|^2`` lies on the
   bounded simplex for every real z (n+1 of them; sum 1, each in [0.025, 0.975]), so the search is
   unconstrained. Unlike a softmax, a bound is reached at a finite z (z_j = 0), where the loss is
   smooth, so optima on a bound (common: a short root link) converge as fast as interior ones.
3. **Residuals.** The loss is a sum of norms of residual vectors. Their Jacobian gives a
   Gauss-Newton curvature with the right scaling from the first step; but the residuals at the
   optimum are not small (m poses x r modes against n + 1 parameters), so pure Gauss-Newton or
   Levenberg-Marquardt crawls (linear convergence, tried and measured). BFGS started from the
   Gauss-Newton matrix, with exact autograd gradients, adds the missing curvature and converges in
   tens of iterations.

All starts of all beams are rows of one batch; a row stops when it converges, a beam stops when
its best starts agree, and the batch shrinks as they do.

Start points (:func:`start_points`): the equal-link, the rigid-finite-element and two long-root
segmentations, then draws on the bounded simplex, half of them flat (a flat Dirichlet covers every
point that the paper's Eq. 17 integer grid can produce) and half in the long-root corner where many
beams' best optima lie. Seeded and reproducible.

Among starts whose loss is within ``rep_rtol`` of the best, the reported representative is the one
closest to the rigid-finite-element segmentation [1/2, 1, ..., 1, 1/2]/n: a deterministic rule, so
that labels of flat-valley beams are reproducible and vary smoothly with the geometry.
"""
from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch

from . import objectives
from .errors import BadInput
from .model import (
    GAMMA_MAX,
    GAMMA_MIN,
    LAWS,
    BeamTensors,
    as_beam_tensors,
    eigenvalues_unit_k,
    frequency_errors,
    loss_percent,
    make_poses,
    uniform_gamma,
)

__all__ = ["FitResult", "fit_prbdm", "fit_many", "FitProblem", "StopRules", "refine_starts",
           "REFINE_CANDIDATES", "REFINE_ITER", "gamma_from_z", "z_from_gamma", "start_points",
           "long_root_gamma", "DEFAULT_STARTS"]

from .constants import DEFAULT_STARTS, REFINE_CANDIDATES, REFINE_ITER  # noqa: E402

#: smallest |z_j| of a start given by ``init_gamma`` (see :func:`fit_many`)
INIT_Z_FLOOR = 0.02


def default_starts(n: int) -> int:
    """Start points used when none are given: 64 up to 4 joints, 128 beyond (measured: with
    fewer, more than 1 beam in 16 misses the best optimum by over 1 %; see docs/validation.md)."""
    return DEFAULT_STARTS if n <= 4 else 2 * DEFAULT_STARTS


@dataclass
class FitResult:
    """One beam's optimised PRBDM.

    gamma (n+1,) link fractions; k (m,) SCFs per pose; loss_percent (Eq. 13 in %);
    omega (m, n) PRBDM frequencies per pose [rad/s]; omega_truth (R,) [rad/s];
    freq_error (m, r) per-mode relative frequency errors; poses (m, n) [rad];
    n_near_best: starts within 1 % of the best loss; gamma_spread: largest range of any gamma_j
    among those starts (0 when the optimum is well determined); time_s: wall time.
    objective: what was minimised (``eigenvalue`` or ``frequency``); loss_percent is always the
    paper's loss and frequency_percent the frequency objective's value (both in %) of the
    result; best_objective_percent is the best value of the minimised objective among the starts.
    """

    gamma: np.ndarray
    k: np.ndarray
    loss_percent: float
    omega: np.ndarray
    omega_truth: np.ndarray
    freq_error: np.ndarray
    poses: np.ndarray
    law: str
    modes: int
    n_starts: int
    n_near_best: int
    gamma_spread: float
    iterations: int
    time_s: float
    seed: int
    best_objective_percent: float = math.nan
    objective: str = "eigenvalue"
    frequency_percent: float = math.nan
    extra: dict = field(default_factory=dict)

    @property
    def joints(self) -> int:
        return len(self.gamma) - 1

    def to_dict(self) -> dict:
        return {
            "joints": self.joints, "modes": self.modes, "law": self.law,
            "gamma": self.gamma.tolist(), "k": self.k.tolist(),
            "poses": self.poses.tolist(),
            "omega_truth": self.omega_truth.tolist(),
            "omega": self.omega.tolist(),
            "freq_hz": (self.omega / (2 * math.pi)).tolist(),
            "freq_error": self.freq_error.tolist(),
            "max_freq_error": float(self.freq_error.max()),
            "loss_percent": self.loss_percent,
            "objective": self.objective, "frequency_percent": self.frequency_percent,
            # the best start's value of what was minimised; the paper's loss of the best start
            # only where that is what was minimised
            "best_objective_percent": self.best_objective_percent,
            **({"best_loss_percent": self.best_objective_percent}
               if self.objective == "eigenvalue" else {}),
            "starts": self.n_starts, "n_near_best": self.n_near_best,
            "gamma_spread": self.gamma_spread, "iterations": self.iterations,
            "seed": self.seed, "time_s": self.time_s, **self.extra,
        }


# ----------------------------------------------------------------------------- parametrisation
def gamma_from_z(z: torch.Tensor, g_min: float = GAMMA_MIN) -> torch.Tensor:
    """(..., n+1) unconstrained (not all zero) -> (..., n+1) on the bounded simplex."""
    n = z.shape[-1] - 1
    y = z * z
    return g_min + (1.0 - (n + 1) * g_min) * y / y.sum(-1, keepdim=True)


def z_from_gamma(gamma: torch.Tensor, g_min: float = GAMMA_MIN) -> torch.Tensor:
    """A preimage of ``gamma`` under :func:`gamma_from_z` (unit norm, non-negative)."""
    n = gamma.shape[-1] - 1
    y = ((gamma - g_min) / (1.0 - (n + 1) * g_min)).clamp_min(0.0)
    z = torch.sqrt(y)
    return z / torch.linalg.vector_norm(z, dim=-1, keepdim=True)


def long_root_gamma(n: int, root: float, dtype=torch.float64) -> torch.Tensor:
    """(n+1,) a long root link ``root`` and the rest cut like a rigid-finite-element chain
    (a half link, then equal links): the family where many random beams' best optima lie, e.g.
    [0.80, 0.025, 0.06, 0.05, 0.06] (and the paper's Table 4, [0.76, 0.04, 0.13, 0.03, 0.05])."""
    w = torch.ones(n, dtype=dtype)
    w[0] = 0.5
    g = torch.cat([torch.tensor([root], dtype=dtype), (1.0 - root) * w / w.sum()])
    return gamma_from_z(z_from_gamma(g))        # onto the bounded simplex (links below g_min)


#: root fractions of the fixed long-root starts (see :func:`start_points`)
LONG_ROOTS = (0.8, 0.65)
#: fixed starts that come first in :func:`start_points`
FIXED_STARTS = 2 + len(LONG_ROOTS)
#: range of the root fraction of the long-root draws (on the unit simplex, before the bounds)
LONG_ROOT_RANGE = (0.55, 0.9)


def start_points(n: int, starts: int, seed: int, dtype=torch.float64) -> torch.Tensor:
    """(starts, n+1) unconstrained start points, seeded.

    Fixed first: the rigid-finite-element and equal-link segmentations and two long-root ones
    (:data:`LONG_ROOTS`). Then draws on the bounded simplex: half of all starts with a long root
    link (root fraction uniform in :data:`LONG_ROOT_RANGE`, the other links a flat Dirichlet of
    the rest), the others a flat Dirichlet. Why: the best optima of many random beams lie in a
    corner of the simplex (root link 0.6 - 0.85, a short second link) that is a few percent of
    its volume and holds many narrow local optima next to each other; flat draws put one or two
    starts there. Measured on 60 beams of seed 7, 5 seeds each, n = 4, 64 starts: runs more than
    1 % above the best loss found for the beam fell from 29 of 300 (two fixed + flat draws) to 3
    of 300, at no extra time per beam (``benchmarks/fit_quality.py starts``; docs/validation.md)."""
    fixed = [uniform_gamma(n, dtype), torch.full((n + 1,), 1.0 / (n + 1), dtype=dtype)]
    fixed += [long_root_gamma(n, g0, dtype) for g0 in LONG_ROOTS]
    fixed = fixed[:starts]
    m = max(starts - len(fixed), 0)
    rng = np.random.default_rng([int(seed), n])
    y = rng.dirichlet(np.ones(n + 1), size=m)
    c = min(starts // 2, m)
    root = rng.uniform(*LONG_ROOT_RANGE, size=c)
    rest = rng.dirichlet(np.ones(n), size=c)
    y[:c] = np.concatenate([root[:, None], (1 - root[:, None]) * rest], 1)
    drawn = torch.as_tensor(GAMMA_MIN + (1 - (n + 1) * GAMMA_MIN) * y, dtype=dtype)
    gammas = torch.cat([torch.stack(fixed), drawn]) if len(fixed) else drawn
    # a link exactly at its bound has z_j = 0, where the gradient in z_j vanishes (see fit_many)
    z = z_from_gamma(gammas).clamp_min(INIT_Z_FLOOR)
    return z / torch.linalg.vector_norm(z, dim=-1, keepdim=True)


# ----------------------------------------------------------------------------- objective
def _residuals(beam, z, poses, lam_truth, r, law, objective="eigenvalue"):
    """Projected residuals (rows, m, r) and best SCFs (rows, m) for unconstrained z (rows, n+1),
    of ``objective`` (:mod:`prbdm.objectives`).

    beam fields and lam_truth carry the same leading rows as z (nondimensional lam_truth)."""
    mu = eigenvalues_unit_k(beam, gamma_from_z(z), poses, law)[..., :r]   # (rows, m, r)
    return objectives.residuals(objective, mu, lam_truth[..., :r])


def _loss(res, objective="eigenvalue"):
    return objectives.loss(objective, res)


def _rows(beam: BeamTensors, idx: torch.Tensor) -> BeamTensors:
    return BeamTensors(beam.x[idx], beam.w[idx], beam.length[idx], beam.thickness[idx],
                       beam.E[idx], beam.rho[idx])


# ----------------------------------------------------------------------------- optimiser
def _objective(beam, z, poses, lam_truth, r, law, grad: bool, objective="eigenvalue"):
    """Loss (rows,) and, if asked, its exact gradient (rows, n+1) by reverse-mode autograd: the
    rows are independent, so the gradient of their sum is every row's own gradient."""
    if not grad:
        with torch.no_grad():
            return _loss(_residuals(beam, z, poses, lam_truth, r, law, objective)[0],
                         objective), None
    z = z.detach().requires_grad_(True)
    f = _loss(_residuals(beam, z, poses, lam_truth, r, law, objective)[0], objective)
    (g,) = torch.autograd.grad(f.sum(), z)
    return f.detach(), g


def _gauss_newton(beam, z, poses, lam_truth, r, law, h=1e-6, objective="eigenvalue"):
    """Curvature of Σ||r_i|| from the residual Jacobian (central differences, one batched call):
    Σ_i J_i^T (I - r̂_i r̂_i^T) J_i / ||r_i||, the Hessian without the residuals' own curvature."""
    rows, d = z.shape
    eye = torch.eye(d, dtype=z.dtype, device=z.device)
    pts = z[:, None, :] + torch.cat([h * eye, -h * eye])
    bb = _rows(beam, torch.arange(rows, device=z.device)[:, None].expand(-1, 2 * d))
    with torch.no_grad():
        res_all, _ = _residuals(bb, pts, poses, lam_truth[:, None, :], r, law, objective)
        res0, _ = _residuals(beam, z, poses, lam_truth, r, law, objective)
    jac = (res_all[:, :d] - res_all[:, d:]) / (2 * h)                     # (rows, d, m, r)
    norm = torch.linalg.vector_norm(res0, dim=-1).clamp_min(1e-14)        # (rows, m)
    unit = res0 / norm[..., None]
    jt = jac.permute(0, 2, 1, 3)                                          # (rows, m, d, r)
    proj = jt - (jt @ unit[..., :, None]) * unit[..., None, :]
    H = torch.einsum("bmdr,bmer,bm->bde", proj, proj, 1.0 / norm)
    return 100.0 / res0.shape[-2] * H


@dataclass(frozen=True)
class FitProblem:
    """What :func:`fit_many` fits: B beams and their truth, the chain and what is compared.

    beams: sequence of :class:`prbdm.geometry.Beam`; omega_truth: (B, R) truth frequencies
    [rad/s], ascending (an array, or a torch tensor: the fit then runs where it is); joints: n;
    modes: how many truth modes to map (r = min(joints, modes), default joints); law: the base
    joint stiffness law (:data:`prbdm.model.LAWS`); poses: the poses' name or angles
    (:func:`prbdm.model.make_poses`); objective: what is minimised, ``"eigenvalue"`` (the paper's
    loss) or ``"frequency"`` (the worst relative frequency error per pose, see
    :mod:`prbdm.objectives`); every result reports both. Checked by :func:`fit_many`."""

    beams: Sequence
    omega_truth: Any
    joints: int
    modes: int | None = None
    law: str = "beam"
    poses: Any = "paper"
    objective: str = "eigenvalue"


@dataclass(frozen=True)
class StopRules:
    """When the multistart stops, and which of its best starts it reports.

    ``max_iter``: the most BFGS iterations. Among the starts whose loss is within ``rep_rtol`` of
    its beam's best, the one reported is the closest to the rigid-finite-element segmentation
    (module docstring). The rest say when the batched BFGS (:func:`_bfgs`) stops a row (one start
    of one beam) or a beam. A row stops when it has converged (a relative decrease below ``ftol``, ``stall`` iterations
    in a row, or less than ``window_rtol`` relative progress over the last ``window``
    iterations), when a better row of its beam is in the same valley (within ``merge_tol`` in
    gamma, max-norm), when its beam's ``quorum`` best rows agree (within ``agree_rtol``) and have
    converged, or when it is behind: at its pace over the last ``window`` iterations it would not
    come within ``behind_rtol`` of its beam's best loss before ``max_iter``. The merge and quorum
    checks run every ``check_every`` iterations (they compare all rows of a beam). ``quorum``
    None: max(3, S // 16) of a beam's S starts."""

    max_iter: int = 150
    rep_rtol: float = 1e-3
    quorum: int | None = None
    agree_rtol: float = 1e-3
    ftol: float = 1e-9
    stall: int = 3
    window: int = 15
    window_rtol: float = 1e-6
    behind_rtol: float = 1e-3
    merge_tol: float = 1e-3
    check_every: int = 5


#: step lengths tried in each BFGS iteration, in one batched call (the longest that satisfies
#: Armijo's condition is kept)
STEP_LENGTHS = (1.0, 0.3, 0.1, 0.02)
#: Armijo's sufficient-decrease constant
ARMIJO_C = 1e-4
#: longest step on the unit sphere [rad]
MAX_STEP = 0.5


@dataclass(frozen=True)
class _Problem:
    """The fixed data of one batched fit: every row is one start of one beam.

    beam: the beams repeated per row; lam_truth (rows, r): each row's nondimensional truth;
    beam_of_row (rows,): which of the n_beams each row fits."""

    beam: BeamTensors
    lam_truth: torch.Tensor
    beam_of_row: torch.Tensor
    n_beams: int
    poses: torch.Tensor
    r: int
    law: str
    objective: str

    def value(self, idx, z, grad: bool):
        """Loss (and its gradient if ``grad``) of the rows ``idx`` at z (len(idx), n+1)."""
        return _objective(_rows(self.beam, idx), z, self.poses, self.lam_truth[idx], self.r,
                          self.law, grad, self.objective)

    def trial_values(self, idx, trial):
        """Losses (len(idx), T) of T trial points per row, trial (len(idx), T, n+1)."""
        bt = _rows(self.beam, idx[:, None].expand(-1, trial.shape[1]))
        f, _ = _objective(bt, trial, self.poses, self.lam_truth[idx][:, None, :], self.r,
                          self.law, False, self.objective)
        return f

    def initial_inverse(self, idx, z):
        """Inverse of the Gauss-Newton curvature of rows ``idx`` at their z (len(idx), n+1)."""
        H = _gauss_newton(_rows(self.beam, idx), z, self.poses, self.lam_truth[idx], self.r,
                          self.law, objective=self.objective)
        eye = torch.eye(z.shape[-1], dtype=z.dtype, device=z.device)
        scale = torch.diagonal(H, dim1=-2, dim2=-1).mean(-1).clamp_min(1e-12)[:, None, None]
        zz = z[:, :, None] * z[:, None, :]
        # the loss is flat along z itself (z and c z give the same gamma): pin that direction
        return torch.linalg.inv(H + scale * (zz + 1e-3 * eye))


@dataclass
class _BfgsState:
    """Per row: z on the unit sphere, loss f, gradient g, inverse Hessian Hinv, whether it is
    still active, how many small decreases in a row (stall), the losses of the last iterations
    (hist, a ring buffer)."""

    z: torch.Tensor
    f: torch.Tensor
    g: torch.Tensor
    Hinv: torch.Tensor
    active: torch.Tensor
    stall: torch.Tensor
    hist: torch.Tensor

    @classmethod
    def start(cls, problem: _Problem, z, window: int) -> "_BfgsState":
        rows = z.shape[0]
        every = torch.arange(rows, device=z.device)
        f, g = problem.value(every, z, True)
        return cls(z=z, f=f, g=g, Hinv=problem.initial_inverse(every, z[every]),
                   active=torch.ones(rows, dtype=torch.bool, device=z.device),
                   stall=torch.zeros(rows, dtype=torch.long, device=z.device),
                   hist=f.detach().clone()[:, None].repeat(1, window))


def _bfgs(problem: _Problem, z, rules: StopRules, progress=None):
    """Batched BFGS over rows (start x beam), z kept on the unit sphere. Returns z, loss, iters.

    The inverse Hessian starts from the Gauss-Newton curvature (good scaling from the first
    step); BFGS updates then add the residual curvature that Gauss-Newton misses, which matters
    here because the residuals at the optimum are not small. Each iteration tries the
    :data:`STEP_LENGTHS` in one batched call and keeps the longest that satisfies Armijo's
    condition. Rows stop by :class:`StopRules`. Most of a lone fit's time used to go to rows
    creeping along poorer valleys to the iteration limit: the `behind` rule. Measured on 100
    random beams (n = 4, seed 2019, 64 starts, batched): 64 s to 49 s, every loss within 2.5e-5
    of the old one; a window of 10 was faster (40 s) but stopped the start that found one
    beam's best optimum early."""
    window = min(rules.window, rules.max_iter + 1)      # a window past the budget never applies
    s = _BfgsState.start(problem, z, window)
    alphas = torch.tensor(STEP_LENGTHS, dtype=z.dtype, device=z.device)
    it = 0
    for it in range(1, rules.max_iter + 1):
        if progress is not None:
            progress(it, rules.max_iter)
        idx = torch.nonzero(s.active).squeeze(-1)
        if idx.numel() == 0:
            break
        # a row whose gradient is not finite (an exact fit: the gradient of a norm at zero)
        # stops where it is; the Gauss-Newton polish takes exact fits to round-off
        lost = ~torch.isfinite(s.g[idx]).all(-1) | ~torch.isfinite(s.Hinv[idx]).all(-1).all(-1)
        if lost.any():
            s.active[idx[lost]] = False
            idx = idx[~lost]
            if idx.numel() == 0:
                break
        fi = s.f[idx]
        f_new = _bfgs_step(problem, s, idx, alphas)
        small = (fi - f_new) <= rules.ftol * fi + 1e-15
        s.stall[idx] = torch.where(small, s.stall[idx] + 1, torch.zeros_like(s.stall[idx]))
        s.active[idx[s.stall[idx] >= rules.stall]] = False
        _stop_slow_rows(problem, s, idx, f_new, it, window, rules)
        if it % rules.check_every == 0:
            _stop_merged_rows(problem, s, rules)
            _stop_agreed_beams(problem, s, rules)
    return s.z, s.f, it


def _bfgs_step(problem: _Problem, s: _BfgsState, idx, alphas):
    """One BFGS iteration of the rows ``idx`` (line search, update of z, f, g and Hinv in
    ``s``); returns their new losses."""
    zi, fi, gi = s.z[idx], s.f[idx], s.g[idx]
    p = -(s.Hinv[idx] @ gi[..., None]).squeeze(-1)
    p = p - (p * zi).sum(-1, keepdim=True) * zi                      # tangent to the sphere
    slope = (p * gi).sum(-1)
    bad = ~(slope < 0)
    p = torch.where(bad[:, None], -gi, p)                            # fall back to descent
    slope = torch.where(bad, -(gi * gi).sum(-1), slope)
    pn = torch.linalg.vector_norm(p, dim=-1, keepdim=True)
    p = p * torch.clamp(MAX_STEP / pn.clamp_min(1e-300), max=1.0)
    slope = (p * gi).sum(-1)
    trial = zi[:, None, :] + alphas[:, None] * p[:, None, :]
    trial = trial / torch.linalg.vector_norm(trial, dim=-1, keepdim=True)
    ft = problem.trial_values(idx, trial)
    armijo = ft <= fi[:, None] + ARMIJO_C * alphas * slope[:, None]
    first = torch.where(armijo.any(-1), armijo.float().argmax(-1), ft.argmin(-1))
    rows = torch.arange(idx.numel(), device=idx.device)
    z_new = trial[rows, first]
    f_new = ft[rows, first]
    improved = f_new < fi
    z_new = torch.where(improved[:, None], z_new, zi)
    f_new, g_new = problem.value(idx, z_new, True)
    # BFGS update of the inverse Hessian where the curvature condition holds
    s_ = z_new - zi
    y_ = g_new - gi
    sy = (s_ * y_).sum(-1)
    ok = improved & (sy > 1e-12 * torch.linalg.vector_norm(s_, dim=-1)
                     * torch.linalg.vector_norm(y_, dim=-1))
    rho_ = torch.where(ok, 1.0 / torch.where(ok, sy, torch.ones_like(sy)), torch.zeros_like(sy))
    eye = torch.eye(zi.shape[-1], dtype=zi.dtype, device=zi.device)
    V = eye - rho_[:, None, None] * s_[:, :, None] * y_[:, None, :]
    Hn = V @ s.Hinv[idx] @ V.transpose(1, 2) + rho_[:, None, None] * s_[:, :, None] * s_[:, None, :]
    s.Hinv[idx] = torch.where(ok[:, None, None], Hn, s.Hinv[idx])
    if (~improved).any():                                            # restart from Gauss-Newton
        s.z[idx] = z_new
        stuck = idx[~improved]
        s.Hinv[stuck] = problem.initial_inverse(stuck, s.z[stuck])
    s.z[idx], s.f[idx], s.g[idx] = z_new, f_new, g_new
    return f_new


def _stop_slow_rows(problem: _Problem, s: _BfgsState, idx, f_new, it, window, rules):
    """Stop rows that made too little progress over the window, or that are behind."""
    slot = it % window
    f_then, s.hist[idx, slot] = s.hist[idx, slot], f_new
    if it < window:
        return
    gain = f_then - f_new
    best_of_beam = torch.full((problem.n_beams,), math.inf, dtype=s.f.dtype,
                              device=s.f.device).scatter_reduce(
        0, problem.beam_of_row, s.f, "amin")[problem.beam_of_row[idx]]
    behind = f_new - gain / window * (rules.max_iter - it) > best_of_beam * (1 + rules.behind_rtol)
    s.active[idx[(gain <= rules.window_rtol * f_new) | behind]] = False


def _stop_merged_rows(problem: _Problem, s: _BfgsState, rules):
    """Starts that have run into the same valley as a better start follow it: drop them."""
    idx = torch.nonzero(s.active).squeeze(-1)
    gam = gamma_from_z(s.z)
    near = torch.cdist(gam[idx], gam, p=float("inf")) < rules.merge_tol
    same = problem.beam_of_row[idx, None] == problem.beam_of_row[None, :]
    better = s.f[None, :] < s.f[idx, None]
    s.active[idx[(near & same & better).any(-1)]] = False


def _stop_agreed_beams(problem: _Problem, s: _BfgsState, rules):
    """A beam stops when its ``quorum`` best starts agree and have converged."""
    for bi in range(problem.n_beams):
        rows_b = torch.nonzero(problem.beam_of_row == bi).squeeze(-1)
        if not s.active[rows_b].any():
            continue
        lb = s.f[rows_b]
        order = torch.argsort(lb)[:rules.quorum]
        top = rows_b[order]
        if (lb[order] <= lb[order[0]] * (1 + rules.agree_rtol) + 1e-15).all() and \
                not s.active[top].any():
            s.active[rows_b] = False


def _polish(beam, z, poses, lam_truth, r, law, iters=8, objective="eigenvalue"):
    """Levenberg-Marquardt on the reweighted residuals (weight 1/sqrt(||r_i||)), kept only where
    it lowers the loss. BFGS stalls on a loss that is a norm going to zero (the cone at an exact
    fit: `linear` poses with r = n); Gauss-Newton converges there quadratically, to round-off."""
    rows, d = z.shape
    f, _ = _objective(beam, z, poses, lam_truth, r, law, False, objective)
    eye = torch.eye(d, dtype=z.dtype, device=z.device)
    damping = torch.full((rows,), 1e-6, dtype=z.dtype, device=z.device)
    h = 1e-7
    for _ in range(iters):
        pts = z[:, None, :] + torch.cat([h * eye, -h * eye])
        bb = _rows(beam, torch.arange(rows, device=z.device)[:, None].expand(-1, 2 * d))
        with torch.no_grad():
            res_all, _ = _residuals(bb, pts, poses, lam_truth[:, None, :], r, law, objective)
            res0, _ = _residuals(beam, z, poses, lam_truth, r, law, objective)
        w = torch.rsqrt(torch.linalg.vector_norm(res0, dim=-1) + 1e-30)[..., None]
        jac = ((res_all[:, :d] - res_all[:, d:]) / (2 * h) * w[:, None]).reshape(rows, d, -1)
        rw = (res0 * w).reshape(rows, -1)
        H = jac @ jac.transpose(1, 2)
        scale = torch.diagonal(H, dim1=-2, dim2=-1).mean(-1)[:, None, None]
        A = H + scale * (z[:, :, None] * z[:, None, :] + damping[:, None, None] * eye)
        step, info = torch.linalg.solve_ex(A + 1e-300 * eye, jac @ rw[..., None])
        step = torch.where((info == 0)[:, None], -step.squeeze(-1), torch.zeros_like(z))
        z_try = z + torch.nan_to_num(step, nan=0.0, posinf=0.0, neginf=0.0)
        z_try = z_try / torch.linalg.vector_norm(z_try, dim=-1, keepdim=True)
        f_try, _ = _objective(beam, z_try, poses, lam_truth, r, law, False, objective)
        better = f_try < f
        z = torch.where(better[:, None], z_try, z)
        f = torch.where(better, f_try, f)
        damping = torch.where(better, damping / 10, damping * 100).clamp(1e-12, 1e6)
    return z, f


def fit_many(problem: FitProblem, *, starts: int | None = None, seed=0, init_gamma=None,
             stop: StopRules | None = None, device=None, progress=None) -> list[FitResult]:
    """Fit n-joint PRBDMs to several beams at once (all starts of all beams in one batch).

    problem: the beams, their truth and what is fitted (:class:`FitProblem`). starts: per beam
    (default :func:`default_starts`). ``seed``: one int (every beam gets the same start points)
    or a sequence of B ints, one per beam (beam b then starts where ``fit_prbdm(..., seed=seed[b])``
    would). ``init_gamma`` (B, n+1) or (B, H, n+1): start every beam from its own gamma(s)
    instead (e.g. a network's candidates, then a few iterations refine them, see
    :func:`refine_starts`); ``starts`` is then H. ``stop``: when to stop and which start to
    report (:class:`StopRules`; default its defaults). ``device``: where the fit runs (a torch
    device or its name); by default where ``omega_truth`` is when it is a tensor, else the CPU.
    ``progress``: called as ``progress(iteration, max_iter)`` at each iteration (a progress bar).
    Returns one :class:`FitResult` per beam (NumPy arrays).

    >>> fit_many(FitProblem(beams, truths, joints=4), stop=StopRules(max_iter=20))  # doctest: +SKIP
    """
    t0 = time.perf_counter()
    stop = StopRules() if stop is None else stop
    beams, omega_truth, joints, modes, law, poses, objective = (
        problem.beams, problem.omega_truth, problem.joints, problem.modes, problem.law,
        problem.poses, problem.objective)
    objectives.check_objective(objective)
    n = _check_int(joints, "joints", 1, int(1 / GAMMA_MIN) - 1)
    starts = default_starts(n) if starts is None else _check_int(starts, "starts", 1, 10 ** 6)
    max_iter = _check_int(stop.max_iter, "max_iter", 1, 10 ** 6)
    if law not in LAWS:
        raise BadInput(f"law: must be one of {', '.join(LAWS)}, got {law!r}")
    device = _fit_device(device, omega_truth)
    if isinstance(omega_truth, torch.Tensor):
        omega_truth = omega_truth.detach().cpu().numpy()
    beams = list(beams)
    bt = as_beam_tensors(beams).to(device=device)
    omega_truth = torch.as_tensor(np.ascontiguousarray(omega_truth, dtype=np.float64))
    if omega_truth.ndim != 2 or omega_truth.shape[0] != len(beams):
        raise BadInput(f"omega_truth: need one row of truth frequencies per beam "
                       f"({len(beams)}), got shape {tuple(omega_truth.shape)}")
    R = omega_truth.shape[1]
    modes = n if modes is None else _check_int(modes, "modes", 1, 10 ** 3)
    r = min(n, modes)
    if R < r:
        raise BadInput(f"omega_truth: need at least {r} truth frequencies, got {R}")
    if not (torch.isfinite(omega_truth[:, :r]).all() and (omega_truth[:, :r] > 0).all()):
        raise BadInput("omega_truth: frequencies must be finite and > 0")
    if (omega_truth[:, 1:r] < omega_truth[:, :r - 1]).any():
        raise BadInput("omega_truth: frequencies must be ascending")
    omega_truth = omega_truth.to(device)
    pose_t = make_poses(poses, n).to(device)
    lam_hat = omega_truth[:, :r] ** 2 / bt.lambda0[:, None]           # nondimensional truth
    B = len(beams)
    if isinstance(seed, (int, np.integer)):
        seeds = [int(seed)] * B
    else:
        seeds = [int(s) for s in seed]
        if len(seeds) != B:
            raise BadInput(f"seed: need one int or one per beam ({B}), got {len(seeds)}")
    z = _initial_z(n, starts, seeds, init_gamma, B)
    S = z.shape[0] // B
    z = z.to(device)
    beam_of_row = torch.arange(B, device=device).repeat_interleave(S)
    rules = dataclasses.replace(stop, max_iter=max_iter,
                                quorum=min(stop.quorum or max(3, S // 16), S))
    batch = _Problem(beam=_rows(bt, beam_of_row), lam_truth=lam_hat[beam_of_row],
                     beam_of_row=beam_of_row, n_beams=B, poses=pose_t, r=r, law=law,
                     objective=objective)
    z, loss, iters = _bfgs(batch, z, rules, progress)
    # polish each beam's near-best starts with Gauss-Newton steps
    best = torch.stack([loss[beam_of_row == bi].min() for bi in range(B)])
    top = torch.nonzero(loss <= best[beam_of_row] * (1 + rules.rep_rtol) + 1e-12).squeeze(-1)
    z[top], loss[top] = _polish(_rows(bt, beam_of_row[top]), z[top], pose_t,
                                lam_hat[beam_of_row[top]], r, law, objective=objective)
    elapsed = time.perf_counter() - t0
    ref = uniform_gamma(n).to(device)
    results = []
    for bi in range(B):
        rows = slice(bi * S, (bi + 1) * S)
        lb, zb = loss[rows], z[rows]
        gam = gamma_from_z(zb)
        best = lb.min()
        near = lb <= best * 1.01 + 1e-12
        cand = torch.nonzero(lb <= best * (1 + rules.rep_rtol) + 1e-12).squeeze(-1)
        pick = cand[torch.argmin(torch.linalg.vector_norm(gam[cand] - ref, dim=-1))]
        starts_info = _StartsSummary(
            n_starts=S, n_near_best=int(near.sum()), iterations=iters, time_s=elapsed / B,
            gamma_spread=float((gam[near].max(0).values - gam[near].min(0).values).max()),
            seed=seeds[bi], best_objective_percent=float(best))
        results.append(_result(batch, _rows(bt, torch.tensor([bi], device=device)), zb[pick],
                               omega_truth[bi], lam_hat[bi], starts_info))
    return results


def _fit_device(device, omega_truth) -> torch.device:
    """The device a fit runs on: the one asked for, else that of a tensor ``omega_truth``."""
    if device is None:
        return omega_truth.device if isinstance(omega_truth, torch.Tensor) else torch.device("cpu")
    try:
        return torch.device(device)
    except (RuntimeError, TypeError) as exc:
        raise BadInput(f"device: must be a torch device such as cpu or cuda, got {device!r}") \
            from exc


def _initial_z(n, starts, seeds, init_gamma, B) -> torch.Tensor:
    """(B * S, n+1) start points, S per beam, on the CPU (see :func:`fit_many`)."""
    if init_gamma is None and len(set(seeds)) > 1:
        return torch.cat([start_points(n, starts, s) for s in seeds])
    if init_gamma is None:
        return start_points(n, starts, seeds[0] if seeds else 0).repeat(B, 1)
    # a copy: a broadcast view is read-only, which torch warns about
    g0 = torch.as_tensor(np.array(init_gamma, dtype=np.float64))
    if g0.shape[:1] != (B,) or g0.shape[-1] != n + 1 or g0.ndim not in (2, 3):
        raise BadInput(f"init_gamma: need shape ({B}, {n + 1}) or ({B}, H, {n + 1}), got "
                       f"{tuple(g0.shape)}")
    S = g0.shape[1] if g0.ndim == 3 else 1
    g0 = g0.reshape(B * S, n + 1)
    if not torch.isfinite(g0).all() or (g0 <= 0).any():
        raise BadInput("init_gamma: must be finite and > 0")
    g0 = (g0 / g0.sum(-1, keepdim=True)).clamp(GAMMA_MIN, GAMMA_MAX)
    # a link at its bound has z_j = 0, where d gamma / d z_j = 0: the gradient and the
    # Gauss-Newton curvature vanish in that direction and the coordinate would stay frozen
    # at the bound (measured: fits from the simplex corners stopped after 4 iterations at
    # 20-600 times the best loss). Starting z_j at INIT_Z_FLOOR moves gamma by <= 4e-4.
    z = z_from_gamma(g0 / g0.sum(-1, keepdim=True)).clamp_min(INIT_Z_FLOOR)
    return z / torch.linalg.vector_norm(z, dim=-1, keepdim=True)


@dataclass(frozen=True)
class _StartsSummary:
    """What one beam's multistart says beside its result (see :class:`FitResult`)."""

    n_starts: int
    n_near_best: int
    gamma_spread: float
    iterations: int
    time_s: float
    seed: int
    best_objective_percent: float


def _result(problem: _Problem, b1: BeamTensors, z, omega_truth, lam_hat,
            starts: _StartsSummary) -> FitResult:
    """The :class:`FitResult` of one beam (b1, shape (1,)) at its chosen z (n+1,)."""
    r = problem.r
    gamma = gamma_from_z(z[None])
    mu = eigenvalues_unit_k(b1, gamma, problem.poses, problem.law)[0]    # (m, n), k = 1
    _, k = objectives.residuals(problem.objective, mu[..., :r], lam_hat[:r])
    lam_nd = mu * k[:, None]
    lam = lam_nd * b1.lambda0[0]
    fe = frequency_errors(lam, omega_truth, r)
    # both measures, whatever was minimised: the paper's loss and the frequency objective
    return FitResult(gamma=gamma[0].cpu().numpy(), k=k.cpu().numpy(),
                     loss_percent=float(loss_percent(lam_nd, lam_hat, r)),
                     objective=problem.objective,
                     frequency_percent=float(objectives.frequency_measure(lam_nd, lam_hat, r)),
                     omega=lam.sqrt().cpu().numpy(), omega_truth=omega_truth.cpu().numpy(),
                     freq_error=fe.cpu().numpy(), poses=problem.poses.cpu().numpy(),
                     law=problem.law, modes=r, **vars(starts))


#: a network-then-refined fit: the network's best REFINE_CANDIDATES candidates
#: (``Prediction.ranked_candidates``) and the four fixed starts, REFINE_ITER iterations. Measured
#: on 200 held-out beams with the two-member beam-n4 (docs/validation.md): a median 1.06 times
#: the optimised loss at 1/10.8 of its time in batches of 8 beams, 1/18 in batches of 40, 1/7.7
#: one beam at a time (all 8 candidates, 12 starts: 1.05 at 1/8.6; 20 iterations: 1.03 at 1/9.1).
#: Both numbers live in prbdm.constants.


def refine_starts(gamma) -> np.ndarray:
    """Start points for a short refinement: the given segmentations (B, n+1) or (B, H, n+1), e.g.
    a network's candidates, followed by the fit's four fixed starts (rigid-finite-element, equal
    links, the two long roots of :func:`start_points`): (B, H + 4, n+1), for
    ``fit_many(..., init_gamma=...)``. Measured on 200 held-out beams (docs/validation.md): with
    the two long-root starts added, 20 iterations from a network's 4 candidates ended a median
    1.16 times the optimised loss instead of 1.29 (the single-network beam-n4 of 2026-12-02)."""
    g = np.asarray(gamma, dtype=np.float64)
    g = g[:, None, :] if g.ndim == 2 else g
    n = g.shape[-1] - 1
    fixed = gamma_from_z(start_points(n, FIXED_STARTS, 0)).numpy()
    return np.concatenate([g, np.broadcast_to(fixed, (g.shape[0], FIXED_STARTS, n + 1))], axis=1)


def fit_prbdm(beam, omega_truth, joints: int, modes: int | None = None, law: str = "beam",
              poses="paper", starts: int | None = None, seed: int = 0, *,
              objective: str = "eigenvalue", **options) -> FitResult:
    """Fit one beam: ``omega_truth`` (R,) [rad/s]; the other arguments are those of
    :class:`FitProblem` and :func:`fit_many` (``options``: ``init_gamma``, ``stop``, ``device``,
    ``progress``)."""
    omega = np.atleast_1d(np.asarray(omega_truth, dtype=np.float64))
    problem = FitProblem([beam], omega[None, :], joints, modes, law, poses, objective)
    return fit_many(problem, starts=starts, seed=seed, **options)[0]


def _check_int(value, name, lo, hi):
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not lo <= value <= hi:
        raise BadInput(f"{name}: must be an integer in [{lo}, {hi}], got {value!r}")
    return int(value)
