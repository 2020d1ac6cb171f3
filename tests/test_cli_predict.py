"""``prbdm predict`` and ``prbdm compare``: output, JSON, no scikit-fem (nor torch) in predict,
start-up time, the out-of-distribution warning, bad input (exit 2, one line), the default
checkpoint. Uses the tiny 2-joint checkpoint of tests/test_surrogate.py."""
from __future__ import annotations

import json
import math
import shutil
import subprocess
import sys
import time

import numpy as np
import pytest

from prbdm import cli
from prbdm.geometry import random_beam
from test_surrogate import SHIPPED, tiny_checkpoint

COMMANDS = {"predict": ("prbdm.commands.predict", "PRBDM from the trained surrogate (no FEM)"),
            "compare": ("prbdm.commands.compare", "truth vs surrogate vs fit vs refined fit")}
# the same registration in a fresh interpreter (a no-op once cli.py lists the commands)
BOOT = ("import sys; from prbdm import cli; "
        + "; ".join(f"cli.COMMANDS.setdefault({k!r}, {v!r})" for k, v in COMMANDS.items()))
NOTCH = {"x": [0, 0.1, 0.12, 0.14, 1], "half_width": [0.3, 0.3, 1e-4, 0.3, 0.3],
         "thickness": 0.02}


@pytest.fixture(autouse=True)
def _commands(monkeypatch):
    for k, v in COMMANDS.items():
        monkeypatch.setitem(cli.COMMANDS, k, cli.COMMANDS.get(k, v))


@pytest.fixture
def beam_file(tmp_path):
    def make(data=None, text=None):
        path = tmp_path / "beam.json"
        if text is None:
            data = data or random_beam(11, 3).to_dict()
            text = json.dumps(data)
        path.write_text(text)
        return str(path)
    return make


def run(capsys, *argv):
    try:
        rc = cli.main([*map(str, argv)])
    except SystemExit as exc:
        rc = exc.code
    out, err = capsys.readouterr()
    return rc, out, err


def assert_bad(rc, out, err, *words):
    assert rc == 2, (rc, err)
    assert out == ""
    lines = err.strip("\n").split("\n")
    assert len(lines) == 1, err
    assert "Traceback" not in err
    for w in words:
        assert w in lines[0], (w, lines[0])


def test_predict_json_and_text(capsys, beam_file):
    ck = str(tiny_checkpoint())
    rc, out, err = run(capsys, "predict", beam_file(), "--joints", 2, "--checkpoint", ck, "--json")
    assert rc == 0, err
    assert out.count("\n") == 1
    o = json.loads(out)
    for key in ("gamma", "k", "law", "poses", "omega", "freq_hz", "omega_truth_predicted",
                "links", "checkpoint", "truth", "time_s", "warnings"):
        assert key in o, key
    assert "omega_truth" not in o and "loss_percent" not in o
    assert len(o["gamma"]) == 3 and math.isclose(sum(o["gamma"]), 1.0, abs_tol=1e-12)
    m = len(o["poses"])
    assert len(o["k"]) == m and all(k > 0 for k in o["k"])
    assert np.asarray(o["omega"]).shape == (m, 2)
    assert np.asarray(o["links"]["stiffness"]).shape == (m, 2)
    for key in ("joint_x", "length", "mass", "com", "inertia", "area_moment", "base_stiffness"):
        assert key in o["links"]
    assert o["checkpoint"]["path"] == ck and o["truth"] == "beam"
    assert o["checkpoint"]["dataset_size"] == 12
    # the PRBDM frequencies are those of `prbdm eval` with the same gamma and k
    rc, out2, err = run(capsys, "eval", beam_file(), "--gamma", ",".join(map(repr, o["gamma"])),
                        "--k", ",".join(map(repr, o["k"])), "--json")
    assert rc == 0, err
    np.testing.assert_allclose(json.loads(out2)["omega"], o["omega"], rtol=1e-8)
    rc, out, err = run(capsys, "predict", beam_file(), "--joints", 2, "--checkpoint", ck)
    assert rc == 0 and "gamma:" in out and "no FEM" in out and "beam-n2" in out


def test_predict_without_fem_or_torch_and_fast(beam_file):
    """A fresh interpreter: no scikit-fem, no torch, and the whole run (start-up included) well
    under 1.5 s."""
    code = (BOOT + "; rc = cli.main(sys.argv[1:]); "
            "assert 'skfem' not in sys.modules, 'skfem imported'; "
            "assert 'torch' not in sys.modules, 'torch imported'; sys.exit(rc)")
    cmd = [sys.executable, "-c", code, "predict", beam_file(), "--joints", "2", "--checkpoint",
           str(tiny_checkpoint()), "--json"]
    best = math.inf
    for _ in range(2):                  # best of two: the first may pay for a cold disk cache
        t0 = time.perf_counter()
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=60)
        best = min(best, time.perf_counter() - t0)
        assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["gamma"]
    assert best < 1.5, f"prbdm predict took {best:.2f} s"


def test_predict_ood_warning(capsys, beam_file):
    rc, out, err = run(capsys, "predict", beam_file(NOTCH), "--joints", 2, "--checkpoint",
                       str(tiny_checkpoint()), "--json")
    assert rc == 0
    o = json.loads(out)
    assert o["warnings"] and "outside the training range" in o["warnings"][0]
    assert err.startswith("prbdm predict: warning: feature log_")


def test_predict_bad_input(capsys, beam_file, tmp_path):
    ck = str(tiny_checkpoint())
    assert_bad(*run(capsys, "predict", str(tmp_path / "nope.json"), "--joints", 2,
                    "--checkpoint", ck), "BEAM", "no such file")
    assert_bad(*run(capsys, "predict", beam_file(text="{"), "--joints", 2, "--checkpoint", ck),
               "not valid JSON")
    assert_bad(*run(capsys, "predict", beam_file({"x": [0, 1], "half_width": [0.1, -0.1],
                                                  "thickness": 0.01}), "--joints", 2,
                    "--checkpoint", ck), "half_width")
    assert_bad(*run(capsys, "predict", beam_file(), "--joints", 3, "--checkpoint", ck),
               "--joints 3", "trained for 2 joints")
    assert_bad(*run(capsys, "predict", beam_file(), "--joints", 2, "--checkpoint", ck,
                    "--truth", "plate"), "--truth plate")
    assert_bad(*run(capsys, "predict", beam_file(), "--joints", 2, "--checkpoint",
                    str(tmp_path / "none.safetensors")), "checkpoint", "no such file")
    junk = tmp_path / "junk.safetensors"
    junk.write_bytes(b"garbage" * 10)
    assert_bad(*run(capsys, "predict", beam_file(), "--joints", 2, "--checkpoint", str(junk)),
               "checkpoint", "not a safetensors file")
    assert_bad(*run(capsys, "predict", beam_file(), "--joints", 0), "--joints")
    assert_bad(*run(capsys, "predict", beam_file(), "--joints", 7), "--joints 7",
               "no trained surrogate checkpoint")


def test_predict_default_checkpoint(capsys, beam_file, tmp_path, monkeypatch):
    monkeypatch.setenv("PRBDM_CHECKPOINTS", str(tmp_path))
    shutil.copy(tiny_checkpoint(), tmp_path / "beam-n2.safetensors")
    rc, out, err = run(capsys, "predict", beam_file(), "--joints", 2, "--json")
    assert rc == 0, err
    assert json.loads(out)["checkpoint"]["path"] == str(tmp_path / "beam-n2.safetensors")


@pytest.mark.skipif(not SHIPPED.is_file(), reason="no shipped n = 4 checkpoint")
def test_predict_shipped_checkpoint(capsys, beam_file):
    rc, out, err = run(capsys, "predict", beam_file(random_beam(0, 10 ** 6).to_dict()),
                       "--joints", 4, "--json")
    assert rc == 0, err
    o = json.loads(out)
    assert o["checkpoint"]["name"] == "beam-n4.safetensors" and len(o["gamma"]) == 5


def test_compare_runs(capsys, beam_file):
    ck = str(tiny_checkpoint())
    rc, out, err = run(capsys, "compare", beam_file(), "--joints", 2, "--checkpoint", ck,
                       "--starts", 4, "--refine-iter", 5, "--json")
    assert rc == 0, err
    o = json.loads(out)
    for key in ("truth", "network", "network_direct", "fit", "refined"):
        assert key in o
    for key in ("network", "fit", "refined"):
        assert o[key]["loss_percent"] >= 0 and len(o[key]["freq_error"]) == 2
        assert o[key]["time_s"] >= 0
    # the fit is at least as good as the network; refining does not make the network worse
    assert o["fit"]["loss_percent"] <= o["network"]["loss_percent"] * (1 + 1e-9)
    assert o["refined"]["loss_percent"] <= o["network"]["loss_percent"] * (1 + 1e-9)
    assert len(o["truth"]["omega"]) >= 2
    rc, out, err = run(capsys, "compare", beam_file(), "--joints", 2, "--checkpoint", ck,
                       "--starts", 4, "--refine-iter", 5)
    assert rc == 0 and "refined" in out and "network (direct)" in out
    assert_bad(*run(capsys, "compare", beam_file(), "--joints", 3, "--checkpoint", ck),
               "trained for 2 joints")


def test_compare_refines_as_the_library_default():
    """`prbdm compare`'s --refine-iter default is prbdm.fit.REFINE_ITER (written out in the
    parser so that a bad flag fails before torch is imported)."""
    import argparse

    from prbdm.commands import compare
    from prbdm.fit import REFINE_ITER

    parser = argparse.ArgumentParser()
    compare.add_arguments(parser)
    assert parser.get_default("refine_iter") == REFINE_ITER


def test_predict_output_exports(capsys, beam_file, tmp_path):
    """`prbdm predict --json` feeds `prbdm export --from`: the exported chain is the network's
    PRBDM (the NumPy PRBDM of predict against the torch model of export), and a prediction made
    for another beam is refused."""
    ck = str(tiny_checkpoint())
    rc, out, err = run(capsys, "predict", beam_file(), "--joints", 2, "--checkpoint", ck, "--json")
    assert rc == 0, err
    p = json.loads(out)
    pred_file = tmp_path / "predict.json"
    pred_file.write_text(out)
    for pose in (0, len(p["poses"]) - 1):
        desc_file = tmp_path / f"panel{pose}.json"
        rc, out, err = run(capsys, "export", beam_file(), "--from", pred_file, "--pose", pose,
                           "-o", desc_file, "--json")
        assert rc == 0, err
        e = json.loads(out)
        np.testing.assert_allclose(e["omega"], p["omega"][pose], rtol=1e-8)
        np.testing.assert_allclose(e["stiffness"], p["links"]["stiffness"][pose], rtol=1e-10)
        desc = json.loads(desc_file.read_text())
        assert desc["source"] == "network beam-n2.safetensors"
        np.testing.assert_allclose(desc["links"]["joint_x"], p["links"]["joint_x"], rtol=1e-12)
        np.testing.assert_allclose([b["mass"] for b in desc["bodies"][1:]], p["links"]["mass"],
                                   rtol=1e-10)
    try:
        from prbdm.export import mujoco_linear_frequencies
        import mujoco  # noqa: F401
    except ImportError:
        pass
    else:
        xml = tmp_path / "panel.xml"
        rc, out, err = run(capsys, "export", beam_file(), "--from", pred_file, "-o", xml,
                           "--pose", 0)        # the network's own pose 0 (default: refit at rest)
        assert rc == 0, err
        omega, _ = mujoco_linear_frequencies(xml.read_text())
        np.testing.assert_allclose(omega, p["omega"][0], rtol=1e-6)
    # the check is on the joint positions, i.e. the length: a longer panel of the same shape
    other = random_beam(11, 3).to_dict()
    other["x"] = [1.5 * v for v in other["x"]]
    assert_bad(*run(capsys, "export", beam_file(other), "--from", pred_file, "-o",
                    tmp_path / "x.xml"), "different beam")
