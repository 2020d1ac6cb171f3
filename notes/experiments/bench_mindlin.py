"""Speed and accuracy of the Mindlin plate truth, setting against setting, on the same panels.

    python notes/experiments/bench_mindlin.py --panels 10
    python notes/experiments/bench_mindlin.py --thin

``--panels`` random panels of the plate data sets' generator (``random_beam(11, i,
min_half_width=0.01)``, the first ones the plate accepts) and four of them made 5 mm thick, each
solved (5 modes) with the default settings, with one step of iterative refinement of the LU
solves (the earlier default), with P3 elements, and with the reference (``elements=24``): CPU
time per panel (median, one BLAS thread as the data-set workers run) and the largest relative
difference of the frequencies of modes 1-4 from the reference.
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import time
import warnings

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

SETTINGS = [("default (P4, elements 12, no refinement)", {}),
            ("one refinement step (the earlier default)", {"refinement_steps": 1}),
            ("P3", {"degree": 3}),
            ("reference: elements 24", {"elements": 24})]


def thin():
    from prbdm.geometry import Beam, random_beam
    from prbdm.truth.mindlin import solve_mindlin

    warnings.simplefilter("ignore")
    cases = [("square", Beam(x=[0, 1], half_width=[0.5, 0.5], thickness=0.001)),
             ("Table-2 beam", Beam(x=[0, 1], half_width=[0.1812, 0.1812], thickness=0.001)),
             ("random_beam(11, 1)", dataclasses.replace(random_beam(11, 1, min_half_width=0.01),
                                                         thickness=0.001))]
    print("t/L = 0.001: frequencies without refinement / with one step - 1, modes 1-4")
    for name, b in cases:
        om = [np.sqrt(solve_mindlin(b, 5, refinement_steps=s)["lam"][:4]) for s in (0, 1)]
        print(f"  {name:20s} " + " ".join(f"{v:+.1e}" for v in om[0] / om[1] - 1))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--panels", type=int, default=10)
    ap.add_argument("--thin", action="store_true", help="only the thin check: t/L = 0.001, no "
                    "refinement against one step (the default below t/L = 0.001 is one step)")
    a = ap.parse_args(argv)
    if a.thin:
        return thin()

    from prbdm.errors import BadInput
    from prbdm.geometry import check_beam, random_beam
    from prbdm.truth.mindlin import solve_mindlin

    warnings.simplefilter("ignore")
    beams, i = [], 0
    while len(beams) < a.panels:
        b = random_beam(11, i, min_half_width=0.01)
        i += 1
        try:
            check_beam(b, "mindlin")
        except BadInput:
            continue
        beams.append(b)
    beams += [dataclasses.replace(b, thickness=0.005) for b in beams[:4]]
    solve_mindlin(beams[0], 5)                                   # warm-up
    omega, times = {}, {}
    for name, kw in SETTINGS:
        om, ts = [], []
        for b in beams:
            t0 = time.process_time()
            r = solve_mindlin(b, 5, **kw)
            ts.append(time.process_time() - t0)
            om.append(np.sqrt(r["lam"][:4]))
        omega[name], times[name] = np.array(om), np.array(ts)
    ref = omega[SETTINGS[-1][0]]
    print(f"{len(beams)} panels (random_beam(11, i, min_half_width=0.01), {a.panels} as drawn and "
          "4 of them at t = 5 mm), 5 modes, CPU per panel")
    for name, _ in SETTINGS:
        d = np.abs(omega[name] / ref - 1).max(1)
        print(f"  {name:44s} median {np.median(times[name]):5.2f} s   vs reference: largest "
              f"{d.max():.1e}, median {np.median(d):.1e}")
    base = omega[SETTINGS[0][0]]
    step = np.abs(omega[SETTINGS[1][0]] / base - 1).max()
    print(f"one refinement step changes the default's frequencies by at most {step:.1e}; it costs "
          f"{np.median(times[SETTINGS[1][0]]) / np.median(times[SETTINGS[0][0]]):.2f}x the time")


if __name__ == "__main__":
    main()
