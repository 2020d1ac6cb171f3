"""Evaluate a surrogate checkpoint on held-out beams of its data set; print one table.

    python training/evaluate_surrogate.py [--checkpoint checkpoints/beam-n4.safetensors]
        [--data DIR] [--split heldout] [--refine_count 200] [--refit_count 20] [--config FILE]

(``--help`` lists every setting.)

Held-out beams (``--split``): ``test`` is the checkpoint's test split (``index % 10 == 9`` among
the records it was trained from); ``new`` is every record of the data set with an index beyond the
last one the checkpoint saw (generated later, never used in any way); ``heldout`` (default) is
both. A data set drawn with another ``--seed`` than the training set holds only new beams (another
random stream of the same generator); it may also differ in its start count (a truth-only
training set has none) and labelling batch, nothing else. Measured, on the same beams:

- network: the PRBDM predicted by the checkpoint, re-evaluated against the stored truth
  (docs/conventions.md §3 loss, %): median, p95, mean; the per-mode error of the network's direct truth-frequency
  prediction (median, p95); time per beam (one batched call, and one beam at a time);
- fit: the optimised fits stored in the data set (their loss; their time as recorded by the
  labelling worker, and, for ``refit_count`` beams, re-run here with the data set's start count);
- refined: the fit started from the network's gamma with ``refine_iter`` iterations
  (:func:`prbdm.fit.fit_many` with ``init_gamma``), ``fit_batch`` beams per call, for
  ``refine_count`` beams: its loss against the optimised fit's (ratio; share within 10 %) and its
  time, beside the full fit re-run with the same batching;
- throughput of :func:`prbdm.surrogate.predict` on ``throughput_count`` random beams.
"""
import json
import os
import time
from pathlib import Path

import _cli  # first: one BLAS thread per process before NumPy loads (see _cli)
from _cli import Setting as S

# isort: split
import numpy as np

PROG = "evaluate_surrogate"
SETTINGS = {
    "checkpoint": S("checkpoints/beam-n4.safetensors", "surrogate checkpoint to evaluate"),
    "data": S("", "data set folder (default: the one recorded in the checkpoint)"),
    "split": S("heldout", "held-out beams: the checkpoint's test split, new beams, or both",
               ("test", "new", "heldout")),
    "refine_count": S(200, "beams refined, fit_batch per call (0: skip)"),
    "refine_iter": S(15, "iterations of the refinement (prbdm.fit.REFINE_ITER)"),
    "refine_candidates": S(True, "also refine from the network's best candidates and the fit's "
                                 "four fixed starts (prbdm.fit.refine_starts), each beam in one "
                                 "fit"),
    "refit_count": S(20, "beams re-fitted here for a same-machine time comparison (0: skip)"),
    "fit_batch": S(1, "beams per fit_many call in the refined and re-fit rows (1: one at a "
                      "time; the data sets label in batches of 8)"),
    "throughput_count": S(10000, "random beams for the batched-prediction rate (0: skip)"),
    "threads": S(1, "torch threads"),
    "json_out": S("", "also write the results as JSON to this file"),
}
config = _cli.parse(PROG, __doc__.split("\n\n")[0], SETTINGS)
globals().update({k: v for k, v in config.items() if k in SETTINGS})


def _fail(message):
    """Bad input: one line on stderr, exit status 2 (as the prbdm commands)."""
    _cli.fail(PROG, message.removeprefix(f"{PROG}: "))


for _name in ("refine_count", "refit_count", "throughput_count"):
    if globals()[_name] < 0:
        _fail(f"--{_name}: must be an integer >= 0, got {globals()[_name]}")
for _name in ("refine_iter", "fit_batch", "threads"):
    if globals()[_name] < 1:
        _fail(f"--{_name}: must be an integer >= 1, got {globals()[_name]}")
if json_out and Path(json_out).is_dir():
    _fail(f"--json_out: {json_out!r} is a folder; give a file name")

from prbdm import dataset as ds  # noqa: E402
from prbdm import surrogate as sg  # noqa: E402
from prbdm.chain import BeamBatch, loss_percent_np  # noqa: E402
from prbdm.errors import BadInput  # noqa: E402
from prbdm.geometry import Material, random_beam  # noqa: E402
from prbdm.surrogate.checkpoint import matching_training_set, training_sets

try:
    sur = sg.load_checkpoint(checkpoint)
except BadInput as exc:
    _fail(str(exc))
meta = sur.metadata
# a recorded path is relative to the repository (no machine paths in committed metadata)
data = data or str(_cli.find_path(training_sets(meta)[0]["path"]))
try:
    manifest = ds.read_manifest(data)
except BadInput as exc:
    _fail(f"--data: {str(exc).removeprefix('DIR: ')}")
# a set may differ from a training set in what does not change the beams' distribution or their
# truth: the random stream (another seed: every beam is new), the fit's start count (a truth-only
# training set has 0) and the labelling batch
trained_on = matching_training_set(meta, manifest["spec"])
if trained_on is None:
    _a, _b = dict(manifest["spec"]), dict(training_sets(meta)[0]["spec"])
    for _key in ("seed", "starts", "fit_batch"):
        _a.pop(_key, None), _b.pop(_key, None)
    _fail(f"evaluate_surrogate: data set {data} has a different spec than the checkpoint's "
          f"(field {ds.spec_difference(_a, _b)})")
other_seed = manifest["spec"]["seed"] != trained_on["spec"]["seed"]
if manifest["spec"]["starts"] == 0:
    _fail(f"evaluate_surrogate: data set {data} is truth-only (no optimised fits to compare "
          "with); make one with --starts 64 (the default)")
table = ds.read_table(data, columns=["index", "x", "half_width", "thickness", "omega_truth",
                                     "gamma", "k", "loss_percent", "fit_time_s"],
                      status="ok").to_pandas()
max_index = trained_on["max_index"]
idx = table["index"].to_numpy()
test_mask = (idx <= max_index) & (idx % 10 == 9) & (not other_seed)
new_mask = (idx > max_index) | other_seed
mask = {"test": test_mask, "new": new_mask, "heldout": test_mask | new_mask}[split]
table = table[mask].reset_index(drop=True)
# records whose beam today's truth refuses (plate panels with a corner sharper than it resolves:
# their stored frequencies can be wrong) are left out (prbdm.dataset.refused_by_truth)
refused = ds.refused_by_truth(table, manifest["spec"])
table = table[~refused].reset_index(drop=True)
B = len(table)
if B == 0:
    _fail(f"evaluate_surrogate: no {split} beams in {data}")
n, r = sur.joints, sur.modes
material = Material(**manifest["spec"]["beam"]["material"])
batch = BeamBatch.from_table(table, material)
R = len(sur.norm["freq_mean"])
omega_t = np.stack(table["omega_truth"].to_numpy())
lam_hat = omega_t[:, :r] ** 2 / batch.lambda0[:, None]
results = {"checkpoint": _cli.portable_path(checkpoint), "data": _cli.portable_path(data),
           "split": split, "beams": B, "left_out_refused": int(refused.sum()),
           "checkpoint_dataset_size": meta["dataset"]["size"],
           "checkpoint_max_index": max_index,
           "test_beams": int(test_mask.sum()), "new_beams": int(new_mask.sum())}


def q(v, p):
    return float(np.percentile(v, p))


# ------------------------------------------------------------------------------- network
t0 = time.perf_counter()
pred = sur.predict(batch, frequencies=True, warn=False)
t_batch = (time.perf_counter() - t0) / B
lam_net = (pred.omega / np.sqrt(batch.lambda0)[:, None, None]) ** 2
loss_net = loss_percent_np(lam_net, lam_hat, r)
ferr = np.abs(pred.omega_truth[:, :R] / omega_t[:, :R] - 1)
loss_fit = table["loss_percent"].to_numpy()
t_single = []
for i in range(min(B, 50)):
    b1 = batch.take([i])
    t0 = time.perf_counter()
    sur.predict(b1, frequencies=True, warn=False)
    t_single.append(time.perf_counter() - t0)
results["network"] = {
    "loss_median": q(loss_net, 50), "loss_p95": q(loss_net, 95), "loss_mean": float(loss_net.mean()),
    "loss_max": float(loss_net.max()),
    "freq_err_median": np.median(ferr, 0).tolist(), "freq_err_p95": np.percentile(ferr, 95, 0).tolist(),
    "time_s_per_beam_batched": t_batch, "time_s_per_beam_single": float(np.median(t_single)),
    "out_of_range_beams": int(pred.ood.any(1).sum())}
results["fit"] = {"loss_median": q(loss_fit, 50), "loss_p95": q(loss_fit, 95),
                  "loss_mean": float(loss_fit.mean()),
                  "time_s_median_recorded": float(np.median(table["fit_time_s"]))}

# ------------------------------------------------------------------------------- refined / refit
if refine_count or refit_count:
    import torch

    torch.set_num_threads(threads)
    from prbdm.fit import REFINE_CANDIDATES, FitProblem, StopRules, fit_many, refine_starts

    poses = sur.poses.tolist()
    law = sur.law
    spec = manifest["spec"]
    rng = np.random.default_rng(0)
    pick = np.sort(rng.choice(B, size=min(refine_count, B), replace=False))
    beams = {i: ds.beam_for(spec, int(table["index"][i])) for i in
             set(pick.tolist()) | set(range(min(refit_count, B)))}
    def batched_fits(rows, **options):
        """fit_many over ``rows`` in calls of ``fit_batch`` beams: (losses, time per beam), each
        beam charged its call's time divided by the call's beams."""
        rows = np.asarray(rows)
        losses, times = [], []
        for g in [rows[i:i + fit_batch] for i in range(0, len(rows), fit_batch)]:
            extra = {k: (v[g] if isinstance(v, np.ndarray) else v) for k, v in options.items()}
            t0 = time.perf_counter()
            res = fit_many(FitProblem([beams[i] for i in g], omega_t[g], n, r, law, poses),
                           **extra)
            times += [(time.perf_counter() - t0) / len(g)] * len(g)
            losses += [x.loss_percent for x in res]
        return np.array(losses), np.array(times)

    if refine_count:
        lr, tr = batched_fits(pick, init_gamma=pred.gamma, stop=StopRules(max_iter=refine_iter))
        if refine_candidates and "gamma_candidates" in pred.extra:
            starts = refine_starts(pred.ranked_candidates(REFINE_CANDIDATES))
            H = starts.shape[1]
            lc, tc = batched_fits(pick, init_gamma=starts, stop=StopRules(max_iter=refine_iter))
            rc = lc / loss_fit[pick]
            results["refined_candidates"] = {
                "beams": int(len(pick)), "starts": int(H), "max_iter": refine_iter,
                "fit_batch": fit_batch,
                "loss_median": q(lc, 50), "loss_p95": q(lc, 95), "ratio_median": q(rc, 50),
                "ratio_p95": q(rc, 95), "share_within_10pct": float(np.mean(rc <= 1.10)),
                "time_s_median": q(tc, 50), "time_s_mean": float(tc.mean())}
        ratio = lr / loss_fit[pick]
        results["refined"] = {"beams": int(len(pick)), "max_iter": refine_iter, "fit_batch": fit_batch,
                              "loss_median": q(lr, 50), "loss_p95": q(lr, 95),
                              "fit_loss_median_same_beams": q(loss_fit[pick], 50),
                              "ratio_median": q(ratio, 50), "ratio_p95": q(ratio, 95),
                              "share_within_10pct": float(np.mean(ratio <= 1.10)),
                              "network_loss_median_same_beams": q(loss_net[pick], 50),
                              "time_s_median": q(tr, 50), "time_s_mean": float(tr.mean())}
    if refit_count:
        lf, tf = batched_fits(range(min(refit_count, B)), starts=spec["starts"], seed=0)
        results["refit"] = {"beams": len(tf), "starts": spec["starts"], "fit_batch": fit_batch,
                            "time_s_median": q(tf, 50), "time_s_mean": float(np.mean(tf)),
                            "loss_median": q(lf, 50)}

# ------------------------------------------------------------------------------- throughput
if throughput_count:
    tb = [random_beam(12345, i) for i in range(throughput_count)]
    sur.predict(tb[:100], warn=False)                       # warm-up
    wall, cpu = [], []
    for _ in range(3):                                      # best of three
        t0, c0 = time.perf_counter(), time.process_time()
        sur.predict(tb, frequencies=True, warn=False)
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    F = sur.features(BeamBatch.from_beams(tb))
    t3 = time.perf_counter()
    sur.predict(F, warn=False)
    t4 = time.perf_counter()
    try:
        load = os.getloadavg()[0]
    except OSError:
        load = float("nan")
    results["throughput"] = {"beams": throughput_count,
                             "beams_per_s": throughput_count / min(wall),
                             "beams_per_cpu_s": throughput_count / min(cpu),
                             "features_to_truth_frequencies_per_s": throughput_count / (t4 - t3),
                             "load_average": load, "cores": os.cpu_count()}

# ------------------------------------------------------------------------------- report
net, fit = results["network"], results["fit"]
print(f"checkpoint {checkpoint}: trained on {meta['dataset']['size']} beams (index <= "
      f"{max_index}); evaluated on {B} {split} beams ({results['test_beams']} test split, "
      f"{results['new_beams']} generated after training)")
print()
rows = [("network", f"{net['loss_median']:.4f}", f"{net['loss_p95']:.4f}", f"{net['loss_mean']:.4f}",
         f"{net['time_s_per_beam_single'] * 1e3:.2f} ms (batched {net['time_s_per_beam_batched'] * 1e6:.0f} us)"),
        ("optimised fit (data set)", f"{fit['loss_median']:.4f}", f"{fit['loss_p95']:.4f}",
         f"{fit['loss_mean']:.4f}", f"{fit['time_s_median_recorded']:.2f} s (recorded)")]
if "refit" in results:
    rf = results["refit"]
    rows.append((f"optimised fit (re-run, {rf['beams']} beams)", f"{rf['loss_median']:.4f}", "", "",
                 f"{rf['time_s_median']:.2f} s"))
if "refined" in results:
    rd = results["refined"]
    rows.append((f"network + refine ({rd['max_iter']} it., {rd['beams']} beams)",
                 f"{rd['loss_median']:.4f}", f"{rd['loss_p95']:.4f}", "",
                 f"{rd['time_s_median']:.3f} s"))
if "refined_candidates" in results:
    rc_ = results["refined_candidates"]
    rows.append((f"network + refine from {rc_['starts']} starts ({rc_['max_iter']} it.)",
                 f"{rc_['loss_median']:.4f}", f"{rc_['loss_p95']:.4f}", "",
                 f"{rc_['time_s_median']:.3f} s"))
w = [max(len(r_[i]) for r_ in rows + [("method", "loss median %", "loss p95 %", "loss mean %",
                                        "time per beam")]) for i in range(5)]
hdr = ("method", "loss median %", "loss p95 %", "loss mean %", "time per beam")
print("  ".join(h.ljust(w[i]) for i, h in enumerate(hdr)))
print("  ".join("-" * x for x in w))
for row in rows:
    print("  ".join(c.ljust(w[i]) for i, c in enumerate(row)))
if "refined" in results:
    rd = results["refined"]
    print(f"\nrefined / optimised loss on the same beams: median ratio {rd['ratio_median']:.3f}, "
          f"p95 {rd['ratio_p95']:.3f}, within 10 %: {rd['share_within_10pct'] * 100:.1f} % of "
          f"beams (network alone on them: median {rd['network_loss_median_same_beams']:.4f} %, "
          f"fits: {rd['fit_loss_median_same_beams']:.4f} %)")
if "refined_candidates" in results:
    rc_ = results["refined_candidates"]
    print(f"refined from {rc_['starts']} starts (candidates + 4 fixed) / optimised: median ratio "
          f"{rc_['ratio_median']:.3f}, p95 {rc_['ratio_p95']:.3f}, within 10 %: "
          f"{rc_['share_within_10pct'] * 100:.1f} % of beams")
    if "refit" in results:
        tf_ = results["refit"]["time_s_mean"]
        print(f"time per beam ({fit_batch} beams per call): refined from {rc_['starts']} starts "
              f"{rc_['time_s_mean']:.4f} s, optimised fit re-run {tf_:.4f} s: 1/"
              f"{tf_ / rc_['time_s_mean']:.1f} of the fit's time")
print("\nnetwork's direct truth-frequency prediction, relative error per mode:")
print("  median: " + ", ".join(f"mode {j + 1} {e * 100:.3f} %" for j, e in
                                enumerate(net["freq_err_median"])))
print("  p95:    " + ", ".join(f"mode {j + 1} {e * 100:.3f} %" for j, e in
                                enumerate(net["freq_err_p95"])))
print(f"  beams with an out-of-range feature: {net['out_of_range_beams']} of {B}")
if "throughput" in results:
    tp = results["throughput"]
    print(f"\nbatched prediction (Beam objects in; gamma, k, PRBDM frequencies per pose, truth "
          f"frequencies out), {tp['beams']} beams: {tp['beams_per_s']:.0f} beams/s wall, "
          f"{tp['beams_per_cpu_s']:.0f} beams per CPU-second (load average {tp['load_average']:.1f} "
          f"on {tp['cores']} cores); from precomputed features to the truth frequencies: "
          f"{tp['features_to_truth_frequencies_per_s']:.0f} /s")
if json_out:
    Path(json_out).write_text(json.dumps({"config": config, **results}, indent=1) + "\n")
