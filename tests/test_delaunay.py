"""The plate's unstructured mesher (prbdm/truth/_delaunay.py) on its own: conformity, area,
angles, the stations as nodes, determinism, on uniform, tapered, necked, stepped and random
half planforms (nondimensional coordinates, as the plate model calls it)."""
import numpy as np
import pytest

from prbdm.geometry import random_beam
from prbdm.truth._delaunay import H_FLOOR, half_planform_mesh


def _random(seed, index, hw_min):
    b = random_beam(seed, index, min_half_width=hw_min)
    return b.x / b.length, b.half_width / b.length


PLANFORMS = {
    "uniform, square": ([0.0, 1.0], [0.5, 0.5]),
    "uniform, slender (stretched)": ([0.0, 1.0], [0.02, 0.02]),
    "tapered 10:1": ([0.0, 1.0], [0.5, 0.05]),
    "wider at the tip": ([0.0, 1.0], [0.05, 0.4]),
    "100:1 neck over 1 % of the span": ([0.0, 0.5, 0.505, 0.51, 1.0], [0.1, 0.1, 0.001, 0.1, 0.1]),
    "100:1 step": ([0.0, 0.4, 0.41, 1.0], [0.2, 0.2, 0.002, 0.002]),
    "2 mm tip": ([0.0, 1.0], [0.5, 0.001]),
    "random (0, 0)": _random(0, 0, 0.01),
    "random (0, 1), stations 0.07 mm apart": _random(0, 1, 0.0),
    "random (0, 10)": _random(0, 10, 0.01),
    "random (1, 13), the steepest of 120": _random(1, 13, 0.01),
    "random (2, 21), no minimum width": _random(2, 21, 0.0),
}
#: the fixed planforms above whose free edge is straight or gently kinked: well-shaped elements
SMOOTH = {"uniform, square", "uniform, slender (stretched)", "tapered 10:1", "wider at the tip"}


@pytest.fixture(scope="module", params=list(PLANFORMS))
def meshed(request):
    xs, ws = (np.asarray(a, float) for a in PLANFORMS[request.param])
    p, t, info = half_planform_mesh(xs, ws)
    return request.param, xs, ws, p, t, info


def _polygon_segments(xs, ws):
    """The half planform's boundary: axis, tip edge, free edge, root edge."""
    pts = np.vstack([[[0.0, 0.0], [1.0, 0.0]], np.column_stack([xs[::-1], ws[::-1]])])
    return pts, np.roll(pts, -1, axis=0)


def _distance_to_boundary(q, xs, ws):
    a, b = _polygon_segments(xs, ws)
    d = b - a                                                   # (S, 2)
    rel = q[:, None, :] - a[None]                               # (Q, S, 2)
    s = np.clip((rel * d).sum(-1) / np.maximum((d * d).sum(-1), 1e-300), 0.0, 1.0)
    return np.sqrt(((rel - s[..., None] * d) ** 2).sum(-1)).min(axis=1)


def _edges(t):
    e = np.sort(np.hstack([t[[0, 1]], t[[1, 2]], t[[2, 0]]]), axis=0).T
    uniq, count = np.unique(e, axis=0, return_counts=True)
    return uniq, count


def _angles(p, t):
    """(3, elements) interior angles in degrees."""
    P = p[:, t]
    out = np.empty((3, t.shape[1]))
    for k in range(3):
        u, v = P[:, (k + 1) % 3] - P[:, k], P[:, (k + 2) % 3] - P[:, k]
        out[k] = np.degrees(np.arctan2(np.abs(u[0] * v[1] - u[1] * v[0]), (u * v).sum(0)))
    return out


def _chords(p, t, xs, ws):
    """Boundary edges (in one triangle) and which of them cut across the polygon instead of
    running along it, with their midpoints' distance from it."""
    edges, count = _edges(t)
    bnd = edges[count == 1]
    mid = 0.5 * (p[:, bnd[:, 0]] + p[:, bnd[:, 1]]).T
    dist = _distance_to_boundary(mid, xs, ws)
    return edges, count, bnd, dist > 1e-12, dist


def test_conforming(meshed):
    """Every edge belongs to one triangle (then it lies on the polygon's boundary) or two (then
    it is interior); the boundary edges cover the polygon's perimeter.

    Exception, measured on "random (1, 13)": its free edge runs from (0.99993, 0.014) to the tip
    (1, 0.236), a sliver 7e-5 wide beside the tip edge, narrower than the smallest element the
    mesher makes (H_FLOOR = 1e-4): the mesh zig-zags across it and leaves parts of it out (10 of
    294 boundary edges cut across, at most 3.3e-5 from the polygon; 3.8e-6 of the area)."""
    name, xs, ws, p, t, _ = meshed
    edges, count, bnd, chord, dist = _chords(p, t, xs, ws)
    assert set(count.tolist()) <= {1, 2}, name
    # every boundary node lies on the polygon, chords or not
    ends = np.unique(bnd)
    assert _distance_to_boundary(p[:, ends].T, xs, ws).max() < 1e-12, name
    # an interior edge does not run along the boundary (its midpoint is inside)
    inner = edges[count == 2]
    mid = 0.5 * (p[:, inner[:, 0]] + p[:, inner[:, 1]]).T
    assert _distance_to_boundary(mid, xs, ws).min() > 1e-12, name
    a, b = _polygon_segments(xs, ws)
    perimeter = np.hypot(*(b - a).T).sum()
    length = np.hypot(*(p[:, bnd[:, 0]] - p[:, bnd[:, 1]])).sum()
    if name.startswith("random (1, 13)"):
        assert chord.sum() <= 0.05 * len(bnd) and dist.max() < H_FLOOR, name
    else:
        assert not chord.any() and abs(length / perimeter - 1) < 1e-12, name


def test_nodes_inside_and_stations_are_nodes(meshed):
    name, xs, ws, p, t, _ = meshed
    # every node in the closed polygon, every used once at least, none doubled
    # (in or on it: boundary points, interpolated in stretched coordinates, may stand 1e-16
    # outside)
    inside = (p[0] >= 0) & (p[0] <= 1) & (p[1] >= 0) & (p[1] <= np.interp(p[0], xs, ws))
    assert inside.all() or _distance_to_boundary(p[:, ~inside].T, xs, ws).max() < 1e-15, name
    assert np.array_equal(np.unique(t), np.arange(p.shape[1])), name
    diff = p[:, :, None] - p[:, None, :]
    dist = np.sqrt((diff ** 2).sum(0)) + np.eye(p.shape[1])
    assert dist.min() > 1e-9, name
    # the corners and every station of the free edge are nodes, exactly
    corners = np.vstack([[[0.0, 0.0], [1.0, 0.0]], np.column_stack([xs, ws])])
    for c in corners:
        assert np.min(np.abs(p[0] - c[0]) + np.abs(p[1] - c[1])) < 1e-15, (name, c)


def test_positive_areas_sum_to_the_planform_area(meshed):
    """All triangles counter-clockwise with positive area, summing to the planform's area."""
    name, xs, ws, p, t, _ = meshed
    P = p[:, t]
    area = 0.5 * ((P[0, 1] - P[0, 0]) * (P[1, 2] - P[1, 0])
                  - (P[1, 1] - P[1, 0]) * (P[0, 2] - P[0, 0]))
    assert np.all(area > 0), name                       # counter-clockwise, none degenerate
    exact = np.sum(np.diff(xs) * 0.5 * (ws[1:] + ws[:-1]))
    # the planform's area exactly, but for "random (1, 13)", whose sliver narrower than the
    # smallest element is partly left out (measured: 3.8e-6 of the area, test_conforming)
    missing = 1e-5 if name.startswith("random (1, 13)") else 1e-12
    assert -missing < area.sum() / exact - 1 < 1e-12, name


def test_angles(meshed):
    """In the mesher's own (y-stretched) coordinates. Measured over 120 random planforms (40
    each of seeds 0 and 1 with min_half_width 0.01, and of seed 2 without; docs/validation.md): at
    most 3.9 % of the triangles below 5 degrees and 4.2 % above 150 (mean 0.15 % and 0.10 %);
    the worst single angles, 0.02 and 179.9 degrees, on "random (1, 13)" (its sliver beside the
    tip edge, test_conforming). Straight or gently kinked free edges give no triangle below 20
    or above 120 degrees."""
    name, xs, ws, p, t, info = meshed
    q = p.copy()
    q[1] *= info["stretch"]
    a = _angles(q, t)
    smallest, largest = a.min(axis=0), a.max(axis=0)
    assert np.all(np.abs(a.sum(axis=0) - 180) < 1e-9)
    assert np.mean(smallest < 5) <= 0.05 and np.mean(largest > 150) <= 0.05, name
    if name in SMOOTH:
        assert smallest.min() > 20 and largest.max() < 120, (name, smallest.min(), largest.max())


def test_stretch_and_determinism():
    xs, ws = np.array([0.0, 1.0]), np.array([0.02, 0.02])
    p, t, info = half_planform_mesh(xs, ws)
    assert info["stretch"] > 1                          # slender: meshed in stretched coordinates
    p2, t2, _ = half_planform_mesh(xs, ws)
    assert np.array_equal(p, p2) and np.array_equal(t, t2)
    wide = half_planform_mesh(np.array([0.0, 1.0]), np.array([0.5, 0.5]))[2]
    assert wide["stretch"] == 1.0
