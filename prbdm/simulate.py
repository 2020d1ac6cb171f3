"""Time response of a PRBDM, against the Euler-Bernoulli beam's modal superposition (issue 8).

The PRBDM (:class:`ChainDynamics`). The full nonlinear equations of the planar chain,

    M(theta) theta'' + C(theta, theta') theta' + D theta' + K (theta - theta_ref) = tau,

are integrated with ``scipy.integrate.solve_ivp`` (DOP853, rtol 1e-9). They are written in the
absolute link angles ``q_j = theta_1 + ... + theta_j``, where a planar chain's kinetic energy is
``T = 1/2 sum_ab A_ab cos(q_a - q_b) q'_a q'_b`` with a *constant* matrix
``A_ab = sum_j m_j L_ja L_jb + delta_ab J_a`` (``L_ja`` = length of link a for a < j, centre
offset c_j for a = j, 0 beyond). Lagrange's equations are then exactly

    sum_b A_ab cos(q_a - q_b) q''_b + sum_b A_ab sin(q_a - q_b) q'_b^2 = Q_a,

the second sum being the Coriolis/centrifugal term (the Christoffel symbols of ``M`` in closed
form), and the joint torques map as ``Q_a = tau_a - tau_{a+1}``. ``M(theta) = T^T (A o cos) T``
equals :func:`prbdm.model.mass_matrix` and the Coriolis term equals the one from autograd of the
kinetic energy (both checked in tests/test_simulate.py); in closed form a right-hand side costs
microseconds instead of a torch call.

Damping: a first-mode damping ratio ``zeta`` becomes stiffness-proportional damping
``D = (2 zeta / omega_1) K`` (diagonal: per-joint viscous), the same in the truth
(``zeta_r = zeta omega_r / omega_1``), so both have ratio zeta on their first mode.

The truth (:func:`beam_modes`): the Euler-Bernoulli cantilever of docs/conventions.md §2 (``b = 2 w``,
``I = b t^3/12``, ``A = b t``), solved by :mod:`prbdm.truth`'s beam model (the same solve as
``prbdm truth`` and ``prbdm fit``), its mode shapes scaled to unit modal mass in SI. The tip
motion is the modal superposition ``w(L, t) = sum_r phi_r(L) eta_r(t)`` of its lowest R modes
(default 20).

Initial conditions, the same for both: ``tip_deflection D`` releases the beam from rest in its
static deflection under a tip force, scaled so the tip's z is D (PRBDM: the chain's linear static
shape ``theta_k proportional to (L - x_k) / K_k``, scaled with the exact kinematics; truth:
``eta_r(0) = F phi_r(L) / omega_r^2``); ``tip_impulse P`` [N s] strikes the straight beam at the
tip (PRBDM: ``theta'(0) = M(0)^-1 J^T P``; truth: ``eta'_r(0) = P phi_r(L)``).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from .chain import (
    TipLoadStatics,
    absolute_inertia,
    joint_accelerations,
    joint_coriolis,
    joint_mass_matrix,
    tip_position,
)
from .errors import BadInput
from .preflight import DEFAULT_TOLERANCE
from .signals import (
    CROSSING_FLOOR,
    damped_frequency,
    decaying_window,
    dominant_frequency,
    zero_crossing_period,
)

__all__ = ["ChainDynamics", "beam_modes", "BeamModes", "modal_tip_response", "simulate",
           "SimulationResult", "dominant_frequency", "zero_crossing_period", "plot_simulation"]

#: the truth is linear: beyond this tip deflection (fraction of L) the comparison gets a warning
SMALL_DEFLECTION = 0.01
MAX_PERIODS = 500
#: the shortest run whose periods can be measured (two upward zero crossings of the tip, with room
#: for a released or struck start): a shorter one has no period to compare
MIN_PERIODS = 3
#: most samples of the grid on which the periods are measured
MAX_MEASURE_SAMPLES = 400_000
#: the measured periods are reported only when the truth's measured period is this close to its
#: exact damped period (its own check of the measurement): else they are null, with a warning
PERIOD_MEASURE_TOLERANCE = 1e-3
#: a zero-crossing period is reported only within this of its model's measured period
CROSSING_TOLERANCE = 0.01


# ----------------------------------------------------------------------------- the PRBDM
@dataclass
class ChainDynamics:
    """Planar chain of links 1..n (link 0 clamped), SI units, relative joint angles theta.

    length (n,) link lengths [m] (link j from joint j to joint j+1, the tip for j = n);
    com (n,) centre of mass from joint j [m]; mass (n,) [kg]; inertia (n,) about the centre
    [kg m^2]; stiffness, damping (n,) per joint [N m/rad, N m s/rad]; springref (n,) rest angles;
    springs: the joint spring law (:mod:`prbdm.springs`; default the constant ``stiffness`` about
    ``springref``). Its physics is :mod:`prbdm.chain`'s (``A``: :func:`prbdm.chain.absolute_inertia`).
    """

    length: np.ndarray
    com: np.ndarray
    mass: np.ndarray
    inertia: np.ndarray
    stiffness: np.ndarray
    damping: np.ndarray
    springref: np.ndarray
    springs: object = None
    A: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        from .springs import LinearSprings

        for name in ("length", "com", "mass", "inertia", "stiffness", "damping", "springref"):
            setattr(self, name, np.asarray(getattr(self, name), dtype=float))
        if self.springs is None:
            self.springs = LinearSprings(self.stiffness, self.springref)
        self.A = absolute_inertia(self.length, self.com, self.mass, self.inertia)

    @property
    def n(self) -> int:
        return self.length.size

    @classmethod
    def from_description(cls, desc: dict, springs=None) -> "ChainDynamics":
        """From :func:`prbdm.export.prbdm_from_fit`'s description; ``springs`` replaces its
        constant hinge stiffness by another law (:func:`prbdm.springs.fitted_springs`)."""
        bodies, hinges = desc["bodies"][1:], desc["hinges"]
        return cls(length=[b["length"] for b in bodies], com=[b["com"][0] for b in bodies],
                   mass=[b["mass"] for b in bodies], inertia=[b["inertia"][1] for b in bodies],
                   stiffness=[h["stiffness"] for h in hinges],
                   damping=[h["damping"] for h in hinges],
                   springref=[h["springref"] for h in hinges], springs=springs)

    def mass_matrix(self, theta) -> np.ndarray:
        """M(theta) [kg m^2], relative angles."""
        return joint_mass_matrix(self.A, theta)

    def coriolis(self, theta, theta_dot) -> np.ndarray:
        """C(theta, theta') theta' [N m] in joint coordinates."""
        return joint_coriolis(self.A, theta, theta_dot)

    def rhs(self, t, y, tau=None):
        """d/dt [theta, theta'] for solve_ivp; tau(t) -> (n,) joint torques, optional."""
        n = self.n
        theta, thd = y[:n], y[n:]
        Q = -self.springs.torque(theta) - self.damping * thd
        if tau is not None:
            Q = Q + tau(t)
        return np.concatenate([thd, joint_accelerations(self.A, theta, thd, Q)])

    def tip(self, theta):
        """Tip position (x relative to joint 1, z) [m] for theta (..., n)."""
        return tip_position(self.length, theta)

    def energy(self, theta, theta_dot) -> float:
        """Kinetic + spring energy [J]."""
        M = self.mass_matrix(theta)
        return float(0.5 * theta_dot @ M @ theta_dot) + self.springs.energy(np.asarray(theta))

    def linear_frequencies(self, theta=None) -> np.ndarray:
        """omega [rad/s] of K v = lambda M(theta) v (default about the spring reference)."""
        from scipy.linalg import eigh

        theta = self.springref if theta is None else theta
        return np.sqrt(eigh(np.diag(self.stiffness), self.mass_matrix(theta), eigvals_only=True))

    def lever(self) -> np.ndarray:
        """d z_tip / d theta_k at theta = 0: distance from joint k to the tip [m]."""
        return np.cumsum(self.length[::-1])[::-1]

    def static_tip_shape(self, deflection: float) -> np.ndarray:
        """theta of the linear static shape under a tip force, scaled so that the tip's z
        (exact kinematics) is ``deflection``."""
        from scipy.optimize import brentq

        shape = self.lever() / self.stiffness
        shape = shape / (self.lever() @ shape)     # unit tip deflection to first order
        if deflection == 0:
            return np.zeros(self.n)
        # up to a total rotation of pi/2 the tip's z grows monotonically along the shape
        s_hi = math.copysign(0.5 * math.pi / np.abs(shape).sum(), deflection)
        z_hi = self.tip(s_hi * shape)[1]
        if abs(deflection) >= abs(z_hi):
            raise BadInput(f"--tip-deflection: {deflection:g} m is more than this chain reaches "
                           f"in its static shape ({abs(z_hi):.4g} m)")
        s = brentq(lambda s: self.tip(s * shape)[1] - deflection, 0.0, s_hi,
                   xtol=1e-16 * abs(s_hi), rtol=1e-15)
        return s * shape

    def statics(self, x1: float = 0.0) -> TipLoadStatics:
        """Its equilibria under a dead tip force (:class:`prbdm.chain.TipLoadStatics`; joint 1
        at ``(x1, 0)``), with its spring law."""
        return TipLoadStatics(self.length, self.springs, x1, "the PRBDM")

    def impulse_velocity(self, impulse: float) -> np.ndarray:
        """theta'(0) after a tip impulse P [N s] (along z) on the straight chain at rest."""
        return np.linalg.solve(self.mass_matrix(np.zeros(self.n)), self.lever() * impulse)


# ----------------------------------------------------------------------------- the truth
@dataclass
class BeamModes:
    """Euler-Bernoulli cantilever modes in SI: ``omega`` (R,) [rad/s]; ``tip`` (R,) tip values of
    the mass-normalised modes [1/sqrt(kg)]; ``static_compliance`` tip deflection per tip force of
    the whole discrete model [m/N]; ``elements``."""

    omega: np.ndarray
    tip: np.ndarray
    static_compliance: float
    elements: int


def beam_modes(beam, modes: int = 10, elements: int | None = None) -> BeamModes:
    """The truth's Euler-Bernoulli model of ``beam`` (:mod:`prbdm.truth.beam`, docs/conventions.md §2) as SI
    modes for a modal superposition: the same solve as ``prbdm truth --model beam`` (``elements``
    is its base mesh, default ``max(120, 12 modes)``), its mode shapes' tip values scaled to unit
    modal mass.

    The truth returns nondimensional shapes ``w(xi)`` (largest value 1) with their modal mass
    ``m = int beta w^2 dxi`` (``beta = b / b_max``); the SI modal mass is ``rho t b_max L m``, so the
    mass-normalised tip value is ``w(1) / sqrt(rho t b_max L m)``. The static tip compliance is
    the exact unit-load integral ``int (L - x)^2 / EI dx``.
    """
    from scipy.integrate import quad

    from .truth import bending_frequencies

    # finer than the truth's default base mesh (8 elements per mode): the superposition uses its
    # highest modes too, and the period comparison resolves 1e-6 of the first
    res = bending_frequencies(beam, model="beam", modes=int(modes),
                              elements=elements or max(120, 12 * int(modes)))
    shapes = res.shapes
    L = beam.length
    xs, ws = np.asarray(beam.x, float), np.asarray(beam.half_width, float)
    E, rho, t = beam.material.E, beam.material.rho, beam.thickness
    mass_si = rho * t * 2 * ws.max() * L * np.asarray(shapes["modal_mass"], float)
    tip = np.asarray(shapes["w"], float)[:, -1] / np.sqrt(mass_si)     # unit modal mass
    compliance = 0.0
    for a, b in zip(xs[:-1], xs[1:]):
        compliance += quad(lambda x: (L - x) ** 2 * 12 / (E * 2 * np.interp(x, xs, ws) * t ** 3),
                           a, b, epsabs=0, epsrel=1e-13, limit=200)[0]
    return BeamModes(omega=np.asarray(res.omega, float), tip=tip,
                     static_compliance=float(compliance), elements=int(res.mesh["elements"]))


def _sdof(t, omega, zeta, x0, v0):
    """Free response of x'' + 2 zeta omega x' + omega^2 x = 0 (any zeta >= 0)."""
    zeta = np.where(np.abs(zeta - 1.0) < 1e-9, 1.0 + 1e-9, zeta)
    root = np.sqrt((zeta ** 2 - 1.0).astype(complex))
    s1, s2 = omega * (-zeta + root), omega * (-zeta - root)
    c1 = (v0 - s2 * x0) / (s1 - s2)
    c2 = (s1 * x0 - v0) / (s1 - s2)
    return np.real(c1 * np.exp(np.multiply.outer(t, s1)) + c2 * np.exp(np.multiply.outer(t, s2)))


def modal_tip_response(modes: BeamModes, t, *, tip_deflection=None, tip_impulse=None,
                       damping: float = 0.0) -> np.ndarray:
    """Tip deflection w(L, t) [m] of the truth's modal superposition."""
    w, phi = modes.omega, modes.tip
    zeta = damping * w / w[0]
    if tip_impulse is not None:
        x0, v0 = np.zeros_like(w), tip_impulse * phi
    else:
        F = tip_deflection / modes.static_compliance   # the exact static shape of the model
        x0, v0 = F * phi / w ** 2, np.zeros_like(w)
    return _sdof(np.asarray(t, float), w, zeta, x0, v0) @ phi


# ----------------------------------------------------------------------------- simulate
@dataclass
class SimulationResult:
    """Tip motion of the PRBDM and of the truth, and the first-mode periods of both."""

    t: np.ndarray
    tip_prbdm: np.ndarray
    tip_truth: np.ndarray
    theta: np.ndarray
    info: dict

    def to_dict(self, series: bool = True) -> dict:
        d = dict(self.info)
        if series:
            d["t"] = self.t.tolist()
            d["tip_prbdm"] = self.tip_prbdm.tolist()
            d["tip_truth"] = self.tip_truth.tolist()
        return d


def check_damping(damping) -> None:
    """BadInput naming ``--damping`` unless ``0 <= damping < 1``: the comparison measures the
    first-mode period, and an overdamped (or critically damped) first mode does not oscillate."""
    if isinstance(damping, bool) or not isinstance(damping, (int, float, np.floating, np.integer)) \
            or not 0.0 <= damping < 1.0:
        shown = float(damping) if isinstance(damping, (np.floating, np.integer)) else damping
        raise BadInput(f"--damping: the first-mode damping ratio must lie in [0, 1) (underdamped: "
                       f"a simulation compares oscillation periods), got {shown!r}")


def check_duration(duration: float, T1: float, damping: float) -> None:
    """BadInput naming ``--duration`` unless it spans MIN_PERIODS damped to MAX_PERIODS
    first-mode periods of the truth (``T1`` [s] undamped; the tip crosses zero once per damped
    period, so fewer than MIN_PERIODS of those leave no period to measure)."""
    if not math.isfinite(duration) or duration <= 0:
        raise BadInput(f"--duration: must be > 0 s, got {duration!r}")
    Td = T1 / math.sqrt(1 - damping ** 2)          # check_damping: damping < 1
    if MIN_PERIODS * Td > MAX_PERIODS * T1:
        raise BadInput(f"--damping: {MIN_PERIODS} damped first-mode periods must fit in "
                       f"{MAX_PERIODS} undamped ones (damping ratio below "
                       f"{math.sqrt(1 - (MIN_PERIODS / MAX_PERIODS) ** 2):.6g}), got {damping:g}")
    # (a duration of 3 periods computed from another solve of the same truth may fall short by
    # round-off)
    if not MIN_PERIODS * Td * (1 - 1e-3) <= duration <= MAX_PERIODS * T1:
        raise BadInput(f"--duration: at least {MIN_PERIODS} damped and at most {MAX_PERIODS} "
                       f"first-mode periods ({MIN_PERIODS * Td:.4g} to {MAX_PERIODS * T1:.4g} s), "
                       f"got {duration:g} s")


def default_duration(T1: float, damping: float, periods: float = 20.0) -> float:
    """The simulated time [s] when none is given: ``periods`` first-mode periods of the truth
    (``T1`` [s], undamped), and at least MIN_PERIODS + 1 damped ones (a heavily damped run),
    within the MAX_PERIODS undamped ones :func:`check_duration` allows."""
    return min(max(periods * T1, (MIN_PERIODS + 1) * T1 / math.sqrt(1 - damping ** 2)),
               MAX_PERIODS * T1)


def truth_and_duration(beam, truth_modes: int, duration: float | None, damping: float,
                       periods: float = 20.0, modes: "BeamModes | None" = None):
    """(modes, T1, duration): the truth's :func:`beam_modes` (``modes`` when given), its first
    undamped period ``T1`` [s], and the run's ``duration`` [s] (:func:`default_duration` when
    None), checked (:func:`check_duration`). Cheap next to a fit: the command line calls it
    before fitting, so that a bad duration is refused first."""
    if modes is None:
        modes = beam_modes(beam, truth_modes)
    T1 = 2 * math.pi / modes.omega[0]
    if duration is None:
        duration = default_duration(T1, damping, periods)
    check_duration(duration, T1, damping)
    return modes, T1, duration


#: the truths whose physics the simulation's reference (the Euler-Bernoulli modal
#: superposition) is: a result fitted to another is judged by the truth it was fitted to or not
#: at all
SIMULATED_TRUTHS = ("beam", "analytic")


def check_simulated_truth(fit: dict) -> None:
    """BadInput for a result made for another truth than the simulated one: its PRBDM would be
    judged against physics it was not fitted to (a plate fit against the beam: a 'period error'
    that is the beam-plate gap, labelled truth). A result that names no truth passes."""
    truth = fit.get("truth") if isinstance(fit, dict) else None
    model = truth.get("model") if isinstance(truth, dict) else truth
    if isinstance(model, str) and model not in SIMULATED_TRUTHS:
        raise BadInput(f"--from: the result was made for the {model} truth, but simulate's "
                       "reference is the Euler-Bernoulli beam's modal superposition (the truth "
                       "it integrates in time); refit with `--truth beam` (`prbdm simulate BEAM "
                       "--joints N` does), or export it and simulate in MuJoCo")


def simulate(beam, fit: dict, *, pose="rest", tip_deflection: float | None = None,
             tip_impulse: float | None = None, damping: float = 0.0,
             duration: float | None = None, periods: float = 20.0, samples_per_period: int = 64,
             truth_modes: int = 20, modes: "BeamModes | None" = None, rtol: float = 1e-9,
             tolerance: float = DEFAULT_TOLERANCE,
             ignore_fingerprint: bool = False, check_beam: bool = True) -> SimulationResult:
    """Free response of the PRBDM of ``fit`` (see :func:`prbdm.export.prbdm_from_fit`; springs at
    rest straight, stiffness of pose ``pose``) and of the Euler-Bernoulli truth, from the same
    initial condition: ``tip_deflection`` [m] (default 1e-3 L) or ``tip_impulse`` [N s].
    ``duration`` [s] (default :func:`default_duration`; MIN_PERIODS damped to MAX_PERIODS
    first-mode periods of the truth, else BadInput). The first-mode periods of both are measured
    from the tip motions (:func:`prbdm.signals.damped_frequency`) and reported where the truth's
    measured period is within PERIOD_MEASURE_TOLERANCE of its exact one, else null with a
    warning. ``modes``: :func:`beam_modes` of ``beam`` with ``truth_modes`` modes, when the caller
    has them.

    Before the run, :func:`prbdm.preflight.prepare` checks the result's ``beam_fingerprint``
    (``check_beam``; BadInput for another beam unless ``ignore_fingerprint``) and, for
    ``pose="rest"`` (default), refits a result made for deflected poses at theta = 0 against its
    own truth (``info["refit"]``); the chain's small-vibration frequencies at the start are then
    compared with the truth (``info["check"]``, a warning per mode beyond ``tolerance``)."""
    from scipy.integrate import solve_ivp

    from .export import prbdm_from_fit
    from .preflight import check_frequencies, prepare, where_of

    t0 = time.perf_counter()
    L = beam.length
    if tip_deflection is not None and tip_impulse is not None:
        raise BadInput("--tip-deflection and --tip-impulse: give one, not both")
    check_damping(damping)
    warnings = []
    if tip_impulse is not None:
        if not math.isfinite(tip_impulse) or tip_impulse == 0:
            raise BadInput(f"--tip-impulse: must be a finite non-zero impulse [N s], "
                           f"got {tip_impulse!r}")
        kind, amount = "tip_impulse", float(tip_impulse)
    else:
        if tip_deflection is None:
            tip_deflection = 1e-3 * L
        if not math.isfinite(tip_deflection) or tip_deflection == 0 \
                or abs(tip_deflection) > 0.3 * L:
            raise BadInput(f"--tip-deflection: must be non-zero with |D| <= 0.3 L = {0.3 * L:g} m, "
                           f"got {tip_deflection!r}")
        kind, amount = "tip_deflection", float(tip_deflection)
    check_simulated_truth(fit)
    # the truth's modes first: a duration out of range is refused before any refit
    modes, T1, duration = truth_and_duration(beam, truth_modes, duration, damping, periods, modes)
    prep = prepare(beam, fit, pose=pose, ignore_fingerprint=ignore_fingerprint,
                   check_beam=check_beam)
    warnings += prep.warnings
    fit = prep.fit
    desc = prbdm_from_fit(beam, fit, pose=prep.pose, springref="zero", damping=damping)
    check, bad = check_frequencies(desc["omega"], prep.truth, prep.modes, tolerance=tolerance,
                                   truth_source=prep.truth_source, where=where_of(desc))
    warnings += bad
    chain = ChainDynamics.from_description(desc)
    damped = math.sqrt(1 - damping ** 2)      # damped / undamped frequency (check_damping: < 1)
    n = chain.n
    if kind == "tip_deflection":
        y0 = np.concatenate([chain.static_tip_shape(amount), np.zeros(n)])
        if abs(amount) > SMALL_DEFLECTION * L:
            warnings.append(f"tip deflection {amount:g} m > {SMALL_DEFLECTION:g} L: the truth is "
                            "linear, the PRBDM is not; compare at small amplitudes")
    else:
        y0 = np.concatenate([np.zeros(n), chain.impulse_velocity(amount)])
    count = int(math.ceil(duration / T1 * samples_per_period)) + 1
    t = np.linspace(0.0, duration, count)
    # absolute tolerances: rtol times the motion's scale (angle, and angle times omega_n)
    omega0 = chain.linear_frequencies(np.zeros(n))
    scale_theta = max(np.abs(y0[:n]).max(), np.abs(y0[n:]).max() / omega0[0])
    atol = np.concatenate([np.full(n, rtol * scale_theta),
                           np.full(n, rtol * scale_theta * omega0[-1])])
    ts = time.perf_counter()
    sol = solve_ivp(chain.rhs, (0.0, duration), y0, method="DOP853", t_eval=t, rtol=rtol,
                    atol=atol, dense_output=True)
    ode_s = time.perf_counter() - ts
    if not sol.success:
        raise RuntimeError(f"solve_ivp failed: {sol.message}")
    theta = sol.y[:n].T
    tip_prbdm = chain.tip(theta)[1]
    truth_kw = {kind: amount}
    tip_truth = modal_tip_response(modes, t, damping=damping, **truth_kw)

    omega_lin = omega0
    # the periods are measured on a grid fine enough for every mode of either model (4 samples
    # per period of the fastest): on the output grid, fast modes would alias onto the first
    fast = max(omega_lin[-1], modes.omega[-1]) / modes.omega[0]
    count_m = int(min(MAX_MEASURE_SAMPLES, math.ceil(duration / T1 * 4 * fast))) + 1
    tm = np.linspace(0.0, duration, count_m)
    # each model's known first-mode decay divided out (signals.damped_frequency): read as it is,
    # a decaying record gives a period biased by its decay, alike in both models, so that their
    # difference looked right while both were wrong (7 % at zeta 0.7)
    w_prbdm = damped_frequency(tm, chain.tip(sol.sol(tm)[:n].T)[1], omega_lin[0], damping)
    w_truth = damped_frequency(tm, modal_tip_response(modes, tm, damping=damping, **truth_kw),
                               modes.omega[0], damping)
    T_prbdm, T_truth = 2 * math.pi / w_prbdm, 2 * math.pi / w_truth
    T_exact = T1 / damped
    # the truth's exact damped period checks the measurement itself: where it fails (zeta above
    # about 0.72, where overdamped higher modes outlast the first) no period is reported
    measured = bool(abs(T_truth / T_exact - 1) <= PERIOD_MEASURE_TOLERANCE
                    and math.isfinite(T_prbdm))
    if not measured:
        warnings.append(
            f"at damping ratio {damping:g} the first-mode period cannot be measured from the tip "
            "motion (" + (f"the truth's measured period is {100 * (T_truth / T_exact - 1):+.2g} "
                          f"% off its exact {T_exact:.6g} s"
                          if math.isfinite(T_truth) and math.isfinite(T_prbdm) else
                          "the first mode dies out within a fraction of its period")
            + "): the measured periods and period_error are null; "
            "compare the linear periods (period_prbdm_linear_s, period_truth_exact_s) or a "
            "smaller --damping")
    # zero crossings while the first mode's envelope is well above the integrator's noise
    # (later, noise crossings gave periods 90 % short), and each kept only where it agrees with
    # its model's measured period: strong higher modes (an impulse) cross zero more than once a
    # period, and such a "period" was 75 % short
    live = decaying_window(t, modes.omega[0], damping, CROSSING_FLOOR)

    def crossing_period(tip, T):
        Tz = zero_crossing_period(t[live], tip[live])
        return None if math.isnan(Tz) or not measured or abs(Tz / T - 1) > CROSSING_TOLERANCE \
            else Tz
    fit_err = None
    if "freq_error" in fit:
        try:
            fit_err = float(np.asarray(fit["freq_error"], float)[desc["pose"]["index"], 0])
        except (IndexError, TypeError, ValueError):
            fit_err = None
        if fit_err is not None and not math.isfinite(fit_err):
            fit_err = None
    # the fit was made against its own truth solve: their first-mode difference is part of the
    # budget of the period comparison
    truth_diff = float(abs(prep.truth[0] / modes.omega[0] - 1))
    amp = float(np.max(np.abs(tip_truth)))
    info = {
        "joints": n, "law": desc["law"], "pose": desc["pose"]["index"],
        "pose_theta": desc["pose"]["theta"], "k": desc["pose"]["k"],
        "initial": {kind: amount}, "damping_ratio": float(damping), "duration_s": duration,
        "samples": int(count), "measure_samples": int(count_m),
        "omega_prbdm_linear": omega_lin.tolist(),
        "omega_truth": modes.omega.tolist(),
        "period_prbdm_s": T_prbdm if measured else None,
        "period_truth_s": T_truth if measured else None,
        "period_truth_exact_s": T_exact,
        "period_prbdm_linear_s": 2 * math.pi / omega_lin[0] / damped,
        # null where the tip crossed zero upwards fewer than twice (a heavily damped run)
        "period_zero_crossings_s": {"prbdm": crossing_period(tip_prbdm, T_prbdm),
                                    "truth": crossing_period(tip_truth, T_truth)},
        "period_error": abs(T_prbdm - T_truth) / T_truth if measured else None,
        # how far the truth's measured period is from its exact one: the resolution of
        # period_error (the same estimator reads both records)
        "period_resolution": (abs(T_truth / T_exact - 1) if math.isfinite(T_truth) else None),
        "fit_freq_error_mode1": fit_err,
        "fit_truth_difference_mode1": truth_diff,
        "max_tip_difference": float(np.max(np.abs(tip_prbdm - tip_truth)) / amp),
        "rms_tip_difference": float(np.sqrt(np.mean((tip_prbdm - tip_truth) ** 2)) / amp),
        "energy_drift": (abs(chain.energy(theta[-1], sol.y[n:, -1])
                             - chain.energy(y0[:n], y0[n:])) / chain.energy(y0[:n], y0[n:])
                         if damping == 0 else None),
        "truth": {"model": "Euler-Bernoulli modal superposition (prbdm.truth's beam "
                           "model, prbdm.simulate.beam_modes)",
                  "modes": int(modes.omega.size), "elements": modes.elements,
                  "truncation": float(1 - np.sum(modes.tip ** 2 / modes.omega ** 2)
                                      / modes.static_compliance)},
        "solver": {"method": "DOP853", "rtol": rtol, "nfev": int(sol.nfev), "time_s": ode_s},
        "refit": prep.refit, "check": check, "beam_fingerprint": prep.fingerprint,
        "warnings": warnings,
        "time_s": time.perf_counter() - t0,
        "units": {"t": "s", "tip": "m (z of the tip)", "omega": "rad/s", "period": "s"},
    }
    return SimulationResult(t=t, tip_prbdm=tip_prbdm, tip_truth=tip_truth, theta=theta,
                            info=info)


def plot_simulation(result: SimulationResult, path, title: str = "") -> None:
    """Tip deflection of the PRBDM and the truth against time (whole run, and its last three
    periods, where a period error shows as a phase shift), saved to ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t, a, b = result.t, result.tip_truth, result.tip_prbdm
    info = result.info
    fig, axes = plt.subplots(2, 1, figsize=(8, 6), constrained_layout=True)
    T = info["period_truth_s"]
    for ax, sel in ((axes[0], slice(None)), (axes[1], t >= t[-1] - 3 * T)):
        ax.plot(t[sel], 1e3 * a[sel], "k-", lw=1.2, label="truth (Euler-Bernoulli modes)")
        ax.plot(t[sel], 1e3 * b[sel], "C1--", lw=1.2,
                label=f"{info['joints']}R-PRBDM (nonlinear, pose {info['pose']})")
        ax.set_xlabel("time [s]")
        ax.set_ylabel("tip deflection [mm]")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=8)
    axes[0].set_title(title or f"free response: first-mode period PRBDM "
                      f"{info['period_prbdm_s']:.6g} s, truth {T:.6g} s "
                      f"(error {100 * info['period_error']:.3g} %)",
                      fontsize=9)
    axes[1].set_title("last three periods", fontsize=9)
    fig.savefig(path, dpi=120)
    plt.close(fig)
