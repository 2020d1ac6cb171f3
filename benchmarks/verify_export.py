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
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from prbdm.commands.demo import DEMO_BEAM  # noqa: E402
from prbdm.export import (mujoco_free_vibration, mujoco_linear_frequencies,  # noqa: E402
                          prbdm_from_fit, run_fit, to_mjcf, to_urdf)
from prbdm.geometry import Beam, random_beam  # noqa: E402
from prbdm.simulate import simulate  # noqa: E402


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


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--joints", default="3,4")
    ap.add_argument("--starts", type=int, default=None)
    ap.add_argument("--beams", default="demo,random17")
    args = ap.parse_args(argv)
    try:
        import mujoco
    except ImportError:
        mujoco = None
        print("mujoco not installed: MuJoCo columns skipped (pip install prbdm[sim])")
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
            sim_p = simulate(beam, paper).info
            fe_p = paper["freq_error"][0][0]
            cells += [f"{sim['period_error']:.1e}", f"{sim['fit_freq_error_mode1']:.1e}",
                      f"{sim['fit_truth_difference_mode1']:.1e}",
                      f"{sim_p['period_error']:.1e}", f"{fe_p:.1e}",
                      f"{time.perf_counter() - t0:.1f}"]
            print(" | ".join(cells), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
