"""What a fit minimises: the paper's eigenvalue loss, or the worst relative frequency error.

Both objectives compare a PRBDM's eigenvalues ``lam_i = k_i mu_i(gamma)`` (pose i, one stiffness
correction factor k_i per pose, ``mu`` the eigenvalues at ``k = 1``) with the truth's ``lam_T``
over the first ``r`` modes, and both have the best k_i of each pose in closed form, so a fit
searches gamma alone (variable projection, see :mod:`prbdm.fit`).

- ``eigenvalue`` (the paper's Eqs. 12-13; docs/conventions.md §3): per pose the residual vector
  ``(k_i mu_i - lam_T) / ||lam_T||``, its 2-norm averaged over the poses, in percent. The best
  k_i is the least-squares ratio ``<mu_i, lam_T> / <mu_i, mu_i>``. The highest mapped mode has the
  largest eigenvalue and dominates the norm, so the first mode, the one a designer cares about
  most, can be left 15-60 % off.
- ``frequency``: per pose the log frequency errors ``e_ij = log(omega_ij / omega_Tj) =
  (log k_i + log mu_ij - log lam_Tj) / 2``, reduced by a p-norm with ``p = FREQUENCY_P`` (a
  smooth equivalent of the maximum: it lies between ``max_j |e_ij|`` and ``r^(1/p)`` times it),
  averaged over the poses, in percent. Every mode counts alike, and the worst counts most. The
  best ``log k_i`` minimises a smooth convex function of one variable: started at the minimax
  value (the midrange of ``-(log mu_ij - log lam_Tj)``), a few Newton steps converge to round-off.
  Because k_i is optimal, the loss's gradient in gamma does not depend on how k_i moves
  (envelope theorem), so k_i is computed without autograd.

Log errors rather than ``omega / omega_T - 1``: they treat a model too stiff and one too soft by
the same factor alike, and the p-norm of them is smooth. For the errors that matter here (a few
%), ``|e| ≈ |omega / omega_T - 1|`` to within ``e^2 / 2``; the reported ``max_freq_error`` is
always the exact ``|omega / omega_T - 1|``.
"""
from __future__ import annotations

import torch

from .constants import OBJECTIVES  # noqa: E402

#: the p of the frequency objective's p-norm over modes. Measured on 12 held-out beams (n = 4,
#: 4 modes, paper poses, 64 starts): median worst-mode error 4.72 % (p = 4), 4.57 (8), 4.56 (16),
#: 4.53 (32); 16 overestimates the maximum of 4 modes by at most 9 %
FREQUENCY_P = 16.0
#: Newton steps for the frequency objective's log k (each one batched over all rows and poses)
_NEWTON_STEPS = 12


def check_objective(objective: str) -> str:
    from .errors import BadInput
    if objective not in OBJECTIVES:
        raise BadInput(f"objective: must be one of {', '.join(OBJECTIVES)}, got {objective!r}")
    return objective


def eigenvalue_residuals(mu: torch.Tensor, lam_truth: torch.Tensor):
    """Residuals ``(k mu - lam_T) / ||lam_T||`` (..., m, r) and the best SCFs k (..., m).

    mu (..., m, r): PRBDM eigenvalues at k = 1 per pose; lam_truth (..., r), same units."""
    t = lam_truth[..., None, :]
    k = (mu * t).sum(-1) / (mu * mu).sum(-1)
    return (k[..., None] * mu - t) / torch.linalg.vector_norm(t, dim=-1, keepdim=True), k


def eigenvalue_loss(res: torch.Tensor) -> torch.Tensor:
    """The paper's loss in percent (...,): 100 x the mean over poses of ||residual||_2."""
    return 100.0 * torch.linalg.vector_norm(res, dim=-1).mean(-1)


def best_log_scf(d: torch.Tensor, p: float = FREQUENCY_P) -> torch.Tensor:
    """c (...,) minimising ``sum_j (d_j + c)^p`` over the last axis of d: half the log SCF that
    makes the p-norm of the log frequency errors smallest. Convex for even-like p >= 2 (|.|^p)."""
    with torch.no_grad():
        c = -(d.amax(-1) + d.amin(-1)) / 2           # the minimax (p = infinity) answer
        for _ in range(_NEWTON_STEPS):
            e = d + c[..., None]
            ae = e.abs()
            g = (ae ** (p - 1) * torch.sign(e)).sum(-1)
            h = (p - 1) * (ae ** (p - 2)).sum(-1)
            c = c - g / h.clamp_min(1e-300)
    return c


def frequency_residuals(mu: torch.Tensor, lam_truth: torch.Tensor, p: float = FREQUENCY_P):
    """Log frequency errors ``log(omega / omega_T)`` (..., m, r) at the best SCFs, and those
    SCFs k (..., m). mu (..., m, r) eigenvalues at k = 1; lam_truth (..., r)."""
    d = 0.5 * (torch.log(mu) - torch.log(lam_truth[..., None, :]))
    c = best_log_scf(d, p)
    return d + c[..., None], torch.exp(2.0 * c)


def frequency_loss(res: torch.Tensor, p: float = FREQUENCY_P) -> torch.Tensor:
    """The frequency objective in percent (...,): 100 x the mean over poses of ||e||_p."""
    return 100.0 * torch.linalg.vector_norm(res, ord=p, dim=-1).mean(-1)


def residuals(objective: str, mu: torch.Tensor, lam_truth: torch.Tensor):
    """(residuals, best k) of ``objective`` for eigenvalues mu (..., m, r) at k = 1."""
    if objective == "eigenvalue":
        return eigenvalue_residuals(mu, lam_truth)
    return frequency_residuals(mu, lam_truth)


def loss(objective: str, res: torch.Tensor) -> torch.Tensor:
    """The objective's value in percent from its residuals."""
    return eigenvalue_loss(res) if objective == "eigenvalue" else frequency_loss(res)


def frequency_measure(lam: torch.Tensor, lam_truth: torch.Tensor, r: int,
                      p: float = FREQUENCY_P) -> torch.Tensor:
    """The frequency objective's value in percent (...,) for given eigenvalues lam (..., m, n)
    (their own k, e.g. a network's, not re-optimised) against lam_truth (..., R)."""
    e = 0.5 * (torch.log(lam[..., :r]) - torch.log(lam_truth[..., None, :r]))
    return frequency_loss(e, p)
