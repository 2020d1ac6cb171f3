"""How close the plate networks' physical estimates are to the Mindlin plate's bending spectrum.

    python benchmarks/planform_ritz.py --data datasets/mindlin-n5-spectrum --count 500 \
        [--basis 3,3 4,4] [--json docs/planform-ritz.json]

On the first ``--count`` accepted panels of a Mindlin data set (truth-only sets store the
spectrum), for each bending mode of the spectrum (../SPEC §2.1): the median and the scatter (std)
of ``log omega_truth - log omega_estimate`` for the two estimates a plate network can correct:
the load-spread chain (``log_omega_spread``) and the Rayleigh-Ritz plate on the planform
(``log_omega_ritz``, :mod:`prbdm.truth.planform_ritz`) in each ``--basis`` (span-wise degree,
chord-wise terms; 3,3 is the default), and the Ritz estimate's CPU time per panel. A network
learns the scatter; the median is a constant it absorbs. The median absolute deviation from the
median (MAD) says what the std says without the few panels far out. One core, ~20 ms a panel
in the default basis.
"""
from __future__ import annotations

import argparse
import glob
import json
import sys
import time
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from prbdm.chain import BeamBatch
from prbdm.surrogate.features import FeatureSpec, feature_names, features, ritz_log_omega


def _basis(text: str) -> str:
    try:
        FeatureSpec(ritz_basis=text.split(","))
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", required=True)
    ap.add_argument("--count", type=int, default=500)
    ap.add_argument("--modes", type=int, default=5)
    ap.add_argument("--basis", nargs="+", default=["3,3"], type=_basis,
                    help="DEGREE,CHORD_TERMS of the Ritz bases to compare")
    ap.add_argument("--json")
    a = ap.parse_args(argv)
    manifest = json.loads(Path(a.data, "_manifest.json").read_text())
    spec = manifest["spec"]
    parts, n = [], 0
    for f in sorted(glob.glob(str(Path(a.data, "part-*.parquet")))):
        t = pq.read_table(f)
        t = t.filter(pc.equal(t["status"], "ok"))
        parts.append(t)
        n += len(t)
        if n >= a.count:
            break
    table = pa.concat_tables(parts, promote_options="default").slice(0, a.count)
    batch = BeamBatch.from_table(table, spec["beam"]["material"])
    R = a.modes
    truth = np.log(np.stack(table["omega_truth"].to_numpy())[:, :R]
                   / np.sqrt(batch.lambda0)[:, None])
    fs = FeatureSpec(cells=16, rfe_segments=96, rfe_coarse=16, rfe_modes=R, truth="mindlin",
                     spread=True)
    names = feature_names(fs)
    spread = features(batch, fs)[:, [names.index(f"log_omega_spread[{r}]") for r in range(R)]]
    out = {"data": a.data, "panels": len(batch), "modes": R}
    print(f"{len(batch)} panels of {a.data}; log omega_truth - log omega_estimate, modes 1-{R}")
    estimates = [("spread chain", spread, None)]
    for b in a.basis:
        t0 = time.process_time()
        est = ritz_log_omega(batch, R, FeatureSpec(ritz_basis=b.split(",")).ritz_basis)
        estimates.append((f"planform Ritz {b}", est,
                          1e3 * (time.process_time() - t0) / len(batch)))
    for name, est, ms in estimates:
        d = truth - est
        med = np.median(d, 0)
        mad = np.median(np.abs(d - med), 0)
        out[name] = {"median": med.tolist(), "std": d.std(0).tolist(), "mad": mad.tolist()}
        line = (f"  {name:18s} median {np.round(med, 3).tolist()}  std "
                f"{np.round(d.std(0), 3).tolist()}  MAD {np.round(mad, 4).tolist()}")
        if ms is not None:
            out[name]["ms_per_panel"] = ms
            line += f"  {ms:.0f} ms a panel (CPU)"
        print(line)
    if a.json:
        Path(a.json).write_text(json.dumps(out, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
