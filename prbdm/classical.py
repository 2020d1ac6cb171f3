"""Classical static pseudo-rigid-body models (PRBMs), used as dynamic models in prbdm's own chain.

Two textbook PRBMs of a cantilever loaded at its tip, both designed for uniform beams and static
large deflection, are here cut from the beam like any prbdm PRBDM (docs/conventions.md §3: link masses, centres
and rotary inertias are the exact integrals of the real planform) and given their own joint
springs instead of an SCF times a stiffness law:

- **Howell 1R** (Howell & Midha 1995; Howell, *Compliant Mechanisms*, 2001): a rigid root segment
  of length ``(1 - gamma) L``, then the characteristic pivot and a rigid link of ``gamma L`` to the
  tip; ``gamma = 0.85``, torsional spring ``K = gamma K_Theta EI / L`` with ``K_Theta = 2.65``.
  In prbdm's terms: n = 1, ``gamma = [0.15, 0.85]``.
- **Su 3R** (Su, J. Mechanisms Robotics 1(2) 021008, 2009): ``gamma = [0.10, 0.35, 0.40, 0.15]``
  and springs ``K_i = k_i EI / L`` with ``k = 3.51, 2.99, 2.58``. n = 3.

**What EI means on a tapered beam** (the classical formulas assume a uniform one). Default
``ei="tip"``: the *tip-load equivalent* stiffness

    EI_tip = L^3 / (3 ∫_0^L (L - x)^2 / EI(x) dx),

the EI of the uniform cantilever whose small-deflection compliance under a tip force equals the
real beam's. Both models were calibrated for tip forces on uniform beams, so this keeps what they
were built to reproduce (for a uniform beam it is just EI). Alternatives, for comparison:
``"harmonic"``: ``EI_h = L / ∫ dx / EI`` (equal compliance under a tip *moment*); ``"joint"``: the
local ``EI(x_j)`` at each joint. All three coincide on a uniform beam. The integrals are exact
for the piecewise-linear planform (``I = 2 w t^3 / 12``).

Each model also has an equivalent per-joint SCF of prbdm's ``beam`` law, ``K_j / s_j``
(:func:`beam_law_scf`); it is per joint, not per pose, so the models are evaluated with their
explicit stiffness (:func:`eigenvalues`) rather than through :func:`prbdm.model.eigenvalues`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from .errors import BadInput
from .model import (
    BeamTensors,
    Links,
    as_beam_tensors,
    base_stiffness,
    links_from_gamma,
    make_poses,
    mass_matrix,
)

__all__ = ["ClassicalPRBM", "HOWELL_1R", "SU_3R", "CLASSICAL", "EI_CHOICES", "joint_ei",
           "joint_stiffness", "beam_law_scf", "eigenvalues", "tip_compliance",
           "weighted_compliance"]

EI_CHOICES = ("tip", "harmonic", "joint")


@dataclass(frozen=True)
class ClassicalPRBM:
    """A classical PRBM: link fractions ``gamma`` (n+1) and spring coefficients ``c`` (n),
    ``K_j = c_j EI / L``."""

    key: str
    name: str
    gamma: tuple
    coefficients: tuple
    reference: str

    @property
    def joints(self) -> int:
        return len(self.coefficients)


HOWELL_1R = ClassicalPRBM(
    "howell-1r", "Howell 1R", (0.15, 0.85), (0.85 * 2.65,),
    "Howell & Midha 1995: gamma = 0.85, K = gamma K_Theta EI / L, K_Theta = 2.65")
SU_3R = ClassicalPRBM(
    "su-3r", "Su 3R", (0.10, 0.35, 0.40, 0.15), (3.51, 2.99, 2.58),
    "Su 2009: gamma = 0.10/0.35/0.40/0.15, K_i = (3.51, 2.99, 2.58) EI / L")
CLASSICAL = {m.key: m for m in (HOWELL_1R, SU_3R)}


# ----------------------------------------------------------------------------- EI of a tapered beam
def weighted_compliance(x, w, a: float, p: int) -> float:
    """Exact ``∫_0^L (a - x)^p / w(x) dx`` for a piecewise-linear ``w > 0`` through ``(x, w)``,
    ``p`` in {0, 1, 2}, ``a >= x[-1]`` (arrays in any consistent unit)."""
    x, w = np.asarray(x, dtype=np.float64), np.asarray(w, dtype=np.float64)
    total = 0.0
    for xa, xb, wa, wb in zip(x[:-1], x[1:], w[:-1], w[1:]):
        h = xb - xa
        if h <= 0:
            continue
        c = a - xa
        beta = (wb - wa) / wa
        if abs(beta) < 1e-2:
            # 1/(1 + beta u) as a series: the closed form below divides by beta^3
            u_int = [_poly_moment(c, h, p, k) for k in range(14)]
            total += h / wa * sum((-beta) ** k * u_int[k] for k in range(14))
        else:
            b = (wb - wa) / h
            D = wa + b * c                        # (a - x) = (D - w) / b along the segment
            lq = math.log(wb / wa)
            if p == 0:
                total += lq / b
            elif p == 1:
                total += (D * lq - (wb - wa)) / b ** 2
            else:
                total += (D * D * lq - 2 * D * (wb - wa) + (wb * wb - wa * wa) / 2) / b ** 3
    return total


def _poly_moment(c, h, p, k):
    """∫_0^1 (c - h u)^p u^k du."""
    coef = [(1,), (c, -h), (c * c, -2 * c * h, h * h)][p]
    return sum(cj / (j + k + 1) for j, cj in enumerate(coef))


def joint_ei(beam, prbm: ClassicalPRBM, ei: str = "tip") -> np.ndarray:
    """EI [N m^2] used for each of the model's joints (n,), see the module docstring."""
    if ei not in EI_CHOICES:
        raise BadInput(f"ei: must be one of {', '.join(EI_CHOICES)}, got {ei!r}")
    E, t, L = beam.material.E, beam.thickness, beam.length
    x, w = beam.x, beam.half_width
    scale = E * t ** 3 / 6.0                                   # EI = scale * w  (I = 2 w t^3/12)
    if ei == "tip":
        value = scale * L ** 3 / (3.0 * weighted_compliance(x, w, L, 2))
        return np.full(prbm.joints, value)
    if ei == "harmonic":
        return np.full(prbm.joints, scale * L / weighted_compliance(x, w, L, 0))
    xj = L * np.cumsum(prbm.gamma)[:-1]
    return scale * np.interp(xj, x, w)


def joint_stiffness(beam, prbm: ClassicalPRBM, ei: str = "tip") -> np.ndarray:
    """Spring constants K_j = c_j EI / L [N m / rad], (n,)."""
    return np.asarray(prbm.coefficients) * joint_ei(beam, prbm, ei) / beam.length


def beam_law_scf(beam, prbm: ClassicalPRBM, ei: str = "tip") -> np.ndarray:
    """The classical springs as per-joint SCFs of prbdm's ``beam`` law, ``K_j / s_j`` (n,)."""
    bt = as_beam_tensors(beam)
    links = links_from_gamma(bt, torch.tensor(prbm.gamma, dtype=torch.float64))
    s_si = base_stiffness(bt, links, "beam").numpy() * beam.material.E * beam.thickness ** 3
    return joint_stiffness(beam, prbm, ei) / s_si


def tip_compliance(beam, prbm: ClassicalPRBM, ei: str = "tip") -> float:
    """Small-deflection static tip compliance under a tip force, ``Σ (L - x_j)^2 / K_j`` [m/N]
    (a rigid chain deflects only by its joint rotations)."""
    xj = beam.length * np.cumsum(prbm.gamma)[:-1]
    return float(np.sum((beam.length - xj) ** 2 / joint_stiffness(beam, prbm, ei)))


# ----------------------------------------------------------------------------- dynamics
def eigenvalues(beams, prbm: ClassicalPRBM, poses="paper", ei: str = "tip") -> torch.Tensor:
    """Eigenvalues omega^2 [rad^2/s^2] of the classical PRBM cut from ``beams`` (one Beam or a
    list), ``(m, n)`` or ``(B, m, n)``, ascending per pose; poses as :func:`prbdm.model.make_poses`
    for the model's own n."""
    single = not isinstance(beams, (list, tuple))
    blist = [beams] if single else list(beams)
    bt = BeamTensors.from_beams(blist)
    n = prbm.joints
    gamma = torch.tensor(prbm.gamma, dtype=torch.float64).expand(len(blist), n + 1)
    pose_t = make_poses(poses, n)
    links = links_from_gamma(bt, gamma)
    # SI stiffness -> prbdm's nondimensional unit E t^3 (model.base_stiffness)
    s = torch.as_tensor(np.stack([joint_stiffness(b, prbm, ei) / (b.material.E * b.thickness ** 3)
                                  for b in blist]))
    lam = _eigen_explicit(links, s, pose_t) * bt.lambda0[:, None, None]
    return lam[0] if single else lam


def _eigen_explicit(links: Links, s: torch.Tensor, poses: torch.Tensor) -> torch.Tensor:
    """As :func:`prbdm.model.eigenvalues_unit_k`, with a given diagonal stiffness s (B, n)."""
    expanded = Links(*(v[..., None, :] for v in (links.cuts, links.length, links.mass, links.com,
                                                  links.inertia, links.mean_half_width,
                                                  links.tributary_compliance)))
    M = mass_matrix(expanded, poses)                               # (B, m, n, n)
    d = torch.rsqrt(s)[:, None, :]
    mu = torch.linalg.eigvalsh(d[..., :, None] * M * d[..., None, :])
    return torch.flip(1.0 / mu, [-1])
