"""prbdm.dataset and `prbdm dataset`: storage, resume after kill -9, extension, refusal of a
different spec, failure isolation, the Dask path, the manifest, reading with plain pyarrow.

The real pipeline (FEM truth + torch fit) runs on a few small beams (joints 2, 4 starts); the
storage mechanics that need many records use a light stand-in labeller.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from prbdm import dataset as D
from prbdm import random_beam
from prbdm.cli import main
from prbdm.errors import BadInput

# the real pipeline, kept small: 2 joints, 4 starts
REAL = ["--joints", "2", "--starts", "4", "--seed", "7"]
SPEC = dict(joints=2, starts=4, seed=7)


def fake_labeller(index, spec):
    """Stand-in for label_beam: the real geometry, made-up labels, beam 3 fails."""
    beam = D.beam_for(spec, index)
    if index == 3:
        return {"index": index, "status": "error", "error": "fit: ValueError: injected"}
    return {"index": index, "status": "ok", "x": beam.x.tolist(),
            "half_width": beam.half_width.tolist(), "thickness": beam.thickness,
            "gamma": [0.5, 0.5], "k": [1.0], "loss_percent": 0.01 * index, "time_s": 0.001}


def _cli(*argv) -> list[str]:
    return [sys.executable, "-c", "import sys; from prbdm.cli import main; sys.exit(main())", *argv]


def _indices(path) -> list[int]:
    return sorted(pq.read_table(path, columns=["index"]).column("index").to_pylist())


# ---------------------------------------------------------------------- spec

def test_spec_defaults_and_validation():
    spec = D.make_spec(joints=3)
    assert spec["modes"] == 3 and spec["truth_modes"] == 4 and spec["truth"] == "beam"
    assert spec["beam"]["p"] == 10 and spec["beam"]["material"]["E"] == 205e9
    assert D.make_spec(joints=2, modes=4)["truth_modes"] == 5
    assert spec["starts"] == 64                                     # recorded as a number
    assert D.spec_difference(spec, D.make_spec(joints=3)) is None
    assert D.spec_difference(spec, D.make_spec(joints=3, p=4)) == "beam.p"
    with pytest.raises(BadInput, match="--truth"):
        D.make_spec(joints=3, truth="analytic")
    with pytest.raises(BadInput, match="--joints"):
        D.make_spec(joints=0)
    # a beam of the set is a pure function of (seed, index)
    a, b = D.beam_for(spec, 5), D.beam_for(D.make_spec(joints=3), 5)
    assert np.array_equal(a.x, b.x) and a.thickness == b.thickness


def test_spec_width_range(tmp_path, capsys):
    """--max-half-width LO,HI is part of the spec, gives the generator's range, is refused with
    one line when malformed, and a set made with it cannot be resumed without it."""
    spec = D.make_spec(joints=2, max_half_width=[0.025, 0.25], min_half_width=0.01)
    assert spec["beam"]["max_half_width"] == [0.025, 0.25]
    assert D.make_spec(joints=2, max_half_width=[0.3])["beam"]["max_half_width"] == 0.3
    assert D.spec_difference(D.make_spec(joints=2), spec) == "beam.max_half_width"
    b, ref = D.beam_for(spec, 3), random_beam(0, 3, max_half_width=(0.025, 0.25),
                                              min_half_width=0.01)
    assert np.array_equal(b.half_width, ref.half_width)
    for bad in ([0.3, 0.1], [0.1, 0.2, 0.3], [-1.0], [float("nan")], [True]):
        with pytest.raises(BadInput, match="--max-half-width"):
            D.make_spec(joints=2, max_half_width=bad)
    with pytest.raises(BadInput, match="--min-half-width.*0.02"):
        D.make_spec(joints=2, max_half_width=[0.02, 0.2], min_half_width=0.05)
    out = tmp_path / "narrow"
    args = ["dataset", "generate", "--out", str(out), "--count", "3", "--joints", "2",
            "--starts", "0", "--workers", "0", "--progress", "none"]
    assert main(args + ["--max-half-width", "0.025,0.25"]) == 0
    capsys.readouterr()
    assert main(args + ["--count", "4"]) == 2                # resumed without the option
    assert "beam.max_half_width" in capsys.readouterr().err
    assert main(args + ["--max-half-width", "0.25,0.025"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--max-half-width" in err[0]


def test_spec_thickness_range(tmp_path, capsys):
    """--thickness LO,HI (the paper's generator): part of the spec, the generator's bounds,
    refused with one line naming the allowed range, and not an option of the smooth family."""
    spec = D.make_spec(joints=2, thickness=[0.002, 0.01])
    assert (spec["beam"]["min_thickness"], spec["beam"]["max_thickness"]) == (0.002, 0.01)
    assert D.spec_difference(D.make_spec(joints=2), spec) in ("beam.max_thickness",
                                                               "beam.min_thickness")
    b = D.beam_for(spec, 4)
    assert b.thickness == random_beam(0, 4, min_thickness=0.002, max_thickness=0.01).thickness
    assert 0.002 <= min(D.beam_for(spec, i).thickness for i in range(20)) < 0.01
    for bad in ([0.01, 0.002], [0.002], [0.0, 0.01], [0.002, 0.3], [float("nan"), 0.01]):
        with pytest.raises(BadInput, match=r"--thickness.*0 < LO <= HI <= 0.2"):
            D.make_spec(joints=2, thickness=bad)
    with pytest.raises(BadInput, match="--thickness: an option of the paper's generator"):
        D.make_spec(joints=2, family="smooth", thickness=[0.002, 0.01])
    args = ["dataset", "generate", "--out", str(tmp_path / "thin"), "--count", "2", "--joints",
            "2", "--starts", "0", "--workers", "0", "--progress", "none"]
    assert main(args + ["--thickness", "0.01,0.002"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--thickness" in err[0] and "0.2" in err[0]
    assert not (tmp_path / "thin").exists()


# ---------------------------------------------------------------------- storage, resume, extend

def test_generate_extend_and_plain_pyarrow(tmp_path):
    out = tmp_path / "set"
    spec = D.make_spec(**SPEC)
    s1 = D.generate(out, 6, spec, workers=0, labeller=fake_labeller, part_size=4,
                    progress="none")
    assert s1["new"] == 6 and s1["new_errors"] == 1 and s1["missing"] == 0 and s1["parts"] == 2
    first_parts = {p.name: p.read_bytes() for p in D.part_files(out)}
    s2 = D.generate(out, 10, spec, workers=0, labeller=fake_labeller, part_size=4,
                    progress="none")
    assert s2["new"] == 4 and s2["records"] == 10
    # records already written are neither recomputed nor rewritten
    assert all((out / name).read_bytes() == data for name, data in first_parts.items())
    s3 = D.generate(out, 10, spec, workers=0, labeller=fake_labeller, progress="none")
    assert s3["new"] == 0

    # plain pyarrow / pandas, without prbdm
    table = pq.read_table(out)
    assert sorted(table.column("index").to_pylist()) == list(range(10))
    import pandas as pd

    df = pd.read_parquet(out).set_index("index").sort_index()
    assert df.loc[3, "status"] == "error" and "injected" in df.loc[3, "error"]
    assert list(df.loc[4, "gamma"]) == [0.5, 0.5]
    assert list(df.loc[4, "x"]) == D.beam_for(spec, 4).x.tolist()

    manifest = json.loads((out / D.MANIFEST).read_text())
    assert manifest["format"] == "prbdm-dataset" and manifest["count"] == 10
    assert manifest["spec"] == {**spec, "fit_batch": D.DEFAULT_FIT_BATCH, "objective": "eigenvalue",
                                "target": "spectrum"}
    assert manifest["spec"]["seed"] == 7 and manifest["runs"][0]["fit_batch"] == 8
    assert {"python", "prbdm", "numpy", "pyarrow"} <= set(manifest["versions"])
    assert "git_commit" in manifest and len(manifest["runs"]) == 3
    assert all(r["finished"] for r in manifest["runs"])
    assert set(manifest["columns"]) == set(table.column_names)


def test_refusals(tmp_path, capsys):
    out = tmp_path / "set"
    D.generate(out, 2, D.make_spec(**SPEC), workers=0, labeller=fake_labeller, progress="none")
    # different spec: exit 2, one line naming the field
    assert main(["dataset", "generate", "--out", str(out), "--count", "4", "--joints", "3",
                 "--starts", "4", "--seed", "7"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "--joints" in err and "joints = 2" in err
    assert main(["dataset", "generate", "--out", str(out), "--count", "4", *REAL,
                 "--truth", "plate"]) == 2
    assert "--truth" in capsys.readouterr().err
    # a folder that is not a data set
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    assert main(["dataset", "generate", "--out", str(other), "--count", "1", *REAL]) == 2
    assert "not a prbdm data set" in capsys.readouterr().err
    # a folder being written by another run
    with D.FolderLock(out):
        with pytest.raises(BadInput, match="another run"):
            D.generate(out, 4, D.make_spec(**SPEC), workers=0, labeller=fake_labeller,
                       progress="none")
    assert main(["dataset", "info", str(tmp_path / "nowhere")]) == 2


def test_stale_temporary_is_ignored_and_removed(tmp_path):
    out = tmp_path / "set"
    spec = D.make_spec(**SPEC)
    D.generate(out, 2, spec, workers=0, labeller=fake_labeller, progress="none")
    junk = out / ".part-000001.parquet.abc.tmp"
    junk.write_bytes(b"PAR1 half a file")       # what a kill -9 during a write leaves
    assert pq.read_table(out).num_rows == 2       # readers skip hidden files
    D.generate(out, 3, spec, workers=0, labeller=fake_labeller, progress="none")
    assert not junk.exists() and pq.read_table(out).num_rows == 3


def test_process_pool_matches_in_process(tmp_path):
    spec = D.make_spec(**SPEC)
    D.generate(tmp_path / "a", 5, spec, workers=0, labeller=fake_labeller, progress="none")
    s = D.generate(tmp_path / "b", 5, {**spec, "fit_batch": 2}, workers=2,
                   labeller=fake_labeller, part_size=2, progress="none")
    assert s["workers"] == 2
    a = D.read_table(tmp_path / "a").drop(["time_s", "worker"])
    b = D.read_table(tmp_path / "b").drop(["time_s", "worker"])
    assert a.equals(b)


# ---------------------------------------------------------------------- the real pipeline

def test_label_beam_real_and_failure_isolation(tmp_path, monkeypatch):
    import prbdm.truth

    spec = D.make_spec(**SPEC)
    rec = D.label_beam(0, spec)
    assert rec["status"] == "ok", rec["error"]
    assert len(rec["omega_truth"]) == spec["truth_modes"] == 3
    assert np.all(np.diff(rec["omega_truth"]) > 0)
    assert len(rec["gamma"]) == 3 and abs(sum(rec["gamma"]) - 1) < 1e-9
    assert len(rec["k"]) >= 1 and rec["loss_percent"] >= 0 and rec["time_s"] > 0
    assert len(rec["freq_error_max"]) == 2 and rec["error"] is None

    real = prbdm.truth.bending_frequencies

    def flaky(beam, **kw):
        if "index=1 " in beam.name:
            raise RuntimeError("solver blew up")
        return real(beam, **kw)

    monkeypatch.setattr(prbdm.truth, "bending_frequencies", flaky)
    out = tmp_path / "set"
    s = D.generate(out, 3, spec, workers=0, progress="none")
    assert s["new"] == 3 and s["new_errors"] == 1
    df = D.read_table(out).to_pandas().set_index("index")
    assert df.loc[1, "status"] == "error"
    assert df.loc[1, "error"] == "truth: RuntimeError: solver blew up"
    assert list(df.loc[1, "x"]) == D.beam_for(spec, 1).x.tolist()  # geometry kept
    assert (df.loc[[0, 2], "status"] == "ok").all()
    # reproducible: the geometry exactly, the truth to rounding, the fit to its tolerance
    assert np.allclose(df.loc[0, "omega_truth"], rec["omega_truth"], rtol=1e-10, atol=0)
    assert np.allclose(df.loc[0, "gamma"], rec["gamma"], atol=2e-3)
    assert df.loc[0, "loss_percent"] == pytest.approx(rec["loss_percent"], rel=1e-3)


def test_truth_only_set(tmp_path):
    """--starts 0: the geometry and truth of the labelled set, no fit, status ok; the fit columns
    are null and `dataset info` reports no loss."""
    out = tmp_path / "truth"
    assert main(["dataset", "generate", "--out", str(out), "--count", "3", "--joints", "2",
                 "--starts", "0", "--seed", "7", "--workers", "0", "--progress", "none"]) == 0
    df = D.read_table(out).to_pandas().set_index("index")
    assert (df["status"] == "ok").all() and df["gamma"].isna().all() and df["k"].isna().all()
    assert df["loss_percent"].isna().all() and df["fit_time_s"].isna().all()
    rec = D.label_beam(1, D.make_spec(**SPEC))            # same seed, with a fit
    assert list(df.loc[1, "x"]) == rec["x"]
    assert np.allclose(df.loc[1, "omega_truth"], rec["omega_truth"], rtol=1e-10, atol=0)
    info = D.info(out)
    assert info["ok"] == 3 and info["loss_percent"] is None and info["spec"]["starts"] == 0
    with pytest.raises(BadInput, match="--starts"):
        D.make_spec(joints=2, starts=-1)


def test_dask_local_cluster_same_records(tmp_path):
    from dask.distributed import Client, LocalCluster

    spec = D.make_spec(**SPEC)
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                      dashboard_address=None) as cluster, Client(cluster) as client:
        s = D.generate(tmp_path / "dask", 2, spec, scheduler=client, part_size=1,
                       progress="none")
    assert s["new"] == 2 and s["new_errors"] == 0 and s["parts"] == 2
    manifest = D.read_manifest(tmp_path / "dask")
    assert manifest["runs"][0]["scheduler"].startswith("dask ")
    assert manifest["spec"]["fit_batch"] == D.DEFAULT_FIT_BATCH   # one chunk: a batched fit
    got = D.read_table(tmp_path / "dask").drop(_TIMING).to_pylist()
    # the same executor loop as a pool's: the chunk's labels, bit for bit
    ref = D.label_beams([0, 1], {**spec, "fit_batch": D.DEFAULT_FIT_BATCH,
                                 "objective": D.DEFAULT_OBJECTIVE})
    assert got == [{k: v for k, v in r.items() if k not in _TIMING} for r in ref]


def test_kill9_then_resume(tmp_path):
    """kill -9 the generating process mid-run, rerun: no index missing, none duplicated."""
    out = tmp_path / "set"
    cmd = _cli("dataset", "generate", "--out", str(out), "--count", "8", *REAL,
               "--workers", "1", "--part-size", "1", "--progress", "log", "--fit-batch", "2")
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            start_new_session=True)
    try:
        deadline = time.monotonic() + 60
        while not D.part_files(out) and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.05)
        assert D.part_files(out), proc.stderr.read().decode() if proc.poll() is not None else ""
    finally:
        os.killpg(proc.pid, signal.SIGKILL)      # the process and its pool, like a crash
        proc.wait()
    before = {p.name: _indices(p) for p in D.part_files(out)}
    assert 1 <= sum(map(len, before.values())) < 8
    for p in D.part_files(out):                  # every part left behind is whole
        pq.read_table(p)

    done = subprocess.run(cmd + ["--json"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout)
    assert summary["records"] == 8 and summary["missing"] == 0
    assert summary["new"] == 8 - sum(map(len, before.values()))   # nothing recomputed
    assert {p.name: _indices(out / p.name) for p in map(Path, before)} == before
    idx = pq.read_table(out).column("index").to_pylist()
    assert sorted(idx) == list(range(8))         # none missing, none duplicated

    info = subprocess.run(_cli("dataset", "info", str(out), "--json"), capture_output=True,
                          text=True, timeout=60)
    s = json.loads(info.stdout)
    assert s["complete"] and s["duplicated"] == 0 and s["ok"] + s["errors"] == 8
    assert s["loss_percent"]["median"] >= 0 and s["time_per_beam_s"]["median"] > 0
    assert len(s["runs"]) == 2 and s["runs"][0]["finished"] is None


def test_info_text(tmp_path, capsys):
    out = tmp_path / "set"
    D.generate(out, 5, D.make_spec(**SPEC), workers=0, labeller=fake_labeller, progress="none")
    assert main(["dataset", "info", str(out)]) == 0
    text = capsys.readouterr().out
    assert "records 5 of 5 (complete" in text and "fit: ValueError" in text
    assert main(["dataset", "info", str(out), "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["ok"] == 4 and s["errors"] == 1 and s["error_kinds"] == {"fit: ValueError": 1}
    assert s["loss_percent"]["median"] == pytest.approx(0.015)  # 0, .01, .02, .04


@pytest.mark.slow
def test_cli_local_dask_cluster_processes(tmp_path):
    out = tmp_path / "set"
    r = subprocess.run(_cli("dataset", "generate", "--out", str(out), "--count", "3", *REAL,
                            "--workers", "1", "--scheduler", "local", "--json"),
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["records"] == 3


# ---------------------------------------------------------------------- chunks: batched fits

def test_chunks_have_fixed_boundaries():
    assert D.chunks([0, 1, 2, 3, 4], 2) == [[0, 1], [2, 3], [4]]
    assert D.chunks([1, 2, 5, 7, 8, 9], 4) == [[1, 2], [5, 7], [8, 9]]
    assert D.chunks([3, 4], 1) == [[3], [4]]
    assert D.chunks([], 8) == []


def test_chunked_labels_equal_per_beam_fits():
    """One fit_many call for a chunk gives each beam the label (and seed) of its own fit."""
    spec = D.make_spec(**SPEC, fit_batch=3)
    together = D.label_beams([0, 1, 2], spec)
    assert [r["index"] for r in together] == [0, 1, 2]
    for rec in together:
        ref = D.label_beam(rec["index"], spec)
        assert rec["status"] == ref["status"] == "ok", (rec["error"], ref["error"])
        assert rec["fit_seed"] == ref["fit_seed"] == D.fit_seed(spec, rec["index"])
        assert rec["x"] == ref["x"] and rec["omega_truth"] == ref["omega_truth"]
        assert np.allclose(rec["gamma"], ref["gamma"], atol=1e-3)
        assert rec["loss_percent"] == pytest.approx(ref["loss_percent"], rel=1e-4)
        assert rec["time_s"] > 0 and rec["cpu_s"] > 0
    # the chunk's fit time is divided among its beams
    assert len({r["fit_time_s"] for r in together}) == 1
    # fit_many with one seed per beam: each beam starts where its own fit starts
    from prbdm.fit import FitProblem, fit_many, fit_prbdm

    beams = [D.beam_for(spec, i) for i in (0, 1)]
    om = np.stack([r["omega_truth"][:2] for r in together[:2]])
    many = fit_many(FitProblem(beams, om, 2), starts=4, seed=[11, 12])
    assert [r.seed for r in many] == [11, 12]
    one = fit_prbdm(beams[1], om[1], joints=2, starts=4, seed=12)
    assert np.allclose(many[1].gamma, one.gamma, atol=1e-3)
    with pytest.raises(BadInput, match="seed"):
        fit_many(FitProblem(beams, om, 2), starts=4, seed=[1, 2, 3])


def test_chunk_failure_isolation(monkeypatch):
    """A truth failure is its beam's record; if the batched fit fails, each beam is fitted alone
    and only the beam that fails is an error."""
    import prbdm.fit
    import prbdm.truth

    real_truth, real_many = prbdm.truth.bending_frequencies, prbdm.fit.fit_many

    def flaky_truth(beam, **kw):
        if "index=1 " in beam.name:
            raise RuntimeError("solver blew up")
        return real_truth(beam, **kw)

    def flaky_many(problem, **kw):         # fit_prbdm calls fit_many with one beam
        if len(problem.beams) > 1:
            raise FloatingPointError("batch went wrong")
        if "index=2 " in problem.beams[0].name:
            raise ValueError("bad beam")
        return real_many(problem, **kw)

    monkeypatch.setattr(prbdm.truth, "bending_frequencies", flaky_truth)
    monkeypatch.setattr(prbdm.fit, "fit_many", flaky_many)
    recs = D.label_beams([0, 1, 2, 3], D.make_spec(**SPEC))
    assert [r["status"] for r in recs] == ["ok", "error", "error", "ok"]
    assert recs[1]["error"] == "truth: RuntimeError: solver blew up"
    assert recs[2]["error"] == "fit: ValueError: bad beam"
    assert recs[2]["omega_truth"] and recs[1]["x"]              # what was computed is kept


class _Crash(BaseException):
    pass


def test_resume_after_crash_mid_chunk(tmp_path, monkeypatch):
    """A crash after part of a chunk was written: the resumed run fits only the missing beams of
    that chunk, together, and recomputes nothing."""
    import prbdm.fit

    out = tmp_path / "set"
    spec = D.make_spec(**SPEC, fit_batch=3)
    real_write, writes = D.storage.write_part, []

    def crashing_write(*a, **kw):           # the 5th part write never happens: a crash
        if len(writes) >= 4:
            raise _Crash()
        writes.append(a[2][0]["index"])
        return real_write(*a, **kw)

    monkeypatch.setattr(D.storage, "write_part", crashing_write)
    with pytest.raises(_Crash):
        D.generate(out, 6, spec, workers=0, part_size=1, progress="none")
    monkeypatch.setattr(D.storage, "write_part", real_write)
    assert sorted(D.existing_indices(out).tolist()) == [0, 1, 2, 3]   # chunk [3, 6) partly
    before = {p.name: p.read_bytes() for p in D.part_files(out)}

    real_many, batches = prbdm.fit.fit_many, []

    def spy(problem, **kw):
        batches.append(sorted(int(b.name.split("index=")[1].split()[0]) for b in problem.beams))
        return real_many(problem, **kw)

    monkeypatch.setattr(prbdm.fit, "fit_many", spy)
    s = D.generate(out, 6, D.make_spec(**SPEC), workers=0, progress="none")  # set's fit_batch
    assert s["new"] == 2 and s["missing"] == 0 and s["fit_batch"] == 3
    assert batches == [[4, 5]]                 # the missing beams of the chunk, in one batch
    assert all((out / n).read_bytes() == b for n, b in before.items())
    table = D.read_table(out)
    assert table.column("index").to_pylist() == list(range(6))
    assert pq.read_table(out).num_rows == 6     # none duplicated
    for rec in table.to_pylist()[4:]:
        ref = D.label_beam(rec["index"], spec)
        assert np.allclose(rec["gamma"], ref["gamma"], atol=2e-3)


def test_fit_batch_option_and_old_sets(tmp_path, capsys):
    out = tmp_path / "set"
    # validation: exit 2, one line
    for bad in ("0", "257", "two"):
        with pytest.raises(SystemExit) as exc:    # argparse rejects it before the command runs
            main(["dataset", "generate", "--out", str(out), "--count", "1", *REAL,
                  "--fit-batch", bad])
        assert exc.value.code == 2
        err = capsys.readouterr().err.strip()
        assert "\n" not in err and "--fit-batch" in err, err
    with pytest.raises(BadInput, match="--fit-batch"):
        D.make_spec(**SPEC, fit_batch=0)
    assert not out.exists()
    # a set made before chunking (no fit_batch in its spec) resumes one beam per task
    spec = D.make_spec(**SPEC)
    D.generate(out, 2, spec, workers=0, labeller=fake_labeller, progress="none")
    manifest = json.loads((out / D.MANIFEST).read_text())
    del manifest["spec"]["fit_batch"]
    (out / D.MANIFEST).write_text(json.dumps(manifest))
    s = D.generate(out, 4, spec, workers=0, labeller=fake_labeller, progress="none")
    assert s["fit_batch"] == 1 and s["new"] == 2
    assert "fit_batch" not in D.read_manifest(out)["spec"]        # the old spec is kept as is
    assert D.generate(out, 5, {**spec, "fit_batch": 1}, workers=0, labeller=fake_labeller,
                      progress="none")["new"] == 1
    # asking for another batch size on an existing set is refused, naming the flag
    assert main(["dataset", "generate", "--out", str(out), "--count", "6", *REAL,
                 "--fit-batch", "4"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "--fit-batch" in err and "fit_batch = 1" in err, err


# ---------------------------------------------------------------------- refused runs, progress

def test_refused_scheduler_leaves_manifest_unchanged(tmp_path, capsys):
    """A run refused before its workers are ready (a bad or unreachable --scheduler) changes
    nothing: the manifest keeps its bytes (count, runs), and a new folder gets no manifest."""
    out = tmp_path / "set"
    D.generate(out, 10, D.make_spec(**SPEC), workers=0, labeller=fake_labeller, progress="none")
    before = (out / D.MANIFEST).read_bytes()
    assert main(["dataset", "generate", "--out", str(out), "--count", "20", *REAL,
                 "--scheduler", "bogus", "--progress", "none"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "--scheduler" in err, err
    assert (out / D.MANIFEST).read_bytes() == before
    assert main(["dataset", "info", str(out)]) == 0
    text = capsys.readouterr().out
    assert "records 10 of 10 (complete, 0 missing" in text and text.count("\nrun ") == 1
    # a new folder: refused without a manifest, and a later run makes the set as usual
    new = tmp_path / "new"
    with pytest.raises(BadInput, match="--scheduler"):
        D.generate(new, 3, D.make_spec(**SPEC), scheduler="bogus", progress="none")
    assert not (new / D.MANIFEST).exists()
    s = D.generate(new, 3, D.make_spec(**SPEC), workers=0, labeller=fake_labeller,
                   progress="none")
    assert s["records"] == 3 and len(D.read_manifest(new)["runs"]) == 1


@pytest.mark.slow
def test_unreachable_scheduler_leaves_manifest_unchanged(tmp_path, monkeypatch):
    """An address nobody listens on is refused without touching the manifest. Slow (on demand):
    Dask's client start-up once hung here past its connect timeout on a loaded machine."""
    out = tmp_path / "set"
    D.generate(out, 10, D.make_spec(**SPEC), workers=0, labeller=fake_labeller, progress="none")
    before = (out / D.MANIFEST).read_bytes()
    monkeypatch.setattr(D.execute, "CONNECT_TIMEOUT_S", 0.5)
    with pytest.raises(BadInput, match="--scheduler: cannot connect"):
        D.generate(out, 20, D.make_spec(**SPEC), scheduler="tcp://127.0.0.1:1",
                   labeller=fake_labeller, progress="none")
    assert (out / D.MANIFEST).read_bytes() == before


def test_info_text_runs_without_workers(tmp_path, capsys):
    out = tmp_path / "set"
    spec = D.make_spec(**SPEC)
    D.generate(out, 2, spec, workers=0, labeller=fake_labeller, progress="none")
    D.generate(out, 2, spec, workers=0, labeller=fake_labeller, progress="none")  # nothing to do
    manifest = json.loads((out / D.MANIFEST).read_text())
    manifest["runs"].append({**manifest["runs"][0], "todo": 4, "written": 0, "workers": None,
                             "finished": None, "wall_s": None})   # an older prbdm's record
    (out / D.MANIFEST).write_text(json.dumps(manifest))
    assert main(["dataset", "info", str(out)]) == 0
    runs = [line for line in capsys.readouterr().out.splitlines() if line.startswith("run ")]
    assert len(runs) == 3 and "None" not in "".join(runs)
    assert "1 workers, finished" in runs[0]
    assert "nothing to label, finished" in runs[1]
    assert "not started, interrupted" in runs[2]


def test_progress_log_lines_when_not_a_terminal(tmp_path):
    import io

    stream = io.StringIO()
    meter = D.Progress("auto", total=5, initial=1, stream=stream, every=0)
    assert meter.mode == "log"
    meter.start()
    for i in range(1, 5):
        meter.update({"index": i, "status": "error" if i == 3 else "ok"})
    meter.close()
    lines = stream.getvalue().splitlines()
    assert len(lines) == 4 and all(line.startswith("prbdm dataset: ") for line in lines)
    assert "2/5 beams (0 errors this run)" in lines[0]
    assert "5/5 beams (1 errors this run)" in lines[-1]
    assert all(" beams/s, ETA " in line for line in lines)
    assert lines[-1].endswith("ETA 0s")                        # nothing left
    assert "\r" not in stream.getvalue()                        # no bar drawn
    # with the default interval, generate logs only its first and last lines
    stream = io.StringIO()
    D.generate(tmp_path / "set", 5, D.make_spec(**SPEC), workers=0, labeller=fake_labeller,
               progress="auto", stream=stream)
    lines = stream.getvalue().splitlines()
    assert len(lines) == 2 and "5 beams to label (0 already in" in lines[0]
    assert "done: 5 new records (1 errors)" in lines[1]


def test_progress_bar_on_a_terminal():
    import io

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    stream = Terminal()
    meter = D.Progress("auto", total=5, initial=1, stream=stream, every=0)
    assert meter.mode == "bar"
    meter.start()
    assert meter.bar is not None
    for i in range(1, 5):
        meter.update({"index": i, "status": "error" if i == 3 else "ok"})
    meter.log("a message")
    meter.close()
    text = stream.getvalue()
    assert "5/5" in text and "100%" in text and "<00:00" in text     # tqdm's bar: count, ETA,
    assert "beam/s" in text                                             # and rate
    assert "errors=1" in text and "a message" in text
    assert "prbdm dataset: " not in text.replace("prbdm dataset: a message", "")  # no log lines


# ---------------------------------------------------------------------- executors, objective, old sets

#: columns that hold timings or the worker's name: they differ from run to run
_TIMING = ["time_s", "cpu_s", "fit_time_s", "truth_time_s", "worker"]


def test_inline_and_process_pool_give_bitwise_the_same_labels(tmp_path):
    """The one executor loop, in this process and on a pool of 2 spawned workers: the same
    records, bit for bit (timings aside), for real beams fitted in chunks."""
    spec = D.make_spec(**SPEC, fit_batch=2)
    a = D.generate(tmp_path / "inline", 4, spec, workers=0, progress="none")
    b = D.generate(tmp_path / "pool", 4, spec, workers=2, part_size=1, progress="none")
    assert (a["workers"], b["workers"]) == (1, 2) and a["new_errors"] == b["new_errors"] == 0
    ta = D.read_table(tmp_path / "inline").drop(_TIMING)
    tb = D.read_table(tmp_path / "pool").drop(_TIMING)
    assert ta.num_rows == 4 and ta.equals(tb)
    workers = set(D.read_table(tmp_path / "pool").column("worker").to_pylist())
    assert f"{os.uname().nodename}:{os.getpid()}" not in workers       # labelled elsewhere


def _raising_labeller(index, spec):
    raise KeyError("lost")


def test_a_task_that_raises_is_one_error_record_per_index():
    backend = D.execute.open_backend(0)
    records = list(D.execute.run_tasks(backend, [[0, 1], [2]], {}, _raising_labeller))
    assert [r["index"] for r in records] == [0, 1, 2]
    assert all(r["status"] == "error" and r["error"] == "worker: KeyError: 'lost'"
               for r in records)


def test_objective_is_recorded_and_used(tmp_path, capsys):
    from prbdm.fit import fit_prbdm
    with pytest.raises(BadInput, match="--objective: must be one of eigenvalue, frequency"):
        D.make_spec(**SPEC, objective="energy")
    out = tmp_path / "set"
    assert main(["dataset", "generate", "--out", str(out), "--count", "2", *REAL,
                 "--objective", "frequency", "--workers", "0", "--progress", "none"]) == 0
    assert D.read_manifest(out)["spec"]["objective"] == "frequency"
    assert D.info(out)["objective"] == "frequency"
    rec = D.read_table(out).to_pylist()[1]
    # the record is the frequency fit of that beam, and holds both measures
    beam, seed = D.beam_for(D.make_spec(**SPEC), 1), D.fit_seed(D.make_spec(**SPEC), 1)
    ref = fit_prbdm(beam, rec["omega_truth"], joints=2, starts=4, seed=seed,
                    objective="frequency")
    assert rec["gamma"] == ref.gamma.tolist() and rec["loss_percent"] == ref.loss_percent
    assert rec["frequency_percent"] == 100 * max(rec["freq_error_max"])
    assert rec["frequency_percent"] == pytest.approx(100 * float(np.abs(ref.freq_error).max()))
    eig = D.label_beam(1, D.make_spec(**SPEC))
    assert eig["gamma"] != rec["gamma"]
    assert rec["frequency_percent"] < eig["frequency_percent"]   # what each one minimises
    assert rec["loss_percent"] > eig["loss_percent"]
    # another objective on the set: exit 2, one line, nothing written
    before = (out / D.MANIFEST).read_bytes()
    assert main(["dataset", "generate", "--out", str(out), "--count", "3", *REAL,
                 "--objective", "eigenvalue", "--progress", "none"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and err.startswith("prbdm dataset: error: --objective:"), err
    assert 'objective = "frequency"' in err and "leave --objective out" in err
    assert (out / D.MANIFEST).read_bytes() == before
    # leaving it out resumes with the set's objective
    s = D.generate(out, 3, D.make_spec(**SPEC), workers=0, progress="none")
    assert s["objective"] == "frequency" and s["new"] == 1


def _labeller_with_frequency(index, spec):
    return {**fake_labeller(index, spec), "frequency_percent": 1.0}


def test_old_set_keeps_its_columns_and_objective(tmp_path, capsys):
    """A set made before frequency_percent and --objective existed: resumed with its own
    columns (every part one schema), its manifest spec as it was; another objective refused."""
    import pyarrow as pa

    out = tmp_path / "old"
    spec = D.make_spec(**SPEC)
    D.generate(out, 3, spec, workers=0, labeller=fake_labeller, progress="none")
    manifest = json.loads((out / D.MANIFEST).read_text())
    del manifest["spec"]["objective"]
    del manifest["columns"]["frequency_percent"]
    (out / D.MANIFEST).write_text(json.dumps(manifest))
    for p in D.part_files(out):                      # the parts of an older prbdm
        pq.write_table(pq.read_table(p).drop(["frequency_percent"]), p)
    old_schema = pq.read_schema(D.part_files(out)[0])

    s = D.generate(out, 6, spec, workers=0, labeller=_labeller_with_frequency, progress="none")
    assert s["new"] == 3 and s["objective"] == "eigenvalue"
    assert all(pq.read_schema(p).equals(old_schema) for p in D.part_files(out))
    table = pq.read_table(out)
    assert sorted(table.column("index").to_pylist()) == list(range(6))
    assert "frequency_percent" not in table.column_names
    kept = D.read_manifest(out)
    assert kept["spec"] == manifest["spec"] and kept["columns"] == manifest["columns"]
    assert D.info(out)["frequency_percent"] is None
    assert main(["dataset", "generate", "--out", str(out), "--count", "7", *REAL,
                 "--objective", "frequency", "--progress", "none"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "--objective" in err and 'objective = "eigenvalue"' in err
    assert D.generate(out, 7, {**spec, "objective": "eigenvalue"}, workers=0,
                      labeller=fake_labeller, progress="none")["new"] == 1
    assert isinstance(pa.concat_tables([pq.read_table(p) for p in D.part_files(out)]), pa.Table)


def test_refused_by_truth_flags_records_todays_truth_refuses():
    import pandas as pd

    from prbdm.dataset import make_spec, refused_by_truth
    rows = pd.DataFrame({"x": [[0, 0.5, 1], [0, 0.9984, 1]],
                         "half_width": [[0.3, 0.2, 0.1], [0.2, 0.1119, 0.492]],
                         "thickness": [0.02, 0.02]})
    # the second is a tongue with a 0.24-degree corner: the plate refuses it, the beam does not
    assert refused_by_truth(rows, make_spec(4, truth="plate")).tolist() == [False, True]
    assert refused_by_truth(rows, make_spec(4, truth="beam")).tolist() == [False, False]


def test_a_mindlin_truth_only_record_is_below_the_plate_record():
    """`--truth mindlin` labels with the shear-deformable plate: on a panel of the paper's
    generator (3 cm thick, a 2 cm neck) its frequencies lie below the Kirchhoff plate's."""
    from prbdm.dataset import label_beam, make_spec
    recs = {t: label_beam(1, make_spec(4, truth=t, starts=0, min_half_width=0.01))
            for t in ("mindlin", "plate")}
    assert all(r["status"] == "ok" for r in recs.values()), recs
    m, p = (np.asarray(recs[t]["omega_truth"]) for t in ("mindlin", "plate"))
    assert m.shape == (5,) and np.all(m[:2] < p[:2])
    with pytest.raises(BadInput, match="--truth: must be one of beam, plate, mindlin"):
        make_spec(4, truth="solid")
