"""The discretised geometrically exact planar rod (used by :mod:`prbdm.truth.rod`).

Nondimensional throughout: arc length ``s`` by ``L``, bending stiffness ``E I(s)`` by its largest
value, mass per length ``rho A(s)`` by its largest value, forces by ``E I_max / L^2``, moments by
``E I_max / L``, time by ``sqrt(rho A_max L^4 / E I_max)``. For the panel ``E I`` and ``rho A``
are both proportional to the width, so one profile ``b(s) = w(s) / w_max`` serves both.

The rod is inextensible and unshearable; its configuration is the tangent angle ``theta(s)``
(``r' = e(theta) = (cos theta, sin theta)``), ``theta(0) = 0`` at the clamp. The angle is
``theta = theta_rest(s) + sum_i q_i phi_i(s)`` with ``phi_i`` continuous piecewise polynomials
(Lagrange on Gauss-Lobatto nodes, elements meeting at every station of the planform and every
break of the rest shape). Nothing else is approximated: the position and velocity of every point
are the exact integrals of the kinematics,

    r(s) = int_0^s e(theta) ds',   rdot(s) = J(s) qdot,   J(s) = int_0^s n(theta) phi^T ds',

(``n = de/dtheta``) evaluated by spectral integration on Gauss points inside each element, so the
kinetic energy ``T = 1/2 int rhoA |rdot|^2 ds (+ 1/2 int rhoI thetadot^2 ds)`` and hence the mass
matrix ``M(q) = int rhoA J^T J ds (+ int rhoI phi phi^T ds)`` hold at every configuration. The
strain energy is ``U = 1/2 int EI (theta' - theta_rest')^2 ds = 1/2 q^T K q``. Lagrange's
equations, written through the virtual work of the accelerations
``rddot(s) = J(s) qddot - int_0^s e(theta) thetadot^2 ds'``, are

    M(q) qddot = -K q - int rhoA J^T c ds + Q(q),   c(s) = -int_0^s e(theta) thetadot^2 ds',

with ``Q`` the generalised tip load (dead force ``F``, moment ``M0``):
``Q = int (F . n(theta)) phi ds + M0 phi(1)``. Its derivative gives the geometric (load)
stiffness ``K_G = int (F . e(theta)) phi phi^T ds``, which adds to ``K`` about a loaded
equilibrium and vanishes about a stress-free shape. The model does not import the chain model
(:mod:`prbdm.model`): it is an independent discretisation of the continuous rod, converging as
the elements are refined or their degree raised.
"""
from __future__ import annotations

import numpy as np
from numpy.polynomial import legendre as npleg
from scipy.linalg import lu_factor as _lu_factor
from scipy.linalg import lu_solve as _lu_solve

__all__ = ["RodGalerkin", "element_edges"]


def _gll_nodes(p: int) -> np.ndarray:
    """Gauss-Lobatto-Legendre nodes of degree ``p`` on [-1, 1] (p + 1 points)."""
    if p == 1:
        return np.array([-1.0, 1.0])
    c = np.zeros(p + 1)
    c[p] = 1.0
    inner = npleg.legroots(npleg.legder(c))
    return np.concatenate([[-1.0], np.sort(inner.real), [1.0]])


def _lagrange(nodes: np.ndarray, x: np.ndarray):
    """Values and derivatives at ``x`` of the Lagrange polynomials on ``nodes``."""
    m = nodes.size
    V = npleg.legvander(nodes, m - 1)             # V[i, k] = P_k(node_i)
    C = np.linalg.inv(V)                           # l_j = sum_k C[k, j] P_k
    Vx = npleg.legvander(x, m - 1)
    dVx = np.stack([npleg.legval(x, npleg.legder(np.eye(m)[k])) for k in range(m)], axis=1)
    return Vx @ C, dVx @ C


def _cumulative_matrix(xq: np.ndarray) -> np.ndarray:
    """S[i, j] = int_{-1}^{x_i} l_j(x) dx for the Lagrange polynomials l_j on the points ``xq``:
    spectral cumulative integration of a function sampled at ``xq``."""
    Q = xq.size
    V = npleg.legvander(xq, Q - 1)
    Vp = npleg.legvander(xq, Q)                     # P_0 .. P_Q at the points
    IntV = np.empty((Q, Q))
    IntV[:, 0] = xq + 1.0
    for k in range(1, Q):
        IntV[:, k] = (Vp[:, k + 1] - Vp[:, k - 1]) / (2 * k + 1)
    return IntV @ np.linalg.inv(V)


def element_edges(breaks, elements: int) -> np.ndarray:
    """Element edges on [0, 1]: every break (stations, kinks of a rest shape) is an edge and
    no element is longer than ``1 / elements``."""
    b = np.unique(np.clip(np.concatenate([[0.0, 1.0], np.asarray(breaks, float)]), 0.0, 1.0))
    b = b[np.concatenate([[True], np.diff(b) > 1e-12])]
    b[-1] = 1.0
    edges = [0.0]
    for a, c in zip(b[:-1], b[1:]):
        k = max(1, int(np.ceil((c - a) * elements - 1e-9)))
        edges.extend(a + (c - a) * np.arange(1, k + 1) / k)
    return np.array(edges)


#: largest ratio of the width across one element: the curvature under a moment goes like
#: 1 / (E I), which a polynomial follows poorly where the width changes many times over within an
#: element (random_beam(0, 1), its width 20 times smaller over 0.013 L: mode 1 7e-4 above the
#: converged value with 12 elements, 1e-5 with the width graded by this ratio)
WIDTH_STEP = 1.25


def _width_grading(stations, profile) -> np.ndarray:
    """Extra element edges inside each planform segment where the width changes by more than
    WIDTH_STEP: at the points where it has changed by each further factor of WIDTH_STEP."""
    extra = []
    for a, c, ba, bc in zip(stations[:-1], stations[1:], profile[:-1], profile[1:]):
        lo, hi = min(ba, bc), max(ba, bc)
        if c <= a or lo <= 0 or hi / lo <= WIDTH_STEP:
            continue
        levels = lo * WIDTH_STEP ** np.arange(1, int(np.log(hi / lo) / np.log(WIDTH_STEP)) + 1)
        extra.extend(a + (c - a) * (levels[levels < hi] - ba) / (bc - ba))
    return np.asarray(extra, float)


class RodGalerkin:
    """The planar inextensible rod on ``elements`` x ``degree`` angle unknowns.

    stations, profile: the nondimensional stations ``x_k / L`` and ``b_k = w_k / w_max``
    (``rho A`` and ``E I`` both follow ``b``, piecewise linear).
    rotary: ``t^2 / (12 L^2)`` to include the rotary inertia of the section, else 0.
    theta_rest: the stress-free shape, a function of nondimensional ``s`` (None: straight);
    breaks: where it has kinks or jumps (made element edges).
    """

    def __init__(self, stations, profile, *, elements: int = 12, degree: int = 6,
                 rotary: float = 0.0, theta_rest=None, breaks=(), quad: int | None = None):
        self.stations = np.asarray(stations, float)
        self.profile = np.asarray(profile, float)
        self.degree = p = int(degree)
        self.edges = edges = element_edges(
            np.concatenate([self.stations, _width_grading(self.stations, self.profile),
                            np.asarray(breaks, float)]), elements)
        E = edges.size - 1
        Q = int(quad) if quad else p + 10
        self.E, self.Q = E, Q
        xq, wq = npleg.leggauss(Q)
        h = np.diff(edges)
        self.h = h
        self.s = (0.5 * (edges[:-1, None] + edges[1:, None]) + 0.5 * h[:, None] * xq[None, :]).ravel()
        self.w = (0.5 * h[:, None] * wq[None, :]).ravel()
        self.wq = wq
        self.S = _cumulative_matrix(xq)
        self._half3 = 0.5 * h[:, None, None]
        self.b = np.interp(self.s, self.stations, self.profile)
        nodes = _gll_nodes(p)
        B, D = _lagrange(nodes, xq)
        self.n = n = E * p                         # node 0 (the clamp) removed
        Phi = np.zeros((E * Q, n + 1))
        dPhi = np.zeros((E * Q, n + 1))
        for e in range(E):
            Phi[e * Q:(e + 1) * Q, e * p:e * p + p + 1] = B
            dPhi[e * Q:(e + 1) * Q, e * p:e * p + p + 1] = D * (2.0 / h[e])
        self.Phi, self.dPhi = Phi[:, 1:], dPhi[:, 1:]
        # the unknowns' positions: each element's nodes but its last, then the tip, less the clamp
        inner = (edges[:-1, None] + 0.5 * h[:, None] * (nodes[None, :-1] + 1)).ravel()
        self.node_s = np.append(inner, 1.0)[1:]
        self.tip = np.zeros(n)
        self.tip[-1] = 1.0                                       # phi(1): the last node
        self.K = (self.dPhi * (self.w * self.b)[:, None]).T @ self.dPhi
        self.rotary = float(rotary)
        self.M_rot = ((self.Phi * (self.w * self.b * self.rotary)[:, None]).T @ self.Phi
                      if self.rotary else None)
        self.theta_rest = (np.zeros_like(self.s) if theta_rest is None
                           else np.asarray(theta_rest(self.s), float))
        self._lu = None           # the midpoint rule's Newton matrix, factorised, and its step
        self.halvings = 0         # steps taken as two halves (prbdm.truth.rod._advance)

    # ------------------------------------------------------------------ kinematics
    def cumint(self, f: np.ndarray):
        """Cumulative integral from 0 of ``f`` (values at the Gauss points, first axis) to each
        Gauss point, and the total to s = 1."""
        E, Q = self.E, self.Q
        fe = f.reshape(E, Q, -1) * self._half3
        inside = np.matmul(self.S, fe)
        totals = np.matmul(self.wq, fe)
        offsets = np.cumsum(totals, axis=0) - totals
        return (inside + offsets[:, None, :]).reshape(f.shape), totals.sum(axis=0).reshape(
            f.shape[1:])

    def theta(self, q):
        return self.theta_rest + self.Phi @ q

    def positions(self, q):
        """Positions at the Gauss points (G, 2) and of the tip (2,)."""
        th = self.theta(q)
        return self.cumint(np.stack([np.cos(th), np.sin(th)], axis=1))

    def jacobian(self, th):
        """J at the Gauss points (G, 2, n) and at the tip (2, n): d r / d q."""
        nrm = np.stack([-np.sin(th), np.cos(th)], axis=1)
        return self.cumint(nrm[:, :, None] * self.Phi[:, None, :])

    def mass(self, q, J=None):
        if J is None:
            J, _ = self.jacobian(self.theta(q))
        Jw = (J * np.sqrt(self.w * self.b)[:, None, None]).reshape(-1, J.shape[2])
        M = Jw.T @ Jw
        return M + self.M_rot if self.M_rot is not None else M

    # ------------------------------------------------------------------ loads and statics
    def load(self, q, F, M0):
        """Generalised tip load Q(q) and its geometric stiffness K_G = -dQ/dq."""
        th = self.theta(q)
        c, s = np.cos(th), np.sin(th)
        Fn = -F[0] * s + F[1] * c
        Fe = F[0] * c + F[1] * s
        Qv = self.Phi.T @ (self.w * Fn) + M0 * self.tip
        KG = (self.Phi * (self.w * Fe)[:, None]).T @ self.Phi
        return Qv, KG

    def static(self, F, M0, q0, tol: float = 1e-10, iters: int = 30):
        """Newton on K q = Q(q) from ``q0``; returns (q, K_T, converged)."""
        F = np.asarray(F, float)
        q = np.array(q0, float)
        scale = 1.0 + abs(M0) + np.hypot(*F)
        for _ in range(iters):
            Qv, KG = self.load(q, F, M0)
            R = self.K @ q - Qv
            KT = self.K + KG
            dq = np.linalg.solve(KT, R)
            q -= dq
            if np.max(np.abs(dq)) < tol * (1.0 + np.max(np.abs(q))) and \
                    np.max(np.abs(R)) < 1e-9 * scale:
                Qv, KG = self.load(q, F, M0)
                return q, self.K + KG, True
        return q, self.K + self.load(q, F, M0)[1], False

    # ------------------------------------------------------------------ matrix-free kinematics
    def cumint_t(self, y: np.ndarray) -> np.ndarray:
        """The transpose of :meth:`cumint`'s map to the Gauss points, applied to ``y`` (G, k):
        ``sum_g y_g . cumint(f)_g = sum_g' cumint_t(y)_g' . f_g'`` for every ``f``."""
        E, Q = self.E, self.Q
        ye = y.reshape(E, Q, -1)
        per = ye.sum(axis=1)                                    # (E, k)
        later = per.sum(axis=0) - np.cumsum(per, axis=0)        # sum over the elements after e
        out = (np.matmul(self.S.T, ye) + self.wq[None, :, None] * later[:, None, :]) * self._half3
        return out.reshape(y.shape)

    def velocities(self, th, v):
        """``J v``: velocities at the Gauss points (G, 2) and of the tip (2,), without forming J."""
        nrm = np.stack([-np.sin(th), np.cos(th)], axis=1)
        return self.cumint(nrm * (self.Phi @ v)[:, None])

    def _jt(self, th, y):
        """``J^T y`` for ``y`` (G, 2) at the Gauss points, without forming J."""
        ct = self.cumint_t(y)
        return self.Phi.T @ (-np.sin(th) * ct[:, 0] + np.cos(th) * ct[:, 1])

    def _centripetal(self, th, v):
        """``c(s) = -int_0^s e(theta) thetadot^2 ds'`` at the Gauss points (G, 2)."""
        thd = self.Phi @ v
        return self.cumint(-np.stack([np.cos(th), np.sin(th)], axis=1) * (thd ** 2)[:, None])[0]

    # ------------------------------------------------------------------ dynamics
    def forces(self, q, v, F=(0.0, 0.0), M0=0.0):
        """M(q) and the generalised forces f(q, v) of Lagrange's equations M qddot = f:
        elastic, centripetal/Coriolis (exact) and the tip load."""
        th = self.theta(q)
        J, _ = self.jacobian(th)
        M = self.mass(q, J)
        wc = self._centripetal(th, v) * (self.w * self.b)[:, None]
        f = -self.K @ q - wc.reshape(-1) @ J.reshape(-1, J.shape[2])
        if F[0] or F[1] or M0:
            f = f + self.load(q, np.asarray(F, float), M0)[0]
        return M, f

    def accel(self, q, v, F=(0.0, 0.0), M0=0.0):
        """qddot from Lagrange's equations (exact centripetal/Coriolis terms)."""
        M, f = self.forces(q, v, F, M0)
        return np.linalg.solve(M, f)

    def _midpoint_residual(self, q0, v0, u, h):
        """``M(qm) (v1 - v0) - h f(qm, vm)`` of the free rod at ``u = q1 - q0``, without forming
        M(qm): ``J^T (rhoA (J a + h c)) + M_rot a + h K qm`` with ``a = 2 u / h - 2 v0``."""
        qm, vm, a = q0 + 0.5 * u, u / h, 2.0 * u / h - 2.0 * v0
        th = self.theta(qm)
        wb = (self.w * self.b)[:, None]
        ra, _ = self.velocities(th, a)
        res = self._jt(th, wb * (ra + h * self._centripetal(th, vm))) + h * (self.K @ qm)
        return res + self.M_rot @ a if self.M_rot is not None else res

    def _iteration_matrix(self, q, h):
        """LU of ``(2/h) M(q) + (h/2) K``, the Newton matrix of the midpoint rule at ``q``."""
        self._lu = (_lu_factor((2.0 / h) * self.mass(q) + 0.5 * h * self.K), h)

    def midpoint_step(self, q0, v0, h, tol: float = 1e-11, iters: int = 30):
        """One step of the implicit midpoint rule: ``q1 = q0 + h vm``,
        ``M(qm) (v1 - v0) = h f(qm, vm)`` at ``qm = (q0 + q1)/2``, ``vm = (v0 + v1)/2``.
        Second order, symmetric, A-stable and without numerical damping: the rod's stiff high
        modes need not be resolved.

        Solved for ``u = q1 - q0`` by a simplified Newton iteration: the residual is matrix-free
        (a few matrix-vector products, no n x n matrix formed), the matrix
        ``(2/h) M + (h/2) K`` is kept from step to step and formed again at ``q0`` only when
        the iteration contracts slowly (its solution does not depend on the matrix).
        Converged when the update is below ``tol (1 + |u|)``, or, once the residual has fallen
        by 1e-9, when the update stops falling below ``100 tol (1 + |u|)`` (the floor that
        rounding sets on a rod whose mass matrix spans many decades)."""
        fresh = self._lu is None or self._lu[1] != h
        for _attempt in range(2):
            if fresh:
                self._iteration_matrix(q0, h)
            lu = self._lu[0]
            u = h * v0
            r0 = None
            prev = np.inf
            for it in range(iters if fresh else 8):
                res = self._midpoint_residual(q0, v0, u, h)
                rn = np.max(np.abs(res))
                if not np.isfinite(rn):
                    break                       # diverged (lu_solve would raise ValueError)
                r0 = rn if r0 is None else r0
                du = _lu_solve(lu, res)
                u -= du
                dn = np.max(np.abs(du))
                scale = 1.0 + np.max(np.abs(u))
                if not np.isfinite(dn):
                    break
                if dn <= tol * scale or (rn <= 1e-9 * r0 and dn <= 100 * tol * scale
                                         and dn > 0.5 * prev):
                    return q0 + u, 2.0 * u / h - v0
                if not fresh and it >= 2 and dn > 0.3 * prev:
                    break                                   # slow: form the matrix again
                prev = dn
            if fresh:
                break
            fresh = True
        self._lu = None
        raise ArithmeticError("the implicit midpoint iteration did not converge; "
                              "take more steps per period")

    def rhs(self, t, y):
        n = self.n
        return np.concatenate([y[n:], self.accel(y[:n], y[n:])])

    def energy(self, q, v):
        """Kinetic + strain energy (free rod)."""
        rd, _ = self.velocities(self.theta(q), v)
        T = 0.5 * np.sum(self.w * self.b * np.sum(rd * rd, axis=1))
        if self.M_rot is not None:
            T += 0.5 * v @ self.M_rot @ v
        return T + 0.5 * q @ self.K @ q

    def tip_velocity(self, q, v):
        return self.velocities(self.theta(q), v)[1]
