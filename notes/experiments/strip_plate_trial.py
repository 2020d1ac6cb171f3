"""A trial, not kept: can a mesh-free strip model of the plate be the network's physical base?

    python notes/experiments/strip_plate_trial.py datasets/plate-n4-seed1 200 32 4

Kantorovich reduction of the Kirchhoff plate: w(x, y) = sum_j f_j(x) (y / max w)^(2 j), j < J
(symmetric modes only), f_j clamped cubic B-splines on NK uniform intervals of the span; the
energy's y-integrals are exact (moments of the half-width), the x-integrals Gauss on the union of
knots and planform stations. Modes are kept by the truth's section rule (section fraction >= 1/2,
exact section averages here). Arguments: DATA (a plate data set) PANELS NK J. Prints the
frequency error against the stored plate truth per mode (docs/surrogate.md, plate-n4, records the
outcome: exact on rectangles, 4-20 % off on the paper's necked panels).
"""
import glob
import json
import sys
import time

import numpy as np
import pandas as pd
from scipy.interpolate import BSpline
from scipy.linalg import eigh

from prbdm import dataset as ds


def bspline_basis(nk, pts, knots_extra=None):
    # clamped cubic B-splines on [0,1], nk uniform intervals; drop first two (w = w' = 0 at root)
    t = np.r_[[0.0]*4, np.linspace(0,1,nk+1)[1:-1], [1.0]*4]
    n = len(t) - 4
    out = np.zeros((3, n, pts.size))
    for i in range(n):
        c = np.zeros(n)
        c[i] = 1
        s = BSpline(t, c, 3, extrapolate=False)
        out[0, i] = np.nan_to_num(s(pts))
        out[1, i] = np.nan_to_num(s.derivative(1)(pts))
        out[2, i] = np.nan_to_num(s.derivative(2)(pts))
    return out[:, 2:], t

def strip(x, w, nu, nk=32, J=4, ng=6, nmodes=5):
    wmax = w.max()
    bp = np.unique(np.r_[np.linspace(0,1,nk+1), x])
    g, gw = np.polynomial.legendre.leggauss(ng)
    a, b = bp[:-1], bp[1:]
    pts = (0.5*(b-a)[:,None]*(g+1) + a[:,None]).ravel()
    wts = (0.5*(b-a)[:,None]*gw).ravel()
    h = np.interp(pts, x, w) / wmax      # relative half width
    F, _ = bspline_basis(nk, pts)
    nb = F.shape[1]
    p = 2*np.arange(J)
    def mom(m):  # int (y/wmax)^m dy over [-h,h] in units: 2 wmax (h)^(m+1)/(m+1)
        return 2*wmax*h**(m+1)/(m+1)
    K = np.zeros((J, nb, J, nb))
    M = np.zeros_like(K)
    S = np.zeros_like(K)
    for ja in range(J):
        for jb in range(J):
            pa, pb = p[ja], p[jb]
            q = pa+pb
            M[ja,:,jb,:] = (F[0]*wts*mom(q)) @ F[0].T
            S[ja,:,jb,:] = (F[0]*wts*mom(pa)*mom(pb)/mom(0)) @ F[0].T
            k = (F[2]*wts*mom(q)) @ F[2].T
            if pa >= 2 and pb >= 2:
                k += pa*(pa-1)*pb*(pb-1)/wmax**4 * (F[0]*wts*mom(q-4)) @ F[0].T
            if pb >= 2:
                k += nu*pb*(pb-1)/wmax**2 * (F[2]*wts*mom(q-2)) @ F[0].T
            if pa >= 2:
                k += nu*pa*(pa-1)/wmax**2 * (F[0]*wts*mom(q-2)) @ F[2].T
            if pa >= 1 and pb >= 1:
                k += 2*(1-nu)*pa*pb/wmax**2 * (F[1]*wts*mom(q-2)) @ F[1].T
            K[ja,:,jb,:] = k
    n = J*nb
    K = K.reshape(n,n)
    M = M.reshape(n,n)
    S = S.reshape(n,n)
    lam, V = eigh(K, M)
    frac = np.einsum('ik,ij,jk->k', V, S, V)  # V^T M V = I
    kept = np.flatnonzero(frac >= 0.5)[:nmodes]
    return np.sqrt(lam[kept]), frac, np.sqrt(lam)

if __name__ == "__main__":
    d = sys.argv[1]
    N = int(sys.argv[2])
    nk = int(sys.argv[3])
    J = int(sys.argv[4])
    spec = json.load(open(f'{d}/_manifest.json'))['spec']
    mat = spec['beam']['material']
    t = pd.concat([pd.read_parquet(f) for f in sorted(glob.glob(f'{d}/*.parquet'))[:1]])
    t = t[t.status=='ok']
    t = t[~ds.refused_by_truth(t, spec)].head(N)   # stale labels that today's plate refuses
    errs = []
    t0 = time.time()
    for _, r in t.iterrows():
        x = np.asarray(r.x)
        w = np.asarray(r.half_width)
        th = r.thickness
        L = r.length
        D = mat['E']*th**3/(12*(1-mat['nu']**2))
        om_truth = np.asarray(r.omega_truth)
        s = np.sqrt(D/(mat['rho']*th))/L**2
        om, frac, allom = strip(x/L, w/L, mat['nu'], nk, J)
        m = min(len(om), 5)
        e = np.full(5, np.nan)
        e[:m] = om[:m]*s/om_truth[:m] - 1
        errs.append(e)
    errs = np.array(errs)
    print(f"nk {nk} J {J}: {(time.time()-t0)/len(t)*1e3:.1f} ms/panel")
    print("median |err| %", np.round(np.nanmedian(abs(errs),0)*100, 3))
    print("p90 |err| %", np.round(np.nanpercentile(abs(errs),90,0)*100, 3))
    print("median err %", np.round(np.nanmedian(errs,0)*100, 3))
    print("std log", np.round(np.nanstd(np.log1p(errs),0), 4))
    print("frac >5%", np.round(np.nanmean(abs(errs)>0.05,0),3))
