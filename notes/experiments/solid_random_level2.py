"""The 3-D check of the random panels one mesh level further, and which plate model it supports.

    python notes/experiments/solid_random_level2.py --workers 2 --json docs/solid-random-level2.json

docs/plate-vs-solid.json holds the 3-D model (:mod:`prbdm.truth.solid`) of the six random panels
``random_beam(16, i, min_half_width=0.01)`` at mesh levels 0 and 1, which were not converged (the
first frequency moved by up to 2.9 % between them), and docs/mindlin-vs-solid.json the Mindlin
and Kirchhoff plates of the same panels. This solves level 2 (8x the elements of level 1, about
2 minutes of one core per panel) and extrapolates the three levels per mode (Richardson, with
the observed ratio of successive changes when it is between 0 and 0.9, else none): the table
gives ``model / 3-D - 1`` for both plates against level 2 and against the extrapolated value.
The 3-D frequencies fall with each level (the neck's stress field is resolved further), so
level 2 is an upper bound of the converged 3-D value.
"""
from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

MODES = 4


def _level2(i):
    from prbdm.geometry import random_beam
    from prbdm.truth.solid import solve_solid

    t0 = time.process_time()
    r = solve_solid(random_beam(16, i, min_half_width=0.01), MODES, 2)
    return i, [float(v) for v in r["freq_hz"][:MODES]], time.process_time() - t0


def extrapolate(f0, f1, f2):
    """Richardson from three levels: the observed ratio q of successive changes, f2 + d2 q / (1 - q)
    when 0 < q < 0.9 (else f2)."""
    d1, d2 = f1 - f0, f2 - f1
    q = d2 / d1 if d1 != 0 else np.nan
    return f2 + d2 * q / (1 - q) if 0 < q < 0.9 else f2


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--solid", default="docs/plate-vs-solid.json")
    ap.add_argument("--mindlin", default="docs/mindlin-vs-solid.json")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--json", default="")
    a = ap.parse_args(argv)
    solid = {p["panel"]: p for p in json.load(open(a.solid))["panels"]}
    mind = {p["panel"]: p for p in json.load(open(a.mindlin))["panels"]}
    ids = list(range(6))
    if a.workers > 1:
        import multiprocessing
        with multiprocessing.get_context("spawn").Pool(a.workers) as pool:
            done = pool.map(_level2, ids)
    else:
        done = [_level2(i) for i in ids]
    rows = []
    print("random_beam(16, i, min_half_width=0.01): model / 3-D - 1 [%], modes 1-4, against the "
          "3-D at level 2 | against its extrapolation")
    for i, f2, cpu in done:
        name = f"random seed=16 index={i}"
        s, m = solid[name], mind[name]
        f0, f1 = np.array(s["solid_coarse_hz"]), np.array(s["solid_hz"])
        f2 = np.array(f2)
        fx = np.array([extrapolate(*v) for v in zip(f0, f1, f2)])
        k, mm = np.array(m["plate_hz"]), np.array(m["mindlin_hz"])
        row = {"panel": name, "thickness_ratio": s["thickness_ratio"],
               "solid_levels_hz": [f0.tolist(), f1.tolist(), f2.tolist()],
               "solid_extrapolated_hz": fx.tolist(), "level2_cpu_s": cpu,
               "plate_vs_level2": (100 * (k / f2 - 1)).tolist(),
               "mindlin_vs_level2": (100 * (mm / f2 - 1)).tolist(),
               "plate_vs_extrapolated": (100 * (k / fx - 1)).tolist(),
               "mindlin_vs_extrapolated": (100 * (mm / fx - 1)).tolist(),
               "level_change_1_to_2": (100 * (f2 / f1 - 1)).tolist()}
        rows.append(row)
        print(f"index {i} (t/L {s['thickness_ratio']:.3f}), level 1->2 change "
              + " ".join(f"{v:+5.2f}" for v in row["level_change_1_to_2"]))
        for model in ("plate", "mindlin"):
            print(f"  {model:8s}" + " ".join(f"{v:+6.2f}" for v in row[f"{model}_vs_level2"])
                  + "  |" + " ".join(f"{v:+6.2f}" for v in row[f"{model}_vs_extrapolated"]))
    out = {"rows": rows, "command": "python notes/experiments/solid_random_level2.py "
           + " ".join(argv or sys.argv[1:])}
    if a.json:
        from prbdm.files import atomic_write
        atomic_write(a.json, json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
