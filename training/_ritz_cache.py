"""The Rayleigh-Ritz columns of the features, kept between training runs.

The plate's own estimate (:func:`prbdm.surrogate.features.ritz_log_omega`) costs ~20 ms a panel:
minutes for a training set. A data set's panel is fixed by the set's spec and its index, so the
columns are kept per set (``ritz-<key>.npz`` in a folder beside the checkpoint), keyed by the
set's spec, the number of modes and the code that computes them, one row per index, with a
digest of the row's planform, thickness and Poisson's ratio that must match when it is read
back. A run computes only the panels no earlier run did (a set still being labelled grows).
The files may be deleted at any time (the next run computes them again); an edit of the code
starts new ones, and a file that cannot be read is ignored (and replaced).
"""
from __future__ import annotations

import hashlib
import inspect
import json
import os
import tempfile
import zipfile
from pathlib import Path

import numpy as np

from prbdm.chain import BeamBatch
from prbdm.surrogate import features as features_module
from prbdm.truth import modes as modes_module
from prbdm.truth import planform_ritz

from _sets import panel_digests

# the code that computes the columns, as imported (an edit during a run does not change this
# run's key): the Ritz plate, the spectrum, the features' call and the batch's nondimensional
# planform (BeamBatch.from_arrays: x / L, padded stations)
_CODE = (Path(planform_ritz.__file__).read_bytes() + Path(modes_module.__file__).read_bytes()
         + inspect.getsource(features_module.ritz_log_omega).encode()
         + inspect.getsource(BeamBatch.from_arrays).encode())


#: computed panels between two saves (a minute or two of a richer basis on 2 cores)
SAVE_EVERY = 2000


def _key(spec: dict, modes: int, basis=()) -> str:
    head = {"spec": spec, "modes": modes}
    if basis:                    # the default basis: as before ritz_basis existed
        head["basis"] = [int(v) for v in basis]
    head = json.dumps(head, sort_keys=True).encode()
    return hashlib.sha256(head + _CODE).hexdigest()[:24]


def _save(path: Path, index, digest, cols):
    """The file, whole or not at all (another run may write the same set: its own temporary)."""
    order = np.argsort(index, kind="stable")
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, partial = tempfile.mkstemp(dir=path.parent, prefix=path.name, suffix=".partial.npz")
    try:
        with os.fdopen(fd, "wb") as f:
            np.savez(f, index=index[order], digest=digest[order], columns=cols[order])
        os.replace(partial, path)
    finally:
        Path(partial).unlink(missing_ok=True)


def ritz_columns(table, spec: dict, modes: int, folder: Path, log=print,
                 basis=()) -> np.ndarray:
    """:func:`prbdm.surrogate.features.ritz_log_omega` of a data set's records ``table`` (pandas,
    with ``index``), its rows read from ``folder`` where an earlier run computed them and the
    rest computed now and added there, ``SAVE_EVERY`` panels at a time (a killed run keeps what
    it computed). ``basis``: the Ritz basis (``FeatureSpec.ritz_basis``)."""
    path = Path(folder) / f"ritz-{_key(spec, modes, basis)}.npz"
    index, digest = table["index"].to_numpy().astype(np.int64), panel_digests(table)
    out = np.full((len(table), modes), np.nan)
    kept_index, kept_digest, kept_cols = index[:0], digest[:0], out[:0]
    hit = np.zeros(len(index), bool)
    if len(np.unique(index)) != len(index):
        raise ValueError("ritz_columns: a table with repeated indices")
    try:
        with np.load(path) as kept:
            kept_index, kept_digest, kept_cols = kept["index"], kept["digest"], kept["columns"]
    except FileNotFoundError:
        pass
    except (OSError, ValueError, KeyError, zipfile.BadZipFile) as exc:
        log(f"  {path.name} unreadable ({type(exc).__name__}): computed again")
        kept_index, kept_digest, kept_cols = index[:0], digest[:0], out[:0]
    else:
        if len(kept_index):
            pos = np.clip(np.searchsorted(kept_index, index), 0, len(kept_index) - 1)
            hit = (kept_index[pos] == index) & (kept_digest[pos] == digest)
            out[hit] = kept_cols[pos[hit]]
    todo = np.flatnonzero(~hit)
    log(f"  Ritz columns of {spec['beam'].get('family', 'paper')} panels, seed {spec['seed']}: "
        f"{int(hit.sum())} kept in {path.name}, {len(todo)} to compute")
    if len(kept_index):          # rows this run does not read stay in the file
        other = ~np.isin(kept_index, index)
        kept_index, kept_digest, kept_cols = (kept_index[other], kept_digest[other],
                                              kept_cols[other])
    for start in range(0, len(todo), SAVE_EVERY):
        part = todo[start:start + SAVE_EVERY]
        batch = BeamBatch.from_table(table.iloc[part], spec["beam"]["material"])
        out[part] = features_module.ritz_log_omega(batch, modes, basis)
        hit[part] = True
        _save(path, np.concatenate([index[hit], kept_index]),
              np.concatenate([digest[hit], kept_digest]),
              np.concatenate([out[hit], kept_cols]))
    return out


def set_columns(tables, sets, modes: int, folder: Path, log=print, basis=()) -> np.ndarray:
    """:func:`ritz_columns` of several data sets' records, concatenated in their order:
    ``tables[i]`` (pandas, with ``index``) read from the set whose recorded entry is
    ``sets[i]`` (its ``spec``)."""
    return np.concatenate([ritz_columns(t, s["spec"], modes, folder, log, basis=basis)
                           for t, s in zip(tables, sets)])
