"""Throughput of the differentiable PRBDM, and start-up cost of ``prbdm eval``.

    python benchmarks/bench_model.py                 # full table (one to two minutes on 2 cores)
    python benchmarks/bench_model.py --quick         # fewer repeats
    python benchmarks/bench_model.py --json out.json # also save the numbers
    python benchmarks/bench_model.py --convergence   # beam law -> Euler-Bernoulli table
    python benchmarks/bench_model.py --threads 1     # one intra-op thread (busy machines)

Part 1: (beam x pose) eigen-evaluations per second of ``model.eigenvalues_unit_k`` (links, joint
stiffness, M(theta) at every pose, symmetric eigenvalues), for n = 3, 4, 5, 10, 20 joints at batch
sizes 1 and 4096 random beams (docs/conventions.md §1 generator, p = 10), one random gamma per beam, the paper's
poses (9, 6, 5, 1, 1 poses), float64, torch's default thread count. ``fwd`` is inference
(``torch.no_grad``); ``fwd+bwd`` adds the backward pass to gamma (what a fit pays per step).
Building the beam tensors is set-up and not timed. Time per case: the best of several repeats.

Part 2: wall time of ``prbdm eval`` on one beam against ``python -c pass`` and
``python -c "import torch"``: the command is dominated by interpreter and torch start-up.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time

import torch

from prbdm import model
from prbdm.geometry import random_beam


def _gammas(B: int, n: int, gen: torch.Generator) -> torch.Tensor:
    g = 0.3 + torch.rand(B, n + 1, generator=gen, dtype=torch.float64)
    return g / g.sum(-1, keepdim=True)


def _time(fn, min_time: float, repeats: int) -> float:
    """Best seconds per call over ``repeats`` runs of at least ``min_time`` each."""
    fn()                                    # warm-up
    best = float("inf")
    for _ in range(repeats):
        calls, t0 = 0, time.perf_counter()
        while True:
            fn()
            calls += 1
            dt = time.perf_counter() - t0
            if dt >= min_time:
                break
        best = min(best, dt / calls)
    return best


def throughput(ns, batches, min_time, repeats, seed=0):
    rows = []
    gen = torch.Generator().manual_seed(seed)
    beams_all = [random_beam(seed, i) for i in range(max(batches))]
    for n in ns:
        poses = model.paper_poses(n)
        m = poses.shape[0]
        for B in batches:
            bt = model.BeamTensors.from_beams(beams_all[:B])
            gamma = _gammas(B, n, gen)

            def fwd():
                with torch.no_grad():
                    model.eigenvalues_unit_k(bt, gamma, poses)

            g_req = gamma.clone().requires_grad_(True)

            def fwd_bwd():
                lam = model.eigenvalues_unit_k(bt, g_req, poses)
                lam.sum().backward()
                g_req.grad = None

            t_f = _time(fwd, min_time, repeats)
            t_fb = _time(fwd_bwd, min_time, repeats)
            rows.append({"n": n, "poses": m, "batch": B, "evals_per_call": B * m,
                         "fwd_s": t_f, "fwd_evals_per_s": B * m / t_f,
                         "fwd_bwd_s": t_fb, "fwd_bwd_evals_per_s": B * m / t_fb})
            print(f"  n={n:2d} m={m} batch={B:5d}: fwd {B * m / t_f:12.4g} evals/s "
                  f"({t_f * 1e3:8.3f} ms/call), fwd+bwd {B * m / t_fb:12.4g} evals/s", flush=True)
    return rows


def _wall(cmd, repeats):
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        p = subprocess.run(cmd, capture_output=True, text=True)
        times.append(time.perf_counter() - t0)
        if p.returncode != 0:
            raise RuntimeError(f"{cmd} failed: {p.stderr}")
    return statistics.median(times), min(times)


def startup(repeats):
    beam = random_beam(0, 0)
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "beam.json")
        beam.to_json(path)
        py = sys.executable
        cases = [
            ("python -c pass", [py, "-c", "pass"]),
            ('python -c "import torch"', [py, "-c", "import torch"]),
            ("prbdm eval BEAM --gamma 0.2,0.2,0.2,0.2,0.2 --k 1 --json",
             [py, "-m", "prbdm.cli", "eval", path, "--gamma", "0.2,0.2,0.2,0.2,0.2", "--k", "1",
              "--json"]),
        ]
        rows = []
        for label, cmd in cases:
            med, best = _wall(cmd, repeats)
            rows.append({"command": label, "median_s": med, "min_s": best})
            print(f"  {label:58s} median {med:6.3f} s  min {best:6.3f} s", flush=True)
        p = subprocess.run(cases[-1][1], capture_output=True, text=True)
        rows.append({"command": "prbdm eval: reported time_s (evaluation only)",
                     "median_s": json.loads(p.stdout)["time_s"], "min_s": None})
        print(f"  {'prbdm eval: its own time_s (evaluation only)':58s} "
              f"{rows[-1]['median_s']:.4f} s", flush=True)
    return rows


ALPHA = (1.87510407, 4.69409113, 7.85475744)   # cos(a) cosh(a) = -1


def convergence(ns=(10, 20, 40, 80)):
    """Beam law, k = 1, gamma = uniform_gamma(n), theta = 0, the paper's uniform beam (L = 1 m,
    b = 0.3624 m, t = 0.040532 m, steel) against Euler-Bernoulli: relative frequency errors of
    the first three modes and the observed order log2(e(n) / e(2n))."""
    import math

    from prbdm.geometry import Beam

    E, rho, b, t = 205e9, 7850.0, 0.3624, 0.040532
    beam = Beam(x=[0.0, 1.0], half_width=[b / 2, b / 2], thickness=t)
    scale = math.sqrt(E * b * t ** 3 / 12 / (rho * b * t))
    exact = [a * a * scale for a in ALPHA]
    print("  omega_EB [rad/s]: " + ", ".join(f"{w:.6f}" for w in exact))
    rows, prev = [], None
    for n in ns:
        lam = model.eigenvalues(beam, model.uniform_gamma(n), poses="linear")[0, :3]
        omega = lam.sqrt().tolist()
        err = [(w - we) / we for w, we in zip(omega, exact)]
        order = None if prev is None else [math.log2(p / e) for p, e in zip(prev, err)]
        rows.append({"n": n, "omega": omega, "rel_error": err, "order": order})
        print(f"  n={n:3d}  omega = " + ", ".join(f"{w:11.6f}" for w in omega)
              + "   error = " + ", ".join(f"{e:9.3e}" for e in err)
              + ("" if order is None else "   order = " + ", ".join(f"{o:.3f}" for o in order)))
        prev = err
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="shorter timings")
    ap.add_argument("--ns", default="3,4,5,10,20", help="joint counts (default 3,4,5,10,20)")
    ap.add_argument("--batches", default="1,4096", help="batch sizes (default 1,4096)")
    ap.add_argument("--json", metavar="PATH", help="write the results as JSON")
    ap.add_argument("--no-startup", action="store_true", help="skip the CLI start-up timing")
    ap.add_argument("--threads", type=int, default=None,
                    help="torch.set_num_threads for part 1 (default: leave torch's default)")
    ap.add_argument("--convergence", action="store_true",
                    help="only print the convergence of the beam law to Euler-Bernoulli")
    args = ap.parse_args(argv)
    if args.convergence:
        print("Beam law, k = 1, uniform_gamma(n), theta = 0 vs Euler-Bernoulli (uniform beam):")
        rows = convergence()
        if args.json:
            with open(args.json, "w") as fh:
                json.dump({"convergence": rows}, fh, indent=1)
        return 0
    ns = [int(v) for v in args.ns.split(",")]
    batches = [int(v) for v in args.batches.split(",")]
    min_time, repeats = (0.2, 2) if args.quick else (0.5, 3)
    if args.threads is not None:
        torch.set_num_threads(args.threads)

    info = {"python": platform.python_version(), "torch": torch.__version__,
            "threads": torch.get_num_threads(), "cpu_count": os.cpu_count(),
            "machine": platform.machine()}
    info["threads"] = torch.get_num_threads()
    try:
        info["load_average"] = os.getloadavg()
    except OSError:
        pass
    print(f"torch {info['torch']}, {info['threads']} threads, {info['cpu_count']} CPUs, float64, "
          f"load average {info.get('load_average', ('?',))[0]}")
    print("PRBDM eigen-evaluations ((beam x pose) per second):")
    rows = throughput(ns, batches, min_time, repeats)
    start = []
    if not args.no_startup:
        print("Start-up (wall time of a fresh process):")
        start = startup(3 if args.quick else 5)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"info": info, "throughput": rows, "startup": start}, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
