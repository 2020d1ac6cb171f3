"""prbdm.chain (NumPy) against its torch twin prbdm.model: links, base stiffness of both laws,
mass matrix and eigenvalues on random beams and poses; the chain's two ways of integrating
spans (cumulative, for the batched prediction; ``direct``, to round-off) and its roll inertia;
the laws' one home. tests/test_surrogate.py checks the batched prediction's (cumulative) path."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from prbdm import chain, model
from prbdm.constants import GAMMA_MIN
from prbdm.errors import BadInput
from prbdm.geometry import Beam, random_beam

EPS = np.finfo(np.float64).eps
BEAMS = [random_beam(0, i) for i in range(12)] + [
    Beam(x=[0, 0.4, 1.3], half_width=[0.2, 0.05, 0.11], thickness=0.02),
    Beam(x=[0.0, 0.35, 1.0], half_width=[0.18, 0.12, 0.05], thickness=0.03)]


def random_chains(n, seed):
    """Link fractions (B, n+1) down to GAMMA_MIN and poses (4, n): straight and three random."""
    rng = np.random.default_rng(seed)
    g = GAMMA_MIN + (1 - (n + 1) * GAMMA_MIN) * rng.dirichlet(np.ones(n + 1), len(BEAMS))
    poses = np.vstack([np.zeros((1, n)), rng.uniform(-1.0, 1.0, (3, n))])
    return g, poses


@pytest.mark.parametrize("law", chain.LAWS)
@pytest.mark.parametrize("n", [1, 3, 6])
def test_numpy_chain_matches_the_torch_model(n, law):
    bb = chain.BeamBatch.from_beams(BEAMS)
    bt = model.BeamTensors.from_beams(BEAMS)
    g, poses = random_chains(n, seed=n)
    lt = model.links_from_gamma(bt, torch.as_tensor(g))
    ln = chain.links_from_gamma(bb.x, bb.w, g, direct=True)
    for key, v in ln.items():
        np.testing.assert_allclose(v, getattr(lt, key).numpy(), rtol=1e-13, atol=0, err_msg=key)
    # base stiffness, nondimensional and in SI (the torch model's unit rho t L^4 lambda0 = E t^3)
    s_t = model.base_stiffness(bt, lt, law).numpy()
    np.testing.assert_allclose(chain.base_stiffness(ln, law, bb), s_t, rtol=1e-13, atol=0)
    unit = (bt.rho * bt.thickness * bt.length ** 4 * bt.lambda0).numpy()[:, None]
    np.testing.assert_allclose(chain.base_stiffness(ln, law, bb, si=True), s_t * unit,
                               rtol=1e-13, atol=0)
    table = chain.link_table(bb, g, law=law, direct=True)
    np.testing.assert_allclose(table["base_stiffness"], s_t * unit, rtol=1e-13, atol=0)
    # the mass matrix at every pose
    M_t = model.mass_matrix(model._expand_links(lt), torch.as_tensor(poses)).numpy()
    M_n = chain.mass_matrix(ln, poses)
    assert np.max(np.abs(M_n - M_t)) <= 1e-14 * np.max(np.abs(M_t))
    # eigenvalues: the first mode to round-off; mode i within a few eps lam_i / lam_1, the
    # symmetric eigensolvers' own accuracy (prbdm.model's docstring), which is 1e-12 relative
    # up to lam_i / lam_1 ~ 1e3
    ref = model.eigenvalues_unit_k(bt, torch.as_tensor(g), torch.as_tensor(poses), law).numpy()
    got = chain.prbdm_eigenvalues(bb.x, bb.w, g, poses, law=law, batch=bb, direct=True)
    rel = np.abs(got / ref - 1)
    assert rel[..., 0].max() < 1e-14
    assert np.all(rel <= 16 * EPS * ref / ref[..., :1])
    assert np.all(rel[ref / ref[..., :1] < 1e3] < 1e-12)


def test_cumulative_spans_agree_with_direct_ones():
    """The batched prediction's cumulative integrals against each span integrated on its own:
    areas to 1e-12, centred second moments of short spans far from the root to ~1e-10 (they
    cancel); the roll inertia to 1e-12."""
    bb = chain.BeamBatch.from_beams(BEAMS)
    rng = np.random.default_rng(3)
    a = rng.uniform(0, 0.975, (len(BEAMS), 20))
    b = np.minimum(a + rng.uniform(0.025, 0.5, a.shape), 1.0)
    fast = chain.span_integrals(bb.x, bb.w, a, b, roll=True)
    exact = chain.span_integrals(bb.x, bb.w, a, b, direct=True, roll=True)
    for i in (0, 3, 4):                     # area, compliance, roll inertia
        np.testing.assert_allclose(fast[i], exact[i], rtol=1e-12, atol=0)
    area, first, second = exact[:3]
    J = second - first ** 2 / area
    J_fast = fast[2] - fast[1] ** 2 / fast[0]
    np.testing.assert_allclose(J_fast, J, rtol=1e-9, atol=0)
    g, _ = random_chains(5, seed=4)
    slow = chain.links_from_gamma(bb.x, bb.w, g, direct=True)
    for key, v in chain.links_from_gamma(bb.x, bb.w, g).items():
        np.testing.assert_allclose(v, slow[key], rtol=1e-9, atol=0, err_msg=key)


def test_roll_inertia_by_hand():
    """∫ (2/3) w^3 dx: exact (Simpson) on a linear taper, whichever way it is integrated."""
    x = np.array([[0.0, 0.3, 1.0]])
    w = np.array([[0.2, 0.1, 0.05]])
    a, b = np.array([[0.0, 0.1, 0.3, 0.5]]), np.array([[1.0, 0.3, 0.8, 0.5]])

    def exact(lo, hi):   # antiderivative of (2/3) w^3 on each linear piece
        total = 0.0
        for x0, x1, w0, w1 in zip(x[0, :-1], x[0, 1:], w[0, :-1], w[0, 1:]):
            p, q = max(lo, x0), min(hi, x1)
            if q > p:
                slope = (w1 - w0) / (x1 - x0)
                wp, wq = w0 + slope * (p - x0), w0 + slope * (q - x0)
                total += (wq ** 4 - wp ** 4) / (6 * slope)
        return total
    ref = [exact(lo, hi) for lo, hi in zip(a[0], b[0])]
    for direct in (False, True):
        roll = chain.span_integrals(x, w, a, b, direct=direct, roll=True)[4][0]
        np.testing.assert_allclose(roll, ref, rtol=1e-14, atol=1e-17)
    assert len(chain.span_integrals(x, w, a, b)) == 4


def test_base_stiffness_laws_have_one_home():
    assert model.LAWS is chain.LAWS
    bb = chain.BeamBatch.from_beams(BEAMS[:2])
    links = chain.links_from_gamma(bb.x, bb.w, np.full((2, 3), 1 / 3))
    with pytest.raises(BadInput, match="law: must be one of beam, paper"):
        chain.base_stiffness(links, "spring")
    with pytest.raises(BadInput, match="needs the beams"):
        chain.base_stiffness(links, "paper")
    with pytest.raises(BadInput, match="needs the beams"):
        chain.base_stiffness(links, "beam", si=True)
    # the paper law, Eq. 11 as printed: sqrt(E I_j / m_j) with I_j / m_j = t^2 / (12 rho l_j)
    table = chain.link_table(bb, np.full((2, 3), 1 / 3), law="paper")
    np.testing.assert_allclose(table["base_stiffness"],
                               np.sqrt(bb.E[:, None] * table["area_moment"] / table["mass"]),
                               rtol=1e-14)
