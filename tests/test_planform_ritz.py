"""The plate estimate by Rayleigh-Ritz on the planform (prbdm.truth.planform_ritz), checked
against the mesh-free Kirchhoff reference and the Mindlin FEM."""
import json
import os
import subprocess
import sys

import numpy as np
import pytest

from prbdm.chain import BeamBatch
from prbdm.geometry import Beam, Material
from prbdm.surrogate.features import FeatureSpec, feature_names, features, ritz_log_omega
from prbdm.truth import bending_frequencies
from prbdm.truth.modes import bending_spectrum
from prbdm.truth.planform_ritz import planform_ritz, ritz_bending_spectrum
from prbdm.truth.ritz_plate import ritz_cantilever_plate

FINE = dict(degree=4, chord_terms=5, max_element=0.1)


def _fem_symmetric(beam, count=6):
    res = bending_frequencies(beam, "mindlin", 4)
    sym = [m for m in res.all_modes if m.get("symmetry", "symmetric") == "symmetric"][:count]
    return (np.array([m["lambda"] for m in sym]), np.array([m["section_fraction"] for m in sym]))


def test_thin_square_plate_is_the_kirchhoff_reference():
    # t/L = 0.002: the Mindlin energy at its thin limit (no locking with cubic-quartic span
    # functions), against the Legendre Ritz of a rectangle (prbdm.truth.ritz_plate)
    lam, frac = planform_ritz([0.0, 1.0], [0.5, 0.5], 0.002, 0.3, **FINE)
    ref = ritz_cantilever_plate(1.0, 0.3, 16, 16, "symmetric")[:6]
    np.testing.assert_allclose(np.sqrt(lam[:6]), ref, rtol=3e-4)
    # the first chord-wise mode (third symmetric) moves its sections little
    assert frac[0] > 0.999 and frac[2] < 0.1 and frac[4] > 0.95


def test_tapered_thick_panel_matches_the_mindlin_fem():
    beam = Beam(x=[0, 0.4, 1], half_width=[0.3, 0.15, 0.06], thickness=0.05)
    lam_f, frac_f = _fem_symmetric(beam)
    lam, frac = planform_ritz(beam.x, beam.half_width, 0.05, beam.material.nu, **FINE)
    # measured 2e-5 on modes 1-4, 1.4e-4 on 5-6; section fractions within 1e-3
    np.testing.assert_allclose(lam[:6], lam_f, rtol=5e-4)
    np.testing.assert_allclose(frac[:6], frac_f, atol=3e-3)
    assert np.all(lam[:6] >= lam_f * (1 - 1e-5))          # Ritz values bound from above


def test_a_neck_converges_slowly_and_from_above():
    # a neck 0.02 L wide beside chords of 0.2 and 0.4 L: the default basis is several per cent
    # stiff on mode 1 (what the networks correct), a richer one comes closer
    beam = Beam(x=[0, 0.3, 0.5, 1], half_width=[0.2, 0.02, 0.4, 0.3], thickness=0.02)
    lam_f, _ = _fem_symmetric(beam, 4)
    coarse, _ = planform_ritz(beam.x, beam.half_width, 0.02, beam.material.nu)
    fine, _ = planform_ritz(beam.x, beam.half_width, 0.02, beam.material.nu, **FINE)
    e_coarse, e_fine = coarse[:4] / lam_f - 1, fine[:4] / lam_f - 1
    assert np.all(e_fine > -1e-5) and np.all(e_fine < e_coarse)
    assert e_coarse[0] < 0.15 and e_fine[0] < 0.03          # measured 8.5 % and 1.6 %


def test_spectrum_of_the_estimate():
    lam, frac = planform_ritz([0.0, 1.0], [0.5, 0.5], 0.01, 0.3)
    spec = ritz_bending_spectrum([0.0, 1.0], [0.5, 0.5], 0.01, 0.3, 4)
    use = len(lam) // 3
    np.testing.assert_array_equal(spec, bending_spectrum(lam[:use], frac[:use], 4)[0])
    assert np.all(np.diff(spec) > 0)


def test_feature_is_scale_free_and_in_the_beam_units():
    # the same panel in metres and in millimetres, steel and rubber: the same feature
    x, w, t = [0.0, 0.5, 1.0], [0.2, 0.05, 0.3], 0.01
    steel = BeamBatch.from_arrays([x], [w], [t], Material(E=205e9, rho=7850.0, nu=0.3))
    rubber = BeamBatch.from_arrays([[1000 * v for v in x]], [[1000 * v for v in w]],
                                   [1000 * t], Material(E=5e6, rho=1100.0, nu=0.3))
    a, b = ritz_log_omega(steel, 4), ritz_log_omega(rubber, 4)
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-9)
    # omega / sqrt(E t^2 / (rho L^4)) = sqrt(lam / (12 (1 - nu^2)))
    lam = ritz_bending_spectrum(x, w, t, 0.3, 4)
    np.testing.assert_allclose(np.exp(a[0]), np.sqrt(lam / (12 * (1 - 0.09))), rtol=1e-12)


@pytest.mark.parametrize("spread", [False, True])
def test_a_ritz_network_corrects_the_ritz_columns(spread):
    spec = FeatureSpec(cells=4, rfe_segments=8, rfe_modes=3, truth="mindlin", spread=spread,
                       profile=5, ritz=True)
    names = feature_names(spec)
    assert names[spec.base_columns(3)] == [f"log_omega_ritz[{r}]" for r in range(3)]
    batch = BeamBatch.from_arrays([[0.0, 1.0]], [[0.1, 0.05]], [0.01], Material(nu=0.3))
    assert features(batch, spec).shape == (1, len(names))
    assert FeatureSpec(**spec.to_dict()) == spec
    rich = FeatureSpec(**{**spec.to_dict(), "ritz_basis": [4, 4]})
    assert rich.ritz_basis == (4, 4) and FeatureSpec(**rich.to_dict()) == rich
    assert not np.allclose(features(batch, rich), features(batch, spec))
    # the default basis spelled out is the default: the same features, cache and metadata
    assert FeatureSpec(**{**spec.to_dict(), "ritz_basis": [3, 3]}) == spec
    for bad in ([4], [4, 4, 4], ["a", "b"], [0, 3], [4, 9]):
        with pytest.raises(ValueError, match="two integers"):
            FeatureSpec(ritz_basis=bad)


def test_stations_a_sliver_apart_are_a_step():
    # a narrow panel of the data sets with two stations 5e-8 L apart (a step from 0.01 to 0.039
    # L): read as a sliver element, mode 1 came out 30 times too stiff
    x = [0.0, 0.0101, 0.4379, 0.5285, 0.6471, 0.7672, 0.8158, 0.8158 + 5e-8, 0.8202, 0.8461,
         0.8872, 1.0]
    w = [0.024, 0.0145, 0.017, 0.0398, 0.01, 0.0132, 0.01, 0.0392, 0.0352, 0.01, 0.0122, 0.01]
    sliver, _ = planform_ritz(x, w, 0.0325, 0.28)
    x[7] = x[6]
    step, _ = planform_ritz(x, w, 0.0325, 0.28)
    np.testing.assert_allclose(sliver[:4], step[:4], rtol=1e-9)
    assert 12.0 < sliver[0] < 13.0                           # the FEM: 12.61


def test_the_same_on_another_cpus_kernels():
    """A narrow jagged panel of the data sets (random_beam(2, 3775, max_half_width=(0.025,
    0.25))-like, rounded): the estimate must not depend on the BLAS kernels. Solved in M's
    Cholesky factor its lowest modes came out 0.4 % apart under OpenBLAS's generic x86-64
    kernels (OPENBLAS_CORETYPE=Prescott); in K's they agree to 1e-7."""
    code = ("import json, numpy as np\n"
            "from prbdm.truth.planform_ritz import planform_ritz\n"
            "x = [0.0, 0.2719, 0.5582, 0.6079, 0.6103, 0.6905, 0.8278, 0.8358, 0.8369, 0.9328, "
            "0.9998, 1.0]\n"
            "w = [0.0942, 0.0746, 0.0942, 0.0203, 0.0499, 0.01, 0.0585, 0.0169, 0.01, 0.029, "
            "0.0925, 0.01]\n"
            "lam, frac = planform_ritz(x, w, 0.01404, 0.28)\n"
            "print(json.dumps([lam[:20].tolist(), frac[:20].tolist()]))\n")
    runs = []
    for coretype in (None, "Prescott"):
        env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_CORETYPE"}
        if coretype:
            env["OPENBLAS_CORETYPE"] = coretype
        done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                              env=env, timeout=120)
        assert done.returncode == 0, done.stderr[-2000:]
        runs.append(np.array(json.loads(done.stdout)))
    np.testing.assert_allclose(runs[0][0], runs[1][0], rtol=1e-6)
    np.testing.assert_allclose(runs[0][1], runs[1][1], atol=1e-7)
