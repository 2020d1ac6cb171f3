"""Sparse linear algebra shared by the FEM models."""
from __future__ import annotations

import math

import numpy as np
import scipy.linalg
import scipy.sparse as sp
from scipy.sparse.linalg import LinearOperator, splu


def refined_inverse(K, steps: int = 1, spd: bool = False) -> LinearOperator:
    """``K^-1`` as a LinearOperator for shift-invert Lanczos: a sparse LU of ``K`` plus
    ``steps`` rounds of iterative refinement (``x += LU^-1 (b - K x)``).

    Graded meshes (elements 1e-5 long beside elements 1e-2 long) give stiffness matrices with
    condition numbers of 1e12 even after diagonal scaling; a plain LU solve then carries relative
    errors of ~1e-5 into the lowest eigenvalues. One refinement step squares that error away for
    the cost of one more triangular solve and one sparse product.

    ``spd=True`` (``K`` symmetric positive definite, e.g. a diagonally scaled clamped stiffness):
    SuperLU's symmetric mode, a minimum-degree ordering of ``K + K^T`` and no pivoting (an SPD
    matrix needs none), which keeps the factors symmetric in structure: about 40 % fewer nonzeros
    than the default column ordering with partial pivoting, hence a cheaper factorisation and
    cheaper solves.
    """
    K = K.tocsc()
    if spd:
        lu = splu(K, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                  options={"SymmetricMode": True})
    else:
        lu = splu(K)

    def solve(b):
        x = lu.solve(b)
        for _ in range(steps):
            x = x + lu.solve(b - K @ x)
        return x

    return LinearOperator(K.shape, matvec=solve, matmat=solve, dtype=float)



def grown(k: int) -> int:
    """The next number of modes to ask a :class:`ShiftInvertLanczos` for when those computed
    were not enough (too little bending among them): half as many again, at least 8 more. The
    Krylov basis is kept, so a small step costs only the steps it adds; doubling overshot (on the
    paper's wide panels, 6 bending modes of the spectrum: 0.90 s a Mindlin panel instead of 1.18,
    benchmarks/bench_truth.py)."""
    return int(k) + max(8, int(k) // 2)


class ShiftInvertLanczos:
    """The lowest eigenpairs of ``K x = lambda M x`` (``K``, ``M`` symmetric positive definite)
    by Lanczos on ``K^-1 M`` in the ``M`` inner product, with full reorthogonalisation.

    It replaces ARPACK's ``eigsh(K, M=M, sigma=0, OPinv=...)`` for the plate, for two reasons:
    with scipy's ARPACK the extraction of the Ritz vectors (``dseupd``) alone cost about 0.1 s
    for a 4,000-DOF plate, two thirds of the eigen-solve, where the Ritz vectors are one small
    matrix product here; and the Krylov basis is kept, so asking for more modes (the plate's
    mode search doubles its count when too few bending modes were found) extends the basis
    instead of starting over. With full reorthogonalisation (twice, "twice is enough") no Ritz
    value is duplicated, and the Krylov space grows until every wanted pair has converged:
    ``||K^-1 M x - theta x||_M <= tol * theta`` (ARPACK's criterion), read off the projected
    matrix.

    ``solve(b)`` = ``K^-1 b``; ``v0`` the start vector (a fixed one makes results reproducible).
    """

    def __init__(self, solve, M, v0, tol: float = 1e-10):
        self.solve, self.M, self.tol = solve, M, tol
        self.n = M.shape[0]
        # rows: the M-orthonormal Krylov basis and M times it, grown by doubling
        self._Q = np.empty((64, self.n))
        self._MQ = np.empty((64, self.n))
        self._AQ = np.empty((64, self.n))   # K^-1 M times each basis vector (the raw solves)
        self.m = 0                          # basis vectors so far
        self.T = np.zeros((0, 0))           # projected operator Q^T M K^-1 M Q (m - 1 square)
        self.beta = 0.0                     # norm of the residual direction after the last step
        self._restarts = np.random.default_rng(0)
        self._append(np.asarray(v0, dtype=float))

    def _append(self, w, Mw=None):
        """Add ``w`` (already M-orthogonal to the basis) normalised; returns its M-norm."""
        if Mw is None:
            Mw = self.M @ w
        nrm = math.sqrt(max(float(w @ Mw), 0.0))
        if self.m == len(self._Q):
            self._reserve(2 * len(self._Q))
        self._Q[self.m] = w / nrm
        self._MQ[self.m] = Mw / nrm
        self.m += 1
        return nrm

    def _reserve(self, rows: int):
        """Room for ``rows`` basis vectors (growing never copies more than the ``m`` in use)."""
        if rows <= len(self._Q):
            return
        for name in ("_Q", "_MQ", "_AQ"):
            grown = np.empty((rows, self.n))
            grown[:self.m] = getattr(self, name)[:self.m]
            setattr(self, name, grown)

    def _orthogonalise(self, w):
        """``w`` minus its M-projection on the basis, twice; returns it and the coefficients."""
        Q, MQ = self._Q[:self.m], self._MQ[:self.m]
        h = MQ @ w
        w = w - h @ Q
        c = MQ @ w
        return w - c @ Q, h + c

    def _step(self):
        j = self.m - 1                                   # the newest basis vector
        self._AQ[j] = self.solve(self._MQ[j])
        w, h = self._orthogonalise(self._AQ[j])
        T = np.zeros((j + 1, j + 1))
        T[:j, :j] = self.T
        # symmetric by construction: the Gram-Schmidt coefficients of the new column
        T[:, j] = h
        T[j, :] = h
        self.T = T
        Mw = self.M @ w
        beta = math.sqrt(max(float(w @ Mw), 0.0))
        if beta <= 1e-13 * np.abs(T).max():
            # an invariant subspace: continue from a fresh direction, M-orthogonal to the basis
            w, _ = self._orthogonalise(self._restarts.standard_normal(self.n))
            self.beta = 0.0
            self._append(w)
            return
        self.beta = self._append(w, Mw)

    def eigs(self, k: int):
        """The ``k`` lowest eigenvalues (ascending) and M-orthonormal eigenvectors (n, k)."""
        k = int(k)
        if k > self.n - 2:
            raise ValueError(f"at most {self.n - 2} eigenpairs of a {self.n}-DOF problem")
        # k pairs converge in about 2k steps: one allocation instead of a copy per doubling
        self._reserve(min(self.n, 2 * k + 16))
        check = k + 2
        while True:
            m = self.T.shape[0]
            if m >= check or m >= self.n - 1:
                # the convergence test is a dense eigh of T, O(m^3): at m ~ 200 as dear as a
                # Lanczos step itself, so past 32 steps it runs every m // 32 steps (a step or
                # few past convergence only sharpens the pairs)
                check = m + max(1, m // 32)
                # scipy's LAPACK syev, not numpy's eigh (syevd): with multi-threaded OpenBLAS
                # numpy's took 16 ms of CPU for a 40 x 40 matrix, threads waiting, scipy's 0.2
                theta, S = scipy.linalg.eigh(self.T, driver="ev")
                theta, S = theta[::-1][:k], S[:, ::-1][:, :k]     # largest theta = lowest lambda
                # residual of each Ritz pair: beta * |last component|
                resid = self.beta * np.abs(S[-1])
                if np.all(resid <= self.tol * np.abs(theta)) or m >= self.n - 1:
                    break
            self._step()
        # Ritz vectors from the raw solves, (K^-1 M Q s) / theta instead of Q s: equal up to the
        # residual, but in the range of K^-1. Once the Krylov space has taken in everything the
        # start vector holds (ill-conditioned K: the off-diagonal of T falls to 1e-11 of its
        # diagonal), new basis vectors are mostly rounding noise, with components along the
        # stiffest modes that the operator hardly sees (a residual of 1e-6) but the Rayleigh
        # quotient does (a slender strip's first frequency came out 8x too high). One more
        # application of K^-1 damps them by the ratio of the eigenvalues (purification).
        return 1.0 / theta, (self._AQ[:m].T @ S) / theta


def node_pattern(el, N: int):
    """The sparsity pattern of an ``N`` x ``N`` matrix summed from elements with the node lists
    ``el`` (E, B): ``(indptr, indices, pos)``, CSR with sorted columns, and ``pos`` (E, B, B) the
    place of each element entry ``(el[e, i], el[e, j])`` in it (entries that meet share one)."""
    el = np.asarray(el, dtype=np.int64)
    keys = (el[:, :, None] * N + el[:, None, :]).ravel()
    uniq, pos = np.unique(keys, return_inverse=True)
    rows = uniq // N
    indptr = np.zeros(N + 1, dtype=np.int64)
    np.cumsum(np.bincount(rows, minlength=N), out=indptr[1:])
    return indptr, uniq - rows * N, pos.reshape(el.shape + el.shape[1:])


def assemble_fields(Ke, el, N: int, fields: int):
    """The sum of element matrices of ``fields`` fields on the same nodes, as a CSR matrix on
    the DOFs ``fields * node + field`` (node-interleaved): ``Ke`` (E, F B, F B) with each
    element's DOFs field-major (field ``a``, local node ``i`` at ``a B + i``), ``el`` (E, B) the
    element's nodes. One pattern of the node graph serves every field pair, as 3 x 3 blocks
    (scipy's BSR), so no sort of the F^2 times more entries a COO assembly would make."""
    E, B = el.shape
    indptr, indices, pos = node_pattern(el, N)
    blocks = Ke.reshape(E, fields, B, fields, B)
    data = np.empty((len(indices), fields, fields))
    for a in range(fields):
        for b in range(fields):
            data[:, a, b] = np.bincount(pos.ravel(), weights=blocks[:, a, :, b, :].ravel(),
                                        minlength=len(indices))
    return sp.bsr_matrix((data, indices, indptr), shape=(fields * N, fields * N)).tocsr()


class CondensedInverse:
    """``K^-1`` of an SPD finite-element matrix by static condensation of the element-interior
    DOFs (those of one element only, e.g. the bubbles of P3/P4 triangles), exact as a linear
    solve: ``S = K_bb - K_bi K_ii^-1 K_ib`` is summed from element Schur complements and
    factorised (SuperLU's symmetric mode, as :func:`refined_inverse`); a solve eliminates the
    interior DOFs element by element, solves ``S`` and recovers them. ``K`` itself is never
    assembled: on the Mindlin plate's P4 mesh ``S`` has 2/3 of the DOFs and 3/4 of the factor's
    entries, cheaper to factorise and to solve with.

    ``Ke`` (E, F B, F B): element matrices, field-major (field ``a``, local node ``i`` at
    ``a B + i``), with the rows and columns of fixed DOFs zero (e.g. scaled by 0); ``el`` (E, B)
    element nodes (of ``N``); ``interior``: the local nodes interior to each element (never
    fixed); ``number`` (F N,): each global DOF ``a N + node``'s place among the ``n`` free DOFs,
    ``n`` for a fixed one. ``solve(b)`` takes and returns vectors (n,) or (n, k) on the free
    DOFs; ``matvec(x)`` is ``K x`` from the element matrices."""

    def __init__(self, Ke, el, N: int, interior, number, n: int, steps: int = 0):
        E, B = el.shape
        F = Ke.shape[1] // B
        self.n, self.steps = int(n), int(steps)
        inner = np.asarray(interior, dtype=np.int64)
        outer = np.setdiff1d(np.arange(B), inner)
        li = (np.arange(F)[:, None] * B + inner).ravel()           # local DOFs, field-major
        lb = (np.arange(F)[:, None] * B + outer).ravel()
        dofs = (np.arange(F)[None, :, None] * N + el[:, None, :]).reshape(E, F * B)
        self.Ke, self.epos = Ke, number[dofs]                      # (E, F B) free places
        self.ipos = self.epos[:, li]                               # interior: all free
        if np.any(self.ipos >= n):
            raise ValueError("an element-interior DOF is fixed")
        Kii, Kib = Ke[:, li][:, :, li], Ke[:, li][:, :, lb]
        self.Ci = np.linalg.inv(Kii) if len(li) else Kii           # (E, Fi, Fi)
        self.X = self.Ci @ Kib                                     # K_ii^-1 K_ib (E, Fi, Fb)
        self.Kbi = np.ascontiguousarray(Kib.transpose(0, 2, 1))
        Se = Ke[:, lb][:, :, lb] - self.Kbi @ self.X
        # the outer nodes, renumbered 0..Nb-1; S on their DOFs, node-interleaved
        nodes, cel = np.unique(el[:, outer], return_inverse=True)
        cel = cel.reshape(E, len(outer))
        S = assemble_fields(Se, cel, len(nodes), F)
        self.spos = number[(np.arange(F)[None, :] * N + nodes[:, None]).ravel()]
        fixed = self.spos >= n
        # fixed DOFs: their rows and columns are zero; a unit diagonal keeps S regular and
        # gives them 0 in every solve
        S = S + sp.diags(fixed.astype(float), format="csr")
        S.eliminate_zeros()
        self.fixed = fixed
        self.ebs = (F * cel[:, None, :] + np.arange(F)[None, :, None]).reshape(E, F * len(outer))
        self.nS = S.shape[0]
        # S is symmetric: its CSR arrays are its CSC arrays
        self.lu = splu(sp.csc_matrix((S.data, S.indices, S.indptr), shape=S.shape),
                       permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                       options={"SymmetricMode": True})

    def _solve(self, b2):
        k = b2.shape[1]
        bp = np.vstack([b2, np.zeros((1, k))])
        y = self.Ci @ bp[self.ipos]                                # (E, Fi, k)
        c = self.Kbi @ y                                           # (E, Fb, k)
        rhs = bp[self.spos]
        flat = self.ebs.ravel()
        for j in range(k):
            rhs[:, j] -= np.bincount(flat, weights=c[:, :, j].ravel(), minlength=self.nS)
        rhs[self.fixed] = 0.0
        xb = self.lu.solve(rhs)
        out = np.empty((self.n + 1, k))
        out[self.spos] = xb
        out[self.ipos] = y - self.X @ xb[self.ebs]
        return out[:self.n]

    def matvec(self, x):
        """``K x`` on the free DOFs, element by element."""
        x2 = x.reshape(self.n, -1)
        xp = np.vstack([x2, np.zeros((1, x2.shape[1]))])
        Kx = self.Ke @ xp[self.epos]                               # (E, F B, k)
        flat = self.epos.ravel()
        out = np.column_stack([np.bincount(flat, weights=Kx[:, :, j].ravel(),
                                           minlength=self.n + 1)[:self.n]
                               for j in range(x2.shape[1])])
        return out.reshape(x.shape)

    def quadratic(self, x):
        """``x_j^T K x_j`` for each column of ``x`` (n, k), element by element."""
        xp = np.vstack([x, np.zeros((1, x.shape[1]))])[self.epos]  # (E, F B, k)
        return np.einsum("eak,eak->k", xp, self.Ke @ xp)

    def solve(self, b):
        b2 = np.asarray(b, dtype=float).reshape(self.n, -1)
        x = self._solve(b2)
        for _ in range(self.steps):
            x = x + self._solve(b2 - self.matvec(x))
        return x.reshape(np.shape(b))
