"""What a PRBDM away from rest should match: the straight panel (the paper) or the panel in the
pose's shape (issue: large deflection, item 2; docs/large-deflection.md).

    python benchmarks/pose_targets.py [--beams 100] [--seed 0] [--joints 4] [--json FILE]

For each of ``--beams`` random beams of the paper's generator (``random_beam(seed, i)``, treated
as beams: the Euler-Bernoulli truth at rest), two PRBDMs of ``--joints`` joints mapping as many
modes, the beam law, 64 starts:

``--objective`` picks what both fits minimise (the paper's eigenvalue loss by default).

- ``paper``: the paper's fit (Eqs. 7-13): the paper's poses, one SCF per pose, every pose matched
  to the straight panel's frequencies;
- ``rest``: fitted at rest (theta = 0, one SCF) and used at every pose with that same constant
  stiffness: the chain's inertia changes with the pose, as the panel's does.

Each is compared, at every paper pose, with two truths: the straight panel's frequencies, and the
geometrically exact rod (:mod:`prbdm.truth.rod`) in that pose's shape, stress-free (the chain's
own pose shape: its links straight, bent at its joints; independent of the chain model). Printed:
the spread of the paper fit's per-pose SCF (largest over smallest, less 1), and for each model and
truth the worst per-mode frequency error over the poses, median and p90 over the beams.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

import torch  # noqa: E402

from prbdm.fit import fit_prbdm  # noqa: E402
from prbdm.geometry import random_beam  # noqa: E402
from prbdm.model import eigenvalues, paper_poses  # noqa: E402
from prbdm.pose_target import shape_truths as shape_truth  # noqa: E402
from prbdm.truth import bending_frequencies  # noqa: E402


def one_beam(beam, n, objective="eigenvalue"):
    straight = bending_frequencies(beam, "beam", modes=n).omega
    poses = paper_poses(n).numpy()
    paper = fit_prbdm(beam, straight, joints=n, objective=objective)
    rest = fit_prbdm(beam, straight, joints=n, poses="linear", objective=objective)
    with torch.no_grad():
        lam = eigenvalues(beam, torch.as_tensor(rest.gamma), torch.full((len(poses),),
                          float(rest.k[0]), dtype=torch.float64), torch.as_tensor(poses))
    models = {"paper": (paper.gamma, paper.omega), "rest": (rest.gamma, lam.sqrt().numpy())}
    out = {"scf_spread": float(paper.k.max() / paper.k.min() - 1)}
    for name, (gamma, omega) in models.items():
        shaped = shape_truth(beam, gamma, poses, n)
        for truth, ref in (("straight", np.broadcast_to(straight, omega[:, :n].shape)),
                           ("shape", shaped)):
            err = np.abs(omega[:, :n] / ref - 1)                       # (m, n)
            out[f"{name}/{truth}"] = float(err.max())
            out[f"{name}/{truth}/modes"] = err.max(0).tolist()
        out[f"shape_vs_straight/{name}"] = (shaped[-1] / straight - 1).tolist()
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--beams", type=int, default=100)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--joints", type=int, default=4)
    ap.add_argument("--objective", choices=("eigenvalue", "frequency"), default="eigenvalue",
                    help="what both fits minimise (default the paper's eigenvalue loss)")
    ap.add_argument("--json", default=None, help="write every beam's numbers here")
    args = ap.parse_args(argv)
    torch.set_num_threads(1)
    t0 = time.perf_counter()
    rows = []
    for i in range(args.beams):
        rows.append(one_beam(random_beam(args.seed, i), args.joints, args.objective))
    print(f"{len(rows)} beams random_beam({args.seed}, i), n = {args.joints}, paper poses, "
          f"{args.objective} objective, beam truth at rest, rod truth in each pose's shape "
          f"({time.perf_counter() - t0:.0f} s)")
    spread = np.array([r["scf_spread"] for r in rows])
    print(f"paper fit's SCF, largest over smallest per beam, less 1: median "
          f"{100 * np.median(spread):.1f} %, p90 {100 * np.percentile(spread, 90):.1f} %")
    print("worst per-mode frequency error over the poses (median / p90 over the beams):")
    print("  model \\ truth      straight panel      panel in the pose's shape")
    for name in ("paper", "rest"):
        cells = []
        for truth in ("straight", "shape"):
            v = np.array([r[f"{name}/{truth}"] for r in rows])
            cells.append(f"{100 * np.median(v):6.2f} / {100 * np.percentile(v, 90):6.2f} %")
        print(f"  {name:<6}          {cells[0]:>18}      {cells[1]:>18}")
    shift = np.array([r["shape_vs_straight/rest"] for r in rows])
    print("the panel in the largest pose's shape vs straight, modes 1-"
          f"{args.joints}, median: " + ", ".join(f"{100 * v:+.1f} %" for v in
                                                 np.median(shift, 0)))
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"command": " ".join(["python benchmarks/pose_targets.py",
                                            *(argv or sys.argv[1:])]), "beams": rows}, f)


if __name__ == "__main__":
    main()
