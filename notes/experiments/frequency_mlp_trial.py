"""A trial: how well can any network learn the Mindlin plate's kept modes from the planform?

    python notes/experiments/frequency_mlp_trial.py                      # 256 x 3, without / with profile
    python notes/experiments/frequency_mlp_trial.py --width 1024 --only-profile   # a network that memorises

A frequency-only MLP (no PRBDM, no physics loss), trained from scratch with the median (L1)
regression of the network's frequency head on the wide Mindlin set (``datasets/mindlin-n4-truth``,
the train split index % 10 < 8), predicts the log correction of the load-spread chain's
frequencies (the shipped networks' base, prbdm.surrogate.features) for modes 1-4. It is judged on
the validation split (index % 10 == 8) and on the held-out panels of seed 1
(``datasets/mindlin-n4-seed1``), median relative error per mode, and on 8,000 of its own training
panels. With and without the ``profile`` features (64 points): whether the planform's necks,
which the cell means blur, are what the network lacks. docs/surrogate.md §5 records the outcome.
"""
from __future__ import annotations

import argparse
import time

import numpy as np
import torch

from prbdm import dataset as ds
from prbdm import surrogate as sg
from prbdm.geometry import Material


def load(path, fspec):
    spec = ds.read_manifest(path)["spec"]
    tab = ds.read_table(path, columns=["index", "x", "half_width", "thickness", "omega_truth"],
                        status="ok").to_pandas()
    tab = tab[~ds.refused_by_truth(tab, spec)].reset_index(drop=True)
    batch = sg.BeamBatch.from_table(tab, Material(**spec["beam"]["material"]))
    omega = np.stack(tab["omega_truth"].to_numpy())[:, :4]
    log_omega_hat = np.log(omega / np.sqrt(batch.lambda0)[:, None])
    feats = sg.features(batch, fspec)
    return tab["index"].to_numpy(), feats, log_omega_hat - feats[:, fspec.base_columns(4)]


def train(X, C, XH, CH, idx, width, epochs, label, seed=0):
    train_, val = idx % 10 < 8, idx % 10 == 8
    torch.manual_seed(seed)
    mu, sd = X[train_].mean(0), np.maximum(X[train_].std(0), 1e-6)
    cm, cs = C[train_].mean(0), C[train_].std(0)

    def t(a):
        return torch.as_tensor(a, dtype=torch.float32)

    Xn, Yn, XHn = t((X - mu) / sd), t((C - cm) / cs), t((XH - mu) / sd)
    layers, d = [], X.shape[1]
    for _ in range(3):
        layers += [torch.nn.Linear(d, width), torch.nn.SiLU()]
        d = width
    net = torch.nn.Sequential(*layers, torch.nn.Linear(d, 4))
    opt = torch.optim.AdamW(net.parameters(), 2e-3, weight_decay=1e-5)
    tri = np.flatnonzero(train_)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, 2e-3, total_steps=epochs * (len(tri) // 256 + 1))
    vi, ti = torch.as_tensor(np.flatnonzero(val)), torch.as_tensor(tri[:8000])
    t0 = time.perf_counter()
    for ep in range(epochs):
        perm = torch.as_tensor(np.random.default_rng(ep + 100 * seed).permutation(tri))
        for s in range(0, len(perm), 256):
            b = perm[s:s + 256]
            loss = (net(Xn[b]) - Yn[b]).abs().mean()
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
        if (ep + 1) % 10 == 0 or ep + 1 == epochs:
            with torch.no_grad():
                def err(rows):
                    return 100 * np.median(np.abs(np.expm1((net(Xn[rows]) - Yn[rows]).numpy() * cs)), 0)
                eh = 100 * np.median(np.abs(np.expm1(net(XHn).numpy() * cs + cm - CH)), 0)
                print(f"  {label:18s} epoch {ep + 1:3d} {time.perf_counter() - t0:5.0f} s  median error "
                      f"modes 1-4 [%]: validation {np.round(err(vi), 2)}  held-out {np.round(eh, 2)}"
                      f"  own training panels {np.round(err(ti), 2)}", flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", default="datasets/mindlin-n4-truth")
    ap.add_argument("--heldout", default="datasets/mindlin-n4-seed1")
    ap.add_argument("--points", type=int, default=64, help="profile points")
    ap.add_argument("--width", type=int, default=256, help="hidden units (3 layers)")
    ap.add_argument("--epochs", type=int, default=60)
    ap.add_argument("--only-profile", action="store_true", help="skip the run without profile")
    args = ap.parse_args()
    torch.set_num_threads(2)
    fspec = sg.FeatureSpec(cells=16, rfe_segments=96, rfe_modes=5, truth="mindlin",
                           rfe_coarse=16, spread=True, profile=args.points)
    t0 = time.perf_counter()
    idx, X, C = load(args.data, fspec)
    _, XH, CH = load(args.heldout, fspec)
    plain = len(sg.feature_names(sg.FeatureSpec(**{**fspec.to_dict(), "profile": 0})))
    print(f"{len(idx)} panels of {args.data}, {len(XH)} of {args.heldout}; {X.shape[1]} features "
          f"({plain} without the profile) in {time.perf_counter() - t0:.0f} s")
    print("the load-spread chain alone, held-out median error modes 1-4 [%]:",
          np.round(100 * np.median(np.abs(np.expm1(-CH)), 0), 2))
    if not args.only_profile:
        train(X[:, :plain], C, XH[:, :plain], CH, idx, args.width, args.epochs, "features")
    train(X, C, XH, CH, idx, args.width, args.epochs, f"+ profile {args.points}")


if __name__ == "__main__":
    main()
