"""The geometrically exact rod truth (prbdm.truth.rod) against independent references:
the elastica's closed form (Bisshopp & Drucker 1945), the analytic and Euler-Bernoulli beam truths
at rest, its own convergence, and (slow, optional) PyElastica's Cosserat rod."""
import json
import math

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.special import ellipe, ellipeinc, ellipk, ellipkinc

from prbdm.errors import BadInput
from prbdm.geometry import Beam, Material
from prbdm.truth import bending_frequencies
from prbdm.truth.rod import (
    MAX_LOAD,
    RestShape,
    arc_shape,
    chain_shape,
    rod_frequencies,
    rod_response,
    rod_static,
    sampled_shape,
)

UNIFORM = Beam(x=[0.0, 1.0], half_width=[0.02, 0.02], thickness=0.005)
TAPERED = Beam(x=[0.0, 0.35, 1.0], half_width=[0.05, 0.03, 0.01], thickness=0.004)
# the paper's Table-2 beam (SPEC §5)
TABLE2 = Beam(x=[0.0, 1.0], half_width=[0.1812, 0.1812], thickness=0.040532)
RUBBER = Beam(x=[0.0, 0.5, 0.3 + 0.5], half_width=[0.01, 0.004, 0.006], thickness=0.002,
              material=Material(E=5e6, rho=1100.0, nu=0.45))


def EI(beam):
    return beam.material.E * 2 * beam.half_width.max() * beam.thickness ** 3 / 12


def bisshopp_drucker(alpha):
    """Cantilever, perpendicular dead tip load, alpha = P L^2 / EI: tip angle phi0 and the
    horizontal and vertical tip displacements / L. sqrt(alpha) = K(k) - F(phi1, k),
    k^2 = (1 + sin phi0)/2, sin phi1 = 1/(sqrt(2) k); x_tip/L = sqrt(2 sin phi0 / alpha);
    z_tip/L = 1 - 2 (E(k) - E(phi1, k)) / sqrt(alpha)."""
    def f(phi0):
        m = (1 + math.sin(phi0)) / 2
        return ellipk(m) - ellipkinc(math.asin(1 / math.sqrt(2 * m)), m) - math.sqrt(alpha)
    phi0 = brentq(f, 1e-12, math.pi / 2 - 1e-13, xtol=1e-15)
    m = (1 + math.sin(phi0)) / 2
    phi1 = math.asin(1 / math.sqrt(2 * m))
    x = math.sqrt(2 * math.sin(phi0) / alpha)
    z = 1 - 2 * (ellipe(m) - ellipeinc(phi1, m)) / math.sqrt(alpha)
    return phi0, 1 - x, z


@pytest.mark.parametrize("alpha", [1.0, 2.0, 5.0, 10.0, 50.0])
def test_elastica_closed_form(alpha):
    phi0, dh, dv = bisshopp_drucker(alpha)
    eq = rod_static(UNIFORM, force=alpha * EI(UNIFORM))
    assert eq.tip_angle == pytest.approx(phi0, abs=1e-9)
    assert 1 - eq.tip_x == pytest.approx(dh, abs=1e-9)
    assert eq.tip_z == pytest.approx(dv, abs=1e-9)
    assert eq.stability > 0


def test_howell_table_alpha_1():
    # Howell, Compliant Mechanisms: alpha = 1 -> a/L ~ 0.3017 vertical, 0.0566 horizontal
    eq = rod_static(UNIFORM, force=EI(UNIFORM))
    assert eq.tip_z == pytest.approx(0.3017, abs=1e-4)
    assert 1 - eq.tip_x == pytest.approx(0.0564, abs=3e-4)


def test_load_for_tip_angle_and_moment():
    eq = rod_static(TAPERED, tip_angle=1.3)               # ~75 degrees by a perpendicular force
    assert eq.tip_angle == pytest.approx(1.3, abs=1e-10)
    again = rod_static(TAPERED, force=math.hypot(*eq.force))
    assert again.tip_z == pytest.approx(eq.tip_z, rel=1e-9)
    # a tip moment bends a uniform strip into a circular arc of radius EI/M
    eqm = rod_static(UNIFORM, tip_angle=2.0, load="moment")
    R = 1 / 2.0
    assert eqm.tip_x == pytest.approx(R * math.sin(2.0), abs=1e-10)
    assert eqm.tip_z == pytest.approx(R * (1 - math.cos(2.0)), abs=1e-10)
    assert eqm.moment == pytest.approx(2.0 * EI(UNIFORM), rel=1e-12)


def test_inclined_force_and_shape_arrays():
    eq = rod_static(TAPERED, force=3 * EI(TAPERED), force_angle=2.0)     # partly compressive
    assert eq.s[0] == 0 and eq.s[-1] == pytest.approx(TAPERED.length)
    assert eq.theta[0] == 0
    assert eq.x[-1] == pytest.approx(eq.tip_x) and eq.z[-1] == pytest.approx(eq.tip_z)
    # arc length: |r'| = 1
    ds = np.hypot(np.diff(eq.x), np.diff(eq.z))
    assert np.all(ds <= np.diff(eq.s) * (1 + 1e-9))


def test_refusals():
    with pytest.raises(BadInput, match="force"):
        rod_static(UNIFORM, force=2 * MAX_LOAD * EI(UNIFORM))
    with pytest.raises(BadInput, match="tip_angle"):
        rod_static(UNIFORM, tip_angle=1.5707)             # needs P L^2/EI far beyond the limit
    with pytest.raises(BadInput, match="tip_angle"):
        rod_static(UNIFORM, tip_angle=-0.5)               # the force bends towards +z
    with pytest.raises(BadInput, match="load"):
        rod_static(UNIFORM, force=1.0, moment=1.0)
    with pytest.raises(BadInput, match="limit or bifurcation"):
        # an axial compressive end load beyond Euler's critical load pi^2/4 EI/L^2
        rod_static(UNIFORM, force=4 * EI(UNIFORM), force_angle=math.pi)
    # slightly off axis the path has no bifurcation: the stable post-buckled shape
    eq = rod_static(UNIFORM, force=4 * EI(UNIFORM), force_angle=math.pi - 1e-4)
    assert eq.stability > 0 and eq.tip_angle > math.pi / 2
    with pytest.raises(BadInput, match="modes"):
        rod_frequencies(UNIFORM, modes=0)
    with pytest.raises(BadInput, match="about"):
        rod_frequencies(UNIFORM, about=RestShape(theta=lambda s: 0.1 + 0 * s))


@pytest.mark.parametrize("beam", [UNIFORM, TAPERED, RUBBER], ids=["uniform", "tapered", "rubber"])
def test_straight_against_beam_truth(beam):
    rod = rod_frequencies(beam, modes=4)
    ref = bending_frequencies(beam, model="beam", modes=4)
    assert np.allclose(rod.omega, ref.omega, rtol=1e-4)
    if beam is UNIFORM:
        ana = bending_frequencies(beam, model="analytic", modes=4)
        assert np.allclose(rod.omega, ana.omega, rtol=1e-10)


def test_rotary_inertia_lowers_frequencies_slightly():
    plain = rod_frequencies(TABLE2, modes=3)
    rot = rod_frequencies(TABLE2, modes=3, rotary=True)
    drop = 1 - rot.omega / plain.omega
    assert np.all(drop > 0) and np.all(np.diff(drop) > 0) and drop[-1] < 0.05


def test_stress_free_arc_equals_moment_equilibrium_and_spec_numbers():
    # a dead end moment adds no load stiffness: the uniform strip it bends has the frequencies
    # of the same stress-free arc; SPEC §3 quotes +4/-16/-7/-4 % on modes 1-4 at 1.4 rad
    arc = rod_frequencies(TABLE2, about=arc_shape(TABLE2, 1.4), modes=4)
    eqm = rod_frequencies(TABLE2, about=rod_static(TABLE2, tip_angle=1.4, load="moment"),
                          modes=4)
    straight = rod_frequencies(TABLE2, modes=4)
    assert np.allclose(arc.omega, eqm.omega, rtol=1e-9)
    change = np.round(100 * (arc.omega / straight.omega - 1))
    assert change.tolist() == [4, -16, -7, -4]


def test_load_stiffness_raises_first_frequency():
    eq = rod_static(UNIFORM, tip_angle=1.0)
    loaded = rod_frequencies(UNIFORM, about=eq, modes=3)
    free = rod_frequencies(UNIFORM, about=sampled_shape(eq.s, eq.theta), modes=3)
    assert loaded.about == "equilibrium" and free.about == "stress-free"
    assert loaded.omega[0] > free.omega[0]


@pytest.mark.parametrize("about", ["equilibrium", "chain"])
def test_convergence_about_bent_shapes(about):
    beam = TAPERED
    shape = (rod_static(beam, tip_angle=1.2) if about == "equilibrium"
             else chain_shape(beam, [0.125, 0.25, 0.25, 0.25, 0.125], 0.3))
    lo = rod_frequencies(beam, about=shape, modes=4, elements=6, degree=4).omega
    mid = rod_frequencies(beam, about=shape, modes=4).omega
    hi = rod_frequencies(beam, about=shape, modes=4, elements=24, degree=6).omega
    assert np.max(np.abs(hi / mid - 1)) < 1e-8
    assert np.max(np.abs(lo / hi - 1)) < 1e-4


def _linear_first_crossing_period(beam, elements=6, degree=4):
    """The small-amplitude reference: modal superposition of the straight rod released from
    its linear static tip-load deflection; the time between the first two downward crossings
    of the tip through z = 0 (the higher modes move it away from 2 pi / omega_1)."""
    from scipy.linalg import eigh

    from prbdm.truth.rod import _model, _scaled
    sc = _scaled(beam)
    m = _model(sc, None, False, elements, degree)
    M = m.mass(np.zeros(m.n))
    lam, V = eigh(m.K, M)
    q0 = np.linalg.solve(m.K, m.load(np.zeros(m.n), np.array([0.0, 1.0]), 0.0)[0])
    tip = m.jacobian(m.theta(np.zeros(m.n)))[1][1]        # d z_tip / d q at rest
    amp = (V.T @ M @ q0) * (tip @ V)

    def z(t):
        return np.cos(np.sqrt(lam) * t) @ amp
    T1 = 2 * np.pi / np.sqrt(lam[0])
    t = np.linspace(0, 2.5 * T1, 20001)
    zz = np.array([z(x) for x in t])
    i = np.nonzero((zz[:-1] > 0) & (zz[1:] <= 0))[0][:2]
    c = [brentq(z, t[k], t[k + 1], xtol=1e-15) for k in i]
    return (c[1] - c[0]) * sc.time


def test_response_energy_and_period():
    r = rod_response(UNIFORM, 0.8, periods=1, steps=256)
    assert r.energy_drift < 1e-4
    assert r.tip_z[0] == pytest.approx(r.equilibrium.tip_z, rel=1e-6)
    assert r.period_error < 2e-3
    # a small release is linear: the modal superposition's crossing period
    # (the midpoint rule aliases the discretisation's highest modes: the crossing times converge
    # to ~1e-4, not monotonically: -3e-5 at 1024 steps, +1.1e-4 at 2048, +4e-5 at 4096)
    small = rod_response(UNIFORM, 0.005, periods=1, steps=1024, check=False)
    assert small.period == pytest.approx(_linear_first_crossing_period(UNIFORM), rel=3e-4)
    # at 0.8 rad the nonlinearity shortens it measurably
    assert r.period < small.period * (1 - 5e-3)


@pytest.mark.slow
def test_response_midpoint_against_dop853():
    a = rod_response(UNIFORM, 0.8, periods=1, elements=3, degree=2, method="DOP853",
                     rtol=1e-9)
    b = rod_response(UNIFORM, 0.8, periods=1, elements=3, degree=2, steps=2048)
    assert b.period == pytest.approx(a.period, rel=1e-4)


@pytest.mark.slow
def test_against_pyelastica():
    pytest.importorskip("elastica")
    import importlib.util
    import pathlib
    path = pathlib.Path(__file__).resolve().parents[1] / "benchmarks" / "rod_vs_pyelastica.py"
    spec = importlib.util.spec_from_file_location("rod_vs_pyelastica", path)
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    beam = bench.STRIPS["uniform"]
    ref = rod_response(beam, 0.8, periods=1, rotary=True)
    per = []
    for n in (50, 100):
        ts, tx, tz, _, _ = bench.pyelastica_release(beam, ref.equilibrium, n, ref.t[-1] * 1.02)
        per.append(np.diff(bench.downward_crossings(ts, tz))[0])
    extrapolated = 2 * per[1] - per[0]          # first order in the element length
    assert extrapolated == pytest.approx(ref.period, rel=1e-3)


def test_a_jagged_planform_is_resolved_at_rest():
    """The paper's random_beam(0, 1), its width 20 times smaller within 0.013 L: the element
    grading by width (prbdm.truth._rod_dynamics.WIDTH_STEP) keeps the rod at rest within 1e-5 of
    a fine beam FEM (with 12 ungraded elements mode 1 was 7e-4 off)."""
    from prbdm.geometry import random_beam
    from prbdm.truth import bending_frequencies
    from prbdm.truth.rod import rod_frequencies

    beam = random_beam(0, 1)
    rod = rod_frequencies(beam, modes=4, degree=4).omega
    fem = bending_frequencies(beam, "beam", modes=4, elements=400).omega
    np.testing.assert_allclose(rod, fem, rtol=1e-5)


def test_matrix_free_dynamics_equal_the_formed_matrices():
    """The midpoint residual, velocities and energy are evaluated without forming J or M(q);
    they must equal the formed ones (J from the Jacobian, M = int rhoA J^T J + rotary)."""
    from prbdm.geometry import random_beam
    from prbdm.truth.rod import _model, _scaled

    m = _model(_scaled(random_beam(0, 3)), None, True, 4, 4)
    rng = np.random.default_rng(0)
    q, v, u = 0.05 * rng.normal(size=m.n), rng.normal(size=m.n), 1e-3 * rng.normal(size=m.n)
    th = m.theta(q)
    J, J_tip = m.jacobian(th)
    rd, tip = m.velocities(th, v)
    np.testing.assert_allclose(rd, np.einsum("gdn,n->gd", J, v), atol=1e-14)
    np.testing.assert_allclose(tip, J_tip @ v, atol=1e-14)
    y = rng.normal(size=(m.s.size, 2))
    np.testing.assert_allclose(m._jt(th, y), np.einsum("gdn,gd->n", J, y), rtol=1e-12, atol=1e-12)
    h = 0.01
    M, f = m.forces(q + 0.5 * u, u / h)
    ref = M @ (2 * u / h - 2 * v) - h * f
    np.testing.assert_allclose(m._midpoint_residual(q, v, u, h), ref,
                               atol=1e-12 * np.abs(ref).max())
    M0, _ = m.forces(q, v)
    assert m.energy(q, v) == pytest.approx(0.5 * v @ M0 @ v + 0.5 * q @ m.K @ q, rel=1e-13)


def test_a_jagged_planform_is_released():
    """random_beam(0, 1): its mass matrix spans ~20 decades (width 20 times smaller within
    0.013 L), where rounding sets a floor on the Newton update of the midpoint rule; the release
    converges (it used to stop with 'did not converge' at 512 and 1024 steps), conserves energy
    and its period moves by less than 1e-3 when the steps are halved."""
    from prbdm.geometry import random_beam

    r = rod_response(random_beam(0, 1), math.radians(10), periods=1, steps=256, degree=4,
                     elements=4)
    assert r.energy_drift < 1e-4
    assert r.period_error < 1e-3


def test_a_step_that_does_not_converge_is_taken_in_halves(monkeypatch):
    """rod._advance: where the midpoint iteration of a step fails, two steps of half the length
    are taken (counted), with the same result as two half steps; past MAX_HALVINGS it fails."""
    from prbdm.truth import rod as rod_mod
    from prbdm.truth.rod import _model, _scaled

    m = _model(_scaled(UNIFORM), None, False, 4, 4)
    q0 = 0.1 * np.linspace(0, 1, m.n)
    v0 = np.zeros(m.n)
    h = 0.05
    qa, va = m.midpoint_step(*m.midpoint_step(q0, v0, h / 2), h / 2)
    real = rod_mod.RodGalerkin.midpoint_step

    def refuse_full(self, q, v, step, **kw):
        if step > 0.75 * h:
            raise ArithmeticError("no")
        return real(self, q, v, step, **kw)
    monkeypatch.setattr(rod_mod.RodGalerkin, "midpoint_step", refuse_full)
    (_, qh, vh), (_, qb, vb) = rod_mod._advance(m, q0, v0, h)
    np.testing.assert_allclose(qb, qa, atol=1e-12)
    np.testing.assert_allclose(vb, va, atol=1e-10)
    assert m.halvings == 1
    steps = rod_mod._advance(m, q0, v0, h)
    assert [dt for dt, _, _ in steps] == [h / 2, h / 2] and m.halvings == 2
    monkeypatch.setattr(rod_mod.RodGalerkin, "midpoint_step",
                        lambda self, q, v, step, **kw: (_ for _ in ()).throw(ArithmeticError()))
    m.halvings = 0
    with pytest.raises(ArithmeticError):
        rod_mod._advance(m, q0, v0, h)
    assert m.halvings == rod_mod.MAX_HALVINGS       # the recursion stops there


def test_a_diverging_step_fails_as_not_converged():
    """A midpoint iteration that diverges to inf/NaN raises ArithmeticError (which rod._advance
    halves and rod_response reports as BadInput), not the ValueError of the linear solve."""
    from prbdm.geometry import random_beam
    from prbdm.truth.rod import _model, _scaled

    m = _model(_scaled(random_beam(0, 1)), None, False, 4, 4)
    rng = np.random.default_rng(1)
    q0, v0 = 2 * rng.normal(size=m.n), 50 * rng.normal(size=m.n)
    with np.errstate(all="ignore"), pytest.raises(ArithmeticError):
        m.midpoint_step(q0, v0, 0.1)


def test_the_truth_command_gives_the_rod_at_rest_bent_and_loaded(run, beam_file):
    path = beam_file({"x": [0, 1], "half_width": [0.02, 0.01], "thickness": 0.005})
    rc, out, err = run("truth", path, "--model", "rod", "--modes", 4, "--json")
    assert rc == 0, err
    rod = json.loads(out)
    rc, out, err = run("truth", path, "--model", "beam", "--modes", 4, "--json")
    np.testing.assert_allclose(rod["omega"], json.loads(out)["omega"], rtol=1e-5)
    rc, out, err = run("truth", path, "--model", "rod", "--modes", 4, "--tip-angle", 1.0,
                       "--json")
    loaded = json.loads(out)
    assert rc == 0 and loaded["about"] == "equilibrium"
    assert loaded["omega"][0] > 1.2 * rod["omega"][0]      # the tip force stiffens mode 1
    rc, out, err = run("truth", path, "--model", "rod", "--modes", 4, "--arc", 1.4, "--json")
    assert rc == 0 and json.loads(out)["about"] == "stress-free"
    for argv, words in ((["--tip-angle", 1.0], "--model rod only"),
                        (["--model", "rod", "--tip-angle", 1, "--arc", 1], "give one"),
                        (["--model", "rod", "--tip-angle", 9], "tip_angle")):
        rc, out, err = run("truth", path, *argv)
        assert rc == 2 and words in err and len(err.strip().splitlines()) == 1
