"""How often the plate's kept bending modes are a close call, and what that does to a network.

    python notes/experiments/plate_mode_switching.py --data data/plate-n4-seed1 --panels 1000 \
        --checkpoints checkpoints/plate-n4.safetensors --json docs/plate-mode-switching.json

The plate truth keeps a symmetric mode as a bending mode when more than half of its modal mass
moves with its chord sections (``section_fraction >= 1/2``, :mod:`prbdm.truth.modes`). On jagged
wide panels a bending and a chordwise mode can mix, and a mode's fraction then lies near 1/2: a
small change of the planform can swap which of two neighbouring modes is kept, and the kept
frequency jumps. No smooth function of the geometry (a network) can follow such a jump.

For each held-out panel of a plate data set (its stored truth is recomputed here, symmetric
modes with their section fractions, and checked equal to the stored one), this script records,
per kept mode 1..r, whether its section fraction is within 0.1 of 1/2 (the truth's own
``ambiguous`` flag) or a neighbouring unkept mode's is; then prints the share of panels with a
close call per mode, and each network's error of its own truth-frequency prediction per mode,
median and p95, split into panels whose modes 1..j are all clear and the rest.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
import warnings

import numpy as np


def close_calls(res, r: int) -> np.ndarray:
    """(r,) bool: kept mode j is a close call (it, or an unkept symmetric mode between kept
    modes j-1 and j+1, has a section fraction within 0.1 of 1/2)."""
    sym = [e for e in res.all_modes if e["symmetry"] == "symmetric"]
    kept = [i for i, e in enumerate(sym) if e["kept"]][:r]
    out = np.zeros(r, dtype=bool)
    for j, i in enumerate(kept):
        lo = kept[j - 1] + 1 if j > 0 else 0
        hi = kept[j + 1] if j + 1 < len(kept) else i + 2
        out[j] = any(e["ambiguous"] for e in sym[lo:min(hi, len(sym))])
    return out


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", required=True, help="a plate data set (prbdm dataset generate)")
    ap.add_argument("--panels", type=int, default=200, help="first N panels of the set")
    ap.add_argument("--checkpoints", default="", help="comma-separated checkpoints to split")
    ap.add_argument("--json", default="", help="also write the results here")
    a = ap.parse_args(argv)

    from prbdm import dataset as ds
    from prbdm import surrogate as sg
    from prbdm.geometry import Material
    from prbdm.truth import bending_frequencies

    spec = ds.read_manifest(a.data)["spec"]
    if spec["truth"] != "plate":
        sys.exit(f"plate_mode_switching: --data {a.data} is a {spec['truth']} set, not plate")
    table = ds.read_table(a.data, columns=["index", "x", "half_width", "thickness",
                                           "omega_truth"], status="ok").to_pandas()
    table = table[~ds.refused_by_truth(table, spec)]          # labels today's plate refuses
    table = table.sort_values("index").head(a.panels).reset_index(drop=True)
    r = spec["modes"]
    flags, t0 = [], time.perf_counter()
    for i in table["index"]:
        beam = ds.beam_for(spec, int(i))
        res = bending_frequencies(beam, "plate", spec["truth_modes"])
        stored = np.asarray(table["omega_truth"][len(flags)])
        assert np.allclose(res.omega, stored, rtol=1e-6), (i, res.omega, stored)
        flags.append(close_calls(res, r))
    flags = np.array(flags)
    B = len(flags)
    out = {"data": a.data, "panels": B, "modes": r, "truth_seconds": time.perf_counter() - t0,
           "close_call_share_per_mode": flags.mean(0).round(4).tolist(),
           "panels_with_any_close_call": float(flags.any(1).mean()), "networks": []}
    print(f"{B} panels of {a.data}: a close call (section fraction within 0.1 of 1/2) on kept "
          f"mode 1..{r}: {', '.join(f'{100 * v:.1f} %' for v in flags.mean(0))}; "
          f"any: {100 * flags.any(1).mean():.1f} %")
    omega_t = np.stack(table["omega_truth"].to_numpy())[:, :r]
    batch = sg.BeamBatch.from_table(table, Material(**spec["beam"]["material"]))
    for path in [p for p in a.checkpoints.split(",") if p]:
        sur = sg.load_checkpoint(path)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            pred = sur.predict(batch, frequencies=False, warn=False)
        err = 100 * np.abs(pred.omega_truth[:, :r] / omega_t - 1)
        row = {"checkpoint": sur.name, "truth": sur.truth, "clear": [], "close": []}
        print(f"{sur.name} ({sur.truth} network): truth-frequency error, median (p95) [%]")
        print(f"{'mode':>5s} {'all panels':>24s} {'modes 1..j all clear':>24s} "
              f"{'a close call in 1..j':>24s}")
        for j in range(r):
            clear = ~flags[:, :j + 1].any(1)
            cells = []
            for sel in (np.ones(B, bool), clear, ~clear):
                e = err[sel, j]
                cells.append((float(np.median(e)), float(np.percentile(e, 95)), int(sel.sum()))
                             if sel.any() else (float("nan"), float("nan"), 0))
            row["clear"].append(cells[1])
            row["close"].append(cells[2])
            print(f"{j + 1:5d} " + " ".join(f"{m:6.2f} ({p:6.1f}) n={k:<5d}".rjust(24)
                                            for m, p, k in cells))
        out["networks"].append(row)
    if a.json:
        from prbdm.files import atomic_write
        atomic_write(a.json, json.dumps(dict(out, command="python notes/experiments/plate_mode_switching.py "
                                             + " ".join(argv or sys.argv[1:])), indent=1) + "\n")
    return out


if __name__ == "__main__":
    main()
