"""The differentiable PRBDM (prbdm.model) against independent references.

- M(theta) is the Hessian in thetadot of the kinetic energy computed by autograd from explicit
  forward kinematics (homogeneous transforms, written here, not model.py's formulas), both from the
  links' mass/centre/inertia and from the material points of the planform directly;
- n = 1 is the spring-pendulum omega^2 = k s / (m c^2 + J) with m, c, J and s integrated by hand;
- the beam law with k = 1 and the rigid-finite-element segmentation converges to Euler-Bernoulli
  at second order;
- gradients pass gradcheck (float64), and stay finite at theta = 0 and at a repeated eigenvalue;
- batched == one at a time.
"""
import math

import numpy as np
import pytest
import torch
from scipy.optimize import fsolve

from prbdm import model
from prbdm.errors import BadInput
from prbdm.geometry import Beam, Material, random_beam


@pytest.fixture(autouse=True)
def _float64():
    """float64 for every tensor made in these tests, restored afterwards (no leak elsewhere)."""
    old = torch.get_default_dtype()
    torch.set_default_dtype(torch.float64)
    yield
    torch.set_default_dtype(old)

# torch.func.jvp scripts its decompositions on first use, which warns in torch >= 2.10
pytestmark = pytest.mark.filterwarnings(
    "ignore:`torch.jit.script` is deprecated")

ALPHA = np.array([1.87510407, 4.69409113, 7.85475744])  # cos a cosh a = -1


# --------------------------------------------------------------------------- independent kinematics
def _rot(a):
    c, s = torch.cos(a), torch.sin(a)
    z, o = torch.zeros_like(a), torch.ones_like(a)
    return torch.stack([torch.stack([c, -s, z]), torch.stack([s, c, z]), torch.stack([z, z, o])])


def _trans(dx):
    z, o = torch.zeros_like(dx), torch.ones_like(dx)
    return torch.stack([torch.stack([o, z, dx]), torch.stack([z, o, z]), torch.stack([z, z, o])])


def _frames(theta, joints, lengths):
    """Homogeneous transform of each link's frame (origin at its joint, x along the link):
    ground -> translate to joint 1 -> rotate theta_1 -> translate l_1 -> rotate theta_2 -> ..."""
    T = _trans(torch.as_tensor(joints[0]))
    frames = []
    for j in range(len(theta)):
        T = T @ _rot(theta[j])
        frames.append(T)
        T = T @ _trans(torch.as_tensor(lengths[j]))
    return frames


def _point(frame, s):
    return (frame @ torch.stack([torch.as_tensor(s), torch.tensor(0.0), torch.tensor(1.0)]))[:2]


def _gauss_points(beam, a, b, order=3):
    """Gauss-Legendre points and weights of ∫_a^b 2 w(x) f(x) dx, split at the stations (exact
    for polynomial f of degree <= 2 * order - 2)."""
    g, gw = np.polynomial.legendre.leggauss(order)
    cuts = np.concatenate([[a], [s for s in beam.x if a < s < b], [b]])
    pts, wts = [], []
    for lo, hi in zip(cuts[:-1], cuts[1:]):
        x = (lo + hi) / 2 + (hi - lo) / 2 * g
        pts.append(x)
        wts.append((hi - lo) / 2 * gw * 2 * np.interp(x, beam.x, beam.half_width))
    return np.concatenate(pts), np.concatenate(wts)


def _links_by_quadrature(beam, gamma):
    """Joint positions, link lengths, masses, centres (from the joint), inertias about the centre,
    all by Gauss quadrature of the planform (rho t = 1, lengths in the beam's units)."""
    L = beam.length
    cuts = L * np.concatenate([[0.0], np.cumsum(gamma[:-1]), [1.0]])
    out = []
    for j in range(1, len(gamma)):
        x, wt = _gauss_points(beam, cuts[j], cuts[j + 1])
        m = wt.sum()
        c = (wt * (x - cuts[j])).sum() / m
        J = (wt * (x - cuts[j] - c) ** 2).sum()
        out.append((m, c, J))
    m, c, J = map(np.array, zip(*out))
    return cuts[1:-1], np.diff(cuts)[1:], m, c, J


def _hessian_of_T(T, n):
    return torch.autograd.functional.hessian(T, torch.zeros(n))


def mass_matrix_from_links(beam, gamma, theta):
    """Hessian in thetadot of T = 1/2 Σ (m |v_c|^2 + J qdot^2), v_c by jvp of explicit FK."""
    joints, lengths, m, c, J = _links_by_quadrature(beam, gamma)
    n = len(theta)

    def centres_and_angles(th):
        frames = _frames(th, joints, lengths)
        rc = torch.stack([_point(F, c[j]) for j, F in enumerate(frames)])
        q = torch.stack([torch.atan2(F[1, 0], F[0, 0]) for F in frames])
        return rc, q

    def T(thetadot):
        (_, _), (vc, qdot) = torch.func.jvp(centres_and_angles, (theta,), (thetadot,))
        return 0.5 * (torch.tensor(m) * (vc ** 2).sum(-1) + torch.tensor(J) * qdot ** 2).sum()

    return _hessian_of_T(T, n)


def mass_matrix_from_material_points(beam, gamma, theta):
    """Hessian in thetadot of T = 1/2 ∫ dm |v|^2 over the planform's material points (no mass,
    centre or inertia computed anywhere)."""
    joints, lengths, *_ = _links_by_quadrature(beam, gamma)
    L = beam.length
    cuts = L * np.concatenate([[0.0], np.cumsum(gamma[:-1]), [1.0]])
    quad = [_gauss_points(beam, cuts[j], cuts[j + 1]) for j in range(1, len(gamma))]

    def points(th):
        frames = _frames(th, joints, lengths)
        return torch.cat([torch.stack([_point(F, xq - cuts[j + 1]) for xq in quad[j][0]])
                          for j, F in enumerate(frames)])

    weights = torch.tensor(np.concatenate([q[1] for q in quad]))

    def T(thetadot):
        _, v = torch.func.jvp(points, (theta,), (thetadot,))
        return 0.5 * (weights * (v ** 2).sum(-1)).sum()

    return _hessian_of_T(T, len(theta))


def _model_M(beam, gamma, theta):
    bt = model.BeamTensors.from_beams(beam)
    links = model.links_from_gamma(bt, torch.tensor(gamma))
    return model.mass_matrix(links, theta)


def _random_gamma(rng, n):
    g = rng.uniform(0.3, 1.0, n + 1)
    return g / g.sum()


@pytest.mark.parametrize("n", [1, 2, 5])
def test_mass_matrix_is_hessian_of_kinetic_energy(n):
    rng = np.random.default_rng(n)
    beam = random_beam(42, n, p=6)                    # L = 1: nondimensional == SI / (rho t)
    gamma = _random_gamma(rng, n)
    for theta in [torch.zeros(n), torch.tensor(rng.uniform(-1.5, 1.5, n)),
                  torch.tensor(rng.uniform(-3, 3, n))]:
        M = _model_M(beam, gamma, theta)
        M_links = mass_matrix_from_links(beam, gamma, theta)
        M_points = mass_matrix_from_material_points(beam, gamma, theta)
        torch.testing.assert_close(M, M_links, rtol=1e-11, atol=1e-14)
        torch.testing.assert_close(M, M_points, rtol=1e-11, atol=1e-14)
        torch.testing.assert_close(M, M.mT, rtol=1e-14, atol=1e-16)
        assert torch.linalg.eigvalsh(M).min() > 0


def test_mass_matrix_positive_definite_at_theta_zero_many_links():
    beam = random_beam(1, 1)
    for n in (1, 2, 5, 20):
        M = _model_M(beam, model.uniform_gamma(n).numpy(), torch.zeros(n))
        ev = torch.linalg.eigvalsh(M)
        assert ev.min() > 0, n
        torch.testing.assert_close(M, M.mT, rtol=1e-14, atol=1e-16)


def test_mass_matrix_batched_poses_and_lengths_non_unit():
    """A 2.3 m beam, SI link table: the model's nondimensional M times rho t L^4 equals the Hessian
    computed in metres."""
    beam = Beam(x=[0.0, 0.9, 2.3], half_width=[0.4, 0.25, 0.07], thickness=0.02)
    gamma = np.array([0.3, 0.2, 0.25, 0.25])
    poses = torch.tensor([[0.0, 0.0, 0.0], [0.2, -0.4, 1.0], [1.0, 2.0, -3.0]])
    M = _model_M(beam, gamma, poses) * beam.length ** 4
    for i in range(3):
        torch.testing.assert_close(M[i], mass_matrix_from_material_points(beam, gamma, poses[i]),
                                   rtol=1e-11, atol=1e-14)


# ----------------------------------------------------------------------------- single joint
def _trapezoid_link(wa, wb, h):
    """Hand-integrated link of length h with half-width wa -> wb (linear): per rho t,
    area A = h (wa + wb), centre c = h (wa + 2 wb) / (3 (wa + wb)) from the joint,
    ∫ 2 w s^2 ds = h^3 (wa + 3 wb) / 6, J = that - A c^2."""
    A = h * (wa + wb)
    c = h * (wa + 2 * wb) / (3 * (wa + wb))
    J = h ** 3 * (wa + 3 * wb) / 6 - A * c ** 2
    return A, c, J


@pytest.mark.parametrize("law", ["beam", "paper"])
@pytest.mark.parametrize("w0, w1", [(0.18, 0.18), (0.3, 0.05), (0.02, 0.4)])
def test_single_joint_spring_pendulum(law, w0, w1):
    L, t = 2.3, 0.021
    mat = Material(E=70e9, rho=2700.0, nu=0.33)
    beam = Beam(x=[0.0, L], half_width=[w0, w1], thickness=t, material=mat)
    g0 = 0.37
    a = g0 * L
    h = L - a
    wa = w0 + (w1 - w0) * a / L
    A, c, J1 = _trapezoid_link(wa, w1, h)
    m, J = mat.rho * t * A, mat.rho * t * J1
    if law == "beam":
        # ∫_0^L dx / (E I), I = 2 w t^3 / 12, w linear from w0 to w1
        inv_w = L / w0 if w0 == w1 else L * math.log(w1 / w0) / (w1 - w0)
        s = mat.E * t ** 3 / 6 / inv_w
    else:
        I_mean = t ** 3 / 12 * A / h            # (1/h) ∫ 2 w t^3 / 12 dx
        s = math.sqrt(mat.E * I_mean / m)
    k = 1.7
    expected = k * s / (m * c ** 2 + J)

    lam = model.eigenvalues(beam, torch.tensor([g0, 1 - g0]), k=torch.full((30,), k), law=law)
    assert lam.shape == (30, 1)                  # paper poses for n = 1: 0.1 ... 1.55
    np.testing.assert_allclose(lam.numpy(), expected, rtol=1e-12)

    bt = model.BeamTensors.from_beams(beam)
    phys = model.links_from_gamma(bt, torch.tensor([g0, 1 - g0])).physical(bt)
    assert phys["mass"].item() == pytest.approx(m, rel=1e-13)
    assert phys["com"].item() == pytest.approx(c, rel=1e-13)
    assert phys["inertia"].item() == pytest.approx(J, rel=1e-11)
    assert phys["joint_x"].item() == pytest.approx(a, rel=1e-14)
    assert phys["area_moment"].item() == pytest.approx(t ** 3 / 12 * A / h, rel=1e-13)


# ----------------------------------------------------------------------------- convergence
def test_beam_law_converges_to_euler_bernoulli_at_second_order():
    """k = 1, gamma = uniform_gamma(n): relative errors of the first three frequencies fall by 4
    per doubling of n. The same table is in docs/validation.md."""
    E, rho, b, t = 205e9, 7850.0, 0.3624, 0.040532
    beam = Beam(x=[0.0, 1.0], half_width=[b / 2, b / 2], thickness=t)
    I, A = b * t ** 3 / 12, b * t
    omega_eb = ALPHA ** 2 * np.sqrt(E * I / (rho * A))
    errs = []
    for n in (10, 20, 40, 80):
        lam = model.eigenvalues(beam, model.uniform_gamma(n), poses="linear")
        omega = lam[0, :3].sqrt().numpy()
        errs.append(np.abs(omega - omega_eb) / omega_eb)
    errs = np.array(errs)
    orders = np.log2(errs[:-1] / errs[1:])
    assert np.all((orders > 1.9) & (orders < 2.1)), orders
    assert errs[-1].max() < 3e-4


def test_paper_pose_counts():
    assert [model.paper_poses(n).shape[0] for n in (3, 4, 5)] == [9, 6, 5]
    p = model.paper_poses(4)
    assert torch.allclose(p[:, 0], 0.1 + 0.05 * torch.arange(6.0))
    assert (4 * p.max() <= math.pi / 2)
    assert model.paper_poses(20).shape == (1, 20)             # pi/40 < 0.1: one pose
    assert model.paper_poses(20)[0, 0].item() == pytest.approx(math.pi / 40)


def test_eigenvalues_scale_with_k_and_are_ascending():
    beam = random_beam(3, 3)
    g = torch.tensor([0.4, 0.2, 0.25, 0.15])
    lam1 = model.eigenvalues(beam, g)
    k = torch.linspace(0.5, 3.0, lam1.shape[0])
    torch.testing.assert_close(model.eigenvalues(beam, g, k), lam1 * k[:, None], rtol=1e-13, atol=0)
    assert torch.all(lam1[:, 1:] >= lam1[:, :-1])


# ----------------------------------------------------------------------------- gradients
def _free_gamma(g_free):
    return torch.cat([g_free, 1 - g_free.sum(-1, keepdim=True)], -1)


POSES3 = torch.tensor([[0.0, 0.0, 0.0], [0.1, 0.1, 0.1], [0.3, -0.2, 0.5]],
                      dtype=torch.float64)


@pytest.mark.parametrize("law", ["beam", "paper"])
def test_gradcheck_eigenvalues_wrt_gamma(law):
    bt = model.BeamTensors.from_beams(random_beam(5, 0, p=4))
    g_free = torch.tensor([0.31, 0.23, 0.17], requires_grad=True)
    assert torch.autograd.gradcheck(
        lambda g: model.eigenvalues_unit_k(bt, _free_gamma(g), POSES3, law), (g_free,))


def test_gradcheck_eigenvalues_wrt_k_and_loss():
    beam = random_beam(5, 1, p=4)
    bt = model.BeamTensors.from_beams(beam)
    scale = bt.lambda0
    g_free = torch.tensor([0.28, 0.26, 0.21], requires_grad=True)
    k = torch.tensor([1.3, 0.8, 2.1], requires_grad=True)
    assert torch.autograd.gradcheck(
        lambda k: model.eigenvalues(bt, _free_gamma(g_free.detach()), k, POSES3) / scale, (k,))
    lam_truth = model.eigenvalues(bt, torch.tensor([0.3, 0.25, 0.25, 0.2]), poses="linear")[0]
    lam_truth = lam_truth * torch.tensor([1.1, 0.9, 1.05])

    def loss(g, k):
        return model.loss_percent(model.eigenvalues(bt, _free_gamma(g), k, POSES3), lam_truth)

    assert torch.autograd.gradcheck(loss, (g_free, k))
    assert torch.autograd.gradcheck(lambda g, k: model.loss_percent(
        model.eigenvalues(bt, _free_gamma(g), k, POSES3), lam_truth, r=2), (g_free, k))


@pytest.mark.parametrize("law", ["beam", "paper"])
def test_gradcheck_eigenvalues_wrt_beam_geometry(law):
    beam = random_beam(9, 2, p=4)
    bt = model.BeamTensors.from_beams(beam)
    gamma = torch.tensor([0.33, 0.22, 0.27, 0.18])
    stations = np.cumsum(gamma.numpy())[:-1]
    assert np.min(np.abs(beam.x[:, None] - stations[None, :])) > 1e-3   # cuts off the stations
    xi = bt.x[1:-1].clone().requires_grad_(True)
    w = bt.w.clone().requires_grad_(True)
    t = bt.thickness.clone().requires_grad_(True)

    def f(xi, w, t):
        x = torch.cat([bt.x[:1], xi, bt.x[-1:]])
        b = model.BeamTensors(x, w, bt.length, t, bt.E, bt.rho)
        return model.eigenvalues(b, gamma, None, POSES3, law) / 1e4

    assert torch.autograd.gradcheck(f, (xi, w, t))


def test_gradients_finite_at_theta_zero():
    beam = random_beam(4, 4)
    g_free = torch.tensor([0.3, 0.3, 0.2], requires_grad=True)
    k = torch.tensor([1.0], requires_grad=True)
    lam = model.eigenvalues(beam, _free_gamma(g_free), k, poses="linear")
    for i in range(3):
        grads = torch.autograd.grad(lam[0, i], (g_free, k), retain_graph=True)
        assert all(torch.isfinite(g).all() for g in grads)


def _degenerate_case():
    """A uniform 2R model and pose where K^-1/2 M K^-1/2 is a multiple of the identity, i.e. the two
    eigenvalues coincide: solve A_12 = 0 and A_11 = A_22 for (theta_2, gamma_1), gamma_0 = 0.2."""
    bt = model.BeamTensors.from_beams(Beam(x=[0.0, 1.0], half_width=[0.2, 0.2], thickness=0.02))

    def A(p):
        gamma = torch.tensor([0.2, p[1], 0.8 - p[1]])
        links = model.links_from_gamma(bt, gamma)
        d = model.base_stiffness(bt, links).rsqrt()
        M = model.mass_matrix(links, torch.tensor([0.3, p[0]]))
        return (d[:, None] * M * d[None, :]).numpy()

    def F(p):
        a = A(p)
        return [a[0, 1] / a[0, 0], (a[0, 0] - a[1, 1]) / a[0, 0]]

    sol = fsolve(F, [2.5, 0.36], xtol=1e-13)
    return bt, sol


def test_gradients_finite_at_repeated_eigenvalue():
    bt, (theta2, g1) = _degenerate_case()
    assert 0.025 < g1 < 0.775
    poses = torch.tensor([[0.3, theta2]])
    g_free = torch.tensor([0.2, g1], requires_grad=True)
    w = bt.w.clone().requires_grad_(True)

    def lam_of(g, w):
        b = model.BeamTensors(bt.x, w, bt.length, bt.thickness, bt.E, bt.rho)
        return model.eigenvalues_unit_k(b, _free_gamma(g), poses)

    lam = lam_of(g_free, w)
    assert abs(lam[0, 1] - lam[0, 0]) < 1e-12 * lam[0, 0]      # repeated to round-off
    for i in range(2):
        grads = torch.autograd.grad(lam[0, i], (g_free, w), retain_graph=True)
        assert all(torch.isfinite(g).all() for g in grads)
    # symmetric functions of the eigenvalues stay differentiable there: gradcheck their sum
    assert torch.autograd.gradcheck(lambda g, w: lam_of(g, w).sum(), (g_free, w))


# ----------------------------------------------------------------------------- batching
def _stack_beams(beams):
    bt = model.BeamTensors.from_beams(beams)                  # (B,)
    return model.BeamTensors(bt.x[:, None], bt.w[:, None], *(v[:, None] for v in
                             (bt.length, bt.thickness, bt.E, bt.rho)))   # (B, 1)


@pytest.mark.parametrize("law", ["beam", "paper"])
def test_batched_equals_one_at_a_time(law):
    n = 4
    beams = [random_beam(8, i, p=p) for i, p in enumerate([0, 2, 10])]
    beams.append(Beam(x=[0.0, 0.5, 1.7], half_width=[0.3, 0.2, 0.1], thickness=0.03,
                      material=Material(E=70e9, rho=2700.0, nu=0.3)))
    rng = np.random.default_rng(0)
    G = 5
    gammas = torch.tensor(np.stack([[_random_gamma(rng, n) for _ in range(G)] for _ in beams]))
    m = model.paper_poses(n).shape[0]
    ks = torch.tensor(rng.uniform(0.5, 2.0, (len(beams), G, m)))
    lam = model.eigenvalues(_stack_beams(beams), gammas, ks, "paper", law)
    assert lam.shape == (len(beams), G, m, n)
    for i, b in enumerate(beams):
        for j in range(G):
            one = model.eigenvalues(b, gammas[i, j], ks[i, j], "paper", law)
            torch.testing.assert_close(lam[i, j], one, rtol=1e-12, atol=0)
            for p in range(m):   # and each pose alone
                single = model.eigenvalues(b, gammas[i, j], ks[i, j, p:p + 1],
                                           model.paper_poses(n)[p:p + 1], law)
                torch.testing.assert_close(lam[i, j, p], single[0], rtol=1e-12, atol=0)


def test_bad_law_and_gamma():
    beam = random_beam(0, 0)
    with pytest.raises(BadInput, match="law"):
        model.eigenvalues(beam, torch.tensor([0.5, 0.5]), law="nope")
    with pytest.raises(BadInput, match="gamma"):
        model.eigenvalues(beam, torch.tensor([1.0]))
    with pytest.raises(BadInput, match="poses"):
        model.eigenvalues(beam, torch.tensor([0.5, 0.5]), poses="sideways")
    with pytest.raises(BadInput, match="poses"):
        model.eigenvalues(beam, torch.tensor([0.5, 0.5]), poses=[float("nan")])


def test_public_entry_points_are_float64_whatever_the_default_dtype():
    """float64 by default, not by the torch default dtype (the autouse fixture above sets float64:
    undo that here, so a float32 default would show)."""
    old = torch.get_default_dtype()
    torch.set_default_dtype(torch.float32)
    try:
        beam = Beam(x=[0.0, 0.4, 1.0], half_width=[0.2, 0.1, 0.05], thickness=0.02)
        assert model.uniform_gamma(3).dtype == torch.float64
        assert model.paper_poses(3).dtype == torch.float64
        assert model.make_poses("linear", 3).dtype == torch.float64
        assert model.make_poses([0.1, 0.2], 3).dtype == torch.float64
        assert model.BeamTensors.from_beams(beam).x.dtype == torch.float64
        lam = model.eigenvalues(beam, [0.3, 0.2, 0.25, 0.25], [1.0], "linear")
        assert lam.dtype == torch.float64
        lam = model.eigenvalues(beam, [0.3, 0.2, 0.25, 0.25], None, "paper", "paper")
        assert lam.dtype == torch.float64
        lam = model.eigenvalues(beam, model.uniform_gamma(3))
        assert lam.dtype == torch.float64
        # and the values are float64-accurate: the same as with a float64 default
        torch.set_default_dtype(torch.float64)
        ref = model.eigenvalues(beam, [0.3, 0.2, 0.25, 0.25], [1.0], "linear")
        torch.set_default_dtype(torch.float32)
        again = model.eigenvalues(beam, [0.3, 0.2, 0.25, 0.25], [1.0], "linear")
        assert torch.equal(again, ref)
    finally:
        torch.set_default_dtype(old)
