"""A network's own truth frequencies against a held-out set's truth, whatever its poses.

    python benchmarks/direct_frequencies.py --data datasets/mindlin-n4-rest-frequency-seed1 \
        --checkpoints checkpoints/mindlin-n4.safetensors[,OTHER.safetensors] [--modes 4]

``training/evaluate_objective.py`` compares PRBDMs and refuses a network fitted at other poses
than the set's fits; the truth frequencies a network predicts (``omega_truth``) do not depend on
poses, so this compares any network's with the set's truth, e.g. a previous checkpoint from git
(``git show COMMIT:checkpoints/mindlin-n4.safetensors > old.safetensors``). Printed per network:
median and p95 of ``|omega_predicted / omega_truth - 1|`` per mode, in %, and how many panels it
refused (a Poisson's ratio or thickness it never learned: answered one by one to count them).

``--thin-limit T`` (a Kirchhoff ``plate`` set only): a Mindlin network answers each panel at
``t = T L`` and its frequencies are scaled by ``t / (T L)``, the thin limit in which the Mindlin
plate is the Kirchhoff plate (whose frequencies are proportional to t): how a Mindlin network
would answer the Kirchhoff truth, beside the Kirchhoff networks (docs/method.md, "One plate
family"):

    python benchmarks/direct_frequencies.py --data datasets/plate-spectrum-seed11 --thin-limit \
        0.002 --checkpoints checkpoints/plate-n4.safetensors,checkpoints/mindlin-n4.safetensors
"""
from __future__ import annotations

import argparse
import glob
import json
import sys
import warnings
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from prbdm import surrogate as sg
from prbdm.errors import BadInput
from prbdm.geometry import Beam, Material


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", required=True)
    ap.add_argument("--checkpoints", required=True)
    ap.add_argument("--modes", type=int, default=4)
    ap.add_argument("--thin-limit", type=float, metavar="T",
                    help="Kirchhoff plate sets: Mindlin networks answer at t = T L, their "
                    "frequencies scaled by t / (T L) (0 < T <= 0.01; smaller extrapolates below "
                    "the thicknesses they saw, larger adds a shear bias)")
    a = ap.parse_args(argv)
    spec = json.loads(Path(a.data, "_manifest.json").read_text())["spec"]
    if a.thin_limit is not None:
        if not 0 < a.thin_limit <= 0.01:
            ap.error(f"--thin-limit: a t/L in (0, 0.01], got {a.thin_limit}")
        if spec["truth"] != "plate":
            ap.error(f"--thin-limit: on a Kirchhoff plate set only, {a.data} has the "
                     f"{spec['truth']!r} truth")
    mat = spec["beam"]["material"]
    table = pa.concat_tables([pq.read_table(f) for f in
                              sorted(glob.glob(str(Path(a.data, "part-*.parquet"))))],
                             promote_options="default")
    rows = table.filter(pc.equal(table["status"], "ok")).to_pylist()
    beams = [Beam(x=r["x"], half_width=r["half_width"], thickness=r["thickness"],
                  material=Material(E=mat["E"], rho=mat["rho"], nu=r.get("nu") or mat["nu"]))
             for r in rows]
    R = a.modes
    truth = np.array([r["omega_truth"][:R] for r in rows])
    print(f"{len(beams)} panels of {a.data}; |omega_predicted / omega_truth - 1|, modes 1-{R}")
    for path in a.checkpoints.split(","):
        sur = sg.load_checkpoint(path)
        thin = a.thin_limit if (a.thin_limit and sur.truth == "mindlin") else 0.0
        if thin:            # the same panels at t = thin L; frequencies scale with t (Kirchhoff)
            asked = [Beam(x=b.x, half_width=b.half_width, thickness=thin * b.length,
                          material=b.material) for b in beams]
            scale = np.array([b.thickness / (thin * b.length) for b in beams])[:, None]
        else:
            asked, scale = beams, 1.0
        om = np.full((len(beams), R), np.nan)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                om = sur.predict(asked, frequencies=True, warn=False).omega_truth[:, :R]
            except BadInput:                  # some panels refused: one by one, to count them
                for i, b in enumerate(asked):
                    try:
                        om[i] = sur.predict([b], frequencies=True,
                                            warn=False).omega_truth[0, :R]
                    except BadInput:
                        pass
        e = 100 * np.abs(om * scale / truth - 1)
        ok = ~np.isnan(e).any(1)
        refused = int((~ok).sum())
        name = Path(path).name + (f" (thin limit, t/L = {thin:g})" if thin else "")
        if ok.any():
            print(f"  {name}: median {np.round(np.median(e[ok], 0), 2).tolist()} %, "
                  f"p95 {np.round(np.percentile(e[ok], 95, axis=0), 2).tolist()} %; "
                  f"{refused} refused")
        else:
            print(f"  {name}: refused all {refused} panels")
    return 0


if __name__ == "__main__":
    sys.exit(main())
