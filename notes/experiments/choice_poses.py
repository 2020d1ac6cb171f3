"""Which poses to compare a network's candidate segmentations on, and what pooling networks buys.

    python notes/experiments/choice_poses.py --data data/beam-n4-seed1 \
        --checkpoints checkpoints/beam-n4.safetensors,m0.safetensors,m1.safetensors,\
m0.safetensors+m1.safetensors

For each checkpoint (``PATH@1`` uses only its first ensemble member; ``A+B`` pools
single-network checkpoints trained on the same data set into an in-memory ensemble, as
``train_surrogate.py --members=2`` does) and each choice rule — the first and last poses
(format-1 checkpoints), the two Gauss poses (:func:`prbdm.surrogate.gauss_select_poses`, the
default since format 2), all poses — the prediction runs through
:meth:`prbdm.surrogate.Surrogate.predict` and its PRBDM is re-evaluated against the data set's
truth (docs/conventions.md §3 loss, %). Printed: median and 95th percentile of the loss, the
share of beams on which the rule keeps the same candidate as the all-pose rule, and the median
loss of the best candidate with SCFs projected on the *true* frequencies (what the candidates can
reach).
"""
from __future__ import annotations

import argparse

import numpy as np

from prbdm import dataset as ds
from prbdm import surrogate as sg
from prbdm.geometry import Material


def pooled(paths: list[str]) -> sg.Surrogate:
    """One checkpoint (``PATH@K``: its first K members only), or several single networks of one
    data set pooled as an ensemble."""
    if len(paths) == 1:
        path, _, k = paths[0].partition("@")
        sur = sg.load_checkpoint(path)
        return sur.with_members(int(k)) if k else sur
    surs = [sg.load_checkpoint(p) for p in paths]
    meta = dict(surs[0].metadata)
    for s in surs[1:]:
        if s.metadata["normalisation"] != meta["normalisation"] or s.n_members != 1:
            raise SystemExit("choice_poses: pooled checkpoints must be single networks trained "
                             "on the same data set (same normalisation)")
    tensors = {}
    for j, s in enumerate(surs):
        for i, (W, b) in enumerate(s.layers):
            tensors[f"members.{j}.layers.{i}.weight"] = W
            tensors[f"members.{j}.layers.{i}.bias"] = b
    meta["network"] = {**meta["network"], "members": len(surs)}
    return sg.Surrogate(tensors, meta)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", required=True, help="data set with the beams' truth")
    ap.add_argument("--checkpoints", required=True, help="comma list; A+B pools A and B")
    args = ap.parse_args()
    spec = ds.read_manifest(args.data)["spec"]
    table = ds.read_table(args.data, columns=["index", "x", "half_width", "thickness",
                                              "omega_truth"], status="ok").to_pandas()
    table = table[~ds.refused_by_truth(table, spec)].reset_index(drop=True)   # stale labels
    batch = sg.BeamBatch.from_table(table, Material(**spec["beam"]["material"]))
    omega = np.stack(table["omega_truth"].to_numpy())
    print(f"{len(table)} beams of {args.data}")
    print(f"{'checkpoint':48s} {'choice poses':20s} {'median %':>9s} {'p95 %':>7s} "
          f"{'same as all':>11s} {'best, true k':>12s}")
    for spec_c in args.checkpoints.split(","):
        sur = pooled(spec_c.split("+"))
        r, m = sur.modes, len(sur.poses)
        lam_t = omega[:, :r] ** 2 / batch.lambda0[:, None]
        rules = [("first, last", sg.SELECT_POSES), ("Gauss", sg.gauss_select_poses(m)),
                 ("all", list(range(m)))]
        picks, rows = {}, []
        for name, poses in rules:
            sur.select_poses = poses
            pred = sur.predict(batch, warn=False)
            lam = (pred.omega / np.sqrt(batch.lambda0)[:, None, None]) ** 2
            loss = sg.loss_percent_np(lam, lam_t, r)
            picks[name] = pred.extra.get("selected", np.zeros(len(table), dtype=int))
            rows.append((name, poses, loss))
            cand = pred.extra.get("gamma_candidates", pred.gamma[:, None])
        B, H, n1 = cand.shape
        mu = sg.prbdm_eigenvalues(np.repeat(batch.x, H, 0), np.repeat(batch.w, H, 0),
                                  cand.reshape(B * H, n1), sur.poses)
        best = sg.candidate_losses(mu.reshape(B, H, m, -1)[..., :r], lam_t)[1].min(1)
        label = spec_c if len(spec_c) <= 48 else "..." + spec_c[-45:]
        for name, poses, loss in rows:
            same = np.mean(picks[name] == picks["all"])
            print(f"{label:48s} {name + ' ' + (str(poses) if len(poses) < 4 else ''):20s} "
                  f"{np.median(loss):9.4f} {np.percentile(loss, 95):7.4f} {same:11.3f} "
                  f"{np.median(best):12.4f}")


if __name__ == "__main__":
    main()
