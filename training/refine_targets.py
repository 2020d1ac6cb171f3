"""Refined targets for the surrogate's candidates: where a few optimiser iterations take them.

    python training/refine_targets.py --checkpoint=prbdm/checkpoints/beam-n4.safetensors \
        --data=data/beam-n4-truth --out=data/beam-n4-targets.npz

For every training beam of the data set (``index % 10 < 8``, the training split of
``train_surrogate.py``), the checkpoint proposes its H candidate segmentations; each is refined
alone by ``max_iter`` iterations of the fit (:func:`prbdm.fit.fit_many` with one start,
``init_gamma``) against the beam's stored truth. The refined gamma of candidate h is the target of
candidate h in the next training round (``train_surrogate.py --targets=FILE``): each candidate is
pulled to the bottom of its own valley, so the families the candidates stand for are kept, and a
candidate that loses today can win once it sits at its optimum. (Fitted labels from a full
multistart jump between those families from beam to beam; a smooth map averages them.)

Configuration: the plain values below, overridable as ``--name=value``. The output (``.npz``,
written whole or not at all) holds ``index`` (B,), ``gamma0`` (B, H, n+1) the candidates,
``gamma`` (B, H, n+1) the refined ones, ``loss0`` / ``loss`` (B, H) their PRBDM losses [%] with
their best SCFs, and ``meta`` (JSON: this configuration, the checkpoint's and the data set's
sha256, versions, git commit, time).
"""
import ast
import hashlib
import json
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

# ------------------------------------------------------------------------------- configuration
checkpoint = "prbdm/checkpoints/beam-n4.safetensors"
data = "data/beam-n4-truth"
out = "data/beam-n4-targets.npz"
max_iter = 20                        # fit iterations from each candidate
chunk = 64                           # beams per fit_many call (x H candidates, one start each)
workers = 2                          # processes (torch one thread each)
max_index = -1                       # only records with index <= max_index (-1: all)
# -------------------------------------------------------------------------------------------


def _parse(argv):
    cfg = {k: v for k, v in globals().items()
           if not k.startswith("_") and isinstance(v, (int, float, str, bool))}
    for arg in argv:
        if not arg.startswith("--") or "=" not in arg:
            sys.exit(f"refine_targets: arguments are --name=value, got {arg!r}")
        key, val = arg[2:].split("=", 1)
        key = key.replace("-", "_")
        if key not in cfg:
            sys.exit(f"refine_targets: unknown setting {key!r}; known: {', '.join(sorted(cfg))}")
        try:
            globals()[key] = (val if isinstance(cfg[key], str)
                              else type(cfg[key])(ast.literal_eval(val)))
        except (ValueError, SyntaxError):
            sys.exit(f"refine_targets: --{key} must be a {type(cfg[key]).__name__}, got {val!r}")
    return {k: globals()[k] for k in cfg}


def _refine(job):
    """One chunk: (spec, indices, omega_truth, candidates, poses, law, r, max_iter) -> gammas,
    losses of every candidate refined alone."""
    import torch

    from prbdm import dataset as ds
    from prbdm.fit import fit_many
    torch.set_num_threads(1)
    spec, index, omega, cand, poses, law, r, iters = job
    B, H, n1 = cand.shape
    beams = [ds.beam_for(spec, int(i)) for i in index for _ in range(H)]
    res = fit_many(beams, np.repeat(omega, H, 0), joints=n1 - 1, modes=r, law=law, poses=poses,
                   init_gamma=cand.reshape(B * H, 1, n1), max_iter=iters)
    return (np.stack([x.gamma for x in res]).reshape(B, H, n1),
            np.array([x.loss_percent for x in res]).reshape(B, H))


def _sha256(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def main():
    config = _parse(sys.argv[1:])
    from prbdm import dataset as ds
    from prbdm import surrogate as sg
    from prbdm.geometry import Material

    t_start = time.perf_counter()
    sur = sg.load_checkpoint(checkpoint)
    spec = ds.read_manifest(data)["spec"]
    table = ds.read_table(data, columns=["index", "x", "half_width", "thickness", "omega_truth"],
                          status="ok").to_pandas()
    keep = table["index"] % 10 < 8
    if max_index >= 0:
        keep &= table["index"] <= max_index
    table = table[keep].reset_index(drop=True)
    if len(table) == 0:
        sys.exit(f"refine_targets: no training records in {data}")
    batch = sg.BeamBatch.from_table(table, Material(**spec["beam"]["material"]))
    pred = sur.predict(batch, warn=False)
    cand = np.asarray(pred.extra.get("gamma_candidates", pred.gamma[:, None, :]))
    omega = np.stack(table["omega_truth"].to_numpy())
    index = table["index"].to_numpy()
    poses, law, r = sur.poses.tolist(), sur.law, sur.modes
    jobs = [(spec, index[i:i + chunk], omega[i:i + chunk], cand[i:i + chunk], poses, law, r,
             max_iter) for i in range(0, len(index), chunk)]
    gam, loss = [], []
    with ProcessPoolExecutor(max_workers=max(1, workers)) as pool:
        for done, (g, l) in enumerate(pool.map(_refine, jobs), 1):
            gam.append(g)
            loss.append(l)
            if done % 20 == 0 or done == len(jobs):
                print(f"refine_targets: {done}/{len(jobs)} chunks, "
                      f"{time.perf_counter() - t_start:.0f} s", flush=True)
    gam, loss = np.concatenate(gam), np.concatenate(loss)
    # the candidates' own losses with their best SCFs (the refinement's starting point)
    B, H, n1 = cand.shape
    mu = sg.prbdm_eigenvalues(np.repeat(batch.x, H, 0), np.repeat(batch.w, H, 0),
                              cand.reshape(B * H, n1), sur.poses).reshape(B, H, -1, n1 - 1)
    lam_hat = omega[:, :r] ** 2 / batch.lambda0[:, None]
    _, loss0 = sg._candidate_losses(mu[..., :r], lam_hat)
    meta = {"config": config, "checkpoint_sha256": _sha256(checkpoint),
            "dataset_spec": spec,
            "dataset_sha256": sg.dataset_hash(ds.read_table(
                data, columns=["index", "x", "half_width", "thickness", "omega_truth", "gamma",
                               "k"], status="ok").to_pandas()),
            "beams": int(len(index)), "candidates": int(cand.shape[1]),
            "versions": ds._versions(), "git_commit": ds._git_commit(),
            "time_s": time.perf_counter() - t_start}
    out_path = Path(out)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    tmp = out_path.with_name(out_path.name + ".partial.npz")
    np.savez(tmp, index=index, gamma0=cand, gamma=gam, loss0=np.asarray(loss0), loss=loss,
             meta=np.array(json.dumps(meta)))
    os.replace(tmp, out_path)
    print(f"refine_targets: {len(index)} beams x {cand.shape[1]} candidates, {max_iter} "
          f"iterations: best-candidate loss median {np.median(np.min(loss0, 1)):.4f} % -> "
          f"{np.median(loss.min(1)):.4f} %; {meta['time_s']:.0f} s -> {out_path}")


if __name__ == "__main__":
    main()
