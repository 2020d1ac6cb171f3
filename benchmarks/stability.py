"""Stability on stiff and extreme cases (issue 7): run the case suite, print the Markdown section.

    python benchmarks/stability.py            # full suite (plate truth, n = 1..39, every corner)
    python benchmarks/stability.py --quick    # the subset the tests run
    python benchmarks/stability.py --json rows.json   # also save every check's numbers

Prints ``prbdm.stability.format_markdown(run_suite(...))``: one table row per case with its
checks, the accuracy nearest its tolerance, cond(M), cond(K), cond(K^-1/2 M K^-1/2), the beam
truth's FEM stiffness before/after diagonal scaling, gradient finiteness and time; then every
check in detail (``--details``) and the conditioning tricks. Exit status 1 if any case fails.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time

import torch

from prbdm import stability


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="only the cases the tests run")
    ap.add_argument("--json", metavar="FILE", help="write the rows (every check) as JSON")
    ap.add_argument("--details", action="store_true", help="list every check of every case")
    args = ap.parse_args(argv)
    torch.set_num_threads(1)
    t0 = time.perf_counter()
    rows = stability.run_suite(quick=args.quick)
    wall = time.perf_counter() - t0
    print(stability.format_markdown(rows))
    if args.details:
        print("\nEvery check:\n")
        print("| case | check | value | tolerance | passed |")
        print("|---|---|---|---|---|")
        for r in rows:
            for c in r["checks"]:
                v = "–" if c["value"] is None else f"{c['value']:.3g}"
                t = "–" if c["tol"] is None else f"{c['tol']:.2g}"
                print(f"| {r['name']} | {stability._cell(c['check'])} | {v} | {t} | "
                      f"{'yes' if c['passed'] else '**NO**'} |")
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"\n({len(rows)} cases in {wall:.1f} s; Python {platform.python_version()}, "
          f"torch {torch.__version__}, 1 thread, load average {load:.2f})")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(rows, fh, indent=1)
    return 0 if all(r["passed"] for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
