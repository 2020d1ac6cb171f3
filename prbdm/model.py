"""The differentiable nR-PRBDM (docs/conventions.md §3): links cut from the beam, M(theta), K, eigenvalues, loss.

Everything is batched over leading dimensions and differentiable in torch:

    gamma  (..., n+1)   link lengths as fractions of L (sum 1)
    k      (..., m)     stiffness correction factors, one per pose
    poses  (m, n) or (..., m, n)  relative joint angles theta [rad]
    lam    (..., m, n)  eigenvalues omega^2 [rad^2/s^2], ascending per pose

Units. The physics is solved in nondimensional form: lengths in units of L, masses in rho t L^2,
inertias and M in rho t L^4, eigenvalues in ``lambda_0 = E t^2 / (rho L^4)``. A rubber strip and a
steel panel then give matrices of the same size, and the SI eigenvalues are ``lambda_0 * lam_hat``.

Eigenvalues. K is diagonal and positive, so ``K v = lam M v`` is solved as the symmetric standard
problem ``(D M D) u = mu u`` with ``D = K^(-1/2)`` and ``lam = 1 / mu``: no Cholesky, no inverse of a
possibly ill-conditioned M, and the lowest frequencies (the ones we fit) are the largest ``mu``,
which a symmetric eigensolver returns to full relative accuracy. Only eigenvalues are
differentiated (``eigvalsh``): their gradient ``v^T dA v`` has no ``1 / (mu_i - mu_j)`` factor, so
it stays finite when eigenvalues coincide. Because K scales with one SCF per pose,
``lam(k_i) = k_i * lam(1)``: one eigen-solve per pose serves every k.

Precision. The solver's absolute error in ``mu`` is about ``eps * mu_max``, so ``lam_i`` is good
to about ``eps * lam_i / lam_1``: mode 1 to round-off, the highest mode to ``eps * cond`` with
``cond = lam_max / lam_min``. In float64 that is harmless (cond <= ~1e8 for n <= 39); in float32
(eps 1.2e-7) the highest mode of a 4R model is already a few % off. So every solve checks, on the
detached result and with one reduction: a short float type (float32, float16, bfloat16) with
``PRECISION_FACTOR * eps * cond > PRECISION_RTOL`` (4 eps cond > 1e-3), or any eigenvalue not
finite or not positive (any dtype), raises
a :class:`PrecisionWarning` naming the dtype and the condition estimate. Autograd and batching
are untouched (the check only reads the values).
"""
from __future__ import annotations

import math
import sys
import warnings
from dataclasses import dataclass

import numpy as np
import torch

from .errors import BadInput
from .geometry import check_prbdm_width_ratio
from .poses import pose_set
from .sections import span_integrals

__all__ = ["BeamTensors", "Links", "links_from_gamma", "mass_matrix", "base_stiffness",
           "paper_poses", "make_poses", "eigenvalues", "eigenvalues_unit_k", "loss_percent",
           "frequency_errors", "uniform_gamma", "GAMMA_MIN", "GAMMA_MAX", "LAWS",
           "PrecisionWarning", "PRECISION_RTOL", "PRECISION_FACTOR"]

from .chain import LAWS  # noqa: E402  (the base stiffness laws; chain.base_stiffness is the twin)
from .constants import GAMMA_MAX, GAMMA_MIN  # noqa: E402  (Eq. 13 bounds on each gamma_j)

#: a short float type warns when its estimated relative error of the highest eigenvalue,
#: PRECISION_FACTOR * eps * lam_max / lam_min, exceeds PRECISION_RTOL. The factor is measured:
#: float32 errors of the highest mode reach 2.4-5.8 eps lam_n / lam_1 (docs/validation.md)
PRECISION_RTOL = 1e-3
PRECISION_FACTOR = 4.0


class PrecisionWarning(UserWarning):
    """Eigenvalues computed in a float type too short for the problem's conditioning, or not
    finite / not positive: some of the returned numbers are not to be trusted (use float64)."""


# ----------------------------------------------------------------------------- beams as tensors
@dataclass(frozen=True)
class BeamTensors:
    """A batch of beams as tensors, leading shape ``(...)``.

    x, w: (..., S) stations and half-widths divided by the length L (x from 0 to 1);
    length, thickness [m], E [Pa], rho [kg/m^3]: (...,).
    Beams with fewer stations are padded by repeating their tip station (zero-length segments).
    """

    x: torch.Tensor
    w: torch.Tensor
    length: torch.Tensor
    thickness: torch.Tensor
    E: torch.Tensor
    rho: torch.Tensor

    @classmethod
    def from_beams(cls, beams, dtype=torch.float64, device=None) -> "BeamTensors":
        """From one :class:`prbdm.geometry.Beam` (shape ()) or a sequence of them (shape (B,))."""
        single = not isinstance(beams, (list, tuple))
        beams = [beams] if single else list(beams)
        if not beams:
            raise BadInput("beams: need at least one beam")
        for b in beams:
            check_prbdm_width_ratio(b)
        S = max(len(b.x) for b in beams)
        xs = np.empty((len(beams), S))
        ws = np.empty((len(beams), S))
        for i, b in enumerate(beams):
            n = len(b.x)
            xs[i, :n], ws[i, :n] = b.x / b.length, b.half_width / b.length
            xs[i, n:], ws[i, n:] = 1.0, b.half_width[-1] / b.length
        xs[:, -1] = 1.0  # exactly, whatever the rounding of x / L
        scal = np.array([[b.length, b.thickness, b.material.E, b.material.rho] for b in beams])
        kw = dict(dtype=dtype, device=device)
        t = [torch.as_tensor(v, **kw) for v in (xs, ws, *scal.T)]
        if single:
            t = [v[0] for v in t]
        return cls(*t)

    @property
    def batch_shape(self):
        return self.length.shape

    @property
    def lambda0(self) -> torch.Tensor:
        """Eigenvalue scale E t^2 / (rho L^4) [rad^2/s^2]."""
        return self.E * self.thickness ** 2 / (self.rho * self.length ** 4)

    def to(self, dtype=None, device=None) -> "BeamTensors":
        return BeamTensors(*(v.to(dtype=dtype, device=device) for v in
                             (self.x, self.w, self.length, self.thickness, self.E, self.rho)))


def as_beam_tensors(beam, dtype=torch.float64) -> BeamTensors:
    return beam if isinstance(beam, BeamTensors) else BeamTensors.from_beams(beam, dtype=dtype)


# ----------------------------------------------------------------------------- links
@dataclass(frozen=True)
class Links:
    """Rigid links 1..n (link 0 is clamped and carries no dynamics), nondimensional.

    cuts (..., n+2): link boundaries [0, x_1, ..., x_n, 1] / L; x_j is joint j.
    length (..., n+1) link lengths / L (link 0 included);
    mass (..., n) / (rho t L^2); com (..., n) distance of the centre of mass from joint j / L;
    inertia (..., n) rotary inertia about the centre of mass / (rho t L^4);
    mean_half_width (..., n): (1/len) ∫ w dx / L, from which the mean area moment follows;
    tributary_compliance (..., n): ∫ dx / w over joint j's tributary span (the `beam` law).
    """

    cuts: torch.Tensor
    length: torch.Tensor
    mass: torch.Tensor
    com: torch.Tensor
    inertia: torch.Tensor
    mean_half_width: torch.Tensor   # (..., n) (1/len) ∫ w dx / L, gives the mean area moment
    tributary_compliance: torch.Tensor  # (..., n) ∫ dx / w over joint j's tributary span

    def physical(self, beam: BeamTensors) -> dict:
        """SI link table: lengths [m], masses [kg], centres [m from joint], inertias [kg m^2],
        mean area moments [m^4], for links 1..n (and link 0's length)."""
        L, t, rho = beam.length[..., None], beam.thickness[..., None], beam.rho[..., None]
        return {
            "joint_x": self.cuts[..., 1:-1] * L,
            "length": self.length * L,
            "mass": self.mass * rho * t * L ** 2,
            "com": self.com * L,
            "inertia": self.inertia * rho * t * L ** 4,
            "area_moment": 2 * self.mean_half_width * L * t ** 3 / 12,
        }


def links_from_gamma(beam: BeamTensors, gamma: torch.Tensor) -> Links:
    """Cut the beam into n+1 links of length fractions ``gamma`` (..., n+1), exact integrals."""
    inner = torch.cumsum(gamma[..., :-1], dim=-1)
    zero = torch.zeros_like(inner[..., :1])
    cuts = torch.cat([zero, inner, torch.ones_like(zero)], dim=-1)   # tip exactly at 1
    n = gamma.shape[-1] - 1
    # links 1..n, then the joints' tributary spans (centre of the link before to centre of the
    # link after; clamp and tip at the ends) for the `beam` law: one call integrates both
    mids = (cuts[..., 1:] + cuts[..., :-1]) / 2
    a = torch.cat([cuts[..., 1:-1], zero, mids[..., 1:-1]], dim=-1)
    b = torch.cat([cuts[..., 2:], mids[..., 1:-1], torch.ones_like(zero)], dim=-1)
    si = span_integrals(beam.x, beam.w, a, b)
    area, first, second = si.area[..., :n], si.first[..., :n], si.second[..., :n]
    length = cuts[..., 1:] - cuts[..., :-1]
    lj = length[..., 1:]
    return Links(cuts=cuts, length=length, mass=area, com=lj / 2 + first / area,
                 inertia=second - first ** 2 / area, mean_half_width=area / (2 * lj),
                 tributary_compliance=si.compliance[..., n:])


def uniform_gamma(n: int, dtype=torch.float64) -> torch.Tensor:
    """The rigid-finite-element segmentation [1/2, 1, ..., 1, 1/2] / n."""
    g = torch.ones(n + 1, dtype=dtype)
    g[0] = g[-1] = 0.5
    return g / n


# ----------------------------------------------------------------------------- dynamics
def mass_matrix(links: Links, theta: torch.Tensor) -> torch.Tensor:
    """M(theta), nondimensional (rho t L^4), shape (..., n, n) for theta (..., n).

    T = 1/2 Σ_j (m_j |v_cj|^2 + J_j qdot_j^2) with q_j = theta_1 + ... + theta_j. Rotating joint
    k moves the centre of link j >= k with velocity perpendicular to (r_cj - p_k), so
    M_kl = Σ_{j >= max(k,l)} [ m_j (r_cj - p_k)·(r_cj - p_l) + J_j ].
    """
    n = theta.shape[-1]
    q = torch.cumsum(theta, dim=-1)
    e = torch.stack([torch.cos(q), torch.sin(q)], dim=-1)              # (..., n, 2) link axes
    ell = links.length[..., 1:-1, None]                                 # links 1..n-1 lengths
    # joint positions p_1..p_n: p_1 = (x_1, 0); p_{j+1} = p_j + l_j e_j
    p1 = torch.stack([links.cuts[..., 1], torch.zeros_like(links.cuts[..., 1])], dim=-1)
    steps = torch.nn.functional.pad(torch.cumsum(ell * e[..., :-1, :], dim=-2), (0, 0, 1, 0))
    p = p1[..., None, :] + steps                                        # (..., n, 2)
    rc = p + links.com[..., None] * e                                   # (..., n, 2)
    lower = torch.ones(n, n, dtype=torch.bool, device=theta.device).tril()  # [j, k]: k <= j
    d = (rc[..., :, None, :] - p[..., None, :, :]) * lower[..., None]  # (..., j, k, 2)
    M = torch.einsum("...j,...jkd,...jld->...kl", links.mass, d, d)
    # rotary terms: Σ_{j >= max(k,l)} J_j, a reversed cumulative sum indexed by max(k, l)
    tail = torch.flip(torch.cumsum(torch.flip(links.inertia, [-1]), -1), [-1])
    idx = torch.maximum(torch.arange(n)[:, None], torch.arange(n)[None, :]).to(theta.device)
    return M + tail[..., idx]


def base_stiffness(beam: BeamTensors, links: Links, law: str = "beam") -> torch.Tensor:
    """Base joint stiffness s_j (..., n), nondimensional: SI value / (rho t L^4 lambda_0).

    ``beam``: s_j = 1 / ∫ dx / (E I(x)) over the joint's tributary span, from the centre of the
    link before it (the clamp for joint 1) to the centre of the link after it (the tip for
    joint n). With I = 2 w t^3 / 12 this is (E t^3 / 6) / ∫ dx / w, i.e. 1 / (6 ∫ dx/w) here.
    ``paper``: s_j = sqrt(E I_j / m_j) with I_j the mean area moment and m_j the mass of link j
    (joint j drives link j, as in the paper's reference code). Eq. 11 as printed, in SI units,
    then made nondimensional.
    """
    if law == "beam":
        return 1.0 / (6.0 * links.tributary_compliance)
    if law == "paper":
        L, t = beam.length[..., None], beam.thickness[..., None]
        E, rho = beam.E[..., None], beam.rho[..., None]
        # I_j / m_j = (t^3/12 · area / len) / (rho t area) = t^2 / (12 rho len)
        s_si = torch.sqrt(E * t ** 2 / (12 * rho * links.length[..., 1:] * L))
        return s_si / (rho * t * L ** 4 * beam.lambda0[..., None])
    raise BadInput(f"law: must be one of {', '.join(LAWS)}, got {law!r}")


# ----------------------------------------------------------------------------- poses
def paper_poses(n: int, dtype=torch.float64) -> torch.Tensor:
    """The paper's pose set (m, n), Eqs. 7-8 (:func:`prbdm.poses.paper_angles`)."""
    return torch.as_tensor(pose_set("paper", n)).to(dtype)


def make_poses(spec, n: int, dtype=torch.float64) -> torch.Tensor:
    """Pose set (m, n) from ``'paper'``, ``'linear'`` (theta = 0), a list of angles (each pose puts
    every joint at that angle), or an explicit (m, n) array (:func:`prbdm.poses.pose_set`)."""
    if isinstance(spec, torch.Tensor):
        spec = spec.detach().cpu().numpy()
    return torch.as_tensor(pose_set(spec, n)).to(dtype)


# ----------------------------------------------------------------------------- eigenvalues
def eigenvalues_unit_k(beam: BeamTensors, gamma: torch.Tensor, poses: torch.Tensor,
                       law: str = "beam") -> torch.Tensor:
    """Nondimensional eigenvalues with every SCF equal to 1, (..., m, n), ascending.

    Multiply by k_i and by ``beam.lambda0`` for SI values (see :func:`eigenvalues`)."""
    links = links_from_gamma(beam, gamma)
    s = base_stiffness(beam, links, law)                                # (..., n)
    M = mass_matrix(_expand_links(links), poses)                        # (..., m, n, n)
    d = torch.rsqrt(s)[..., None, :]                                    # D = K^-1/2
    A = d[..., :, None] * M * d[..., None, :]
    mu = torch.linalg.eigvalsh(A)                                       # ascending
    _check_precision(mu)
    return torch.flip(1.0 / mu, [-1])


def _check_precision(mu: torch.Tensor) -> None:
    """Warn (:class:`PrecisionWarning`) when the eigenvalues ``mu`` of A (..., n), ascending, are
    not all finite and positive, or, in a short float type, when ``PRECISION_FACTOR * eps * mu_max
    / mu_min`` (the estimated relative error of the highest eigenvalue lam = 1/mu) exceeds
    ``PRECISION_RTOL``.
    Reads detached values only; one host sync per call."""
    if mu.numel() == 0:
        return
    with torch.no_grad():
        m = mu.detach()
        eps = torch.finfo(m.dtype).eps
        short = eps > 1e-10
        sane = torch.isfinite(m).all() & (m > 0).all()
        if short:
            cond = (m[..., -1] / m[..., 0]).abs().nan_to_num(math.inf).max()
            flags = torch.stack([sane.to(m.dtype), cond.to(m.dtype)]).double().cpu()
            sane, cond = bool(flags[0]), float(flags[1])
        else:
            sane, cond = bool(sane), None
    if sane and (cond is None or PRECISION_FACTOR * eps * cond <= PRECISION_RTOL):
        return
    dt = str(m.dtype).replace("torch.", "")
    what = ("some eigenvalues are not finite or not positive" if not sane else
            f"the highest eigenvalues may be off by up to ~{PRECISION_FACTOR * eps * cond:.1e} "
            f"relative ({PRECISION_FACTOR:g} eps * cond; lam_i is good to about "
            f"{PRECISION_FACTOR:g} eps * lam_i / lam_1)")
    cond_txt = "" if cond is None else f", condition estimate lam_max / lam_min = {cond:.2e}"
    level, frame = 1, sys._getframe(0)           # point at the first caller outside this module
    while frame is not None and frame.f_code.co_filename == __file__:
        frame, level = frame.f_back, level + 1
    warnings.warn(f"PRBDM eigenvalues in {dt}{cond_txt}: {what}; use float64 "
                  "(e.g. gamma.double(), BeamTensors.from_beams(..., dtype=torch.float64))",
                  PrecisionWarning, stacklevel=level)


def _expand_links(links: Links) -> Links:
    # insert a pose dimension before the link dimension so links broadcast against poses
    return Links(*(v[..., None, :] for v in (links.cuts, links.length, links.mass, links.com,
                                              links.inertia, links.mean_half_width,
                                              links.tributary_compliance)))


def eigenvalues(beam, gamma, k=None, poses="paper", law: str = "beam") -> torch.Tensor:
    """Eigenvalues lambda = omega^2 [rad^2/s^2] of ``K v = lambda M v`` per pose, (..., m, n).

    beam: :class:`BeamTensors` or Beam(s); gamma (..., n+1); k (..., m) or None for all ones;
    poses: see :func:`make_poses`.
    """
    beam = as_beam_tensors(beam, dtype=gamma.dtype if torch.is_tensor(gamma) else torch.float64)
    gamma = torch.as_tensor(gamma, dtype=beam.x.dtype)
    n = gamma.shape[-1] - 1
    if n < 1:
        raise BadInput(f"gamma: needs n + 1 >= 2 link fractions, got {gamma.shape[-1]}")
    poses = make_poses(poses, n, dtype=gamma.dtype)
    lam = eigenvalues_unit_k(beam, gamma, poses, law) * beam.lambda0[..., None, None]
    if k is not None:
        k = torch.as_tensor(k, dtype=gamma.dtype)
        lam = lam * k[..., :, None]
    return lam


def loss_percent(lam: torch.Tensor, lam_truth: torch.Tensor, r: int | None = None) -> torch.Tensor:
    """Eqs. 12-13 as the reference code computes them, in percent, (...):
    100/m Σ_i ||lam(pose i)[:r] - lam_truth[:r]|| / ||lam_truth[:r]||, r = min(n, modes)."""
    n = lam.shape[-1]
    r = min(n, lam_truth.shape[-1]) if r is None else min(r, n, lam_truth.shape[-1])
    ref = lam_truth[..., None, :r]
    rel = torch.linalg.vector_norm(lam[..., :r] - ref, dim=-1) / torch.linalg.vector_norm(ref, dim=-1)
    return 100.0 * rel.mean(-1)


def frequency_errors(lam: torch.Tensor, omega_truth: torch.Tensor, r: int | None = None):
    """Per-mode relative frequency errors |omega - omega_truth| / omega_truth, (..., m, r)."""
    n = lam.shape[-1]
    r = min(n, omega_truth.shape[-1]) if r is None else min(r, n, omega_truth.shape[-1])
    omega = torch.sqrt(lam[..., :r])
    return (omega - omega_truth[..., None, :r]).abs() / omega_truth[..., None, :r]
