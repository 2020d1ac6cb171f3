"""How far the Euler-Bernoulli beam is from the Kirchhoff plate, against the panel's width.

    python benchmarks/truth_choice.py [--panels 20] [--json docs/truth-choice.json]

For families of random planforms (the paper's generator with the half-width scaled to at most
``h`` L, and at least h/50 so the plate can mesh them; thickness min(0.01, 0.4 h) L), both truths
are solved and the per-mode difference ``|omega_beam / omega_plate - 1|`` is tabulated against
the full width ratio
``b/L = 2 max(w) / L``. ``prbdm.truth.choice`` turns the table into the rule of ``--truth auto``.
"""
from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

from prbdm.geometry import random_beam
from prbdm.truth import bending_frequencies

FAMILIES = (0.005, 0.01, 0.02, 0.035, 0.05, 0.075, 0.1, 0.15, 0.2, 0.35, 0.5)
MODES = 4


def measure(panels: int, seed: int) -> list[dict]:
    rows = []
    for h in FAMILIES:
        for i in range(panels):
            # both truths are thin theories whose frequencies scale with t alike: the thickness
            # does not enter their ratio, it only has to be thin against the width for the plate
            t = min(0.01, 0.4 * h)
            b = random_beam(seed, i, max_half_width=h, min_half_width=h / 50,
                            max_thickness=t, min_thickness=t)
            t0 = time.process_time()
            beam = bending_frequencies(b, "beam", MODES).omega
            plate = bending_frequencies(b, "plate", MODES).omega
            rows.append({"family": h, "index": i, "width_ratio": float(2 * b.half_width.max() / b.length),
                         "thickness_ratio": float(b.thickness / b.length),
                         "diff": (np.abs(beam / plate - 1)).tolist(),
                         "cpu_s": time.process_time() - t0})
        d = np.array([r["diff"] for r in rows if r["family"] == h]) * 100
        print(f"half-width <= {h:5.3f} L: median |beam/plate - 1| per mode "
              + ", ".join(f"{v:.2f}" for v in np.median(d, 0)) + " %; max "
              + ", ".join(f"{v:.2f}" for v in d.max(0)) + " %", file=sys.stderr, flush=True)
    return rows


def table(rows: list[dict]) -> str:
    edges = [0, 0.01, 0.02, 0.04, 0.07, 0.1, 0.15, 0.2, 0.3, 0.5, 0.7, 1.0]
    out = ["| b/L = 2 max(w)/L | panels | median diff, modes 1-4 (%) | max diff, modes 1-4 (%) |",
           "|---|---|---|---|"]
    wr = np.array([r["width_ratio"] for r in rows])
    d = np.array([r["diff"] for r in rows]) * 100
    for lo, hi in zip(edges[:-1], edges[1:]):
        sel = (wr > lo) & (wr <= hi)
        if sel.any():
            out.append(f"| {lo:g} - {hi:g} | {sel.sum()} | "
                       + ", ".join(f"{v:.2f}" for v in np.median(d[sel], 0)) + " | "
                       + ", ".join(f"{v:.2f}" for v in d[sel].max(0)) + " |")
    return "\n".join(out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--panels", type=int, default=20, help="panels per width family")
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--json", help="write the measurements here")
    args = ap.parse_args(argv)
    rows = measure(args.panels, args.seed)
    print(table(rows))
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"command": "python benchmarks/truth_choice.py " + " ".join(argv or sys.argv[1:]),
                       "modes": MODES, "families": FAMILIES, "rows": rows}, f, indent=0)
    return 0


if __name__ == "__main__":
    sys.exit(main())
