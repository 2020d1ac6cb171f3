"""How a fitted PRBDM's error grows with the joint count n and with the largest pose, for both fit
objectives: a table to pick the n a scene needs for a stated accuracy.

    python notes/experiments/objective_table.py --beams 12 --joints 3,4,5,6,7,8 --tip 0,0.4,0.8,1.5708 \
        --json docs/objective-table.json

Beams ``random_beam(1, i)``, i < beams (seed 1: never used for training), Euler-Bernoulli truth,
``min(n, 4)`` modes mapped (4 modes, or n when n < 4), beam law, default start counts, one torch
thread. The largest pose is given as the tip rotation ``Theta = n theta_max`` of the straight-bent
chain (the paper's poses reach pi/2): the poses put every joint at ``0.1, 0.15, ...`` rad up to
``Theta / n`` (the paper's rule with pi/2 replaced by Theta), a single pose at ``Theta / n`` when that
is below 0.1 rad, and ``theta = 0`` (small vibration, ``--poses linear``) when Theta is 0. Each row
reports, over the beams, the median and the maximum of the worst per-mode frequency error over the
poses, and the median of the paper's loss of the same fits.
"""
from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np
import torch

from prbdm.fit import fit_many
from prbdm.geometry import random_beam
from prbdm.objectives import OBJECTIVES
from prbdm.truth import bending_frequencies

MODES = 4


def pose_angles(n: int, tip: float) -> list[float] | str:
    """Joint angles of the pose set whose largest pose turns the tip by ``tip`` rad."""
    if tip <= 0:
        return "linear"
    limit = tip / n
    if limit < 0.1:
        return [limit]
    m = int(math.floor((limit - 0.1) / 0.05 + 1e-9)) + 1
    return [0.1 + 0.05 * i for i in range(m)]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--beams", type=int, default=12)
    ap.add_argument("--joints", default="3,4,5,6,7,8")
    ap.add_argument("--tip", default=f"0,0.4,0.8,{math.pi / 2:.4f}",
                    help="largest tip rotations Theta [rad], comma separated")
    ap.add_argument("--json", help="also write the rows to this JSON file")
    a = ap.parse_args(argv)
    torch.set_num_threads(1)
    joints = [int(s) for s in a.joints.split(",")]
    tips = [float(s) for s in a.tip.split(",")]
    beams = [random_beam(1, i) for i in range(a.beams)]
    omega = np.array([bending_frequencies(b, "beam", MODES + 1).omega for b in beams])
    print(f"{a.beams} beams random_beam(1, i), beam truth, min(n, {MODES}) modes, default starts")
    print(f"{'n':>2} {'Theta rad':>9} {'poses':>5} {'objective':<10} {'worst-mode err median %':>24}"
          f" {'max %':>7} {'paper loss median %':>20} {'s/beam':>7}")
    rows = []
    for n in joints:
        for tip in tips:
            poses = pose_angles(n, tip)
            for objective in OBJECTIVES:
                t0 = time.perf_counter()
                fits = fit_many(beams, omega, n, modes=min(n, MODES), poses=poses,
                                objective=objective)
                dt = (time.perf_counter() - t0) / a.beams
                worst = np.array([f.freq_error.max() for f in fits]) * 100
                loss = np.array([f.loss_percent for f in fits])
                row = dict(joints=n, tip_rad=tip, poses=1 if poses == "linear" else len(poses),
                           objective=objective, worst_median=float(np.median(worst)),
                           worst_max=float(worst.max()), loss_median=float(np.median(loss)),
                           time_s_per_beam=dt)
                rows.append(row)
                print(f"{n:2d} {tip:9.3f} {row['poses']:5d} {objective:<10} "
                      f"{row['worst_median']:24.2f} {row['worst_max']:7.2f} "
                      f"{row['loss_median']:20.3f} {dt:7.3f}", flush=True)
    if a.json:
        with open(a.json, "w") as f:
            json.dump(dict(beams=a.beams, seed=1, truth="beam", modes=MODES,
                           command="python notes/experiments/objective_table.py " +
                           " ".join(argv or __import__("sys").argv[1:]), rows=rows), f, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
