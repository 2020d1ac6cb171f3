"""What the Kirchhoff plate leaves out on the paper's panels: Kirchhoff against Reissner-Mindlin.

    python notes/experiments/mindlin_vs_plate.py --panels 80 --workers 2 --json docs/mindlin-vs-plate.json

``random_beam(seed, i, min_half_width=0.01)`` (the plate data sets' generator: full width 0.4-1 L,
thickness 0.01-0.05 L) for i < ``--panels``, the ones the plate accepts: both truths at their
default meshes, 4 kept modes each by the same section rule, and ``plate / mindlin - 1`` per mode,
by band of ``t / L``. Modes 3-4 of some panels are kept differently by the two models (a section
fraction near 1/2); such a pairing is not physics, so the table gives medians and the share of
panels whose kept modes pair (each Mindlin mode within 10 % of the Kirchhoff one).

Also a candidate closed-form correction, checked here and not used by the product: Mindlin's
first-order dispersion for a plate bending wave of wavenumber ``k`` lowers the frequency by
``1 / sqrt(1 + (k t)^2 (1 + 2 / (kappa (1 - nu))) / 12)`` (shear and rotary inertia), and each
Kirchhoff mode's own wavenumber is ``(k L)^2 = sqrt(lambda)`` (its nondimensional eigenvalue).
"""
from __future__ import annotations

import argparse
import json
import sys
import time
import warnings

import numpy as np

MODES = 4
BANDS = [0.0, 0.01, 0.02, 0.03, 0.04, 0.0501]
KAPPA = 5.0 / 6.0
NECKS = [0.0, 1.0, 2.0, 4.0, 8.0, 1e9]


def _solve(job):
    seed, i, thickness = job
    from prbdm.errors import BadInput
    from prbdm.geometry import random_beam
    from prbdm.truth import bending_frequencies

    warnings.simplefilter("ignore")
    beam = random_beam(seed, i, min_half_width=0.01)
    if thickness:
        import dataclasses
        beam = dataclasses.replace(beam, thickness=thickness * beam.length)
    try:
        k = bending_frequencies(beam, "plate", MODES + 1)
    except BadInput:
        return None                                 # refused by the plate (sharp corner)
    m = bending_frequencies(beam, "mindlin", MODES + 1)
    return {"index": i, "t_over_L": beam.thickness / beam.length, "nu": beam.material.nu,
            "neck_over_t": float(2 * beam.half_width.min() / beam.thickness),
            "plate": k.omega[:MODES].tolist(), "mindlin": m.omega[:MODES].tolist(),
            "plate_lambda": [float(e["lambda"]) for e in k.all_modes if e["kept"]][:MODES],
            "plate_s": k.time_s, "mindlin_s": m.time_s}


def corrected(row) -> np.ndarray:
    """The closed-form shear/rotary-inertia correction of the Kirchhoff frequencies."""
    tl, nu = row["t_over_L"], row["nu"]
    kt2 = np.sqrt(np.asarray(row["plate_lambda"])) * tl ** 2          # (k t)^2
    return np.asarray(row["plate"]) / np.sqrt(1 + kt2 * (1 + 2 / (KAPPA * (1 - nu))) / 12)


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--panels", type=int, default=40)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--thickness", type=float, default=0.0,
                    help="t / L of every panel instead of the generator's (0: the generator's)")
    ap.add_argument("--json", default="")
    a = ap.parse_args(argv)
    t0 = time.perf_counter()
    jobs = [(a.seed, i, a.thickness) for i in range(a.panels)]
    if a.workers > 1:
        import multiprocessing
        with multiprocessing.get_context("spawn").Pool(a.workers) as pool:
            rows = pool.map(_solve, jobs, chunksize=2)
    else:
        rows = [_solve(j) for j in jobs]
    refused = sum(r is None for r in rows)
    rows = [r for r in rows if r is not None]
    tl = np.array([r["t_over_L"] for r in rows])
    k = np.array([r["plate"] for r in rows])
    m = np.array([r["mindlin"] for r in rows])
    c = np.array([corrected(r) for r in rows])
    diff = 100 * (k / m - 1)
    cdiff = 100 * (c / m - 1)
    paired = np.all(np.abs(m / k - 1) < 0.1, axis=1)
    print(f"{len(rows)} panels random_beam({a.seed}, i, min_half_width=0.01), i < {a.panels} "
          f"({refused} refused by the plate); plate / mindlin - 1 [%], modes 1-{MODES}, median "
          "(p95) over the panels whose modes pair")
    out_bands = []
    for lo, hi in zip(BANDS[:-1], BANDS[1:]):
        s = (tl >= lo) & (tl < hi)
        p = s & paired
        if not p.any():
            continue
        med, p95 = np.median(diff[p], 0), np.percentile(np.abs(diff[p]), 95, 0)
        cmed = np.median(np.abs(cdiff[p]), 0)
        out_bands.append({"t_over_L": [lo, min(hi, 0.05)], "panels": int(s.sum()),
                          "max_mode_abs_p95": float(np.percentile(np.abs(diff[p]).max(1), 95)),
                          "paired": int(p.sum()), "median": med.tolist(), "abs_p95": p95.tolist(),
                          "corrected_abs_median": cmed.tolist()})
        print(f"t/L {lo:.2f}-{min(hi, 0.05):.2f}: {p.sum():3d} of {s.sum():3d} paired  "
              + "  ".join(f"{v:+6.2f} ({w:5.2f})" for v, w in zip(med, p95))
              + "   | closed-form corrected, |error| median "
              + " ".join(f"{v:5.2f}" for v in cmed))
    neck = np.array([r["neck_over_t"] for r in rows])
    print("by the narrowest full width over the thickness, 2 min(half_width) / t:")
    out_necks = []
    for lo, hi in zip(NECKS[:-1], NECKS[1:]):
        p = (neck >= lo) & (neck < hi) & paired
        if not p.any():
            continue
        med = np.median(diff[p], 0)
        out_necks.append({"neck_over_t": [lo, hi], "paired": int(p.sum()), "median": med.tolist()})
        print(f"  {lo:g}-{hi:g}: {p.sum():3d} paired  " + "  ".join(f"{v:+6.2f}" for v in med))
    over = np.mean(np.abs(diff[paired]).max(1) > 1.0)
    print(f"panels (paired) with some mode of 1-{MODES} more than 1 % apart: {100 * over:.0f} %; "
          f"time per panel median: plate {np.median([r['plate_s'] for r in rows]):.2f} s, "
          f"mindlin {np.median([r['mindlin_s'] for r in rows]):.2f} s")
    out = {"seed": a.seed, "panels": a.panels, "refused": refused, "paired": int(paired.sum()),
           "bands": out_bands, "necks": out_necks, "share_over_1_percent": float(over), "rows": rows,
           "time_s": time.perf_counter() - t0,
           "command": "python notes/experiments/mindlin_vs_plate.py " + " ".join(argv or sys.argv[1:])}
    if a.json:
        from prbdm.files import atomic_write
        atomic_write(a.json, json.dumps(out, indent=1) + "\n")
    return out


if __name__ == "__main__":
    main()
