"""The plate truth's default mesh against a refined one, on panels of the plate data set's
generator, and an independent check where two meshes disagree.

    python notes/experiments/plate_mesh_check.py --panels 24 --seed 5        # about 1 minute

1. For ``random_beam(SEED, i, min_half_width=0.01)``, i < PANELS: the largest relative difference
   of bending modes 1-5 between the default mesh and ``elements=24, corner_ratio=0.003``
   (median, p90, max over the panels) and the default's CPU time per panel.
2. The stepped panel ``random_beam(5, 16, min_half_width=0.01)`` (its width steps from 0.08 to
   0.27 L at one station): mode 1 from the default mesh, the refined one, the ``grade=0.3`` mesh,
   and the ``mindlin`` truth at t/L = 0.001 (C0 elements, no C1 condition; the thin limit of the
   shear-deformable plate is the Kirchhoff plate), scaled back to the panel's thickness.
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from prbdm.geometry import Beam, random_beam
from prbdm.truth import bending_frequencies

REFINED = {"elements": 24, "corner_ratio": 0.003}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--panels", type=int, default=24)
    ap.add_argument("--seed", type=int, default=5)
    a = ap.parse_args(argv)
    worst, cpu = [], []
    for i in range(a.panels):
        b = random_beam(a.seed, i, min_half_width=0.01)
        t0 = time.process_time()
        d = bending_frequencies(b, "plate", 5).omega
        cpu.append(time.process_time() - t0)
        r = bending_frequencies(b, "plate", 5, **REFINED).omega
        worst.append(float(np.abs(d / r - 1).max()))
    w = np.array(worst)
    print(f"{a.panels} panels random_beam({a.seed}, i, min_half_width=0.01), default vs {REFINED}: "
          f"largest mode 1-5 difference per panel median {np.median(w):.3g}, p90 "
          f"{np.percentile(w, 90):.3g}, max {w.max():.3g} (panel {int(w.argmax())}); "
          f"{int((w > 3e-4).sum())} above 3e-4; default {np.median(cpu):.3f} s CPU median")

    b = random_beam(5, 16, min_half_width=0.01)
    rows = {"default": {}, "refined": REFINED, "grade=0.3": {"grade": 0.3}}
    out = {k: float(bending_frequencies(b, "plate", 1, **o).omega[0]) for k, o in rows.items()}
    thin = Beam(b.x, b.half_width, 0.001, b.material)
    out["mindlin t/L=0.001, scaled"] = float(
        bending_frequencies(thin, "mindlin", 1).omega[0] * b.thickness / 0.001)
    ref = out["mindlin t/L=0.001, scaled"]
    print("stepped panel random_beam(5, 16, min_half_width=0.01), mode 1 [rad/s]: " + "; ".join(
        f"{k} {v:.5g} ({100 * (v / ref - 1):+.2f} % vs mindlin)" for k, v in out.items()))
    return {"worst": worst, "stepped": out}


if __name__ == "__main__":
    main()
