"""Fits whose results are recorded in tests/data/fit_reference.json: tests/test_fit.py checks that
the optimiser still reaches at least the recorded optimum of each (a property, not the bits).
Regenerate only on purpose: ``PYTHONPATH=. python tests/fit_reference_cases.py``."""
import json
import sys
from pathlib import Path

import numpy as np
import torch

from prbdm.fit import FitProblem, StopRules, fit_many
from prbdm.geometry import random_beam
from prbdm.model import eigenvalues, uniform_gamma

REFERENCE = Path(__file__).with_name("data") / "fit_reference.json"


def _truth(beam):
    """A cheap truth (60-link rigid-finite-element chain): any fixed numbers do here."""
    with torch.no_grad():
        return eigenvalues(beam, uniform_gamma(60), None, "linear")[0, :5].sqrt().numpy()


def _record(result):
    """Every number of a result that the optimiser decides, as exact hexadecimal floats."""
    def hexs(a):
        return [float(v).hex() for v in np.ravel(a)]
    return {"gamma": hexs(result.gamma), "k": hexs(result.k), "omega": hexs(result.omega),
            "loss_percent": float(result.loss_percent).hex(),
            "frequency_percent": float(result.frequency_percent).hex(),
            "best_loss_percent": float(result.best_objective_percent).hex(),
            "gamma_spread": float(result.gamma_spread).hex(),
            "n_near_best": result.n_near_best, "iterations": result.iterations,
            "n_starts": result.n_starts}


def cases(**fit_kwargs):
    """{name: [record per beam]}: multistart and refinement fits, both objectives."""
    beams = [random_beam(s, 1) for s in (3, 11)]
    om = np.stack([_truth(b) for b in beams])
    out = {}
    for objective in ("eigenvalue", "frequency"):
        rs = fit_many(FitProblem(beams, om, 3, 4, objective=objective), starts=8, seed=1,
                      stop=StopRules(max_iter=40), **fit_kwargs)
        out[f"{objective}-multistart"] = [_record(r) for r in rs]
        init = np.tile(uniform_gamma(3).numpy(), (2, 2, 1)) + 0.01 * np.arange(4)
        rs = fit_many(FitProblem(beams, om, 3, 3, objective=objective), seed=[0, 1],
                      init_gamma=init, stop=StopRules(max_iter=12), **fit_kwargs)
        out[f"{objective}-refine"] = [_record(r) for r in rs]
    return out


def reference():
    return json.loads(REFERENCE.read_text())


if __name__ == "__main__":
    data = {"torch": torch.__version__, "cases": cases()}
    REFERENCE.write_text(json.dumps(data, indent=1) + "\n")
    print(f"wrote {REFERENCE}", file=sys.stderr)
