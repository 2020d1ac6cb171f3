"""Time response of a PRBDM against a truth: ``prbdm simulate`` (issue 8; large amplitude, issue 37).

The PRBDM (:class:`prbdm.chain.ChainDynamics`, re-exported here). The full nonlinear equations
of the planar chain,

    M(theta) theta'' + C(theta, theta') theta' + D theta' + tau_spring(theta) = tau,

are integrated with ``scipy.integrate.solve_ivp`` (DOP853, rtol 1e-9), in the absolute link
angles, where the kinetic energy has a *constant* matrix and Lagrange's equations are exact in
closed form (:func:`prbdm.chain.absolute_inertia`, :func:`prbdm.chain.joint_accelerations`; the
mass matrix equals :func:`prbdm.model.mass_matrix` and the Coriolis term the one from autograd
of the kinetic energy, tests/test_simulate.py): a right-hand side costs microseconds. Damping: a
first-mode damping ratio ``zeta`` becomes stiffness-proportional damping
``D = (2 zeta / omega_1) K`` (per-joint viscous), the same in the truth
(``zeta_r = zeta omega_r / omega_1``), so both have ratio zeta on their first mode.

The reference (:func:`reference_kind`), decided by the initial condition:

- **Small amplitude** (a tip deflection up to SMALL_DEFLECTION = 0.01 L, a tip impulse, or a
  damped run): the Euler-Bernoulli cantilever of docs/conventions.md §2 (:func:`beam_modes`, the
  same solve as ``prbdm truth --model beam``) as the modal superposition
  ``w(L, t) = sum_r phi_r(L) eta_r(t)`` of its lowest R modes (default 20), each exact. The chain
  has the constant stiffness of one pose (the small-vibration model at rest by default, a
  paper-pose result refitted at theta = 0). ``tip_deflection D`` releases both from rest in
  their linear static shape under a tip force, scaled so the tip's z is D (PRBDM:
  ``theta_k proportional to (L - x_k) / K_k`` with the exact kinematics; truth:
  ``eta_r(0) = F phi_r(L) / omega_r^2``); ``tip_impulse P`` [N s] strikes the straight beam at
  the tip (PRBDM: ``theta'(0) = M(0)^-1 J^T P``; truth: ``eta'_r(0) = P phi_r(L)``). The
  first-mode periods are measured by one estimator on both records. A damped release beyond
  0.01 L, and an impulse that swings the tip beyond it, get a warning: the rod is undamped and
  starts from rest.
- **Large amplitude** (an undamped release from a tip deflection beyond 0.01 L): the
  geometrically exact rod (:mod:`prbdm.large_amplitude`, :mod:`prbdm.truth.rod`), each model
  released from its own static equilibrium under a dead tip force with its tip at D, the chain
  with the spring law its result was fitted with (:func:`model_pose`,
  :func:`prbdm.springs.fitted_springs`: constant stiffness for a ``shape`` result, the per-pose
  SCFs interpolated by an energy-consistent law for a ``straight`` one, simulated as fitted
  with no refit); periods from downward zero crossings of the tip. A tip deflection the rod
  does not reach under the loads it accepts is refused (BadInput naming ``--tip-deflection``).

:func:`simulate` takes settings objects: :class:`InitialCondition`, :class:`RunSettings`,
:class:`ReferenceSettings`, :class:`CheckSettings`; :func:`prepare_reference` checks them and
prepares the reference before any fit.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from .chain import ChainDynamics
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
           "SimulationResult", "InitialCondition", "RunSettings", "ReferenceSettings",
           "CheckSettings", "Reference", "prepare_reference", "reference_kind", "model_pose",
           "dominant_frequency", "zero_crossing_period", "plot_simulation"]

#: the small-deflection limit (fraction of L): up to it the reference is the linear truth's
#: modal superposition, beyond it the geometrically exact rod (:func:`reference_kind`)
SMALL_DEFLECTION = 0.01
#: the largest tip deflection (fraction of L) released against the linear truth (a damped run)
LINEAR_MAX_DEFLECTION = 0.3
MAX_PERIODS = 500
#: against the rod (seconds per period of its implicit integration): at most this many periods,
#: and this many by default; against the modal truth (closed form), MODAL_PERIODS by default
ROD_MAX_PERIODS = 40
ROD_PERIODS = 5
MODAL_PERIODS = 20
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


# ----------------------------------------------------------------------------- settings
@dataclass(frozen=True)
class InitialCondition:
    """How both models start (give one): ``tip_deflection`` D [m], released from rest in the
    static shape under a tip force whose tip z is D (default 1e-3 L when neither is given), or
    ``tip_impulse`` P [N s], the straight beam at rest struck at the tip along z."""

    tip_deflection: float | None = None
    tip_impulse: float | None = None

    def resolve(self, length: float) -> tuple[str, float]:
        """(kind, amount), checked for a beam of ``length`` [m]: ``("tip_deflection", D)`` with
        ``0 < |D| < L``, or ``("tip_impulse", P)`` with ``P != 0``; BadInput otherwise."""
        if self.tip_deflection is not None and self.tip_impulse is not None:
            raise BadInput("--tip-deflection and --tip-impulse: give one, not both")
        if self.tip_impulse is not None:
            P = self.tip_impulse
            if not _finite(P) or P == 0:
                raise BadInput(f"--tip-impulse: must be a finite non-zero impulse [N s], "
                               f"got {P!r}")
            return "tip_impulse", float(P)
        D = 1e-3 * length if self.tip_deflection is None else self.tip_deflection
        if not _finite(D) or D == 0 or abs(D) >= length:
            raise BadInput(f"--tip-deflection: must be non-zero with |D| < L = {length:g} m, "
                           f"got {D!r}")
        return "tip_deflection", float(D)


@dataclass(frozen=True)
class RunSettings:
    """The run: ``damping`` (first-mode damping ratio in [0, 1), both models alike),
    ``duration`` [s] (default ``periods`` first-mode periods of the linear truth: 20 against
    the modal truth, 5 against the rod), ``samples_per_period`` of the output grid, ``rtol`` of
    the PRBDM's integration (DOP853)."""

    damping: float = 0.0
    duration: float | None = None
    periods: float | None = None
    samples_per_period: int = 64
    rtol: float = 1e-9


@dataclass(frozen=True)
class ReferenceSettings:
    """The truths: ``truth_modes`` of the modal superposition; the rod's discretisation
    (``rod_elements`` of degree ``rod_degree``), ``rod_steps`` per linear period and
    ``rod_check`` (a second run at half the steps: the resolution of the period comparison).
    The rod's defaults are coarser than :func:`prbdm.truth.rod.rod_response`'s (6 elements, 1024
    steps): on the README's tapered strip and the demo panel released at 0.2 L their period is
    within 2e-4 of those and 10 to 40 times faster (docs/howto/export-and-simulate.md)."""

    truth_modes: int = 20
    rod_elements: int = 4
    rod_degree: int = 4
    rod_steps: int = 512
    rod_check: bool = True


@dataclass(frozen=True)
class CheckSettings:
    """The checks before use (:mod:`prbdm.preflight`): the frequency ``tolerance`` (relative),
    ``ignore_fingerprint`` (apply a result made for another beam), ``check_beam`` (off for a
    fit run here on this beam)."""

    tolerance: float = DEFAULT_TOLERANCE
    ignore_fingerprint: bool = False
    check_beam: bool = True


def _finite(v) -> bool:
    return not isinstance(v, bool) and isinstance(v, (int, float, np.floating, np.integer)) \
        and math.isfinite(v)


# ----------------------------------------------------------------------------- the reference
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


def check_duration(duration: float, T1: float, damping: float,
                   max_periods: int = MAX_PERIODS) -> None:
    """BadInput naming ``--duration`` unless it spans MIN_PERIODS damped to ``max_periods``
    first-mode periods of the truth (``T1`` [s] undamped; the tip crosses zero once per damped
    period, so fewer than MIN_PERIODS of those leave no period to measure)."""
    if not _finite(duration) or duration <= 0:
        raise BadInput(f"--duration: must be > 0 s, got {duration!r}")
    Td = T1 / math.sqrt(1 - damping ** 2)          # check_damping: damping < 1
    if MIN_PERIODS * Td > max_periods * T1:
        raise BadInput(f"--damping: {MIN_PERIODS} damped first-mode periods must fit in "
                       f"{max_periods} undamped ones (damping ratio below "
                       f"{math.sqrt(1 - (MIN_PERIODS / max_periods) ** 2):.6g}), got {damping:g}")
    # (a duration of 3 periods computed from another solve of the same truth may fall short by
    # round-off)
    if not MIN_PERIODS * Td * (1 - 1e-3) <= duration <= max_periods * T1:
        raise BadInput(f"--duration: at least {MIN_PERIODS} damped and at most {max_periods} "
                       f"first-mode periods ({MIN_PERIODS * Td:.4g} to {max_periods * T1:.4g} s)"
                       + (" against the rod" if max_periods == ROD_MAX_PERIODS else "")
                       + f", got {duration:g} s")


def default_duration(T1: float, damping: float, periods: float = MODAL_PERIODS,
                     max_periods: int = MAX_PERIODS) -> float:
    """The simulated time [s] when none is given: ``periods`` first-mode periods of the truth
    (``T1`` [s], undamped), and at least MIN_PERIODS + 1 damped ones (a heavily damped run),
    within the ``max_periods`` undamped ones :func:`check_duration` allows."""
    return min(max(periods * T1, (MIN_PERIODS + 1) * T1 / math.sqrt(1 - damping ** 2)),
               max_periods * T1)


def reference_kind(kind: str, amount: float, damping: float, length: float):
    """(reference, warnings): which truth a run is compared with. ``"rod"`` (the geometrically
    exact rod, :mod:`prbdm.large_amplitude`) for an undamped release from a tip deflection
    beyond SMALL_DEFLECTION L; ``"modal"`` (the linear Euler-Bernoulli modal superposition)
    otherwise: at small amplitude, where it is the panel's motion, and, with a warning, for a
    damped release beyond it (the rod is undamped). A tip impulse is always compared with the
    modal truth (the rod starts from rest); its warning, where the struck beam swings beyond the
    limit, comes with the run (:func:`simulate`)."""
    if kind != "tip_deflection" or abs(amount) <= SMALL_DEFLECTION * length:
        return "modal", []
    if damping == 0:
        return "rod", []
    return "modal", [f"tip deflection {amount:g} m > {SMALL_DEFLECTION:g} L with damping: the "
                     "large-amplitude reference (the geometrically exact rod) is undamped, so the "
                     "reference is the linear truth, which the panel leaves at this amplitude; "
                     "give --damping 0 to compare with the rod"]


@dataclass
class Reference:
    """The truth a run is compared with, chosen and prepared before any fit
    (:func:`prepare_reference`): ``kind`` ("modal" or "rod"), ``initial`` (kind, amount),
    ``modes`` (:func:`beam_modes`, the linear truth), ``T1`` its first period [s], ``duration``
    [s], ``rod`` (the rod's released equilibrium, :func:`prbdm.truth.rod.rod_static`; rod only),
    ``warnings``."""

    kind: str
    initial: tuple
    modes: BeamModes
    T1: float
    duration: float
    rod: object = None
    warnings: list = field(default_factory=list)


def prepare_reference(beam, initial: InitialCondition | None = None,
                      run: RunSettings | None = None,
                      reference: ReferenceSettings | None = None,
                      modes: BeamModes | None = None) -> Reference:
    """Check the initial condition and the run and prepare the truth they are compared with
    (:func:`reference_kind`): the linear truth's modes (``modes`` when the caller has them), the
    duration (:func:`default_duration`; :func:`check_duration`, at most ROD_MAX_PERIODS periods
    against the rod) and, against the rod, its released equilibrium (BadInput naming
    ``--tip-deflection`` beyond what the rod resolves). Cheap next to a fit (the rod's static
    solve takes up to a second or two): the command line calls it before fitting, so that bad
    input is refused first."""
    initial = initial or InitialCondition()
    run = run or RunSettings()
    reference = reference or ReferenceSettings()
    check_damping(run.damping)
    L = beam.length
    kind, amount = initial.resolve(L)
    which, warnings = reference_kind(kind, amount, run.damping, L)
    if which == "modal" and kind == "tip_deflection" and abs(amount) > LINEAR_MAX_DEFLECTION * L:
        raise BadInput(f"--tip-deflection: with damping the reference is the linear truth: |D| "
                       f"<= {LINEAR_MAX_DEFLECTION:g} L = {LINEAR_MAX_DEFLECTION * L:g} m, got "
                       f"{amount!r}")
    if modes is None:
        modes = beam_modes(beam, reference.truth_modes)
    T1 = 2 * math.pi / modes.omega[0]
    top = ROD_MAX_PERIODS if which == "rod" else MAX_PERIODS
    periods = run.periods or (ROD_PERIODS if which == "rod" else MODAL_PERIODS)
    duration = run.duration
    if duration is None:
        duration = default_duration(T1, run.damping, periods, top)
    check_duration(duration, T1, run.damping, top)
    rod = None
    if which == "rod":
        from .large_amplitude import rod_release

        rod = rod_release(beam, amount)
    return Reference(kind=which, initial=(kind, amount), modes=modes, T1=T1,
                     duration=float(duration), rod=rod, warnings=warnings)


#: the truths whose physics the simulation's references (the Euler-Bernoulli modal
#: superposition, the rod) are: a result fitted to another is judged by the truth it was fitted
#: to or not at all
SIMULATED_TRUTHS = ("beam", "analytic")


def check_simulated_truth(fit: dict) -> None:
    """BadInput for a result made for another truth than the simulated one: its PRBDM would be
    judged against physics it was not fitted to (a plate fit against the beam: a 'period error'
    that is the beam-plate gap, labelled truth). A result that names no truth passes."""
    truth = fit.get("truth") if isinstance(fit, dict) else None
    model = truth.get("model") if isinstance(truth, dict) else truth
    if isinstance(model, str) and model not in SIMULATED_TRUTHS:
        raise BadInput(f"--from: the result was made for the {model} truth, but simulate's "
                       "reference is the Euler-Bernoulli beam (its modal superposition, or the "
                       "geometrically exact rod at large amplitude); refit with `--truth beam` "
                       "(`prbdm simulate BEAM --joints N` does), or export it and simulate in "
                       "MuJoCo")


def model_pose(fit: dict, pose, target: str, reference: str):
    """(pose for :func:`prbdm.preflight.prepare`, fitted law?): which of the result's poses the
    chain takes its stiffness from, and whether its spring law is the fitted one
    (:func:`prbdm.springs.fitted_springs`) or that pose's constant stiffness.

    ``pose="rest"``: a ``shape`` result holds its rest stiffness at every pose (pose 0, no refit);
    against the rod, a ``straight`` result fitted away from rest is simulated as fitted (from its
    smallest pose, with its SCFs interpolated between the poses: no refit); otherwise ``"rest"``
    (a paper-pose result refitted at theta = 0 for small vibrations). An index or ``"linear"``:
    that pose, its constant stiffness."""
    from .poses import is_rest
    from .preflight import REST_NAMES

    if not (isinstance(pose, str) and pose.strip() in REST_NAMES):
        return pose, False
    if target == "shape":
        return 0, True
    if reference == "rod":
        try:
            poses = np.atleast_2d(np.asarray(fit["poses"], dtype=float))
        except (KeyError, TypeError, ValueError):
            return "rest", False                 # prepare names what is wrong with it
        if poses.ndim == 2 and poses.size and not is_rest(poses):
            return int(np.argmin(np.abs(poses).max(axis=1))), True
    return "rest", False


#: what a check warning of a result simulated as fitted at large amplitude advises
AS_FITTED_REMEDY = ("at large amplitude the result is simulated as fitted (its per-pose SCFs "
                    "interpolated between the poses); for a chain that follows the bent panel, "
                    "fit with `prbdm fit --pose-target shape`")


def _modal_run(chain, ref: Reference, run: RunSettings, length: float) -> dict:
    """The PRBDM and the linear truth's modal superposition from the same initial condition
    (``length``: the beam's, for the small-deflection limit of an impulse's swing): the same
    keys as :func:`prbdm.large_amplitude.compare_with_rod`, the periods measured by one
    estimator on both records (:func:`prbdm.signals.damped_frequency`)."""

    kind, amount = ref.initial
    modes, T1, duration, damping = ref.modes, ref.T1, ref.duration, run.damping
    n = chain.n
    if kind == "tip_deflection":
        y0 = np.concatenate([chain.static_tip_shape(amount), np.zeros(n)])
    else:
        y0 = np.concatenate([np.zeros(n), chain.impulse_velocity(amount)])
    count = int(math.ceil(duration / T1 * run.samples_per_period)) + 1
    t = np.linspace(0.0, duration, count)
    # absolute tolerances: rtol times the motion's scale (angle, and angle times omega_n)
    omega0 = chain.linear_frequencies(np.zeros(n))
    scale_theta = max(np.abs(y0[:n]).max(), np.abs(y0[n:]).max() / omega0[0])
    atol = np.concatenate([np.full(n, run.rtol * scale_theta),
                           np.full(n, run.rtol * scale_theta * omega0[-1])])
    sol, ode_s = chain.integrate(y0, duration, t, run.rtol, atol, dense_output=True)
    theta = sol.y[:n].T
    tip_prbdm = chain.tip(theta)[1]
    truth_kw = {kind: amount}
    tip_truth = modal_tip_response(modes, t, damping=damping, **truth_kw)
    # the periods are measured on a grid fine enough for every mode of either model (4 samples
    # per period of the fastest): on the output grid, fast modes would alias onto the first
    fast = max(omega0[-1], modes.omega[-1]) / modes.omega[0]
    count_m = int(min(MAX_MEASURE_SAMPLES, math.ceil(duration / T1 * 4 * fast))) + 1
    tm = np.linspace(0.0, duration, count_m)
    # each model's known first-mode decay divided out (signals.damped_frequency): read as it is,
    # a decaying record gives a period biased by its decay, alike in both models, so that their
    # difference looked right while both were wrong (7 % at zeta 0.7)
    w_prbdm = damped_frequency(tm, chain.tip(sol.sol(tm)[:n].T)[1], omega0[0], damping)
    w_truth = damped_frequency(tm, modal_tip_response(modes, tm, damping=damping, **truth_kw),
                               modes.omega[0], damping)
    T_prbdm, T_truth = 2 * math.pi / w_prbdm, 2 * math.pi / w_truth
    T_exact = T1 / math.sqrt(1 - damping ** 2)
    # the truth's exact damped period checks the measurement itself: where it fails (zeta above
    # about 0.72, where overdamped higher modes outlast the first) no period is reported
    measured = bool(abs(T_truth / T_exact - 1) <= PERIOD_MEASURE_TOLERANCE
                    and math.isfinite(T_prbdm))
    warnings = []
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
    amp = float(np.max(np.abs(tip_truth)))
    if kind == "tip_impulse" and amp > SMALL_DEFLECTION * length:
        warnings.append(f"the struck beam swings to {amp:.4g} m, beyond {SMALL_DEFLECTION:g} L: "
                        "the reference is the linear truth, which the panel leaves at this "
                        "amplitude (the large-amplitude reference, the geometrically exact rod, "
                        "starts from rest: release from --tip-deflection to compare with it)")
    return {
        "t": t, "tip_prbdm": tip_prbdm, "tip_truth": tip_truth, "theta": theta,
        "period_prbdm": T_prbdm if measured else None,
        "period_truth": T_truth if measured else None,
        # null where the tip crossed zero upwards fewer than twice (a heavily damped run)
        "crossings": {"prbdm": crossing_period(tip_prbdm, T_prbdm),
                      "truth": crossing_period(tip_truth, T_truth)},
        # how far the truth's measured period is from its exact one: the resolution of
        # period_error (the same estimator reads both records)
        "resolution": abs(T_truth / T_exact - 1) if math.isfinite(T_truth) else None,
        "measure_samples": int(count_m), "warnings": warnings,
        "truth": {"model": "Euler-Bernoulli modal superposition (prbdm.truth's beam "
                           "model, prbdm.simulate.beam_modes)",
                  "modes": int(modes.omega.size), "elements": modes.elements,
                  "truncation": float(1 - np.sum(modes.tip ** 2 / modes.omega ** 2)
                                      / modes.static_compliance)},
        "nfev": int(sol.nfev), "ode_s": ode_s,
        "energy_drift": (abs(chain.energy(theta[-1], sol.y[n:, -1])
                             - chain.energy(y0[:n], y0[n:])) / chain.energy(y0[:n], y0[n:])
                         if damping == 0 else None),
    }


def simulate(beam, fit: dict, pose="rest", initial: InitialCondition | None = None,
             run: RunSettings | None = None, reference: ReferenceSettings | None = None,
             checks: CheckSettings | None = None, *,
             prepared: Reference | None = None) -> SimulationResult:
    """Free response of the PRBDM of ``fit`` (see :func:`prbdm.export.prbdm_from_fit`; springs at
    rest straight) and of the truth, from the same initial condition (``initial``, default a tip
    deflection of 1e-3 L), over ``run`` (damping, duration), against the truth of
    :func:`reference_kind` (``reference`` its settings; ``prepared``: the
    :func:`prepare_reference` the caller made already, which then decides the initial condition
    and the duration). Defaults: :class:`InitialCondition`, :class:`RunSettings`,
    :class:`ReferenceSettings`, :class:`CheckSettings`.

    Small amplitude (the modal truth): the chain's stiffness is pose ``pose``'s SCF at every
    angle; the first-mode periods of both are measured from the tip motions
    (:func:`prbdm.signals.damped_frequency`) and reported where the truth's measured period is
    within PERIOD_MEASURE_TOLERANCE of its exact one, else null with a warning. Large amplitude
    (the rod, :mod:`prbdm.large_amplitude`): the chain has the spring law the result was fitted
    with (:func:`model_pose`, :func:`prbdm.springs.fitted_springs`), and the periods are the
    mean times between downward zero crossings of the tip.

    Before the run, :func:`prbdm.preflight.prepare` checks the result's ``beam_fingerprint``
    (``checks.check_beam``; BadInput for another beam unless ``checks.ignore_fingerprint``) and,
    where :func:`model_pose` says ``"rest"``, refits a result made for deflected poses at
    theta = 0 against its own truth (``info["refit"]``); the chain's small-vibration frequencies
    at rest are then compared with the truth (``info["check"]``, a warning per mode beyond
    ``checks.tolerance``)."""
    from .export import prbdm_from_fit
    from .preflight import REMEDY, check_frequencies, prepare, where_of
    from .springs import fitted_springs, pose_target_of

    t0 = time.perf_counter()
    run = run or RunSettings()
    checks = checks or CheckSettings()
    check_damping(run.damping)
    if prepared is None:
        (initial or InitialCondition()).resolve(beam.length)      # before the result's checks
    check_simulated_truth(fit)
    target = pose_target_of(fit) if isinstance(fit, dict) else "straight"
    # the reference first: a duration or deflection out of range is refused before any refit
    ref = prepared or prepare_reference(beam, initial, run, reference)
    damping = run.damping
    use_pose, fitted_law = model_pose(fit, pose, target, ref.kind) if isinstance(fit, dict) \
        else (pose, False)
    prep = prepare(beam, fit, pose=use_pose, ignore_fingerprint=checks.ignore_fingerprint,
                   check_beam=checks.check_beam)
    warnings = list(ref.warnings) + prep.warnings
    fit = prep.fit
    desc = prbdm_from_fit(beam, fit, pose=prep.pose, springref="zero", damping=damping)
    check, bad = check_frequencies(desc["omega"], prep.truth, prep.modes,
                                   tolerance=checks.tolerance, truth_source=prep.truth_source,
                                   where=where_of(desc))
    springs = None
    law = {"law": "constant", "pose_target": target, "k": desc["pose"]["k"],
           "why": f"the SCF of pose {desc['pose']['index']} at every angle"}
    if fitted_law:
        springs, law = fitted_springs(fit, [h["base_stiffness"] for h in desc["hinges"]])
    if law["law"] == "interpolated":
        bad = [w[:-len(REMEDY)] + AS_FITTED_REMEDY if w.endswith(REMEDY) else w for w in bad]
    warnings += bad
    chain = ChainDynamics.from_description(desc, springs)
    if ref.kind == "rod":
        from .large_amplitude import compare_with_rod

        r = compare_with_rod(beam, chain, ref, run, reference or ReferenceSettings(),
                             x1=desc["bodies"][0]["length"])
        got = [v for v in (r["period_prbdm"], r["period_truth"]) if math.isfinite(v)]
        if len(got) < 2:
            warnings.append("fewer than two downward zero crossings of the tip within the run "
                            f"({r['crossings']['prbdm']} of the PRBDM, "
                            f"{r['crossings']['truth']} of the rod): no period to compare; "
                            "give a longer --duration")
            r["period_prbdm"] = r["period_truth"] = None
        r["crossings"] = {"prbdm": r["period_prbdm"], "truth": r["period_truth"]}
        r["measure_samples"] = None
    else:
        r = _modal_run(chain, ref, run, beam.length)
        warnings += r["warnings"]
    T_prbdm, T_truth = r["period_prbdm"], r["period_truth"]
    fit_err = None
    if target == "shape":
        # held at every pose, fitted at rest: its error there is the check's (the result's
        # freq_error is against the rod bent into each pose)
        fit_err = float(abs(check["error"][0]))
    elif "freq_error" in fit:
        try:
            fit_err = float(np.asarray(fit["freq_error"], float)[desc["pose"]["index"], 0])
        except (IndexError, TypeError, ValueError):
            fit_err = None
        if fit_err is not None and not math.isfinite(fit_err):
            fit_err = None
    # the fit was made against its own truth solve: their first-mode difference is part of the
    # budget of the period comparison
    modes, T1 = ref.modes, ref.T1
    truth_diff = float(abs(prep.truth[0] / modes.omega[0] - 1))
    tip_prbdm, tip_truth = r["tip_prbdm"], r["tip_truth"]
    amp = float(np.max(np.abs(tip_truth)))
    omega_lin = chain.linear_frequencies(np.zeros(chain.n))
    damped = math.sqrt(1 - damping ** 2)      # damped / undamped frequency (check_damping: < 1)
    kind, amount = ref.initial
    info = {
        "joints": chain.n, "law": desc["law"], "pose": desc["pose"]["index"],
        "pose_theta": desc["pose"]["theta"], "k": desc["pose"]["k"],
        "reference": ref.kind, "pose_target": target, "springs": law,
        "initial": {kind: amount}, "damping_ratio": float(damping), "duration_s": ref.duration,
        "samples": int(r["t"].size), "measure_samples": r["measure_samples"],
        "omega_prbdm_linear": omega_lin.tolist(),
        "omega_truth": modes.omega.tolist(),
        "period_prbdm_s": T_prbdm,
        "period_truth_s": T_truth,
        "period_truth_exact_s": T1 / damped,
        "period_prbdm_linear_s": 2 * math.pi / omega_lin[0] / damped,
        "period_zero_crossings_s": r["crossings"],
        "period_error": (abs(T_prbdm - T_truth) / T_truth
                         if T_prbdm is not None and T_truth is not None else None),
        "period_resolution": r["resolution"],
        "fit_freq_error_mode1": fit_err,
        "fit_truth_difference_mode1": truth_diff,
        "max_tip_difference": float(np.max(np.abs(tip_prbdm - tip_truth)) / amp),
        "rms_tip_difference": float(np.sqrt(np.mean((tip_prbdm - tip_truth) ** 2)) / amp),
        "energy_drift": r["energy_drift"],
        "release": r.get("release"),
        "truth": r["truth"],
        "solver": {"method": "DOP853", "rtol": run.rtol, "nfev": r["nfev"], "time_s": r["ode_s"]},
        "refit": prep.refit, "check": check, "beam_fingerprint": prep.fingerprint,
        "warnings": warnings,
        "time_s": time.perf_counter() - t0,
        "units": {"t": "s", "tip": "m (z of the tip)", "omega": "rad/s", "period": "s"},
    }
    return SimulationResult(t=r["t"], tip_prbdm=tip_prbdm, tip_truth=tip_truth, theta=r["theta"],
                            info=info)


def plot_simulation(result: SimulationResult, path, title: str = "") -> None:
    """Tip deflection of the PRBDM and the truth against time (whole run, and its last three
    periods, where a period error shows as a phase shift), saved to ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t, a, b = result.t, result.tip_truth, result.tip_prbdm
    info = result.info
    rod = info.get("reference") == "rod"
    fig, axes = plt.subplots(2, 1, figsize=(8, 6), constrained_layout=True)
    T = info["period_truth_s"] or info["period_truth_exact_s"]
    law = (info.get("springs") or {}).get("law", "constant")
    for ax, sel in ((axes[0], slice(None)), (axes[1], t >= t[-1] - 3 * T)):
        ax.plot(t[sel], 1e3 * a[sel], "k-", lw=1.2,
                label="truth (geometrically exact rod)" if rod
                else "truth (Euler-Bernoulli modes)")
        ax.plot(t[sel], 1e3 * b[sel], "C1--", lw=1.2,
                label=f"{info['joints']}R-PRBDM (nonlinear, "
                      + (f"{law} springs)" if rod else f"pose {info['pose']})"))
        ax.set_xlabel("time [s]")
        ax.set_ylabel("tip deflection [mm]")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=8)
    pe = info["period_error"]
    axes[0].set_title(title or ("free response: first-mode period " + (
        f"PRBDM {info['period_prbdm_s']:.6g} s, truth {info['period_truth_s']:.6g} s (error "
        f"{100 * pe:.3g} %)" if pe is not None else "not measured (see the warnings)")),
        fontsize=9)
    axes[1].set_title("last three periods", fontsize=9)
    fig.savefig(path, dpi=120)
    plt.close(fig)
