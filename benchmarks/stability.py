"""Stability on stiff and extreme cases (issue 7): run the case suite, print the Markdown section.

    python benchmarks/stability.py --details  # full suite (plate truth, n = 1..39, every corner)
    python benchmarks/stability.py --quick    # the subset tests/test_stability.py runs by default
    python benchmarks/stability.py --json rows.json   # also save every check's numbers

Kept in benchmarks/ because a maintainer reruns it whenever the truth, the model or the network
changes: docs/stability.md carries its output. A thin script over the library: the cases are
:mod:`prbdm.report.stability_cases` (harness and references: :mod:`prbdm.report.stability_checks`),
the tables :mod:`prbdm.report.stability` (``format_markdown``, ``details``; ``section`` is what
``prbdm report`` appends). This script adds one thread, the timing line and ``--json``. Exit
status 1 if any case fails.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time

from prbdm.report.stability import details, format_markdown, run_suite


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="only the cases the tests run")
    ap.add_argument("--json", metavar="FILE", help="write the rows (every check) as JSON")
    ap.add_argument("--details", action="store_true", help="list every check of every case")
    args = ap.parse_args(argv)
    import torch

    torch.set_num_threads(1)
    t0 = time.perf_counter()
    rows = run_suite(quick=args.quick)
    wall = time.perf_counter() - t0
    print(format_markdown(rows))
    if args.details:
        print("\nEvery check:\n")
        print(details(rows))
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"\n({len(rows)} cases in {wall:.1f} s; Python {platform.python_version()}, "
          f"torch {torch.__version__}, 1 thread, load average {load:.2f})")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(rows, fh, indent=1)
    return 0 if all(r["passed"] for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
