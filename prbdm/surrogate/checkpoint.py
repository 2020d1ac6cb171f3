"""Checkpoints: one safetensors file holding the weights and, in its header, the JSON metadata
(data set spec, size and hash, seeds, versions, git commit, feature normalisation and ranges,
metrics, and ``weights_sha256``). A copy of the metadata is written beside it as ``NAME.json`` for
people to read.

Loading reads the file with ``safetensors`` (JSON header and raw arrays: no pickle, no code
executed, no torch) and checks it before anything is predicted with it (:func:`read_checkpoint`):
the weights match their recorded sha256, are finite and have the shapes the metadata implies, and
the normalisation is finite and of the right lengths. Each failure is a :class:`BadInput` naming
the file. :func:`prbdm.surrogate.load_checkpoint` turns the result into a
:class:`prbdm.surrogate.Surrogate`.
"""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import numpy as np

from ..errors import BadInput
from .decode import K_MODES
from .features import FeatureSpec, feature_names
from .neighbours import NEIGHBOURS_TENSOR, check_reference, reference_sha256

CHECKPOINT_FORMAT = "prbdm-surrogate"
CHECKPOINT_VERSION = 3      # 2: several members (an ensemble) and the choice poses; 3: the
#                             training panels' reference (neighbours), which an older prbdm refuses
#: folders searched for default checkpoints: $PRBDM_CHECKPOINTS (os.pathsep-separated), then the
#: shipped ones: prbdm/checkpoints/ in an installed wheel (pyproject.toml maps the repository's
#: top-level checkpoints/ there), the repository's checkpoints/ in a source checkout or an
#: editable install
_PRBDM = Path(__file__).resolve().parents[1]
PACKAGE_CHECKPOINTS = next((d for d in (_PRBDM / "checkpoints", _PRBDM.parent / "checkpoints")
                            if d.is_dir()), _PRBDM / "checkpoints")


def dataset_hash(table) -> str:
    """sha256 of a data set's records that training uses, sorted by index: ``index``, ``x``,
    ``half_width``, ``thickness``, ``omega_truth``, ``gamma``, ``k`` (float64 values and the list
    lengths, little-endian). Equal hashes mean equal training data."""
    if hasattr(table, "to_pandas"):
        table = table.to_pandas()
    table = table.sort_values("index")
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(table["index"].to_numpy(), dtype="<i8").tobytes())
    for col in ("x", "half_width", "thickness", "omega_truth", "gamma", "k"):
        vals = table[col].to_list()
        if isinstance(vals[0], (list, tuple, np.ndarray)):
            h.update(np.array([len(v) for v in vals], dtype="<i8").tobytes())
            flat = np.concatenate([np.asarray(v, dtype=np.float64) for v in vals])
        else:
            flat = np.asarray(vals, dtype=np.float64)
        h.update(col.encode())
        h.update(np.ascontiguousarray(flat, dtype="<f8").tobytes())
    return h.hexdigest()


def training_sets(metadata: dict) -> list[dict]:
    """The data sets a checkpoint was trained on, each ``{"path", "spec", "max_index", ...}``:
    ``dataset.sets`` when it saw several (``train_surrogate.py --data A,B``), else its one
    ``dataset``. Which beams it saw: index <= max_index of each set's stream (spec seed and
    generator), the test split (index % 10 == 9) excepted."""
    ds = metadata.get("dataset", {})
    return list(ds.get("sets") or [ds])


def matching_training_set(metadata: dict, spec: dict, allowed=("seed", "starts", "fit_batch")):
    """The training set whose spec equals ``spec`` but for the ``allowed`` fields (None when
    none does): another data set of the same kind of beams and truth."""
    from ..dataset import spec_difference

    def strip(d):
        return {k: v for k, v in d.items() if k not in allowed}

    for s in training_sets(metadata):
        if spec_difference(strip(s.get("spec", {})), strip(spec)) is None:
            return s
    return None


def accuracy_by_width(width_ratio, loss_percent, freq_err) -> list[dict]:
    """The held-out test per full-width band, as training records it (metadata ``test.by_width``)
    and :meth:`prbdm.surrogate.Surrogate.held_out_accuracy` reads it: for each band ``lo < width
    <= hi`` of prbdm.constants.ACCURACY_WIDTH_EDGES (the last open, ``hi`` None) holding at least
    ACCURACY_BAND_MIN_BEAMS panels, their count, the PRBDM loss median and p95 [%] and the median
    relative error of each predicted truth frequency. ``width_ratio`` (B,) full width over
    length, ``loss_percent`` (B,), ``freq_err`` (B, R)."""
    from ..constants import ACCURACY_BAND_MIN_BEAMS, ACCURACY_WIDTH_EDGES

    width = np.asarray(width_ratio, dtype=np.float64)
    loss = np.asarray(loss_percent, dtype=np.float64)
    err = np.asarray(freq_err, dtype=np.float64)
    edges = [0.0, *map(float, ACCURACY_WIDTH_EDGES), float("inf")]
    bands = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        sel = (width > lo) & (width <= hi)
        if sel.sum() >= ACCURACY_BAND_MIN_BEAMS:
            bands.append({"full_width": [lo, None if hi == float("inf") else hi],
                          "beams": int(sel.sum()),
                          "loss_median": float(np.median(loss[sel])),
                          "loss_p95": float(np.percentile(loss[sel], 95)),
                          "freq_err_median": [float(e) for e in np.median(err[sel], 0)]})
    return bands


def width_band_index(bands: list, width_ratio) -> np.ndarray:
    """For each full width over length in ``width_ratio``, the index in ``bands`` (a checkpoint's
    ``test.by_width``) of the first band ``lo < width <= hi`` (``hi`` None: open) holding it, -1
    where none does."""
    w = np.atleast_1d(np.asarray(width_ratio, dtype=np.float64))
    index = np.full(w.shape, -1)
    for j, b in reversed(list(enumerate(bands))):
        lo, hi = b["full_width"]
        index[(w > lo) & (w <= (np.inf if hi is None else hi))] = j
    return index


def weights_sha256(weights: dict) -> str:
    """sha256 of the weights, by name in sorted order: the name, the little-endian dtype and the
    shape (as JSON), then the raw little-endian bytes. It does not depend on the file's layout,
    so a re-saved checkpoint with the same weights keeps its hash. The training panels' reference
    (:data:`.neighbours.NEIGHBOURS_TENSOR`) is not a weight and is left out: it has its own hash
    (metadata ``neighbours.sha256``), so adding one leaves ``weights_sha256`` as it was."""
    h = hashlib.sha256()
    for name in sorted(k for k in weights if k != NEIGHBOURS_TENSOR):
        a = np.asarray(weights[name])
        a = np.ascontiguousarray(a, dtype=a.dtype.newbyteorder("<"))
        h.update(json.dumps([name, a.dtype.str, list(a.shape)]).encode())
        h.update(a.tobytes())
    return h.hexdigest()


def save_checkpoint(path, weights: dict, metadata: dict) -> Path:
    """Write ``weights`` (name -> NumPy array) and ``metadata`` (JSON-able) as one safetensors
    file (metadata in its header, key ``prbdm``, with ``weights_sha256`` of these weights), and a
    readable copy ``PATH`` with ``.json``. Each file is written whole or not at all. ``weights``
    may hold the training panels' reference (:data:`.neighbours.NEIGHBOURS_TENSOR`) with its
    record in ``metadata["neighbours"]``: its ``sha256`` is written there."""
    from safetensors.numpy import save

    from ..files import atomic_write

    path = Path(path)
    arrays = {k: np.ascontiguousarray(v) for k, v in weights.items()}
    for name, a in arrays.items():
        if not np.all(np.isfinite(a)):
            raise BadInput(f"checkpoint {str(path)!r}: weight {name} is not finite; nothing "
                           "written")
    meta = {"format": CHECKPOINT_FORMAT, "format_version": CHECKPOINT_VERSION, **metadata,
            "weights_sha256": weights_sha256(arrays)}
    if NEIGHBOURS_TENSOR in arrays:
        if not isinstance(meta.get("neighbours"), dict):
            raise BadInput(f"checkpoint {str(path)!r}: tensor {NEIGHBOURS_TENSOR} without its "
                           "metadata 'neighbours'; nothing written")
        meta["neighbours"] = {**meta["neighbours"],
                              "sha256": reference_sha256(arrays[NEIGHBOURS_TENSOR])}
    text = json.dumps(meta, allow_nan=False)
    path.parent.mkdir(parents=True, exist_ok=True)
    # both files whole or not at all (the JSON written second: a checkpoint found without its
    # JSON beside it is refused, never read with a stale one)
    atomic_write(path, save(arrays, metadata={"prbdm": text}))
    atomic_write(path.with_suffix(".json"), json.dumps(meta, indent=1, allow_nan=False) + "\n")
    return path


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text[:200]}" if text else type(exc).__name__


def read_checkpoint(path) -> tuple[dict, dict]:
    """(tensors, metadata) of a checkpoint file, checked (see the module docstring and
    :func:`check_checkpoint`). BadInput naming the file for a missing, corrupt, foreign or
    inconsistent one."""
    from safetensors.numpy import safe_open

    path = Path(path)
    where = f"checkpoint {str(path)!r}"
    if not path.is_file():
        raise BadInput(f"checkpoint: no such file {str(path)!r}")
    try:
        with safe_open(str(path), framework="numpy") as fh:
            header = fh.metadata() or {}
            tensors = {name: fh.get_tensor(name) for name in fh.keys()}
    except OSError as exc:
        raise BadInput(f"{where}: cannot read it ({exc.strerror or _one_line(exc)})") from None
    except Exception as exc:        # the safetensors parser's errors have no public base class
        raise BadInput(f"{where} is not a safetensors file ({_one_line(exc)})") from None
    try:
        metadata = json.loads(header["prbdm"])
        if not isinstance(metadata, dict):
            raise TypeError("not an object")
    except (KeyError, TypeError, ValueError):
        raise BadInput(f"{where} has no prbdm surrogate metadata") from None
    if metadata.get("format") != CHECKPOINT_FORMAT:
        raise BadInput(f"{where} is not a prbdm surrogate checkpoint")
    version = metadata.get("format_version", 0)
    if not isinstance(version, int) or version > CHECKPOINT_VERSION:
        raise BadInput(f"{where}: format version {version!r} is newer than this prbdm "
                       f"understands ({CHECKPOINT_VERSION}); upgrade prbdm")
    recorded = metadata.get("weights_sha256")
    if recorded is not None and recorded != weights_sha256(tensors):
        raise BadInput(f"{where}: the weights do not match their recorded weights_sha256 (the "
                       "file is corrupt or was edited); restore or retrain it")
    ref = tensors.get(NEIGHBOURS_TENSOR)
    nb = metadata.get("neighbours")
    if ref is not None and (not isinstance(nb, dict) or nb.get("sha256") != reference_sha256(ref)):
        raise BadInput(f"{where}: the training panels' reference does not match its recorded "
                       "neighbours.sha256 (the file is corrupt or was edited); restore it or "
                       "add it again with training/add_neighbours.py")
    try:
        check_checkpoint(tensors, metadata)
    except BadInput as exc:
        raise BadInput(f"{where}: {exc}") from None
    return tensors, metadata


def _vector(meta, key, length, name, positive=False) -> np.ndarray:
    v = np.asarray(meta[key], dtype=np.float64)
    if v.shape != (length,):
        raise BadInput(f"{name} has shape {v.shape}, expected ({length},)")
    if not np.all(np.isfinite(v)) or (positive and not np.all(v > 0)):
        raise BadInput(f"{name} has {'non-positive or ' if positive else ''}non-finite values")
    return v


def member_prefixes(members: int) -> list[str]:
    """Name prefixes of the ensemble members' weights: none for a single network."""
    return [""] if members == 1 else [f"members.{j}." for j in range(members)]


def check_checkpoint(tensors: dict, metadata: dict) -> None:
    """Raise BadInput (without the file name) unless the weights and the metadata agree: every
    weight finite and floating point; each member's layers 0..L-1 chain from the feature count to
    the head's H (n + 1) + m + R outputs; the normalisation and feature ranges finite and of the
    feature, pose and mode counts; the poses (m, n)."""
    try:
        n = int(metadata["joints"])
        net = metadata["network"]
        members, hyp = int(net.get("members", 1)), int(net.get("hypotheses", 1))
        k_mode = str(net.get("k_mode", "direct"))
        spec = FeatureSpec(**metadata["features"]["spec"])
        names = list(metadata["features"]["names"])
        norm = metadata["normalisation"]
        poses = np.asarray(metadata["poses"], dtype=np.float64)
        m, R = len(norm["logk_mean"]), len(norm["freq_mean"])
        modes = int(metadata["modes"])
        select = [int(i) for i in net.get("select_poses", [])]
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise BadInput(f"incomplete surrogate metadata ({_one_line(exc)})") from None
    if n < 1 or members < 1 or hyp < 1 or not 1 <= modes <= n:
        raise BadInput(f"metadata: joints {n}, modes {modes}, members {members} or hypotheses "
                       f"{hyp} out of range")
    if k_mode not in K_MODES:
        raise BadInput(f"unknown k_mode {k_mode!r} (known: {', '.join(K_MODES)})")
    if names != feature_names(spec):
        raise BadInput(f"the {len(names)} feature names do not match the feature spec "
                       f"({len(feature_names(spec))} features)")
    if poses.shape != (m, n) or not np.all(np.isfinite(poses)):
        raise BadInput(f"poses of shape {poses.shape} disagree with the SCF normalisation and "
                       f"joints ({m}, {n})")
    if any(not -m <= i < m for i in select):
        raise BadInput(f"network.select_poses {select} outside the {m} poses")
    F = len(names)
    try:
        _vector(norm, "feature_mean", F, "normalisation.feature_mean")
        _vector(norm, "feature_std", F, "normalisation.feature_std", positive=True)
        for key in ("logk_mean", "logk_std", "freq_mean", "freq_std"):
            _vector(norm, key, m if key.startswith("logk") else R, f"normalisation.{key}",
                    positive=key.endswith("std"))
        lo = _vector(metadata["features"], "min", F, "features.min")
        hi = _vector(metadata["features"], "max", F, "features.max")
    except BadInput:
        raise
    except (KeyError, TypeError, ValueError) as exc:
        raise BadInput(f"incomplete surrogate normalisation ({_one_line(exc)})") from None
    if np.any(lo > hi):
        raise BadInput("features.min exceeds features.max")
    if R < modes or R > spec.rfe_modes:
        raise BadInput(f"{R} frequency outputs, need between modes = {modes} and rfe_modes = "
                       f"{spec.rfe_modes}")
    out = hyp * (n + 1) + m + R
    expected = set()
    for pre in member_prefixes(members):
        count = len([k for k in tensors if k.startswith(pre + "layers.")
                     and k.endswith(".weight")])
        if count == 0:
            raise BadInput(f"no weights {pre}layers.*")
        rows = F
        for i in range(count):
            w, b = tensors.get(f"{pre}layers.{i}.weight"), tensors.get(f"{pre}layers.{i}.bias")
            if w is None or b is None:
                raise BadInput(f"weights {pre}layers.{i}.weight/bias missing")
            want = out if i == count - 1 else w.shape[0] if w.ndim == 2 else -1
            if w.ndim != 2 or w.shape[1] != rows or w.shape[0] != want or b.shape != (want,):
                raise BadInput(f"weight {pre}layers.{i} has shape {w.shape} and bias "
                               f"{b.shape}; expected ({want if want > 0 else 'N'}, {rows}) "
                               f"and its bias")
            for name, a in ((f"{pre}layers.{i}.weight", w), (f"{pre}layers.{i}.bias", b)):
                if a.dtype.kind != "f":
                    raise BadInput(f"weight {name} has dtype {a.dtype}, need floating point")
                if not np.all(np.isfinite(a)):
                    raise BadInput(f"weight {name} has non-finite values")
            rows = w.shape[0]
            expected |= {f"{pre}layers.{i}.weight", f"{pre}layers.{i}.bias"}
    if "neighbours" in metadata or NEIGHBOURS_TENSOR in tensors:
        if not isinstance(metadata.get("neighbours", {}), dict):
            raise BadInput("metadata 'neighbours' is not an object")
        check_reference(tensors, metadata, F)
        expected.add(NEIGHBOURS_TENSOR)
    extra = sorted(set(tensors) - expected)
    if extra:
        raise BadInput(f"unexpected weights {', '.join(extra[:3])} for {members} member(s)")


def _checkpoint_dirs() -> list[Path]:
    dirs = [Path(p) for p in os.environ.get("PRBDM_CHECKPOINTS", "").split(os.pathsep) if p]
    return dirs + [PACKAGE_CHECKPOINTS]


from ..constants import OBJECTIVES  # noqa: E402


def checkpoint_name(joints: int, truth: str, objective: str = "eigenvalue") -> str:
    """``TRUTH-nJOINTS.safetensors`` (the paper's eigenvalue objective), or
    ``TRUTH-nJOINTS-frequency.safetensors`` (the frequency objective)."""
    suffix = "" if objective == "eigenvalue" else f"-{objective}"
    return f"{truth}-n{joints}{suffix}.safetensors"


def available_checkpoints() -> list[Path]:
    """Every default checkpoint found (``TRUTH-nJOINTS[-OBJECTIVE].safetensors`` in the
    checkpoint folders)."""
    found = []
    for d in _checkpoint_dirs():
        found += sorted(d.glob("*-n*.safetensors")) if d.is_dir() else []
    return found


def default_checkpoint(joints: int, truth: str = "beam", objective: str = "eigenvalue") -> Path:
    """The default checkpoint for ``joints`` joints, the ``truth`` model and the ``objective``:
    the first :func:`checkpoint_name` in $PRBDM_CHECKPOINTS (folders separated by os.pathsep),
    then in the shipped ``checkpoints/``. BadInput listing what exists when there is none."""
    if objective not in OBJECTIVES:
        raise BadInput(f"--objective: must be one of {', '.join(OBJECTIVES)}, got {objective!r}")
    # a network trained at rest (the shape pose target, the default's) serves either objective:
    # at rest both have one optimum; it answers before an objective's own network of the paper's
    # poses, so that the objective does not change the pose target
    plain = checkpoint_name(joints, truth, "eigenvalue")
    name = checkpoint_name(joints, truth, objective)
    for d in _checkpoint_dirs():
        if (d / plain).is_file() and _trained_at_rest(d / plain):
            return d / plain
        if (d / name).is_file():
            return d / name
    have = ", ".join(p.stem for p in available_checkpoints()) or "none"
    raise BadInput(f"--joints {joints} --truth {truth} --objective {objective}: no trained "
                   f"surrogate checkpoint {name!r} (available: {have}); train one with "
                   "training/train_surrogate.py or pass --checkpoint PATH")


def pose_target(metadata: dict) -> str:
    """A checkpoint's pose target (:mod:`prbdm.pose_target`) from its metadata: the one recorded,
    else ``"shape"`` for a network trained at the one straight pose, ``"straight"`` otherwise."""
    from ..poses import is_rest

    return str(metadata.get("pose_target")
               or ("shape" if is_rest(metadata.get("poses", [[1.0]])) else "straight"))


def _trained_at_rest(path: Path) -> bool:
    """Whether the checkpoint ``path`` was trained at rest (its pose target ``shape``), read from
    the metadata copy beside it (``.json``); False where there is none."""
    try:
        meta = json.loads(path.with_suffix(".json").read_text())
    except (OSError, ValueError):
        return False
    return pose_target(meta) == "shape"
