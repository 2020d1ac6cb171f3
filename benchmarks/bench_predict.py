"""Surrogate speed: batched beams per second through the Python API, by thread count, and the
wall and CPU time of one `prbdm predict` command with its start-up.

    python benchmarks/bench_predict.py [--beams 10000] [--threads 1,2] [--repeat 3] [--members all,1]

What is timed is ``Surrogate.predict(beams)`` from a list of :class:`prbdm.Beam` to gamma, k, the
PRBDM frequencies at every pose and the truth frequencies (features, network, candidate choice,
SCF projection, eigenvalues), best of ``--repeat``; the checkpoint is loaded once before. The
machine's load average is printed beside: on a shared machine the wall rate is only as good as
the cores that are free. The command's CPU time (user + system of the child process, from
``resource.getrusage(RUSAGE_CHILDREN)``) does not depend on the load: it is the figure to compare
between versions (0.262 s median before and after prbdm/surrogate.py became a package).
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time

import numpy as np

from prbdm import random_beam
from prbdm import surrogate as sg


def rate(sur, beams, threads, repeat):
    sur.predict(beams[:200], warn=False, threads=threads)            # warm-up
    wall, cpu = [], []
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        sur.predict(beams, warn=False, threads=threads)
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return len(beams) / min(wall), len(beams) / min(cpu)


def cli_seconds(repeat):
    beam = random_beam(12345, 0)
    with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
        json.dump(beam.to_dict(), f)
    times, cpu = [], []
    for _ in range(repeat):
        t0 = time.perf_counter()
        r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        subprocess.run([sys.executable, "-m", "prbdm.cli", "predict", f.name, "--joints", "4",
                        "--json"], check=True, capture_output=True)
        r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        times.append(time.perf_counter() - t0)
        cpu.append(r1.ru_utime - r0.ru_utime + r1.ru_stime - r0.ru_stime)
    os.unlink(f.name)
    return min(times), float(np.median(times)), float(np.median(cpu))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--beams", type=int, default=10000)
    ap.add_argument("--threads", default="1,2", help="comma list (default 1,2)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--checkpoint", default=None, help="default: the shipped beam-n4")
    ap.add_argument("--members", default="all",
                    help="comma list of ensemble sizes to time (Surrogate.with_members; default: "
                         "all members)")
    a = ap.parse_args()
    full = sg.load_checkpoint(a.checkpoint or sg.default_checkpoint(4, "beam"))
    beams = [random_beam(12345, i) for i in range(a.beams)]
    print(f"checkpoint {full.name} ({full.n_members} members); {a.beams} random beams (seed "
          f"12345); {os.cpu_count()} cores")
    print(f"{'members':>7}  {'threads':>7}  {'beams/s wall':>12}  {'beams per CPU-s':>15}")
    for k in a.members.split(","):
        sur = full if k == "all" else full.with_members(int(k))
        for th in [int(t) for t in a.threads.split(",")]:
            w, c = rate(sur, beams, th, a.repeat)
            print(f"{sur.n_members:>7}  {th:>7}  {w:>12,.0f}  {c:>15,.0f}")
    best, med, cpu = cli_seconds(a.repeat)
    print(f"`prbdm predict BEAM --joints 4 --json`: {best:.2f} s wall best, {med:.2f} s median, "
          f"{cpu:.3f} s CPU median, with interpreter start-up")
    print(f"load average at the end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
