"""Speed and accuracy of the truth models (issue 3).

    python benchmarks/bench_truth.py                 # full run (a few minutes on 2 cores)
    python benchmarks/bench_truth.py --quick         # fewer beams
    python benchmarks/bench_truth.py --validation    # the validation section only (~1 min)
    python benchmarks/bench_truth.py --compare OLD_TREE --panels 40   # plate, old vs this code

Prints
1. ms per beam for ``beam`` and ``plate`` at the default accuracy (random beams of the paper's
   generator, p = 10, seed 0; the first call of each model is a warm-up and is not counted);
2. the mesh-convergence tables: for each mesh setting, the largest and median relative error of
   the first five bending frequencies over the random beams, against a much finer reference mesh,
   and the mean time per beam;
3. the validation numbers: the uniform beam against cos(a) cosh(a) = -1, the square plate against
   Barton/Leissa, rectangular plates (L/b = 2, 0.5) against a converged Rayleigh-Ritz solution
   (prbdm.truth.ritz_plate), the beam against shooting, the extreme planforms' default-mesh
   error against the reference mesh.

``--compare OLD_TREE`` (a checkout of another commit, e.g. ``git worktree add ../old COMMIT``)
instead runs the plate truth (``--model mindlin``: the Mindlin plate's) of OLD_TREE and of this
tree side by side in one run: two worker processes, one importing each tree, solve the same
random panels (the paper's generator, ``--seed``, minimum half-width ``--min-half-width``; or
``--family smooth``: :func:`prbdm.planforms.smooth_beam`),
taking turns panel by panel (which tree goes first alternates), so that a changing load on a
shared machine hits both alike. Each worker
measures the CPU time of its process per panel (``time.process_time``: counts every thread of
the process, waiting ones included, and not the time other jobs take the core away), after one
warm-up solve. Printed: median, p90 and mean CPU (and wall) seconds per panel for each tree, the
speed-up, the largest relative difference of the bending frequencies between the trees, and
whether the meshes are identical (SHA-256 of node and element arrays). ``--threads N`` sets
OMP/OPENBLAS/MKL_NUM_THREADS in both workers (default 1, as the data-set workers run;
0 leaves the environment as it is).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from prbdm.geometry import Beam, Material, random_beam  # noqa: E402
from prbdm.truth import bending_frequencies  # noqa: E402
from prbdm.truth.ritz_plate import ritz_cantilever_plate  # noqa: E402
from prbdm.truth.shooting import shooting_eigenvalues  # noqa: E402

PLATE_REFERENCE = dict(elements=24, corner_ratio=0.003, grade=0.3)


def timed(beams, model, **kw):
    bending_frequencies(beams[0], model, **kw)                     # warm-up
    times, out = [], []
    for b in beams:
        t = time.perf_counter()
        r = bending_frequencies(b, model, **kw)
        times.append(time.perf_counter() - t)
        out.append(r)
    return np.array(times), out


def speed(n_beam, n_plate):
    print("== speed at default accuracy (random beams, seed 0, p = 10) ==")
    beams = [random_beam(0, i) for i in range(max(n_beam, n_plate))]
    for model, n in (("beam", n_beam), ("plate", n_plate)):
        t, res = timed(beams[:n], model)
        dofs = [r.mesh.get("dofs", 0) for r in res]
        print(f"{model:6s} {n:4d} beams: median {1e3 * np.median(t):7.1f} ms, mean "
              f"{1e3 * t.mean():7.1f} ms, max {1e3 * t.max():7.1f} ms per beam "
              f"(mean {np.mean(dofs):.0f} DOFs)")
    print(f"(load average while running: {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores)")
    print()


def convergence(title, beams, model, settings, reference):
    print(f"== {title} ==")
    refs = [bending_frequencies(b, model, modes=5, **reference).omega for b in beams]
    print(f"reference: {reference}")
    print(f"{'setting':44s} {'max err':>9s} {'median':>9s} {'ms/beam':>8s} {'DOFs':>6s} "
          f"{'other modes':>11s}")
    for label, kw in settings:
        errs, ts, dofs, flips = [], [], [], 0
        for b, ref in zip(beams, refs):
            r = bending_frequencies(b, model, modes=5, **kw)
            e = np.abs(r.omega / ref - 1).max()
            # an error of percents is not discretisation: the coarse mesh picked another mode
            # as bending (plate, near-threshold section fractions); counted apart
            if model == "plate" and e > 0.02:
                flips += 1
            else:
                errs.append(e)
            ts.append(r.time_s)
            dofs.append(r.mesh.get("dofs", 0))
        print(f"{label:44s} {max(errs):9.2e} {np.median(errs):9.2e} {1e3 * np.mean(ts):8.1f} "
              f"{np.mean(dofs):6.0f} {flips:11d}")
    print("(max err, median: of the largest relative error of modes 1-5 of each beam; other "
          "modes: plate beams where a different mode was selected as bending, left out of the "
          "errors)")
    print()


def validation():
    print("== validation ==")
    u = Beam(x=[0, 1.0], half_width=[0.1812, 0.1812], thickness=0.040532)
    exact = bending_frequencies(u, "analytic", modes=5).omega
    fem = bending_frequencies(u, "beam", modes=5).omega
    print("uniform beam, beam model vs cos(a)cosh(a) = -1, relative error of modes 1-5:",
          " ".join(f"{e:+.1e}" for e in fem / exact - 1))
    sq = Beam(x=[0, 1.0], half_width=[0.5, 0.5], thickness=0.01, material=Material(nu=0.3))
    res = bending_frequencies(sq, "plate", modes=3, all_modes=True)
    m = sq.material
    D = m.E * sq.thickness ** 3 / (12 * (1 - m.nu ** 2))
    lam = np.array([e["omega"] for e in res.all_modes[:6]]) * math.sqrt(m.rho * sq.thickness / D)
    barton = np.array([3.492, 8.525, 21.43, 27.33, 31.11, 54.44])
    print("square plate nu = 0.3, omega a^2 sqrt(rho t / D):")
    print("  present:", " ".join(f"{v:.4f}" for v in lam))
    print("  Barton/Leissa:", " ".join(f"{v:.4g}" for v in barton))
    print("  difference:", " ".join(f"{v:+.2%}" for v in lam / barton - 1))
    print("beam model vs the mesh-free shooting solution (prbdm.truth.shooting), relative "
          "frequency error of modes 1-5:")
    cases = {"100:1 waist over 1 % of the span": Beam(x=[0, 0.5, 0.505, 0.51, 1],
                                                      half_width=[0.1, 0.1, 0.001, 0.1, 0.1],
                                                      thickness=0.01),
             "100:1 step over 1 % of the span": Beam(x=[0, 0.4, 0.41, 1],
                                                     half_width=[0.2, 0.2, 0.002, 0.002],
                                                     thickness=0.01)}
    cases["2 mm wide tip (0.5 m -> 1 mm)"] = Beam(x=[0, 1], half_width=[0.5, 0.001],
                                                  thickness=0.01)
    cases.update({f"random_beam(1, {i})": random_beam(1, i) for i in range(6)})
    for name, b in cases.items():
        graded = bending_frequencies(b, "beam")
        exact = shooting_eigenvalues(b, graded.lam, rel=1e-3)
        line = " ".join(f"{e:+.1e}" for e in np.sqrt(graded.lam / exact) - 1)
        flat = bending_frequencies(b, "beam", grading=False)
        worst = np.abs(np.sqrt(flat.lam / exact) - 1).max()
        print(f"  {name:34s} {line}   (without width grading: max {worst:.1e})")
    print("plate model, slender plates vs the analytic beam (plate / beam - 1, modes 1-4):")
    for hw in (0.05, 0.02, 0.005, 0.002):
        b = Beam(x=[0, 1.0], half_width=[hw, hw], thickness=0.001)
        p = bending_frequencies(b, "plate", modes=4).omega
        a = bending_frequencies(b, "analytic", modes=4).omega
        print(f"  L / b = {1 / (2 * hw):5.0f}: " + " ".join(f"{v:+.2e}" for v in p / a - 1))
    print("beam model, uniform beams at the half-width limits vs cos(a)cosh(a) = -1 (modes 1-5):")
    for hw in (0.002, 0.5):
        b = Beam(x=[0, 1.0], half_width=[hw, hw], thickness=0.01)
        e = (bending_frequencies(b, "beam").omega / bending_frequencies(b, "analytic").omega - 1)
        print(f"  half-width {hw:5.3f} m: " + " ".join(f"{v:+.1e}" for v in e))
    print("rectangular plates nu = 0.3 vs Rayleigh-Ritz (prbdm.truth.ritz_plate, Legendre basis "
          "n x n), omega L^2 sqrt(rho t / D), first 8 modes, both families:")
    for aspect in (2.0, 0.5):
        ritz = {n: ritz_cantilever_plate(aspect, nu=0.3, nx=n, ny=n)[:8] for n in (10, 14, 18)}
        b = Beam(x=[0, 1.0], half_width=[0.5 / aspect] * 2, thickness=0.01,
                 material=Material(nu=0.3))
        res = bending_frequencies(b, "plate", modes=3, all_modes=True)
        m = b.material
        D = m.E * b.thickness ** 3 / (12 * (1 - m.nu ** 2))
        fem = np.array([e["omega"] for e in res.all_modes[:8]]) * math.sqrt(m.rho * b.thickness
                                                                               / D)
        print(f"  L / b = {aspect:g}:")
        for n, v in ritz.items():
            print(f"    Ritz n = {n:2d}:  " + " ".join(f"{x:9.4f}" for x in v)
                  + f"   (max change to n = 18: {np.abs(v / ritz[18] - 1).max():.1e})")
        print("    plate FEM:    " + " ".join(f"{x:9.4f}" for x in fem))
        print("    symmetry:     " + " ".join(f"{e['symmetry'][:4]:>9s}"
                                             for e in res.all_modes[:8]))
        print("    FEM/Ritz - 1: " + " ".join(f"{x:+9.1e}" for x in fem / ritz[18] - 1))
    print("plate model, extreme planforms: default mesh vs the reference mesh "
          f"{PLATE_REFERENCE}, largest relative error of the 5 bending frequencies:")
    extreme = {"2 mm wide tip (0.5 m -> 1 mm)": Beam(x=[0, 1], half_width=[0.5, 0.001],
                                                     thickness=0.01),
               "half-width 2 mm (t = 1 mm)": Beam(x=[0, 1], half_width=[0.002, 0.002],
                                                  thickness=0.001),
               "half-width 0.5 m": Beam(x=[0, 1], half_width=[0.5, 0.5], thickness=0.01),
               "100:1 waist over 1 % of the span": cases["100:1 waist over 1 % of the span"],
               "100:1 step over 1 % of the span": cases["100:1 step over 1 % of the span"]}
    for name, b in extreme.items():
        d = bending_frequencies(b, "plate", modes=5).omega
        f = bending_frequencies(b, "plate", modes=5, **PLATE_REFERENCE).omega
        print(f"  {name:34s} {np.abs(d / f - 1).max():.1e}")
    print()


# ------------------------------------------------------------------ old vs new, side by side
# The worker runs in its own process with the tree to measure first on sys.path; it reads panel
# indices from stdin and answers one JSON line per panel.
_WORKER = r"""
import hashlib, json, sys, time
sys.path.insert(0, sys.argv[1])
import numpy as np
from prbdm.geometry import random_beam
from prbdm.planforms import smooth_beam
from prbdm.errors import BadInput
from prbdm.truth import bending_frequencies
seed, hw_min, modes, model = int(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4]), sys.argv[5]
kw = json.loads(sys.argv[6]) if len(sys.argv) > 6 else {}
family = sys.argv[7] if len(sys.argv) > 7 else "random"
beam = ((lambda i: smooth_beam(seed, i)) if family == "smooth" else
        (lambda i: random_beam(seed, i, min_half_width=hw_min)))
bending_frequencies(beam(10 ** 6), model, modes=modes, **kw)          # warm-up, not counted
print(json.dumps({"ready": True}), flush=True)
for line in sys.stdin:
    i = int(line)
    b = beam(i)
    c, w = time.process_time(), time.perf_counter()
    try:
        r = bending_frequencies(b, model, modes=modes, **kw)
    except BadInput as exc:                     # a planform the model refuses
        print(json.dumps({"i": i, "refused": str(exc)[:80]}), flush=True)
        continue
    c, w = time.process_time() - c, time.perf_counter() - w
    h = hashlib.sha256()
    for a in (r.shapes["p"], r.shapes["t"]):
        h.update(np.ascontiguousarray(a).tobytes())
    print(json.dumps({"i": i, "cpu": c, "wall": w, "omega": r.omega.tolist(),
                      "mesh": h.hexdigest(), "dofs": r.mesh.get("dofs", 0)}), flush=True)
"""


def _start_worker(tree, seed, hw_min, modes, threads, model, kw=None, family="random"):
    env = dict(os.environ)
    env.pop("PYTHONPATH", None)
    if threads > 0:
        for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
            env[k] = str(threads)
    proc = subprocess.Popen([sys.executable, "-c", _WORKER, os.path.abspath(tree), str(seed),
                             str(hw_min), str(modes), model, json.dumps(kw or {}), family],
                            cwd=os.path.abspath(tree), env=env,
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    if not json.loads(proc.stdout.readline()).get("ready"):
        raise RuntimeError(f"worker for {tree} did not start")
    return proc


def _ask(proc, i):
    proc.stdin.write(f"{i}\n")
    proc.stdin.flush()
    return json.loads(proc.stdout.readline())


def compare(old_tree, panels, seed=0, hw_min=0.01, modes=5, threads=1, model="plate",
            new_kw=None, old_kw=None, family="random"):
    new_tree = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
    trees = {"old": old_tree, "new": new_tree}
    what = (f"smooth panels (prbdm.planforms.smooth_beam, seed {seed})" if family == "smooth"
            else f"random panels (seed {seed}, min half-width {hw_min} m)")
    print(f"== {model} truth, old vs new, side by side: {panels} {what}, {modes} modes, "
          "default mesh ==")
    print(f"old: {os.path.abspath(old_tree)}\nnew: {os.path.abspath(new_tree)}")
    print("BLAS/OpenMP threads per worker: "
          + (str(threads) if threads > 0 else "environment default"))
    kws = {"old": old_kw or {}, "new": new_kw or {}}
    print(f"options: old {kws['old']}, new {kws['new']}")
    workers = {k: _start_worker(t, seed, hw_min, modes, threads, model, kws[k], family)
               for k, t in trees.items()}
    res = {"old": [], "new": []}
    try:
        for i in range(panels):
            for k in (("old", "new") if i % 2 == 0 else ("new", "old")):
                res[k].append(_ask(workers[k], i))
    finally:
        for p in workers.values():
            p.stdin.close()
            p.wait()
    refused = {k: {r["i"] for r in v if "refused" in r} for k, v in res.items()}
    if refused["old"] != refused["new"]:
        print(f"!! the trees refuse different panels: old {sorted(refused['old'])}, "
              f"new {sorted(refused['new'])}")
    both = refused["old"] | refused["new"]
    res = {k: [r for r in v if r["i"] not in both] for k, v in res.items()}
    print(f"refused (not timed): {len(both)} of {panels} panels")
    cpu = {k: np.array([r["cpu"] for r in v]) for k, v in res.items()}
    wall = {k: np.array([r["wall"] for r in v]) for k, v in res.items()}
    for k in ("old", "new"):
        print(f"{k}: CPU median {np.median(cpu[k]):.3f} s, "
              f"p90 {np.percentile(cpu[k], 90):.3f} s, mean {np.mean(cpu[k]):.3f} s per panel; "
              f"wall median {np.median(wall[k]):.3f} s, p90 "
              f"{np.percentile(wall[k], 90):.3f} s (mean "
              f"{np.mean([r['dofs'] for r in res[k]]):.0f} DOFs)")
    ratio = cpu["old"] / cpu["new"]
    print(f"speed-up (CPU): median {np.median(cpu['old']) / np.median(cpu['new']):.2f}x of the "
          f"medians; per panel median {np.median(ratio):.2f}x, smallest {ratio.min():.2f}x; "
          f"wall: {np.median(wall['old']) / np.median(wall['new']):.2f}x of the medians")
    diffs = [np.abs(np.array(n["omega"]) / np.array(o["omega"]) - 1).max()
             for o, n in zip(res["old"], res["new"])]
    same = sum(o["mesh"] == n["mesh"] for o, n in zip(res["old"], res["new"]))
    worst = int(np.argmax(diffs))
    signed = np.array(res["new"][worst]["omega"]) / np.array(res["old"][worst]["omega"]) - 1
    print(f"largest relative frequency difference new vs old (modes 1-{modes}, all panels): "
          f"{max(diffs):.1e} (median over panels {np.median(diffs):.1e}); worst panel "
          f"{res['new'][worst]['i']}: new / old - 1 = " + " ".join(f"{v:+.1e}" for v in signed))
    print(f"meshes identical (SHA-256 of nodes and elements): {same} of {len(res['old'])}")
    print(f"(load average at the end: {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores)")
    print()


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer beams")
    ap.add_argument("--validation", action="store_true", help="the validation section only")
    ap.add_argument("--compare", metavar="OLD_TREE",
                    help="plate (or --model) truth of OLD_TREE vs this tree, side by side")
    ap.add_argument("--panels", type=int, default=40, help="panels for --compare")
    ap.add_argument("--seed", type=int, default=0, help="random stream for --compare")
    ap.add_argument("--min-half-width", type=float, default=0.01,
                    help="smallest half-width [m] of the --compare panels")
    ap.add_argument("--threads", type=int, default=1,
                    help="BLAS/OpenMP threads per --compare worker (0: environment default)")
    ap.add_argument("--model", choices=("plate", "mindlin"), default="plate",
                    help="the truth model --compare times (default plate)")
    ap.add_argument("--modes", type=int, default=5, help="bending modes asked for (--compare)")
    ap.add_argument("--family", choices=("random", "smooth"), default="random",
                    help="--compare panels: the paper's generator (random, default) or "
                         "prbdm.planforms.smooth_beam (smooth; --min-half-width unused)")
    ap.add_argument("--new-options", default="{}", metavar="JSON",
                    help='options of this tree\'s solve, e.g. \'{"selection": "section"}\' '
                         "(--compare; the old tree's: --old-options)")
    ap.add_argument("--old-options", default="{}", metavar="JSON",
                    help="options of OLD_TREE's solve (--compare)")
    args = ap.parse_args(argv)
    if args.compare:
        compare(args.compare, args.panels, args.seed, args.min_half_width, modes=args.modes,
                threads=args.threads, model=args.model, new_kw=json.loads(args.new_options),
                old_kw=json.loads(args.old_options), family=args.family)
        return
    if args.validation:
        validation()
        return
    n_beam, n_plate = (20, 4) if args.quick else (100, 12)
    n_conv_beam, n_conv_plate = (8, 3) if args.quick else (30, 8)
    speed(n_beam, n_plate)
    validation()
    beams = [random_beam(1, i) for i in range(n_conv_beam)]
    convergence(f"beam model convergence ({n_conv_beam} random beams, seed 1)", beams, "beam",
                [("elements=10", dict(elements=10)),
                 ("elements=20", dict(elements=20)),
                 ("elements=40 (default)", dict()),
                 ("elements=80", dict(elements=80)),
                 ("elements=40, no width grading", dict(grading=False)),
                 ("elements=160, no width grading", dict(elements=160, grading=False))],
                dict(elements=600))
    beams = [random_beam(0, i) for i in range(n_conv_plate)]
    convergence(f"plate model convergence ({n_conv_plate} random beams, seed 0)", beams, "plate",
                [("elements=6", dict(elements=6)),
                 ("elements=8", dict(elements=8)),
                 ("elements=12 (default)", dict()),
                 ("elements=16", dict(elements=16)),
                 ("elements=12, corner_ratio=0.05", dict(corner_ratio=0.05)),
                 ("elements=12, corner_ratio=0.003, grade=0.3",
                  dict(corner_ratio=0.003, grade=0.3))],
                dict(elements=24, corner_ratio=0.003, grade=0.3))


if __name__ == "__main__":
    main()
