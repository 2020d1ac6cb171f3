"""``prbdm simulate`` at large amplitude: the PRBDM against the geometrically exact rod.

Above the small-deflection limit (:data:`prbdm.simulate.SMALL_DEFLECTION`, 0.01 L) the linear
beam's modal superposition is no longer the panel's motion; an undamped release from a static
tip deflection D is then compared with :mod:`prbdm.truth.rod` (the planar, inextensible
Euler-Bernoulli rod with exact kinematics, the panel as a strip; docs/large-deflection.md):

- **Release**: each model from rest in its own static equilibrium under a dead tip force along z
  whose tip z is D: the rod's (:func:`prbdm.truth.rod.rod_static` with ``tip_deflection``) and
  the chain's, with its spring law (:class:`prbdm.chain.TipLoadStatics`). The two forces differ
  by the chain's static error; the starting tip deflections are the same.
- **Rod**: :func:`prbdm.truth.rod.rod_response` (implicit midpoint rule, ``steps`` per linear
  period), run for enough periods to cover the duration; its tip z is interpolated onto the
  output grid (cubic spline on its own grid of ``steps`` per period). With ``check`` the release
  is run again at half the steps, and the change of the measured period is the resolution of
  the comparison.
- **PRBDM**: its full nonlinear equations (:class:`prbdm.simulate.ChainDynamics`, DOP853).
- **Period**: the rod's own definition, the mean time between successive downward crossings of
  z = 0 by the tip within the run, for both (the chain's from the integrator's events, the rod's
  from the spline of its record).

The rod has no damping and starts from rest: a damped run or a tip impulse at large amplitude is
compared with the linear truth, with a warning (:func:`prbdm.simulate.reference_kind`).
"""
from __future__ import annotations

import math

import numpy as np

from .errors import BadInput

__all__ = ["rod_release", "downward_crossings", "compare_with_rod", "ROD_RUN_PERIODS"]

#: the most periods one rod run integrates (:func:`prbdm.truth.rod.rod_response` takes 50)
ROD_RUN_PERIODS = 50


def rod_release(beam, deflection: float):
    """The rod's static equilibrium under a dead tip force along z (perpendicular to the straight
    strip) whose tip z is ``deflection`` [m]; BadInput naming ``--tip-deflection`` where the rod
    does not reach it within the loads it accepts (:data:`prbdm.truth.rod.MAX_LOAD`)."""
    from .truth.rod import rod_static

    try:
        return rod_static(beam, tip_deflection=float(deflection),
                          force_angle=math.copysign(math.pi / 2, deflection))
    except BadInput as exc:
        text = str(exc).split(": ", 1)[-1]
        raise BadInput(f"--tip-deflection: beyond what the large-amplitude reference (the "
                       f"geometrically exact rod) resolves: {text}") from None


def downward_crossings(t, z, sign: float = 1.0) -> np.ndarray:
    """Times where ``sign * z`` crosses zero downwards, located on the cubic spline through the
    samples ``(t, z)`` (sorted, near-duplicates at the knots merged)."""
    from scipy.interpolate import CubicSpline

    spline = CubicSpline(np.asarray(t, float), sign * np.asarray(z, float))
    roots = np.sort(spline.roots(extrapolate=False))
    if roots.size:
        roots = roots[np.concatenate([[True], np.diff(roots) > 1e-12 * (t[-1] - t[0])])]
    return roots[spline(roots, 1) < 0]


def _mean_period(crossings) -> float:
    return float(np.mean(np.diff(crossings))) if len(crossings) >= 2 else math.nan


def compare_with_rod(beam, chain, ref, run, settings, x1: float) -> dict:
    """Release the rod and the chain (:class:`prbdm.simulate.ChainDynamics`, joint 1 at
    ``(x1, 0)``) from the tip deflection of ``ref`` (:func:`prbdm.simulate.prepare_reference`)
    and integrate both over ``ref.duration``; ``run`` and ``settings`` are the simulation's
    :class:`~prbdm.simulate.RunSettings` and :class:`~prbdm.simulate.ReferenceSettings`.

    Returns a dict: ``t``, ``tip_prbdm``, ``tip_truth`` [m] on the output grid, ``theta``,
    ``period_prbdm``, ``period_truth`` (nan with fewer than two crossings), ``resolution`` (the
    rod's period change at half its steps, or None), ``crossings`` (counts), ``release``,
    ``truth`` (JSON-ready, the rod run), ``nfev``, ``ode_s``, ``energy_drift``."""
    from scipy.interpolate import CubicSpline

    from .truth.rod import rod_response

    _, D = ref.initial
    eq = ref.rod
    fa = math.copysign(math.pi / 2, D)
    sign = 1.0 if D > 0 else -1.0
    try:
        th0, P = chain.statics(x1).release_shape(D, force_angle=fa,
                                                 load_guess=float(np.hypot(*eq.force)),
                                                 measure="tip_z")
    except RuntimeError:
        raise BadInput(f"--tip-deflection: the PRBDM finds no stable static shape with its tip at "
                       f"z = {D:g} m under a tip force (its links 1..n are "
                       f"{float(chain.length.sum()):.4g} m long)") from None
    duration, T1 = ref.duration, ref.T1
    # the rod runs until its crossing number `periods`, near T/4 + periods T: enough for the
    # duration unless its period is 5 % below the linear one; then again, with more
    periods = min(ROD_RUN_PERIODS, max(1, math.ceil(duration / T1)))

    def release(steps):
        return rod_response(beam, eq.tip_angle, force_angle=fa, periods=periods, steps=steps,
                            check=False, elements=settings.rod_elements,
                            degree=settings.rod_degree)

    def crossings(rod):
        inside = rod.t <= duration
        return downward_crossings(rod.t[inside], rod.tip_z[inside], sign)
    while True:
        rod = release(settings.rod_steps)
        if rod.t[-1] >= duration or periods == ROD_RUN_PERIODS:
            break
        periods = min(ROD_RUN_PERIODS, periods + math.ceil((duration - rod.t[-1]) / rod.period))
    if rod.t[-1] < duration:
        raise BadInput(f"--duration: the rod covered {rod.t[-1]:.4g} s in {ROD_RUN_PERIODS} "
                       f"periods; give at most that")
    count = int(math.ceil(duration / T1 * run.samples_per_period)) + 1
    t = np.linspace(0.0, duration, count)
    tip_truth = CubicSpline(rod.t, rod.tip_z)(t)
    rod_cross = crossings(rod)
    T_rod = _mean_period(rod_cross)
    resolution = half = None
    if settings.rod_check:
        # the same release at half the steps: the change of the period compared (the mean over
        # the run's crossings) is the resolution of the comparison
        half = release(max(16, settings.rod_steps // 2))
        T_half = _mean_period(crossings(half)) if half.t[-1] >= duration else math.nan
        if math.isfinite(T_half) and math.isfinite(T_rod):
            resolution = abs(T_half / T_rod - 1)

    n = chain.n
    y0 = np.concatenate([th0, np.zeros(n)])
    omega0 = chain.linear_frequencies(np.zeros(n))
    scale = float(np.abs(th0).max())
    atol = np.concatenate([np.full(n, run.rtol * scale), np.full(n, run.rtol * scale * omega0[-1])])

    def crossing(_, y):
        return sign * chain.tip(y[:n])[1]
    crossing.direction = -1
    sol, ode_s = chain.integrate(y0, duration, t, run.rtol, atol, events=crossing)
    theta = sol.y[:n].T
    chain_cross = sol.t_events[0]
    e0 = chain.energy(y0[:n], y0[n:])
    return {
        "t": t, "tip_prbdm": chain.tip(theta)[1], "tip_truth": tip_truth, "theta": theta,
        "period_prbdm": _mean_period(chain_cross), "period_truth": T_rod,
        "resolution": resolution,
        "crossings": {"prbdm": int(len(chain_cross)), "truth": int(len(rod_cross))},
        "release": {"tip_deflection": float(D),
                    "prbdm": {"tip_angle": float(np.sum(th0)), "force_N": float(sign * P)},
                    "truth": {"tip_angle": eq.tip_angle, "force_N": float(eq.force[1]),
                              "tip_z_discretised": float(rod.tip_z[0])}},
        "truth": {"model": "geometrically exact rod (prbdm.truth.rod.rod_response): the panel "
                           "as an inextensible strip, released from rest in its static shape "
                           "under a tip force",
                  "periods_run": int(periods), "linear_period_s": rod.linear_period,
                  "energy_drift": rod.energy_drift, "mesh": rod.mesh,
                  "time_s": rod.time_s + (half.time_s if half is not None else 0.0)},
        "nfev": int(sol.nfev), "ode_s": ode_s,
        "energy_drift": abs(chain.energy(theta[-1], sol.y[n:, -1]) - e0) / e0,
    }
