"""Measure a checkpoint's held-out test again, from the data sets its metadata records.

    python training/retest.py --checkpoint checkpoints/plate-n4.safetensors [--write 1]

It reads each recorded set (``dataset.sets``, or the one ``dataset``) up to its recorded
``max_index``, checks that the records are the ones the network was trained on (each set's
sha256, prbdm.surrogate.checkpoint.dataset_hash; a set recorded with ``refused_by_truth`` leaves those
records out as training did), takes the test split (index % 10 == 9) and measures it as training
does (training/_heldout.py). The whole-test figures must equal the recorded ones: then the
measurement is the same one and ``--write 1`` stores the result, its per-width bands (``by_width``,
which ``predict`` quotes for a panel of that width) included, in the checkpoint (weights
unchanged; both files rewritten whole). A checkpoint trained before the bands existed gains them
so. Bad input or a mismatch: one line, exit status 2, nothing written.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _cli  # noqa: E402
import _heldout  # noqa: E402
import _sets  # noqa: E402

PROG = "retest"
SETTINGS = {
    "checkpoint": _cli.Setting("", "the checkpoint to measure again (.safetensors)"),
    "write": _cli.Setting(False, "store the measured test (by_width included) in the checkpoint"),
}
cfg = _cli.parse(PROG, __doc__.split("\n\n")[0], SETTINGS, required=("checkpoint",))
#: the recomputed figures must equal the recorded ones to this. The network runs in float32
#: (epsilon 1.2e-7) and another CPU's BLAS kernels sum its layers in another order; a PRBDM loss
#: is a difference of eigenvalues, which amplifies that. Measured with every OpenBLAS kernel
#: family on this machine (OPENBLAS_CORETYPE=Prescott, Nehalem, Sandybridge, Haswell, Zen,
#: SkylakeX) on plate-n4 and mindlin-n4: at most 2e-5 relative (tests/test_training.py runs one
#: under Prescott's); 1e-4 leaves a factor 5, and a different split or set moves these medians
#: and percentiles of thousands of panels by far more.
RTOL = 1e-4
ATOL = 1e-9      # figures are percents and seconds; an exact zero stays a zero


def _fail(message):
    _cli.fail(PROG, message)


import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from prbdm import surrogate as sg  # noqa: E402
from prbdm.chain import BeamBatch  # noqa: E402
from prbdm.errors import BadInput  # noqa: E402
from prbdm.surrogate.checkpoint import (  # noqa: E402
    read_checkpoint,
    save_checkpoint,
    training_sets,
)

path = Path(cfg["checkpoint"])
try:
    weights, meta = read_checkpoint(path)
    sur = sg.Surrogate(weights, meta, path)         # load_checkpoint, without reading it again
    # the candidate rule the recorded test was measured with (checkpoints before the rule
    # existed chose by the loss alone)
    sur.candidate_rule = meta.get("network", {}).get("candidate_rule", "loss")
except BadInput as exc:
    _fail(str(exc))
recorded = meta.get("test")
if not recorded:
    _fail(f"--checkpoint: {path} records no held-out test to measure again")

tables = []
for s in training_sets(meta):
    if "partial_modes" in s:            # --partial: training panels only, no test split
        continue
    if not {"path", "max_index", "sha256", "spec"} <= s.keys():
        _fail(f"--checkpoint: {path.name} does not record its data set (path, max_index, sha256, "
              "spec), so its test cannot be measured again")
    # a set recorded without ``refused_by_truth`` was read before that filter existed
    try:
        t, record = _sets.read_set(_cli.find_path(s["path"]), s["max_index"],
                                   refuse="refused_by_truth" in s, ranges=s.get("index_ranges"))
    except _sets.SetError as exc:
        _fail(f"--checkpoint: its data set {s['path']!r}: {exc}")
    if record["sha256"] != s["sha256"]:
        _fail(f"--checkpoint: data set {s['path']} (index <= {s['max_index']}) is not the one "
              f"{path.name} was trained on (sha256 differs)")
    tables.append(t)
table = pd.concat(tables, ignore_index=True) if len(tables) > 1 else tables[0]
te = _sets.split(table["index"].to_numpy())["test"]
if len(te) != recorded["beams"]:
    _fail(f"--checkpoint: {len(te)} test beams, {path.name} records {recorded['beams']}")

spec = training_sets(meta)[0]["spec"]
batch = BeamBatch.from_table(table, spec["beam"]["material"]).take(te)
R = len(sur.norm["freq_mean"])
omega_truth = np.stack(table["omega_truth"].to_numpy())[te, :R]
loss_fit = table["loss_percent"].to_numpy(dtype=np.float64, na_value=np.nan)[te]
test = _heldout.test_metrics(sur, batch, omega_truth, sur.modes, loss_fit)


def _worst(old, new) -> float:
    """The largest relative difference of the floats of ``new`` from ``old`` (inf where counts,
    bands or keys differ): 0 for the same measurement bit for bit."""
    if isinstance(old, dict):
        if not old.keys() <= new.keys():
            return math.inf
        return max((_worst(old[k], new[k]) for k in old), default=0.0)
    if isinstance(old, list) and old and isinstance(old[0], dict):
        if len(old) != len(new):
            return math.inf
        return max(_worst(o, n) for o, n in zip(old, new))
    if isinstance(old, float) or (isinstance(old, list) and old
                                  and all(isinstance(v, float) for v in old)):
        a, b = np.asarray(old, float), np.asarray(new, float)
        if a.shape != b.shape:
            return math.inf
        excess = np.abs(b - a) - ATOL
        return float(np.max(np.where(excess > 0, excess / np.maximum(np.abs(a), 1e-300), 0.0)))
    return 0.0 if old == new else math.inf


# the same measurement or none: every recorded figure but the timing (the bands where recorded)
largest = 0.0
for key, old in recorded.items():
    if key in ("predict_time_s_per_beam", "evaluated_with", "by_width_added_by"):
        continue
    if key not in test:
        _fail(f"--checkpoint: {path.name} records test.{key}, which this measurement does not "
              "make (nothing written)")
    worst = _worst(old, test[key])
    if not worst <= RTOL:
        _fail(f"--checkpoint: recomputed test.{key} differs from the recorded one by "
              f"{worst:.2g} relative (allowed {RTOL:g}; {str(test[key])[:80]} vs "
              f"{str(old)[:80]}); not the measurement training made (nothing written)")
    largest = max(largest, worst)
for line in _heldout.describe(test):
    print(line)
print(f"recorded test reproduced ({len(te)} beams, rtol {RTOL:g}; largest relative difference "
      f"{largest:.2g})")
if cfg["write"]:
    # the recorded timing stays (it was measured with the training machine's load)
    meta["test"] = {**test, "predict_time_s_per_beam": recorded["predict_time_s_per_beam"]}
    if "by_width" not in recorded or "by_width_added_by" in recorded:
        meta["test"]["by_width_added_by"] = "training/retest.py"
    save_checkpoint(path, weights, {k: v for k, v in meta.items() if k != "weights_sha256"})
    print(f"wrote {path} and {path.with_suffix('.json').name}: test.by_width "
          f"({len(test['by_width'])} bands)")
