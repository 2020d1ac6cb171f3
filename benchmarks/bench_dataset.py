"""Labelled beams per second: each truth model, 1 and 2 workers (issue 5).

    python benchmarks/bench_dataset.py                      # beam + plate truth, 1 and 2 workers
    python benchmarks/bench_dataset.py --truth beam --count 32 --workers 1,2 --joints 4
    python benchmarks/bench_dataset.py --truth beam --workers 1,2 --count 64 --fit-batch 1,8
    python benchmarks/bench_dataset.py --truth beam --workers 1 --count 16 --objective eigenvalue,frequency

Each case labels ``--count`` random beams (seed 0) into a fresh temporary folder through
:func:`prbdm.dataset.generate` with a local process pool, exactly as ``prbdm dataset generate``
does, and reports:

* ``startup s``: spawning the workers (imports of torch and scikit-fem included);
* ``beams/s``: records written per second of labelling after start-up (the steady rate);
* ``per worker``: beams/s divided by the number of workers;
* ``beams/CPU-s``: beams per second of CPU time of the labelling threads, i.e. the rate of one
  core that is not shared: the number to compare with the target on a busy machine;
* ``truth s``, ``fit s``: median wall time of each stage per beam inside a worker (with
  ``--fit-batch B`` > 1 a chunk's fit time divided among its beams);
* ``worst %``: median over the beams of the fit's worst per-mode frequency error
  (``frequency_percent``), whichever ``--objective`` was minimised;
* ``load``: the 1-minute load average at the start and at the end of the case.

``--workers 0`` labels in the calling process (the inline executor).

With several ``--fit-batch`` values, the labels of each batched case are compared with those of
the ``--fit-batch 1`` case of the same truth and workers (same beams, same seeds): relative
difference of the loss (median, max) and largest difference of gamma.

Target (issue 5): with the ``beam`` truth and n = 4, at least 1 beam/s per core. The wall-clock
rates are only meaningful when as many cores as workers are free (the load average is printed).
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time

import numpy as np


def bench(truth: str, workers: int, count: int, joints: int, starts, seed: int,
          fit_batch: int | None = None, objective: str | None = None) -> dict:
    from prbdm import dataset as D

    spec = D.make_spec(joints=joints, truth=truth, starts=starts, seed=seed, fit_batch=fit_batch,
                       objective=objective)
    load_start = os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="bench-dataset-") as tmp:
        t0 = time.perf_counter()
        s = D.generate(tmp, count, spec, workers=workers, progress="none")
        wall = time.perf_counter() - t0
        t = D.read_table(tmp, columns=["status", "truth_time_s", "fit_time_s", "time_s",
                                       "cpu_s", "loss_percent", "frequency_percent", "gamma"])
        d = t.to_pydict()
    med = lambda key: float(np.nanmedian(np.asarray(d[key], dtype=float)))  # noqa: E731
    cpu = float(np.nansum(np.asarray(d["cpu_s"], dtype=float)))
    return {"truth": truth, "workers": workers, "fit_batch": s["fit_batch"],
            "objective": s["objective"], "worst_percent": med("frequency_percent"),
            "joints": joints, "beams": s["new"],
            "errors": s["new_errors"], "startup_s": s["startup_s"], "wall_s": wall,
            "beams_per_s": s["beams_per_s"], "per_worker": s["beams_per_s"] / max(workers, 1),
            "beams_per_cpu_s": s["new"] / cpu if cpu > 0 else None,
            "truth_s": med("truth_time_s"), "fit_s": med("fit_time_s"), "beam_s": med("time_s"),
            "load_start": load_start, "load_avg": os.getloadavg()[0],
            "labels": {i: (l, g) for i, l, g in zip(d["index"], d["loss_percent"], d["gamma"])}}


def compare(a: dict, b: dict) -> dict:
    """Labels of the same beams in two cases: relative loss difference, largest gamma change."""
    common = [i for i in a["labels"] if i in b["labels"] and a["labels"][i][0] is not None
              and b["labels"][i][0] is not None]
    la = np.array([a["labels"][i][0] for i in common])
    lb = np.array([b["labels"][i][0] for i in common])
    rel = np.abs(lb - la) / np.abs(la)
    dg = max((float(np.max(np.abs(np.subtract(a["labels"][i][1], b["labels"][i][1]))))
              for i in common), default=float("nan"))
    return {"beams": len(common), "loss_rel_median": float(np.median(rel)),
            "loss_rel_max": float(rel.max()), "gamma_max_abs": dg,
            "loss_median": (float(np.median(la)), float(np.median(lb)))}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--truth", default="beam,plate", help="comma list (default beam,plate)")
    ap.add_argument("--workers", default="1,2", help="comma list (default 1,2)")
    ap.add_argument("--count", type=int, default=24, help="beams per case (default 24)")
    ap.add_argument("--plate-count", type=int, default=None,
                    help="beams per plate case (default: --count)")
    ap.add_argument("--joints", type=int, default=4, help="n (default 4)")
    ap.add_argument("--starts", type=int, default=None, help="fit starts (default 64)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--fit-batch", default=None,
                    help="comma list of beams per batched fit (default: the package default, "
                    "8); 1 = one fit per beam")
    ap.add_argument("--objective", default=None,
                    help="comma list of fit objectives (default: the package default, eigenvalue)")
    ap.add_argument("--json", action="store_true", help="one JSON line per case, no table")
    args = ap.parse_args(argv)

    batches = [None] if args.fit_batch is None else [int(v) for v in args.fit_batch.split(",")]
    objectives = [None] if args.objective is None else args.objective.split(",")
    rows, load0 = [], os.getloadavg()[0]
    for truth in args.truth.split(","):
        for w in (int(v) for v in args.workers.split(",")):
            for fb, obj in ((fb, obj) for fb in batches for obj in objectives):
                count = args.plate_count if truth == "plate" and args.plate_count else args.count
                r = bench(truth, w, count, args.joints, args.starts, args.seed, fb, obj)
                rows.append(r)
                if args.json:
                    print(json.dumps({k: v for k, v in r.items() if k != "labels"}), flush=True)
                else:
                    print(f"  {truth} truth, {w} worker(s), fit batch {r['fit_batch']}, "
                          f"{r['objective']}: "
                          f"{r['beams_per_s']:.2f} beams/s, {r['beams_per_cpu_s']:.2f} "
                          f"beams/CPU-s", file=sys.stderr, flush=True)
    quality = []
    for r in rows:
        ref = [q for q in rows if q["fit_batch"] == 1 and q["truth"] == r["truth"]
               and q["workers"] == r["workers"] and q["objective"] == r["objective"]]
        if r["fit_batch"] != 1 and ref:
            c = compare(ref[0], r)
            quality.append([r["truth"], r["workers"], r["fit_batch"], c["beams"],
                            f"{c['loss_median'][0]:.5f}", f"{c['loss_median'][1]:.5f}",
                            f"{c['loss_rel_median']:.2e}", f"{c['loss_rel_max']:.2e}",
                            f"{c['gamma_max_abs']:.2e}"])
            if args.json:
                print(json.dumps({"compare": [r["truth"], r["workers"], r["fit_batch"]], **c}),
                      flush=True)
    if not args.json:
        from prbdm import dataset as D
        from prbdm.commands._common import table

        print(f"n = {args.joints}, starts = {args.starts or D.DEFAULT_STARTS}, "
              f"{os.cpu_count()} cores visible, load average before {load0:.2f}")
        print(table([[r["truth"], r["workers"], r["fit_batch"], r["objective"], r["beams"],
                      r["errors"],
                      f"{r['startup_s']:.1f}", f"{r['beams_per_s']:.2f}", f"{r['per_worker']:.2f}",
                      f"{r['beams_per_cpu_s']:.2f}", f"{r['truth_s']:.3f}", f"{r['fit_s']:.3f}",
                      f"{r['worst_percent']:.3g}",
                      f"{r['load_start']:.1f}-{r['load_avg']:.1f}"] for r in rows],
                    ["truth", "workers", "fit batch", "objective", "beams", "errors", "startup s",
                     "beams/s", "per worker", "beams/CPU-s", "truth s", "fit s", "worst %",
                     "load"]))
        if quality:
            print("\nlabels against --fit-batch 1 (same beams, same seeds):")
            print(table(quality, ["truth", "workers", "fit batch", "beams", "median loss % (1)",
                                  "median loss % (B)", "rel. loss diff median", "max",
                                  "max |d gamma|"]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
