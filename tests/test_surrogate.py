"""prbdm.surrogate: outputs valid by construction, invariances (features, truth, PRBDM, fit,
network), the NumPy PRBDM against prbdm.model, checkpoint round trip and metadata, the
out-of-distribution warning, and training end to end on a tiny data set.

The tiny data set (12 beams, 2 joints) and its checkpoint are made once per test session by the
``tiny_set`` fixture (tests/conftest.py; also used by tests/test_cli_predict.py).
"""
from __future__ import annotations

import copy
import json
import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
import torch

from prbdm import dataset as D
from prbdm import model
from prbdm import surrogate as sg
from prbdm.chain import BeamBatch, link_table, loss_percent_np, prbdm_eigenvalues, uniform_gamma
from prbdm.constants import GAMMA_MAX, GAMMA_MIN
from prbdm.errors import BadInput
from prbdm.geometry import Beam, Material, random_beam
from prbdm.surrogate import numpy_model as nm
from prbdm.surrogate import prediction as sp
from prbdm.surrogate.checkpoint import (
    PACKAGE_CHECKPOINTS,
    dataset_hash,
    read_checkpoint,
    save_checkpoint,
    weights_sha256,
)
from prbdm.surrogate.decode import (
    SELECT_POSES,
    candidate_losses,
    decode_numpy,
    decode_torch,
    gauss_select_poses,
    project_k,
)
from prbdm.surrogate.features import FeatureSpec, feature_names, features, rfe_log_omega
from prbdm.surrogate.net import SurrogateEnsemble, SurrogateNet
from prbdm.surrogate.prediction import default_threads, physical_problems

REPO = Path(__file__).resolve().parents[1]
TRAIN = REPO / "training" / "train_surrogate.py"
SHIPPED = PACKAGE_CHECKPOINTS / "beam-n4.safetensors"


def tiny_checkpoint(root: Path) -> Path:
    """The tiny checkpoint in the ``tiny_set`` fixture's folder (tests/conftest.py)."""
    return root / "ckpt" / "beam-n2.safetensors"


def _scaled(beam: Beam, width=1.0, thickness=1.0, length=1.0, E=1.0, rho=1.0) -> Beam:
    m = beam.material
    return Beam(x=beam.x * length, half_width=beam.half_width * width * length,
                thickness=beam.thickness * thickness,
                material=Material(E=m.E * E, rho=m.rho * rho, nu=m.nu))


SCALINGS = [dict(width=0.37), dict(thickness=2.9), dict(length=3.1), dict(E=0.01, rho=0.3),
            dict(width=4.0, thickness=0.2, length=0.05, E=7.0, rho=3.0)]


# ------------------------------------------------------------------------ outputs by construction
def test_outputs_valid_by_construction():
    rng = np.random.default_rng(0)
    n, m, R = 4, 6, 5
    norm = {"logk_mean": np.zeros(m), "logk_std": np.ones(m), "freq_mean": np.zeros(R),
            "freq_std": np.ones(R)}
    tn = {key: torch.as_tensor(v) for key, v in norm.items()}
    beams = [random_beam(1, i) for i in range(8)]
    bb = BeamBatch.from_beams(beams)
    rfe = rfe_log_omega(bb, 12, R)
    poses = model.make_poses("paper", n).numpy()
    for k_mode, H in (("direct", 1), ("projection", 1), ("projection", 3)):
        for scale in (1.0, 10.0, 30.0, 300.0):  # wild head outputs, saturated softmax included
            out = scale * rng.standard_normal((8, H * (n + 1) + m + R))
            with np.errstate(over="ignore", invalid="ignore"):
                d = decode_numpy(out, norm, n, k_mode, rfe, bb.x, bb.w, poses, 4, H)
            gamma = d["gamma"]
            assert np.allclose(gamma.sum(-1), 1.0, atol=1e-12)
            assert gamma.min() >= GAMMA_MIN - 1e-15 and gamma.max() <= GAMMA_MAX + 1e-15
            assert np.allclose(d["gamma_all"].sum(-1), 1.0, atol=1e-12)
            if scale > 100:      # gamma stays valid whatever the head says; k may overflow
                continue
            k = np.exp(d["logk"])
            assert np.all(np.isfinite(k)) and np.all(k > 0)
            assert np.all(np.isfinite(d["log_omega_hat"]))
            t = decode_torch(torch.as_tensor(out), tn, n, m, k_mode, torch.as_tensor(rfe),
                             torch.as_tensor(bb.x), torch.as_tensor(bb.w),
                             torch.as_tensor(poses), 4, H, SELECT_POSES)
            np.testing.assert_array_equal(t["select"].numpy(), d["select"])
            np.testing.assert_allclose(t["gamma"].numpy(), gamma, atol=1e-12)
            np.testing.assert_allclose(t["logk"].numpy(), d["logk"], rtol=1e-8, atol=1e-8)
            if H > 1:     # the kept candidate is the best against the predicted frequencies
                lam_p = np.exp(2 * d["log_omega_hat"][:, :4])
                for h in range(H):
                    mu_h = prbdm_eigenvalues(bb.x, bb.w, d["gamma_all"][:, h],
                                             poses[SELECT_POSES])
                    kp = project_k(mu_h[..., :4], lam_p)
                    mu_s = prbdm_eigenvalues(bb.x, bb.w, gamma, poses[SELECT_POSES])
                    ks = project_k(mu_s[..., :4], lam_p)
                    loss_h = loss_percent_np(mu_h * kp[..., None], lam_p, 4)
                    loss_s = loss_percent_np(mu_s * ks[..., None], lam_p, 4)
                    assert np.all(loss_s <= loss_h + 1e-12)


def test_numpy_prbdm_matches_model():
    beams = [random_beam(0, i) for i in range(20)] + [
        Beam(x=[0, 0.4, 1.3], half_width=[0.2, 0.05, 0.11], thickness=0.02)]
    bb = BeamBatch.from_beams(beams)
    bt = model.BeamTensors.from_beams(beams)
    rng = np.random.default_rng(1)
    for n in (1, 2, 4, 6):
        g = GAMMA_MIN + (1 - (n + 1) * GAMMA_MIN) * rng.dirichlet(np.ones(n + 1), len(beams))
        poses = model.make_poses("paper", n)
        ref = model.eigenvalues_unit_k(bt, torch.as_tensor(g), poses).numpy()
        got = prbdm_eigenvalues(bb.x, bb.w, g, poses.numpy())
        np.testing.assert_allclose(got, ref, rtol=1e-8)
        links_t = model.links_from_gamma(bt, torch.as_tensor(g)).physical(bt)
        table = link_table(bb, g)
        for key in ("joint_x", "length", "mass", "com", "area_moment"):
            np.testing.assert_allclose(table[key], links_t[key].numpy(), rtol=1e-9, atol=1e-14)
        np.testing.assert_allclose(table["inertia"], links_t["inertia"].numpy(), rtol=1e-7)
        s_t = model.base_stiffness(bt, model.links_from_gamma(bt, torch.as_tensor(g)))
        np.testing.assert_allclose(table["base_stiffness"],
                                   (s_t * (bt.E * bt.thickness ** 3)[:, None]).numpy(), rtol=1e-9)
    # the straight-beam fast path of the rigid-finite-element features
    n = 11
    g = np.broadcast_to(uniform_gamma(n), (len(beams), n + 1))
    ref = model.eigenvalues_unit_k(bt, torch.as_tensor(np.ascontiguousarray(g)),
                                   torch.zeros(1, n)).numpy()[:, 0, :5]
    np.testing.assert_allclose(np.exp(2 * rfe_log_omega(bb, 12, 5)), ref, rtol=1e-9)

    # the straight M from its semiseparable generators, and V^T M V without forming M
    links = nm.links_from_gamma(bb.x, bb.w, np.ascontiguousarray(g))
    M0 = nm.straight_mass_matrix(links)
    np.testing.assert_allclose(M0, nm.mass_matrix(links, np.zeros((1, n)))[:, 0], rtol=1e-12,
                               atol=1e-15)
    V = rng.standard_normal((len(beams), n, 3))
    np.testing.assert_allclose(nm.straight_projected_mass(links, V),
                               np.swapaxes(V, -1, -2) @ M0 @ V, rtol=1e-10, atol=1e-14)


def test_rfe_rayleigh_ritz_matches_the_fine_chain():
    # Ritz values from a 16-link chain's moments bound the 96-link chain's eigenvalues from above
    # and agree with them closely; measured on 200 random beams
    bb = BeamBatch.from_beams([random_beam(5, i) for i in range(200)])
    exact = rfe_log_omega(bb, 96, 5)
    ritz = rfe_log_omega(bb, 96, 5, coarse=16)
    assert np.all(ritz >= exact - 1e-12)
    assert np.all(np.median(ritz - exact, axis=0) < [1e-6, 2e-5, 2e-4, 5e-4, 1.5e-3])
    assert np.max(ritz - exact) < 1e-2
    # and they are far closer to the fine chain than the coarse chain is
    coarse = rfe_log_omega(bb, 16, 5)
    assert np.all(np.median(ritz - exact, axis=0) < 0.2 * np.median(coarse - exact, axis=0))


# ------------------------------------------------------------------------ invariances
def test_feature_invariances_beam_truth():
    beams = [random_beam(2, i) for i in range(6)]
    base = features(BeamBatch.from_beams(beams))
    for s in SCALINGS:
        got = features(BeamBatch.from_beams([_scaled(b, **s) for b in beams]))
        np.testing.assert_allclose(got, base, rtol=1e-10, atol=1e-10, err_msg=str(s))
    # the shape does matter
    other = features(BeamBatch.from_beams([random_beam(3, 0)]))
    assert np.abs(other - base[0]).max() > 1e-2


def test_plate_features_add_aspect_and_nu():
    b = random_beam(2, 0)
    spec = FeatureSpec(truth="plate")
    names = feature_names(spec)
    assert names[-2:] == ["log_aspect", "nu"]
    f0 = features(BeamBatch.from_beams([b]), spec)[0]
    f_w = features(BeamBatch.from_beams([_scaled(b, width=0.5)]), spec)[0]
    f_t = features(BeamBatch.from_beams([_scaled(b, thickness=3.0, E=2.0)]), spec)[0]
    nu = Beam(x=b.x, half_width=b.half_width, thickness=b.thickness, material=Material(nu=0.3))
    f_nu = features(BeamBatch.from_beams([nu]), spec)[0]
    np.testing.assert_allclose(f_w[:-2], f0[:-2], atol=1e-10)      # the shape is the same
    assert f_w[-2] == pytest.approx(f0[-2] + np.log(0.5))           # the aspect is not
    np.testing.assert_allclose(f_t, f0, atol=1e-10)                 # Kirchhoff: t drops out
    assert f_nu[-1] == 0.3 and f0[-1] == 0.28


def test_truth_prbdm_and_fit_invariances():
    """Beam truth + beam law: omega / sqrt(E t^2 / (rho L^4)), the PRBDM's nondimensional
    eigenvalues at a given (gamma, k), and the fitted (gamma, k) do not change when the widths,
    the thickness, the length or the material are scaled."""
    from prbdm.fit import fit_prbdm
    from prbdm.truth import bending_frequencies

    beam = random_beam(4, 1)
    bb = BeamBatch.from_beams(beam)
    om0 = bending_frequencies(beam, model="beam", modes=4).omega / np.sqrt(bb.lambda0[0])
    g = torch.tensor([0.3, 0.2, 0.25, 0.25], dtype=torch.float64)
    k = torch.linspace(0.8, 1.2, 9, dtype=torch.float64)
    lam0 = model.eigenvalues(beam, g, k) / model.BeamTensors.from_beams(beam).lambda0
    for s in SCALINGS:
        b = _scaled(beam, **s)
        l0 = BeamBatch.from_beams(b).lambda0[0]
        om = bending_frequencies(b, model="beam", modes=4).omega / np.sqrt(l0)
        np.testing.assert_allclose(om, om0, rtol=1e-8, err_msg=str(s))
        lam = model.eigenvalues(b, g, k) / model.BeamTensors.from_beams(b).lambda0
        np.testing.assert_allclose(lam.numpy(), lam0.numpy(), rtol=1e-10)
    # the fitted labels too (few starts, same seed: the same nondimensional problem)
    fit0 = fit_prbdm(beam, om0 * np.sqrt(bb.lambda0[0]), joints=2, starts=3, seed=0)
    fit = fit_prbdm(b, om * np.sqrt(l0), joints=2, starts=3, seed=0)
    # (to the fit's own tolerance: its iterations see round-off of the scaled inputs)
    np.testing.assert_allclose(fit.gamma, fit0.gamma, atol=1e-3)
    np.testing.assert_allclose(fit.k, fit0.k, rtol=1e-3)
    assert fit.loss_percent == pytest.approx(fit0.loss_percent, rel=1e-4)


def test_prediction_invariances(tiny_set):
    sur = sg.load_checkpoint(tiny_checkpoint(tiny_set))
    beams = [random_beam(5, i) for i in range(5)]
    p0 = sur.predict(beams, warn=False)
    for s in SCALINGS:
        scaled = [_scaled(b, **s) for b in beams]
        p = sur.predict(scaled, warn=False)
        np.testing.assert_allclose(p.gamma, p0.gamma, atol=1e-12)
        np.testing.assert_allclose(p.k, p0.k, rtol=1e-9)
        np.testing.assert_allclose(p.log_omega_hat, p0.log_omega_hat, atol=1e-10)
        ratio = np.sqrt(BeamBatch.from_beams(scaled).lambda0 /
                        BeamBatch.from_beams(beams).lambda0)
        np.testing.assert_allclose(p.omega, p0.omega * ratio[:, None, None], rtol=1e-9)


# ------------------------------------------------------------------------ checkpoints
REQUIRED_META = ["joints", "modes", "truth", "law", "poses", "features", "normalisation",
                 "network", "dataset", "training", "versions", "git_commit", "test"]


def _torch_outputs(net, src, bb, select_poses):
    """A torch network's decoded outputs for a batch, with the checkpoint ``src``'s features and
    normalisation (what training sees), candidates compared on ``select_poses``."""
    feats = features(bb, src.feature_spec)
    f_std = torch.as_tensor((feats - src.f_mean) / src.f_std, dtype=torch.float32)
    norm = {k: torch.as_tensor(v, dtype=torch.float32) for k, v in src.norm.items()}
    rfe = torch.as_tensor(feats[:, src.feature_spec.base_columns(len(src.norm["freq_mean"]))],
                          dtype=torch.float32)
    with torch.no_grad():
        return net.outputs(f_std, norm, rfe, torch.as_tensor(bb.x), torch.as_tensor(bb.w),
                           torch.as_tensor(src.poses), src.modes, select_poses)


def test_checkpoint_round_trip(tmp_path, tiny_set):
    src = sg.load_checkpoint(tiny_checkpoint(tiny_set))
    meta = src.metadata
    for key in REQUIRED_META:
        assert key in meta, key
    ds = meta["dataset"]
    assert ds["size"] == 12 and len(ds["sha256"]) == 64 and ds["spec"]["joints"] == 2
    assert set(meta["training"]["comparison"]) == {"label", "physics", "combined"}
    assert meta["training"]["selected_mode"] in meta["training"]["comparison"]
    for key in ("torch", "numpy"):
        assert key in meta["versions"]
    assert {"loss_median", "loss_p95", "freq_err_median"} <= set(meta["test"])
    assert len(meta["features"]["min"]) == len(meta["features"]["names"])
    # the hash is the data set's
    table = D.read_table(tiny_set / "data", status="ok").to_pandas()
    assert dataset_hash(table) == ds["sha256"]
    # weights -> torch network -> save -> load: same predictions, and the torch forward agrees
    net = SurrogateNet(len(src.names), 2, len(src.poses), len(src.norm["freq_mean"]),
                          width=meta["network"]["width"], depth=meta["network"]["depth"],
                          k_mode=src.k_mode, hypotheses=src.hypotheses)
    assert src.hypotheses > 1
    tensors, _ = read_checkpoint(tiny_checkpoint(tiny_set))
    net.load_weights(tensors)
    path = save_checkpoint(tmp_path / "copy.safetensors", net.weights(), {
        k: v for k, v in meta.items() if k not in ("format", "format_version")})
    assert path.with_suffix(".json").is_file()
    copy = sg.load_checkpoint(path)
    beams = [random_beam(6, i) for i in range(7)]
    a, b = src.predict(beams, warn=False), copy.predict(beams, warn=False)
    for f in ("gamma", "k", "log_omega_hat", "omega", "omega_truth"):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f))
    d = _torch_outputs(net, src, BeamBatch.from_beams(beams), src.select_poses)
    np.testing.assert_allclose(d["gamma"].numpy(), a.gamma, atol=2e-6)
    np.testing.assert_allclose(d["logk"].numpy(), np.log(a.k), atol=2e-5)
    np.testing.assert_allclose(d["log_omega_hat"].numpy(), a.log_omega_hat, atol=2e-5)


def test_checkpoint_loading_refuses_bad_files(tmp_path):
    with pytest.raises(BadInput, match="no such file"):
        sg.load_checkpoint(tmp_path / "missing.safetensors")
    junk = tmp_path / "junk.safetensors"
    junk.write_bytes(b"\x10\x00\x00\x00\x00\x00\x00\x00not json at all!")
    with pytest.raises(BadInput, match="not a safetensors file"):
        sg.load_checkpoint(junk)
    from safetensors.numpy import save_file

    foreign = tmp_path / "foreign.safetensors"
    save_file({"a": np.zeros(3, dtype=np.float32)}, str(foreign))
    with pytest.raises(BadInput, match="no prbdm surrogate metadata"):
        sg.load_checkpoint(foreign)
    # a pickle is never unpickled: the loader reads JSON and raw arrays only
    evil = tmp_path / "evil.safetensors"
    evil.write_bytes(b"\x80\x04\x95" + b"\x00" * 40)
    with pytest.raises(BadInput):
        sg.load_checkpoint(evil)


def test_default_checkpoint_lookup(tmp_path, monkeypatch, tiny_set):
    monkeypatch.setenv("PRBDM_CHECKPOINTS", str(tmp_path))
    with pytest.raises(BadInput, match="no trained surrogate checkpoint"):
        sg.default_checkpoint(2, "plate")
    shutil.copy(tiny_checkpoint(tiny_set), tmp_path / "beam-n2.safetensors")
    assert sg.default_checkpoint(2, "beam") == tmp_path / "beam-n2.safetensors"
    p = sg.predict([random_beam(0, 1)], joints=2, warn=False)
    assert p.gamma.shape == (1, 3)
    with pytest.raises(BadInput, match="trained for 2 joints"):
        sg.predict([random_beam(0, 1)], joints=3, checkpoint=tmp_path / "beam-n2.safetensors")


@pytest.mark.skipif(not SHIPPED.is_file(), reason="no shipped n = 4 checkpoint")
def test_shipped_checkpoint():
    sur = sg.load_checkpoint(SHIPPED)
    assert (sur.joints, sur.truth, sur.law) == (4, "beam", "beam")
    assert sg.default_checkpoint(4, "beam").resolve() == SHIPPED.resolve()
    for key in REQUIRED_META:
        assert key in sur.metadata, key
    beams = [random_beam(0, 10 ** 6 + i) for i in range(2000)]
    p = sur.predict(beams, warn=False)
    assert np.all(np.abs(p.gamma.sum(-1) - 1) < 1e-12) and np.all(p.k > 0)
    # trained at rest (the shape pose target): one pose, the straight one
    m = 1 if sur.pose_target == "shape" else 6
    assert np.all(np.isfinite(p.omega)) and p.omega.shape == (2000, m, 4)


# ------------------------------------------------------------------------ prediction API
def test_predict_from_features_and_ood_warning(tiny_set):
    sur = sg.load_checkpoint(tiny_checkpoint(tiny_set))
    beams = [random_beam(7, i) for i in range(4)]
    pb = sur.predict(beams, warn=False)
    pf = sur.predict(sur.features(beams), warn=False)
    np.testing.assert_array_equal(pf.log_omega_hat, pb.log_omega_hat)
    np.testing.assert_array_equal(pf.extra["gamma_candidates"], pb.extra["gamma_candidates"])
    rows = np.arange(4)
    np.testing.assert_array_equal(pb.extra["gamma_candidates"][rows, pb.extra["selected"]],
                                  pb.gamma)
    assert pf.omega is None and pf.omega_truth is None and pf.k is None and pf.gamma is None
    with pytest.raises(BadInput, match="features"):
        sur.predict(np.zeros((2, 3)))
    # a deep notch near the root: far outside anything in training
    notch = Beam(x=[0, 0.1, 0.12, 0.14, 1], half_width=[0.3, 0.3, 1e-4, 0.3, 0.3],
                 thickness=0.02)
    with pytest.warns(sg.OutOfDistributionWarning, match=r"feature\(s\) log_\w+\[\d+\]"):
        p = sur.predict([notch])
    assert p.ood[0].any()
    j = int(np.flatnonzero(p.ood[0])[0])
    assert f"feature {sur.names[j]} = " in p.warnings[0] and "training range" in p.warnings[0]
    # in range: no warning
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        inside = sur.predict(sur.f_min[None] / 2 + sur.f_max[None] / 2)
    assert not inside.ood.any() and inside.warnings == []
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sur.predict([notch], warn=False)


def test_training_log_and_comparison_recorded(tiny_set):
    log = tiny_checkpoint(tiny_set).with_suffix(".log").read_text()
    assert "selected mode:" in log and "test (" in log
    meta = json.loads(tiny_checkpoint(tiny_set).with_suffix(".json").read_text())
    for res in meta["training"]["comparison"].values():
        assert {"loss_mean", "loss_median", "loss_p95", "freq_err_median"} <= set(res["val"])
        assert res["epochs"] <= 4


def test_threaded_prediction_equals_one_thread(monkeypatch, tiny_set):
    sur = sg.load_checkpoint(tiny_checkpoint(tiny_set))
    monkeypatch.setattr(sp, "PIECE", 7)          # several pieces from a small batch
    beams = BeamBatch.from_beams([random_beam(5, i) for i in range(30)])
    one = sur.predict(beams, warn=False, threads=1)
    for threads in (2, 3):
        many = sur.predict(beams, warn=False, threads=threads)
        for key in ("gamma", "k", "omega", "omega_truth", "log_omega_hat"):
            np.testing.assert_array_equal(getattr(many, key), getattr(one, key))
    # one piece: the same numbers to the float32 MLP's round-off, which depends on the shape
    # of its matrix products (hence pieces that do not depend on the thread count)
    monkeypatch.setattr(sp, "PIECE", 10 ** 6)
    whole = sur.predict(beams, warn=False, threads=2)
    np.testing.assert_allclose(whole.k, one.k, rtol=1e-5)
    np.testing.assert_allclose(whole.omega_truth, one.omega_truth, rtol=1e-6)
    monkeypatch.setenv("PRBDM_THREADS", "zero")
    with pytest.raises(BadInput, match="PRBDM_THREADS"):
        default_threads()


def test_gauss_select_poses():
    """Candidates are compared on the poses nearest the 2-point Gauss-Legendre nodes."""
    assert gauss_select_poses(1) == [0] and gauss_select_poses(2) == [0, 1]
    assert gauss_select_poses(5) == [1, 3] and gauss_select_poses(6) == [1, 4]
    assert gauss_select_poses(9) == [2, 6] and gauss_select_poses(14) == [3, 10]
    # two nodes integrate a smooth loss over the poses far better than the end points
    t = np.linspace(0, 1, 6)
    f = 1 + 3 * t ** 2                          # e.g. a loss growing with the pose angle
    assert abs(f[[1, 4]].mean() - f.mean()) < 0.3 * abs(f[[0, -1]].mean() - f.mean())


def test_format_1_checkpoint_keeps_its_choice_poses(tmp_path, tiny_set):
    """A checkpoint written before ensembles (no members, no select_poses) loads as one network
    that compares candidates on the first and last poses, as it was trained and measured."""
    tensors, meta = read_checkpoint(tiny_checkpoint(tiny_set))
    for key in ("members", "select_poses"):
        meta["network"].pop(key)
    old = sg.load_checkpoint(save_checkpoint(tmp_path / "old.safetensors", tensors, {
        k: v for k, v in meta.items() if k not in ("format", "format_version")}))
    assert old.n_members == 1 and old.select_poses == SELECT_POSES
    new = sg.load_checkpoint(tiny_checkpoint(tiny_set))
    assert new.select_poses == gauss_select_poses(len(new.poses))
    beams = [random_beam(6, i) for i in range(30)]
    a, b = old.predict(beams, warn=False), new.predict(beams, warn=False)
    np.testing.assert_array_equal(a.log_omega_hat, b.log_omega_hat)
    np.testing.assert_array_equal(a.extra["gamma_candidates"], b.extra["gamma_candidates"])


def test_ensemble_checkpoint(tmp_path, tiny_set):
    """Two members saved as one checkpoint: the candidates of both, side by side, the mean
    frequency prediction; NumPy inference equals the torch ensemble."""
    src = sg.load_checkpoint(tiny_checkpoint(tiny_set))
    meta = dict(src.metadata)
    net_meta = meta["network"]
    tensors, _ = read_checkpoint(tiny_checkpoint(tiny_set))
    torch.manual_seed(0)
    members = []
    for j in range(2):
        net = SurrogateNet(len(src.names), 2, len(src.poses), len(src.norm["freq_mean"]),
                              width=net_meta["width"], depth=net_meta["depth"],
                              k_mode=src.k_mode, hypotheses=src.member_hypotheses)
        net.load_weights(tensors)
        if j:                                 # a second, different member
            with torch.no_grad():
                for prm in net.parameters():
                    prm.add_(0.05 * torch.randn_like(prm))
        members.append(net)
    ens = SurrogateEnsemble(members)

    def save(name, weights, n_members):
        meta["network"] = {**net_meta, "members": n_members}
        return sg.load_checkpoint(save_checkpoint(tmp_path / name, weights, {
            k: v for k, v in meta.items() if k not in ("format", "format_version")}))

    loaded = save("ens.safetensors", ens.weights(), 2)
    assert loaded.n_members == 2 and loaded.hypotheses == 2 * src.member_hypotheses
    singles = [save(f"m{j}.safetensors", net.weights(), 1) for j, net in enumerate(members)]
    beams = [random_beam(6, i) for i in range(25)]
    p = loaded.predict(beams, warn=False)
    q = [s.predict(beams, warn=False) for s in singles]
    np.testing.assert_allclose(p.extra["gamma_candidates"], np.concatenate(
        [x.extra["gamma_candidates"] for x in q], 1), atol=1e-12)
    np.testing.assert_allclose(p.log_omega_hat, (q[0].log_omega_hat + q[1].log_omega_hat) / 2,
                               atol=1e-6)
    # the kept candidate is the one whose PRBDM best matches the predicted frequencies
    bb = BeamBatch.from_beams(beams)
    lam_p = np.exp(2 * p.log_omega_hat[:, :src.modes])
    cand = p.extra["gamma_candidates"]
    H, P = cand.shape[1], len(loaded.select_poses)
    mu = prbdm_eigenvalues(np.repeat(bb.x, H, 0), np.repeat(bb.w, H, 0),
                           cand.reshape(-1, 3), src.poses[loaded.select_poses])
    _, loss = candidate_losses(mu.reshape(len(beams), H, P, 2)[..., :src.modes], lam_p)
    np.testing.assert_array_equal(p.extra["selected"], loss.argmin(1))
    assert (p.extra["selected"] >= src.member_hypotheses).any()   # both members contribute
    # the torch ensemble (used in training) gives the same
    d = _torch_outputs(ens, src, bb, loaded.select_poses)
    np.testing.assert_array_equal(d["select"].numpy(), p.extra["selected"])
    np.testing.assert_allclose(d["gamma"].numpy(), p.gamma, atol=2e-6)


def test_physics_training_on_a_truth_only_set(tmp_path):
    """A truth-only set (starts 0: no fits) trains the physics mode and refuses the label modes."""
    data = tmp_path / "truth-only"
    D.generate(data, 12, D.make_spec(joints=2, starts=0, seed=3), workers=0, progress="none")
    table = D.read_table(data).to_pandas()
    assert (table["status"] == "ok").all() and table["gamma"].isna().all()
    assert table["omega_truth"].map(len).eq(3).all()
    ckpt = tmp_path / "ckpt" / "beam-n2.safetensors"
    common = [sys.executable, str(TRAIN), f"--data={data}", f"--out={ckpt}", "--max_epochs=2",
              "--width=16", "--depth=1", "--quiet=True", "--batch_size=4"]
    run = subprocess.run(common + ["--modes=physics,label"], capture_output=True, text=True,
                         cwd=REPO, timeout=300)
    assert run.returncode != 0 and "truth-only" in run.stderr
    # with a frequency trunk of its own (freq_width): stored as one block-diagonal MLP
    run = subprocess.run(common + ["--modes=physics", "--freq_width=8", "--depth=2"],
                         capture_output=True, text=True, cwd=REPO, timeout=300)
    assert run.returncode == 0, run.stderr[-3000:]
    meta = json.loads(ckpt.with_suffix(".json").read_text())
    assert meta["dataset"]["spec"]["starts"] == 0 and meta["test"]["fit_loss_median"] is None
    assert meta["network"]["freq_width"] == 8
    tensors, _ = read_checkpoint(ckpt)
    assert tensors["layers.0.weight"].shape[0] == 16 + 8
    assert not tensors["layers.1.weight"][:16, 16:].any()     # no path between the trunks
    assert not tensors["layers.1.weight"][16:, :16].any()
    assert not tensors["layers.2.weight"][-3:, :16].any()     # the 3 frequencies: its own trunk
    assert not tensors["layers.2.weight"][:-3, 16:].any()
    p = sg.load_checkpoint(ckpt).predict([random_beam(3, 100)], warn=False)
    assert np.all(p.k > 0) and abs(p.gamma.sum() - 1) < 1e-12


def test_frequency_trunk_is_one_mlp_and_separate():
    """freq_width > 0: the frequency outputs have a trunk of their own. The checkpoint's dense
    MLP (what NumPy inference runs) equals the two trunks, loading it back gives the same network,
    and no PRBDM output depends on the frequency trunk's weights, nor the frequencies on the
    PRBDM trunk's."""
    torch.manual_seed(0)
    n, m, R = 3, 2, 5
    net = SurrogateNet(11, n, m, R, width=9, depth=3, hypotheses=2, freq_width=6)
    f = torch.randn(7, 11)
    y = net(f)
    w = net.weights()
    h = f.double().numpy()
    for i in range(4):
        h = h @ w[f"layers.{i}.weight"].T.astype(np.float64) + w[f"layers.{i}.bias"]
        h = h / (1 + np.exp(-h)) if i < 3 else h
    np.testing.assert_allclose(h, y.detach().numpy(), atol=1e-5)
    copy = SurrogateNet(11, n, m, R, width=9, depth=3, hypotheses=2, freq_width=6)
    np.testing.assert_array_equal(copy.load_weights(w)(f).detach().numpy(), y.detach().numpy())
    n_prbdm = 2 * (n + 1) + m
    y[:, :n_prbdm].sum().backward()
    assert all(p.grad is None or not p.grad.any() for p in net.freq_hidden.parameters())
    assert net.hidden[0].weight.grad.abs().sum() > 0
    net.zero_grad()
    net(f)[:, n_prbdm:].sum().backward()
    assert all(p.grad is None or not p.grad.any() for p in net.hidden.parameters())
    assert net.freq_hidden[0].weight.grad.abs().sum() > 0
    with pytest.raises(BadInput, match="freq_width"):
        SurrogateNet(11, n, m, 0, freq_width=4)


def test_evaluate_surrogate_script(tmp_path, tiny_set):
    """training/evaluate_surrogate.py end to end on the tiny set: every row, JSON written."""
    out = tmp_path / "eval.json"
    run = subprocess.run([sys.executable, str(REPO / "training" / "evaluate_surrogate.py"),
                          f"--checkpoint={tiny_checkpoint(tiny_set)}", f"--data={tiny_set / 'data'}",
                          "--split=test", "--refine_count=1", "--refine_iter=3", "--fit_batch=2",
                          "--refit_count=1", "--throughput_count=20", f"--json_out={out}"],
                         capture_output=True, text=True, cwd=REPO, timeout=300)
    assert run.returncode == 0, run.stderr[-3000:]
    res = json.loads(out.read_text())
    assert res["beams"] == 1 and res["test_beams"] == 1
    for key in ("network", "fit", "refined", "refined_candidates", "refit", "throughput"):
        assert key in res, key
    from prbdm.fit import REFINE_CANDIDATES

    hyp = sg.load_checkpoint(tiny_checkpoint(tiny_set)).hypotheses
    assert res["refined_candidates"]["starts"] == min(hyp, REFINE_CANDIDATES) + 4
    assert res["refit"]["starts"] == 2 and res["network"]["loss_median"] >= 0


def test_with_members_uses_the_first_members(tmp_path, tiny_set):
    """``with_members(k)``: the first k members of an ensemble, as their own checkpoint would
    predict; bad counts are refused."""
    src = sg.load_checkpoint(tiny_checkpoint(tiny_set))
    tensors, meta = read_checkpoint(tiny_checkpoint(tiny_set))
    meta.pop("format"), meta.pop("format_version")
    ens = {**{f"members.0.{k}": v for k, v in tensors.items()},
           **{f"members.1.{k}": v * 1.01 for k, v in tensors.items()}}
    meta["network"] = {**meta["network"], "members": 2}
    two = sg.load_checkpoint(save_checkpoint(tmp_path / "two.safetensors", ens, meta))
    one = two.with_members(1)
    assert (one.n_members, one.hypotheses, two.n_members) == (1, src.hypotheses, 2)
    beams = [random_beam(6, i) for i in range(9)]
    a, b = one.predict(beams, warn=False), src.predict(beams, warn=False)
    np.testing.assert_array_equal(a.gamma, b.gamma)
    np.testing.assert_array_equal(a.k, b.k)
    for bad in (0, 3, 1.0, True):
        with pytest.raises(BadInput, match="members"):
            two.with_members(bad)


# ------------------------------------------------------------------------ checks on load
def _raw_save(path, tensors, meta):
    """Write a checkpoint as it is, bypassing save_checkpoint's own checks and hash (a file
    damaged or edited after it was saved)."""
    from safetensors.numpy import save_file

    save_file({k: np.ascontiguousarray(v) for k, v in tensors.items()}, str(path),
              metadata={"prbdm": json.dumps(meta)})
    return path


def test_weights_sha256_written_and_checked(tmp_path, tiny_set):
    tensors, meta = read_checkpoint(tiny_checkpoint(tiny_set))
    assert meta["weights_sha256"] == weights_sha256(tensors)
    # the hash does not depend on the order or the layout of the file
    assert weights_sha256(dict(reversed(list(tensors.items())))) == meta["weights_sha256"]
    edited = {k: v.copy() for k, v in tensors.items()}
    name = sorted(edited)[0]
    edited[name].flat[0] += np.float32(1e-3)
    assert weights_sha256(edited) != meta["weights_sha256"]
    path = _raw_save(tmp_path / "edited.safetensors", edited, meta)
    with pytest.raises(BadInput, match=r"edited\.safetensors.*weights_sha256"):
        sg.load_checkpoint(path)
    # without a recorded hash (an older checkpoint) the same file loads
    old = {k: v for k, v in meta.items() if k != "weights_sha256"}
    sg.load_checkpoint(_raw_save(tmp_path / "old.safetensors", edited, old))


def _refused(tmp_path, tensors, meta, *words):
    path = _raw_save(tmp_path / "bad.safetensors", tensors,
                     {k: v for k, v in meta.items() if k != "weights_sha256"})
    with pytest.raises(BadInput) as err:
        sg.load_checkpoint(path)
    text = str(err.value)
    assert "bad.safetensors" in text and "\n" not in text
    for w in words:
        assert w in text, (w, text)
    return text


def test_checkpoint_checks_on_load(tmp_path, tiny_set):
    """Non-finite weights, wrong shapes, weights that the metadata does not describe and
    inconsistent metadata are refused, naming the file and the weight or field."""
    tensors, meta = read_checkpoint(tiny_checkpoint(tiny_set))
    first = sorted(k for k in tensors if k.endswith(".weight"))[0]
    for bad in (np.nan, np.inf):
        t = {k: v.copy() for k, v in tensors.items()}
        t[first].flat[3] = bad
        _refused(tmp_path, t, meta, first, "non-finite")
    t = dict(tensors, **{first: tensors[first][:, :-1].copy()})
    _refused(tmp_path, t, meta, first.rsplit(".", 1)[0], "shape")
    t = dict(tensors, **{first: tensors[first].astype(np.int32)})
    _refused(tmp_path, t, meta, "dtype")
    t = {k: v for k, v in tensors.items() if not k.endswith(".bias")}
    _refused(tmp_path, t, meta, "missing")
    _refused(tmp_path, dict(tensors, extra=np.zeros(2, np.float32)), meta, "unexpected", "extra")
    # metadata that does not match the weights or itself
    m = json.loads(json.dumps(meta))
    m["joints"] = 3
    _refused(tmp_path, tensors, m, "poses")
    m = json.loads(json.dumps(meta))
    m["normalisation"]["feature_std"][0] = 0.0
    _refused(tmp_path, tensors, m, "feature_std")
    m = json.loads(json.dumps(meta))
    m["normalisation"]["freq_mean"] = m["normalisation"]["freq_mean"][:-1]
    _refused(tmp_path, tensors, m, "normalisation.freq_std has shape")
    m = json.loads(json.dumps(meta))
    m["features"]["names"] = m["features"]["names"][:-1]
    _refused(tmp_path, tensors, m, "feature names")
    m = json.loads(json.dumps(meta))
    m["network"]["members"] = 2
    _refused(tmp_path, tensors, m, "members.0.layers")
    m = json.loads(json.dumps(meta))
    del m["normalisation"]
    _refused(tmp_path, tensors, m, "incomplete")
    # and save_checkpoint writes no file with non-finite weights
    t = {k: v.copy() for k, v in tensors.items()}
    t[first].flat[0] = np.nan
    with pytest.raises(BadInput, match="not finite"):
        save_checkpoint(tmp_path / "nan.safetensors", t, meta)
    assert not list(tmp_path.glob("nan*")) and not list(tmp_path.glob(".nan*"))


@pytest.mark.parametrize("joints", ["3", "4", "5", "4-frequency"])
def test_shipped_checkpoints_are_hashed_and_clean(joints):
    """Every shipped checkpoint records the hash of its weights (checked on load), its readable
    copy equals the header, and neither holds a machine path."""
    path = PACKAGE_CHECKPOINTS / f"beam-n{joints}.safetensors"
    tensors, meta = read_checkpoint(path)
    assert meta["weights_sha256"] == weights_sha256(tensors)
    assert json.loads(path.with_suffix(".json").read_text()) == meta
    assert "/work/" not in json.dumps(meta) and "/home/" not in json.dumps(meta)


def plate_checkpoint(tmp_path, root, nu=0.28) -> Path:
    """The tiny network made into a plate-truth checkpoint trained on one Poisson's ratio: the
    plate features (log_aspect, nu) added with zero weights, nu's training range the single value
    ``nu`` (as a data set of one material gives)."""
    tensors, meta = read_checkpoint(tiny_checkpoint(root))
    meta = json.loads(json.dumps(meta))
    spec = dict(meta["features"]["spec"], truth="plate")
    meta["truth"], meta["features"]["spec"] = "plate", spec
    meta["features"]["names"] = feature_names(FeatureSpec(**spec))
    meta["features"]["min"] += [-6.0, nu]
    meta["features"]["max"] += [2.0, nu]
    meta["normalisation"]["feature_mean"] += [-2.0, nu]
    meta["normalisation"]["feature_std"] += [1.0, 1e-6]    # training's floor for a constant
    first = "layers.0.weight"
    W = tensors[first]
    tensors = dict(tensors, **{first: np.concatenate([W, np.zeros((W.shape[0], 2), W.dtype)], 1)})
    meta = {k: v for k, v in meta.items() if k not in ("format", "format_version")}
    return save_checkpoint(tmp_path / "plate-n2.safetensors", tensors, meta)


def _with_nu(beam, nu):
    m = beam.material
    return Beam(x=beam.x, half_width=beam.half_width, thickness=beam.thickness,
                material=Material(E=m.E, rho=m.rho, nu=nu))


def test_extrapolation_of_a_fixed_feature_is_refused(tmp_path, tiny_set):
    sur = sg.load_checkpoint(plate_checkpoint(tmp_path, tiny_set))
    assert [sur.names[j] for j in np.flatnonzero(sur.fixed)] == ["nu"]
    beam = random_beam(5, 1)
    ok = sur.predict([_with_nu(beam, 0.28)], warn=False)
    assert not ok.ood[0, -1] and not ok.implausible.any()
    alu = [_with_nu(beam, 0.33)]
    with pytest.raises(BadInput, match=r"feature nu = 0\.33 .*\[0\.28, 0\.28\].*extrapolat"):
        sur.predict(alu, warn=False)
    with pytest.raises(BadInput, match="nu = 0.33"):
        sg.predict(alu, checkpoint=sur, warn=False)
    with pytest.raises(BadInput, match="nu = 0.33"):
        sur.predict(sur.features(alu), warn=False)          # from features too
    with pytest.warns(sg.OutOfDistributionWarning, match="nu = 0.33"):
        forced = sur.predict(alu, allow_extrapolation=True)
    assert forced.ood[0, -1] and np.all(np.isfinite(forced.omega))
    # a feature that varied in training keeps its margin and only warns
    assert not sur.fixed[:-1].any()


def test_physical_problems_flag_broken_predictions(tmp_path, tiny_set):
    """A prediction outside physical ranges is flagged and explained, never passed on silently;
    a network whose frequency head is far off (a damaged bias) is caught."""
    sur = sg.load_checkpoint(tiny_checkpoint(tiny_set))
    beams = [random_beam(5, i) for i in range(6)]
    good = sur.predict(beams, warn=False)
    assert not good.implausible.any() and good.problems == []
    rfe = sur.features(beams)[:, sur.feature_spec.base_columns(good.log_omega_hat.shape[1])]
    bb = BeamBatch.from_beams(beams)
    for field_, change, word in (("k", lambda v: v * 1e142, "k = "),
                                 ("k", lambda v: v * np.nan, "k = "),
                                 ("gamma", lambda v: v * np.nan, "gamma"),
                                 ("log_omega_hat", lambda v: v + 3.0, "truth frequencies"),
                                 ("log_omega_hat", lambda v: v[[1, 0, *range(2, len(v))]], "ascending"),
                                 ("omega", lambda v: v * 1e-3, "PRBDM's mode 1")):
        pred = copy.deepcopy(good)
        value = getattr(pred, field_).copy()
        value[2] = change(value[2])
        setattr(pred, field_, value)
        bad, texts = physical_problems(pred, rfe, bb)
        assert bad.tolist() == [False, False, True, False, False, False], field_
        assert texts[0].startswith("beam 2: implausible prediction: ") and word in texts[0]
    # a damaged checkpoint (hash recomputed, so it loads): the frequency head's bias far off
    tensors, meta = read_checkpoint(tiny_checkpoint(tiny_set))
    last = max((k for k in tensors if k.endswith(".bias")), key=lambda k: int(k.split(".")[-2]))
    b = tensors[last].copy()
    b[-1] += 1e4
    meta = {k: v for k, v in meta.items() if k not in ("format", "format_version")}
    broken = sg.load_checkpoint(save_checkpoint(tmp_path / "broken.safetensors",
                                                dict(tensors, **{last: b}), meta))
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)      # no numpy overflow warnings
        warnings.simplefilter("ignore", sg.OutOfDistributionWarning)
        with pytest.warns(sg.ImplausiblePredictionWarning, match="implausible prediction"):
            p = broken.predict(beams)
    assert p.implausible.all()


#: test-split median loss [%] of each shipped checkpoint as docs/reference/checkpoints.md states it
# the test splits' loss medians of the networks trained at rest (docs/reference/checkpoints.md)
DOCUMENTED_MEDIAN_LOSS = {3: 0.082, 4: 0.142, 5: 0.171}


@pytest.mark.parametrize("joints", sorted(DOCUMENTED_MEDIAN_LOSS))
def test_shipped_checkpoint_is_as_accurate_as_documented_on_held_out_beams(joints):
    """Accuracy, not a property that holds by construction: 16 beams of seed 1 (no checkpoint
    was trained on seed 1), each PRBDM against the beam truth by the FEM: the median paper's loss
    within 2x the documented test median, the direct frequency prediction within 0.05 % (the
    documented per-mode medians are 0.002-0.023 %), nothing implausible."""
    from prbdm.geometry import random_beam
    from prbdm.truth import bending_frequencies

    path = PACKAGE_CHECKPOINTS / f"beam-n{joints}.safetensors"
    if not path.is_file():
        pytest.skip(f"{path.name} not shipped in this tree")
    sur = sg.load_checkpoint(path)
    beams = [random_beam(1, i) for i in range(16)]
    omega = np.array([bending_frequencies(b, "beam", sur.modes + 1).omega for b in beams])
    pred = sg.predict(beams, checkpoint=sur, frequencies=True, warn=False)
    r = sur.modes
    lam, ref = pred.omega[..., :r] ** 2, omega[:, None, :r] ** 2
    loss = 100 * (np.linalg.norm(lam - ref, axis=-1) / np.linalg.norm(ref, axis=-1)).mean(-1)
    assert not pred.implausible.any()
    assert np.median(loss) <= 2 * DOCUMENTED_MEDIAN_LOSS[joints]
    assert np.median(np.abs(pred.omega_truth[:, :r] / omega[:, :r] - 1)) <= 5e-4


def test_frequency_checkpoint_keeps_every_mode_within_its_recorded_figure():
    """beam-n4-frequency (issue 18; the paper's poses) on 16 beams of seed 1 against the beam
    truth: the median of the worst per-mode frequency error over the poses within 2x the 5.5 %
    measured on 1,000 held-out beams (docs/validation.md, training/evaluate_objective.py); the
    paper-loss network it was compared with (22.7 % there) is retired: beam-n4 is trained at rest."""
    from prbdm.geometry import random_beam
    from prbdm.truth import bending_frequencies

    path = PACKAGE_CHECKPOINTS / "beam-n4-frequency.safetensors"
    if not path.is_file():
        pytest.skip(f"{path.name} not shipped in this tree")
    beams = [random_beam(1, i) for i in range(16)]
    omega = np.array([bending_frequencies(b, "beam", 5).omega for b in beams])
    pred = sg.predict(beams, checkpoint=sg.load_checkpoint(path), frequencies=True, warn=False)
    worst = np.abs(pred.omega[..., :4] / omega[:, None, :4] - 1).max(axis=(1, 2))
    assert sg.load_checkpoint(sg.default_checkpoint(4, "beam", "frequency")).objective == \
        "frequency"
    assert np.median(worst) <= 2 * 0.055


def test_the_physics_chooses_a_plausible_candidate():
    """The candidate of least loss may leave mode 1 far off its own predicted truth (the loss
    weighs the highest mode most): on 80 wide seed-1 panels plate-n4's (trained on the paper's
    eigenvalue loss at the paper's poses) did on 42 % (a rigid root link over a flexible neck).
    Among its other candidates one mostly has every mode within SELF_CHECK_IMPLAUSIBLE: the rule
    predict answers with takes it ('plausible', 5 % left); the rule its recorded test was
    measured with ('loss') does not. mindlin-n4, trained at rest on the frequency objective,
    leaves none implausible under either rule."""
    import warnings

    from prbdm.geometry import random_beam

    path = PACKAGE_CHECKPOINTS / "plate-n4.safetensors"
    if not path.is_file():
        pytest.skip("plate-n4 is not shipped")
    beams = [random_beam(1, i, min_half_width=0.01) for i in range(80)]
    rest = PACKAGE_CHECKPOINTS / "mindlin-n4.safetensors"
    if rest.is_file():
        sur = sg.load_checkpoint(rest)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            for rule in ("loss", "plausible"):
                sur.candidate_rule = rule
                assert sur.predict(beams).implausible.mean() <= 0.0125       # measured 0
    sur = sg.load_checkpoint(path)
    rates = {}
    for rule in ("loss", "plausible"):
        sur.candidate_rule = rule
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            pred = sur.predict(beams)
        rates[rule] = pred.implausible.mean()
        if rule == "loss":
            loss_rule = pred
    assert rates["loss"] > 0.2 and rates["plausible"] <= 0.075
    assert loss_rule.implausible[1] and not pred.implausible[1]


def test_silu_is_quiet_and_exact_far_below_zero():
    """The NumPy network's activation at large negative pre-activations (panels far outside the
    training range reach them): -0 (the limit), finite, and no overflow warning on stderr."""
    from prbdm.surrogate.decode import silu

    v = np.array([-1e4, -800.0, -30.0, 0.0, 30.0, 800.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out = silu(v)
    assert np.all(np.isfinite(out))
    assert out[0] == 0.0 and out[1] == 0.0 and out[3] == 0.0 and out[5] == 800.0
    assert out[2] == pytest.approx(-30.0 / (1.0 + np.exp(30.0)), rel=1e-12)


def test_detached_frequencies_take_no_gradient_from_the_prbdm(tiny_set):
    """``detach_frequencies`` (training's ``freq_detach``): the SCFs, projected on the predicted
    frequencies, pass no gradient back to them; without it they do."""
    src = sg.load_checkpoint(tiny_checkpoint(tiny_set))
    bb = BeamBatch.from_beams([random_beam(6, i) for i in range(5)])
    feats = features(bb, src.feature_spec)
    f = torch.as_tensor((feats - src.f_mean) / src.f_std, dtype=torch.float32)
    norm = {k: torch.as_tensor(v, dtype=torch.float32) for k, v in src.norm.items()}
    R = len(src.norm["freq_mean"])
    rfe = torch.as_tensor(feats[:, src.feature_spec.base_columns(R)], dtype=torch.float32)
    torch.manual_seed(0)
    net = SurrogateNet(len(src.names), 2, len(src.poses), R, width=8, depth=1, hypotheses=2,
                       freq_width=4)
    for detach in (False, True):
        net.zero_grad()
        d = net.outputs(f, norm, rfe, torch.as_tensor(bb.x), torch.as_tensor(bb.w),
                        torch.as_tensor(src.poses), src.modes, detach_frequencies=detach)
        d["logk"].sum().backward()
        moved = net.freq_head.weight.grad
        assert (moved is None or not moved.any()) == detach
        assert net.head.weight.grad.abs().sum() > 0          # the PRBDM's own outputs learn
