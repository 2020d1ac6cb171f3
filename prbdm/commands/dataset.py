"""``prbdm dataset generate|info``: labelled data sets of random beams (see prbdm.dataset).

This module imports neither torch nor scikit-fem: the labelling runs in worker processes.
"""
from __future__ import annotations

import signal
import sys

from ..errors import BadInput
from ._common import float_list, positive_int, print_json, require, table


def add_arguments(parser):
    sub = parser.add_subparsers(dest="dataset_command", metavar="ACTION",
                                parser_class=type(parser))
    g = sub.add_parser(
        "generate", help="label random beams (truth + fit) into a folder of Parquet parts",
        description="Label random beams 0..N-1 (docs/conventions.md §1) into DIR: geometry, truth frequencies, "
        "fitted PRBDM, timings, status. Run the same command again to resume after a crash or to "
        "extend the set with a larger --count; different options on an existing DIR are refused.")
    g.add_argument("--out", required=True, metavar="DIR", help="data set folder (created)")
    g.add_argument("--count", required=True, type=positive_int(0), metavar="N",
                   help="label beams 0..N-1 (a larger N extends an existing set)")
    g.add_argument("--joints", required=True, type=positive_int(1), metavar="n",
                   help="revolute joints of the PRBDM")
    g.add_argument("--modes", type=positive_int(1), metavar="r",
                   help="truth modes the fit maps (default: n); the truth keeps max(r, n) + 1")
    g.add_argument("--truth", default="beam", choices=["beam", "plate", "mindlin"],
                   help="truth model (default beam; mindlin: the shear-deformable plate, about "
                        "0.7 s a panel)")
    g.add_argument("--law", default="beam", choices=["beam", "paper"],
                   help="stiffness law (default beam)")
    g.add_argument("--poses", default="paper", metavar="paper|linear|t1,t2,...",
                   help="pose set (default paper)")
    g.add_argument("--starts", type=positive_int(0), metavar="S",
                   help="fit multistart points (default 64; 0 = truth only, no fit: enough for "
                   "the surrogate's physics training)")
    g.add_argument("--fit-batch", type=positive_int(1, 256), metavar="B",
                   help="beams per batched fit, one task each (default: the set's value; 8 for a "
                   "new set; 1 = one fit per beam). Part of the spec")
    g.add_argument("--objective", metavar="eigenvalue|frequency",
                   help="what the fit minimises: eigenvalue (the paper's loss) or frequency (the "
                   "worst relative frequency error per pose); every record holds both measures "
                   "(default: the set's; eigenvalue for a new set). Part of the spec")
    g.add_argument("--target", choices=("spectrum", "section"), default=None,
                   help="plate, mindlin: the bending spectrum (default for a new set) or the "
                   "section rule's pick (the set's own for an existing one). Part of the spec")
    g.add_argument("--seed", type=positive_int(0), default=0, metavar="S",
                   help="random-beam stream (default 0); beam i is random_beam(S, i)")
    g.add_argument("--family", choices=("paper", "smooth"), default="paper",
                   help="the panels: 'paper' (default), the paper's jagged random planforms of "
                   "steel 10-50 mm thick; 'smooth': uniform, tapered, trapezoidal and smoothly "
                   "necked planforms 0.02-1 L wide, t/L 0.002-0.05, nu 0.2-0.45 "
                   "(prbdm.planforms). Part of the spec")
    g.add_argument("--stations", type=positive_int(0), metavar="p",
                   help="interior planform stations of the random beams (default 10)")
    g.add_argument("--min-half-width", type=float, metavar="M",
                   help="lower bound on the random half-widths [m] (default 0)")
    g.add_argument("--max-half-width", metavar="W|LO,HI",
                   help="upper bound on the random half-widths [m] (default 0.5, the paper's); "
                   "LO,HI: each beam's bound drawn log-uniformly in [LO, HI] (narrow and wide "
                   "panels in one set)")
    g.add_argument("--thickness", metavar="LO,HI",
                   help="bounds of the random thickness [m] (default 0.01,0.05, the paper's): "
                   "HI times a uniform draw, raised to LO; e.g. 0.002,0.05 for thin panels too")
    g.add_argument("--workers", type=positive_int(0), metavar="W",
                   help="worker processes (default: usable cores; 0 = in this process)")
    g.add_argument("--scheduler", metavar="ADDRESS",
                   help="run on a Dask cluster: tcp://host:8786, or 'local' for a LocalCluster "
                   "of W workers (default: a local process pool, no Dask)")
    g.add_argument("--part-size", type=positive_int(1), default=256, metavar="K",
                   help="records per Parquet part (default 256; also written every 60 s)")
    g.add_argument("--progress", default="auto", choices=["auto", "bar", "log", "none"],
                   help="progress on stderr: a bar on a terminal, log lines otherwise (auto)")
    g.add_argument("--json", action="store_true", help="print a JSON summary on stdout")

    i = sub.add_parser("info", help="counts, failures, loss distribution, time per beam",
                       description="Summarise a data set folder made by `prbdm dataset generate`.")
    i.add_argument("dir", metavar="DIR", help="data set folder")
    i.add_argument("--json", action="store_true", help="print one JSON object on stdout")


def run(args) -> int:
    if args.dataset_command == "generate":
        return _generate(args)
    if args.dataset_command == "info":
        return _info(args)
    raise BadInput("ACTION: choose generate or info (prbdm dataset --help)")


def _sigterm(signum, frame):
    raise KeyboardInterrupt  # write the buffered records, then stop


def _generate(args) -> int:
    require("pyarrow", purpose="prbdm dataset")
    if args.scheduler is not None:
        require("dask", "distributed", purpose="--scheduler")
    from .. import dataset

    if args.poses in ("paper", "linear"):
        poses = args.poses
    else:
        poses = float_list(args.poses, "--poses")
    spec = dataset.make_spec(joints=args.joints, modes=args.modes, truth=args.truth,
                             law=args.law, poses=poses, starts=args.starts, seed=args.seed,
                             p=args.stations, min_half_width=args.min_half_width,
                             max_half_width=(None if args.max_half_width is None else
                                             float_list(args.max_half_width, "--max-half-width",
                                                        positive=True)),
                             thickness=(None if args.thickness is None else
                                        float_list(args.thickness, "--thickness",
                                                   positive=True)),
                             fit_batch=args.fit_batch, objective=args.objective,
                             target=args.target, family=args.family)
    previous = signal.signal(signal.SIGTERM, _sigterm)
    try:
        summary = dataset.generate(args.out, args.count, spec, workers=args.workers,
                                   scheduler=args.scheduler, part_size=args.part_size,
                                   progress=args.progress)
    except RuntimeError as exc:
        sys.stderr.write(f"prbdm dataset: error: {exc}\n")
        return 1
    finally:
        signal.signal(signal.SIGTERM, previous)
    if args.json:
        print_json(summary)
    else:
        rate = summary["beams_per_s"]
        print(f"{summary['out']}: {summary['records']} records ({summary['missing']} missing of "
              f"{summary['count']}); this run {summary['new']} new, {summary['new_errors']} "
              f"errors, {summary['wall_s']:.1f} s"
              + (f", {rate:.2f} beams/s on {summary['workers']} workers" if rate else ""))
    return 0


def _fmt(q, key, scale=1.0, digits=4):
    return "-" if q is None else f"{q[key] * scale:.{digits}g}"


def _info(args) -> int:
    require("pyarrow", purpose="prbdm dataset")
    from .. import dataset

    s = dataset.info(args.dir)
    if args.json:
        print_json(s)
        return 0
    spec = s["spec"]
    print(f"{s['dir']}: joints {spec['joints']}, modes {spec['modes']}, truth {spec['truth']} "
          f"({spec['truth_modes']} modes), law {spec['law']}, poses {spec['poses']}, "
          f"starts {spec['starts']}, seed {spec['seed']}, fit batch {spec.get('fit_batch', 1)}, "
          f"objective {s['objective']}")
    print(f"records {s['unique']} of {s['count']} ({'complete' if s['complete'] else 'incomplete'}"
          f", {s['missing']} missing, {s['duplicated']} duplicated) in {s['parts']} parts, "
          f"{s['bytes'] / 1e6:.2f} MB")
    print(f"ok {s['ok']}, errors {s['errors']}")
    for kind, n in s["error_kinds"].items():
        print(f"  {n:6d}  {kind}")
    rows = []
    for label, key in (("loss [%]", "loss_percent"),
                       ("worst-mode freq. error [%]", "frequency_percent"),
                       ("gamma spread", "gamma_spread"),
                       ("time per beam [s]", "time_per_beam_s"),
                       ("CPU per beam [s]", "cpu_per_beam_s"), ("truth time [s]", "truth_time_s"),
                       ("fit time [s]", "fit_time_s")):
        q = s[key]
        rows.append([label] + [_fmt(q, k) for k in ("mean", "median", "p95", "max")])
    print(table(rows, ["", "mean", "median", "p95", "max"]))
    for r in s["runs"]:
        state = "finished" if r["finished"] else "interrupted (or still running)"
        if r["workers"] is not None:
            where = f"{r['workers']} workers{' on ' + r['scheduler'] if r['scheduler'] else ''}"
        else:  # no workers were started: nothing to do, or a run from before they were recorded
            where = "nothing to label" if r.get("todo") == 0 else "not started"
        print(f"run {r['started']}: {r['written']} records, {r['errors']} errors, {where}, "
              f"{state}" + (f", {r['wall_s']:.1f} s" if r.get("wall_s") else ""))
    return 0
