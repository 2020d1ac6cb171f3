"""Fit speed: prbdm's batched multistart against a scipy baseline, side by side on the same beams.

The baseline is what a user of the paper would write in Python: scipy SLSQP over (gamma, k) with
the equality constraint sum(gamma) = 1 and the bounds of Eq. 13, finite-difference gradients,
tolerances 1e-6 as in the paper's Table 1, from the same start points, one start at a time, on
the same objective (Eq. 13 evaluated by prbdm.model).

    python benchmarks/bench_fit.py                    # 10 beams, 3 of them for scipy (~40 min)
    python benchmarks/bench_fit.py --beams 20 --scipy-beams 5 --joints 4

Prints seconds per beam and median loss of each, and the speed ratio.
"""
from __future__ import annotations

import argparse
import math
import os
import time

import numpy as np
import torch
from scipy.optimize import minimize

from prbdm.fit import DEFAULT_STARTS, FitProblem, fit_many, fit_prbdm, gamma_from_z, start_points
from prbdm.geometry import random_beam
from prbdm.model import GAMMA_MAX, GAMMA_MIN, BeamTensors, eigenvalues, loss_percent, make_poses
from prbdm.truth import bending_frequencies


def scipy_fit(beam, omega, n, starts, seed):
    """SLSQP from each start point in turn; returns (best loss, wall seconds, CPU seconds)."""
    bt = BeamTensors.from_beams(beam)
    poses = make_poses("paper", n)
    m = poses.shape[0]
    lam_t = torch.as_tensor(omega[:n]) ** 2
    rng = np.random.default_rng(seed)

    def objective(x):
        # SLSQP's finite differences may step just outside the bounds: clip, as fmincon would
        g = torch.as_tensor(np.clip(x[:n + 1], 1e-6, 1.0))
        k = torch.as_tensor(np.maximum(x[n + 1:], 1e-12))
        try:
            with torch.no_grad():
                f = float(loss_percent(eigenvalues(bt, g, k, poses), lam_t, n))
        except RuntimeError:
            return 1e6
        return f if np.isfinite(f) else 1e6

    # SCFs are scaled by the k that matches the first frequency on the equal-link chain, then
    # drawn uniformly around it (Eq. 17c draws them in (0, 1) for its own scaling)
    with torch.no_grad():
        lam1 = eigenvalues(bt, torch.full((n + 1,), 1 / (n + 1), dtype=torch.float64), None, poses)
    k_scale = float((lam_t[0] / lam1[:, 0]).mean())
    cons = [{"type": "eq", "fun": lambda x: np.sum(x[:n + 1]) - 1.0}]
    bounds = [(GAMMA_MIN, GAMMA_MAX)] * (n + 1) + [(1e-6 * k_scale, None)] * m
    t0, c0 = time.perf_counter(), time.process_time()
    best = np.inf
    for z in start_points(n, starts, seed):
        x0 = np.concatenate([gamma_from_z(z).numpy(), k_scale * rng.uniform(0.5, 1.5, m)])
        res = minimize(objective, x0, method="SLSQP", bounds=bounds, constraints=cons,
                       options={"ftol": 1e-6, "maxiter": 10000})
        if np.all(np.isfinite(res.x)) and abs(res.x[:n + 1].sum() - 1) < 1e-6:
            best = min(best, res.fun)
    return best, time.perf_counter() - t0, time.process_time() - c0


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--beams", type=int, default=10)
    ap.add_argument("--scipy-beams", type=int, default=3)
    ap.add_argument("--joints", type=int, default=4)
    ap.add_argument("--starts", type=int, default=DEFAULT_STARTS)
    ap.add_argument("--seed", type=int, default=2024)
    ap.add_argument("--threads", type=int, default=1,
                    help="torch threads (default 1: fastest for these small problems)")
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    n = args.joints
    beams = [random_beam(args.seed, i) for i in range(args.beams)]
    omega = np.stack([bending_frequencies(b, model="beam", modes=n).omega for b in beams])
    print(f"n = {n}, mapping {n} modes, paper poses, beam truth, {args.starts} starts, "
          f"torch threads {torch.get_num_threads()}")

    # one untimed fit first: torch's one-off start-up (kernels, thread pools) is paid once per
    # process, not per beam
    fit_prbdm(random_beam(args.seed + 1, 0), omega[0], joints=n, starts=args.starts)
    # CPU time beside wall time: on a shared machine wall time measures the neighbours too
    t0, c0 = time.perf_counter(), time.process_time()
    singles = [fit_prbdm(b, o, joints=n, starts=args.starts) for b, o in zip(beams, omega)]
    t_single = (time.perf_counter() - t0) / len(beams)
    c_single = (time.process_time() - c0) / len(beams)
    t0, c0 = time.perf_counter(), time.process_time()
    batched = fit_many(FitProblem(beams, omega, n), starts=args.starts)
    t_batch = (time.perf_counter() - t0) / len(beams)
    c_batch = (time.process_time() - c0) / len(beams)

    ns = min(args.scipy_beams, len(beams))
    sp = [scipy_fit(b, o, n, args.starts, 0) for b, o in zip(beams[:ns], omega[:ns])]
    t_scipy = np.mean([t for _, t, _ in sp]) if sp else math.nan
    c_scipy = np.mean([c for _, _, c in sp]) if sp else math.nan
    loss_sp = np.array([l for l, _, _ in sp])
    loss_single = np.array([r.loss_percent for r in singles])
    loss_batch = np.array([r.loss_percent for r in batched])

    print()
    print(f"load average at the end: {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    print(f"{'method':38s} {'beams':>5s} {'s/beam':>8s} {'CPU s/beam':>10s} {'median loss %':>14s}")
    print(f"{'prbdm fit, one beam at a time':38s} {len(beams):5d} {t_single:8.3f} "
          f"{c_single:10.3f} {np.median(loss_single):14.5f}")
    print(f"{'prbdm fit_many, all beams in one batch':38s} {len(beams):5d} {t_batch:8.3f} "
          f"{c_batch:10.3f} {np.median(loss_batch):14.5f}")
    if ns == 0:                 # --scipy-beams 0: prbdm's own timings only
        return
    print(f"{'scipy SLSQP, one start at a time':38s} {ns:5d} {t_scipy:8.3f} "
          f"{c_scipy:10.3f} {np.median(loss_sp):14.5f}")
    print(f"{'prbdm (one at a time) on the scipy beams':38s} {ns:5d} "
          f"{np.mean([r.time_s for r in singles[:ns]]):8.3f} {np.median(loss_single[:ns]):14.5f}")
    print()
    print(f"speed-up over scipy (wall): {t_scipy / t_single:.0f}x one beam at a time, "
          f"{t_scipy / t_batch:.0f}x batched; (CPU): {c_scipy / c_single:.0f}x, "
          f"{c_scipy / c_batch:.0f}x")
    worse = np.sum(loss_single[:ns] > loss_sp * (1 + 1e-6))
    print(f"beams where prbdm's loss exceeds scipy's: {worse} of {ns}")


if __name__ == "__main__":
    main()
