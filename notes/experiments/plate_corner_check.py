"""Sharp corners: how far the plate truth can be trusted on planforms with a very acute corner.

    python notes/experiments/plate_corner_check.py --panels 20000 --below 1.2 --workers 2 \
        --json docs/plate-corner-check.json

A random planform whose stations lie a millimetre apart with a large change of half-width between
them has a tongue: a corner of a fraction of a degree, which any triangulation fills with
slivers. For every panel ``random_beam(seed, i, min_half_width=0.01)``, i < ``--panels`` (the
plate data sets' generator), this finds the smallest interior corner of the half planform
(:func:`prbdm.geometry.smallest_corner`); for those below ``--below`` degrees it solves the plate
at the default mesh and at ``elements=16`` (the plate's own accuracy check: they agree to 3e-4 on
ordinary panels, docs/truth.md) and prints, per band of corner angle, how many panels differ by
more than 1e-3 and 3e-4 on modes 1-2 (modes 3-4 can swap between meshes on mixed modes). The plate
refuses corners below :data:`prbdm.geometry.MIN_PLATE_CORNER_DEGREES`; this script calls its
solver directly, past that check, to measure what the check prevents.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
import warnings

import numpy as np

BANDS = [0.0, 0.2, 0.4, 0.6, 0.8, 1.0, 1.2, 1.5, 2.0, 5.0, 180.0]


def _solve(job):
    seed, i = job
    from prbdm.geometry import random_beam
    from prbdm.truth.plate import solve_plate

    warnings.simplefilter("ignore")
    beam = random_beam(seed, i, min_half_width=0.01)
    try:
        a = solve_plate(beam, 5)["lam"][:2]
        b = solve_plate(beam, 5, elements=16)["lam"][:2]
    except Exception as exc:  # noqa: BLE001  (reported, not hidden)
        return i, None, f"{type(exc).__name__}: {exc}"
    # lambda ~ omega^2: half the relative difference of lambda is that of omega
    return i, float(np.max(np.abs(np.sqrt(b / a) - 1))), None


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--panels", type=int, default=2000, help="random panels 0..N-1 scanned")
    ap.add_argument("--below", type=float, default=1.2, help="solve panels with a corner below "
                    "this many degrees")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--json", default="", help="also write the results here")
    a = ap.parse_args(argv)

    from prbdm.geometry import MIN_PLATE_CORNER_DEGREES, random_beam, smallest_corner

    t0 = time.perf_counter()
    corner = np.array([smallest_corner(random_beam(a.seed, i, min_half_width=0.01))[0]
                       for i in range(a.panels)])
    sharp = [int(i) for i in np.flatnonzero(corner < a.below)]
    shares = ", ".join(f"{100 * np.mean(corner < v):.2f} %" for v in (0.4, 1, 2, 5))
    print(f"{a.panels} panels random_beam({a.seed}, i, min_half_width=0.01): smallest corner "
          f"below 0.4 / 1 / 2 / 5 degrees on {shares}; "
          f"solving the {len(sharp)} below {a.below:g} degrees at two meshes", flush=True)
    jobs = [(a.seed, i) for i in sharp]
    if a.workers > 1:
        import multiprocessing
        with multiprocessing.get_context("spawn").Pool(a.workers) as pool:
            done = pool.map(_solve, jobs, chunksize=4)
    else:
        done = [_solve(j) for j in jobs]
    diff = {i: d for i, d, _ in done}
    errors = {i: e for i, _, e in done if e}
    rows = []
    print(f"{'corner [deg]':>14s} {'panels':>7s} {'> 1e-3':>7s} {'> 3e-4':>7s} {'largest':>9s}  "
          "(default vs elements=16, modes 1-2)")
    for lo, hi in zip(BANDS[:-1], BANDS[1:]):
        ids = [i for i in sharp if lo <= corner[i] < hi and diff[i] is not None]
        if lo >= a.below or not ids:
            continue
        d = np.array([diff[i] for i in ids])
        worst = ids[int(np.argmax(d))]
        rows.append({"band": [lo, hi], "panels": len(ids), "above_1e-3": int((d > 1e-3).sum()),
                     "above_3e-4": int((d > 3e-4).sum()), "largest": float(d.max()),
                     "largest_panel": worst})
        print(f"{lo:6.1f} - {hi:<5.1f} {len(ids):7d} {rows[-1]['above_1e-3']:7d} "
              f"{rows[-1]['above_3e-4']:7d} {d.max():9.1e}  (panel {worst})")
    for i, e in errors.items():
        print(f"panel {i}: {e}")
    failing = [corner[i] for i in sharp if diff[i] is not None and diff[i] > 1e-3]
    print(f"bluntest corner that failed (> 1e-3): {max(failing):.3f} degrees; the plate refuses "
          f"corners below {MIN_PLATE_CORNER_DEGREES:g} degrees" if failing else
          "no panel differed by more than 1e-3")
    out = {"seed": a.seed, "panels": a.panels, "below": a.below, "solved": len(sharp),
           "share_below": {str(v): float(np.mean(corner < v)) for v in (0.4, 1, 2, 5)},
           "bands": rows, "errors": errors, "time_s": time.perf_counter() - t0,
           "command": "python notes/experiments/plate_corner_check.py " + " ".join(argv or sys.argv[1:])}
    if a.json:
        from prbdm.files import atomic_write
        atomic_write(a.json, json.dumps(out, indent=1) + "\n")
    return out


if __name__ == "__main__":
    main()
