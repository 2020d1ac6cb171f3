"""Networks against the plate truth, band by band of the panel's full width 2 max(w) / L.

    python benchmarks/plate_width_bands.py --data datasets/plate-n4-narrow-seed3 \
        --checkpoints checkpoints/plate-n4.safetensors,checkpoints/beam-n4.safetensors

For each held-out panel of a plate data set with fits (``prbdm dataset generate --truth plate``
or ``--truth mindlin``, ``--starts`` > 0), each network's PRBDM is measured against the stored
plate truth, Kirchhoff or Mindlin as the set was labelled (the paper's loss over the network's
poses, which the data set's fits share, docs/conventions.md §3), beside the optimised fit's, and its
direct prediction of the plate frequencies (error per mode); medians per width band. This is
what decides which network ``--truth auto`` should give a panel of a given width. No FEM runs:
the truth is the stored one. Runs in seconds.
"""
from __future__ import annotations

import argparse
import json
import sys
import warnings

import numpy as np

#: band edges of the full width 2 max(w) / L; a panel up to 0.05 L (AUTO_BEAM_MAX_WIDTH) is a
#: beam for --truth auto and not listed
BANDS = (0.05, 0.1, 0.2, 0.4, 0.7, 1.01)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", required=True, help="held-out plate data set with fits")
    ap.add_argument("--checkpoints", required=True, help="comma-separated checkpoints")
    ap.add_argument("--auto", default="", choices=("", "beam", "plate", "mindlin"),
                    help="only the panels that --truth auto gives this truth (default: all)")
    ap.add_argument("--json", default="", help="also write the table here")
    args = ap.parse_args(argv)

    from prbdm import dataset as ds
    from prbdm import surrogate as sg
    from prbdm.chain import BeamBatch, loss_percent_np
    from prbdm.errors import BadInput

    try:
        spec = ds.read_manifest(args.data)["spec"]
        t = ds.read_table(args.data, status="ok").to_pandas()
    except (BadInput, OSError) as exc:
        sys.exit(f"plate_width_bands: --data: {exc}")
    if spec["truth"] not in ("plate", "mindlin") or spec["starts"] == 0:
        sys.exit("plate_width_bands: --data: need a plate or mindlin data set with fits "
                 "(--starts > 0)")
    # records whose planform today's plate refuses (corners sharper than it resolves; their
    # stored frequencies can be wrong) are left out
    refused = ds.refused_by_truth(t, spec)
    t = t[~refused].reset_index(drop=True)
    print(f"{len(t)} panels of {args.data} ({int(refused.sum())} left out: refused by today's "
          f"{spec['truth']} truth)")
    if args.auto:
        from prbdm.dataset.schema import record_beam
        from prbdm.geometry import Material
        from prbdm.truth.choice import choose_truth

        material = Material(**spec["beam"]["material"])
        auto = np.array([choose_truth(record_beam(x, w, th, material))[0]
                         for x, w, th in zip(t["x"], t["half_width"], t["thickness"])])
        t = t[auto == args.auto].reset_index(drop=True)
        print(f"{len(t)} of them are {args.auto} panels for --truth auto")
        if len(t) == 0:
            print(f"plate_width_bands: --auto: no panel of {args.data} is a {args.auto} panel "
                  "for --truth auto", file=sys.stderr)
            return 2
    batch = BeamBatch.from_table(t, spec["beam"]["material"])
    r = spec["modes"]
    omega = np.stack(t["omega_truth"].to_numpy())[:, :r]
    width = np.array([2 * max(w) for w in t["half_width"]]) / t["length"].to_numpy()
    rows = {f"fit ({spec['starts']} starts)": {"loss": t["loss_percent"].to_numpy()}}
    for path in args.checkpoints.split(","):
        sur = sg.load_checkpoint(path)
        if (sur.joints, sur.modes) != (spec["joints"], r):
            sys.exit(f"plate_width_bands: --checkpoints: {sur.name} is n = {sur.joints}, "
                     f"r = {sur.modes}; the data set's fits are n = {spec['joints']}, r = {r}")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            pred = sur.predict(batch, frequencies=True, warn=False)
        loss = loss_percent_np(pred.omega, omega ** 2, r, is_lambda=False)
        direct = np.abs(pred.omega_truth[:, :r] / omega - 1) * 100
        rows[sur.name] = {"loss": loss, "direct": direct}
    out = {"data": args.data, "panels": len(t), "left_out_refused": int(refused.sum()),
           "auto": args.auto or None, "bands": []}
    listed = (width > BANDS[0]) & (width <= BANDS[-1])
    print(f"{len(t)} held-out panels of {args.data} ({listed.sum()} wider than {BANDS[0]} L), "
          f"against the {spec['truth']} truth; each network's PRBDM over its own poses; medians")
    for lo, hi in zip(BANDS[:-1], BANDS[1:]):
        s = (width > lo) & (width <= hi)
        if not s.any():
            continue
        band = {"width": [lo, min(hi, 1.0)], "panels": int(s.sum())}
        print(f"full width {lo:g}-{min(hi, 1.0):g} L, {s.sum()} panels")
        for name, v in rows.items():
            loss = float(np.median(v["loss"][s]))
            line = f"  {name:28s} loss {loss:8.3f} %"
            band[name] = {"loss_median": loss}
            if "direct" in v:
                d = np.median(v["direct"][s], 0)
                band[name]["direct_median"] = d.tolist()
                line += "   direct freq. " + " / ".join(f"{e:.2f}" for e in d) + " %"
            print(line)
        out["bands"].append(band)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
