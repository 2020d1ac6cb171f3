"""Every answer checks itself against the panels its network was trained on (issue 35): the
training panels' reference a checkpoint keeps (prbdm.surrogate.neighbours), its checks on load,
and the warning for a panel whose every feature lies in its range but whose combination is unlike
any training panel."""
from __future__ import annotations

import json
import subprocess
import sys
import warnings

import numpy as np
import pytest

from prbdm import surrogate as sg
from prbdm.errors import BadInput
from prbdm.geometry import Beam, random_beam
from prbdm.surrogate.checkpoint import (
    PACKAGE_CHECKPOINTS,
    read_checkpoint,
    save_checkpoint,
    weights_sha256,
)
from prbdm.surrogate.neighbours import (
    LIMIT_QUANTILE,
    NEIGHBOURS_TENSOR,
    build_reference,
    nearest_distance,
)

SHIPPED = sorted(p.stem for p in PACKAGE_CHECKPOINTS.glob("*-n*.safetensors"))
#: a narrow strip ending in a wide paddle: each feature of beam-n4 lies in its training range
#: (the random beams reach every width in every cell), their combination in none of its
#: training panels (nearest distance 17.0, limit 8.6 when the reference was added)
PADDLE = {"name": "paddle", "x": [0.0, 0.9, 1.0], "half_width": [0.01, 0.01, 0.5],
          "thickness": 0.01}


def test_nearest_distance_is_the_brute_force_one():
    rng = np.random.default_rng(0)
    ref = rng.normal(size=(300, 7)).astype(np.float32)
    q = rng.normal(size=(2100, 7))          # more than one block
    brute = np.sqrt(((q[:, None, :] - ref[None].astype(np.float64)) ** 2).sum(-1)).min(1)
    assert np.allclose(nearest_distance(q, ref), brute, rtol=1e-9, atol=1e-9)
    q[3, 2] = np.nan
    assert np.isnan(nearest_distance(q, ref)[3])


def test_build_reference_draws_training_rows_and_places_the_limit():
    rng = np.random.default_rng(1)
    train, held = rng.normal(size=(5000, 4)), rng.normal(size=(1000, 4))
    ref, rec = build_reference(train, held, count=400, seed=3)
    assert ref.shape == (400, 4) and ref.dtype == np.float32
    # every reference row is a training row, drawn without repeats, the same for the same seed
    rows = {tuple(r) for r in train.astype(np.float32)}
    assert all(tuple(r) in rows for r in ref) and len({tuple(r) for r in ref}) == 400
    assert np.array_equal(build_reference(train, held, count=400, seed=3)[0], ref)
    dist = nearest_distance(held, ref)
    assert rec["limit"] == pytest.approx(np.percentile(dist, LIMIT_QUANTILE))
    assert rec["held_out"]["p99"] == pytest.approx(np.percentile(dist, 99))
    assert rec["count"] == 400 and rec["drawn_from"] == 5000 and rec["seed"] == 3
    with pytest.raises(BadInput, match="too few"):
        build_reference(train, held[:50])


def _with_reference(tensors, meta, F, count=64, seed=0):
    rng = np.random.default_rng(seed)
    ref, rec = build_reference(rng.normal(size=(500, F)), rng.normal(size=(200, F)), count)
    return {**tensors, NEIGHBOURS_TENSOR: ref}, {**meta, "neighbours": rec}


def test_the_reference_is_kept_hashed_and_checked(tmp_path):
    """Adding a reference leaves the weights and weights_sha256 as they were; a reference edited
    after saving, one without its record, or of the wrong width is refused naming the file."""
    from test_surrogate import _raw_save

    tensors, meta = read_checkpoint(PACKAGE_CHECKPOINTS / "beam-n3.safetensors")
    weights = {k: v for k, v in tensors.items() if k != NEIGHBOURS_TENSOR}
    meta = {k: v for k, v in meta.items() if k not in ("weights_sha256", "neighbours")}
    F = len(meta["features"]["names"])
    t, m = _with_reference(weights, meta, F)
    path = save_checkpoint(tmp_path / "ref.safetensors", t, m)
    back, meta2 = read_checkpoint(path)
    assert meta2["weights_sha256"] == weights_sha256(weights)
    assert np.array_equal(back[NEIGHBOURS_TENSOR], t[NEIGHBOURS_TENSOR])
    assert json.loads(path.with_suffix(".json").read_text())["neighbours"]["sha256"] == \
        meta2["neighbours"]["sha256"]
    sur = sg.load_checkpoint(path)
    assert sur.reference.shape == (64, F)

    edited = dict(back)
    edited[NEIGHBOURS_TENSOR] = back[NEIGHBOURS_TENSOR].copy()
    edited[NEIGHBOURS_TENSOR][0, 0] += 1
    with pytest.raises(BadInput, match=r"edited\.safetensors.*neighbours\.sha256"):
        sg.load_checkpoint(_raw_save(tmp_path / "edited.safetensors", edited, meta2))
    bare = {k: v for k, v in meta2.items() if k != "neighbours"}
    with pytest.raises(BadInput, match=r"bare\.safetensors.*neighbours"):
        sg.load_checkpoint(_raw_save(tmp_path / "bare.safetensors", back, bare))
    narrow = dict(back, **{NEIGHBOURS_TENSOR: back[NEIGHBOURS_TENSOR][:, :3].copy()})
    rehashed = dict(meta2, neighbours=dict(meta2["neighbours"]))
    from prbdm.surrogate.neighbours import reference_sha256
    rehashed["neighbours"]["sha256"] = reference_sha256(narrow[NEIGHBOURS_TENSOR])
    with pytest.raises(BadInput, match=r"shape"):
        sg.load_checkpoint(_raw_save(tmp_path / "narrow.safetensors", narrow, rehashed))
    with pytest.raises(BadInput, match="without its metadata"):
        save_checkpoint(tmp_path / "x.safetensors", t, meta)


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_checkpoints_keep_their_training_panels(name):
    tensors, meta = read_checkpoint(PACKAGE_CHECKPOINTS / f"{name}.safetensors")
    nb = meta.get("neighbours")
    assert nb is not None, f"{name}: add it with training/add_neighbours.py"
    ref = tensors[NEIGHBOURS_TENSOR]
    assert ref.shape == (nb["count"], len(meta["features"]["names"]))
    held = nb["held_out"]
    assert 0 < held["p50"] <= held["p99"] <= nb["limit"] <= held["max"]
    assert nb["limit"] == held["p99.9"]


def test_panels_like_the_training_ones_pass_and_an_unlike_one_is_warned():
    """beam-n4: 64 random beams of seed 1 (its generator, a stream it never saw), a prismatic
    strip and a tapered one are near a training panel; the paddle, none of whose features is
    out of its range, is unlike them all: an OutOfDistributionWarning saying so."""
    sur = sg.load_checkpoint(PACKAGE_CHECKPOINTS / "beam-n4.safetensors")
    limit = sur.neighbours["limit"]
    like = [random_beam(1, i) for i in range(64)]
    like += [Beam(x=[0, 1], half_width=[0.1, 0.1], thickness=0.01),
             Beam(x=[0, 1], half_width=[0.1, 0.05], thickness=0.01)]
    pred = sur.predict(like, warn=False)
    assert not pred.ood.any() and not pred.unlike.any(), pred.neighbour_distance.max()
    assert np.all(pred.neighbour_distance <= limit)

    paddle = Beam.from_dict(PADDLE)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        pred = sur.predict([paddle])
    assert not pred.ood.any()                       # every feature in its range
    assert pred.unlike[0] and pred.neighbour_distance[0] > 1.5 * limit
    texts = [str(w.message) for w in caught if w.category is sg.OutOfDistributionWarning]
    assert len(texts) == 1 and "no training panel of checkpoint beam-n4" in texts[0]
    assert f"held-out p99 {sur.neighbours['held_out']['p99']:.3g}" in texts[0]
    assert pred.warnings == texts


def test_predict_says_so_on_the_command_line(tmp_path):
    paddle = tmp_path / "paddle.json"
    paddle.write_text(json.dumps(PADDLE))
    strip = tmp_path / "strip.json"
    strip.write_text(json.dumps({"x": [0, 1], "half_width": [0.02, 0.01], "thickness": 0.01}))
    for path, unlike in ((paddle, True), (strip, False)):
        run = subprocess.run([sys.executable, "-m", "prbdm.cli", "predict", str(path),
                              "--joints", "4", "--truth", "beam", "--json"],
                             capture_output=True, text=True)
        assert run.returncode == 0, run.stderr
        out = json.loads(run.stdout)
        said = [w for w in out["warnings"] if "no training panel" in w]
        assert bool(said) == unlike, out["warnings"]
        assert ("warning: no training panel of checkpoint beam-n4.safetensors is like this one "
                "(nearest distance" in run.stderr) == unlike


def _close(a, b, rtol=1e-9) -> bool:
    """Equal structures, floats to ``rtol``."""
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_close(a[k], b[k], rtol) for k in a)
    if isinstance(a, list):
        return len(a) == len(b) and all(_close(x, y, rtol) for x, y in zip(a, b))
    if isinstance(a, float):
        return isinstance(b, float) and abs(a - b) <= rtol * max(abs(a), abs(b))
    return a == b


def test_add_neighbours_reproduces_the_shipped_reference(tmp_path):
    """training/add_neighbours.py on beam-n3 without its reference (its data set is not in the
    repository: its panels are made again from the recorded spec and checked by the recorded
    feature ranges) writes the shipped reference again (the stored features bit for bit, the
    distances' percentiles to 1e-9), weights unchanged."""
    from pathlib import Path

    script = Path(__file__).resolve().parents[1] / "training" / "add_neighbours.py"
    tensors, meta = read_checkpoint(PACKAGE_CHECKPOINTS / "beam-n3.safetensors")
    weights = {k: v for k, v in tensors.items() if k != NEIGHBOURS_TENSOR}
    bare = save_checkpoint(tmp_path / "beam-n3.safetensors", weights,
                           {k: v for k, v in meta.items()
                            if k not in ("weights_sha256", "neighbours")})
    run = subprocess.run([sys.executable, str(script), "--checkpoint", str(bare), "--write", "1"],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert "recorded feature ranges reproduced" in run.stdout
    back, meta2 = read_checkpoint(bare)
    assert np.array_equal(back[NEIGHBOURS_TENSOR], tensors[NEIGHBOURS_TENSOR])
    # the distances' percentiles are float64 sums in BLAS: another CPU's kernels round them
    # apart by ~1e-15 (seen with OPENBLAS_CORETYPE=Prescott); everything else equal
    assert _close(meta2["neighbours"], meta["neighbours"])
    assert meta2["weights_sha256"] == meta["weights_sha256"]
    # a checkpoint whose recorded ranges its panels do not reproduce is refused, nothing written
    wrong = dict(meta2, features=dict(meta2["features"],
                                      min=[v - 1 for v in meta2["features"]["min"]]))
    path = save_checkpoint(tmp_path / "wrong.safetensors", weights,
                           {k: v for k, v in wrong.items()
                            if k not in ("weights_sha256", "neighbours")})
    before = path.read_bytes()
    run = subprocess.run([sys.executable, str(script), "--checkpoint", str(path), "--write", "1"],
                         capture_output=True, text=True)
    assert run.returncode == 2 and "not the ones" in run.stderr
    assert len(run.stderr.strip().splitlines()) == 1 and path.read_bytes() == before
