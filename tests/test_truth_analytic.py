"""Analytic truth: the uniform cantilever, cos(a) cosh(a) = -1 (docs/conventions.md §2, paper Eqs. 18-20)."""
import math
import subprocess
import sys

import numpy as np
import pytest

from prbdm.errors import BadInput
from prbdm.geometry import Beam, Material
from prbdm.truth import bending_frequencies
from prbdm.truth.analytic import cantilever_roots

# Published roots of cos(a) cosh(a) = -1 (e.g. Blevins, Formulas for Natural Frequency and Mode
# Shape, Table 8-1; Timoshenko): 1.87510407, 4.69409113, 7.85475744, 10.99554073, 14.13716839
PUBLISHED_ROOTS = [1.87510407, 4.69409113, 7.85475744, 10.99554073, 14.13716839]
# effective (transverse) mass fractions of a uniform cantilever's modes (Blevins; Chopra):
# 0.6131, 0.1883, 0.0647, 0.0331, 0.0200
PUBLISHED_MASS_FRACTIONS = [0.6131, 0.1883, 0.0647, 0.0331, 0.0200]

PAPER_UNIFORM = Beam(x=[0.0, 1.0], half_width=[0.1812, 0.1812], thickness=0.040532,
                     name="paper Table 2 uniform beam")


def test_roots_match_published_values():
    roots = cantilever_roots(5)
    np.testing.assert_allclose(roots, PUBLISHED_ROOTS, atol=1e-8)


def test_roots_solve_the_characteristic_equation_and_approach_the_asymptote():
    roots = cantilever_roots(40)
    # cos a cosh a + 1 = 0, scaled by cosh a so that it stays O(1)
    assert np.all(np.abs(np.cos(roots) + 1 / np.cosh(roots)) < 1e-13)
    n = np.arange(1, 41)
    assert np.all(np.diff(roots) > 0)
    np.testing.assert_allclose(roots[5:], (2 * n[5:] - 1) * math.pi / 2, atol=1e-6)


def test_omega_is_the_textbook_formula():
    b = PAPER_UNIFORM
    res = bending_frequencies(b, "analytic", modes=3)
    E, rho = b.material.E, b.material.rho
    width, t, L = 2 * 0.1812, b.thickness, b.length
    I, A = width * t ** 3 / 12, width * t
    expected = np.array(PUBLISHED_ROOTS[:3]) ** 2 * math.sqrt(E * I / (rho * A * L ** 4))
    np.testing.assert_allclose(res.omega, expected, rtol=1e-8)
    np.testing.assert_allclose(res.freq_hz, res.omega / (2 * math.pi))
    assert res.model == "analytic" and res.omega.dtype == np.float64 and res.time_s >= 0


def test_participations_are_the_effective_mass_fractions():
    res = bending_frequencies(PAPER_UNIFORM, "analytic", modes=5)
    part = [m["participation"] for m in res.all_modes]
    np.testing.assert_allclose(part, PUBLISHED_MASS_FRACTIONS, atol=1e-4)
    assert all(m["kept"] and m["symmetry"] == "symmetric" for m in res.all_modes)


def test_analytic_refuses_a_non_uniform_beam():
    taper = Beam(x=[0, 1], half_width=[0.2, 0.1], thickness=0.01)
    with pytest.raises(BadInput, match="analytic.*uniform"):
        bending_frequencies(taper, "analytic")


@pytest.mark.parametrize("modes", [0, -1, 2.5, True, "3", 10 ** 6])
def test_invalid_modes_are_bad_input(modes):
    with pytest.raises(BadInput, match="modes"):
        bending_frequencies(PAPER_UNIFORM, "analytic", modes=modes)


def test_unknown_model_is_bad_input():
    with pytest.raises(BadInput, match="model"):
        bending_frequencies(PAPER_UNIFORM, "shell")


def test_materials_scale_out():
    """Rubber and steel of the same shape: the same nondimensional eigenvalues."""
    rubber = Beam(x=[0, 2.0], half_width=[0.05, 0.05], thickness=0.002,
                  material=Material(E=5e6, rho=1100, nu=0.49))
    a = bending_frequencies(rubber, "analytic", modes=4)
    b = bending_frequencies(PAPER_UNIFORM, "analytic", modes=4)
    np.testing.assert_allclose(a.lam, b.lam, rtol=1e-12)
    np.testing.assert_allclose(a.lam, np.array(PUBLISHED_ROOTS[:4]) ** 4, rtol=1e-7)


def test_to_dict_has_the_spec_keys():
    d = bending_frequencies(PAPER_UNIFORM, "analytic", modes=2).to_dict()
    assert {"model", "omega", "freq_hz", "time_s"} <= set(d)
    assert len(d["omega"]) == 2 and "all_modes" not in d
    d = bending_frequencies(PAPER_UNIFORM, "analytic", modes=2).to_dict(all_modes=True)
    assert [m["participation"] for m in d["all_modes"]] == pytest.approx(
        PUBLISHED_MASS_FRACTIONS[:2], abs=1e-4)


def test_truth_does_not_import_torch():
    code = "import prbdm.truth, sys; assert 'torch' not in sys.modules"
    subprocess.run([sys.executable, "-c", code], check=True)
    code = ("import sys; from prbdm.truth import bending_frequencies; from prbdm.geometry import "
            "random_beam; b = random_beam(0, 0); bending_frequencies(b, 'beam'); "
            "bending_frequencies(b, 'plate', modes=2); "
            "assert 'torch' not in sys.modules and 'matplotlib' not in sys.modules")
    subprocess.run([sys.executable, "-c", code], check=True)
