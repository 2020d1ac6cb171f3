"""The plate network's features: the load-spread half-width and the chain built on it
(prbdm/surrogate/features.py, ``FeatureSpec.spread``)."""
from __future__ import annotations

import numpy as np
import pytest

from prbdm.chain import BeamBatch
from prbdm.geometry import random_beam
from prbdm.surrogate.features import FeatureSpec, feature_names, features


def test_spread_half_width_is_the_lower_envelope_of_45_degree_cones():
    """w_s(x) = min_x' (w(x') + |x - x'|), checked against a brute-force minimum over 4,001
    points of each planform, its stations and the grid included (there the brute force is exact
    too: the minimum over x' of a piecewise-linear w plus a cone lies at a station or at x' = x),
    and the minimum never above w itself."""
    from prbdm.surrogate.features import spread_half_width

    bb = BeamBatch.from_beams([random_beam(3, i, min_half_width=0.01) for i in range(12)])
    xg, ws = spread_half_width(bb.x, bb.w)
    for b in range(len(bb)):
        fine = np.unique(np.concatenate([np.linspace(0, 1, 4001), bb.x[b], xg[b]]))
        wf = np.interp(fine, bb.x[b], bb.w[b])
        brute = (wf[None, :] + np.abs(xg[b][:, None] - fine[None, :])).min(1)
        assert np.allclose(ws[b], brute, atol=1e-12)
        assert (ws[b] <= np.interp(xg[b], bb.x[b], bb.w[b]) + 1e-15).all()
    # a uniform strip narrower than its length spreads nowhere
    x, w = np.array([[0.0, 1.0]]), np.array([[0.2, 0.2]])
    assert np.allclose(spread_half_width(x, w)[1], 0.2)


def test_spread_features_extend_the_spec_and_old_checkpoints_keep_theirs():
    old = FeatureSpec(cells=4, rfe_segments=12, rfe_modes=3, truth="plate")
    new = FeatureSpec(cells=4, rfe_segments=12, rfe_modes=3, truth="plate", spread=True)
    assert "spread" not in old.to_dict() and FeatureSpec(**old.to_dict()) == old
    assert FeatureSpec(**new.to_dict()) == new
    names = feature_names(new)
    assert names[new.base_columns(3)] == [f"log_omega_spread[{r}]" for r in range(3)]
    assert feature_names(old)[old.base_columns(3)] == [f"log_omega_rfe[{r}]" for r in range(3)]
    bb = BeamBatch.from_beams([random_beam(2, i) for i in range(5)])
    f_old, f_new = features(bb, old), features(bb, new)
    assert np.array_equal(f_old, np.delete(f_new, new.base_columns(3), axis=1))
    # the load spread removes stiffness, so the spread chain is softer; not guaranteed to the last
    # digit (the tabulated width is linear between grid points and can exceed w at a neck
    # narrower than the grid spacing), measured: never stiffer on 400 panels (by 9e-4 at least)
    assert (f_new[:, new.base_columns(3)] <= f_new[:, old.base_columns(3)] + 1e-3).all()


def test_the_load_spread_chain_is_closer_to_the_plate_than_the_beam_chain():
    """Physics, not construction: on 8 wide necked panels of the paper's generator the plate
    truth's modes 1-2 lie closer (in log frequency, after removing the mean offset of each base)
    to the load-spread chain than to the beam's chain; measured on 3,000 panels the scatter falls
    from 0.095 / 0.087 to 0.038 / 0.038 (prbdm.surrogate.features)."""
    from prbdm.truth import bending_frequencies

    beams = [random_beam(1, i, min_half_width=0.01) for i in range(8)]
    spec = FeatureSpec(cells=16, rfe_segments=96, rfe_modes=2, truth="plate", rfe_coarse=16,
                       spread=True)
    bb = BeamBatch.from_beams(beams)
    f = features(bb, spec)
    plate = np.log([bending_frequencies(b, "plate", 2).omega for b in beams]
                   / np.sqrt(bb.lambda0)[:, None])
    beam_chain = plate - f[:, 32:34]
    spread_chain = plate - f[:, spec.base_columns(2)]
    assert (spread_chain.std(0) < 0.7 * beam_chain.std(0)).all(), (spread_chain.std(0),
                                                                   beam_chain.std(0))


def test_mindlin_features_add_the_thickness():
    """The shear-deformable plate's frequencies depend on t / L (the Kirchhoff plate's do not):
    a `mindlin` spec adds log_thickness after the plate's features, and only it moves with t."""
    import dataclasses
    spec = FeatureSpec(truth="mindlin", spread=True)
    plate = FeatureSpec(truth="plate", spread=True)
    names = feature_names(spec)
    assert names[-3:] == ["log_aspect", "nu", "log_thickness"]
    assert names[:-1] == feature_names(plate)
    b = random_beam(0, 3, min_half_width=0.01)
    thin = dataclasses.replace(b, thickness=b.thickness / 4)
    f = features(BeamBatch.from_beams([b, thin]), spec)
    assert np.allclose(f[:, -1], np.log([b.thickness, thin.thickness]))
    assert np.allclose(f[0, :-1], f[1, :-1])


def test_profile_features_sample_the_planform_and_old_checkpoints_keep_theirs():
    """``profile = P``: log(w / max w) at the P cell midpoints of x / L (against np.interp),
    floored at PROFILE_FLOOR, then the same of the load-spread width (relative to the real
    width's maximum); appended after every other feature, so
    the base columns and a checkpoint without it are unchanged."""
    from prbdm.surrogate.features import PROFILE_FLOOR, spread_half_width

    base = FeatureSpec(cells=4, rfe_segments=12, rfe_modes=3, truth="mindlin", spread=True)
    spec = FeatureSpec(cells=4, rfe_segments=12, rfe_modes=3, truth="mindlin", spread=True,
                       profile=10)
    assert "profile" not in base.to_dict() and FeatureSpec(**spec.to_dict()) == spec
    names = feature_names(spec)
    assert names[:len(feature_names(base))] == feature_names(base)
    assert names[-20:] == ([f"log_profile[{i}]" for i in range(10)]
                           + [f"log_spread_profile[{i}]" for i in range(10)])
    beams = [random_beam(1, i, min_half_width=0.01) for i in range(6)]
    bb = BeamBatch.from_beams(beams)
    f, f0 = features(bb, spec), features(bb, base)
    assert np.array_equal(f[:, :f0.shape[1]], f0)
    xq = (np.arange(10) + 0.5) / 10
    xs, ws = spread_half_width(bb.x, bb.w)
    for b in range(len(bb)):
        ratio = np.interp(xq, bb.x[b], bb.w[b]) / bb.w[b].max()
        assert np.allclose(f[b, -20:-10], np.log(np.maximum(ratio, PROFILE_FLOOR)), atol=1e-12)
        spread = np.interp(xq, xs[b], ws[b]) / bb.w[b].max()
        assert np.allclose(f[b, -10:], np.log(np.maximum(spread, PROFILE_FLOOR * ws[b].max()
                                                         / bb.w[b].max())), atol=1e-12)
        # never above the real profile but for the tabulated spread width's linear reading
        # across a neck narrower than its grid (spread_half_width; 0.012 at most on these)
        assert (f[b, -10:] <= f[b, -20:-10] + 0.05).all()
    # a neck to (almost) nothing, over two sample points (x/L 0.45 and 0.55), reads as the floor
    # there, not as minus infinity
    x, w = np.array([[0.0, 0.4, 0.6, 1.0]]), np.array([[0.3, 1e-9, 1e-9, 0.3]])
    tiny = BeamBatch(x, w, np.ones(1), np.full(1, 0.01), np.full(1, 7e10), np.full(1, 2700.0),
                     np.full(1, 0.3))
    f = features(tiny, spec)[0]
    assert np.isfinite(f).all()
    assert f[-20:-10][[4, 5]] == pytest.approx([np.log(PROFILE_FLOOR)] * 2, abs=1e-12)
    assert f[-20:-10].min() >= np.log(PROFILE_FLOOR) - 1e-12
