"""Classical PRBMs (Howell 1R, Su 3R) in prbdm's chain, against hand formulas and quadrature."""
import math

import numpy as np
import pytest
import scipy.linalg
from scipy.integrate import quad

from prbdm import BadInput, Beam, random_beam
from prbdm import classical as cl

# cantilever eigenvalue roots of cos a cosh a = -1 (Euler-Bernoulli), a_n^2
EB = [1.8751040687119611 ** 2, 4.6940911329741745 ** 2, 7.8547574382376126 ** 2]


def uniform():
    return Beam(x=[0.0, 1.3], half_width=[0.1, 0.1], thickness=0.02)


def tapered():
    return Beam(x=[0.0, 0.8], half_width=[0.2, 0.05], thickness=0.015)


def scale(beam):
    """sqrt(EI / (rho A L^4)) of a uniform beam."""
    b, t, L, m = 2 * beam.half_width[0], beam.thickness, beam.length, beam.material
    return math.sqrt(m.E * b * t ** 3 / 12 / (m.rho * b * t * L ** 4))


def rod_chain(gamma, coeffs):
    """Independent small-vibration model of a uniform rod cut into rigid links at the joints:
    M_kl = ∫_{x > max(p_k, p_l)} (x - p_k)(x - p_l) dx (units rho A L^3), K = diag(c) (EI/L)."""
    p = np.cumsum(gamma)[:-1]
    n = len(p)
    M = np.array([[quad(lambda x: (x - p[k]) * (x - p[l]), max(p[k], p[l]), 1.0)[0]
                   for l in range(n)] for k in range(n)])
    return np.sqrt(scipy.linalg.eigh(np.diag(coeffs), M, eigvals_only=True))


def test_howell_uniform_first_frequency_hand_formula():
    # one rigid link gamma L about the pivot: omega^2 = gamma K_Theta (EI/L) / (rho A (gamma L)^3/3)
    beam = uniform()
    omega = np.sqrt(cl.eigenvalues(beam, cl.HOWELL_1R, poses="paper").numpy())
    expected = math.sqrt(3 * 2.65 / 0.85 ** 2) * scale(beam)       # 3.3171 sqrt(EI/(m L^4))
    assert omega.shape == (30, 1)                                   # n = 1: 30 paper poses
    np.testing.assert_allclose(omega, expected, rtol=1e-10)          # M does not depend on theta_1
    # honest distance from Euler-Bernoulli's 3.5160: 5.7 % low
    assert omega[0, 0] / (EB[0] * scale(beam)) - 1 == pytest.approx(-0.0566, abs=5e-4)


def test_howell_static_tip_relation():
    # small deflection: delta = gamma L Theta, K Theta = F gamma L  ->  delta = gamma F L^3 / (K_Theta EI)
    beam = uniform()
    EI = beam.material.E * 2 * 0.1 * 0.02 ** 3 / 12
    K = cl.joint_stiffness(beam, cl.HOWELL_1R)
    assert K[0] == pytest.approx(0.85 * 2.65 * EI / beam.length, rel=1e-12)
    c = cl.tip_compliance(beam, cl.HOWELL_1R) * EI / beam.length ** 3
    assert c == pytest.approx(0.85 / 2.65, rel=1e-12)
    assert c * 3 - 1 == pytest.approx(-0.0377, abs=5e-4)            # 3.8 % stiffer than L^3/(3EI)


def test_su_uniform_against_independent_rod_chain_and_euler_bernoulli():
    beam = uniform()
    omega = np.sqrt(cl.eigenvalues(beam, cl.SU_3R, poses="linear").numpy()[0]) / scale(beam)
    ref = rod_chain([0.10, 0.35, 0.40, 0.15], [3.51, 2.99, 2.58])
    np.testing.assert_allclose(omega, ref, rtol=1e-9)
    # the honest numbers against Euler-Bernoulli: mode 1 -3.0 %, mode 2 +1.3 %, mode 3 +21 %
    err = omega / np.array(EB) - 1
    np.testing.assert_allclose(err, [-0.0303, 0.0128, 0.2067], atol=5e-4)
    assert abs(err[0]) < 0.035


def test_su_static_tip_compliance():
    beam = uniform()
    EI = beam.material.E * 2 * 0.1 * 0.02 ** 3 / 12
    c = cl.tip_compliance(beam, cl.SU_3R) * EI / beam.length ** 3
    assert c == pytest.approx(0.81 / 3.51 + 0.55 ** 2 / 2.99 + 0.15 ** 2 / 2.58, rel=1e-12)
    assert c * 3 - 1 == pytest.approx(0.022, abs=1e-3)


def test_ei_choices_coincide_on_uniform_beam():
    beam = uniform()
    for model in cl.CLASSICAL.values():
        vals = [cl.joint_ei(beam, model, ei) for ei in cl.EI_CHOICES]
        for v in vals[1:]:
            np.testing.assert_allclose(v, vals[0], rtol=1e-12)


def test_ei_choices_on_tapered_beam_against_quadrature():
    beam = tapered()
    E, t, L = beam.material.E, beam.thickness, beam.length

    def EI(x):
        return E * 2 * np.interp(x, beam.x, beam.half_width) * t ** 3 / 12
    tip = L ** 3 / (3 * quad(lambda x: (L - x) ** 2 / EI(x), 0, L, epsrel=1e-13)[0])
    harm = L / quad(lambda x: 1 / EI(x), 0, L, epsrel=1e-13)[0]
    np.testing.assert_allclose(cl.joint_ei(beam, cl.SU_3R, "tip"), tip, rtol=1e-11)
    np.testing.assert_allclose(cl.joint_ei(beam, cl.SU_3R, "harmonic"), harm, rtol=1e-11)
    np.testing.assert_allclose(cl.joint_ei(beam, cl.SU_3R, "joint"),
                               EI(L * np.array([0.10, 0.45, 0.85])), rtol=1e-12)
    # the tip-equivalent EI makes the 1R model's tip compliance the real beam's times 3 gamma/K_Theta
    exact = quad(lambda x: (L - x) ** 2 / EI(x), 0, L, epsrel=1e-13)[0]
    assert cl.tip_compliance(beam, cl.HOWELL_1R) == pytest.approx(exact * 3 * 0.85 / 2.65, rel=1e-11)


def test_howell_tapered_frequency_hand_formula():
    # omega^2 = K / (rotary inertia of the beam beyond the pivot about the pivot), by quadrature
    beam = tapered()
    L, t, rho = beam.length, beam.thickness, beam.material.rho
    x1 = 0.15 * L
    J = quad(lambda x: rho * t * 2 * np.interp(x, beam.x, beam.half_width) * (x - x1) ** 2,
             x1, L, epsrel=1e-13)[0]
    K = cl.joint_stiffness(beam, cl.HOWELL_1R)[0]
    lam = cl.eigenvalues(beam, cl.HOWELL_1R, poses="linear").numpy()
    assert lam[0, 0] == pytest.approx(K / J, rel=1e-10)


@pytest.mark.parametrize("p", [0, 1, 2])
def test_weighted_compliance_exact(p):
    # strong taper, a near-zero waist (closed form) and nearly equal widths (series branch)
    x = np.array([0.0, 0.2, 0.21, 0.5, 0.5001, 1.0])
    w = np.array([0.3, 0.3003, 0.0004, 0.2, 0.2000001, 0.05])
    ref = sum(quad(lambda s: (1.0 - s) ** p / np.interp(s, x, w), a, b, epsrel=1e-13,
                   epsabs=0, limit=400)[0] for a, b in zip(x[:-1], x[1:]))
    assert cl.weighted_compliance(x, w, 1.0, p) == pytest.approx(ref, rel=1e-11)


def test_batched_equals_single_and_beam_law_scf():
    beams = [random_beam(3, i) for i in range(3)]
    lam = cl.eigenvalues(beams, cl.SU_3R).numpy()
    assert lam.shape == (3, 9, 3)
    for i, b in enumerate(beams):
        np.testing.assert_allclose(lam[i], cl.eigenvalues(b, cl.SU_3R).numpy(), rtol=1e-12)
    # uniform beam: the beam-law base stiffness is EI / (tributary span), spans from docs/conventions.md §3
    scf = cl.beam_law_scf(uniform(), cl.SU_3R)
    np.testing.assert_allclose(scf, [3.51 * 0.275, 2.99 * 0.375, 2.58 * 0.35], rtol=1e-12)


def test_bad_ei_choice():
    with pytest.raises(BadInput, match="ei"):
        cl.joint_ei(uniform(), cl.HOWELL_1R, "mean")
