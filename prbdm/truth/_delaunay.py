"""An unstructured triangulation of the half planform, for the plate model.

The half planform (nondimensional, ``0 <= x <= 1``, ``0 <= y <= w(x)``) is an x-monotone polygon:
root edge ``x = 0``, symmetry line ``y = 0``, tip edge ``x = 1`` and the piecewise-linear free
edge ``y = w(x)``. Random planforms have steep free edges (a fin 1 m wide and 2 cm long) and
stations a fraction of a millimetre apart, where any mesh whose lines follow the stations (a
mapped mesh) degenerates into slivers. Here the stations are only boundary vertices and the
interior is meshed freely:

1. a size function ``h(p)``: ``h0`` in general; graded linearly (``h_c + grade * r``) toward the
   clamped-free corner (``h_c = corner_ratio * h0``), toward re-entrant free-edge corners (both
   singular points of the plate solution; ``h_c`` falls from ``corner_ratio * h0`` at 180 degrees
   to ``corner_ratio^1.5 * h0`` at a crack-like 360-degree notch) and toward short free-edge
   segments; never below ``H_FLOOR`` (smaller elements only ruin the conditioning); and at most
   ``across * w(x)`` so that narrow
   parts get elements across their width;
2. points: the boundary walked at the local size, and quadtree-like lattices (spacing ``h0 / 2^l``)
   inside, each lattice point kept where the local size asks for that level and away from the
   boundary;
3. ``scipy.spatial.Delaunay``, triangles with their centroid outside dropped, boundary segments that
   are not mesh edges split until they are (so the mesh conforms to the polygon exactly), and a few
   rounds of Laplacian smoothing of the interior points;
4. for planforms much narrower than long, all this happens in coordinates stretched by ``s`` in y
   (``y' = s y``): the triangles come out ``s`` times longer than wide, aligned with the span, and a
   2 mm wide strip costs a few dozen elements instead of thousands.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import Delaunay, cKDTree
from scipy.spatial.distance import cdist

__all__ = ["half_planform_mesh"]

#: largest stretch: equilateral triangles stretched by s have a largest angle of
#: 180 - 2 atan(sqrt(3) / s) degrees (133 at s = 4), beyond which accuracy degrades
MAX_STRETCH = 4.0
#: smallest element size (nondimensional, stretched coordinates)
H_FLOOR = 1e-4


def _polygon(xs, ws):
    """Counter-clockwise vertices of the half planform: axis, tip edge, free edge (tip to root),
    root edge."""
    top = np.column_stack([xs[::-1], ws[::-1]])
    return np.vstack([[[0.0, 0.0], [1.0, 0.0]], top])


def half_planform_mesh(xs, ws, h0=1.0 / 12, grade=0.4, corner_ratio=0.01, across=0.75,
                       smooth=4, stretch=None):
    """Points ``p`` (2, N) and triangles ``t`` (3, M) of the half planform.

    ``xs``, ``ws``: nondimensional stations and half-widths (``xs[0] = 0``, ``xs[-1] = 1``).
    Returns ``p, t, info``.
    """
    xs = np.asarray(xs, float)
    ws = np.asarray(ws, float)
    # the stretch for slender planforms: mean half-width -> about 2 elements across
    mean_w = float(np.sum(np.diff(xs) * 0.5 * (ws[1:] + ws[:-1])))
    if stretch is None:
        stretch = float(np.clip(2.0 * h0 / mean_w, 1.0, MAX_STRETCH))
    s = stretch
    W = ws * s                                              # stretched half-widths
    verts = _polygon(xs, W)
    nv = len(verts)
    hc = h0 * corner_ratio

    # ---- refinement sources: (point, size at the point)
    sources = [(np.array([0.0, W[0]]), hc)]                 # clamped-free corner
    # free-edge vertices: re-entrant corners get refined like the clamped corner (more, the
    # sharper they are); every vertex gets a size no larger than its adjacent segments
    for k in range(1, len(xs) - 1):
        a = np.array([xs[k - 1], W[k - 1]])
        v = np.array([xs[k], W[k]])
        b = np.array([xs[k + 1], W[k + 1]])
        seg = min(np.hypot(*(v - a)), np.hypot(*(b - v)))
        # interior (material) angle: the polygon runs counter-clockwise, tip -> root along the
        # free edge, so at (x_k, w_k) it comes from station k+1 and goes to station k-1; angles
        # in physical (unstretched) coordinates
        d1 = np.array([xs[k] - xs[k + 1], ws[k] - ws[k + 1]])
        d2 = np.array([xs[k - 1] - xs[k], ws[k - 1] - ws[k]])
        turn = np.arctan2(d1[0] * d2[1] - d1[1] * d2[0], d1 @ d2)
        angle = np.pi - turn
        if angle > np.pi * (1 + 1e-9):
            # re-entrant corner: singular moments, the sharper the stronger; the corner size
            # falls from corner_ratio * h0 at 180 degrees to corner_ratio^1.5 * h0 at 360
            # (a crack)
            size = min(h0 * corner_ratio ** (1.0 + 0.5 * (angle - np.pi) / np.pi),
                       max(seg, 1e-9))
        else:
            size = min(h0, max(seg, 1e-9))
        sources.append((v, size))
    for k in (0, len(xs) - 1):                              # root-top and tip-top vertices
        j = 1 if k == 0 else len(xs) - 2
        seg = np.hypot(xs[j] - xs[k], W[j] - W[k])
        sources.append((np.array([xs[k], W[k]]), min(h0, max(seg, 1e-9))))
    src_p = np.array([p for p, _ in sources])
    src_h = np.maximum(np.array([h for _, h in sources]), H_FLOOR)

    def size(p):
        p = np.atleast_2d(p)
        d = cdist(p, src_p)         # the same sqrt(dx^2 + dy^2) as broadcasting, cheaper
        h = np.min(src_h[None] + grade * d, axis=1)
        wloc = np.interp(p[:, 0], xs, W)
        return np.minimum(np.minimum(h, h0), np.maximum(across * wloc, H_FLOOR))

    hmin = float(max(min(src_h.min(), across * W.min()), H_FLOOR))

    # ---- boundary points
    bpts = []
    for k in range(nv):
        a, b = verts[k], verts[(k + 1) % nv]
        bpts.append(_march(a, b, size, hmin))
    boundary = np.vstack(bpts)

    # ---- interior lattice points, level by level
    levels = int(np.ceil(np.log2(h0 / max(hmin, 1e-12)))) + 1
    levels = min(levels, 30)
    inner = []
    tree = cKDTree(boundary)
    ymax = float(W.max())
    for lev in range(levels):
        hl = h0 / 2 ** lev
        if lev == 0:
            boxes = [(0.0, 1.0, 0.0, ymax)]
        else:
            boxes = _boxes_needing(hl, src_p, src_h, grade, xs, W, across, ymax)
        for (x0, x1, y0, y1) in boxes:
            gx = np.arange(np.floor(x0 / hl), np.ceil(x1 / hl) + 1) * hl
            gy = np.arange(np.floor(y0 / hl), np.ceil(y1 / hl) + 1) * hl
            if gx.size * gy.size > 400000:
                raise ValueError("plate mesh: too many points; the planform is too extreme")
            X, Y = np.meshgrid(gx, gy, indexing="ij")
            P = np.column_stack([X.ravel(), Y.ravel()])
            # a tiny shift off the lattice avoids co-circular quadruples in Delaunay
            P = P + hl * np.array([1e-3, 2e-3])
            ok = (P[:, 0] > 0) & (P[:, 0] < 1) & (P[:, 1] > 0)
            P = P[ok]
            P = P[P[:, 1] < np.interp(P[:, 0], xs, W)]
            if not len(P):
                continue
            hp = size(P)
            # keep the points of this level where the local size asks for it
            keep = hp <= hl * 1.0001 if lev > 0 else np.ones(len(P), bool)
            if lev > 0:
                keep &= hp > hl / 2 * 0.9999 if lev < levels - 1 else keep
            P, hp = P[keep], hp[keep]
            inner.append(np.column_stack([P, hp]))
    inner = np.vstack(inner) if inner else np.empty((0, 3))
    if len(inner):
        # drop duplicates across levels and points too close to the boundary
        dist, _ = tree.query(inner[:, :2])
        inner = inner[dist > 0.55 * inner[:, 2]]
        inner = inner[:, :2]
        inner = _dedupe(inner, 0.3 * hmin)
    pts = np.vstack([boundary, inner])
    nb = len(boundary)

    # boundary segments as index pairs (consecutive boundary points, closed)
    bseg = np.column_stack([np.arange(nb), (np.arange(nb) + 1) % nb])
    for _ in range(smooth + 1):
        tri, pts, nb, bseg = _conforming_delaunay(pts, nb, bseg, xs, W)
        if _ == smooth:
            break
        pts = _smooth(pts, tri, nb)
    p = pts.T.copy()
    p[1] /= s
    return p, tri.T.copy(), {"stretch": s, "points": int(len(pts)), "triangles": int(len(tri))}


def _march(a, b, size, hmin):
    """Points on segment a->b (a included, b excluded) spaced by the local size: as many steps
    as the integral of ds / h, placed at equal increments of that integral."""
    length = float(np.hypot(*(b - a)))
    u = np.linspace(0.0, 1.0, 257)
    h = np.maximum(size(a[None] + u[:, None] * (b - a)[None]), hmin)
    dens = length / h
    cum = np.concatenate([[0.0], np.cumsum(0.5 * (dens[1:] + dens[:-1]) * np.diff(u))])
    n = max(1, int(np.ceil(cum[-1] - 1e-9)))
    ts = np.interp(np.arange(n) * cum[-1] / n, cum, u)
    return a[None] + ts[:, None] * (b - a)[None]


def _boxes_needing(hl, src_p, src_h, grade, xs, W, across, ymax):
    """Bounding boxes of the regions where the size can be below ``hl``."""
    boxes = []
    for p, h in zip(src_p, src_h):
        if h < hl:
            r = (hl - h) / grade
            boxes.append((p[0] - r, p[0] + r, max(0.0, p[1] - r), min(ymax, p[1] + r)))
    narrow = across * W < hl
    if narrow.any():
        # stretches of span where the width is below hl/across (plus a margin)
        xx = np.linspace(0, 1, 2001)
        ww = np.interp(xx, xs, W)
        mask = across * ww < hl
        idx = np.flatnonzero(mask)
        if idx.size:
            splits = np.flatnonzero(np.diff(idx) > 1)
            starts = np.concatenate([[idx[0]], idx[splits + 1]])
            ends = np.concatenate([idx[splits], [idx[-1]]])
            for a, b in zip(starts, ends):
                x0, x1 = xx[max(a - 1, 0)], xx[min(b + 1, len(xx) - 1)]
                boxes.append((x0, x1, 0.0, min(ymax, hl / across)))
    return boxes


def _dedupe(P, tol):
    tree = cKDTree(P)
    pairs = tree.query_pairs(tol, output_type="ndarray")
    if len(pairs):
        drop = np.zeros(len(P), bool)
        drop[np.maximum(pairs[:, 0], pairs[:, 1])] = True
        P = P[~drop]
    return P


def _inside(c, xs, W):
    return (c[:, 0] > 0) & (c[:, 0] < 1) & (c[:, 1] > 0) & (c[:, 1] < np.interp(c[:, 0], xs, W))


def _conforming_delaunay(pts, nb, bseg, xs, W, max_rounds=30):
    """Delaunay triangulation whose edges include every boundary segment; boundary segments
    missing from it are split at their midpoints (and interior points inside their diametral
    circles removed) until none is missing."""
    for _ in range(max_rounds):
        d = Delaunay(pts)
        tri = d.simplices
        c = pts[tri].mean(axis=1)
        tri = tri[_inside(c, xs, W)]
        # boundary segments that are no triangle edge, by integer keys lo * n + hi (one
        # vectorised membership test instead of a Python set of tuples)
        n = len(pts)
        e = np.vstack([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
        have = np.min(e, axis=1).astype(np.int64) * n + np.max(e, axis=1)
        want = np.min(bseg, axis=1).astype(np.int64) * n + np.max(bseg, axis=1)
        missing = np.flatnonzero(~np.isin(want, have)).tolist()
        if not missing:
            tri = _drop_caps(pts, tri, nb)
            # drop unused points (interior points in no triangle, boundary points of a dropped
            # cap); the boundary points stay first and in ring order
            used = np.unique(tri)
            if len(used) < len(pts):
                remap = -np.ones(len(pts), int)
                remap[used] = np.arange(len(used))
                nb = int(np.sum(used < nb))
                pts = pts[used]
                tri = remap[tri]
                bseg = np.column_stack([np.arange(nb), (np.arange(nb) + 1) % nb])
            # orient counter-clockwise
            a, b, cc = pts[tri[:, 0]], pts[tri[:, 1]], pts[tri[:, 2]]
            area = (b[:, 0] - a[:, 0]) * (cc[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (cc[:, 0] - a[:, 0])
            tri[area < 0] = tri[area < 0][:, [0, 2, 1]]
            return tri, pts, nb, bseg
        # split the missing segments at their midpoints, keeping the boundary points in ring
        # order; interior points inside the new points' diametral circles go
        missing = set(missing)
        inner = pts[nb:]
        ring, mids = [], []
        for k, (i, j) in enumerate(bseg):
            ring.append(pts[i])
            if k in missing:
                m = 0.5 * (pts[i] + pts[j])
                ring.append(m)
                mids.append((m, 0.5 * np.hypot(*(pts[j] - pts[i]))))
        bnew = np.array(ring)
        if len(inner):
            keep = np.ones(len(inner), bool)
            for m, r in mids:
                keep &= np.hypot(*(inner - m).T) > r * 1.05
            inner = inner[keep]
        nb = len(bnew)
        pts = np.vstack([bnew, inner])
        bseg = np.column_stack([np.arange(nb), (np.arange(nb) + 1) % nb])
    raise ValueError("plate mesh: could not recover the boundary")


def _drop_caps(pts, tri, nb, max_angle=175.0, rel_area=1e-6):
    """Remove flat triangles made of three boundary points where the boundary is almost straight
    (a kink of a fraction of a degree): they carry no area (at most ``rel_area`` of the total
    each) and would wreck the conditioning."""
    P = pts[tri]                                                    # (M, 3, 2)
    e = np.roll(P, -1, axis=1) - P
    a = P[:, 1] - P[:, 0]
    b = P[:, 2] - P[:, 0]
    area = 0.5 * np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
    L = np.sqrt((e ** 2).sum(-1))
    # largest angle, opposite the longest edge: cos = (l1^2 + l2^2 - l3^2) / (2 l1 l2)
    Ls = np.sort(L, axis=1)
    cosmax = (Ls[:, 0] ** 2 + Ls[:, 1] ** 2 - Ls[:, 2] ** 2) / np.maximum(2 * Ls[:, 0] * Ls[:, 1], 1e-300)
    flat = (cosmax < np.cos(np.radians(max_angle))) & np.all(tri < nb, axis=1) \
        & (area < rel_area * area.sum())
    return tri[~flat]


def _smooth(pts, tri, nb):
    """One round of Laplacian smoothing of the interior points (boundary points fixed)."""
    n = len(pts)
    i = np.concatenate([tri[:, 0], tri[:, 1], tri[:, 2], tri[:, 1], tri[:, 2], tri[:, 0]])
    j = np.concatenate([tri[:, 1], tri[:, 2], tri[:, 0], tri[:, 0], tri[:, 1], tri[:, 2]])
    # each neighbour once, rows in order and neighbours ascending within a row: bincount then
    # adds them in the order a CSR adjacency product would (the mesh stays bit-identical to the
    # sparse-matrix version this replaces, at a third of its cost)
    keys = np.unique(i.astype(np.int64) * n + j)
    r, c = keys // n, keys % n
    deg = np.bincount(r, minlength=n).astype(float)
    avg = np.column_stack([np.bincount(r, weights=pts[c, k], minlength=n) for k in range(2)])
    avg /= np.maximum(deg, 1)[:, None]
    new = pts.copy()
    new[nb:] = 0.5 * pts[nb:] + 0.5 * avg[nb:]
    return new
