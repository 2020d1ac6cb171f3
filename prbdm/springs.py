"""Joint spring laws of a PRBDM away from rest: the stiffness law a fit result was made with.

A fit result's ``pose_target`` (:mod:`prbdm.pose_target`) says what its SCFs mean away from
rest, and so which spring law its chain has at large deflection (:func:`fitted_springs`):

- ``shape`` (fitted at rest, its stiffness held at every pose): :class:`LinearSprings`, the
  constant stiffness ``K_j = k s_j`` at every angle;
- ``straight`` (the paper's: one SCF per pose, each matched to the straight panel; results
  without ``pose_target``, made by older versions, are this): :class:`InterpolatedSprings`, the
  pose SCFs interpolated between the pose angles by an energy-consistent law. A result with a
  single pose has one SCF: constant stiffness.

The energy-consistent law. Joint j has the potential

    V_j(theta) = s_j * int_0^|theta| k(u) u du,   torque  dV_j/dtheta = s_j k(|theta|) theta,

with ``s_j`` the base stiffness [N m/rad] and ``k(u)`` the pose SCFs interpolated linearly in the
joint angle ``u`` between the pose angles (0.10 ... 0.35 rad for the paper's n = 4 poses) and
held constant outside them (below the first pose ``k`` of the first, above the last ``k`` of the
last). Each joint's SCF follows its own angle; the torque is the gradient of a potential, so a
free vibration conserves energy (tests/test_large_deflection_bench.py). Used by :mod:`prbdm.simulate` and
benchmarks/large_deflection.py.

A spring law here is any object with ``torque(theta)`` [N m], ``dtorque(theta)`` (the diagonal
of its stiffness, N m/rad) and ``energy(theta)`` [J], for relative joint angles theta (n,).
"""
from __future__ import annotations

import numpy as np

from .errors import BadInput

__all__ = ["LinearSprings", "InterpolatedSprings", "fitted_springs", "pose_target_of",
           "LAW_OF_POSE_TARGET"]

#: the spring law of each pose target (:data:`prbdm.pose_target.POSE_TARGETS`; a test keeps the
#: two in step: this module imports nothing of the fit, so that the chain can use its laws)
LAW_OF_POSE_TARGET = {"straight": "interpolated", "shape": "constant"}


class LinearSprings:
    """Constant joint stiffness K (n,) [N m/rad] about the rest angles ``ref`` (default 0)."""

    def __init__(self, K, ref=None):
        self.K = np.asarray(K, float)
        self.ref = np.zeros_like(self.K) if ref is None else np.asarray(ref, float)

    def torque(self, th):
        return self.K * (th - self.ref)

    def dtorque(self, th):
        return self.K.copy()

    def energy(self, th):
        d = th - self.ref
        return float(0.5 * np.sum(self.K * d * d))


class InterpolatedSprings:
    """Per-joint potential ``V_j = s_j int_0^|theta| k(u) u du``, ``k`` the pose SCFs ``k``
    piecewise linear in the pose angles ``a`` (ascending), held constant outside them."""

    def __init__(self, s, a, k):
        self.s = np.asarray(s, float)
        self.a = np.asarray(a, float)
        self.k = np.asarray(k, float)
        if self.a.size == 1:
            self.a, self.k = np.array([0.0, 1.0]), np.repeat(self.k, 2)
        # energy per unit s at the pose angles: int_0^a k(u) u du
        a, k = self.a, self.k
        e = [0.5 * k[0] * a[0] ** 2]
        for i in range(a.size - 1):
            e.append(e[-1] + self._seg(a[i], a[i + 1], k[i], k[i + 1], a[i + 1]))
        self.e = np.array(e)

    @staticmethod
    def _seg(a0, a1, k0, k1, u):
        """int_a0^u (k0 + (k1 - k0)(v - a0)/(a1 - a0)) v dv."""
        sl = (k1 - k0) / (a1 - a0)
        c = k0 - sl * a0
        return c * (u * u - a0 * a0) / 2 + sl * (u ** 3 - a0 ** 3) / 3

    def kval(self, u):
        return np.interp(u, self.a, self.k)

    def kslope(self, u):
        i = np.clip(np.searchsorted(self.a, u, side="right") - 1, 0, self.a.size - 2)
        sl = (self.k[i + 1] - self.k[i]) / (self.a[i + 1] - self.a[i])
        return np.where((u < self.a[0]) | (u > self.a[-1]), 0.0, sl)

    def torque(self, th):
        return self.s * self.kval(np.abs(th)) * th

    def dtorque(self, th):
        u = np.abs(th)
        return self.s * (self.kval(u) + self.kslope(u) * u)

    def energy(self, th):
        total = 0.0
        for sj, t in zip(self.s, np.abs(th)):
            a, k = self.a, self.k
            if t <= a[0]:
                v = 0.5 * k[0] * t * t
            elif t >= a[-1]:
                v = self.e[-1] + 0.5 * k[-1] * (t * t - a[-1] ** 2)
            else:
                i = int(np.searchsorted(a, t, side="right") - 1)
                v = self.e[i] + self._seg(a[i], a[i + 1], k[i], k[i + 1], t)
            total += sj * v
        return float(total)


def pose_target_of(fit: dict) -> str:
    """The result's ``pose_target``: ``"straight"`` or ``"shape"`` (``prbdm fit`` and
    ``prbdm predict`` write it); ``"straight"`` where it has none (made before pose targets
    existed, or by :func:`prbdm.export.run_fit`). A ``shape`` result must hold one SCF at every
    pose; BadInput otherwise."""
    target = fit.get("pose_target", "straight")
    if target not in LAW_OF_POSE_TARGET:
        raise BadInput(f"--from: pose_target must be one of {', '.join(LAW_OF_POSE_TARGET)}, "
                       f"got {target!r}")
    if target == "shape":
        k = np.atleast_1d(np.asarray(fit.get("k", []), float))
        if k.size and np.ptp(k) > 1e-12 * np.abs(k).max():
            raise BadInput("--from: pose_target 'shape' holds one stiffness at every pose, but "
                           "the result's k differs between poses")
    return target


def fitted_springs(fit: dict, base_stiffness) -> tuple[object, dict]:
    """(springs, info): the spring law the result ``fit`` (gamma, k, poses, law, pose_target)
    was fitted with, on the base stiffness ``base_stiffness`` s_j (n,) [N m/rad] of its chain
    (``prbdm.export.prbdm_from_fit``'s hinges ``base_stiffness``), at rest straight (springref 0).
    ``info`` (JSON-ready) names the law, the pose target and the SCFs used.

    ``shape`` or a single pose: :class:`LinearSprings` with ``k`` (the same at every pose);
    ``straight`` with several poses: :class:`InterpolatedSprings` over the poses' joint angle,
    which must be one angle per pose (every joint at it, as ``make_poses`` builds them), all
    distinct and >= 0 (BadInput otherwise)."""
    s = np.asarray(base_stiffness, float)
    target = pose_target_of(fit)
    k = np.atleast_1d(np.asarray(fit["k"], float))
    poses = np.atleast_2d(np.asarray(fit["poses"], float))
    if LAW_OF_POSE_TARGET[target] == "constant" or k.size == 1:
        info = {"law": "constant", "pose_target": target, "k": float(k[0]),
                "why": ("a shape result holds its rest stiffness at every pose"
                        if target == "shape" else "a single pose: one SCF")}
        return LinearSprings(k[0] * s), info
    if np.ptp(poses, axis=1).max() > 1e-12 or np.any(poses[:, 0] < 0):
        raise BadInput("--from: the interpolated spring law of a result fitted for several "
                       "poses needs every joint at one angle >= 0 in each pose (the paper's "
                       "poses, or `prbdm fit --poses T1,T2,...`)")
    order = np.argsort(poses[:, 0], kind="stable")
    a, kk = poses[order, 0], k[order]
    if np.any(np.diff(a) <= 0):
        raise BadInput("--from: two poses of the result have the same angle: the interpolated "
                       "spring law needs one SCF per angle")
    info = {"law": "interpolated", "pose_target": target, "pose_angles": a.tolist(),
            "k": kk.tolist(),
            "why": "one SCF per pose, matched to the straight panel (the paper's): its SCFs "
                   "interpolated between the pose angles by an energy-consistent law "
                   "(prbdm.springs.InterpolatedSprings), held at the end poses' outside them"}
    return InterpolatedSprings(s, a, kk), info
