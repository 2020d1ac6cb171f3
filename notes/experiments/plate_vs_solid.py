"""What the Kirchhoff plate leaves out: the plate truth against 3-D elasticity (issue 16 item 2).

    python notes/experiments/plate_vs_solid.py [--random 6] [--seed 16] [--json docs/plate-vs-solid.json]

For each panel, the first ``--modes`` symmetric bending frequencies of the plate truth (default
mesh) and of the 3-D model of :mod:`prbdm.truth.solid` at two mesh levels (``--level`` and the
next); the table gives, per mode, the plate, the 3-D (finer level) frequency, their difference
``plate / 3-D - 1`` and the change of the 3-D frequency between the two levels (its own
discretisation error is about that change or less: both the refinement and the physics lower the
3-D frequencies, so the true plate-vs-3-D difference is at least as large as the one listed).

Panels: the uniform beam of the paper's Table 2 (docs/conventions.md §5, t/L = 0.04), the square
plate at t/L = 0.01 and 0.04, a trapezoid (half-width 0.5 -> 0.25) at t/L = 0.01, 0.02, 0.04, and
``--random`` panels of the paper's generator (``prbdm.geometry.random_beam(seed, i,
min_half_width=0.01)``, their own thickness 10-50 mm). The JSON is written at the end, atomically.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

from prbdm.geometry import Beam, random_beam
from prbdm.truth import bending_frequencies
from prbdm.truth.solid import DEFAULT_LEVEL, solve_solid

#: the paper's Table 2 uniform beam (docs/conventions.md §5): full width 0.3624 m, t 0.040532 m
TABLE2 = dict(x=[0.0, 1.0], half_width=[0.1812, 0.1812], thickness=0.040532)


def panels(random: int, seed: int) -> list[tuple[str, Beam]]:
    out = [("Table-2 uniform beam", Beam(**TABLE2, name="table2"))]
    for t in (0.01, 0.04):
        out.append((f"square, t/L = {t:g}", Beam(x=[0, 1], half_width=[0.5, 0.5], thickness=t)))
    for t in (0.01, 0.02, 0.04):
        out.append((f"trapezoid 0.5 -> 0.25, t/L = {t:g}",
                    Beam(x=[0, 1], half_width=[0.5, 0.25], thickness=t)))
    for i in range(random):
        out.append((f"random seed={seed} index={i}",
                    random_beam(seed, i, min_half_width=0.01)))
    return out


def compare(name: str, beam: Beam, modes: int, level: int) -> dict:
    t0 = time.process_time()
    plate = bending_frequencies(beam, "plate", modes)
    plate_fraction = [e["section_fraction"] for e in plate.all_modes if e["kept"]]
    t1 = time.process_time()
    coarse = solve_solid(beam, modes, level)
    fine = solve_solid(beam, modes, level + 1)
    t2 = time.process_time()
    diff = 100 * (plate.freq_hz / fine["freq_hz"] - 1)
    change = 100 * (fine["freq_hz"] / coarse["freq_hz"] - 1)
    row = {"panel": name, "beam": beam.to_dict(),
           "thickness_ratio": beam.thickness / beam.length,
           "width_ratio": float(2 * beam.half_width.max() / beam.length),
           "plate_hz": plate.freq_hz.tolist(), "solid_hz": fine["freq_hz"].tolist(),
           "solid_coarse_hz": coarse["freq_hz"].tolist(),
           "plate_minus_solid_percent": diff.tolist(),
           "solid_level_change_percent": change.tolist(),
           "plate_section_fraction": plate_fraction,
           "solid_section_fraction": fine["section_fraction"].tolist(),
           "levels": [coarse["mesh"], fine["mesh"]],
           "cpu_s": {"plate": t1 - t0, "solid_both_levels": t2 - t1}}
    print(f"{name:38s} t/L={row['thickness_ratio']:.4f}  plate-3D %: "
          + " ".join(f"{d:+6.2f}" for d in diff) + "   level change %: "
          + " ".join(f"{c:+6.2f}" for c in change) + f"   ({t2 - t1:.0f} s CPU)", flush=True)
    return row


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--random", type=int, default=6)
    ap.add_argument("--seed", type=int, default=16)
    ap.add_argument("--modes", type=int, default=4)
    ap.add_argument("--level", type=int, default=DEFAULT_LEVEL)
    ap.add_argument("--json", default="docs/plate-vs-solid.json")
    args = ap.parse_args(argv)
    rows = [compare(n, b, args.modes, args.level) for n, b in panels(args.random, args.seed)]
    out = {"command": "python notes/experiments/plate_vs_solid.py "
                      + " ".join(sys.argv[1:] if argv is None else argv),
           "modes": args.modes, "levels": [args.level, args.level + 1],
           "plate": "prbdm.truth plate, default mesh",
           "solid": "prbdm.truth.solid: 27-node hexahedra, half panel, symmetric family",
           "panels": rows}
    path = Path(args.json)
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(json.dumps(out, indent=1) + "\n")
    os.replace(tmp, path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
