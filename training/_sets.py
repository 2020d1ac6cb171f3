"""The data sets a network is trained on, read as training reads them: one home for
``train_surrogate.py``, which records each set in the checkpoint (``dataset.sets``), and
``retest.py``, which reads them back from that record.

A set's records are its ``ok`` ones with index <= ``max_index`` (-1: all), less those whose beam
today's truth refuses (prbdm.dataset.refused_by_truth: e.g. plate panels with a corner sharper
than the mesh resolves, labelled before that limit existed); its sha256
(prbdm.surrogate.checkpoint.dataset_hash) says that two runs saw the same records.
"""
from __future__ import annotations

import _cli

#: the columns training reads
COLUMNS = ["index", "x", "half_width", "thickness", "length", "omega_truth", "gamma", "k",
           "loss_percent", "fit_time_s", "gamma_spread"]


def parse_partial(text: str, data_sets=()) -> list:
    """``[(path, K), ...]`` of ``--partial`` (``PATH:K`` comma-separated: data sets of which the
    first K truth modes alone are the target), each a data set folder not in ``data_sets``."""
    from pathlib import Path

    full = {Path(d).resolve() for d in data_sets}
    out = []
    for item in (t.strip() for t in text.split(",")):
        if not item:
            continue
        path, _, k = item.rpartition(":")
        if not path or not k.isdigit() or int(k) < 1:
            raise SetError(f"each one PATH:K with K >= 1 (the modes known), got {item!r}")
        if not Path(path, "_manifest.json").is_file():
            raise SetError(f"{path!r} is not a data set folder (no _manifest.json)")
        if Path(path).resolve() in full:
            raise SetError(f"{path!r} is in --data as well")
        out.append((path, int(k)))
    return out


def panel_digests(table):
    """An 8-byte digest of each record's panel (x, half-width, thickness, Poisson's ratio): the
    same panel in two data sets has the same digest."""
    import hashlib

    import numpy as np

    nu = table["nu"].to_numpy() if "nu" in table.columns else np.zeros(len(table))
    out = np.empty(len(table), dtype=np.uint64)
    for i, (x, w, t, v) in enumerate(zip(table["x"], table["half_width"],
                                         table["thickness"].to_numpy(), nu)):
        h = hashlib.blake2b(np.asarray(x, np.float64).tobytes()
                            + np.asarray(w, np.float64).tobytes()
                            + np.float64(t).tobytes() + np.float64(v).tobytes(), digest_size=8)
        out[i] = np.frombuffer(h.digest(), dtype=np.uint64)[0]
    return out


class SetError(ValueError):
    """A data set that cannot be read or holds no records to use: the message names it."""


def index_ranges(index) -> list:
    """The sorted distinct ``index`` values as inclusive runs ``[[first, last], ...]``: the
    records a run read, compactly (a data set's failures and a labelling front leave gaps)."""
    import numpy as np

    idx = np.unique(np.asarray(index, dtype=np.int64))
    if not len(idx):
        return []
    cut = np.flatnonzero(np.diff(idx) != 1)
    return [[int(a), int(b)] for a, b in zip(idx[np.r_[0, cut + 1]], idx[np.r_[cut, len(idx) - 1]])]


def read_set(path, max_index: int = -1, columns=COLUMNS, refuse: bool = True, ranges=None):
    """(table, record) of the data set at ``path``: its records as a pandas DataFrame, and what a
    checkpoint records of it (path, spec, size, records read, max_index, refused, manifest count,
    sha256, the commit that made it). ``refuse`` False keeps the records today's truth refuses
    (a checkpoint trained before that filter, which records no ``refused_by_truth``). A set
    still being labelled is read up to its labelling front at most (``labelling_front`` in the
    record), so that ``max_index`` names the records read. ``ranges`` (a record's
    ``index_ranges``): exactly those records, wherever the labelling front has gone since."""
    import numpy as np

    from prbdm import dataset as ds
    from prbdm.errors import BadInput
    from prbdm.surrogate.checkpoint import dataset_hash

    try:
        manifest = ds.read_manifest(path)
        spec = manifest["spec"]
        table = ds.read_table(path, columns=columns, status="ok").to_pandas()
    except (BadInput, OSError, KeyError, ValueError) as exc:
        raise SetError(f"cannot read the data set {str(path)!r} "
                       f"({str(exc).splitlines()[0]})") from None
    if "thickness" in table.columns and "nu" not in table.columns:
        # a set of one material: its Poisson's ratio on every record, so that sets that draw one
        # per beam (the smooth family) and sets that do not can be trained together
        table["nu"] = float(spec["beam"]["material"]["nu"])
    read = len(table)
    top = int(table["index"].max()) if (max_index < 0 and read) else max_index
    # a set still being labelled (two workers write their parts out of order) is read only up to
    # its labelling front, the last index below which every record exists: beyond it the records
    # read would depend on the moment, and no max_index could name them again
    capped = False
    if ranges is None:                     # recorded ranges name the records themselves
        every = np.unique(ds.read_table(path, columns=["index"]).column("index").to_numpy())
        gaps = np.flatnonzero(every != np.arange(len(every)))
        front = int(gaps[0] if len(gaps) else len(every)) - 1
        capped = top > front and len(every) < (manifest.get("count") or 0)
    if capped:
        top = front
    table = table[table["index"] <= top].reset_index(drop=True)
    if ranges is not None:
        wanted = np.concatenate([np.arange(a, b + 1) for a, b in ranges] or [np.zeros(0, int)])
        table = table[np.isin(table["index"].to_numpy(), wanted)].reset_index(drop=True)
    refused = ds.refused_by_truth(table, spec) if refuse else None
    if refuse:
        table = table[~refused].reset_index(drop=True)
    if len(table) == 0:
        raise SetError(f"no ok records with index <= {top} in {str(path)!r}")
    record = {"path": _cli.portable_path(path), "spec": spec, "size": len(table),
              "records_ok_read": read, "max_index": top,
              **({"labelling_front": "read up to the index below which every record exists; the "
                                     "set was still being labelled"} if capped else {}),
              **({"refused_by_truth": int(refused.sum())} if refuse else {}),
              "manifest_count": manifest.get("count"), "sha256": dataset_hash(table),
              "index_ranges": index_ranges(table["index"]),
              "dataset_git_commit": manifest.get("git_commit")}
    return table, record


#: what sets trained together must agree on (with the material): what defines their labels
SAME_FIELDS = ("truth", "truth_modes", "joints", "modes", "law", "poses", "starts", "objective")


def read_sets(paths, max_index: int = -1):
    """(tables, records) of the data sets trained together (:func:`read_set` each): they must
    agree on ``SAME_FIELDS`` and the material, and differ only in their random beams (seed,
    generator bounds), e.g. the paper's wide panels and a narrower range."""
    from prbdm import dataset as ds
    from prbdm.dataset.schema import flatten

    tables, records = [], []
    for path in paths:
        table, record = read_set(path, max_index)
        spec = record["spec"]
        if spec["law"] != "beam":
            raise SetError(f"the surrogate supports the 'beam' law only, {path} has "
                           f"{spec['law']!r}")
        if records:
            a = flatten({"objective": ds.DEFAULT_OBJECTIVE, **records[0]["spec"]})
            b = flatten({"objective": ds.DEFAULT_OBJECTIVE, **spec})
            for f in SAME_FIELDS + tuple(k for k in a if k.startswith("beam.material.")):
                if a.get(f) != b.get(f):
                    raise SetError(f"{path} differs from {paths[0]} in {f} ({b.get(f)!r} vs "
                                   f"{a.get(f)!r}); sets trained together must agree on "
                                   f"{', '.join(SAME_FIELDS)}, material")
        tables.append(table)
        records.append(record)
    return tables, records


def split(index) -> dict:
    """Row positions of the test (``index % 10 == 9``), validation (``== 8``) and training (the
    rest) beams, from the records' ``index``: a beam's split depends on its index alone, so
    every run and every later measurement of a set splits it alike."""
    import numpy as np

    index = np.asarray(index)
    return {"test": np.flatnonzero(index % 10 == 9), "val": np.flatnonzero(index % 10 == 8),
            "train": np.flatnonzero(index % 10 < 8)}


def partial_rows(table, seen):
    """The records of a partial set a network learns from: its training split's, less the panels
    among ``seen`` (digests of the full sets' panels)."""
    import numpy as np

    keep = (table["index"].to_numpy() % 10 < 8) & ~np.isin(panel_digests(table), seen)
    return table[keep].reset_index(drop=True)


def read_partial(path, modes_known: int, spec: dict, seen, modes: int):
    """(table, record) of a partial set (``--partial PATH:K``): its training-split records whose
    panel is not among ``seen`` (digests of the full sets' panels), ``omega_truth`` padded to
    ``modes`` with NaN past the first K. ``spec``: the full sets' (same truth and material)."""
    import numpy as np

    table, record = read_set(path)
    other = record["spec"]
    if other["truth"] != spec["truth"] or other["beam"]["material"] != spec["beam"]["material"]:
        raise SetError(f"{path} differs from the --data sets in its truth or material")
    if modes_known > min(other["truth_modes"], modes):
        raise SetError(f"{path} holds {other['truth_modes']} truth modes, {modes} are trained; "
                       f"K = {modes_known} must be at most both")
    table = partial_rows(table, seen)
    table["omega_truth"] = [np.r_[np.asarray(o, float)[:modes_known],
                                  np.full(modes - modes_known, np.nan)]
                            for o in table["omega_truth"]]
    return table, {**record, "partial_modes": int(modes_known), "rows_used": len(table),
                   "rows_used_are": "the training split's panels that are in no --data set"}
