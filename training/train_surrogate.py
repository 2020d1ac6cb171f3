"""Train the PRBDM surrogate: from a data set folder to a checkpoint.

One script, read top to bottom (nanoGPT style). Every setting is a flag (``--help`` lists them
with their defaults); ``--config FILE`` reads them from a TOML or JSON file, and flags override
it. The recipe of each shipped checkpoint is a config under ``training/configs/``:

    python training/train_surrogate.py --config training/configs/beam-n4.toml \
        --out runs/beam-n4.safetensors

``--data`` (a data set folder, ``prbdm dataset generate``) and ``--out`` are required: nothing
overwrites a checkpoint by default. Bad settings or a missing data set end the script with one
line and exit status 2 before anything is written.

What it does:

1. reads the data set (``status == 'ok'`` records with ``index <= max_index``) and computes the
   features (:func:`prbdm.surrogate.features`) and the targets: gamma, log k, and the correction
   ``log omega_hat - log_omega_rfe`` of the truth frequencies;
2. splits by beam index: ``index % 10 == 9`` test, ``== 8`` validation, the rest training;
3. trains one network per training mode, each from the same seed:
   - ``label``: mean squared error of (gamma, log k, frequency correction), standardised;
   - ``physics``: the ``objective`` (:mod:`prbdm.objectives`: the paper's eigenvalue loss, SPEC
     §3 Eq. 12-13, or the frequency objective, both in percent) of the predicted (gamma, k)
     against the stored truth frequencies, through the differentiable :mod:`prbdm.model`; the
     frequency head keeps its label term (the truth frequencies are its only supervision);
   - ``combined``: label loss + ``phys_weight`` * physics loss;
   with AdamW, the learning rate halved when the validation objective stalls, and early stopping
   on it (the best epoch's weights are kept);
4. keeps the mode with the lowest validation objective (mean or median, ``select``), and records
   all modes' validation metrics in the checkpoint metadata;
5. writes the checkpoint beside ``OUT`` under a temporary name, loads it back through
   :func:`prbdm.surrogate.load_checkpoint` (the NumPy inference path that ``prbdm predict``
   uses), measures it on the test split (both measures, the paper's loss and the frequency
   objective, beside the optimised fits' on the same beams, and the per-mode error of the direct
   truth-frequency prediction), and only then writes ``OUT`` with these in its metadata.

A log goes to stdout and to ``OUT`` with the suffix ``.log`` (written as ``.log.partial`` while
the run lasts, so a failed run leaves an earlier log as it was).
"""
import atexit
import datetime as dt
import hashlib
import json
import math
import os
import time
from pathlib import Path

import _cli  # first: one BLAS thread per process before NumPy loads (see _cli)
import _heldout
import _sets
import _start
from _cli import Setting

# isort: split
import numpy as np

PROG = "train_surrogate"
S = Setting
SETTINGS = {
    "data": S("", "data set folder (prbdm dataset generate); several, comma-separated, train "
                  "one network when they differ only in their random beams"),
    "out": S("", "checkpoint to write (.safetensors; a .json copy of its metadata and a .log "
                 "beside it)"),
    "objective": S("eigenvalue", "what the physics loss and the selection measure: the paper's "
                                 "eigenvalue loss or the frequency objective (prbdm.objectives)",
                   ("eigenvalue", "frequency")),
    "device": S("auto", "torch device for training (auto: cuda when available, else cpu)"),
    "poses": S("", "pose set the PRBDM is trained at ('': the data set's; a truth-only set may "
                   "be trained at another: 'linear', at rest, is the shape pose target, "
                   "prbdm.pose_target)"),
    "joints": S(0, "PRBDM joints n (0: the data set's; another n only from a truth-only set "
                   "that holds n + 1 truth modes)"),
    "modes": S("label,physics,combined", "training modes to compare, comma-separated"),
    "seed": S(0, "torch seed of every mode (weights init and batch order)"),
    "max_index": S(-1, "use records with index <= max_index (-1: all present)"),
    "width": S(256, "hidden units per layer"),
    "depth": S(3, "hidden layers"),
    "freq_width": S(0, "> 0: the frequency outputs get a trunk of their own, depth layers of this "
                       "many units (0: they share the PRBDM's; stored as one MLP either way)"),
    "k_mode": S("projection", "SCFs: least squares against the predicted truth frequencies, or "
                              "log k regressed", ("projection", "direct")),
    "hypotheses": S(4, "candidate segmentations per beam; the one whose PRBDM best matches the "
                       "predicted truth frequencies is kept"),
    "members": S(1, "networks trained side by side, member j from seed + j, in parallel "
                    "processes: an ensemble whose candidates are pooled"),
    "wta_eps": S(0.05, "candidates' losses: (1 - eps) * best + eps * mean"),
    "init_gamma": S("", "start of candidate 0, comma-separated n+1 values (default: the mean "
                        "fitted label; equal links for a truth-only set)"),
    "batch_size": S(128, "beams per optimiser step"),
    "lr": S(2e-3, "AdamW learning rate"),
    "weight_decay": S(1e-5, "AdamW weight decay"),
    "max_epochs": S(400, "epochs at most"),
    "patience": S(80, "epochs without a better validation loss before stopping"),
    "lr_patience": S(20, "plateau schedule: epochs without improvement before halving the lr"),
    "lr_schedule": S("plateau", "plateau: halve after lr_patience epochs without a better "
                                "validation loss; cosine: lr (1 + cos(pi e / max_epochs)) / 2",
                     ("plateau", "cosine")),
    "max_minutes": S(9.0, "wall-clock limit per mode [min]"),
    "phys_weight": S(1.0, "combined mode: label + phys_weight * physics [%]"),
    "freq_weight": S(1.0, "weight of the frequency head's label term"),
    "freq_loss": S("mse", "the frequency head's label term: mse (its mean) or l1 (its median: "
                          "where the kept mode switches with the shape the label is two-valued, "
                          "and the mean of the two is wrong for both)", ("mse", "l1")),
    "freq_detach": S(False, "the PRBDM loss does not move the frequency outputs (the SCF "
                            "projection reads them without their gradient): they learn the "
                            "truth labels alone"),
    "vp_weight": S(1.0, "physics: + vp_weight * the objective of the predicted gamma with its "
                        "best SCFs (variable projection on the truth, as the fit)"),
    "loss_power": S(1.0, "physics: each beam's loss L [%] enters as L**p / p (p = 0: log L, "
                         "which moves the median rather than the tail)"),
    "select": S("mean", "validation statistic that drives the lr schedule, early stopping and "
                        "the choice of mode", ("mean", "median")),
    "cells": S(16, "feature cells along x / L"),
    "rfe_segments": S(96, "links of the rigid-finite-element frequency estimate"),
    "rfe_coarse": S(16, "> 0: that estimate by Rayleigh-Ritz from a chain of this many links"),
    "spread": S(False, "add the same estimate with the 45-degree load-spread width's stiffness "
                "(log_omega_spread, prbdm.surrogate.features) and correct that one: for plates"),
    "profile": S(0, "> 0: add the half-width profile w / max(w) at this many points of x / L "
                    "(log_profile, and log_spread_profile with spread): what the cell means "
                    "blur, the necks that set the plate's higher modes"),
    "ritz": S(False, "add the plate's bending spectrum estimated by Rayleigh-Ritz on the planform "
                     "(log_omega_ritz, prbdm.truth.planform_ritz, ~20 ms a panel) and correct "
                     "that one: for plates"),
    "ritz_basis": S("", "DEGREE,CHORD_TERMS of the Ritz estimate's basis (empty: the defaults, "
                        "prbdm.truth.planform_ritz.RITZ_DEFAULTS): 4,4 follows the paper's "
                        "jagged panels closer at ~4x the cost"),
    "partial": S("", "data sets of which the first K truth modes alone are the target, "
                     "PATH:K comma-separated (e.g. a section-rule set: its modes 1-2 are the "
                     "bending spectrum's): their training panels teach the frequency head those "
                     "K modes, no PRBDM loss; panels also in --data are left out (physics mode, "
                     "truth-only sets)"),
    "init_from": S("", "checkpoint to start from (fine-tuning): member j starts as its member j "
                       "mod M; its network and feature settings must be these; the features it "
                       "lacks start with zero weight, and its normalisation is kept, so that "
                       "the start predicts exactly what it did"),
    "threads": S(1, "torch threads"),
    "quiet": S(False, "only the summary lines"),
}

config = _cli.parse(PROG, __doc__.split("\n\n")[0], SETTINGS, required=("data", "out"))
globals().update({k: v for k, v in config.items() if k in SETTINGS})


def _fail(message):
    """Bad input: one line on stderr, exit status 2 (as the prbdm commands)."""
    _cli.fail(PROG, message)


# ------------------------------------------------------------------------------- check inputs
# everything that can be checked is checked here, before anything is written
run_modes = [s.strip() for s in modes.split(",") if s.strip()]
if not run_modes or set(run_modes) - {"label", "physics", "combined"}:
    _fail(f"--modes: each one of label, physics, combined, got {modes!r}")
for _name, _lo in (("joints", 0), ("members", 1), ("width", 1), ("freq_width", 0), ("depth", 1),
                   ("hypotheses", 1), ("batch_size", 1), ("max_epochs", 1), ("patience", 1), ("lr_patience", 1),
                   ("cells", 1), ("rfe_segments", 2), ("threads", 1)):
    if globals()[_name] < _lo:
        _fail(f"--{_name}: must be an integer >= {_lo}, got {globals()[_name]}")
for _name in ("lr", "max_minutes"):
    if not globals()[_name] > 0:
        _fail(f"--{_name}: must be > 0, got {globals()[_name]}")
if not 0 <= wta_eps <= 1:
    _fail(f"--wta_eps: must be in [0, 1], got {wta_eps}")
if not 0 <= loss_power <= 8:
    _fail(f"--loss_power: must be in [0, 8], got {loss_power}")
if ritz_basis.strip() and not ritz:
    _fail(f"--ritz_basis: only with --ritz true, got {ritz_basis!r}")
try:
    from prbdm.surrogate.features import FeatureSpec as _Spec  # checks the basis
    ritz_basis = _Spec(ritz_basis=tuple(ritz_basis.split(",")) if ritz_basis.strip()
                       else ()).ritz_basis
except ValueError as exc:
    _fail(f"--ritz_basis: {str(exc).removeprefix('ritz_basis: ')}, got {ritz_basis!r}")
out_path = Path(out)
if out_path.suffix != ".safetensors":
    _fail(f"--out: must end in .safetensors, got {out!r}")
if out_path.is_dir():
    _fail(f"--out: {out!r} is a folder; give the checkpoint's file name")
data_sets = [d.strip() for d in data.split(",") if d.strip()]
for _d in data_sets:
    if not Path(_d, "_manifest.json").is_file():
        _fail(f"--data: {_d!r} is not a data set folder (no _manifest.json); make one with "
              f"`prbdm dataset generate`")
if not data_sets or len({Path(d).resolve() for d in data_sets}) != len(data_sets):
    _fail(f"--data: one or more distinct data set folders, comma-separated, got {data!r}")
try:
    partial_sets = _sets.parse_partial(partial, data_sets)
except _sets.SetError as exc:
    _fail(f"--partial: {exc}")
if partial_sets and set(run_modes) != {"physics"}:
    _fail(f"--partial: trains the physics mode only (the sets' fitted labels are not this "
          f"target's), got --modes {modes!r}")

import _ritz_cache
import torch  # after the configuration, as in nanoGPT (E402 is off for this file)

from prbdm import dataset as ds
from prbdm import model, objectives
from prbdm import surrogate as sg
from prbdm.chain import BeamBatch, uniform_gamma
from prbdm.constants import GAMMA_MIN
from prbdm.surrogate.checkpoint import member_prefixes, save_checkpoint
from prbdm.surrogate.decode import candidate_losses, gauss_select_poses
from prbdm.surrogate.features import PROFILE_FLOOR, FeatureSpec, feature_names, features
from prbdm.surrogate.net import SurrogateEnsemble, SurrogateNet
from prbdm.surrogate.prediction import OOD_MARGIN

if device == "auto":
    device = "cuda" if torch.cuda.is_available() else "cpu"
try:
    dev = torch.device(device)
    torch.empty(0, device=dev)
except (RuntimeError, AssertionError) as exc:     # unknown name, or no such device here
    _fail(f"--device: {device!r} is not usable here ({str(exc).splitlines()[0]}); "
          f"use cpu, cuda or auto")
torch.set_num_threads(threads)

# ------------------------------------------------------------------------------- 1. data
# several sets (``--data A,B``) train one network when they agree on everything that defines
# the labels and differ only in their random beams (training/_sets.py read_sets)
try:
    tables, sets = _sets.read_sets(data_sets, max_index)
except _sets.SetError as exc:
    _fail(f"--data: {exc}")
import pandas as pd

manifest, spec = ds.read_manifest(data_sets[0]), sets[0]["spec"]
if max_index < 0 or len(sets) == 1:
    max_index = sets[0]["max_index"]          # capped at a growing set's labelling front
# partial sets (--partial): their training panels, less those in --data, with the truth modes
# past their first K unknown (NaN); they teach the frequency head those K modes only
_R_all = len(tables[0]["omega_truth"].iloc[0])
_seen = np.concatenate([_sets.panel_digests(t_) for t_ in tables])
for _d, _k in partial_sets:
    try:
        _t, _record = _sets.read_partial(_d, _k, spec, _seen, _R_all)
    except _sets.SetError as exc:
        _fail(f"--partial: {exc}")
    sets.append(_record)
    tables.append(_t)
table = pd.concat(tables, ignore_index=True) if len(tables) > 1 else tables[0]
known = np.isfinite(np.stack(table["omega_truth"].to_numpy()))   # a partial set's NaN: unknown
records_read = sum(s_["records_ok_read"] for s_ in sets)
N = len(table)
# a truth-only set's records do not depend on the joints (no fit): it trains any n whose r
# modes and n + 1 truth modes it holds; a labelled set only its own
n = joints or spec["joints"]
if joints and joints != spec["joints"]:
    if spec["starts"] > 0:
        _fail(f"--joints: {data} holds fits for n = {spec['joints']}; another n needs a "
              f"truth-only set (--starts 0), got {joints}")
    if spec["truth_modes"] < joints + 1:
        _fail(f"--joints: {data} holds {spec['truth_modes']} truth modes; n = {joints} needs "
              f"n + 1 = {joints + 1}")
# the poses: the set's, or for a truth-only set any other (its records hold no fit at any pose)
pose_spec = poses or spec["poses"]
if pose_spec != spec["poses"] and spec["starts"] > 0:
    _fail(f"--poses: {data} holds fits at its poses {spec['poses']!r}; another pose set needs a "
          f"truth-only set (--starts 0), got {poses!r}")
# r modes are fitted: the set's, or with another n (truth-only) as many as n, as for its own n
r = min(n, spec["modes"]) if n == spec["joints"] else n
if N < 10:
    _fail(f"--data: need at least 10 ok records, found {N} in {data!r}")
# a truth-only set (``prbdm dataset generate --starts 0``) has no fitted labels: only the physics
# mode can train on it (it needs the truth frequencies alone); the label normalisation is then the
# rigid-finite-element segmentation and k = 1
labelled = spec["starts"] > 0
if not labelled and set(run_modes) - {"physics"}:
    _fail(f"--modes: the data set {data} is truth-only (starts 0, no fitted labels); only "
          f"'physics' can train on it, got {modes!r}")
if init_gamma:
    try:
        _g0 = [float(v) for v in init_gamma.split(",")]
    except ValueError:
        _g0 = []
    if len(_g0) != n + 1 or min(_g0) <= GAMMA_MIN:
        _fail(f"--init_gamma: need {n + 1} comma-separated values > {GAMMA_MIN}, got "
              f"{init_gamma!r}")

# a start checkpoint (fine-tuning, e.g. the Kirchhoff plate's network on Mindlin labels): its
# network and feature settings must be these, so that its weights mean the same here
init_weights, init_meta, init_sha256 = None, None, None
if init_from:
    if init_gamma:
        _fail("--init_gamma: not with --init_from (the start checkpoint's segmentations are the "
              "start)")
    _R = min(spec["truth_modes"], rfe_segments - 1)
    _names = feature_names(FeatureSpec(cells=cells, rfe_segments=rfe_segments, rfe_modes=_R,
                                       truth=spec["truth"], rfe_coarse=rfe_coarse, spread=spread,
                                       profile=profile, ritz=ritz, ritz_basis=ritz_basis))
    try:
        init_weights, init_meta, init_sha256 = _start.read_start(init_from, _names, {
            "joints": n, "width": width, "freq_width": freq_width, "depth": depth,
            "k_mode": k_mode,
            "hypotheses": hypotheses, "poses": model.make_poses(pose_spec, n).tolist(),
            "truth_modes": _R, "cells": cells, "rfe_segments": rfe_segments,
            "rfe_coarse": rfe_coarse, "spread": spread, "ritz_basis": ritz_basis},
            spec["truth"])
    except (_start.StartError, ValueError) as exc:       # BadInput is a ValueError
        _fail(f"--init_from: {exc}")

# ------------------------------------------------------------------------------- log
out_path.parent.mkdir(parents=True, exist_ok=True)
log_path = out_path.with_suffix(".log")
log_partial = log_path.with_name(log_path.name + ".partial")
log_file = open(log_partial, "w")
t_start = time.perf_counter()
trial_path = out_path.with_name(f".{out_path.stem}.partial.safetensors")


@atexit.register
def _clean_up():
    """A run that fails leaves no half-written file: an earlier log and checkpoint stay as
    they were (the log of the failed run went to stdout as well)."""
    if not log_file.closed:
        log_file.close()
        log_partial.unlink(missing_ok=True)
    for p in (trial_path, trial_path.with_suffix(".json")):
        p.unlink(missing_ok=True)


def _feature_groups(names):
    """'a, b[0..63]' for a list of feature names (indexed ones grouped by their stem)."""
    groups = {}
    for n_ in names:
        groups.setdefault(n_.split("[")[0], []).append(n_)
    return ", ".join(g[0] if len(g) == 1 else f"{stem}[0..{len(g) - 1}]"
                     for stem, g in groups.items())


def log(text, always=True):
    if always or not quiet:
        print(text, flush=True)
    log_file.write(text + "\n")
    log_file.flush()


log(f"# train_surrogate {dt.datetime.now(dt.timezone.utc).isoformat(timespec='seconds')}")
log("config " + json.dumps({**config, "data": _cli.portable_path(data),
                            "out": _cli.portable_path(out), "device": device,
                            "init_from": _cli.portable_path(init_from) if init_from else ""}))

poses = model.make_poses(pose_spec, n)
m = poses.shape[0]
R = min(spec["truth_modes"], rfe_segments - 1)
material = spec["beam"]["material"]
fspec = FeatureSpec(cells=cells, rfe_segments=rfe_segments, rfe_modes=R, truth=spec["truth"],
                       rfe_coarse=rfe_coarse, spread=spread, profile=profile, ritz=ritz,
                       ritz_basis=ritz_basis)
# one set: the hash of its records (as before); several: of their hashes, in the given order
sha = (sets[0]["sha256"] if len(sets) == 1 else
       hashlib.sha256("".join(s_["sha256"] for s_ in sets).encode()).hexdigest())
batch = BeamBatch.from_table(table, material)
# the Ritz estimate costs ~20 ms a panel (minutes for a set): its columns are kept beside the
# checkpoint, per set and index, for the next run (training/_ritz_cache.py)
ritz_cols = (_ritz_cache.set_columns(tables, sets, R, out_path.parent / ".feature-cache", log,
                                     basis=ritz_basis) if ritz else None)
feats = features(batch, fspec, ritz_cols)
names = feature_names(fspec)
omega_truth = np.stack(table["omega_truth"].to_numpy())[:, :R]
log_omega_hat = np.log(omega_truth / np.sqrt(batch.lambda0)[:, None])
base = fspec.base_columns(R)           # what the predicted log frequencies correct
if labelled:
    y_gamma = np.stack(table["gamma"].to_numpy())
    y_logk = np.log(np.stack(table["k"].to_numpy()))
else:
    y_gamma = np.broadcast_to(uniform_gamma(n), (N, n + 1)).copy()
    y_logk = np.zeros((N, m))
y_corr = log_omega_hat - feats[:, base]
for s_ in sets[1:]:
    gen = s_["spec"]["beam"]
    log(f"  with {s_['path']}: {s_.get('rows_used', s_['size'])} records (index <= "
        f"{s_['max_index']}), {gen.get('family', 'paper')} panels"
        + (f", max half-width {json.dumps(gen['max_half_width'])} m" if "max_half_width" in gen
           else "") + f", seed {s_['spec']['seed']}"
        + (f"; partial: truth modes 1-{s_['partial_modes']} only, training panels in no --data "
           f"set" if "partial_modes" in s_ else ""))
log(f"data {data}: {records_read} ok records, {N} with index <= {max_index} and accepted by "
    f"today's truth ({sum(s_['refused_by_truth'] for s_ in sets)} refused); n = {n}, "
    f"r = {r}, m = {m} poses, {R} truth modes, {len(names)} features; "
    f"{'fitted labels' if labelled else 'truth only (no fitted labels)'}; sha256 {sha[:16]}")

# ------------------------------------------------------------------------------- 2. split
complete = known[:, :R].all(1)          # every trained mode known: not a partial set's row
split = {k: v[complete[v]] for k, v in _sets.split(table["index"].to_numpy()).items()}
partial_rows = np.flatnonzero(~complete)  # training panels only (kept so when read)
log("split " + ", ".join(f"{k} {len(v)}" for k, v in split.items())
    + (f", and {len(partial_rows)} training panels of partial sets" if len(partial_rows) else ""))
tr = split["train"]
tr_all = np.concatenate([tr, partial_rows])             # every panel the network learns from
f_mean, f_std = feats[tr_all].mean(0), np.maximum(feats[tr_all].std(0), 1e-6)
norm_np = {"feature_mean": f_mean, "feature_std": f_std,
           "logk_mean": y_logk[tr].mean(0), "logk_std": np.maximum(y_logk[tr].std(0), 1e-6),
           "freq_mean": y_corr[tr].mean(0), "freq_std": np.maximum(y_corr[tr].std(0), 1e-6),
           "gamma_mean": y_gamma[tr].mean(0), "gamma_std": np.maximum(y_gamma[tr].std(0), 1e-6)}
if init_meta is not None:
    # the start's own normalisation, so that its weights predict what they did: its outputs'
    # and its features' (by name); a feature it lacks keeps this set's (its weights start at 0)
    _old = init_meta["normalisation"]
    for _k in ("logk_mean", "logk_std", "freq_mean", "freq_std", "gamma_mean", "gamma_std"):
        norm_np[_k] = np.asarray(_old[_k], dtype=np.float64)
    _old_names = init_meta["features"]["names"]
    for _j, _name in enumerate(names):
        if _name in _old_names:
            _i = _old_names.index(_name)
            norm_np["feature_mean"][_j] = _old["feature_mean"][_i]
            norm_np["feature_std"][_j] = _old["feature_std"][_i]
    f_mean, f_std = norm_np["feature_mean"], norm_np["feature_std"]
    log(f"start: {_cli.portable_path(init_from)} ({init_meta.get('name')}, truth "
        f"{init_meta['truth']}); features new to it, starting at zero weight: "
        f"{_feature_groups([n_ for n_ in names if n_ not in _old_names]) or 'none'}")
# the training data lives on the training device (every row of it, once)
norm = {k: torch.as_tensor(v, dtype=torch.float32, device=dev) for k, v in norm_np.items()}

F = torch.as_tensor((feats - f_mean) / f_std, dtype=torch.float32, device=dev)
Yg = torch.as_tensor(y_gamma, dtype=torch.float32, device=dev)
Yk = torch.as_tensor(y_logk, dtype=torch.float32, device=dev)
Yc = torch.as_tensor(np.nan_to_num(y_corr), dtype=torch.float32, device=dev)
KNOWN = torch.as_tensor(known[:, :R], dtype=torch.float32, device=dev)
FREQ_OUT = slice(hypotheses * (n + 1) + m, None)     # the frequency head (surrogate.decode)
RFE = torch.as_tensor(feats[:, base], dtype=torch.float32, device=dev)
BX = torch.as_tensor(batch.x, device=dev)
BW = torch.as_tensor(batch.w, device=dev)
lam_hat = torch.as_tensor(omega_truth[:, :r] ** 2 / batch.lambda0[:, None], device=dev)
poses_dev = poses.to(dev)


def beam_rows(rows):
    ones = torch.ones(len(rows), dtype=torch.float64, device=dev)
    # nondimensional: the beam law and the unit-k eigenvalues use only x / L and w / L
    return model.BeamTensors(BX[rows], BW[rows], ones, ones, ones, ones)


def outputs(net, rows):
    """Decoded network outputs for data rows (dict, see prbdm.surrogate.decode.decode_torch), with
    ``corr`` the predicted correction of the rigid-finite-element log frequencies."""
    d = net.outputs(F[rows], norm, RFE[rows], BX[rows], BW[rows], poses_dev, r,
                    detach_frequencies=freq_detach)
    d["corr"] = d["log_omega_hat"] - RFE[rows]
    return d


def physics_loss(rows, gamma, logk, mu=None):
    """Per-beam ``objective`` [%] of the predicted PRBDM (its own k) against the truth, float64:
    the paper's loss (docs/conventions.md §3) or the frequency objective (prbdm.objectives)."""
    if mu is None:
        mu = model.eigenvalues_unit_k(beam_rows(rows), gamma.double(), poses_dev, "beam")
    lam = mu * torch.exp(logk.double())[..., None]
    if objective == "frequency":
        return objectives.frequency_measure(lam, lam_hat[rows], r)
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
    """Per-beam ``objective`` [%] of the candidate segmentations with their best SCFs for the
    truth (what the fit minimises, after variable projection), relaxed min over the candidates:
    what the proposed gammas alone can reach."""
    if d["mu_all"] is None:
        mu_all = model.eigenvalues_unit_k(beam_rows(rows), d["gamma_all"].double(), poses_dev,
                                          "beam")
    else:
        mu_all = d["mu_all"]
    if objective == "frequency":
        res, _ = objectives.residuals(objective, mu_all[..., :r], lam_hat[rows][:, None, :])
        return wta(objectives.loss(objective, res))
    _, loss = candidate_losses(mu_all[..., :r], lam_hat[rows])
    return wta(loss)


def label_terms(rows, d, net=None, partial=None):
    """The label terms of ``rows`` (gamma, log k, frequency correction); with ``partial``
    (rows of partial sets) their known modes join the frequency term, through ``net``'s
    frequency head alone (they have no PRBDM term)."""
    ga = d["gamma_all"]
    lg = wta((((ga - Yg[rows][:, None]) / norm["gamma_std"]) ** 2).mean(-1)).mean()
    lk = (((d["logk"].float() - Yk[rows]) / norm["logk_std"]) ** 2).mean()
    dc = (d["corr"] - Yc[rows]) / norm["freq_std"]
    if partial is None or not len(partial):
        lc = (dc ** 2).mean() if freq_loss == "mse" else dc.abs().mean()
        return lg, lk, lc
    corr_p = net(F[partial])[:, FREQ_OUT] * norm["freq_std"] + norm["freq_mean"]
    dp = (corr_p - Yc[partial]) / norm["freq_std"]
    power = 2 if freq_loss == "mse" else 1
    total = (dc.abs() ** power).sum() + (dp.abs() ** power * KNOWN[partial]).sum()
    return lg, lk, total / (dc.numel() + KNOWN[partial].sum())


@torch.no_grad()
def evaluate(net, rows):
    rows = torch.as_tensor(rows, device=dev)
    net.eval()
    d = outputs(net, rows)
    phys = physics_loss(rows, d["gamma"], d["logk"], d["mu"]).cpu().numpy()
    err = np.abs(np.expm1((d["corr"] - Yc[rows]).double().cpu().numpy()))  # relative freq error
    net.train()
    return {"loss_mean": float(phys.mean()), "loss_median": float(np.median(phys)),
            "loss_p95": float(np.percentile(phys, 95)),
            "freq_err_median": np.median(err, 0).tolist(),
            "freq_err_p95": np.percentile(err, 95, 0).tolist()}


# ------------------------------------------------------------------------------- 3. training
Net = SurrogateNet


def start_weights(member):
    """The start checkpoint's weights for ``member`` (its member ``member`` mod M), its first
    layer's columns placed by feature name: a feature it lacks gets zero weight."""
    prefixes = member_prefixes(int(init_meta["network"].get("members", 1)))
    pre = prefixes[member % len(prefixes)]
    w = {k[len(pre):]: v for k, v in init_weights.items() if k.startswith(pre)}
    old_names = init_meta["features"]["names"]
    first = np.zeros((w["layers.0.weight"].shape[0], len(names)), dtype=np.float32)
    for j, name in enumerate(names):
        if name in old_names:
            first[:, j] = w["layers.0.weight"][:, old_names.index(name)]
    return {**w, "layers.0.weight": first}


def make_net(member=0):
    net = Net(len(names), n, m, R, width=width, depth=depth, k_mode=k_mode,
              hypotheses=hypotheses, freq_width=freq_width)
    if init_meta is not None:
        return net.load_weights(start_weights(member)).to(dev)
    with torch.no_grad():       # start near the mean label: gamma logits, standardised k, freq 0
        for head in (net.head, net.freq_head) if freq_width else (net.head,):
            head.weight.mul_(0.1)
            head.bias.zero_()
        if init_gamma:                                      # checked with the inputs
            g = torch.tensor([float(v) for v in init_gamma.split(",")]) - GAMMA_MIN
        elif labelled:
            g = (norm["gamma_mean"].cpu() - GAMMA_MIN).clamp_min(1e-3)
        else:
            g = torch.full((n + 1,), 1.0 / (n + 1))             # no labels: equal links
        # candidates start apart: the mean label, rigid-finite-element-like, a long root link
        # (the two families of fitted optima), then random segmentations
        long_root = torch.full((n + 1,), 0.3 / n)
        long_root[0] = 0.7
        starts = [g / g.sum(), torch.as_tensor(uniform_gamma(n), dtype=torch.float32),
                  long_root]
        gen0 = torch.Generator().manual_seed(seed + member + 1)
        while len(starts) < hypotheses:
            starts.append(torch.rand(n + 1, generator=gen0) + 0.2)
        for h in range(hypotheses):
            net.head.bias[h * (n + 1):(h + 1) * (n + 1)] = torch.log(starts[h] / starts[h].sum())
    return net.to(dev)


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
    partial_train = torch.as_tensor(partial_rows)
    best, best_state, best_epoch, stale = math.inf, None, 0, 0
    if init_meta is not None:
        # where the start stands on this run's truth; it is epoch 0, kept if no epoch beats it
        v = evaluate(net, split["val"])
        best = v["loss_" + select]
        best_state = {k: v_.clone() for k, v_ in net.state_dict().items()}
        log(f"{label:8s} start       val loss mean {v['loss_mean']:.4f} % median "
            f"{v['loss_median']:.4f} % p95 {v['loss_p95']:.4f} %  freq err median per mode "
            f"{[round(e * 100, 3) for e in v['freq_err_median']]} %")
    t0 = time.perf_counter()
    epoch = 0
    for epoch in range(1, max_epochs + 1):
        # the order is drawn on the CPU, so that it is the same on every device
        perm = train_rows[torch.randperm(len(train_rows), generator=gen)].to(dev)
        # the partial sets' panels spread over the same batches
        pperm = partial_train[torch.randperm(len(partial_train), generator=gen)].to(dev)
        steps = -(-len(perm) // batch_size)
        tot = 0.0
        for i in range(0, len(perm), batch_size):
            rows = perm[i:i + batch_size]
            j = i // batch_size
            prow = pperm[j * len(pperm) // steps:(j + 1) * len(pperm) // steps]
            d = outputs(net, rows)
            lg, lk, lc = label_terms(rows, d, net, prow)
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

    jobs = [(mode, j) for j in range(members)]
    if dev.type == "cpu":
        with multiprocessing.get_context("fork").Pool(members) as pool:
            done = pool.map(_train_member, jobs)
    else:                       # CUDA does not survive a fork: one member after the other
        done = [_train_member(job) for job in jobs]
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
log(f"selected mode: {selected} (lowest {select} validation {objective} objective)")
net = nets[selected]
train_time = time.perf_counter() - t_start

# ------------------------------------------------------------------------------- 4. checkpoint
# no machine paths in the metadata: paths inside the repository are recorded relative to it
recorded_config = {**config, "device": device,
                   **{k: _cli.portable_path(config[k]) for k in ("data", "config", "init_from")
                      if config[k]}, "out": _cli.output_path(config["out"])}
versions = ds._versions()
try:
    from importlib import metadata as _md
    versions["safetensors"] = _md.version("safetensors")
except Exception:  # noqa: BLE001
    pass
meta = {
    "name": out_path.stem,
    "objective": objective,
    "created": dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds"),
    "joints": n, "modes": r, "truth": spec["truth"], "law": spec["law"],
    "poses": poses.tolist(), "pose_spec": pose_spec, "truth_modes": R,
    # trained at rest: the chain's stiffness is held at every pose (prbdm.pose_target)
    "pose_target": "shape" if pose_spec == "linear" else "straight",
    "features": {"spec": fspec.to_dict(), "names": names,
                 "min": feats[tr_all].min(0).tolist(), "max": feats[tr_all].max(0).tolist(),
                 "ood_margin": OOD_MARGIN,
                 "invariances": "beam truth + beam law: gamma, k and omega / sqrt(E t^2 / (rho "
                                "L^4)) depend only on w(x)/max(w) on x/L; features use only "
                                "that shape" + ("; plate adds log_aspect and nu"
                                                if spec["truth"] in ("plate", "mindlin") else "")
                                + ("; mindlin adds log_thickness (t/L: the shear)"
                                   if spec["truth"] == "mindlin" else "")
                                + ("; spread adds log_omega_spread, which depends on w/L "
                                   "itself (the load spread's 45 degrees)" if spread else "")
                                + ("; profile adds log w/max(w) at points of x/L (floored at "
                                   f"{PROFILE_FLOOR})" if profile else "")
                                + ("; ritz adds log_omega_ritz, the plate's bending spectrum by "
                                   "Rayleigh-Ritz on the planform (depends on w/L, t/L and nu)"
                                   if ritz else "")},
    "normalisation": {k: v.tolist() for k, v in norm_np.items()},
    "network": {"kind": "mlp", "width": width, "depth": depth, "activation": "silu",
                # > 0: the frequency outputs' own trunk, stored beside the PRBDM's as one MLP of
                # width + freq_width units with block-diagonal hidden layers
                "freq_width": freq_width,
                "k_mode": k_mode, "hypotheses": hypotheses, "members": members,
                "select_poses": gauss_select_poses(m),
                # the candidate rule predict answers with, and this test is measured with
                "candidate_rule": "plausible",
                "parameters": int(sum(p.numel() for p in net.parameters())),
                "outputs": "see prbdm.surrogate.decode.decode_numpy"},
    "dataset": {"path": _cli.portable_path(data), "spec": spec, "size": N,
                "records_ok_read": records_read, "max_index": max_index,
                "refused_by_truth": sum(s_["refused_by_truth"] for s_ in sets),
                "manifest_count": manifest.get("count"), "sha256": sha,
                "sha256_of": "sorted index + x, half_width, thickness, omega_truth, gamma, k "
                             "(prbdm.surrogate.checkpoint.dataset_hash)",
                "dataset_git_commit": manifest.get("git_commit"),
                "split": {"rule": "index % 10 == 9 test, == 8 validation, else training",
                          **{k: int(len(v)) for k, v in split.items()},
                          **({"partial_training": int(len(partial_rows))} if len(partial_rows)
                             else {})},
                **({"sets": sets, "sha256_of_sets": "sha256 of the sets' sha256 (hex) joined "
                    "in order"} if len(sets) > 1 else
                   {"index_ranges": sets[0]["index_ranges"]})},
    "training": {"config": recorded_config,
                 "seeds": {"torch": seed, "numpy": seed, "batch_order": seed,
                           "members": [seed + j for j in range(members)]},
                 "selected_mode": selected,
                 "selection": f"lowest {select} validation {objective} objective",
                 "comparison": results, "time_s": train_time,
                 **({"init_from": {"path": _cli.portable_path(init_from),
                                   "name": init_meta.get("name"), "truth": init_meta["truth"],
                                   "sha256": init_sha256,
                                   "git_commit": init_meta.get("git_commit")}}
                    if init_meta is not None else {}), "torch_threads": threads,
                 "device": str(dev)},
    "versions": versions, "git_commit": ds._git_commit(),
}
# first under a temporary name beside OUT: OUT is written once, complete, with its test metrics
save_checkpoint(trial_path, net.weights(), meta)

# ------------------------------------------------------------------------------- 5. test metrics
sur = sg.load_checkpoint(trial_path)
te = split["test"]
if len(te):
    loss_fit = table["loss_percent"].to_numpy(dtype=np.float64, na_value=np.nan)[te]
    meta["test"] = _heldout.test_metrics(sur, batch.take(te), omega_truth[te], r, loss_fit)
    for _line in _heldout.describe(meta["test"]):
        log(_line)
save_checkpoint(out_path, net.weights(), meta)
for _p in (trial_path, trial_path.with_suffix(".json")):
    _p.unlink(missing_ok=True)
log(f"checkpoint {out_path} ({out_path.stat().st_size / 1e3:.0f} kB), training "
    f"{train_time:.0f} s, total {time.perf_counter() - t_start:.0f} s; log {log_path}")
os.replace(log_partial, log_path)
log_file.close()
