"""The optimised fit: its reported numbers, its constraints, its reproducibility, its optimality."""
import dataclasses
import json
import math
import subprocess
import sys

import numpy as np
import pytest
import torch
from scipy.optimize import minimize_scalar

from prbdm.cli import main
from prbdm.errors import BadInput
from prbdm.fit import (
    LONG_ROOT_RANGE,
    FitProblem,
    StopRules,
    fit_many,
    fit_prbdm,
    gamma_from_z,
    long_root_gamma,
    refine_starts,
    start_points,
    z_from_gamma,
)
from prbdm.geometry import Beam, random_beam
from prbdm.model import GAMMA_MAX, GAMMA_MIN, eigenvalues, loss_percent, make_poses, uniform_gamma
from prbdm.truth import bending_frequencies

# Table 2 of the paper: the uniform test beam; its analytic frequencies (Eqs. 18-20)
UNIFORM = Beam(x=[0.0, 1.0], half_width=[0.1812, 0.1812], thickness=0.040532)
ALPHA = np.array([1.87510407, 4.69409113, 7.85475744, 10.99554073, 14.13716839])


def analytic_omega(beam=UNIFORM):
    E, rho, t = beam.material.E, beam.material.rho, beam.thickness
    b = 2 * beam.half_width[0]
    return ALPHA ** 2 * math.sqrt(E * b * t ** 3 / 12 / (rho * b * t * beam.length ** 4))


def proxy_truth(beam, modes=6):
    """A truth independent of the fit: the 120-link rigid-finite-element chain, which converges
    to the Euler-Bernoulli frequencies at second order (tested in test_model)."""
    with torch.no_grad():
        return eigenvalues(beam, uniform_gamma(120), None, "linear")[0, :modes].sqrt().numpy()


def test_parametrisation_stays_on_bounded_simplex():
    z = torch.randn(1000, 6, dtype=torch.float64) * 3
    z[::7, 2] = 0.0                                       # exactly at a bound
    g = gamma_from_z(z)
    assert torch.allclose(g.sum(-1), torch.ones(1000, dtype=torch.float64), atol=1e-14)
    assert (g >= GAMMA_MIN - 1e-15).all() and (g <= GAMMA_MAX + 1e-15).all()
    g2 = gamma_from_z(z_from_gamma(g))
    assert torch.allclose(g, g2, atol=1e-13)


@pytest.mark.parametrize("law", ["beam", "paper"])
def test_reported_loss_equals_recomputed_loss(law):
    beam = random_beam(3, 1)
    om = proxy_truth(beam)
    r = fit_prbdm(beam, om, joints=3, modes=3, law=law, starts=16)
    lam = eigenvalues(beam, torch.tensor(r.gamma), torch.tensor(r.k), "paper", law)
    recomputed = float(loss_percent(lam, torch.tensor(om) ** 2, 3))
    assert recomputed == pytest.approx(r.loss_percent, rel=1e-10)
    assert np.allclose(lam.sqrt().numpy(), r.omega, rtol=1e-12)
    # constraints hold exactly
    assert abs(r.gamma.sum() - 1) < 1e-12
    assert r.gamma.min() >= GAMMA_MIN - 1e-15 and r.gamma.max() <= GAMMA_MAX + 1e-15
    assert (r.k > 0).all() and len(r.k) == make_poses("paper", 3).shape[0]


def test_reported_loss_equals_prbdm_eval(tmp_path, capsys):
    """The same numbers through the command line: fit, then eval its gamma and k."""
    beam = random_beam(3, 2)
    om = proxy_truth(beam)
    r = fit_prbdm(beam, om, joints=4, starts=16)
    path = tmp_path / "b.json"
    beam.to_json(path)
    code = main(["eval", str(path), "--gamma", ",".join(repr(float(g)) for g in r.gamma),
                 "--k", ",".join(repr(float(k)) for k in r.k), "--json"])
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    lam = torch.tensor(out["omega"], dtype=torch.float64) ** 2
    assert float(loss_percent(lam, torch.tensor(om) ** 2, 4)) == pytest.approx(r.loss_percent,
                                                                                rel=1e-9)


def test_scf_projection_is_optimal_per_pose():
    """k_i is eliminated in closed form; a 1-D search on each pose's term must not beat it."""
    beam = random_beam(4, 0)
    om = proxy_truth(beam)
    r = fit_prbdm(beam, om, joints=3, starts=8)
    lam1 = eigenvalues(beam, torch.tensor(r.gamma), None, "paper")[..., :3].numpy()
    t = om[:3] ** 2
    for i, k in enumerate(r.k):
        term = lambda kk: np.linalg.norm(kk * lam1[i] - t)
        best = minimize_scalar(term, bracket=(0.5 * k, k, 2 * k), tol=1e-12)
        assert term(k) <= best.fun * (1 + 1e-9)


@pytest.mark.parametrize("n", [1, 2, 4])
def test_linear_pose_set_matches_truth_to_round_off(n):
    """One pose, r = n modes, n + 1 unknowns: the PRBDM can match the truth exactly."""
    beam = random_beam(5, n)
    om = proxy_truth(beam)
    r = fit_prbdm(beam, om, joints=n, poses="linear", starts=32)
    assert r.loss_percent < 1e-8
    assert r.freq_error.max() < 1e-9


@pytest.mark.parametrize("law", ["beam", "paper"])
@pytest.mark.parametrize("n", [1, 2, 4])
def test_linear_pose_set_matches_the_fem_truth_to_round_off(n, law):
    """The same with the real truth (Euler-Bernoulli FEM) and either stiffness law: n modes,
    n + 1 unknowns, an exact fit. The beam law matches any planform; the paper law only where
    its exact gamma lies inside the Eq. 13 bounds (not for random_beam(5, 2), n = 2: 1.4 %, gamma
    at a bound), which it does for this planform (measured ~4e-13 %)."""
    beam = random_beam(5, 4)
    truth = bending_frequencies(beam, model="beam", modes=n)
    r = fit_prbdm(beam, truth.omega, joints=n, law=law, poses="linear", starts=16)
    assert r.loss_percent < 1e-8
    assert r.freq_error.max() < 1e-9


def test_exact_fit_does_not_break_the_optimiser():
    """A start that fits exactly (linear poses, r = n) has a non-finite gradient (a norm at
    zero); it once sent NaN steps into the batched line search and eigvalsh raised."""
    beam = Beam(x=[0, 0.4, 1], half_width=[0.2, 0.1, 0.05], thickness=0.02)
    om = bending_frequencies(beam, model="beam", modes=5).omega
    fit = fit_prbdm(beam, om, joints=4, poses="linear", starts=32)
    assert math.isfinite(fit.loss_percent) and fit.loss_percent < 1e-8
    assert np.all(np.isfinite(fit.gamma)) and abs(fit.gamma.sum() - 1) < 1e-12


def test_fits_are_reproducible_with_a_seed():
    beam = random_beam(6, 0)
    om = proxy_truth(beam)
    a = fit_prbdm(beam, om, joints=3, starts=12, seed=7)
    b = fit_prbdm(beam, om, joints=3, starts=12, seed=7)
    assert np.array_equal(a.gamma, b.gamma) and np.array_equal(a.k, b.k)
    assert a.loss_percent == b.loss_percent
    # the seed is what makes them equal: the start points depend on it, and only on it
    s7, s7_again, s8 = start_points(3, 12, 7), start_points(3, 12, 7), start_points(3, 12, 8)
    assert torch.equal(s7, s7_again)
    assert not torch.equal(s7, s8)
    assert torch.equal(s7[:4], s8[:4])             # the four fixed segmentations come first
    assert not torch.isclose(s7[4:], s8[4:]).all(-1).any()   # every drawn start differs
    assert a.seed == 7


def _fit_json(path, seed):
    r = subprocess.run([sys.executable, "-m", "prbdm.cli", "fit", str(path), "--joints", "2",
                        "--starts", "8", "--seed", str(seed), "--json"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    out.pop("time_s")
    out["truth"].pop("time_s")
    return out


def test_fit_command_is_reproducible_across_processes(tmp_path):
    """Two processes, the same seed: the same JSON bit for bit (timings aside)."""
    path = tmp_path / "beam.json"
    Beam(x=[0.0, 0.4, 1.0], half_width=[0.2, 0.1, 0.05], thickness=0.02).to_json(path)
    a, b = _fit_json(path, 5), _fit_json(path, 5)
    assert a == b
    assert a["seed"] == 5 and a["starts"] == 8
    # another seed: other start points (the JSON has only the seed and the multistart's summary;
    # the start points themselves are start_points(n, starts, seed), checked above)
    c = _fit_json(path, 6)
    assert c["seed"] == 6
    assert not torch.equal(start_points(2, 8, 5), start_points(2, 8, 6))


def test_batched_fit_equals_one_at_a_time():
    beams = [random_beam(8, i) for i in range(3)]
    om = np.stack([proxy_truth(b) for b in beams])
    together = fit_many(FitProblem(beams, om, 3), starts=12)
    for b, o, t in zip(beams, om, together):
        alone = fit_prbdm(b, o, joints=3, starts=12)
        assert alone.best_objective_percent == pytest.approx(t.best_objective_percent, rel=1e-6)


def test_uniform_beam_fit_beats_the_papers_segmentation():
    """Test problem 1 (Table 2, analytic truth, 3 modes): whatever the paper's optimum is in our
    model (with rotary inertia), our fit must be at least as good as it."""
    om = analytic_omega()
    for n, paper_gamma in [(3, [0.7447, 0.0466, 0.0725, 0.1362]),
                           (4, [0.7555, 0.0369, 0.1323, 0.0281, 0.0472])]:
        g = torch.tensor(paper_gamma, dtype=torch.float64)
        g = g / g.sum()
        lam1 = eigenvalues(UNIFORM, g, None, "paper")[..., :3]
        t = torch.tensor(om[:3]) ** 2
        k = (lam1 * t).sum(-1) / (lam1 * lam1).sum(-1)           # best k for the paper's gamma
        paper_loss = float(loss_percent(lam1 * k[:, None], t, 3))
        r = fit_prbdm(UNIFORM, om, joints=n, modes=3)
        assert r.loss_percent <= paper_loss
        assert r.loss_percent < 0.1


def test_fit_reports_how_well_determined_it_is():
    beam = random_beam(9, 0)
    r = fit_prbdm(beam, proxy_truth(beam), joints=3, starts=24)
    assert 1 <= r.n_near_best <= 24
    assert 0 <= r.gamma_spread <= 1
    assert r.best_objective_percent <= r.loss_percent <= r.best_objective_percent * (1 + 1e-3) + 1e-12


def test_fit_bad_input():
    beam = random_beam(1, 0)
    om = proxy_truth(beam)
    with pytest.raises(BadInput, match="joints"):
        fit_prbdm(beam, om, joints=0)
    with pytest.raises(BadInput, match="joints"):
        fit_prbdm(beam, om, joints=40)
    with pytest.raises(BadInput, match="law"):
        fit_prbdm(beam, om, joints=2, law="spring")
    with pytest.raises(BadInput, match="omega_truth"):
        fit_prbdm(beam, om[:2], joints=3)
    with pytest.raises(BadInput, match="omega_truth"):
        fit_prbdm(beam, om[::-1], joints=3)
    with pytest.raises(BadInput, match="starts"):
        fit_prbdm(beam, om, joints=2, starts=0)


@pytest.mark.slow
def test_default_fit_is_globally_good():
    """Default settings reach within 1 % of a 10x longer search (10x starts, 10x iterations)."""
    beams = [random_beam(11, i) for i in range(20)]
    om = np.stack([proxy_truth(b) for b in beams])
    default = fit_many(FitProblem(beams, om, 4))
    long = fit_many(FitProblem(beams, om, 4), starts=640, seed=99, stop=StopRules(max_iter=1500))
    for d, l in zip(default, long):
        assert d.loss_percent <= 1.01 * l.best_objective_percent


def test_several_starts_per_beam_and_refine_starts():
    """init_gamma (B, H, n+1): each beam's own start set, the best kept; refine_starts appends
    the fit's four fixed starts."""
    beams = [random_beam(0, i) for i in (1, 2)]
    om = np.stack([bending_frequencies(b, model="beam", modes=3).omega for b in beams])
    full = fit_many(FitProblem(beams, om, 2), starts=16, seed=0)
    bad = np.full((2, 3), 1 / 3)                       # equal links: far from both optima
    starts = np.stack([np.stack([bad[0], f.gamma]) for f in full])       # (2, 2, 3)
    again = fit_many(FitProblem(beams, om, 2), init_gamma=starts, stop=StopRules(max_iter=5))
    for a, f in zip(again, full):
        # a start on a bound is nudged off it (INIT_Z_FLOOR), hence not exactly the same loss
        assert a.n_starts == 2 and a.best_objective_percent <= f.best_objective_percent * (1 + 1e-4)
    s = refine_starts(starts)
    assert s.shape == (2, 6, 3)
    np.testing.assert_array_equal(s[:, :2], starts)
    np.testing.assert_allclose(s[:, 2], np.broadcast_to([0.25, 0.5, 0.25], (2, 3)))
    np.testing.assert_allclose(s[:, 3], 1 / 3)
    np.testing.assert_allclose(s[:, 4], np.broadcast_to(long_root_gamma(2, 0.8), (2, 3)))
    np.testing.assert_allclose(s[:, 5], np.broadcast_to(long_root_gamma(2, 0.65), (2, 3)))
    with pytest.raises(BadInput, match="init_gamma"):
        fit_many(FitProblem(beams, om, 2), init_gamma=np.full((3, 3), 1 / 3))


def test_stopping_starts_that_fall_behind_keeps_the_optimum(monkeypatch):
    """Rows that at their recent pace cannot reach their beam's best loss stop early (fit._bfgs):
    the fit is faster, the loss unchanged. Beam 36 of seed 2019 is where a 10-iteration window
    stopped the one start that reaches the best optimum (0.1506 % against 0.1790 %)."""
    import prbdm.fit as fit_module

    beam = random_beam(2019, 36)
    om = proxy_truth(beam)
    fast = fit_prbdm(beam, om, joints=4)
    orig = fit_module._bfgs

    def rule_off(problem, z, rules, progress=None):   # a window past the budget: never applies
        return orig(problem, z, dataclasses.replace(rules, window=10 ** 6), progress)

    monkeypatch.setattr(fit_module, "_bfgs", rule_off)
    full = fit_prbdm(beam, om, joints=4)
    assert fast.loss_percent <= full.loss_percent * (1 + 1e-4)
    assert fast.iterations <= full.iterations


def test_start_design_fixed_segmentations_then_half_long_root_draws():
    for n, S in ((1, 8), (4, 64), (5, 128), (9, 20)):
        g = gamma_from_z(start_points(n, S, 3))
        assert g.shape == (S, n + 1)
        assert torch.allclose(g.sum(-1), torch.ones(S, dtype=torch.float64), atol=1e-14)
        assert (g >= GAMMA_MIN - 1e-15).all() and (g <= GAMMA_MAX + 1e-15).all()
        # fixed: rigid-finite-element, equal links, two long roots (to the z floor: each link
        # at its bound is lifted by <= 4e-4, the others give that up)
        tol = 4e-4 * (n + 1)
        assert torch.allclose(g[0], uniform_gamma(n), atol=tol)
        assert torch.allclose(g[1], torch.full((n + 1,), 1.0 / (n + 1), dtype=torch.float64),
                              atol=tol)
        assert torch.allclose(g[2], long_root_gamma(n, 0.8), atol=tol)
        assert torch.allclose(g[3], long_root_gamma(n, 0.65), atol=tol)
        # half of all starts are long-root draws: root fraction in the range (after the bounds)
        lo, hi = (GAMMA_MIN + (1 - (n + 1) * GAMMA_MIN) * v for v in LONG_ROOT_RANGE)
        root = g[4:4 + S // 2, 0]
        assert ((root >= lo - 1e-12) & (root <= hi + 1e-12)).all()
    assert torch.allclose(long_root_gamma(4, 0.8),
                          torch.tensor([0.8, 0.2 / 7, 0.4 / 7, 0.4 / 7, 0.4 / 7], dtype=torch.float64))


def test_long_root_starts_find_the_long_root_optimum(monkeypatch):
    """Beam 42 of seed 7: its best optimum has a root link of 0.77 (gamma [0.765, 0.033, 0.065,
    0.063, 0.074]), in the corner of the simplex that flat draws almost never reach. The default
    fit finds it; the earlier design (two fixed starts, then flat draws only) stopped 21 % above
    it. The reference is a local fit started at that optimum, independent of the start design."""
    import prbdm.fit as fit_module

    beam = random_beam(7, 42)
    om = proxy_truth(beam)
    ref = fit_many(FitProblem([beam], om[None], 4),
                   init_gamma=[[0.765, 0.033, 0.065, 0.063, 0.074]])[0]
    new = fit_prbdm(beam, om, joints=4)
    assert new.loss_percent <= ref.loss_percent * 1.01

    def flat_only(n, starts, seed, dtype=torch.float64):
        fixed = [uniform_gamma(n, dtype), torch.full((n + 1,), 1.0 / (n + 1), dtype=dtype)]
        y = np.random.default_rng([int(seed), n]).dirichlet(np.ones(n + 1), size=starts - 2)
        drawn = torch.as_tensor(GAMMA_MIN + (1 - (n + 1) * GAMMA_MIN) * y, dtype=dtype)
        return fit_module.z_from_gamma(torch.cat([torch.stack(fixed), drawn]))

    monkeypatch.setattr(fit_module, "start_points", flat_only)
    old = fit_prbdm(beam, om, joints=4)
    assert old.loss_percent > ref.loss_percent * 1.1


# ----------------------------------------------------------------------------- the optimiser's structure
#: how much worse than the recorded optimum a short fit may end on another CPU (see below)
RECORDED_SLACK = 1.5


def test_fits_are_no_worse_than_recorded():
    """Multistart and refinement fits, both objectives (tests/fit_reference_cases.py), against
    the optimum each reached when it was recorded (tests/data/fit_reference.json): the minimised
    objective is no worse than RECORDED_SLACK times it, every gamma is inside the bounds and sums
    to 1, k is positive, and every start was run. A property, not the bits of one machine: these
    runs stop after 12-40 iterations, and another CPU rounds them differently, which can end a
    start in a neighbouring optimum (measured: 1.20 times the recorded loss under
    ATEN_CPU_CAPABILITY=default, equal on this machine's own kernels)."""
    from fit_reference_cases import cases, reference

    ref = reference()
    now = cases()
    assert now.keys() == ref["cases"].keys()

    def num(v):
        return np.array([float.fromhex(x) if isinstance(x, str) else float(x)
                         for x in np.atleast_1d(v)])

    for name, results in ref["cases"].items():
        key = "loss_percent" if name.startswith("eigenvalue") else "frequency_percent"
        for got, want in zip(now[name], results, strict=True):
            got_obj, want_obj = num(got[key])[0], num(want[key])[0]
            assert got_obj <= want_obj * RECORDED_SLACK + 1e-12, (name, got_obj, want_obj)
            gamma = num(got["gamma"])
            assert abs(gamma.sum() - 1) < 1e-12, name
            assert np.all((gamma >= GAMMA_MIN - 1e-12) & (gamma <= GAMMA_MAX + 1e-12)), name
            assert np.all(num(got["k"]) > 0) and got["n_starts"] == want["n_starts"], name


def test_fit_device_follows_the_truth_tensor_and_is_numpy_out():
    beam = random_beam(3, 1)
    om = proxy_truth(beam)
    short = StopRules(max_iter=10)
    base = fit_many(FitProblem([beam], om[None], 3), starts=4, stop=short)
    on_cpu = fit_many(FitProblem([beam], torch.tensor(om[None]), 3), starts=4, stop=short)
    named = fit_many(FitProblem([beam], om[None], 3), starts=4, stop=short, device="cpu")
    for r in (on_cpu[0], named[0]):
        assert isinstance(r.gamma, np.ndarray) and isinstance(r.omega, np.ndarray)
        assert np.array_equal(r.gamma, base[0].gamma) and r.loss_percent == base[0].loss_percent
    with pytest.raises(BadInput, match="device"):
        fit_many(FitProblem([beam], om[None], 3), starts=4, device="nowhere")


@pytest.mark.skipif(not torch.cuda.is_available(), reason="no GPU here")
def test_fit_on_gpu_matches_cpu():
    beam = random_beam(3, 1)
    om = proxy_truth(beam)
    cpu = fit_many(FitProblem([beam], om[None], 3), starts=8, stop=StopRules(max_iter=40))[0]
    gpu = fit_many(FitProblem([beam], torch.tensor(om[None], device="cuda"), 3), starts=8,
                   stop=StopRules(max_iter=40))[0]
    assert isinstance(gpu.gamma, np.ndarray)
    assert gpu.loss_percent == pytest.approx(cpu.loss_percent, rel=1e-6)
