"""The two fit objectives: closed-form SCFs against brute-force minimisation, the envelope-theorem
gradient against finite differences, and the eigenvalue loss against prbdm.model.loss_percent."""
import numpy as np
import pytest
import torch
from scipy.optimize import minimize_scalar

from prbdm import objectives as ob
from prbdm.errors import BadInput
from prbdm.model import loss_percent


def _mu_and_truth(seed=0, rows=3, m=5, r=4):
    g = torch.Generator().manual_seed(seed)
    lam_t = torch.sort(torch.rand(rows, r, generator=g, dtype=torch.float64) * 100 + 1).values
    mu = lam_t[:, None, :] * (1 + 0.3 * torch.rand(rows, m, r, generator=g, dtype=torch.float64))
    return mu, lam_t


def test_eigenvalue_scf_is_the_least_squares_optimum():
    mu, lam_t = _mu_and_truth()
    res, k = ob.eigenvalue_residuals(mu, lam_t)
    for b in range(mu.shape[0]):
        for i in range(mu.shape[1]):
            f = lambda kk: float(torch.linalg.vector_norm(kk * mu[b, i] - lam_t[b]))
            best = minimize_scalar(f, bounds=(0.1, 10), method="bounded",
                                   options={"xatol": 1e-12}).x
            assert k[b, i].item() == pytest.approx(best, rel=1e-7)
    lam = k[..., None] * mu
    assert torch.allclose(ob.eigenvalue_loss(res), loss_percent(lam, lam_t), rtol=1e-12)


def test_frequency_scf_minimises_the_p_norm():
    mu, lam_t = _mu_and_truth(1)
    res, k = ob.frequency_residuals(mu, lam_t)
    for b in range(mu.shape[0]):
        for i in range(mu.shape[1]):
            def f(logk):
                e = 0.5 * (logk + torch.log(mu[b, i]) - torch.log(lam_t[b]))
                return float(torch.linalg.vector_norm(e, ord=ob.FREQUENCY_P))
            best = minimize_scalar(f, bounds=(-3, 3), method="bounded",
                                   options={"xatol": 1e-12}).x
            assert np.log(k[b, i].item()) == pytest.approx(best, abs=1e-6)
            assert f(np.log(k[b, i].item())) <= f(best) * (1 + 1e-12)


def test_frequency_loss_is_a_smooth_maximum():
    mu, lam_t = _mu_and_truth(2)
    res, _ = ob.frequency_residuals(mu, lam_t)
    per_pose = torch.linalg.vector_norm(res, ord=ob.FREQUENCY_P, dim=-1)
    worst = res.abs().amax(-1)
    r = res.shape[-1]
    assert (per_pose >= worst * (1 - 1e-12)).all()
    assert (per_pose <= worst * r ** (1 / ob.FREQUENCY_P) * (1 + 1e-12)).all()
    # log errors against exact relative errors at the optimum: within e^2/2
    omega_ratio = torch.sqrt(torch.exp(2 * res))
    assert torch.allclose((omega_ratio - 1).abs(), res.abs(), atol=float(worst.max()) ** 2)


def test_frequency_gradient_matches_finite_differences():
    """The SCF is computed without autograd; the gradient is still the full derivative of the
    re-optimised loss (envelope theorem)."""
    mu, lam_t = _mu_and_truth(3, rows=1)
    mu = mu.clone().requires_grad_(True)
    f = ob.frequency_loss(ob.frequency_residuals(mu, lam_t)[0]).sum()
    (g,) = torch.autograd.grad(f, mu)
    h = 1e-6
    for idx in [(0, 0, 0), (0, 2, 3), (0, 4, 1)]:
        mp, mm = mu.detach().clone(), mu.detach().clone()
        mp[idx] += h
        mm[idx] -= h
        fd = (ob.frequency_loss(ob.frequency_residuals(mp, lam_t)[0]).sum()
              - ob.frequency_loss(ob.frequency_residuals(mm, lam_t)[0]).sum()) / (2 * h)
        assert g[idx].item() == pytest.approx(fd.item(), rel=1e-5, abs=1e-9)


def test_frequency_measure_of_optimal_k_equals_the_loss():
    mu, lam_t = _mu_and_truth(4)
    res, k = ob.frequency_residuals(mu, lam_t)
    lam = k[..., None] * mu
    assert torch.allclose(ob.frequency_measure(lam, lam_t, 4), ob.frequency_loss(res))


def test_unknown_objective_names_the_choices():
    with pytest.raises(BadInput, match="eigenvalue, frequency"):
        ob.check_objective("freq")


def test_frequency_fit_puts_every_mode_closer_than_the_paper_fit():
    """On a tapered beam the paper's loss leaves mode 1 far off; the frequency objective brings
    the worst mode down, and both results report both measures."""
    from prbdm.fit import fit_prbdm
    from prbdm.geometry import Beam
    from prbdm.truth import bending_frequencies
    beam = Beam(x=[0, 0.4, 1], half_width=[0.05, 0.03, 0.02], thickness=0.01)
    om = bending_frequencies(beam, "beam", 5).omega
    eig = fit_prbdm(beam, om, 4, starts=16)
    frq = fit_prbdm(beam, om, 4, starts=16, objective="frequency")
    assert frq.freq_error.max() < 0.5 * eig.freq_error.max()
    assert eig.loss_percent < frq.loss_percent          # each wins on its own measure
    assert frq.frequency_percent < eig.frequency_percent
    assert frq.to_dict()["objective"] == "frequency"
