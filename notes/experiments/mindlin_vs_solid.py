"""The Reissner-Mindlin plate truth against the Kirchhoff plate and 3-D elasticity.

    python notes/experiments/mindlin_vs_solid.py [--solid docs/plate-vs-solid.json]
                                          [--json docs/mindlin-vs-solid.json]

Three checks, all printed and written to the JSON:

1. thin limit (and locking): the square panel and the Table-2 beam at t/L = 0.001, Mindlin with
   P2, P3, P4 triangles against the Kirchhoff plate (``mindlin / plate - 1``, modes 1-4);
2. for every panel of ``--solid`` (the stored 3-D results of notes/experiments/plate_vs_solid.py, not
   recomputed: the 3-D solves take minutes), Mindlin (default mesh) and the stored Kirchhoff
   plate against the stored 3-D frequency, ``model / 3-D - 1`` per mode, and the Mindlin mesh
   convergence, ``default / refined - 1`` with twice the span-wise resolution (``elements``
   24 instead of 12);
3. solve time per panel (``TruthResult.time_s``), Mindlin and Kirchhoff plate, median over the
   panels (indicative: one run, whatever else the machine is doing).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from prbdm.geometry import Beam, Material
from prbdm.truth import bending_frequencies

MODES = 4
REFINED = 24          # elements (1/h0) of the refined mesh; the default is 12 for 4-5 modes


def beam_from(d: dict) -> Beam:
    return Beam(x=d["x"], half_width=d["half_width"], thickness=d["thickness"],
                material=Material(**d["material"]), name=d.get("name"))


def pct(a, b):
    return (100.0 * (np.asarray(a) / np.asarray(b) - 1.0)).tolist()


def fmt(v):
    return " ".join(f"{x:+7.3f}" for x in v)


def thin_limit() -> list[dict]:
    rows = []
    cases = [("square", dict(x=[0, 1], half_width=[0.5, 0.5])),
             ("Table-2 uniform beam", dict(x=[0, 1], half_width=[0.1812, 0.1812]))]
    print("1. thin limit, t/L = 0.001: mindlin / plate - 1 [%], modes 1-4")
    for name, geo in cases:
        beam = Beam(**geo, thickness=0.001)
        plate = bending_frequencies(beam, "plate", MODES).freq_hz
        for degree in (2, 3, 4):
            m = bending_frequencies(beam, "mindlin", MODES, degree=degree)
            d = pct(m.freq_hz, plate)
            rows.append({"panel": name, "thickness_ratio": 0.001, "degree": degree,
                         "dofs": m.mesh["dofs"], "mindlin_hz": m.freq_hz.tolist(),
                         "plate_hz": plate.tolist(), "mindlin_minus_plate_percent": d})
            print(f"  {name:22s} P{degree} ({m.mesh['dofs']:5d} DOFs): {fmt(d)}")
    return rows


def against_solid(stored: dict) -> list[dict]:
    rows = []
    print("2. against 3-D (stored level-1 3-D of docs/plate-vs-solid.json), model / 3-D - 1 [%]")
    for p in stored["panels"]:
        beam = beam_from(p["beam"])
        solid = np.array(p["solid_hz"])
        plate = np.array(p["plate_hz"])
        m = bending_frequencies(beam, "mindlin", MODES)
        fine = bending_frequencies(beam, "mindlin", MODES, elements=REFINED)
        kp = bending_frequencies(beam, "plate", MODES)       # for the timing only
        row = {"panel": p["panel"], "thickness_ratio": p["thickness_ratio"],
               "mindlin_hz": m.freq_hz.tolist(), "mindlin_refined_hz": fine.freq_hz.tolist(),
               "plate_hz": plate.tolist(), "solid_hz": solid.tolist(),
               "mindlin_minus_solid_percent": pct(m.freq_hz, solid),
               "plate_minus_solid_percent": pct(plate, solid),
               "mindlin_refinement_percent": pct(m.freq_hz, fine.freq_hz),
               "solid_level_change_percent": p["solid_level_change_percent"],
               "mindlin_section_fraction": [e["section_fraction"] for e in m.all_modes
                                            if e["kept"]],
               "mesh": m.mesh, "refined_dofs": fine.mesh["dofs"],
               "time_s": {"mindlin": m.time_s, "mindlin_refined": fine.time_s,
                          "plate": kp.time_s}}
        rows.append(row)
        print(f"  {p['panel']:34s} t/L={p['thickness_ratio']:.3f}\n"
              f"    mindlin-3D {fmt(row['mindlin_minus_solid_percent'])}   "
              f"plate-3D {fmt(row['plate_minus_solid_percent'])}\n"
              f"    mindlin default/refined {fmt(row['mindlin_refinement_percent'])}   "
              f"3-D level change {fmt(row['solid_level_change_percent'])}", flush=True)
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--solid", default="docs/plate-vs-solid.json")
    ap.add_argument("--json", default="docs/mindlin-vs-solid.json")
    args = ap.parse_args(argv)
    stored = json.loads(Path(args.solid).read_text())
    thin = thin_limit()
    rows = against_solid(stored)
    t_m = float(np.median([r["time_s"]["mindlin"] for r in rows]))
    t_p = float(np.median([r["time_s"]["plate"] for r in rows]))
    print(f"3. median solve time per panel ({len(rows)} panels, default mesh, 4 modes): "
          f"mindlin {1e3 * t_m:.0f} ms, plate {1e3 * t_p:.0f} ms")
    out = {"command": "python notes/experiments/mindlin_vs_solid.py "
                      + " ".join(sys.argv[1:] if argv is None else argv),
           "modes": MODES, "refined_elements": REFINED,
           "mindlin": "prbdm.truth mindlin, default mesh (P4 Lagrange, plate_mesh)",
           "solid": f"stored: {args.solid}, level {stored['levels'][1]}",
           "thin_limit": thin, "panels": rows,
           "median_time_s": {"mindlin": t_m, "plate": t_p}}
    path = Path(args.json)
    from prbdm.files import atomic_write
    atomic_write(path, json.dumps(out, indent=1, default=float) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
