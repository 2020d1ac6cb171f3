"""A trial, not kept: do the plate's chordwise modes tell the network where its mode 4 goes wrong?

    python notes/experiments/chord_mode_trial.py --data datasets/mindlin-n4-seed1 \
        --checkpoint checkpoints/mindlin-n4.safetensors

The kept bending modes 3-4 of the paper's wide panels mix and switch with symmetric *chordwise*
modes (docs/surrogate.md, "Mode switching"), whose frequency the network's chain features do not
describe. ``chord_log_omega`` below estimates them cheaply (a one-term Kantorovich model across
the chord, about 90 us a panel, 1.5 % above the square cantilever plate's first symmetric
chordwise mode). This script bins the held-out panels by where that estimate lies relative to
the truth's mode 3 and mode 4 and prints the network's error there: were the chordwise crossing
the network's trouble, its error would gather near the crossing (log ratio near 0) and change
sign across it. The outcome (docs/surrogate.md records it) is that the error is 8-13 % in every
bin, with a drift of the signed error from about -8 % to +5 % across the bins; and a fine-tune
with these three frequencies as extra features (a temporary option, not kept) trained to the
shipped network's test numbers within noise.
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from prbdm import dataset as ds
from prbdm import surrogate as sg
from prbdm.geometry import Material
from prbdm.surrogate.features import half_width_at


def chord_log_omega(x, w, nu, modes: int, elements: int = 16) -> np.ndarray:
    """log of the nondimensional frequencies ``omega / sqrt(E t^2 / (rho L^4))`` of the lowest
    *chordwise* symmetric modes of a plate planform (x, w (B, S) in units of L, nu (B,)): (B, modes).

    The modes a plate's kept bending modes 3-4 mix and switch with are symmetric chordwise ones,
    whose frequency is set by the local width, not by the chain. A Kantorovich estimate: the
    deflection ``q(x) (eta^2 - 1/3)``, ``eta = y / w(x)`` (zero mean across the chord, so
    orthogonal to the section's translation), with the Kirchhoff energy per unit span
    ``8 q^2 / w^3`` (chordwise curvature), ``8 w q''^2 / 45`` (spanwise), ``16 (1 - nu) q'^2 /
    (3 w)`` (twist) in units of D, mass ``8 w / 45`` in units of rho t, the terms in ``w'``
    left out; q clamped at the root. On a square plate its first frequency is 1.5 % above the
    plate's first symmetric chordwise mode (Leissa's 30.95 in ``omega a^2 sqrt(rho t / D)``).
    """
    B, N = len(x), elements
    h = 1.0 / N
    gp, gw = np.polynomial.legendre.leggauss(4)
    s = 0.5 * (gp + 1.0)
    xq = ((np.arange(N)[:, None] + s) * h).ravel()
    wq = np.maximum(half_width_at(x, w, xq), 1e-4).reshape(B, N, 4)
    # Hermite cubics on an element, dofs (q0, q0', q1, q1')
    H = np.stack([1 - 3 * s**2 + 2 * s**3, h * (s - 2 * s**2 + s**3), 3 * s**2 - 2 * s**3,
                  h * (s**3 - s**2)], 1)
    dH = np.stack([6 * s**2 - 6 * s, h * (1 - 4 * s + 3 * s**2), 6 * s - 6 * s**2,
                   h * (3 * s**2 - 2 * s)], 1) / h
    ddH = np.stack([12 * s - 6, h * (6 * s - 4), 6 - 12 * s, h * (6 * s - 2)], 1) / h**2
    wts = 0.5 * h * gw

    def form(coef, A):
        return np.einsum("bng,g,gi,gj->bnij", coef, wts, A, A)

    Ke = (form(8 * wq / 45, ddH) + form(16 * (1 - nu[:, None, None]) / (3 * wq), dH)
          + form(8 / wq**3, H))
    Me = form(8 * wq / 45, H)
    K = np.zeros((B, 2 * N + 2, 2 * N + 2))
    M = np.zeros_like(K)
    for e in range(N):
        K[:, 2 * e:2 * e + 4, 2 * e:2 * e + 4] += Ke[:, e]
        M[:, 2 * e:2 * e + 4, 2 * e:2 * e + 4] += Me[:, e]
    Li = np.linalg.inv(np.linalg.cholesky(M[:, 2:, 2:]))
    lam = np.linalg.eigvalsh(Li @ K[:, 2:, 2:] @ np.swapaxes(Li, -1, -2))[:, :modes]
    return 0.5 * np.log(lam / (12.0 * (1.0 - nu[:, None] ** 2)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", required=True, help="held-out plate or Mindlin data set")
    ap.add_argument("--checkpoint", required=True, help="the network whose errors are binned")
    ap.add_argument("--bins", type=int, default=10)
    args = ap.parse_args()
    spec = ds.read_manifest(args.data)["spec"]
    tab = ds.read_table(args.data, columns=["index", "x", "half_width", "thickness",
                                            "omega_truth"], status="ok").to_pandas()
    tab = tab[~ds.refused_by_truth(tab, spec)].reset_index(drop=True)
    batch = sg.BeamBatch.from_table(tab, Material(**spec["beam"]["material"]))
    omega = np.stack(tab["omega_truth"].to_numpy())
    pred = sg.predict(batch, checkpoint=sg.load_checkpoint(args.checkpoint), frequencies=True,
                      warn=False)
    truth = np.log(omega / np.sqrt(batch.lambda0)[:, None])
    err = np.log(pred.omega_truth[:, :4] / omega[:, :4])
    t0 = time.perf_counter()
    chord = chord_log_omega(batch.x, batch.w, batch.nu, 3)
    print(f"{len(tab)} panels of {args.data}; chordwise estimate "
          f"{1e6 * (time.perf_counter() - t0) / len(tab):.0f} us a panel")
    for mode in (2, 3):
        d = chord[:, 0] - truth[:, mode]
        edges = np.percentile(d, np.linspace(0, 100, args.bins + 1))
        print(f"mode {mode + 1}: log(first chordwise estimate / truth's mode {mode + 1}), "
              "network's error median |err| and signed")
        for a, b in zip(edges[:-1], edges[1:]):
            s = (d >= a) & ((d < b) if b < edges[-1] else (d <= b))
            print(f"  {a:+.2f} .. {b:+.2f}  {s.sum():5d} panels  {100 * np.median(np.abs(err[s, mode])):6.2f} %"
                  f"  {100 * np.median(err[s, mode]):+6.2f} %")


if __name__ == "__main__":
    main()
