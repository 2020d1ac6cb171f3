"""The two fit objectives side by side on held-out beams: worst per-mode frequency error, the
paper's loss and fit time.

    python notes/experiments/bench_objective.py [--beams 12] [--joints 4] [--starts 64]

Beams ``random_beam(1, i)``, i < beams (seed 1: never used for training), beam truth, 4 modes,
paper poses, one torch thread, all beams in one batched fit per objective.
"""
from __future__ import annotations

import argparse
import time

import numpy as np
import torch

from prbdm.fit import fit_many
from prbdm.geometry import random_beam
from prbdm.objectives import OBJECTIVES
from prbdm.truth import bending_frequencies


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--beams", type=int, default=12)
    ap.add_argument("--joints", type=int, default=4)
    ap.add_argument("--starts", type=int, default=64)
    a = ap.parse_args(argv)
    torch.set_num_threads(1)
    beams = [random_beam(1, i) for i in range(a.beams)]
    omega = np.array([bending_frequencies(b, "beam", a.joints + 1).omega for b in beams])
    print(f"{a.beams} beams random_beam(1, i), n = {a.joints}, {a.starts} starts, beam truth")
    print("objective    worst-mode error median / max %   paper's loss median %   time/beam s")
    for objective in OBJECTIVES:
        t0 = time.perf_counter()
        fits = fit_many(beams, omega, a.joints, starts=a.starts, objective=objective)
        dt = (time.perf_counter() - t0) / a.beams
        worst = np.array([f.freq_error.max() for f in fits]) * 100
        loss = np.median([f.loss_percent for f in fits])
        print(f"{objective:<12} {np.median(worst):8.2f} / {worst.max():6.2f}"
              f"{loss:28.3f}{dt:18.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
