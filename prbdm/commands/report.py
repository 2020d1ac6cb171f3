"""``prbdm report [--beams N] [--seed S] [--data DIR] [--out DIR] [--quick]``: error against run time.

Evaluates every way to get a model of a beam (the Kirchhoff plate, Mindlin plate and beam
truths, the rigid-finite-element chain, Howell's 1R and Su's 3R classical PRBMs, the optimised fit
at several start counts and to each plate truth, the beam, plate and Mindlin networks, each then
refined, and their direct frequencies) on held-out beams, against each truth, and how
the cost grows (fit time against n and starts, truth time against mesh size, network throughput
against batch size). Writes ``OUT/report.md``, ``OUT/report.json`` and PNG plots, each file
atomically and only once everything is computed (see :mod:`prbdm.report`).

Held-out beams: by default ``random_beam(SEED, i)``, i < N, with truths computed on the fly (the
shipped checkpoint is trained on seed 0, so SEED must differ); with ``--data DIR`` the first N
beams of a prbdm data set that the checkpoint did not train on.
"""
from __future__ import annotations

import shlex
import sys
from pathlib import Path

from ..constants import OBJECTIVES
from ..errors import BadInput
from ._common import positive_int, require


def _starts(text):
    import argparse

    try:
        values = [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be comma-separated integers in [1, 4096], "
                                         f"got {text!r}") from None
    if not values or any(not 1 <= v <= 4096 for v in values):
        raise argparse.ArgumentTypeError(f"must be comma-separated integers in [1, 4096], "
                                         f"got {text!r}")
    return tuple(sorted(set(values)))


def add_arguments(parser):
    parser.add_argument("--beams", type=positive_int(2, 100000), default=None,
                        help="held-out beams (default 40; 3 with --quick)")
    parser.add_argument("--seed", type=positive_int(0), default=1,
                        help="seed of the generated held-out beams, not the checkpoint's "
                             "training seed (default 1)")
    parser.add_argument("--data", metavar="DIR", default=None,
                        help="take the beams from this prbdm data set (those the checkpoint "
                             "did not train on) instead of generating them")
    parser.add_argument("--out", metavar="DIR", default="report",
                        help="output folder (default ./report)")
    parser.add_argument("--checkpoint", metavar="PATH", default=None,
                        help="4-joint beam-truth surrogate checkpoint (default: the packaged "
                             "beam-n4)")
    parser.add_argument("--starts", type=_starts, default=None,
                        help="fit start counts to compare (default 8,16,32,64; 8 with --quick)")
    parser.add_argument("--single", type=positive_int(0, 100000), default=None,
                        help="beams also timed one at a time (default 10; 1 with --quick)")
    parser.add_argument("--scale-beams", type=positive_int(1, 1000), default=None,
                        help="beams of the scaling studies (default 3; 1 with --quick)")
    parser.add_argument("--quick", action="store_true",
                        help="a small, fast run (few beams, short scaling sweeps): for tests")
    parser.add_argument("--objective", choices=OBJECTIVES, default="eigenvalue",
                        help="what the fits minimise and which network is measured "
                             "(the default network for it: beam-n4, trained at rest, answers either; "
                             "default: the paper's eigenvalue loss)")
    parser.add_argument("--no-stability", action="store_true",
                        help="do not append the stability suite (prbdm.report.stability, "
                             "docs/validation.md)")


def _command(args) -> str:
    """The command line that reproduces this run, rebuilt from the parsed arguments."""
    parts = ["prbdm", "report"]
    for flag, value in (("--beams", args.beams), ("--seed", args.seed), ("--data", args.data),
                        ("--checkpoint", args.checkpoint), ("--single", args.single),
                        ("--scale-beams", args.scale_beams), ("--out", args.out)):
        if value is not None:
            parts += [flag, str(value)]
    if args.starts:
        parts += ["--starts", ",".join(map(str, args.starts))]
    if args.objective != "eigenvalue":
        parts += ["--objective", args.objective]
    parts += [f for f, on in (("--quick", args.quick), ("--no-stability", args.no_stability)) if on]
    return " ".join(shlex.quote(p) for p in parts)


def run(args) -> int:
    require("matplotlib", purpose="prbdm report (its plots)")
    if args.data is not None:
        require("pyarrow", purpose="--data")
    from .. import report

    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise BadInput(f"--out {args.out}: exists and is not a folder")
    if args.data is not None and not Path(args.data).is_dir():
        raise BadInput(f"--data {args.data}: not a folder (a prbdm data set folder)")
    q = args.quick
    cfg = report.ReportConfig(
        beams=args.beams or (3 if q else 40), seed=args.seed, data=args.data,
        checkpoint=args.checkpoint, quick=q,
        starts=args.starts or ((8,) if q else report.DEFAULT_STARTS),
        single=args.single if args.single is not None else (1 if q else 10),
        scale_beams=args.scale_beams or (1 if q else 3),
        stability=not args.no_stability, objective=args.objective,
        command=_command(args),
        progress=lambda text: sys.stderr.write(f"prbdm report: {text}\n"))
    res = report.write_report(cfg, out)
    sys.stderr.write(f"prbdm report: wrote {out}/report.md and plots in {res['elapsed_s']:.0f} s\n")
    print(report.method_table(res, "plate"))
    return 0
