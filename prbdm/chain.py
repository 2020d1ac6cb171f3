"""The PRBDM chain in NumPy: one home for its physics (links from gamma, exact span integrals,
the lamina's roll inertia, mass matrix, the base stiffness laws ``beam`` and ``paper``,
eigenvalues, the SI link table), used by ``prbdm predict`` (through :mod:`prbdm.surrogate`),
``prbdm export`` (:mod:`prbdm.export`), ``prbdm simulate``, the features, and the training
checks. :mod:`prbdm.model` is its torch twin, kept only where gradients are needed (the fit and
the training); ``tests/test_chain.py`` and ``tests/test_surrogate.py`` check that the two agree.
No torch here, so that ``prbdm predict`` and ``prbdm export --from`` start in a fraction of a
second (importing torch alone takes about 2 s on a busy machine).

- :class:`BeamBatch`: padded NumPy arrays of stations and half-widths divided by L, plus
  thickness, length and material;
- :func:`uniform_gamma`: the equal-link (rigid-finite-element) chain's link fractions;
- :func:`prbdm_eigenvalues`, :func:`link_table`: the PRBDM of a batch of beams;
- :func:`span_integrals` (with the lamina's roll inertia), :func:`links_from_gamma`,
  :func:`base_stiffness`, :func:`mass_matrix` and the straight-pose fast path
  (:func:`straight_mass_matrix`, :func:`straight_projected_mass`) that the features use;
- one chain in SI, for time integration and statics (:mod:`prbdm.simulate`,
  benchmarks/large_deflection.py): :func:`absolute_inertia` (the constant matrix of the kinetic
  energy in absolute link angles), :func:`joint_mass_matrix`, :func:`joint_coriolis`,
  :func:`joint_accelerations` (Lagrange's equations in closed form), :func:`tip_position`,
  :class:`TipLoadStatics` (equilibria under a dead tip force, with any spring law of
  :mod:`prbdm.springs`) and :class:`ChainDynamics` (the chain of a fit result's description, in
  SI, with its springs and damping).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from .errors import BadInput
from .geometry import Beam, Material, check_prbdm_width_ratio

#: the base joint stiffness laws (:func:`base_stiffness`)
LAWS = ("beam", "paper")


@dataclass(frozen=True)
class BeamBatch:
    """B beams as NumPy arrays. x, w: (B, S) stations and half-widths divided by L (x from 0 to
    1; beams with fewer stations are padded by repeating their tip); length, thickness [m],
    E [Pa], rho [kg/m^3], nu: (B,)."""

    x: np.ndarray
    w: np.ndarray
    length: np.ndarray
    thickness: np.ndarray
    E: np.ndarray
    rho: np.ndarray
    nu: np.ndarray

    def __len__(self):
        return self.x.shape[0]

    @classmethod
    def from_beams(cls, beams) -> "BeamBatch":
        if isinstance(beams, Beam):
            beams = [beams]
        beams = list(beams)
        if not beams:
            raise BadInput("beams: need at least one beam")
        for b in beams:
            if not isinstance(b, Beam):
                raise BadInput(f"beams: must be prbdm.geometry.Beam objects, got "
                               f"{type(b).__name__}")
            check_prbdm_width_ratio(b)
        return cls.from_arrays([b.x for b in beams], [b.half_width for b in beams],
                               [b.thickness for b in beams], [b.material for b in beams])

    @classmethod
    def from_arrays(cls, xs, half_widths, thickness, material=None) -> "BeamBatch":
        """From per-beam station and half-width lists [m] (a data set's ``x`` and ``half_width``
        columns), thicknesses [m] and one :class:`Material` or one per beam."""
        B = len(xs)
        S = max(len(x) for x in xs)
        X = np.empty((B, S))
        W = np.empty((B, S))
        for i, (x, w) in enumerate(zip(xs, half_widths)):
            n = len(x)
            X[i, :n], W[i, :n] = x, w
            X[i, n:], W[i, n:] = x[-1], w[-1]
        L = X[:, -1].copy()
        X /= L[:, None]
        W /= L[:, None]
        X[:, -1] = 1.0
        if material is None or isinstance(material, Material):
            m = material or Material()
            mats = np.tile([m.E, m.rho, m.nu], (B, 1))
        else:
            mats = np.array([[m.E, m.rho, m.nu] for m in material])
        return cls(X, W, L, np.asarray(thickness, dtype=np.float64).reshape(B),
                   mats[:, 0].copy(), mats[:, 1].copy(), mats[:, 2].copy())

    @classmethod
    def from_table(cls, table, material: Material | dict | None = None) -> "BeamBatch":
        """From a data set table (pyarrow Table or pandas DataFrame with columns ``x``,
        ``half_width``, ``thickness`` and, where the set draws one per beam, ``nu``);
        ``material`` is the data set's (``spec['beam']['material']``): its E and rho, and its
        Poisson's ratio where the table has no ``nu`` column."""
        if isinstance(material, dict):
            material = Material(**material)
        if hasattr(table, "column"):                       # pyarrow
            xs = table.column("x").to_pylist()
            ws = table.column("half_width").to_pylist()
            t = table.column("thickness").to_numpy()
            nu = table.column("nu").to_numpy() if "nu" in table.column_names else None
        else:                                              # pandas
            xs, ws, t = list(table["x"]), list(table["half_width"]), table["thickness"].to_numpy()
            nu = table["nu"].to_numpy() if "nu" in table.columns else None
        batch = cls.from_arrays(xs, ws, t, material)
        if nu is None:
            return batch
        nu = np.asarray(nu, dtype=np.float64).reshape(len(xs))
        bad = ~(np.isfinite(nu) & (nu > -1.0) & (nu < 0.5))
        if bad.any():
            raise BadInput(f"nu: Poisson's ratio must be in (-1, 0.5), got {nu[bad][0]!r} "
                           f"(row {int(np.flatnonzero(bad)[0])} of the table)")
        return dataclasses.replace(batch, nu=nu)

    @property
    def lambda0(self) -> np.ndarray:
        """Eigenvalue scale E t^2 / (rho L^4) [rad^2/s^2]."""
        return self.E * self.thickness ** 2 / (self.rho * self.length ** 4)

    def take(self, idx) -> "BeamBatch":
        return BeamBatch(*(getattr(self, f)[idx] for f in
                           ("x", "w", "length", "thickness", "E", "rho", "nu")))


def uniform_gamma(n: int) -> np.ndarray:
    """Link fractions of the equal-link chain with n joints: [1/2, 1, ..., 1, 1/2] / n (the
    rigid-finite-element chain; :func:`prbdm.model.uniform_gamma` is its torch twin)."""
    g = np.ones(n + 1)
    g[0] = g[-1] = 0.5
    return g / n


def _inv_logmean(lo, hi):
    u = (hi - lo) / lo
    small = np.abs(u) < 1e-3
    u_safe = np.where(small, 1.0, u)
    exact = np.log1p(u_safe) / u_safe
    series = 1 - u / 2 + u * u / 3 - u * u * u / 4
    return np.where(small, series, exact) / lo


def _simpson(h, xa, xb, wa, wb, parts=(0, 1, 2, 3)):
    """Integrals over [xa, xb] (length h) of 2 w, 2 x w, 2 x^2 w, of 1 / w and of (2/3) w^3 (the
    polynomials by Simpson's rule, exact for these cubics), for w linear from wa to wb: the ones
    named by ``parts`` (0..4), in order."""
    out = []
    if 1 in parts or 2 in parts or 4 in parts:
        xm, wm = (xa + xb) / 2, (wa + wb) / 2
    for p in parts:
        if p == 0:
            out.append(h * (wa + wb))
        elif p == 1:
            out.append(h / 3 * (xa * wa + 4 * xm * wm + xb * wb))
        elif p == 2:
            out.append(h / 3 * (xa * xa * wa + 4 * xm * xm * wm + xb * xb * wb))
        elif p == 3:
            out.append(h * _inv_logmean(wa, wb))
        else:
            out.append(h / 9 * (wa ** 3 + 4 * wm ** 3 + wb ** 3))
    return out


def _segments(x, q):
    """Index k (B, Q) of the planform segment [x_k, x_k+1] that holds each q: the number of
    stations x_0..x_{S-2} at or below q, less one, clipped to [0, S-2]. One sorted search over
    the rows laid end to end (each row shifted by twice its number; x, q lie in [0, 1])."""
    B, S = x.shape
    shift = 2.0 * np.arange(B)[:, None]
    flat = (x[:, :-1] + shift).ravel()
    pos = np.searchsorted(flat, (q + shift).ravel(), side="right").reshape(q.shape)
    return np.clip(pos - (S - 1) * np.arange(B)[:, None] - 1, 0, S - 2)


def _cumulative(x, w, q, parts=(0, 1, 2, 3)):
    """Integrals from 0 to q of 2 w, 2 x w, 2 x^2 w, 1 / w and (2/3) w^3 (``parts`` 0..4, the
    ones asked for, in order): x, w (B, S), q (B, Q) in [0, 1].

    Cost O(B (S + Q) log(B S)): whole segments by prefix sums, the part of q's own segment by
    Simpson's rule; this is what makes the batched prediction fast."""
    h = np.diff(x, axis=-1)
    full = _simpson(h, x[:, :-1], x[:, 1:], w[:, :-1], w[:, 1:], parts)
    cums = [np.concatenate([np.zeros((x.shape[0], 1)), np.cumsum(p, -1)], -1) for p in full]
    k = _segments(x, q)
    xk = np.take_along_axis(x, k, -1)
    wk = np.take_along_axis(w, k, -1)
    hk = np.take_along_axis(h, k, -1)
    wk1 = np.take_along_axis(w[:, 1:], k, -1)
    slope = np.where(hk > 0, (wk1 - wk) / np.where(hk > 0, hk, 1.0), 0.0)
    dq = np.clip(q - xk, 0.0, None)
    part = _simpson(dq, xk, xk + dq, wk, wk + slope * dq, parts)
    return [np.take_along_axis(c, k, -1) + p for c, p in zip(cums, part)]


def _direct(x, w, a, b, parts=(0, 1, 2, 3)):
    """The integrals of ``parts`` (:func:`_simpson`) over each span [a, b] (B, C) on its own:
    every segment clipped to the span, moments about the span's midpoint. O(B C S), and no
    cancellation: the moments to round-off, as :func:`prbdm.sections.span_integrals` computes
    them for few stations."""
    xk, xk1, wk, wk1 = x[:, None, :-1], x[:, None, 1:], w[:, None, :-1], w[:, None, 1:]
    a_, b_ = a[..., None], b[..., None]
    lo = np.minimum(np.maximum(a_, xk), xk1)
    hi = np.maximum(np.minimum(b_, xk1), lo)
    dx = xk1 - xk
    slope = np.where(dx > 0, (wk1 - wk) / np.where(dx > 0, dx, 1.0), 0.0)
    mid = (a_ + b_) / 2
    return [v.sum(-1) for v in _simpson(hi - lo, lo - mid, hi - mid, wk + slope * (lo - xk),
                                         wk + slope * (hi - xk), parts)]


def span_integrals(x, w, a, b, *, direct: bool = False, roll: bool = False):
    """NumPy twin of :func:`prbdm.sections.span_integrals` for x, w (B, S) and spans a, b
    (B, C): (area, first, second, compliance) (B, C), moments about each span's midpoint, and
    with ``roll`` the lamina's inertia about the x axis, ``∫ y^2 dA = ∫ (2/3) w^3 dx`` (times
    rho t L^4 in kg m^2). By default built from cumulative integrals (:func:`_cumulative`, for the
    batched prediction), which cancel in the moments: they agree with the torch version to about
    1e-12 relative in the area, 1e-10 in the centred second moment of a short span far from
    the root; ``direct`` integrates each span on its own (:func:`_direct`) to round-off."""
    parts = (0, 1, 2, 3, 4) if roll else (0, 1, 2, 3)
    if direct:
        return tuple(_direct(x, w, a, b, parts))
    C = a.shape[-1]
    F = _cumulative(x, w, np.concatenate([np.broadcast_to(a, b.shape), b], -1), parts)
    m0, m1, m2, *rest = (f[:, C:] - f[:, :C] for f in F)
    mid = (a + b) / 2
    first = m1 - mid * m0
    second = m2 - 2 * mid * m1 + mid * mid * m0
    return (m0, first, second, *rest)


def links_from_gamma(x, w, gamma, direct: bool = False):
    """NumPy twin of :func:`prbdm.model.links_from_gamma` (nondimensional): dict of cuts (...,
    n+2), length (..., n+1), mass, com, inertia, mean_half_width, tributary_compliance (..., n).

    The cumulative integrals are evaluated once at the 2n + 1 distinct points (the cuts and the
    centres of links 1..n-1); links and tributary spans are differences of them. ``direct``:
    each link and span integrated on its own instead (:func:`span_integrals`), to round-off."""
    inner = np.cumsum(gamma[..., :-1], axis=-1)
    zero = np.zeros_like(inner[..., :1])
    cuts = np.concatenate([zero, inner, zero + 1.0], axis=-1)          # (B, n+2)
    mids = (cuts[..., 2:-1] + cuts[..., 1:-2]) / 2                      # centres of links 1..n-1
    # tributary spans: [0, c_1], [c_1, c_2], ..., [c_{n-1}, 1] with c_j the centre of link j
    if direct:
        n = inner.shape[-1]
        m0, first, second, comp = span_integrals(
            x, w, np.concatenate([cuts[:, 1:-1], zero, mids], -1),
            np.concatenate([cuts[:, 2:], mids, zero + 1.0], -1), direct=True)
        m0, first, second, comp = m0[:, :n], first[:, :n], second[:, :n], comp[:, n:]
    else:
        # the mass moments at the cuts, the compliance at the link centres and the free end
        m0, m1, m2 = (f[:, 1:] - f[:, :-1] for f in _cumulative(x, w, cuts[:, 1:], (0, 1, 2)))
        mid = (cuts[:, 2:] + cuts[:, 1:-1]) / 2
        first = m1 - mid * m0
        second = m2 - 2 * mid * m1 + mid * mid * m0
        (fc,) = _cumulative(x, w, np.concatenate([mids, cuts[:, -1:]], -1), (3,))
        # ends c_1..c_{n-1}, then 1; starts 0, then c_1..c_{n-1}
        comp = fc - np.concatenate([np.zeros_like(fc[:, :1]), fc[:, :-1]], -1)
    length = cuts[..., 1:] - cuts[..., :-1]
    lj = length[..., 1:]
    return {"cuts": cuts, "length": length, "mass": m0, "com": lj / 2 + first / m0,
            "inertia": second - first ** 2 / m0, "mean_half_width": m0 / (2 * lj),
            "tributary_compliance": comp}


def mass_matrix(links, theta):
    """NumPy twin of :func:`prbdm.model.mass_matrix` for poses theta (m, n): (..., m, n, n)."""
    n = theta.shape[-1]
    q = np.cumsum(theta, axis=-1)                                        # (m, n)
    e = np.stack([np.cos(q), np.sin(q)], axis=-1)                        # (m, n, 2)
    ell = links["length"][..., None, 1:-1, None]                         # (..., 1, n-1, 1)
    steps = np.cumsum(ell * e[:, :-1, :], axis=-2)                       # (..., m, n-1, 2)
    pad = np.zeros(steps.shape[:-2] + (1, 2))
    steps = np.concatenate([pad, steps], axis=-2)                        # (..., m, n, 2)
    x1 = links["cuts"][..., 1]
    p1 = np.stack([x1, np.zeros_like(x1)], axis=-1)[..., None, None, :]
    p = p1 + steps
    rc = p + links["com"][..., None, :, None] * e                        # (..., m, n, 2)
    lower = np.tril(np.ones((n, n)))                                     # [j, k]: k <= j
    d = (rc[..., :, None, :] - p[..., None, :, :]) * lower[..., None]    # (..., m, j, k, 2)
    md = links["mass"][..., None, :, None, None] * d
    # M_kl = sum_j,d m_j d_jkd d_jld as one batched matrix product over (j, d)
    shape = d.shape[:-3] + (n, 2 * n)
    a = np.swapaxes(md, -3, -2).reshape(shape)
    M = a @ np.swapaxes(np.swapaxes(d, -3, -2).reshape(shape), -1, -2)
    tail = np.flip(np.cumsum(np.flip(links["inertia"], -1), -1), -1)
    idx = np.maximum(np.arange(n)[:, None], np.arange(n)[None, :])
    return M + tail[..., idx][..., None, :, :]


def straight_generators(links):
    """Generators of M at theta = 0: ``M_kl = u_L + p_K v_L`` with ``K = min(k, l)``,
    ``L = max(k, l)`` (a semiseparable matrix). Every link lies on the x axis, so
    M_kl = sum_{j >= max(k,l)} m_j (c_j - p_k)(c_j - p_l) + J_j, with c_j the centres and p_k the
    joints, is a combination of suffix sums of m_j, m_j c_j, m_j c_j^2 and J_j."""
    def suffix(v):
        return np.flip(np.cumsum(np.flip(v, -1), -1), -1)

    m = links["mass"]
    p = links["cuts"][..., 1:-1]
    c = p + links["com"]
    t0, t1, t2 = suffix(m), suffix(m * c), suffix(m * c * c)
    tj = suffix(links["inertia"])
    return t2 + tj - p * t1, p, p * t0 - t1


def straight_mass_matrix(links):
    """M at theta = 0 (..., n, n) in O(n^2) from its generators."""
    u, p, v = straight_generators(links)
    n = u.shape[-1]
    hi = np.maximum.outer(np.arange(n), np.arange(n))
    lo = np.minimum.outer(np.arange(n), np.arange(n))
    return u[..., hi] + p[..., lo] * v[..., hi]


def straight_projected_mass(links, V):
    """``V^T M V`` (..., q, q) at theta = 0 in O(n q^2), without forming M: with the generators,
    sum_{k <= l} V_k M_kl = u_l S0_l + v_l S1_l for the prefix sums S0 of V and S1 of p V."""
    u, p, v = straight_generators(links)
    S0 = np.cumsum(V, axis=-2)
    S1 = np.cumsum(p[..., None] * V, axis=-2)
    incl = u[..., None] * S0 + v[..., None] * S1                          # k <= l
    strict = incl - (u + p * v)[..., None] * V                            # k < l
    return np.swapaxes(incl, -1, -2) @ V + np.swapaxes(V, -1, -2) @ strict


def base_stiffness(links, law: str = "beam", batch: BeamBatch | None = None, si: bool = False):
    """Base joint stiffness s_j (B, n) of :func:`links_from_gamma`'s ``links``, nondimensional
    (SI / (E t^3)), or with ``si`` in N m/rad: the NumPy twin of
    :func:`prbdm.model.base_stiffness`.

    ``beam``: s_j = 1 / ∫ dx / (E I(x)) over the joint's tributary span (the centre of the link
    before it, the clamp for joint 1, to the centre of the link after it, the tip for joint n);
    with I = 2 w t^3 / 12 that is (E t^3 / 6) / ∫ dx / w. ``paper``: s_j = sqrt(E I_j / m_j) [SI]
    with I_j the mean area moment and m_j the mass of link j (joint j drives link j, as in the
    paper's reference code), I_j / m_j = t^2 / (12 rho l_j): Eq. 11 as printed. ``batch`` (the
    beams' E, rho, t, L) is needed for ``paper`` and for ``si``."""
    if law not in LAWS:
        raise BadInput(f"law: must be one of {', '.join(LAWS)}, got {law!r}")
    if batch is None and (si or law == "paper"):
        raise BadInput(f"base_stiffness: the law {law!r}{' in SI' if si else ''} needs the beams "
                       "(batch)")
    if law == "beam":
        c = 6.0 * links["tributary_compliance"]
        return batch.E[:, None] * batch.thickness[:, None] ** 3 / c if si else 1.0 / c
    L, t, E, rho = (v[:, None] for v in (batch.length, batch.thickness, batch.E, batch.rho))
    s = np.sqrt(E * t ** 2 / (12 * rho * links["length"][..., 1:] * L))
    return s if si else s / (E * t ** 3)


def prbdm_eigenvalues(x, w, gamma, poses, with_links: bool = False, law: str = "beam",
                      batch: BeamBatch | None = None, direct: bool = False):
    """Nondimensional PRBDM eigenvalues with every SCF 1, (..., m, n) ascending: the NumPy twin
    of :func:`prbdm.model.eigenvalues_unit_k`. Multiply by ``k_i`` and by ``lambda0`` for SI
    values. x, w (..., S) / L; gamma (..., n+1); poses (m, n) [rad]; ``law`` the base stiffness
    law (:func:`base_stiffness`; ``paper`` needs ``batch``, the beams of x, w); ``direct`` as in
    :func:`links_from_gamma`."""
    links = links_from_gamma(x, w, gamma, direct)
    s = base_stiffness(links, law, batch)                                # (..., n)
    M = mass_matrix(links, np.asarray(poses, dtype=np.float64))
    d = (1.0 / np.sqrt(s))[..., None, :]
    A = d[..., :, None] * M * d[..., None, :]
    mu = np.linalg.eigvalsh(A)
    lam = np.flip(1.0 / mu, -1)
    return (lam, links) if with_links else lam


def link_table(batch: BeamBatch, gamma, k=None, law: str = "beam", direct: bool = False) -> dict:
    """SI link table of each beam's PRBDM: ``joint_x`` [m] (joints 1..n), ``length`` [m] (links
    0..n); for links 1..n ``mass`` [kg], ``com`` [m from the joint], ``inertia`` [kg m^2] about the
    centre of mass, ``area_moment`` [m^4]; ``base_stiffness`` s_j [N m/rad] (of ``law``,
    :func:`base_stiffness`) and, with ``k`` (B, m), ``stiffness`` k_i s_j [N m/rad] per pose
    (B, m, n); ``direct`` as in :func:`links_from_gamma`."""
    gamma = np.asarray(gamma, dtype=np.float64)
    lk = links_from_gamma(batch.x, batch.w, gamma, direct)
    L, t, rho = (v[:, None] for v in (batch.length, batch.thickness, batch.rho))
    s = base_stiffness(lk, law, batch, si=True)
    out = {"joint_x": lk["cuts"][..., 1:-1] * L, "length": lk["length"] * L,
           "mass": lk["mass"] * rho * t * L ** 2, "com": lk["com"] * L,
           "inertia": lk["inertia"] * rho * t * L ** 4,
           "area_moment": 2 * lk["mean_half_width"] * L * t ** 3 / 12, "base_stiffness": s}
    if k is not None:
        out["stiffness"] = np.asarray(k, dtype=np.float64)[:, :, None] * s[:, None, :]
    return out


def loss_percent_np(omega_or_lam_pose, lam_truth, r: int, is_lambda: bool = True):
    """NumPy twin of :func:`prbdm.model.loss_percent`: (..., m, n) eigenvalues per pose against
    (..., R) truth eigenvalues, first r modes, in percent."""
    lam = omega_or_lam_pose if is_lambda else omega_or_lam_pose ** 2
    ref = lam_truth[..., None, :r]
    rel = np.linalg.norm(lam[..., :r] - ref, axis=-1) / np.linalg.norm(ref, axis=-1)
    return 100.0 * rel.mean(-1)


# ----------------------------------------------------------------------------- a chain in SI
# The dynamics and statics of one planar chain of rigid links 1..n (link 0 clamped), SI units,
# relative joint angles theta: used by :mod:`prbdm.simulate` and benchmarks/large_deflection.py.
# A spring law (:mod:`prbdm.springs`) is any object with ``torque(theta)``, ``dtorque(theta)``
# (the diagonal of its stiffness) and ``energy(theta)``.
def absolute_inertia(length, com, mass, inertia) -> np.ndarray:
    """The constant matrix A (n, n) [kg m^2] of the chain's kinetic energy in the absolute link
    angles ``q_j = theta_1 + ... + theta_j``:

        T = 1/2 sum_ab A_ab cos(q_a - q_b) q'_a q'_b,   A_ab = sum_j m_j L_ja L_jb + delta_ab J_a,

    ``L_ja`` the lever of link a's rate on the centre of link j (the length of link a for a < j,
    the centre offset ``com_j`` for a = j, 0 beyond). length, com (from the link's joint), mass,
    inertia (about the centre): (n,) for links 1..n."""
    length, com = np.asarray(length, float), np.asarray(com, float)
    mass, inertia = np.asarray(mass, float), np.asarray(inertia, float)
    n = length.size
    Lm = np.zeros((n, n))                      # L[j, a]: lever of link a's rate on centre j
    for j in range(n):
        Lm[j, :j] = length[:j]
        Lm[j, j] = com[j]
    return np.einsum("j,ja,jb->ab", mass, Lm, Lm) + np.diag(inertia)


def joint_mass_matrix(A, theta) -> np.ndarray:
    """M(theta) = T^T (A o cos(q_a - q_b)) T [kg m^2] in the relative angles theta (n,); equals
    :func:`prbdm.model.mass_matrix` in SI (tests/test_simulate.py)."""
    q = np.cumsum(theta)
    n = q.size
    T = np.tril(np.ones((n, n)))
    return T.T @ (A * np.cos(q[:, None] - q[None, :])) @ T


def joint_coriolis(A, theta, theta_dot) -> np.ndarray:
    """The Coriolis/centrifugal term C(theta, theta') theta' [N m] in joint coordinates,
    ``T^T sum_b A_ab sin(q_a - q_b) q'_b^2`` (the Christoffel symbols of M in closed form;
    equals the one from autograd of the kinetic energy, tests/test_simulate.py)."""
    q, qd = np.cumsum(theta), np.cumsum(theta_dot)
    h = (A * np.sin(q[:, None] - q[None, :])) @ (qd * qd)
    return np.cumsum(h[::-1])[::-1]            # T^T h


def joint_accelerations(A, theta, theta_dot, torque) -> np.ndarray:
    """theta'' (n,) of the chain under joint torques ``torque`` (n,) [N m] (springs, damping,
    drive): Lagrange's equations in the absolute angles,
    ``sum_b A_ab cos(q_a - q_b) q''_b + sum_b A_ab sin(q_a - q_b) q'_b^2 = Q_a`` with
    ``Q_a = tau_a - tau_{a+1}``, solved for q'' and mapped back (microseconds, no torch)."""
    q, qd = np.cumsum(theta), np.cumsum(theta_dot)
    dq = q[:, None] - q[None, :]
    Qq = torque.copy()
    Qq[:-1] -= torque[1:]                      # generalised forces on q: T^-T tau
    h = (A * np.sin(dq)) @ (qd * qd)
    qdd = np.linalg.solve(A * np.cos(dq), Qq - h)
    return np.diff(qdd, prepend=0.0)


def tip_position(length, theta):
    """Tip (x, z) [m] relative to joint 1 for theta (..., n): the sum of the link vectors."""
    q = np.cumsum(theta, axis=-1)
    return np.sum(length * np.cos(q), axis=-1), np.sum(length * np.sin(q), axis=-1)


@dataclass
class TipLoadStatics:
    """Static equilibria of the chain (links 1..n of lengths ``length`` [m], joint 1 at
    ``(x1, 0)``) with joint springs ``springs`` under a dead tip force F = (F_x, F_z) [N]: the
    minima of the potential ``V(theta) = springs.energy(theta) - F . r_tip(theta)``."""

    length: np.ndarray
    springs: object
    x1: float = 0.0
    name: str = "chain"

    def __post_init__(self):
        self.length = np.asarray(self.length, float)

    @property
    def n(self) -> int:
        return self.length.size

    def tip(self, th) -> np.ndarray:
        x, z = tip_position(self.length, th)
        return np.array([x + self.x1, z])

    @staticmethod
    def tip_angle(th) -> float:
        return float(np.sum(th))

    def potential(self, th, F) -> float:
        return self.springs.energy(th) - float(np.dot(F, self.tip(th)))

    def gradient_hessian(self, th, F):
        """(dV/dtheta, d2V/dtheta2) of the potential under the dead tip force F."""
        q = np.cumsum(th)
        ell = self.length
        # d r_tip / d theta_k = sum_{j>=k} ell_j n(q_j)
        fn = ell * (-F[0] * np.sin(q) + F[1] * np.cos(q))          # F . n_j ell_j
        fe = ell * (F[0] * np.cos(q) + F[1] * np.sin(q))           # F . e_j ell_j
        g = self.springs.torque(th) - np.cumsum(fn[::-1])[::-1]
        tail = np.cumsum(fe[::-1])[::-1]
        idx = np.maximum.outer(np.arange(self.n), np.arange(self.n))
        H = tail[idx] + np.diag(self.springs.dtorque(th))
        return g, H

    def equilibrium(self, F, th0) -> np.ndarray:
        """Minimum of the potential under the dead tip force F [N] near ``th0`` (trust-region
        Newton, then Newton steps); RuntimeError where none is found or it is not stable."""
        from scipy.optimize import minimize

        F = np.asarray(F, float)
        scale = max(float(np.max(self.springs.dtorque(np.zeros(self.n)))), 1e-300)
        res = minimize(lambda t: self.potential(t, F) / scale, np.array(th0, float),
                       jac=lambda t: self.gradient_hessian(t, F)[0] / scale,
                       hess=lambda t: self.gradient_hessian(t, F)[1] / scale,
                       method="trust-exact", options={"gtol": 1e-12, "maxiter": 500})
        th = res.x
        for _ in range(5):                      # Newton polish
            g, H = self.gradient_hessian(th, F)
            th = th - np.linalg.solve(H, g)
        g, H = self.gradient_hessian(th, F)
        if np.max(np.abs(g)) / scale > 1e-9 or np.linalg.eigvalsh(H)[0] <= 0:
            raise RuntimeError(f"{self.name}: no stable equilibrium found under F = {F}")
        return th

    def step_to(self, F0, th0, F1) -> np.ndarray:
        """Equilibrium under F1 continued from (F0, th0), with sub-steps where needed."""
        F0, F1 = np.asarray(F0, float), np.asarray(F1, float)
        steps = 1
        while True:
            try:
                t = np.array(th0, float)
                for s in range(1, steps + 1):
                    t = self.equilibrium(F0 + (F1 - F0) * s / steps, t)
                return t
            except RuntimeError:
                steps *= 4
                if steps > 256:
                    raise

    def path(self, forces) -> list:
        """Equilibria along a sequence of forces (rows), by continuation from the unloaded
        chain."""
        th, Fprev, out = np.zeros(self.n), np.zeros(2), []
        for F in np.asarray(forces, float):
            th = self.step_to(Fprev, th, F)
            Fprev = F
            out.append(th.copy())
        return out

    def release_shape(self, target, force_angle=math.pi / 2, load_guess=None,
                      measure: str = "tip_angle"):
        """(theta, force magnitude [N]): the equilibrium under a tip force at ``force_angle``
        [rad] whose ``measure`` (``"tip_angle"``: the last link's angle [rad]; ``"tip_z"``: the
        tip's z [m]) is ``target``: the load is raised in steps of ``load_guess / 8`` [N] until
        the measure passes the target, then solved for by Brent's method. RuntimeError where
        400 steps do not reach it."""
        from scipy.optimize import brentq

        if measure not in ("tip_angle", "tip_z"):
            raise ValueError(f"measure: 'tip_angle' or 'tip_z', got {measure!r}")

        def value(th):
            return self.tip_angle(th) if measure == "tip_angle" else float(self.tip(th)[1])
        sign = 1.0 if target >= 0 else -1.0
        d = np.array([math.cos(force_angle), math.sin(force_angle)])
        step = (load_guess or 1.0) / 8
        lo, th_lo, hi = 0.0, np.zeros(self.n), None
        for _ in range(400):           # march the load up until the measure passes the target
            th_t = self.step_to(d * lo, th_lo, d * (lo + step))
            if sign * value(th_t) >= sign * target:
                hi = lo + step
                break
            lo, th_lo = lo + step, th_t
        if hi is None:
            raise RuntimeError(f"{self.name}: {measure.replace('_', ' ')} {target} not reached")

        def miss(P):
            t = self.step_to(d * lo, th_lo, d * P)
            return value(t) - target
        Ps = brentq(miss, lo, hi, xtol=1e-15 * hi, rtol=1e-14)
        return self.step_to(d * lo, th_lo, d * Ps), Ps


@dataclass
class ChainDynamics:
    """Planar chain of links 1..n (link 0 clamped), SI units, relative joint angles theta.

    length (n,) link lengths [m] (link j from joint j to joint j+1, the tip for j = n);
    com (n,) centre of mass from joint j [m]; mass (n,) [kg]; inertia (n,) about the centre
    [kg m^2]; stiffness, damping (n,) per joint [N m/rad, N m s/rad]; springref (n,) rest angles;
    springs: the joint spring law (:mod:`prbdm.springs`; default the constant ``stiffness`` about
    ``springref``). ``A``: :func:`absolute_inertia`; its equations are :func:`joint_accelerations`;
    :mod:`prbdm.simulate` integrates them.
    """

    length: np.ndarray
    com: np.ndarray
    mass: np.ndarray
    inertia: np.ndarray
    stiffness: np.ndarray
    damping: np.ndarray
    springref: np.ndarray
    springs: object = None
    A: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        from .springs import LinearSprings

        for name in ("length", "com", "mass", "inertia", "stiffness", "damping", "springref"):
            setattr(self, name, np.asarray(getattr(self, name), dtype=float))
        if self.springs is None:
            self.springs = LinearSprings(self.stiffness, self.springref)
        self.A = absolute_inertia(self.length, self.com, self.mass, self.inertia)

    @property
    def n(self) -> int:
        return self.length.size

    @classmethod
    def from_description(cls, desc: dict, springs=None) -> "ChainDynamics":
        """From :func:`prbdm.export.prbdm_from_fit`'s description; ``springs`` replaces its
        constant hinge stiffness by another law (:func:`prbdm.springs.fitted_springs`)."""
        bodies, hinges = desc["bodies"][1:], desc["hinges"]
        return cls(length=[b["length"] for b in bodies], com=[b["com"][0] for b in bodies],
                   mass=[b["mass"] for b in bodies], inertia=[b["inertia"][1] for b in bodies],
                   stiffness=[h["stiffness"] for h in hinges],
                   damping=[h["damping"] for h in hinges],
                   springref=[h["springref"] for h in hinges], springs=springs)

    def mass_matrix(self, theta) -> np.ndarray:
        """M(theta) [kg m^2], relative angles."""
        return joint_mass_matrix(self.A, theta)

    def coriolis(self, theta, theta_dot) -> np.ndarray:
        """C(theta, theta') theta' [N m] in joint coordinates."""
        return joint_coriolis(self.A, theta, theta_dot)

    def rhs(self, t, y, tau=None):
        """d/dt [theta, theta'] for solve_ivp; tau(t) -> (n,) joint torques, optional."""
        n = self.n
        theta, thd = y[:n], y[n:]
        Q = -self.springs.torque(theta) - self.damping * thd
        if tau is not None:
            Q = Q + tau(t)
        return np.concatenate([thd, joint_accelerations(self.A, theta, thd, Q)])

    def tip(self, theta):
        """Tip position (x relative to joint 1, z) [m] for theta (..., n)."""
        return tip_position(self.length, theta)

    def energy(self, theta, theta_dot) -> float:
        """Kinetic + spring energy [J]."""
        M = self.mass_matrix(theta)
        return float(0.5 * theta_dot @ M @ theta_dot) + self.springs.energy(np.asarray(theta))

    def integrate(self, y0, duration: float, t, rtol: float, atol, **options):
        """The nonlinear motion from ``y0`` = (theta, theta_dot) over ``[0, duration]`` [s],
        sampled at ``t``: scipy's DOP853 at ``rtol`` / ``atol`` (``options``: ``events``,
        ``dense_output``). Returns the solution and its wall time [s]; RuntimeError if it fails."""
        import time

        from scipy.integrate import solve_ivp

        ts = time.perf_counter()
        sol = solve_ivp(self.rhs, (0.0, duration), y0, method="DOP853", t_eval=t, rtol=rtol,
                        atol=atol, **options)
        if not sol.success:
            raise RuntimeError(f"solve_ivp failed: {sol.message}")
        return sol, time.perf_counter() - ts

    def linear_frequencies(self, theta=None) -> np.ndarray:
        """omega [rad/s] of K v = lambda M(theta) v (default about the spring reference)."""
        from scipy.linalg import eigh

        theta = self.springref if theta is None else theta
        return np.sqrt(eigh(np.diag(self.stiffness), self.mass_matrix(theta), eigvals_only=True))

    def lever(self) -> np.ndarray:
        """d z_tip / d theta_k at theta = 0: distance from joint k to the tip [m]."""
        return np.cumsum(self.length[::-1])[::-1]

    def static_tip_shape(self, deflection: float) -> np.ndarray:
        """theta of the linear static shape under a tip force, scaled so that the tip's z
        (exact kinematics) is ``deflection``."""
        from scipy.optimize import brentq

        shape = self.lever() / self.stiffness
        shape = shape / (self.lever() @ shape)     # unit tip deflection to first order
        if deflection == 0:
            return np.zeros(self.n)
        # up to a total rotation of pi/2 the tip's z grows monotonically along the shape
        s_hi = math.copysign(0.5 * math.pi / np.abs(shape).sum(), deflection)
        z_hi = self.tip(s_hi * shape)[1]
        if abs(deflection) >= abs(z_hi):
            raise BadInput(f"--tip-deflection: {deflection:g} m is more than this chain reaches "
                           f"in its static shape ({abs(z_hi):.4g} m)")
        s = brentq(lambda s: self.tip(s * shape)[1] - deflection, 0.0, s_hi,
                   xtol=1e-16 * abs(s_hi), rtol=1e-15)
        return s * shape

    def statics(self, x1: float = 0.0) -> TipLoadStatics:
        """Its equilibria under a dead tip force (:class:`prbdm.chain.TipLoadStatics`; joint 1
        at ``(x1, 0)``), with its spring law."""
        return TipLoadStatics(self.length, self.springs, x1, "the PRBDM")

    def impulse_velocity(self, impulse: float) -> np.ndarray:
        """theta'(0) after a tip impulse P [N s] (along z) on the straight chain at rest."""
        return np.linalg.solve(self.mass_matrix(np.zeros(self.n)), self.lever() * impulse)
