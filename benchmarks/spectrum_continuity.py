"""How far the plate target moves under a 1 % change of the planform: the section rule's modes
against the bending spectrum (docs/method.md, "The bending spectrum").

    python benchmarks/spectrum_continuity.py [--panels 400] [--seed 7] [--model plate]

For each of ``--panels`` panels of the paper's generator (``random_beam(seed, i)``), the truth is
solved twice: as drawn, and with every half-width multiplied by ``exp(0.01 z)``, z standard normal
(seeded by the panel's index). Both targets come from the same solves (the spectrum is the
answer; the section rule's modes are reported beside it). Printed, per mode 1-4 and target: the
median, p99 and the share of panels over 5 % of the relative change of the frequency. Panels
either solve refuses are counted and left out.
"""
from __future__ import annotations

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from prbdm.errors import BadInput  # noqa: E402
from prbdm.geometry import Beam, random_beam  # noqa: E402
from prbdm.truth import bending_frequencies  # noqa: E402


def targets(beam, model, modes=4):
    """(spectrum, section rule) frequencies of the first ``modes`` bending modes."""
    r = bending_frequencies(beam, model, modes=modes)
    return np.asarray(r.omega), np.array([m["omega"] for m in r.all_modes if m["kept"]])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--panels", type=int, default=400)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--model", choices=("plate", "mindlin"), default="plate")
    args = ap.parse_args(argv)
    changes = {"spectrum": [], "section rule": []}
    refused = 0
    for i in range(args.panels):
        base = random_beam(args.seed, i)
        z = np.random.default_rng([args.seed, i, 1]).standard_normal(base.half_width.size)
        moved = Beam(x=base.x, half_width=base.half_width * np.exp(0.01 * z),
                     thickness=base.thickness, material=base.material)
        try:
            (s0, r0), (s1, r1) = targets(base, args.model), targets(moved, args.model)
        except BadInput:
            refused += 1
            continue
        changes["spectrum"].append(np.abs(s1 / s0 - 1))
        changes["section rule"].append(np.abs(r1 / r0 - 1))
    n = len(changes["spectrum"])
    print(f"{args.model} truth, {n} panels of random_beam({args.seed}, i), half-widths times "
          f"exp(0.01 z); {refused} refused")
    print("relative change of modes 1-4: median / p99 / share over 5 %")
    for name, rows in changes.items():
        c = np.array(rows)
        cells = [f"{100 * np.median(c[:, j]):.2g} / {100 * np.percentile(c[:, j], 99):.2g} % / "
                 f"{100 * np.mean(c[:, j] > 0.05):.1f} %" for j in range(c.shape[1])]
        print(f"  {name:>12}: " + " | ".join(cells))


if __name__ == "__main__":
    main()
