"""Truth model ``rod``: the geometrically exact planar Euler-Bernoulli rod (docs/large-deflection.md).

A planar inextensible, unshearable (Kirchhoff) rod clamped at ``x = 0``, the panel's bending
stiffness ``E I(s) = E 2 w(s) t^3 / 12`` and mass per length ``rho A(s) = rho 2 w(s) t``
(``w`` piecewise linear through the stations), deflecting in the x-z plane; ``theta(s)`` is the
tangent angle from +x towards +z. Rotary inertia of the section is left out by default (as in the
Euler-Bernoulli ``beam`` truth); ``rotary=True`` adds ``rho I(s)``.

- :func:`rod_static`: the large-deflection equilibrium under a dead tip force (magnitude, angle)
  or a tip moment, or the load that gives a tip angle: the elastica boundary-value problem
  ``(E I theta')' + F_z cos theta - F_x sin theta = 0``, ``theta(0) = 0``,
  ``E I theta'(L) = M_tip``, solved by shooting on the root moment (DOP853, rtol 1e-12,
  station by station) with Newton on the variational equation, by continuation in the load.
- :func:`rod_frequencies`: small-vibration frequencies about the straight rod, a loaded
  equilibrium (the load's geometric stiffness included) or a stress-free curved shape
  (:func:`arc_shape`, :func:`chain_shape`, :func:`sampled_shape`).
- :func:`rod_response`: the nonlinear free vibration released from rest in a static deflection.

The dynamics use :class:`prbdm.truth._rod_dynamics.RodGalerkin` (the angle field on continuous
piecewise polynomials, exact kinematics); it does not use the chain model :mod:`prbdm.model`.
Everything is solved in nondimensional form (forces by ``E I_max / L^2``, time by
``sqrt(rho A_max L^4 / E I_max)``), in float64; inputs and outputs are SI.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy.integrate import solve_ivp
from scipy.linalg import eigh
from scipy.optimize import brentq

from ..errors import BadInput
from ..geometry import Beam, check_beam
from ._rod_dynamics import RodGalerkin

__all__ = ["rod_static", "rod_frequencies", "rod_response", "RodEquilibrium", "RestShape",
           "RodFrequencies", "RodResponse", "arc_shape", "chain_shape", "sampled_shape",
           "MAX_LOAD", "MAX_MOMENT_ANGLE"]

#: the largest nondimensional force P L^2 / (E I_max) accepted (the clamp's boundary layer,
#: of length ~ L / sqrt(P L^2 / E I), is then 0.1 L; the tip of a uniform strip under a
#: perpendicular force is then within 1.5e-4 rad of the force's direction)
MAX_LOAD = 100.0
#: the largest tip angle [rad] asked of a tip moment (a uniform strip closes into a circle at 2 pi)
MAX_MOMENT_ANGLE = 2.0 * math.pi
#: default discretisation of the dynamics (converged to ~1e-9 on the first 6 modes, see the docs)
ELEMENTS, DEGREE = 12, 6
_RTOL = 1e-12


# ---------------------------------------------------------------------------- the beam, scaled
@dataclass(frozen=True)
class _Scaled:
    L: float
    EI: float        # E I_max [N m^2]
    rhoA: float      # rho A_max [kg/m]
    xs: np.ndarray   # stations / L
    b: np.ndarray    # w / w_max at the stations
    rotary: float    # t^2 / (12 L^2)

    @property
    def force(self):      # N per unit nondimensional force
        return self.EI / self.L ** 2

    @property
    def moment(self):     # N m per unit nondimensional moment
        return self.EI / self.L

    @property
    def time(self):       # s per unit nondimensional time
        return math.sqrt(self.rhoA * self.L ** 4 / self.EI)


def _scaled(beam: Beam) -> _Scaled:
    check_beam(beam, "beam")
    m = beam.material
    L, t, wmax = beam.length, beam.thickness, float(beam.half_width.max())
    return _Scaled(L=L, EI=m.E * 2 * wmax * t ** 3 / 12.0, rhoA=m.rho * 2 * wmax * t,
                   xs=np.asarray(beam.x) / L, b=np.asarray(beam.half_width) / wmax,
                   rotary=t ** 2 / (12.0 * L ** 2))


def _number(v, name, lo=-math.inf, hi=math.inf, what=""):
    if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)) \
            or not math.isfinite(v):
        raise BadInput(f"{name}: must be a finite number{what}, got {v!r}")
    if not lo <= v <= hi:
        raise BadInput(f"{name}: must lie in [{lo:g}, {hi:g}]{what}, got {v!r}")
    return float(v)


def _integer(v, name: str, lo: int, hi: int) -> int:
    """``v`` as an int in [lo, hi], else BadInput naming ``name`` and the range."""
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not lo <= v <= hi:
        raise BadInput(f"{name}: must be an integer in [{lo}, {hi}], got {v!r}")
    return int(v)


def _discretisation(elements, degree):
    return _integer(elements, "elements", 2, 400), _integer(degree, "degree", 1, 12)


# ---------------------------------------------------------------------------- statics: shooting
@dataclass
class RodEquilibrium:
    """A static equilibrium of the rod under a dead tip load (SI).

    ``s``, ``theta``, ``x``, ``z``: the shape sampled along the arc length [m, rad, m, m];
    ``tip_x``, ``tip_z`` [m], ``tip_angle`` [rad]; the load: ``force`` (F_x, F_z) [N],
    ``moment`` [N m]; ``load`` the nondimensional force ``P L^2 / (E I_max)`` (or moment
    ``M L / (E I_max)``); ``stability`` d m(L) / d m(0) of the shooting (1 unloaded, > 0 on the
    stable branch); ``time_s`` the solve time.
    """

    s: np.ndarray
    theta: np.ndarray
    x: np.ndarray
    z: np.ndarray
    tip_x: float
    tip_z: float
    tip_angle: float
    force: tuple
    moment: float
    load: float
    stability: float
    time_s: float = 0.0
    root_moment: float = 0.0

    def to_dict(self) -> dict:
        return {"model": "rod", "tip_x": self.tip_x, "tip_z": self.tip_z,
                "tip_angle": self.tip_angle, "force": [float(f) for f in self.force],
                "moment": self.moment, "load": self.load, "root_moment": self.root_moment,
                "time_s": self.time_s}


def _shoot(sc: _Scaled, F, M0, m0, samples=None):
    """Integrate the elastica from the root with root moment ``m0`` (nondimensional).

    State (theta, m, x, z, a, c): ``theta' = m / b``, ``m' = -(F_z cos theta - F_x sin theta)``,
    ``x' = cos``, ``z' = sin``, and the variational pair a = d theta / d m0, c = d m / d m0.
    Returns the tip state and, with ``samples``, the state at those arc lengths."""
    Fx, Fz = F

    def rhs(s, y, s0, s1, b0, b1):
        b = b0 + (b1 - b0) * (s - s0) / (s1 - s0)
        th, m, _, _, a, c = y
        cs, sn = math.cos(th), math.sin(th)
        return [m / b, -(Fz * cs - Fx * sn), cs, sn, c / b, (Fz * sn + Fx * cs) * a]

    y = np.array([0.0, m0, 0.0, 0.0, 0.0, 1.0])
    out = []
    xs, bs = sc.xs, sc.b
    last = xs.size - 2
    for k in range(xs.size - 1):
        s0, s1 = xs[k], xs[k + 1]
        ev = None
        if samples is not None:
            ev = np.append(samples[(samples >= s0) & (samples < s1)], s1)
        sol = solve_ivp(rhs, (s0, s1), y, method="DOP853", rtol=_RTOL, atol=1e-13,
                        args=(s0, s1, bs[k], bs[k + 1]), t_eval=ev)
        if not sol.success:
            raise BadInput(f"load: the elastica could not be integrated ({sol.message})")
        if samples is not None:
            out.append(sol.y if k == last else sol.y[:, :-1])
        y = sol.y[:, -1]
    return y, (np.concatenate(out, axis=1) if samples is not None else None)


def _newton(sc, F, M0, m0):
    """Root moment m0 with m(1) = M0; returns (m0, tip state) or None."""
    for _ in range(40):
        y, _ = _shoot(sc, F, M0, m0)
        r = y[1] - M0
        if y[5] <= 0:
            return None                                  # past a limit/bifurcation point
        dm = r / y[5]
        m0 -= dm
        if abs(dm) < 1e-13 * (1 + abs(m0)):
            y, _ = _shoot(sc, F, M0, m0)
            return m0, y
    return None


def _path(sc, direction, kind, target_load=None, target_angle=None, target_z=None):
    """Continuation in the load along ``direction`` (force unit vector, or the moment) up to the
    nondimensional ``target_load``, or until the tip angle is ``target_angle`` (or the tip's z,
    nondimensional, is ``target_z``).

    Returns (load, m0, tip state)."""
    def loads(lam):
        return (lam * direction, 0.0) if kind == "force" else (np.zeros(2), lam)

    # the tip state's entry that is aimed at: its angle (0) or its z (3)
    index, target = (0, target_angle) if target_z is None else (3, target_z)
    lam, m0, lam_prev, m_prev = 0.0, 0.0, None, None
    y = np.array([0.0, 0.0, 1.0, 0.0, 0.0, 1.0])
    top = target_load if target_load is not None else MAX_LOAD
    step = min(0.5, top)
    while lam < top:
        trial = min(lam + step, top)
        F, M0 = loads(trial)
        # predictor: the secant through the last two solutions (the unloaded slope at first)
        if lam_prev is None:
            guess = trial * (direction[1] * _lever(sc) if kind == "force" else 1.0)
        else:
            guess = m0 + (m0 - m_prev) / (lam - lam_prev) * (trial - lam)
        got = _newton(sc, F, M0, guess)
        # corrector accepted only on the same branch: the tip turns by a small angle per step
        if got is None or abs(got[1][0] - y[0]) > 0.15:
            step /= 4
            if step < 1e-6 * max(1.0, lam):
                raise BadInput(f"load: the equilibrium path has a limit or bifurcation point "
                               f"near P L^2/(E I_max) = {trial:.4g}: loads beyond it are not "
                               f"accepted (no stable equilibrium is continued past it)")
            continue
        m1, y1 = got
        if target is not None and abs(y1[index]) >= abs(target):
            def miss(l, lo=lam, hi=trial, mlo=m0, mhi=m1):
                F_, M_ = loads(l)
                g = _newton(sc, F_, M_, mlo + (mhi - mlo) * (l - lo) / (hi - lo))
                if g is None:
                    raise BadInput(f"{'tip_angle' if index == 0 else 'tip_deflection'}: the "
                                   "load path to it has a limit point")
                return g[1][index] - target
            lstar = brentq(miss, lam, trial, xtol=1e-14, rtol=1e-14)
            F_, M_ = loads(lstar)
            m_, y_ = _newton(sc, F_, M_, m0 + (m1 - m0) * (lstar - lam) / (trial - lam))
            return lstar, m_, y_
        lam_prev, m_prev = lam, m0
        lam, m0, y = trial, m1, y1
        step = min(step * 1.5, 0.5 + 0.25 * lam)
    if target_z is not None:
        raise BadInput(f"tip_deflection: at most {abs(y[3]) * sc.L:.4g} m ({abs(y[3]):.4g} L) "
                       f"is reached with a tip force at this angle up to the largest load "
                       f"accepted, P L^2/(E I_max) = {MAX_LOAD:g}; got "
                       f"{abs(target_z) * sc.L:.4g} m")
    if target_angle is not None:
        raise BadInput(f"tip_angle: at most {abs(y[0]):.4g} rad is reached with a force at "
                       f"this angle up to the largest load accepted, P L^2/(E I_max) = "
                       f"{MAX_LOAD:g}; got {abs(target_angle):.4g}")
    return lam, m0, y


def _force_for(sc, direction, fa: float, value: float, name: str, what: str, noun: str,
               **target):
    """(load, root moment) of the dead tip force at ``force_angle`` ``fa`` that puts the tip
    where ``target`` says (``target_z`` or ``target_angle``, by continuation, :func:`_path`); 0
    for ``value`` 0; BadInput naming ``name`` where no force in that direction can."""
    if value == 0:
        return 0.0, 0.0
    if math.sin(fa) * value <= 0 or abs(math.sin(fa)) < 1e-3:
        raise BadInput(f"{name}: a force at force_angle {fa:.4g} rad cannot {what}; give {noun} "
                       "of the sign of sin(force_angle), with |sin(force_angle)| >= 1e-3")
    lam, m0, _ = _path(sc, direction, "force", **target)
    return lam, m0


def rod_static(beam: Beam, *, force: float | None = None, force_angle: float = math.pi / 2,
               moment: float | None = None, tip_angle: float | None = None,
               tip_deflection: float | None = None, load: str = "force",
               samples: int = 401) -> RodEquilibrium:
    """Large-deflection static equilibrium of ``beam`` under a dead tip load.

    Give exactly one of ``force`` [N] (magnitude >= 0, direction ``force_angle`` [rad] from +x
    towards +z: pi/2, the default, is perpendicular to the unloaded strip), ``moment`` [N m]
    (positive bends towards +z), ``tip_angle`` [rad]: the load of kind ``load`` (``"force"``
    at ``force_angle``, or ``"moment"``) that gives this tip angle, found by continuation in the
    load, or ``tip_deflection`` [m]: the force at ``force_angle`` that puts the tip's z there
    (|D| < L, of the sign of sin(force_angle)), found the same way. ``samples``: points of the
    returned shape (the stations are added).

    Raises BadInput beyond ``MAX_LOAD`` (P L^2 / (E I_max)) or ``MAX_MOMENT_ANGLE``, past a limit
    or bifurcation point of the load path, or for a tip angle or deflection no accepted load
    reaches.
    """
    t0 = time.perf_counter()
    sc = _scaled(beam)
    fa = _number(force_angle, "force_angle", -math.pi, math.pi, " rad")
    direction = np.array([math.cos(fa), math.sin(fa)])
    if sum(v is not None for v in (force, moment, tip_angle, tip_deflection)) != 1:
        raise BadInput("load: give exactly one of force, moment, tip_angle or tip_deflection")
    if tip_deflection is not None and load != "force":
        raise BadInput("tip_deflection: is reached by a tip force (load='force') only")
    if load not in ("force", "moment"):
        raise BadInput(f"load: must be 'force' or 'moment', got {load!r}")
    if isinstance(samples, bool) or not isinstance(samples, (int, np.integer)) \
            or not 2 <= samples <= 100000:
        raise BadInput(f"samples: must be an integer in [2, 100000], got {samples!r}")
    rest = np.array([0.0, 0.0, 1.0, 0.0, 0.0, 1.0])
    kind = "force" if force is not None else "moment" if moment is not None else load
    if kind == "moment":
        if tip_angle is not None:
            ta = _number(tip_angle, "tip_angle", -MAX_MOMENT_ANGLE, MAX_MOMENT_ANGLE, " rad")
            lam = ta / _compliance(sc)
        else:
            lam = _number(moment, "moment", what=" N m") / sc.moment
            if abs(lam * _compliance(sc)) > MAX_MOMENT_ANGLE:
                raise BadInput(f"moment: gives a tip angle of {lam * _compliance(sc):.4g} rad; "
                               f"at most {MAX_MOMENT_ANGLE:.4g} rad is accepted")
        m0 = lam
    elif force is not None:
        P = _number(force, "force", 0.0, MAX_LOAD * sc.force,
                    f" N (P L^2/(E I_max) <= {MAX_LOAD:g})")
        lam, m0, _ = _path(sc, direction, "force", target_load=P / sc.force) if P > 0 \
            else (0.0, 0.0, rest)
    elif tip_deflection is not None:
        dz = _number(tip_deflection, "tip_deflection", -sc.L, sc.L, " m (|D| <= L)") / sc.L
        lam, m0 = _force_for(sc, direction, fa, dz, "tip_deflection",
                             f"move the tip to z = {dz * sc.L:.4g} m", "a deflection",
                             target_z=dz)
    else:
        ta = _number(tip_angle, "tip_angle", -math.pi / 2, math.pi, " rad")
        lam, m0 = _force_for(sc, direction, fa, ta, "tip_angle",
                             f"bend the tip to {ta:.4g} rad", "a tip angle", target_angle=ta)
    F = lam * direction if kind == "force" else np.zeros(2)
    M0 = 0.0 if kind == "force" else lam
    s = np.unique(np.concatenate([np.linspace(0.0, 1.0, int(samples)), sc.xs]))
    s = s[np.concatenate([[True], np.diff(s) > 1e-12])]       # no near-duplicates
    s[-1] = 1.0
    tipy, Y = _shoot(sc, F, M0, m0, samples=s)
    return RodEquilibrium(s=s * sc.L, theta=Y[0], x=Y[2] * sc.L, z=Y[3] * sc.L,
                          tip_x=float(tipy[2] * sc.L), tip_z=float(tipy[3] * sc.L),
                          tip_angle=float(tipy[0]),
                          force=(float(F[0] * sc.force), float(F[1] * sc.force)),
                          moment=float(M0 * sc.moment), load=float(abs(lam)),
                          stability=float(tipy[5]), time_s=time.perf_counter() - t0,
                          root_moment=float(m0 * sc.moment))


def _lever(sc: _Scaled) -> float:
    """d m(0) / d F_z of the unloaded strip: the lever arm L (nondimensional 1)."""
    return 1.0


def _compliance(sc: _Scaled) -> float:
    """int_0^1 ds / b(s) (piecewise-linear b, exactly): the tip angle per unit tip moment."""
    total = 0.0
    for s0, s1, b0, b1 in zip(sc.xs[:-1], sc.xs[1:], sc.b[:-1], sc.b[1:]):
        total += (s1 - s0) * (math.log(b1 / b0) / (b1 - b0) if abs(b1 - b0) > 1e-12 * b0
                              else 1.0 / b0)
    return total


# ---------------------------------------------------------------------------- stress-free shapes
@dataclass(frozen=True)
class RestShape:
    """A stress-free (curved) rest shape: ``theta(s)`` [rad] of the arc length ``s`` [m], with
    ``theta(0) = 0`` (the clamp holds the root along x); ``breaks`` [m]: where it has a kink or
    a jump (they become element edges, keeping the discretisation's accuracy)."""

    theta: Callable[[np.ndarray], np.ndarray]
    breaks: tuple = ()
    name: str = ""


def arc_shape(beam: Beam, tip_angle: float) -> RestShape:
    """A circular arc, ``theta(s) = tip_angle s / L`` (the shape of the chain's uniform pose in
    the limit of many joints)."""
    ta = _number(tip_angle, "tip_angle", -MAX_MOMENT_ANGLE, MAX_MOMENT_ANGLE, " rad")
    L = beam.length
    return RestShape(theta=lambda s: ta * np.asarray(s, float) / L, name=f"arc {ta:g} rad")


def chain_shape(beam: Beam, gamma, angles) -> RestShape:
    """The shape of a chain pose: links of lengths ``gamma * L`` (link 0 along x), relative joint
    angles ``angles`` [rad] (one per joint, or one number for all): ``theta`` piecewise constant,
    the absolute link angles, with jumps at the joints."""
    g = np.asarray(gamma, float)
    if g.ndim != 1 or g.size < 2 or not np.all(np.isfinite(g)) or np.any(g <= 0) \
            or abs(g.sum() - 1.0) > 1e-9:
        raise BadInput("gamma: must be a list of at least 2 link fractions > 0 summing to 1")
    a = np.broadcast_to(np.asarray(angles, float), (g.size - 1,)).copy() \
        if np.ndim(angles) == 0 else np.asarray(angles, float)
    if a.shape != (g.size - 1,) or not np.all(np.isfinite(a)):
        raise BadInput(f"angles: must be one number or {g.size - 1} numbers (one per joint)")
    L = beam.length
    joints = L * np.cumsum(g)[:-1]
    absolute = np.concatenate([[0.0], np.cumsum(a)])

    def theta(s):
        return absolute[np.searchsorted(joints, np.asarray(s, float), side="right")]
    return RestShape(theta=theta, breaks=tuple(joints), name="chain pose")


def sampled_shape(s, theta, breaks=()) -> RestShape:
    """A rest shape given by samples ``theta`` [rad] at arc lengths ``s`` [m] (linear between)."""
    s = np.asarray(s, float)
    th = np.asarray(theta, float)
    if s.ndim != 1 or s.shape != th.shape or s.size < 2 or np.any(np.diff(s) <= 0) \
            or not np.all(np.isfinite(th)):
        raise BadInput("theta: must be finite samples at strictly increasing arc lengths s")
    return RestShape(theta=lambda x: np.interp(x, s, th), breaks=tuple(breaks), name="sampled")


# ---------------------------------------------------------------------------- frequencies
#: the most modes :func:`rod_frequencies` gives
MAX_MODES = 20


@dataclass
class RodFrequencies:
    """Small-vibration frequencies of the rod about a configuration: ``omega`` [rad/s] ascending,
    ``freq_hz``, ``lam`` (nondimensional ``(omega T)^2``, ``T = sqrt(rho A_max L^4 / E I_max)``),
    ``about`` ("straight", "equilibrium" or "stress-free"), ``tip_angle`` [rad] of that
    configuration, ``mesh`` (elements, degree, unknowns), ``time_s``."""

    omega: np.ndarray
    freq_hz: np.ndarray
    lam: np.ndarray
    about: str
    tip_angle: float
    mesh: dict
    time_s: float
    model: str = "rod"

    def to_dict(self) -> dict:
        return {"model": self.model, "omega": [float(v) for v in self.omega],
                "freq_hz": [float(v) for v in self.freq_hz], "about": self.about,
                "tip_angle": self.tip_angle, "mesh": dict(self.mesh), "time_s": self.time_s}


def _model(sc: _Scaled, about, rotary, elements, degree) -> RodGalerkin:
    rot = sc.rotary if rotary else 0.0
    if isinstance(about, RestShape):
        L = sc.L
        th0 = float(np.asarray(about.theta(np.array([0.0])), float).ravel()[0])
        if abs(th0) > 1e-12:
            raise BadInput(f"about: a rest shape must leave the clamp along x (theta(0) = 0), "
                           f"got theta(0) = {th0:.4g} rad")
        br = np.asarray(about.breaks, float) / L
        return RodGalerkin(sc.xs, sc.b, elements=elements, degree=degree, rotary=rot,
                           theta_rest=lambda s: np.asarray(about.theta(s * L), float),
                           breaks=br[(br > 0) & (br < 1)])
    return RodGalerkin(sc.xs, sc.b, elements=elements, degree=degree, rotary=rot)


def _discrete_equilibrium(sc: _Scaled, model: RodGalerkin, eq: RodEquilibrium):
    """The discretised rod's equilibrium under ``eq``'s load, from ``eq``'s shape; returns
    (q, K_T, F, M0) nondimensional."""
    F = np.asarray(eq.force, float) / sc.force
    M0 = eq.moment / sc.moment
    q0 = np.interp(model.node_s, eq.s / sc.L, eq.theta)
    q, KT, ok = model.static(F, M0, q0)
    if not ok:       # continuation in the discretised model from the straight rod
        q = np.zeros(model.n)
        for f in np.linspace(0.0, 1.0, 41)[1:]:
            q, KT, ok = model.static(F * f, M0 * f, q)
        if not ok:
            raise BadInput("about: the discretised rod found no equilibrium under this load; "
                           "raise elements")
    return q, KT, F, M0


def _eig(M, K, modes):
    """Lowest ``modes`` eigenvalues of K v = lam M v, solved as M v = (1/lam) K v (K is well
    conditioned, M is not): accurate to ~1e-12 relative on the low modes."""
    mu = eigh(M, K, eigvals_only=True, subset_by_index=[M.shape[0] - modes, M.shape[0] - 1])
    return np.sort(1.0 / mu[::-1])


def rod_frequencies(beam: Beam, about=None, modes: int = 4, *, rotary: bool = False,
                    elements: int = ELEMENTS, degree: int = DEGREE) -> RodFrequencies:
    """Small-vibration bending frequencies of the rod about a configuration.

    about: ``None`` (the straight, stress-free rod), a :class:`RodEquilibrium` from
    :func:`rod_static` (held by its load: the load's geometric stiffness is included), or a
    :class:`RestShape` (a stress-free curved rod: :func:`arc_shape`, :func:`chain_shape`,
    :func:`sampled_shape`). modes: 1 .. ``MAX_MODES``. rotary: add the section's rotary
    inertia. elements, degree: the discretisation (defaults converge the first 6 modes to
    ~1e-9).
    """
    t0 = time.perf_counter()
    sc = _scaled(beam)
    if isinstance(modes, bool) or not isinstance(modes, (int, np.integer)) \
            or not 1 <= modes <= MAX_MODES:
        raise BadInput(f"modes: must be an integer in [1, {MAX_MODES}], got {modes!r}")
    elements, degree = _discretisation(elements, degree)
    if about is not None and not isinstance(about, (RodEquilibrium, RestShape)):
        raise BadInput("about: must be None (straight), a RodEquilibrium (rod_static) or a "
                       f"RestShape (arc_shape, chain_shape, sampled_shape), got "
                       f"{type(about).__name__}")
    model = _model(sc, about, rotary, elements, degree)
    if modes > model.n // 3:
        raise BadInput(f"modes: at most {model.n // 3} with {model.n} unknowns; raise elements")
    if isinstance(about, RodEquilibrium):
        q, K, _, _ = _discrete_equilibrium(sc, model, about)
        kind, tip = "equilibrium", float(q[-1])
    else:
        q, K = np.zeros(model.n), model.K
        kind = "straight" if about is None else "stress-free"
        tip = float(about.theta(np.array([sc.L]))[0]) if about is not None else 0.0
    M = model.mass(q)
    if np.linalg.eigvalsh(K)[0] <= 0:
        raise BadInput("about: this equilibrium is unstable (its tangent stiffness is not "
                       "positive definite): no small-vibration frequencies")
    lam = _eig(M, K, modes)
    omega = np.sqrt(lam) / sc.time
    return RodFrequencies(omega=omega, freq_hz=omega / (2 * math.pi), lam=lam, about=kind,
                          tip_angle=tip, mesh={"elements": int(model.E), "degree": degree,
                                               "unknowns": int(model.n), "rotary": bool(rotary)},
                          time_s=time.perf_counter() - t0)


# ---------------------------------------------------------------------------- nonlinear response
@dataclass
class RodResponse:
    """Free vibration of the rod released from rest in a static deflection (SI).

    ``t`` [s], ``tip_x``, ``tip_z`` [m], ``tip_angle`` [rad] sampled; ``period`` [s]: the mean of
    the measured periods ``periods`` (times between successive downward crossings of the tip
    through z = 0), ``period_error`` its estimated relative error (midpoint: a third of the
    change between the two step sizes); ``linear_period`` [s]: 2 pi / omega_1 of the straight rod (small amplitude);
    ``energy_drift``: the largest |E(t) - E(0)| / E(0) over the samples; ``equilibrium``: the
    released shape (:func:`rod_static`); ``mesh``: the discretisation, the steps per linear
    period and ``halved_steps`` (``halved_steps_check``: of the run at half the steps), the steps
    whose midpoint iteration did not converge and were taken as two halves
    (:data:`MAX_HALVINGS`); ``nfev`` right-hand-side evaluations; ``time_s``."""

    t: np.ndarray
    tip_x: np.ndarray
    tip_z: np.ndarray
    tip_angle: np.ndarray
    period: float
    periods: np.ndarray
    period_error: float
    linear_period: float
    energy_drift: float
    equilibrium: RodEquilibrium
    mesh: dict
    nfev: int
    time_s: float

    def to_dict(self) -> dict:
        return {"model": "rod", "period": self.period,
                "periods": [float(v) for v in self.periods], "period_error": self.period_error,
                "linear_period": self.linear_period, "energy_drift": self.energy_drift,
                "release_tip_angle": self.equilibrium.tip_angle, "mesh": dict(self.mesh),
                "nfev": self.nfev, "time_s": self.time_s}


#: how many times a step whose midpoint iteration does not converge is halved (in two steps
#: of half the length, recursively) before the release gives up
MAX_HALVINGS = 4


def _advance(model: RodGalerkin, q, v, h, depth: int = 0) -> list:
    """One implicit-midpoint step of ``h``, or, where its iteration does not converge (a large
    release of a strip whose width changes many times over: its stiffest modes, hardly
    resolved, move fast), two of ``h / 2``, recursively; counted in ``model.halvings``.
    Returns the steps taken, ``[(dt, q1, v1), ...]``."""
    try:
        return [(h, *model.midpoint_step(q, v, h))]
    except ArithmeticError:
        if depth >= MAX_HALVINGS:
            raise
        model.halvings += 1
        first = _advance(model, q, v, 0.5 * h, depth + 1)
        return first + _advance(model, first[-1][1], first[-1][2], 0.5 * h, depth + 1)


def _march(model: RodGalerkin, q, v, h, periods, sign, max_steps):
    """Implicit-midpoint steps of ``h`` (halved where needed, :func:`_advance`) until
    ``periods + 1`` downward crossings of the tip through z = 0 (located on the cubic Hermite
    interpolant of z and zdot over the step taken). Returns the times, states, crossings and
    the number of halvings."""
    model.halvings = 0
    t, ts, Qs, Vs, crossings = 0.0, [0.0], [q], [v], []
    z = model.positions(q)[1][1]
    zd = (model.tip_velocity(q, v))[1]
    for _ in range(max_steps):
        for dt, q1, v1 in _advance(model, q, v, h):
            z1 = model.positions(q1)[1][1]
            zd1 = model.tip_velocity(q1, v1)[1]
            if sign * z > 0 >= sign * z1:
                def herm(x, z=z, z1=z1, zd=zd, zd1=zd1, dt=dt):
                    return ((2 * x ** 3 - 3 * x ** 2 + 1) * z + (x ** 3 - 2 * x ** 2 + x) * dt * zd
                            + (-2 * x ** 3 + 3 * x ** 2) * z1 + (x ** 3 - x ** 2) * dt * zd1)
                x = brentq(herm, 0.0, 1.0, xtol=1e-15) if z1 != 0 else 1.0
                crossings.append(t + x * dt)
            t += dt
            q, v, z, zd = q1, v1, z1, zd1
            ts.append(t)
            Qs.append(q)
            Vs.append(v)
        if len(crossings) >= periods + 1:
            return (np.array(ts), np.array(Qs), np.array(Vs), np.array(crossings[:periods + 1]),
                    model.halvings)
    raise BadInput(f"periods: only {max(len(crossings) - 1, 0)} periods were measured in "
                   f"{max_steps} steps")


def rod_response(beam: Beam, tip_angle: float, *, force_angle: float = math.pi / 2,
                 periods: int = 3, steps: int = 1024, check: bool = True,
                 rotary: bool = False, elements: int = 6, degree: int = 4,
                 method: str = "midpoint", rtol: float = 1e-10) -> RodResponse:
    """Nonlinear free vibration of ``beam`` released from rest in the static deflection that a
    tip force at ``force_angle`` [rad] holds at ``tip_angle`` [rad] (:func:`rod_static`).

    Lagrange's equations of the discretised rod (exact mass matrix and centripetal/Coriolis
    terms, :mod:`prbdm.truth._rod_dynamics`; ``elements`` x ``degree`` angle unknowns) are
    integrated until ``periods`` full periods have been measured.

    method ``"midpoint"`` (default): the implicit midpoint rule (second order, symmetric,
    A-stable, no numerical damping), ``steps`` steps per linear period; with ``check`` it runs
    again at ``steps / 2`` and ``period_error`` is the change of the period between the two
    (an upper estimate of the error of the finer run; the crossing times converge at the rate
    the excited higher modes are resolved, see docs/large-deflection.md). ``"DOP853"`` /
    ``"Radau"``: scipy's ``solve_ivp`` at ``rtol``, which resolves every mode of the
    discretisation (slow beyond ~10 unknowns: a cross-check for small discretisations).
    """
    t0 = time.perf_counter()
    sc = _scaled(beam)
    periods = _integer(periods, "periods", 1, 50)
    steps = _integer(steps, "steps", 16, 100000)
    rtol = _number(rtol, "rtol", 1e-13, 1e-4)
    if method not in ("midpoint", "DOP853", "Radau"):
        raise BadInput(f"method: must be one of midpoint, DOP853, Radau, got {method!r}")
    elements, degree = _discretisation(elements, degree)
    ta = _number(tip_angle, "tip_angle", -math.pi / 2, math.pi, " rad")
    if ta == 0:
        raise BadInput("tip_angle: must be nonzero (the straight rod at rest does not move)")
    eq = rod_static(beam, tip_angle=ta, force_angle=force_angle)
    model = _model(sc, None, rotary, elements, degree)
    q, _, _, _ = _discrete_equilibrium(sc, model, eq)
    n = model.n
    lam1 = _eig(model.mass(np.zeros(n)), model.K, 1)[0]
    T1 = 2 * math.pi / math.sqrt(lam1)                  # nondimensional linear period
    v0 = np.zeros(n)
    z0 = model.positions(q)[1][1]
    sign = 1.0 if z0 > 0 else -1.0
    nfev, halved, halved_check = 0, 0, 0
    if method == "midpoint":
        max_steps = 4 * steps * (periods + 1)           # periods may grow up to 4x
        try:
            ts, Q, V, tc, halved = _march(model, q, v0, T1 / steps, periods, sign, max_steps)
            per = np.diff(tc)
            err = float("nan")
            if check:
                _, _, _, c2, halved_check = _march(model, q, v0, 2 * T1 / steps, periods, sign,
                                                   max_steps)
                err = float(np.max(np.abs(np.diff(c2) - per)) / per.mean())
        except ArithmeticError as exc:
            raise BadInput(f"steps: {exc}") from None
    else:
        def crossing(t, y):
            return sign * model.positions(y[:n])[1][1]
        crossing.direction = -1
        crossing.terminal = periods + 1
        sol = solve_ivp(model.rhs, (0.0, T1 * (periods + 1) * 4.0), np.concatenate([q, v0]),
                        method=method, rtol=rtol, atol=rtol * 1e-2, events=crossing,
                        dense_output=True)
        tc = sol.t_events[0]
        if not sol.success or tc.size < periods + 1:
            raise BadInput(f"method: {method} measured {max(tc.size - 1, 0)} of {periods} "
                           f"periods ({sol.message})")
        ts = np.linspace(0.0, tc[-1], int(512 * tc[-1] / T1) + 1)
        Y = sol.sol(ts)
        Q, V = Y[:n].T, Y[n:].T
        per, err, nfev = np.diff(tc), float("nan"), int(sol.nfev)
    tips = np.array([model.positions(qq)[1] for qq in Q])
    E = np.array([model.energy(qq, vv) for qq, vv in zip(Q, V)])
    drift = float(np.max(np.abs(E - E[0])) / E[0])
    per = per * sc.time
    return RodResponse(t=ts * sc.time, tip_x=tips[:, 0] * sc.L, tip_z=tips[:, 1] * sc.L,
                       tip_angle=Q[:, -1].copy(), period=float(per.mean()), periods=per,
                       period_error=err, linear_period=T1 * sc.time, energy_drift=drift,
                       equilibrium=eq, mesh={"elements": int(model.E), "degree": degree,
                                             "unknowns": n, "rotary": bool(rotary),
                                             "method": method, "steps": steps,
                                             "halved_steps": halved,
                                             "halved_steps_check": halved_check,
                                             "rtol": rtol},
                       nfev=nfev, time_s=time.perf_counter() - t0)
