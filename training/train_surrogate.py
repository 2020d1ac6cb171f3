"""Train the PRBDM surrogate: from a data set folder to a checkpoint.

One script, read top to bottom (nanoGPT style). Configuration is the plain values just below;
override any of them on the command line as ``--name=value``:

    python training/train_surrogate.py --data=/work/data/beam-n4 \
        --out=checkpoints/beam-n4.safetensors

What it does:

1. reads the data set (``status == 'ok'`` records with ``index <= max_index``) and computes the
   features (:func:`prbdm.surrogate.features`) and the targets: gamma, log k, and the correction
   ``log omega_hat - log_omega_rfe`` of the truth frequencies;
2. splits by beam index: ``index % 10 == 9`` test, ``== 8`` validation, the rest training;
3. trains one network per training mode, each from the same seed:
   - ``label``: mean squared error of (gamma, log k, frequency correction), standardised;
   - ``physics``: the PRBDM loss of SPEC §3 (Eq. 12-13, in percent) of the predicted (gamma, k)
     against the stored truth frequencies, through the differentiable :mod:`prbdm.model`; the
     frequency head keeps its label term (the truth frequencies are its only supervision);
   - ``combined``: label loss + ``phys_weight`` * physics loss;
   with AdamW, the learning rate halved when the validation PRBDM loss stalls, and early stopping
   on it (the best epoch's weights are kept);
4. keeps the mode with the lowest validation PRBDM loss (mean or median, ``select``), and records all modes' validation
   metrics in the checkpoint metadata;
5. writes the checkpoint, loads it back through :func:`prbdm.surrogate.load_checkpoint` (the
   NumPy inference path that ``prbdm predict`` uses) and measures it on the test split: the
   re-evaluated PRBDM loss (median, p95) beside the optimised fits' on the same beams, and the
   per-mode error of the direct truth-frequency prediction; these go into the metadata too.

A log goes to stdout and to ``OUT`` with the suffix ``.log``.
"""
import ast
import datetime as dt
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

# ------------------------------------------------------------------------------- configuration
data = "/work/data/beam-n4"          # data set folder (prbdm.dataset format)
out = "checkpoints/beam-n4.safetensors"
modes = "label,physics,combined"     # training modes to compare, comma-separated
seed = 0                             # torch seed of every mode (weights init and batch order)
max_index = -1                       # use records with index <= max_index (-1: all present)
width = 256                          # hidden units per layer
depth = 3                            # hidden layers
k_mode = "projection"                # SCFs: 'projection' (least squares against the predicted
                                     # truth frequencies) or 'direct' (log k regressed)
hypotheses = 4                       # candidate segmentations per beam; the one whose PRBDM best
                                     # matches the predicted truth frequencies is kept
members = 1                          # networks trained side by side, member j from seed + j, in
                                     # parallel processes (one per member): an ensemble whose
                                     # candidates are pooled (prbdm.surrogate.combine_members)
wta_eps = 0.05                       # candidates' losses: (1 - eps) * best + eps * mean
init_gamma = ""                      # start of candidate 0, comma-separated n+1 values (default:
                                     # the mean fitted label; equal links for a truth-only set)
batch_size = 128
lr = 2e-3
weight_decay = 1e-5
max_epochs = 400
patience = 80                        # epochs without a better validation loss before stopping
lr_patience = 20                     # epochs without improvement before halving the lr
lr_schedule = "plateau"              # plateau: halve after lr_patience epochs without a better
                                     # validation loss; cosine: lr * (1 + cos(pi e / max_epochs)) / 2
                                     # at epoch e, the same for every run of the same length
max_minutes = 9.0                    # wall-clock limit per mode
phys_weight = 1.0                    # combined mode: label + phys_weight * physics [%]
freq_weight = 1.0                    # weight of the frequency head's label term
vp_weight = 1.0                      # physics: + vp_weight * the loss of the predicted gamma with
                                     # its best SCFs (variable projection on the truth, as the fit)
loss_power = 1.0                     # physics: each beam's loss L [%] enters as L**p / p (p = 1: the
                                     # mean loss; p = 0: log L, every beam's relative improvement
                                     # counts alike, which moves the median rather than the tail)
select = "mean"                      # validation statistic of the PRBDM loss that drives the lr
                                     # schedule, early stopping and the choice of mode: mean, median
cells = 16                           # feature cells along x / L
rfe_segments = 96                    # links of the rigid-finite-element frequency estimate
rfe_coarse = 16                      # > 0: that estimate by Rayleigh-Ritz from a chain of this
                                     # many links (cheap; see prbdm.surrogate.rfe_log_omega)
threads = 1                          # torch threads
quiet = False                        # only the summary lines
# -------------------------------------------------------------------------------------------


def _fail(message):
    """Bad input: one line on stderr, exit status 2 (as the prbdm commands)."""
    print(message, file=sys.stderr)
    sys.exit(2)


def _parse_overrides(argv):
    cfg = {k: v for k, v in globals().items()
           if not k.startswith("_") and isinstance(v, (int, float, str, bool))}
    for arg in argv:
        if not arg.startswith("--") or "=" not in arg:
            _fail(f"train_surrogate: arguments are --name=value, got {arg!r}")
        key, val = arg[2:].split("=", 1)
        key = key.replace("-", "_")
        if key not in cfg:
            _fail(f"train_surrogate: unknown setting {key!r}; known: {', '.join(sorted(cfg))}")
        default = cfg[key]
        if isinstance(default, bool):
            new = val.lower() in ("1", "true", "yes", "on")
        elif isinstance(default, str):
            new = val
        else:
            try:
                new = type(default)(ast.literal_eval(val))
            except (ValueError, SyntaxError):
                _fail(f"train_surrogate: --{key} must be a {type(default).__name__}, got {val!r}")
        globals()[key] = new
    return {k: globals()[k] for k in cfg}


config = _parse_overrides(sys.argv[1:])
if select not in ("mean", "median"):
    _fail(f"train_surrogate: --select must be mean or median, got {select!r}")
if members < 1:
    _fail(f"train_surrogate: --members must be >= 1, got {members}")
if lr_schedule not in ("plateau", "cosine"):
    _fail(f"train_surrogate: --lr_schedule must be plateau or cosine, got {lr_schedule!r}")
if set(s.strip() for s in modes.split(",") if s.strip()) - {"label", "physics", "combined"}:
    _fail(f"train_surrogate: --modes: each one of label, physics, combined, got {modes!r}")

import torch  # noqa: E402  (after the configuration, as in nanoGPT)

import prbdm  # noqa: E402
from prbdm import dataset as ds  # noqa: E402
from prbdm import model  # noqa: E402
from prbdm import surrogate as sg  # noqa: E402
from prbdm.surrogate.net import SurrogateEnsemble, SurrogateNet  # noqa: E402

torch.set_num_threads(threads)
out_path = Path(out)
out_path.parent.mkdir(parents=True, exist_ok=True)
log_path = out_path.with_suffix(".log")
log_file = open(log_path, "w")
t_start = time.perf_counter()


def log(text, always=True):
    if always or not quiet:
        print(text, flush=True)
    log_file.write(text + "\n")
    log_file.flush()


log(f"# train_surrogate {dt.datetime.now(dt.timezone.utc).isoformat(timespec='seconds')}")
log("config " + json.dumps(config))

# ------------------------------------------------------------------------------- 1. data
manifest = ds.read_manifest(data)
spec = manifest["spec"]
if spec["law"] != "beam":
    _fail(f"train_surrogate: the surrogate supports the 'beam' law only, data set has "
          f"{spec['law']!r}")
columns = ["index", "x", "half_width", "thickness", "length", "omega_truth", "gamma", "k",
           "loss_percent", "fit_time_s", "gamma_spread"]
table = ds.read_table(data, columns=columns, status="ok").to_pandas()
records_read = len(table)
if max_index < 0:
    max_index = int(table["index"].max())
table = table[table["index"] <= max_index].reset_index(drop=True)
N = len(table)
if N < 10:
    _fail(f"train_surrogate: need at least 10 ok records, found {N}")
n = spec["joints"]
r = min(n, spec["modes"])
poses = model.make_poses(spec["poses"], n)
m = poses.shape[0]
R = min(spec["truth_modes"], rfe_segments - 1)
material = spec["beam"]["material"]
fspec = sg.FeatureSpec(cells=cells, rfe_segments=rfe_segments, rfe_modes=R, truth=spec["truth"],
                       rfe_coarse=rfe_coarse)
batch = sg.BeamBatch.from_table(table, material)
feats = sg.features(batch, fspec)
names = sg.feature_names(fspec)
omega_truth = np.stack(table["omega_truth"].to_numpy())[:, :R]
log_omega_hat = np.log(omega_truth / np.sqrt(batch.lambda0)[:, None])
rfe0 = 2 * cells
# a truth-only set (``prbdm dataset generate --starts 0``) has no fitted labels: only the physics
# mode can train on it (it needs the truth frequencies alone); the label normalisation is then the
# rigid-finite-element segmentation and k = 1
labelled = spec["starts"] > 0
run_modes = [s.strip() for s in modes.split(",") if s.strip()]
if not labelled and set(run_modes) - {"physics"}:
    _fail(f"train_surrogate: --modes: the data set {data} is truth-only (starts 0, no fitted "
          f"labels); only 'physics' can train on it, got {modes!r}")
if labelled:
    y_gamma = np.stack(table["gamma"].to_numpy())
    y_logk = np.log(np.stack(table["k"].to_numpy()))
else:
    y_gamma = np.broadcast_to(sg.uniform_gamma(n), (N, n + 1)).copy()
    y_logk = np.zeros((N, m))
y_corr = log_omega_hat - feats[:, rfe0:rfe0 + R]
sha = sg.dataset_hash(table)
log(f"data {data}: {records_read} ok records, {N} with index <= {max_index}; n = {n}, "
    f"r = {r}, m = {m} poses, {R} truth modes, {len(names)} features; "
    f"{'fitted labels' if labelled else 'truth only (no fitted labels)'}; sha256 {sha[:16]}")

# ------------------------------------------------------------------------------- 2. split
idx = table["index"].to_numpy()
split = {"test": np.flatnonzero(idx % 10 == 9), "val": np.flatnonzero(idx % 10 == 8)}
split["train"] = np.flatnonzero(idx % 10 < 8)
log("split " + ", ".join(f"{k} {len(v)}" for k, v in split.items()))
tr = split["train"]
f_mean, f_std = feats[tr].mean(0), np.maximum(feats[tr].std(0), 1e-6)
norm_np = {"feature_mean": f_mean, "feature_std": f_std,
           "logk_mean": y_logk[tr].mean(0), "logk_std": np.maximum(y_logk[tr].std(0), 1e-6),
           "freq_mean": y_corr[tr].mean(0), "freq_std": np.maximum(y_corr[tr].std(0), 1e-6),
           "gamma_mean": y_gamma[tr].mean(0), "gamma_std": np.maximum(y_gamma[tr].std(0), 1e-6)}
norm = {k: torch.as_tensor(v, dtype=torch.float32) for k, v in norm_np.items()}

F = torch.as_tensor((feats - f_mean) / f_std, dtype=torch.float32)
Yg = torch.as_tensor(y_gamma, dtype=torch.float32)
Yk = torch.as_tensor(y_logk, dtype=torch.float32)
Yc = torch.as_tensor(y_corr, dtype=torch.float32)
RFE = torch.as_tensor(feats[:, rfe0:rfe0 + R], dtype=torch.float32)
BX = torch.as_tensor(batch.x)
BW = torch.as_tensor(batch.w)
lam_hat = torch.as_tensor(omega_truth[:, :r] ** 2 / batch.lambda0[:, None])


def beam_rows(rows):
    ones = torch.ones(len(rows), dtype=torch.float64)
    # nondimensional: the beam law and the unit-k eigenvalues use only x / L and w / L
    return model.BeamTensors(BX[rows], BW[rows], ones, ones, ones, ones)


def outputs(net, rows):
    """Decoded network outputs for data rows (dict, see prbdm.surrogate.decode_torch), with
    ``corr`` the predicted correction of the rigid-finite-element log frequencies."""
    d = net.outputs(F[rows], norm, RFE[rows], BX[rows], BW[rows], poses, r)
    d["corr"] = d["log_omega_hat"] - RFE[rows]
    return d


def physics_loss(rows, gamma, logk, mu=None):
    """Per-beam PRBDM loss [%] (SPEC §3) of the predicted PRBDM against the truth, float64."""
    if mu is None:
        mu = model.eigenvalues_unit_k(beam_rows(rows), gamma.double(), poses, "beam")
    lam = mu * torch.exp(logk.double())[..., None]
    return model.loss_percent(lam, lam_hat[rows], r)


def transform(loss):
    """Per-beam loss [%] as it enters the training objective (``loss_power``)."""
    if loss_power == 0:
        return torch.log(loss.clamp_min(1e-6))
    return loss.clamp_min(1e-12) ** loss_power / loss_power


def wta(values):
    """Relaxed winner-takes-all over the candidates (B, H) -> (B,)."""
    if values.shape[1] == 1:
        return values[:, 0]
    return (1 - wta_eps) * values.min(1).values + wta_eps * values.mean(1)


def vp_loss(rows, d):
    """Per-beam PRBDM loss [%] of the candidate segmentations with their best SCFs for the truth
    (the fit's own objective, SPEC §3 Eq. 13 after variable projection), relaxed min over the
    candidates: what the proposed gammas alone can reach."""
    if d["mu_all"] is None:
        mu_all = model.eigenvalues_unit_k(beam_rows(rows), d["gamma_all"].double(), poses, "beam")
    else:
        mu_all = d["mu_all"]
    _, loss = sg.candidate_losses(mu_all[..., :r], lam_hat[rows])
    return wta(loss)


def label_terms(rows, d):
    ga = d["gamma_all"]
    lg = wta((((ga - Yg[rows][:, None]) / norm["gamma_std"]) ** 2).mean(-1)).mean()
    lk = (((d["logk"].float() - Yk[rows]) / norm["logk_std"]) ** 2).mean()
    lc = (((d["corr"] - Yc[rows]) / norm["freq_std"]) ** 2).mean()
    return lg, lk, lc


@torch.no_grad()
def evaluate(net, rows):
    rows = torch.as_tensor(rows)
    net.eval()
    d = outputs(net, rows)
    phys = physics_loss(rows, d["gamma"], d["logk"], d["mu"]).numpy()
    err = np.abs(np.expm1((d["corr"] - Yc[rows]).double().numpy()))  # relative frequency error
    net.train()
    return {"loss_mean": float(phys.mean()), "loss_median": float(np.median(phys)),
            "loss_p95": float(np.percentile(phys, 95)),
            "freq_err_median": np.median(err, 0).tolist(),
            "freq_err_p95": np.percentile(err, 95, 0).tolist()}


# ------------------------------------------------------------------------------- 3. training
Net = SurrogateNet


def make_net(member=0):
    net = Net(len(names), n, m, R, width=width, depth=depth, k_mode=k_mode,
              hypotheses=hypotheses)
    with torch.no_grad():       # start near the mean label: gamma logits, standardised k, freq 0
        net.head.weight.mul_(0.1)
        net.head.bias.zero_()
        if init_gamma:
            g0 = torch.tensor([float(v) for v in init_gamma.split(",")])
            if g0.shape != (n + 1,) or not bool((g0 > sg.GAMMA_MIN).all()):
                _fail(f"train_surrogate: --init_gamma: need {n + 1} values > {sg.GAMMA_MIN}")
            g = g0 - sg.GAMMA_MIN
        elif labelled:
            g = (norm["gamma_mean"] - sg.GAMMA_MIN).clamp_min(1e-3)
        else:
            g = torch.full((n + 1,), 1.0 / (n + 1))             # no labels: equal links
        # candidates start apart: the mean label, rigid-finite-element-like, a long root link
        # (the two families of fitted optima), then random segmentations
        long_root = torch.full((n + 1,), 0.3 / n)
        long_root[0] = 0.7
        starts = [g / g.sum(), torch.as_tensor(sg.uniform_gamma(n), dtype=torch.float32),
                  long_root]
        gen0 = torch.Generator().manual_seed(seed + member + 1)
        while len(starts) < hypotheses:
            starts.append(torch.rand(n + 1, generator=gen0) + 0.2)
        for h in range(hypotheses):
            net.head.bias[h * (n + 1):(h + 1) * (n + 1)] = torch.log(starts[h] / starts[h].sum())
    return net


def train(mode, member=0):
    """Train one network from seed + member; returns it and a summary of its run."""
    torch.manual_seed(seed + member)
    np.random.seed(seed + member)
    label = mode if members == 1 else f"{mode}[{member}]"
    net = make_net(member)
    opt = torch.optim.AdamW(net.parameters(), lr=lr, weight_decay=weight_decay)
    if lr_schedule == "cosine":
        sched = torch.optim.lr_scheduler.LambdaLR(
            opt, lambda e: 0.5 * (1 + math.cos(math.pi * min(e, max_epochs) / max_epochs)))
    else:
        sched = torch.optim.lr_scheduler.ReduceLROnPlateau(opt, factor=0.5, patience=lr_patience)
    gen = torch.Generator().manual_seed(seed + member)
    train_rows = torch.as_tensor(split["train"])
    best, best_state, best_epoch, stale = math.inf, None, 0, 0
    t0 = time.perf_counter()
    epoch = 0
    for epoch in range(1, max_epochs + 1):
        perm = train_rows[torch.randperm(len(train_rows), generator=gen)]
        tot = 0.0
        for i in range(0, len(perm), batch_size):
            rows = perm[i:i + batch_size]
            d = outputs(net, rows)
            lg, lk, lc = label_terms(rows, d)
            if mode in ("physics", "combined"):
                phys = (transform(physics_loss(rows, d["gamma"], d["logk"], d["mu"])).mean()
                        + vp_weight * transform(vp_loss(rows, d)).mean()).float()
            if mode == "label":
                loss = lg + lk + freq_weight * lc
            elif mode == "physics":
                loss = phys + freq_weight * lc
            else:               # combined (the modes are checked with the configuration)
                loss = lg + lk + freq_weight * lc + phys_weight * phys
            opt.zero_grad(set_to_none=True)
            loss.backward()
            torch.nn.utils.clip_grad_norm_(net.parameters(), 10.0)
            opt.step()
            tot += float(loss.detach()) * len(rows)
        val = evaluate(net, split["val"])
        score = val["loss_" + select]
        if lr_schedule == "plateau":
            sched.step(score)
        else:
            sched.step()
        if score < best:
            best, best_epoch, stale = score, epoch, 0
            best_state = {k: v.clone() for k, v in net.state_dict().items()}
        else:
            stale += 1
        elapsed = time.perf_counter() - t0
        log(f"{label:8s} epoch {epoch:4d}  train {tot / len(perm):.5f}  val loss mean "
            f"{val['loss_mean']:.4f} % median {val['loss_median']:.4f} % p95 {val['loss_p95']:.4f} "
            f"%  freq err median {max(val['freq_err_median']) * 100:.3f} %  lr "
            f"{opt.param_groups[0]['lr']:.2g}  {elapsed:.0f} s", always=False)
        if stale >= patience or elapsed > 60 * max_minutes:
            break
    net.load_state_dict(best_state)
    summary = {"mode": mode, "seed": seed + member, "best_epoch": best_epoch, "epochs": epoch,
               "time_s": time.perf_counter() - t0, "stopped": "patience" if stale >= patience
               else ("time limit" if epoch < max_epochs else "max_epochs"),
               "val": evaluate(net, split["val"]), "train": evaluate(net, split["train"])}
    v = summary["val"]
    log(f"== {label}: best epoch {best_epoch}/{epoch} ({summary['stopped']}), "
        f"{summary['time_s']:.0f} s; val PRBDM loss mean {v['loss_mean']:.4f} % median "
        f"{v['loss_median']:.4f} % p95 {v['loss_p95']:.4f} %; freq err median per mode "
        f"{[round(e * 100, 3) for e in v['freq_err_median']]} %")
    return net, summary


def _train_member(job):
    # runs in a forked process: send back plain arrays, not the module
    mode, member = job
    net, summary = train(mode, member)
    return net.weights(), summary


def train_ensemble(mode):
    """``members`` networks in parallel processes (fork: each inherits the data), then the
    ensemble's own validation and training metrics."""
    import multiprocessing

    with multiprocessing.get_context("fork").Pool(members) as pool:
        done = pool.map(_train_member, [(mode, j) for j in range(members)])
    nets_ = [make_net().load_weights(w) for w, _ in done]
    ens = SurrogateEnsemble(nets_)
    summary = {"mode": mode, "members": [s for _, s in done],
               "time_s": max(s["time_s"] for _, s in done),
               "val": evaluate(ens, split["val"]), "train": evaluate(ens, split["train"])}
    v = summary["val"]
    log(f"== {mode} ensemble of {members}: val PRBDM loss mean {v['loss_mean']:.4f} % median "
        f"{v['loss_median']:.4f} % p95 {v['loss_p95']:.4f} %; freq err median per mode "
        f"{[round(e * 100, 3) for e in v['freq_err_median']]} %")
    return ens, summary


results = {}
nets = {}
for mode in run_modes:
    nets[mode], results[mode] = train(mode) if members == 1 else train_ensemble(mode)
selected = min(results, key=lambda k: results[k]["val"]["loss_" + select])
log(f"selected mode: {selected} (lowest {select} validation PRBDM loss)")
net = nets[selected]
train_time = time.perf_counter() - t_start

# ------------------------------------------------------------------------------- 4. checkpoint
versions = ds._versions()
try:
    from importlib import metadata as _md
    versions["safetensors"] = _md.version("safetensors")
except Exception:  # noqa: BLE001
    pass
meta = {
    "name": out_path.stem,
    "created": dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds"),
    "joints": n, "modes": r, "truth": spec["truth"], "law": spec["law"],
    "poses": poses.tolist(), "pose_spec": spec["poses"], "truth_modes": R,
    "features": {"spec": fspec.to_dict(), "names": names,
                 "min": feats[tr].min(0).tolist(), "max": feats[tr].max(0).tolist(),
                 "ood_margin": sg.OOD_MARGIN,
                 "invariances": "beam truth + beam law: gamma, k and omega / sqrt(E t^2 / (rho "
                                "L^4)) depend only on w(x)/max(w) on x/L; features use only "
                                "that shape" + ("; plate adds log_aspect and nu"
                                                if spec["truth"] == "plate" else "")},
    "normalisation": {k: v.tolist() for k, v in norm_np.items()},
    "network": {"kind": "mlp", "width": width, "depth": depth, "activation": "silu",
                "k_mode": k_mode, "hypotheses": hypotheses, "members": members,
                "select_poses": sg.gauss_select_poses(m),
                "parameters": int(sum(p.numel() for p in net.parameters())),
                "outputs": "see prbdm.surrogate.decode_numpy"},
    "dataset": {"path": str(Path(data).resolve()), "spec": spec, "size": N,
                "records_ok_read": records_read, "max_index": max_index,
                "manifest_count": manifest.get("count"), "sha256": sha,
                "sha256_of": "sorted index + x, half_width, thickness, omega_truth, gamma, k "
                             "(prbdm.surrogate.dataset_hash)",
                "dataset_git_commit": manifest.get("git_commit"),
                "split": {"rule": "index % 10 == 9 test, == 8 validation, else training",
                          **{k: int(len(v)) for k, v in split.items()}}},
    "training": {"config": config,
                 "seeds": {"torch": seed, "numpy": seed, "batch_order": seed,
                           "members": [seed + j for j in range(members)]},
                 "selected_mode": selected, "selection": f"lowest {select} validation PRBDM loss",
                 "comparison": results, "time_s": train_time, "torch_threads": threads},
    "versions": versions, "git_commit": ds._git_commit(),
}
sg.save_checkpoint(out_path, net.weights(), meta)

# ------------------------------------------------------------------------------- 5. test metrics
sur = sg.load_checkpoint(out_path)
te = split["test"]
if len(te):
    t0 = time.perf_counter()
    pred = sur.predict(batch.take(te), frequencies=True, warn=False)
    pred_time = time.perf_counter() - t0
    lam_net = (pred.omega / np.sqrt(batch.lambda0[te])[:, None, None]) ** 2
    loss_net = sg.loss_percent_np(lam_net, lam_hat[te].numpy(), r)
    ferr = np.abs(pred.omega_truth / omega_truth[te] - 1)
    loss_fit = table["loss_percent"].to_numpy(dtype=np.float64, na_value=np.nan)[te]
    has_fit = bool(np.isfinite(loss_fit).all())
    test = {"beams": int(len(te)),
            "loss_median": float(np.median(loss_net)), "loss_p95": float(np.percentile(loss_net, 95)),
            "loss_mean": float(loss_net.mean()), "loss_max": float(loss_net.max()),
            "fit_loss_median": float(np.median(loss_fit)) if has_fit else None,
            "fit_loss_p95": float(np.percentile(loss_fit, 95)) if has_fit else None,
            "freq_err_median": np.median(ferr, 0).tolist(),
            "freq_err_p95": np.percentile(ferr, 95, 0).tolist(),
            "out_of_range_beams": int(pred.ood.any(1).sum()),
            "predict_time_s_per_beam": pred_time / len(te),
            "evaluated_with": "prbdm.surrogate.load_checkpoint + predict (NumPy path)"}
    meta["test"] = test
    sg.save_checkpoint(out_path, net.weights(), meta)
    fits = (f"optimised fits: median {test['fit_loss_median']:.4f} % p95 "
            f"{test['fit_loss_p95']:.4f} %" if has_fit else "no fits in a truth-only set")
    log(f"test ({len(te)} beams): PRBDM loss median {test['loss_median']:.4f} % p95 "
        f"{test['loss_p95']:.4f} % ({fits}); freq-prediction error median per mode "
        f"{[round(e * 100, 3) for e in test['freq_err_median']]} %")
log(f"checkpoint {out_path} ({out_path.stat().st_size / 1e3:.0f} kB), training "
    f"{train_time:.0f} s, total {time.perf_counter() - t_start:.0f} s; log {log_path}")
log_file.close()
