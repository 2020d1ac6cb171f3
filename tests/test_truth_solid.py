"""The 3-D elasticity check of the plate truth (prbdm.truth.solid): a slender cantilever against
Euler-Bernoulli, the clamp and the symmetry plane, material scaling, and (slow) the thin plate."""
import math

import numpy as np
import pytest

from prbdm.geometry import Beam, Material
from prbdm.truth import bending_frequencies
from prbdm.truth.solid import solid_mesh, solve_solid

# a slender uniform cantilever of square section (t = 2 w = 0.02 L): Euler-Bernoulli with E (no
# plate stiffening: the section is as wide as it is thick), Timoshenko corrections of order
# (a_n t / L)^2 / 12 < 0.1 % for the first three modes
SLENDER = Beam(x=[0, 1], half_width=[0.01, 0.01], thickness=0.02, name="slender")


@pytest.fixture(scope="module")
def slender():
    return solve_solid(SLENDER, 3, level=0)


def test_slender_cantilever_matches_euler_bernoulli(slender):
    eb = bending_frequencies(SLENDER, "analytic", 3).freq_hz
    rel = slender["freq_hz"] / eb - 1
    # within 1 % (measured +0.09, +0.06, +0.03 % at level 0: the coarse mesh's own error and the
    # clamp's restraint of the Poisson contraction outweigh shear and rotary inertia here)
    assert np.all(np.abs(rel) < 0.01), rel


def test_first_mode_effective_mass_is_the_cantilevers(slender):
    # uniform cantilever: the first mode carries 61.3 % of the mass, the second 18.8 %
    # (4 / a_n^2 times the mode-shape constants); the clamp holds the body (no rigid mode with
    # participation 1), and each kept mode moves with its sections
    assert slender["participation"][0] == pytest.approx(0.613, abs=0.005)
    assert slender["participation"][1] == pytest.approx(0.188, abs=0.005)
    assert np.all(slender["section_fraction"] > 0.9)


def test_mesh_is_the_planform_clamped_and_symmetric():
    b = Beam(x=[0, 0.3, 1.0], half_width=[0.4, 0.05, 0.2], thickness=0.03)
    mesh, info = solid_mesh(b, 0)
    p = mesh.p
    # every station is a node line, the free edge follows the half-width, the panel spans
    # [0, 1] x [0, w(x)] x [-t/2, t/2] in units of L
    assert np.isclose(p[0], 0.3).any()
    top = p[1] >= np.interp(p[0], b.x, b.half_width) - 1e-12
    assert np.allclose(p[1][top], np.interp(p[0][top], b.x, b.half_width))
    assert p[1].min() == 0.0 and np.isclose(p[2].max(), 0.015) and p[0].max() == 1.0
    assert info["thickness_elements"] >= 2


def test_material_scaling():
    # the nondimensional eigenvalues do not depend on E, rho or L; frequencies scale with
    # sqrt(E / rho) / L
    rubber = Beam(x=[0, 2], half_width=[0.02, 0.02], thickness=0.04,
                  material=Material(E=5e6, rho=1100, nu=0.28))
    a = solve_solid(SLENDER, 2, level=0)
    b = solve_solid(rubber, 2, level=0)
    assert np.allclose(a["lam"], b["lam"], rtol=1e-9)
    ratio = math.sqrt(5e6 / 1100 / (205e9 / 7850)) / 2
    assert np.allclose(b["freq_hz"], a["freq_hz"] * ratio, rtol=1e-9)


@pytest.mark.slow
def test_thin_square_plate_agrees_with_kirchhoff():
    # t/L = 0.01: shear and rotary inertia are small, the plate truth and 3-D agree to 0.2 %
    b = Beam(x=[0, 1], half_width=[0.5, 0.5], thickness=0.01)
    plate = bending_frequencies(b, "plate", 3).freq_hz
    solid = solve_solid(b, 3, level=0)["freq_hz"]
    assert np.allclose(solid, plate, rtol=2e-3)
