"""``prbdm demo``: the whole pipeline on a built-in tapered steel panel, in a few seconds.

Truth frequencies from the truth ``prbdm fit`` takes for this panel (``--truth auto``: 0.4 L wide
and 0.02 L thick, the shear-deformable plate), the classical rigid-finite-element chain (equal
links, k = 1, no fit) for reference, then the optimised 4R-PRBDM twice, side by side: minimising
the paper's eigenvalue loss and the frequency objective (every mode right); prints all against the
truth.
"""
from __future__ import annotations

import math
import time

from ._common import print_json, table

#: a tapered, waisted steel panel (SI units)
DEMO_BEAM = {"name": "demo: tapered steel panel",
             "x": [0.0, 0.3, 0.55, 1.0], "half_width": [0.2, 0.12, 0.14, 0.05],
             "thickness": 0.02, "material": {"E": 205e9, "rho": 7850, "nu": 0.28}}


def add_arguments(parser):
    parser.add_argument("--joints", "-n", type=int, default=4, choices=range(1, 11),
                        metavar="N", help="joints of the fitted PRBDM (1..10, default 4)")
    parser.add_argument("--json", action="store_true", help="print one JSON object on stdout")


def run(args) -> int:
    from ..geometry import Beam
    from ..truth import bending_frequencies
    from ..truth.choice import choose_truth

    beam = Beam.from_dict(DEMO_BEAM)
    n = args.joints
    # the truth this panel needs, as `prbdm fit` takes it; every number below is against it
    model, reason = choose_truth(beam, "auto")
    truth = bending_frequencies(beam, model=model, modes=n)

    import torch

    # one process, small batched problems: one thread is fastest (docs/conventions.md §6, "Threads")
    torch.set_num_threads(1)

    from ..fit import fit_prbdm
    from ..model import eigenvalues, frequency_errors, loss_percent, uniform_gamma

    t0 = time.perf_counter()
    with torch.no_grad():
        lam_rfe = eigenvalues(beam, uniform_gamma(n), None, "paper")
        om_t = torch.as_tensor(truth.omega)
        rfe_loss = float(loss_percent(lam_rfe, om_t ** 2))
        rfe_err = frequency_errors(lam_rfe, om_t).amax(0)
    t_rfe = time.perf_counter() - t0
    fit = fit_prbdm(beam, truth.omega, joints=n)
    ffit = fit_prbdm(beam, truth.omega, joints=n, objective="frequency")
    if args.json:
        print_json({"beam": DEMO_BEAM, "truth": {**truth.to_dict(), "reason": reason},
                    "uniform_chain": {"loss_percent": rfe_loss,
                                      "max_freq_error": rfe_err.tolist(), "time_s": t_rfe},
                    "fit": fit.to_dict(), "fit_frequency": ffit.to_dict()})
        return 0
    print(f"{beam.name}: L = {beam.length} m, t = {beam.thickness * 1e3:g} mm, "
          f"mass {beam.mass:.2f} kg")
    print(f"truth: {truth.model} FEM, {truth.time_s * 1e3:.1f} ms ({reason})\n")
    rows = []
    fe, ffe = fit.freq_error.max(0), ffit.freq_error.max(0)
    for j in range(n):
        rows.append([j + 1, f"{truth.omega[j] / (2 * math.pi):.4g}",
                     f"{math.sqrt(lam_rfe[0, j]) / (2 * math.pi):.4g}", f"{100 * rfe_err[j]:.3f}",
                     f"{fit.omega[0][j] / (2 * math.pi):.4g}", f"{100 * fe[j]:.3f}",
                     f"{ffit.omega[0][j] / (2 * math.pi):.4g}", f"{100 * ffe[j]:.3f}"])
    print(table(rows, ["mode", "truth Hz", "equal-link Hz", "err %", "eigenvalue fit Hz", "err %",
                       "frequency fit Hz", "err %"]))
    print(f"\nfrequencies at the first of {len(fit.k)} paper poses; errors: worst over the poses")
    print(f"loss (Eq. 13): equal-link chain {rfe_loss:.3f} %, optimised {n}R-PRBDM "
          f"{fit.loss_percent:.4f} % ({fit.time_s:.2f} s, {fit.n_starts} starts), the frequency "
          f"fit {ffit.loss_percent:.4f} % ({ffit.time_s:.2f} s)")
    print("eigenvalue fit: gamma = " + ", ".join(f"{g:.4f}" for g in fit.gamma))
    print("frequency fit:  gamma = " + ", ".join(f"{g:.4f}" for g in ffit.gamma))
    print("\nthe eigenvalue objective is the paper's (reproduces its tables; the highest mode "
          "dominates it);\nthe frequency objective keeps every mode within the smallest worst "
          "error: use it when mode 1 matters")
    print("\nnext: prbdm fit BEAM.json --joints 4 --plot fit.png   (see the README)")
    return 0
