"""Network-then-refined against the optimised fit: loss ratio and time, for several start sets.

    python benchmarks/bench_refine.py --data data/beam-n4-seed1 --beams 200 --batch 8
    python benchmarks/bench_refine.py --data data/beam-n4-seed1 --beams 200 --batch 40 \
        --variants "fit;default,15"

On ``--beams`` beams drawn (seed 0) from a labelled data set of the checkpoint's spec, the full
multistart fit is re-run and each refinement variant is run, all with ``--batch`` beams per
:func:`prbdm.fit.fit_many` call, on one torch thread. Printed per variant: the median and 95th
percentile of the refined loss, the median per-beam ratio to the data set's optimised loss, the
share of beams within 10 %, the ratio of the medians, and the time per beam beside the re-run
fit's (one call's time divided by its beams).

Variants (``name,iterations``, separated by ``;``): ``fit`` (the re-run 64-start fit, always
first), ``default`` (the network's best ``REFINE_CANDIDATES`` candidates + the fit's four fixed
starts, :func:`prbdm.fit.refine_starts`), ``all`` (all its candidates + the four fixed starts),
``two_fixed`` (all candidates + the rigid-finite-element and equal-link starts only: an earlier
default), ``fixed`` (the four fixed starts alone, no network),
``drawnK`` (``default`` + K seeded draws of the fit's start design), ``topJ`` (the network's J
best candidates by their loss against its predicted frequencies + the four fixed starts) and
``topJdrawnK`` (that + K draws).
"""
from __future__ import annotations

import argparse
import time

import numpy as np
import torch

from prbdm import dataset as ds
from prbdm import surrogate as sg
from prbdm.chain import BeamBatch
from prbdm.fit import (
    FIXED_STARTS,
    REFINE_CANDIDATES,
    FitProblem,
    StopRules,
    fit_many,
    gamma_from_z,
    refine_starts,
    start_points,
)
from prbdm.geometry import Material

DEFAULT_VARIANTS = "fit;all,15;all,20;default,10;default,15;default,20;default,30;fixed,15;top2,15"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", required=True, help="labelled data set (optimised fits)")
    ap.add_argument("--checkpoint", default=None, help="default: the beam-truth checkpoint")
    ap.add_argument("--beams", type=int, default=200)
    ap.add_argument("--batch", type=int, default=8, help="beams per fit_many call")
    ap.add_argument("--variants", default=DEFAULT_VARIANTS)
    args = ap.parse_args()
    torch.set_num_threads(1)
    spec = ds.read_manifest(args.data)["spec"]
    if spec["starts"] == 0:
        raise SystemExit(f"bench_refine: {args.data} is truth-only; need optimised fits")
    sur = sg.load_checkpoint(args.checkpoint or sg.default_checkpoint(spec["joints"], spec["truth"]))
    n, r = sur.joints, sur.modes
    table = ds.read_table(args.data, columns=["index", "x", "half_width", "thickness",
                                              "omega_truth", "loss_percent"],
                          status="ok").to_pandas()
    table = table[~ds.refused_by_truth(table, spec)].reset_index(drop=True)   # stale labels
    pick = np.sort(np.random.default_rng(0).choice(len(table), min(args.beams, len(table)),
                                                   replace=False))
    table = table.iloc[pick].reset_index(drop=True)
    B = len(table)
    batch = BeamBatch.from_table(table, Material(**spec["beam"]["material"]))
    pred = sur.predict(batch, warn=False)
    cand = pred.ranked_candidates()
    omega = np.stack(table["omega_truth"].to_numpy())
    beams = [ds.beam_for(spec, int(i)) for i in table["index"]]
    fit_loss = table["loss_percent"].to_numpy()
    fixed = gamma_from_z(start_points(n, FIXED_STARTS, 0)).numpy()
    print(f"{sur.name}, {B} beams of {args.data} (fits' median {np.median(fit_loss):.4f} %), "
          f"{args.batch} beams per call, one torch thread")
    print(f"{'variant':34s} {'median %':>9s} {'p95 %':>7s} {'ratio med':>9s} {'<=1.1':>6s} "
          f"{'med/med':>7s} {'s/beam':>7s} {'fit time /':>10s}")
    t_fit = None
    for v in args.variants.split(";"):
        name, _, it = v.partition(",")
        it = int(it) if it else 150
        if name == "fit":
            starts, label = None, "optimised fit re-run (64 starts)"
        elif name == "default":
            starts = refine_starts(pred.ranked_candidates(REFINE_CANDIDATES))
        elif name == "all":
            starts = refine_starts(cand)
        elif name == "two_fixed":
            starts = np.concatenate([cand, np.broadcast_to(fixed[:2], (B, 2, n + 1))], 1)
        elif name == "fixed":
            starts = np.broadcast_to(fixed, (B, len(fixed), n + 1))
        elif name.startswith(("drawn", "top")):
            top, _, k = name.removeprefix("top").partition("drawn")
            k = int(k or 0)
            keep = int(top) if top else REFINE_CANDIDATES
            drawn = gamma_from_z(start_points(n, FIXED_STARTS + k, 0)).numpy()[FIXED_STARTS:]
            starts = np.concatenate([refine_starts(pred.ranked_candidates(keep)),
                                     np.broadcast_to(drawn, (B, k, n + 1))], 1)
        else:
            raise SystemExit(f"bench_refine: unknown variant {name!r}")
        if starts is not None:
            label = f"{name} ({starts.shape[1]} starts), {it} it."
        loss, times = [], []
        for i in range(0, B, args.batch):
            kw = {} if starts is None else dict(init_gamma=starts[i:i + args.batch],
                                                stop=StopRules(max_iter=it))
            t0 = time.perf_counter()
            res = fit_many(FitProblem(beams[i:i + args.batch], omega[i:i + args.batch], n, r,
                                      sur.law, sur.poses.tolist()), **kw)
            times.append(time.perf_counter() - t0)
            loss += [x.loss_percent for x in res]
        loss, t = np.array(loss), sum(times) / B
        t_fit = t if starts is None else t_fit
        ratio = loss / fit_loss
        frac = f"1/{t_fit / t:.1f}" if t_fit else ""
        print(f"{label:34s} {np.median(loss):9.4f} {np.percentile(loss, 95):7.4f} "
              f"{np.median(ratio):9.3f} {np.mean(ratio <= 1.10):6.2f} "
              f"{np.median(loss) / np.median(fit_loss):7.3f} {t:7.4f} {frac:>10s}", flush=True)


if __name__ == "__main__":
    main()
