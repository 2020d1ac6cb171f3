"""Verification numbers of docs/export.md: exported models in MuJoCo, and the time response.

    python benchmarks/verify_export.py                 # demo panel and random beam 17, n = 3, 4
    python benchmarks/verify_export.py --joints 3,4,5 --starts 64

For each beam and n:

* ``MJCF lin``: the largest relative difference, over every pose of a paper-pose fit and every
  mode, between the MJCF's linearised frequencies (``mujoco.mj_fullM`` at the spring reference,
  ``jnt_stiffness`` from the model) and the PRBDM's at that pose;
* ``MuJoCo f1``: free vibration in MuJoCo (pose 0, gravity off, no damping, RK4 with 200 steps per
  period of the highest mode, 1e-4 rad in the first linear mode, 10 periods): relative error of
  the first frequency measured by zero crossings against the prediction;
* ``URDF M``: the URDF loaded by MuJoCo's URDF importer against the MJCF, mass matrices at a
  random pose (largest relative difference);
* ``sim T1`` and ``fit f1 err``: ``prbdm.simulate.simulate`` of a linear-pose fit, tip deflection
  1e-3 L, 20 periods: relative difference of the first-mode periods of the nonlinear PRBDM and
  the Euler-Bernoulli modal superposition, and the fit's own first-mode frequency error;
  ``truths f1``: the first-frequency difference between the truth the fit used (prbdm.truth's
  beam model, default mesh) and the simulation's modal model (part of the period budget);
  ``paper T1``: the same for the paper-pose fit (pose 0's SCF, springs at rest straight), whose
  SCF was fitted for deflected poses.

    python benchmarks/verify_export.py --necked                  # issue 19 item 1, n = 2..5

``--necked``: the README's recipe on issue 19's necked aluminium panel, run as a user runs it
(``prbdm fit panel.json --joints N --json > fit.json``, then ``prbdm export`` / ``prbdm simulate
--from fit.json``, each a fresh process), before and after the checks of :mod:`prbdm.preflight`:

* before (what the commands did by default until then; reproduced with the library's explicit
  pose): ``export`` wrote pose 0 of the paper-pose fit with springs at rest at that pose
  (``old f1``: MuJoCo's linearised first frequency against the fit's truth; ``old worst f1``: the
  worst over every pose and both spring references); ``simulate`` ran pose 0's SCF about the
  straight panel (``old T1``: its period error against the truth's modal superposition);
* after (the commands' defaults now, ``--pose rest``): ``f1``, ``max f``: MuJoCo's linearised
  frequencies of the exported file against the fit's truth, first mode and worst mode;
  ``free f1``: a free vibration in MuJoCo (as ``MuJoCo f1`` above) against the truth;
  ``T1``: the simulate command's period error; ``check``: the command's own check
  (``max_error``), ``refit s``: the refit's wall time on this machine.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from prbdm.commands.demo import DEMO_BEAM  # noqa: E402
from prbdm.export import (  # noqa: E402
    mujoco_free_vibration,
    mujoco_linear_frequencies,
    prbdm_from_fit,
    run_fit,
    to_mjcf,
    to_urdf,
)
from prbdm.geometry import Beam, random_beam  # noqa: E402
from prbdm.simulate import simulate  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
#: issue 19's necked aluminium panel (the README recipe went wrong on it)
NECKED = {"name": "necked aluminium panel", "x": [0.0, 0.4, 0.6, 1.0],
          "half_width": [0.2, 0.03, 0.03, 0.15], "thickness": 0.02,
          "material": {"E": 69e9, "rho": 2700.0, "nu": 0.33}}


def full_mass_matrix(mujoco, xml, qpos):
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_forward(model, data)
    M = np.zeros((model.nv, model.nv))
    try:
        mujoco.mj_fullM(model, data, M)
    except TypeError:
        mujoco.mj_fullM(model, M, data.qM)
    return M


def prbdm(*argv, stdout=None) -> str:
    """Run ``prbdm ARGV`` in a fresh process from this checkout; its stdout (to a file if given)."""
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    res = subprocess.run([sys.executable, "-m", "prbdm.cli", *map(str, argv)], env=env,
                         stdout=stdout or subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         check=False)
    if res.returncode != 0:
        raise SystemExit(f"prbdm {' '.join(map(str, argv))}: exit {res.returncode}\n{res.stderr}")
    return res.stdout


def linearised(mujoco, xml: str, desc_omega) -> np.ndarray:
    """MuJoCo's small-vibration frequencies of an MJCF about its rest keyframe (mass matrix from
    mj_fullM); without mujoco the description's own."""
    if mujoco is None:
        return np.asarray(desc_omega, float)
    return mujoco_linear_frequencies(xml)[0]


def necked(mujoco, joints):
    """Before/after table of the README recipe on the necked panel (module docstring)."""
    beam = Beam.from_dict(NECKED)
    header = ("n", "old f1", "old worst f1", "old T1", "f1", "max f", "free f1", "T1", "check",
              "refit s")
    print(" | ".join(header))
    with tempfile.TemporaryDirectory() as tmp:
        panel = os.path.join(tmp, "panel.json")
        with open(panel, "w") as f:
            json.dump(NECKED, f)
        for n in joints:
            fit_path = os.path.join(tmp, f"fit{n}.json")
            with open(fit_path, "w") as f:
                prbdm("fit", panel, "--joints", n, "--json", stdout=f)
            with open(fit_path) as f:
                fit = json.load(f)
            truth = np.asarray(fit["omega_truth"])
            r = fit["modes"]
            # before: the old defaults, through the library's explicit pose
            old = prbdm_from_fit(beam, fit, pose=0)
            old_f1 = linearised(mujoco, to_mjcf(old), old["omega"])[0] / truth[0] - 1
            worst = 0.0
            for i in range(len(fit["k"])):
                for ref in ("pose", "zero"):
                    d = prbdm_from_fit(beam, fit, pose=i, springref=ref)
                    w = linearised(mujoco, to_mjcf(d), d["omega"])[0] / truth[0] - 1
                    worst = w if abs(w) > abs(worst) else worst
            old_T1 = simulate(beam, fit, pose=0).info["period_error"]
            # after: the commands as a user runs them
            xml = os.path.join(tmp, f"panel{n}.xml")
            rep = json.loads(prbdm("export", panel, "--from", fit_path, "-o", xml, "--json"))
            with open(xml) as f:
                text = f.read()
            w = linearised(mujoco, text, rep["omega"])
            err = w[:r] / truth[:r] - 1
            if mujoco is not None:
                _, _, measured, _ = mujoco_free_vibration(text)
                free = f"{measured / truth[0] - 1:+.1e}"
            else:
                free = "-"
            sim = json.loads(prbdm("simulate", panel, "--from", fit_path, "--json"))
            refit = rep["refit"]
            cells = [str(n), f"{old_f1:+.1%}", f"{worst:+.1%}", f"{old_T1:.1%}",
                     f"{err[0]:+.1e}", f"{np.abs(err).max():.1e}", free,
                     f"{sim['period_error']:.1e}", f"{rep['check']['max_error']:.1e}",
                     f"{refit['time_s']:.2f}" if refit else "-"]
            print(" | ".join(cells), flush=True)
            warnings = rep["warnings"] + sim["warnings"]
            if warnings:
                print("   warnings: " + " / ".join(warnings))
    return 0


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--joints", default=None, help="default 3,4 (--necked: 2,3,4,5)")
    ap.add_argument("--starts", type=int, default=None)
    ap.add_argument("--beams", default="demo,random17")
    ap.add_argument("--necked", action="store_true",
                    help="the README recipe on issue 19's necked panel, before and after")
    args = ap.parse_args(argv)
    try:
        import mujoco
    except ImportError:
        mujoco = None
        print("mujoco not installed: MuJoCo columns skipped (pip install prbdm[sim])")
    if args.necked:
        print(f"mujoco {mujoco.__version__ if mujoco else '-'}; load average "
              f"{os.getloadavg()[0]:.2f}")
        return necked(mujoco, [int(v) for v in (args.joints or "2,3,4,5").split(",")])
    args.joints = args.joints or "3,4"
    beams = {"demo": Beam.from_dict(DEMO_BEAM), "random17": random_beam(0, 17)}
    print(f"mujoco {mujoco.__version__ if mujoco else '-'}; load average "
          f"{os.getloadavg()[0]:.2f}")
    header = ("beam", "n", "MJCF lin", "MuJoCo f1", "URDF M", "sim T1", "fit f1 err",
              "truths f1", "paper T1", "paper f1 err", "s")
    print(" | ".join(header))
    rng = np.random.default_rng(0)
    for name in args.beams.split(","):
        beam = beams[name]
        for n in map(int, args.joints.split(",")):
            t0 = time.perf_counter()
            paper = run_fit(beam, n, starts=args.starts)
            linear = run_fit(beam, n, poses="linear", starts=args.starts)
            cells = [name, str(n)]
            if mujoco is not None:
                worst = 0.0
                for i in range(len(paper["k"])):
                    desc = prbdm_from_fit(beam, paper, pose=i)
                    omega, _ = mujoco_linear_frequencies(to_mjcf(desc))
                    worst = max(worst, float(np.max(np.abs(omega / desc["omega"] - 1))))
                desc = prbdm_from_fit(beam, paper, pose=0)
                _, _, measured, predicted = mujoco_free_vibration(to_mjcf(desc))
                q = rng.uniform(-0.3, 0.3, n)
                Mu = full_mass_matrix(mujoco, to_urdf(desc), q)
                Mm = full_mass_matrix(mujoco, to_mjcf(desc), q)
                cells += [f"{worst:.1e}", f"{abs(measured / predicted - 1):.1e}",
                          f"{np.abs(Mu - Mm).max() / np.abs(Mm).max():.1e}"]
            else:
                cells += ["-", "-", "-"]
            sim = simulate(beam, linear).info
            sim_p = simulate(beam, paper, pose=0).info      # the old default: no refit
            fe_p = paper["freq_error"][0][0]
            cells += [f"{sim['period_error']:.1e}", f"{sim['fit_freq_error_mode1']:.1e}",
                      f"{sim['fit_truth_difference_mode1']:.1e}",
                      f"{sim_p['period_error']:.1e}", f"{fe_p:.1e}",
                      f"{time.perf_counter() - t0:.1f}"]
            print(" | ".join(cells), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
