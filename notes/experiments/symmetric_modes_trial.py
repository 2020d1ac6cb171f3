"""Trial (not kept): learn every symmetric plate mode and apply the truth's section rule.

    python notes/experiments/symmetric_modes_trial.py --wide 2000 --narrow 4500 --workers 2

The plate truth keeps a symmetric mode as a bending mode when its section fraction is at least
1/2 (:mod:`prbdm.truth.modes`), so its modes 3-4 jump where a chordwise mode takes a bending
mode's place, and a network regressing them directly is 3-10 % off (docs/surrogate.md §5). The
ascending symmetric eigenvalues and their section fractions are continuous in the planform
instead. This trial labels the first ``--wide`` panels of ``datasets/plate-n4-truth`` and the
first ``--narrow`` of ``datasets/plate-n4-narrow`` with their first 12 symmetric modes (each
panel's kept modes checked against the stored truth to 1e-3; panels the plate now refuses are
left out), trains an MLP on plate-n4's features to predict the 12 log frequencies (median
regression on the load-spread chain's estimate) and fractions (cross-entropy), applies the
section rule to its outputs and measures the kept frequencies on the held-out
``datasets/plate-n4-seed1``. First it measures the rule's sensitivity with the held-out panels'
exact modes: noise of ``s`` on the log frequencies and ``f`` on the fractions.
"""
from __future__ import annotations

import argparse
import sys
import time
import warnings

import numpy as np

S = 12                      # symmetric modes per panel


def _label(job):
    data, index = job
    from prbdm import dataset as ds
    from prbdm.truth import bending_frequencies

    warnings.simplefilter("ignore")
    spec = ds.read_manifest(data)["spec"]
    res = bending_frequencies(ds.beam_for(spec, int(index)), "plate", spec["truth_modes"])
    sym = [e for e in res.all_modes if e["symmetry"] == "symmetric"][:S]
    return (np.array([e["lambda"] for e in sym]), np.array([e["section_fraction"] for e in sym]),
            np.asarray(res.omega))


def load(data, count, workers, fspec):
    """Features, exact log frequencies (S), fractions (S) and stored kept log frequencies (4)."""
    from prbdm import dataset as ds
    from prbdm import surrogate as sg

    spec = ds.read_manifest(data)["spec"]
    t = ds.read_table(data, columns=["index", "x", "half_width", "thickness", "length",
                                     "omega_truth"], status="ok").to_pandas()
    t = t.sort_values("index").reset_index(drop=True)
    t = t[~ds.refused_by_truth(t, spec)].head(count).reset_index(drop=True)
    jobs = [(data, i) for i in t["index"]]
    if workers > 1:
        import multiprocessing
        with multiprocessing.get_context("spawn").Pool(workers) as pool:
            out = pool.map(_label, jobs, chunksize=16)
    else:
        out = [_label(j) for j in jobs]
    stored = np.stack(t["omega_truth"].to_numpy())
    ok = np.array([len(lam) == S and np.allclose(om, st, rtol=1e-3)
                   for (lam, _, om), st in zip(out, stored)])
    t = t[ok].reset_index(drop=True)
    lam = np.stack([o[0] for o, k in zip(out, ok) if k])
    frac = np.stack([o[1] for o, k in zip(out, ok) if k])
    batch = sg.BeamBatch.from_table(t, spec["beam"]["material"])
    nu = spec["beam"]["material"]["nu"]
    # the network's frequency unit: omega / sqrt(E t^2 / (rho L^4)) = sqrt(lambda / (12 (1 - nu^2)))
    logw = 0.5 * np.log(lam) - 0.5 * np.log(12 * (1 - nu ** 2))
    kept = np.log(np.stack(t["omega_truth"].to_numpy())[:, :4] / np.sqrt(batch.lambda0)[:, None])
    print(f"{data}: {len(t)} panels labelled ({int((~ok).sum())} left out: fewer than {S} "
          "symmetric modes or not reproduced)", flush=True)
    return sg.features(batch, fspec), logw, frac, kept


def rule(logw, frac, r=4):
    """The truth's section rule on predicted modes: the kept log frequencies (B, r)."""
    from prbdm.truth.modes import select_bending
    out = np.empty((len(logw), r))
    for i in range(len(logw)):
        kept, _ = select_bending(np.zeros(S), frac[i], r)
        out[i] = np.sort(logw[i][kept])[:r]
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--wide", type=int, default=2000)
    ap.add_argument("--narrow", type=int, default=4500)
    ap.add_argument("--held_out", type=int, default=1000)
    ap.add_argument("--epochs", type=int, default=60)
    ap.add_argument("--workers", type=int, default=1)
    a = ap.parse_args(argv)

    import torch

    from prbdm import surrogate as sg

    torch.manual_seed(0)
    torch.set_num_threads(1)
    t0 = time.perf_counter()
    fspec = sg.load_checkpoint("checkpoints/plate-n4.safetensors").feature_spec
    fh, lh, frh, kh = load("datasets/plate-n4-seed1", a.held_out, a.workers, fspec)
    rng = np.random.default_rng(0)
    print("sensitivity of the rule (held-out panels' exact modes plus noise): kept-mode error "
          "median [%] per mode 1-4, p90")
    for s, f in [(0.005, 0.0), (0.0, 0.05), (0.005, 0.05), (0.005, 0.1)]:
        k = rule(lh + rng.normal(0, s, lh.shape), np.clip(frh + rng.normal(0, f, frh.shape), 0, 1))
        e = 100 * np.abs(np.expm1(k - kh))
        print(f"  s = {s:.3f}, f = {f:.2f}: {np.round(np.median(e, 0), 2)}, p90 "
              f"{np.round(np.percentile(e, 90, 0), 1)}")
    parts = [load("datasets/plate-n4-truth", a.wide, a.workers, fspec),
             load("datasets/plate-n4-narrow", a.narrow, a.workers, fspec)]
    f, lw, fr = (np.concatenate([p[i] for p in parts]) for i in range(3))
    base = fspec.base_columns(fspec.rfe_modes)
    cols = [base.start + min(j, fspec.rfe_modes - 1) for j in range(S)]
    y = lw - f[:, cols]
    fm, fs, ym, ys = f.mean(0), f.std(0) + 1e-6, y.mean(0), y.std(0) + 1e-6
    X = torch.tensor((f - fm) / fs, dtype=torch.float32)
    Y = torch.tensor((y - ym) / ys, dtype=torch.float32)
    FR = torch.tensor(fr, dtype=torch.float32)
    Xh = torch.tensor((fh - fm) / fs, dtype=torch.float32)
    W = 256
    net = torch.nn.Sequential(torch.nn.Linear(X.shape[1], W), torch.nn.SiLU(),
                              torch.nn.Linear(W, W), torch.nn.SiLU(), torch.nn.Linear(W, W),
                              torch.nn.SiLU(), torch.nn.Linear(W, 2 * S))
    opt = torch.optim.AdamW(net.parameters(), lr=2e-3, weight_decay=1e-5)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, T_max=a.epochs)
    for _epoch in range(a.epochs):
        perm = torch.randperm(len(X))
        for i in range(0, len(X), 128):
            r = perm[i:i + 128]
            o = net(X[r])
            loss = ((o[:, :S] - Y[r]).abs().mean() + 5 * torch.nn.functional.
                    binary_cross_entropy_with_logits(o[:, S:], FR[r]))
            opt.zero_grad()
            loss.backward()
            opt.step()
        sched.step()
    with torch.no_grad():
        o = net(Xh).numpy()
    lp = o[:, :S] * ys + ym + fh[:, cols]
    fp = 1 / (1 + np.exp(-o[:, S:]))
    e = 100 * np.abs(np.expm1(rule(lp, fp) - kh))
    print(f"trained on {len(X)} panels, {a.epochs} epochs; held-out {len(Xh)} panels:")
    print(f"  symmetric modes 1-8, log-frequency error median [%]: "
          f"{np.round(100 * np.median(np.abs(np.expm1(lp - lh)), 0)[:8], 2)}")
    print(f"  section fractions 1-8, absolute error median: "
          f"{np.round(np.median(np.abs(fp - frh), 0)[:8], 3)}")
    print(f"  kept (bending) modes 1-4 by the rule, error median [%]: "
          f"{np.round(np.median(e, 0), 2)}, p90 {np.round(np.percentile(e, 90, 0), 1)}")
    print(f"({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    sys.exit(main())
