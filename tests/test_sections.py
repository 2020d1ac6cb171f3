"""Section integrals (prbdm.sections) against independent references: shapely's area and centroid of
the planform cut between a and b, numerical quadrature of the rotary inertia, and
scipy.integrate.quad of the beam-law compliance ∫ dx / w (near-equal widths and very tapered
segments included); gradients by torch.autograd.gradcheck."""
import numpy as np
import pytest
import torch
from scipy import integrate
from shapely.geometry import box

from prbdm.geometry import Beam, random_beam
from prbdm.sections import span_integrals


@pytest.fixture(autouse=True)
def _float64():
    """float64 for every tensor made in these tests, restored afterwards (no leak elsewhere)."""
    old = torch.get_default_dtype()
    torch.set_default_dtype(torch.float64)
    yield
    torch.set_default_dtype(old)



def _spans(rng, n=6):
    a = rng.uniform(0, 1, n)
    b = rng.uniform(0, 1, n)
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    # include the whole beam, a span starting at the clamp, one ending at the tip
    lo = np.concatenate([lo, [0.0, 0.0, 0.3]])
    hi = np.concatenate([hi, [1.0, 0.2, 1.0]])
    return lo, hi


def _integrals(beam, lo, hi):
    x = torch.tensor(beam.x / beam.length)
    w = torch.tensor(beam.half_width / beam.length)
    return span_integrals(x, w, torch.tensor(lo), torch.tensor(hi))


@pytest.mark.parametrize("index", range(4))
def test_area_and_centroid_match_shapely(index):
    beam = random_beam(7, index)          # L = 1, so nondimensional == SI here
    poly = beam.to_polygon()
    rng = np.random.default_rng(index)
    lo, hi = _spans(rng)
    si = _integrals(beam, lo, hi)
    for i in range(len(lo)):
        cut = poly.intersection(box(lo[i], -1.0, hi[i], 1.0))
        assert si.area[i].item() == pytest.approx(cut.area, rel=1e-12, abs=1e-15)
        centroid = (lo[i] + hi[i]) / 2 + si.centroid[i].item()
        assert centroid == pytest.approx(cut.centroid.x, rel=1e-10, abs=1e-12)


def _w(beam):
    return lambda s: np.interp(s, beam.x, beam.half_width)


@pytest.mark.parametrize("index", range(3))
def test_rotary_inertia_matches_quadrature(index):
    beam = random_beam(11, index, p=6)
    rng = np.random.default_rng(100 + index)
    lo, hi = _spans(rng, 4)
    si = _integrals(beam, lo, hi)
    w = _w(beam)
    for i in range(len(lo)):
        pts = [s for s in beam.x if lo[i] < s < hi[i]]
        area = integrate.quad(lambda s: 2 * w(s), lo[i], hi[i], points=pts, epsabs=0,
                              epsrel=1e-13, limit=200)[0]
        xc = integrate.quad(lambda s: 2 * w(s) * s, lo[i], hi[i], points=pts, epsabs=0,
                            epsrel=1e-13, limit=200)[0] / area
        J = integrate.quad(lambda s: 2 * w(s) * (s - xc) ** 2, lo[i], hi[i], points=pts,
                           epsabs=0, epsrel=1e-13, limit=200)[0]
        assert si.central_second[i].item() == pytest.approx(J, rel=1e-9)
        # also against a dense midpoint rule (an even cruder but fully different method)
        s = np.linspace(lo[i], hi[i], 200_001)
        sm = (s[1:] + s[:-1]) / 2
        Jm = np.sum(2 * w(sm) * (sm - xc) ** 2) * (hi[i] - lo[i]) / len(sm)
        assert si.central_second[i].item() == pytest.approx(Jm, rel=1e-6)


@pytest.mark.parametrize("w0, w1", [
    (0.2, 0.2),                 # uniform: u = 0
    (0.2, 0.2 * (1 + 1e-9)),    # series branch, tiny difference
    (0.2, 0.2 * (1 + 5e-4)),    # series branch near its edge
    (0.2, 0.2 * (1 + 2e-3)),    # exact branch just past the edge
    (0.2, 0.2 * (1 - 9.9e-4)),  # series branch, decreasing
    (0.3, 1e-4),                # very tapered (3000:1)
    (1e-5, 0.5),                # very tapered the other way
])
def test_compliance_matches_quad(w0, w1):
    beam = Beam(x=[0.0, 0.4, 1.0], half_width=[w0, w1, w0], thickness=0.01)
    w = _w(beam)
    for lo, hi in [(0.0, 1.0), (0.05, 0.37), (0.1, 0.9), (0.4, 0.41)]:
        ref = integrate.quad(lambda s: 1 / w(s), lo, hi, points=[0.4] if lo < 0.4 < hi else None,
                             epsabs=0, epsrel=1e-13, limit=200)[0]
        got = _integrals(beam, np.array([lo]), np.array([hi])).compliance.item()
        assert got == pytest.approx(ref, rel=1e-11)


def test_empty_span_is_zero():
    beam = random_beam(3, 0)
    si = _integrals(beam, np.array([0.4, 1.0]), np.array([0.4, 1.0]))
    for v in si:
        assert torch.all(v == 0)


def test_padding_with_repeated_tip_stations_changes_nothing():
    beam = random_beam(3, 1, p=4)
    x = torch.tensor(beam.x)
    w = torch.tensor(beam.half_width)
    xp = torch.cat([x, torch.ones(3)])
    wp = torch.cat([w, w[-1:].expand(3)])
    a, b = torch.tensor([0.0, 0.2, 0.7]), torch.tensor([1.0, 0.5, 1.0])
    for u, v in zip(span_integrals(x, w, a, b), span_integrals(xp, wp, a, b)):
        torch.testing.assert_close(u, v, rtol=1e-14, atol=1e-16)


def test_batched_equals_loop():
    beams = [random_beam(5, i, p=p) for i, p in enumerate([0, 3, 10])]
    S = max(len(b.x) for b in beams)
    X = np.ones((3, S))
    W = np.empty((3, S))
    for i, b in enumerate(beams):
        X[i, :len(b.x)] = b.x
        W[i, :len(b.x)] = b.half_width
        W[i, len(b.x):] = b.half_width[-1]
    rng = np.random.default_rng(0)
    lo = np.sort(rng.uniform(0, 1, (3, 5, 2)), -1)
    si = span_integrals(torch.tensor(X), torch.tensor(W),
                        torch.tensor(lo[..., 0]), torch.tensor(lo[..., 1]))
    for i, b in enumerate(beams):
        for j in range(5):
            one = _integrals(b, lo[i, j, :1], lo[i, j, 1:])
            for u, v in zip(si, one):
                assert u[i, j].item() == pytest.approx(v.item(), rel=1e-13, abs=1e-16)


def test_gradcheck_cut_positions_and_geometry():
    beam = random_beam(2, 4, p=5)
    x = torch.tensor(beam.x)
    w = torch.tensor(beam.half_width, requires_grad=True)
    xi = x[1:-1].clone().requires_grad_(True)       # interior stations
    # cuts away from the stations (the integrals are C^1 in the cuts, piecewise smooth in x)
    a = torch.tensor([0.0, 0.13, 0.51], requires_grad=True)
    b = torch.tensor([0.29, 0.77, 0.995], requires_grad=True)

    def f(a, b, xi, w):
        xx = torch.cat([x[:1], xi, x[-1:]])
        si = span_integrals(xx, w, a, b)
        return torch.cat([si.area, si.first, si.second, si.compliance, si.central_second])

    assert torch.autograd.gradcheck(f, (a, b, xi, w))


def test_gradient_wrt_cut_is_the_integrand():
    """d/db ∫_a^b f = f(b): an exact, independent check of the derivative in the cut positions."""
    beam = random_beam(2, 5, p=5)
    x, w = torch.tensor(beam.x), torch.tensor(beam.half_width)
    a = torch.tensor([0.1], requires_grad=True)
    b = torch.tensor([0.8], requires_grad=True)
    si = span_integrals(x, w, a, b)
    ga, gb = torch.autograd.grad(si.area.sum() + si.compliance.sum(), (a, b))
    wa, wb = np.interp([0.1, 0.8], beam.x, beam.half_width)
    assert gb.item() == pytest.approx(2 * wb + 1 / wb, rel=1e-12)
    assert ga.item() == pytest.approx(-(2 * wa + 1 / wa), rel=1e-12)


def test_gradients_finite_at_stations_and_equal_widths():
    x = torch.tensor([0.0, 0.5, 1.0])
    w = torch.tensor([0.2, 0.2, 0.2], requires_grad=True)
    a = torch.tensor([0.0, 0.5], requires_grad=True)   # cut exactly on a station
    b = torch.tensor([0.5, 1.0], requires_grad=True)
    si = span_integrals(x, w, a, b)
    grads = torch.autograd.grad(sum(v.sum() for v in si), (w, a, b))
    for g in grads:
        assert torch.isfinite(g).all()


def test_stations_on_and_next_to_every_cut_give_finite_exact_links():
    """A station that falls on a cut of the joints' tributary spans, or a hair beside one, must
    not matter: the links and compliances stay finite and agree with the NumPy twin, which
    integrates by cumulative sums (another construction), for many joint layouts."""
    from prbdm.geometry import Beam
    from prbdm.model import BeamTensors, links_from_gamma, uniform_gamma
    from prbdm.surrogate import numpy_model as nm

    rng = np.random.default_rng(35)
    layouts = [uniform_gamma(n).numpy() for n in (2, 3, 4, 5, 6, 8)]
    for _ in range(12):
        n = int(rng.integers(2, 9))
        g = rng.uniform(0.05, 1.0, n + 1)
        layouts.append(g / g.sum())
    checked = 0
    for gamma in layouts:
        cuts = np.concatenate([[0.0], np.cumsum(gamma)[:-1], [1.0]])
        centres = (cuts[1:] + cuts[:-1]) / 2
        for c in np.concatenate([cuts[1:-1], centres]):
            for eps in (0.0, 1e-15, -1e-15, 1e-9, -1e-9):
                s = c + eps
                if not 1e-6 < s < 1 - 1e-6:
                    continue
                # a steep neck: extrapolating a segment past its station gives a width <= 0
                w = np.array([0.1, 0.003, 0.2]) if checked % 2 else rng.uniform(0.005, 0.2, 3)
                beam = Beam(x=np.array([0.0, s, 1.0]), half_width=w, thickness=0.01)
                bt = BeamTensors.from_beams([beam])
                lk = links_from_gamma(bt, torch.tensor(gamma)[None])
                ref = nm.links_from_gamma(bt.x.numpy(), bt.w.numpy(), gamma[None])
                for name in ("mass", "com", "inertia", "tributary_compliance"):
                    got = getattr(lk, name).numpy()
                    assert np.all(np.isfinite(got)), (name, gamma, s)
                    np.testing.assert_allclose(got, ref[name], rtol=1e-9, atol=1e-13,
                                               err_msg=f"{name} gamma={gamma} station={s}")
                checked += 1
    # the exact failure: a segment whose line, extended past its station, reaches width 0 exactly
    # on another cut (dyadic numbers, so the old extrapolation gave 0 and then 0/0 = NaN)
    for n in (2, 4, 8):
        gamma = uniform_gamma(n).numpy()
        cuts = np.concatenate([[0.0], np.cumsum(gamma)[:-1], [1.0]])
        marks = np.unique(np.concatenate([cuts, (cuts[1:] + cuts[:-1]) / 2]))
        for s in marks[1:-1]:
            for c2 in marks[marks < s]:
                beam = Beam(x=np.array([0.0, s, 1.0]),
                            half_width=np.array([0.1, (s - c2) / 4, (1 - c2) / 4]),
                            thickness=0.01)
                bt = BeamTensors.from_beams([beam])
                lk = links_from_gamma(bt, torch.tensor(gamma)[None])
                ref = nm.links_from_gamma(bt.x.numpy(), bt.w.numpy(), gamma[None])
                got = lk.tributary_compliance.numpy()
                assert np.all(np.isfinite(got)), (n, s, c2, got)
                np.testing.assert_allclose(got, ref["tributary_compliance"], rtol=1e-9)
                checked += 1
    assert checked > 300


def test_a_station_on_a_cut_is_the_limit_of_stations_beside_it():
    """Continuity across the cut: moving the station by 1e-12 moves the compliance by about as
    much (it used to be NaN exactly on the cut)."""
    from prbdm.geometry import Beam
    from prbdm.model import BeamTensors, links_from_gamma, uniform_gamma

    vals = []
    for s in (0.75 - 1e-12, 0.75, 0.75 + 1e-12):
        beam = Beam(x=np.array([0.0, s, 1.0]), half_width=np.array([0.1, 0.03, 0.06]),
                    thickness=0.01)
        lk = links_from_gamma(BeamTensors.from_beams([beam]), uniform_gamma(4)[None])
        vals.append(lk.tributary_compliance.numpy()[0])
    np.testing.assert_allclose(vals[1], vals[0], rtol=1e-9)
    np.testing.assert_allclose(vals[1], vals[2], rtol=1e-9)


def test_many_stations_integrate_by_prefix_sums_alike():
    """Above CUMULATIVE_ABOVE stations the integrals come from prefix sums (O(S + C log S));
    they equal the clipping path's, values and gradients in the cut positions, on batched
    planforms padded with repeated tip stations, for spans of a link's length and more."""
    import prbdm.sections as sections

    rng = np.random.default_rng(3)
    S = sections.CUMULATIVE_ABOVE + 300
    xs, ws = [], []
    for real in (S, S - 40):                       # the second is padded to S at its tip
        x = np.sort(np.concatenate([[0.0, 1.0], rng.uniform(0, 1, real - 2)]))
        w = rng.uniform(0.01, 0.3, real)
        xs.append(np.concatenate([x, np.full(S - real, 1.0)]))
        ws.append(np.concatenate([w, np.full(S - real, w[-1])]))
    x, w = torch.tensor(np.array(xs)), torch.tensor(np.array(ws))
    lo = rng.uniform(0, 0.97, (2, 12))
    hi = np.minimum(lo + rng.uniform(0.025, 0.6, (2, 12)), 1.0)
    lo = np.concatenate([lo, [[0.0], [0.0]]], 1)
    hi = np.concatenate([hi, [[1.0], [1.0]]], 1)

    def integrals(dense: bool):
        a = torch.tensor(lo, requires_grad=True)
        b = torch.tensor(hi, requires_grad=True)
        old = sections.CUMULATIVE_ABOVE
        sections.CUMULATIVE_ABOVE = 10 ** 9 if dense else old
        try:
            si = span_integrals(x, w, a, b)
        finally:
            sections.CUMULATIVE_ABOVE = old
        total = sum((v * torch.arange(1, v.shape[-1] + 1)).sum() for v in si)
        ga, gb = torch.autograd.grad(total, (a, b))
        return [v.detach().numpy() for v in si], ga.numpy(), gb.numpy()

    (d, dga, dgb), (c, cga, cgb) = integrals(True), integrals(False)
    for name, dv, cv in zip(("area", "first", "second", "compliance"), d, c):
        np.testing.assert_allclose(cv, dv, rtol=1e-10, atol=1e-13 * np.abs(dv).max(), err_msg=name)
    # gradients where the bounds are interior (at 0 and 1 a bound sits on a station: a kink, where
    # each path returns its own one-sided mix; the fit never moves those bounds)
    inner_a, inner_b = lo > 0, hi < 1
    np.testing.assert_allclose(cga[inner_a], dga[inner_a], rtol=1e-8,
                               atol=1e-10 * np.abs(dga).max())
    np.testing.assert_allclose(cgb[inner_b], dgb[inner_b], rtol=1e-8,
                               atol=1e-10 * np.abs(dgb).max())
    assert inner_a.sum() >= 20 and inner_b.sum() >= 12
