"""Add to a checkpoint the reference of the panels it was trained on (issue 35).

    python training/add_neighbours.py --checkpoint checkpoints/plate-n4.safetensors [--write 1]

It reads each data set the metadata records (``dataset.sets``, or the one ``dataset``) up to its
recorded ``max_index`` and checks that the records are the ones the network was trained on (each
set's sha256, as training/retest.py does). A recorded set that is not on this machine has its
panels made again from its spec (prbdm.dataset.beam_for: a pure function of the spec's seed,
generator options and the index; the geometry is all the features need) and is checked by the
feature ranges the checkpoint records: every recorded features.min and max must be met by a
training panel made again, and all but the records the set lacked (its failures) must lie inside
them. The training split (training/_sets.py ``split``) gives ``--count`` panels drawn at random
(``--seed``), whose normalised features become the reference; the test split's panels give the
held-out nearest distances and the limit beyond which an answer is warned about (their 99.9th
percentile: prbdm.surrogate.neighbours). A ``ritz`` network (the planform Ritz estimate, ~24 ms
a panel, ~90 ms in the 4,4 basis) with every set here computes the features of those panels only, not of the whole
training split, whose ranges are then checked to hold them; ``--cache DIR`` reads their Ritz
columns from the folder training keeps them in (``runs/.feature-cache``: training/_ritz_cache.py,
each row checked against its panel's digest) and computes only the ones missing there (and adds
them). ``--write 1`` stores both in the checkpoint (the tensor
``neighbours.features`` and the metadata ``neighbours``; the weights and weights_sha256
unchanged; both files rewritten whole). Bad input or a mismatch: one line, exit status 2,
nothing written.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _cli  # noqa: E402
import _sets  # noqa: E402

PROG = "add_neighbours"
SETTINGS = {
    "checkpoint": _cli.Setting("", "the checkpoint to add the reference to (.safetensors)"),
    "count": _cli.Setting(4096, "training panels kept in the reference"),
    "seed": _cli.Setting(0, "seed of the random draw of the reference panels"),
    "write": _cli.Setting(False, "store the reference in the checkpoint"),
    "cache": _cli.Setting("", "folder of the Ritz columns training kept (runs/.feature-cache): "
                              "read there, the missing ones computed and added"),
}
cfg = _cli.parse(PROG, __doc__.split("\n\n")[0], SETTINGS, required=("checkpoint",))


def _fail(message):
    _cli.fail(PROG, message)


import _ritz_cache  # noqa: E402  (after _cli: it loads NumPy)
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from prbdm import surrogate as sg  # noqa: E402
from prbdm.chain import BeamBatch  # noqa: E402
from prbdm.dataset import refused_by_truth  # noqa: E402
from prbdm.dataset.schema import beam_for  # noqa: E402
from prbdm.errors import BadInput  # noqa: E402
from prbdm.surrogate.checkpoint import (  # noqa: E402
    read_checkpoint,
    save_checkpoint,
    training_sets,
)
from prbdm.surrogate.features import features  # noqa: E402
from prbdm.surrogate.neighbours import (  # noqa: E402
    NEIGHBOURS_TENSOR,
    build_reference,
    reference_rows,
)

#: the columns the features read (nu: drawn per beam in the smooth family)
GEOMETRY = ["index", "x", "half_width", "thickness", "nu", "length"]

path = Path(cfg["checkpoint"])
if cfg["count"] < 1:
    _fail(f"--count: must be >= 1, got {cfg['count']}")
if cfg["cache"] and Path(cfg["cache"]).exists() and not Path(cfg["cache"]).is_dir():
    _fail(f"--cache: must be a folder (training's runs/.feature-cache), got the file "
          f"{cfg['cache']!r}")
try:
    weights, meta = read_checkpoint(path)
    sur = sg.Surrogate(weights, meta, path)
except BadInput as exc:
    _fail(str(exc))


def made_again(s: dict) -> pd.DataFrame:
    """The panels of a recorded set that is not here, made again from its spec (index <=
    max_index; the records it lacked, its failures, are among them)."""
    rows = []
    for i in range(int(s["max_index"]) + 1):
        b = beam_for(s["spec"], i)
        rows.append({"index": i, "x": b.x, "half_width": b.half_width,
                     "thickness": b.thickness, "nu": b.material.nu, "length": b.length})
    table = pd.DataFrame(rows)
    if "refused_by_truth" in s:
        table = table[~refused_by_truth(table, s["spec"])].reset_index(drop=True)
    return table


tables, regenerated, lacking = [], [], 0
for s in training_sets(meta):
    if not {"path", "max_index", "spec"} <= s.keys():
        _fail(f"--checkpoint: {path.name} does not record its data set (path, max_index, spec), "
              "so its training panels cannot be found")
    where = _cli.find_path(s["path"])
    if where.exists():
        try:
            t, record = _sets.read_set(where, s["max_index"], refuse="refused_by_truth" in s,
                                           ranges=s.get("index_ranges"))
        except _sets.SetError as exc:
            _fail(f"--checkpoint: its data set {s['path']!r}: {exc}")
        if "sha256" in s and record["sha256"] != s["sha256"]:
            _fail(f"--checkpoint: data set {s['path']} (index <= {s['max_index']}) is not the one "
                  f"{path.name} was trained on (sha256 differs)")
        tables.append(t[GEOMETRY])
        print(f"{s['path']}: {len(t)} records read, sha256 as recorded")
    else:
        t0 = time.perf_counter()
        t = made_again(s)
        lacking += max(0, len(t) - int(s.get("size", len(t))))
        regenerated.append(s["path"])
        tables.append(t)
        print(f"{s['path']}: not here; {len(t)} panels made again from its spec "
              f"({time.perf_counter() - t0:.0f} s; the set recorded {s.get('size')})")
# a partial set (train_surrogate.py --partial) gave its training-split panels that are in no
# other set: those only
_seen = np.concatenate([_sets.panel_digests(t_) for t_, s_ in zip(tables, training_sets(meta))
                        if "partial_modes" not in s_])
for _j, _s in enumerate(training_sets(meta)):
    if "partial_modes" in _s:
        tables[_j] = _sets.partial_rows(tables[_j], _seen)
        if "rows_used" in _s and len(tables[_j]) != _s["rows_used"]:
            _fail(f"--checkpoint: {len(tables[_j])} panels of the partial set {_s['path']}, "
                  f"{path.name} records {_s['rows_used']}")
table = pd.concat(tables, ignore_index=True) if len(tables) > 1 else tables[0]
split = _sets.split(table["index"].to_numpy())
tr, te = split["train"], split["test"]
recorded_split = (meta.get("dataset") or {}).get("split") or {}
if not regenerated and recorded_split.get("test") not in (None, len(te)):
    _fail(f"--checkpoint: {len(te)} test panels, {path.name} records {recorded_split['test']}")

material = training_sets(meta)[0]["spec"]["beam"]["material"]
# a ritz network's features cost ~20 ms a panel (the planform Ritz estimate): with every set
# here and its sha256 checked, only the drawn reference panels and the test split are computed
# (the training split's ranges then are checked to hold them, not to be met)
subset = sur.feature_spec.ritz and not regenerated
if subset:
    keep = np.sort(np.concatenate([tr[reference_rows(len(tr), cfg["count"], cfg["seed"])], te]))
else:
    keep = np.arange(len(table))
t0 = time.perf_counter()
feats = np.full((len(table), len(sur.names)), np.nan)
ritz_cols = None
if cfg["cache"] and sur.feature_spec.ritz and not regenerated:
    # each set's rows among ``keep``, in the concatenated order
    starts = np.cumsum([0] + [len(t_) for t_ in tables])
    ritz_cols = _ritz_cache.set_columns(
        [t_.iloc[keep[(keep >= a) & (keep < b)] - a]
         for t_, a, b in zip(tables, starts[:-1], starts[1:])],
        training_sets(meta), sur.feature_spec.rfe_modes, Path(cfg["cache"]),
        basis=sur.feature_spec.ritz_basis)
feats[keep] = features(BeamBatch.from_table(table.iloc[keep], material), sur.feature_spec,
                       ritz_cols)
print(f"features of {len(keep)} of {len(table)} panels: {time.perf_counter() - t0:.0f} s")

# the panels are the training ones: the recorded ranges are those of the training split
f_tr = feats[np.intersect1d(tr, keep)]
lo, hi = f_tr.min(0), f_tr.max(0)
tol = 1e-9 * np.maximum(1.0, np.abs(sur.f_max - sur.f_min))
met = (np.abs(lo - sur.f_min) <= tol) | (np.any(np.abs(f_tr - sur.f_min) <= tol, axis=0))
met &= (np.abs(hi - sur.f_max) <= tol) | (np.any(np.abs(f_tr - sur.f_max) <= tol, axis=0))
met |= subset
outside = int(np.any((f_tr < sur.f_min - tol) | (f_tr > sur.f_max + tol), axis=1).sum())
if not met.all() or outside > lacking:
    bad = [sur.names[j] for j in np.flatnonzero(~met)[:3]]
    _fail(f"--checkpoint: the training panels found are not the ones {path.name} was trained on "
          f"(recorded features.min/max not met: {bad or 'none'}; {outside} panels outside them, "
          f"{lacking} allowed); nothing written")
print(f"training split {len(tr)} panels: " + (
    f"the {len(f_tr)} computed lie inside the recorded feature ranges" if subset else
    f"recorded feature ranges reproduced ({outside} outside them, of {lacking} records the "
    "sets lacked)"))

norm = (feats - sur.f_mean) / sur.f_std
try:
    reference, record = build_reference(norm[tr], norm[te], cfg["count"], cfg["seed"])
except BadInput as exc:                 # e.g. too few held-out panels to place the limit
    _fail(f"--checkpoint: {exc}; nothing written")
record["added_by"] = "training/add_neighbours.py"
if regenerated:
    record["panels_made_again"] = regenerated
h = record["held_out"]
print(f"reference: {record['count']} of {record['drawn_from']} training panels (seed "
      f"{record['seed']}); held-out ({h['beams']} panels) nearest distance median "
      f"{h['p50']:.4g}, p90 {h['p90']:.4g}, p99 {h['p99']:.4g}, p99.9 {h['p99.9']:.4g}, max "
      f"{h['max']:.4g}; limit {record['limit']:.4g}")
if cfg["write"]:
    out = {k: v for k, v in weights.items() if k != NEIGHBOURS_TENSOR}
    out[NEIGHBOURS_TENSOR] = reference
    save_checkpoint(path, out, {**{k: v for k, v in meta.items() if k != "weights_sha256"},
                                "neighbours": record})
    print(f"wrote {path} and {path.with_suffix('.json').name}: neighbours ({record['count']} "
          "panels)")
