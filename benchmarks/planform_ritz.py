"""How close the plate networks' physical estimates are to the Mindlin plate's bending spectrum.

    python benchmarks/planform_ritz.py --data datasets/mindlin-n5-spectrum --count 500 \
        [--json docs/planform-ritz.json]

On the first ``--count`` accepted panels of a Mindlin data set (truth-only sets store the
spectrum), for each bending mode of the spectrum (../SPEC §2.1): the median and the scatter (std)
of ``log omega_truth - log omega_estimate`` for the two estimates a plate network can correct:
the load-spread chain (``log_omega_spread``) and the Rayleigh-Ritz plate on the planform
(``log_omega_ritz``, :mod:`prbdm.truth.planform_ritz`), and the Ritz estimate's time per panel.
A network learns the scatter; the median is a constant it absorbs. One core, ~20 ms a panel.
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


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", required=True)
    ap.add_argument("--count", type=int, default=500)
    ap.add_argument("--modes", type=int, default=5)
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
    t0 = time.process_time()
    ritz = ritz_log_omega(batch, R)
    ms = 1e3 * (time.process_time() - t0) / len(batch)
    out = {"data": a.data, "panels": len(batch), "modes": R, "ritz_ms_per_panel": ms}
    print(f"{len(batch)} panels of {a.data}; log omega_truth - log omega_estimate, modes 1-{R}")
    for name, est in (("spread chain", spread), ("planform Ritz", ritz)):
        d = truth - est
        out[name] = {"median": np.median(d, 0).tolist(), "std": d.std(0).tolist()}
        print(f"  {name:14s} median {np.round(np.median(d, 0), 3).tolist()}  "
              f"std {np.round(d.std(0), 3).tolist()}")
    print(f"  planform Ritz: {ms:.1f} ms a panel (CPU)")
    if a.json:
        Path(a.json).write_text(json.dumps(out, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
