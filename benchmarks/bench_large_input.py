"""Large planforms: `prbdm fit` on a 20-station shape, on the same shape given by 10,000 stations
(simplified, the default), and on those 10,000 stations as given (``--all-stations``).

The 20-station shape is a random beam of the paper's generator (p = 18 interior stations); the
10,000-station file samples the same piecewise-linear half-width at 10,000 stations (a uniform grid
that includes the 20 original ones), so both describe one panel. Every command simplifies a
planform of more than ``prbdm.geometry.SIMPLIFY_ABOVE`` stations to within
``SIMPLIFY_RTOL`` of its local half-width (docs/commands.md, "Large planforms").

    python benchmarks/bench_large_input.py              # n = 4, --starts 8, each case 3 times
    python benchmarks/bench_large_input.py --repeat 1 --joints 3

Each case runs ``prbdm fit BEAM --joints N --starts 8 --json`` in this process (imports warmed
first, one torch thread as the command sets) and reports the best of ``--repeat`` runs in CPU
seconds (``time.process_time``: fair on a loaded machine) and wall seconds, the stations used, and
the truth frequency and fit differences against the 20-station case.
"""
from __future__ import annotations

import argparse
import contextlib
import io
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from prbdm import cli
from prbdm.geometry import Beam, random_beam

STATIONS = 10_000


def run_fit(path: Path, joints: int, starts: int, extra=()) -> tuple[dict, float, float]:
    """(JSON output, CPU s, wall s) of one `prbdm fit` run in this process."""
    out = io.StringIO()
    err = io.StringIO()
    c0, t0 = time.process_time(), time.perf_counter()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = cli.main(["fit", str(path), "--joints", str(joints), "--starts", str(starts),
                       "--json", *extra])
    cpu, wall = time.process_time() - c0, time.perf_counter() - t0
    if rc != 0:
        raise SystemExit(f"prbdm fit failed ({rc}): {err.getvalue().strip()}")
    return json.loads(out.getvalue()), cpu, wall


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--joints", type=int, default=4)
    ap.add_argument("--starts", type=int, default=8)
    ap.add_argument("--repeat", type=int, default=3, help="runs per case; the best is reported")
    ap.add_argument("--seed", type=int, default=2019, help="random-beam stream of the shape")
    args = ap.parse_args(argv)

    small = random_beam(args.seed, 0, p=18)
    x = np.union1d(np.linspace(0.0, small.length, STATIONS - small.x.size + 2), small.x)
    big = Beam(x=x, half_width=np.interp(x, small.x, small.half_width),
               thickness=small.thickness, material=small.material, name="resampled")
    with tempfile.TemporaryDirectory() as tmp:
        p_small, p_big = Path(tmp) / "small.json", Path(tmp) / "big.json"
        small.to_json(p_small)
        big.to_json(p_big)
        run_fit(p_small, args.joints, args.starts)           # warm the imports
        cases = [(f"{small.x.size} stations", p_small, ()),
                 (f"{big.x.size} stations, simplified", p_big, ()),
                 (f"{big.x.size} stations, --all-stations", p_big, ("--all-stations",))]
        rows = []
        for label, path, extra in cases:
            best = None
            for _ in range(args.repeat):
                out, cpu, wall = run_fit(path, args.joints, args.starts, extra)
                if best is None or cpu < best[1]:
                    best = (out, cpu, wall)
            rows.append((label, *best))
    ref = np.asarray(rows[0][1]["omega_truth"])
    print(f"prbdm fit --joints {args.joints} --starts {args.starts}, best of {args.repeat}; "
          f"shape: random_beam({args.seed}, 0, p=18)")
    print(f"{'case':38s} {'stations used':>13s} {'CPU s':>7s} {'wall s':>7s} "
          f"{'truth vs 20':>11s} {'loss %':>9s}")
    for label, out, cpu, wall in rows:
        simp = out["input"]["simplified"]
        used = simp["stations_out"] if simp else out["input"]["stations"]
        d_truth = float(np.max(np.abs(np.asarray(out["omega_truth"]) / ref - 1)))
        print(f"{label:38s} {used:13d} {cpu:7.2f} {wall:7.2f} {d_truth:11.1e} "
              f"{out['loss_percent']:9.4f}")
        if simp:
            print(f"{'':38s} simplified: max deviation {simp['max_deviation']:.1e} of the local "
                  f"half-width (tolerance {simp['rtol']:g})")


if __name__ == "__main__":
    main()
