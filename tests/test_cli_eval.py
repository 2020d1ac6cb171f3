"""``prbdm eval``: output against the library and hand values, flag validation, and every bad beam
file of tests/test_geometry.py through the command line (exit 2, one line on stderr naming the
field, no traceback). Most runs are in-process (``prbdm.cli.main``); a few go through a real
subprocess for the real exit status and streams."""
import io
import json
import math
import subprocess
import sys

import numpy as np
import pytest
import torch
from test_geometry import BAD_BEAMS, BAD_FILES

from prbdm import Beam, model
from prbdm.cli import main

PAPER_3R = "0.7447,0.0466,0.0725,0.1362"
UNIFORM = {"name": "paper uniform beam", "x": [0.0, 1.0], "half_width": [0.1812, 0.1812],
           "thickness": 0.040532}
TAPERED = {"x": [0.0, 0.35, 1.4], "half_width": [0.2, 0.15, 0.04], "thickness": 0.02,
           "material": {"E": 70e9, "rho": 2700, "nu": 0.33}}


@pytest.fixture
def beam_file(tmp_path):
    def make(data=UNIFORM, text=None):
        path = tmp_path / "beam.json"
        path.write_text(json.dumps(data) if text is None else text)
        return str(path)
    return make


def run(capsys, *argv):
    try:
        rc = main(["eval", *map(str, argv)])
    except SystemExit as exc:          # argparse errors
        rc = exc.code
    out, err = capsys.readouterr()
    return rc, out, err


def run_json(capsys, *argv):
    rc, out, err = run(capsys, *argv, "--json")
    assert rc == 0, err
    assert out.endswith("\n") and out.count("\n") == 1      # one JSON object, nothing else
    return json.loads(out), err


def assert_bad(rc, out, err, *words):
    assert rc == 2
    assert out == ""
    lines = err.strip("\n").split("\n")
    assert len(lines) == 1, err
    assert "Traceback" not in err
    assert "np." not in lines[0], lines[0]      # plain numbers, not NumPy reprs
    for w in words:
        assert w in lines[0], (w, lines[0])


# ----------------------------------------------------------------------------- good runs
def test_json_matches_library(capsys, beam_file):
    path = beam_file(TAPERED)
    k = [1.1, 1.2, 1.3, 1.4, 1.5, 1.6]
    r, err = run_json(capsys, path, "--gamma", "0.2,0.3,0.15,0.2,0.15", "--k",
                      ",".join(map(str, k)))
    assert err == ""
    for key in ("poses", "omega", "freq_hz", "gamma", "k", "law", "links", "time_s", "n"):
        assert key in r
    assert r["law"] == "beam" and r["n"] == 4 and r["k"] == k
    np.testing.assert_allclose(r["poses"], model.paper_poses(4).numpy(), rtol=0, atol=1e-15)
    beam = Beam.from_dict(TAPERED)
    lam = model.eigenvalues(beam, torch.tensor([0.2, 0.3, 0.15, 0.2, 0.15], dtype=torch.float64),
                            torch.tensor(k, dtype=torch.float64))
    np.testing.assert_allclose(r["omega"], lam.sqrt().numpy(), rtol=1e-12)
    np.testing.assert_allclose(r["freq_hz"], np.array(r["omega"]) / (2 * math.pi), rtol=1e-14)
    assert np.all(np.diff(r["omega"], axis=1) > 0)
    links = r["links"]
    np.testing.assert_allclose(links["joint_x"], 1.4 * np.cumsum([0.2, 0.3, 0.15, 0.2]))
    np.testing.assert_allclose(links["length"], 1.4 * np.array([0.2, 0.3, 0.15, 0.2, 0.15]))
    assert len(links["mass"]) == len(links["com"]) == len(links["inertia"]) == 4
    # link 1 spans [0.28, 0.7] m: hand-integrated trapezoids 0.28-0.35 and 0.35-0.7
    w = lambda x: np.interp(x, TAPERED["x"], TAPERED["half_width"])
    m1 = 2700 * 0.02 * ((0.35 - 0.28) * (w(0.28) + w(0.35)) + (0.7 - 0.35) * (w(0.35) + w(0.7)))
    assert links["mass"][0] == pytest.approx(m1, rel=1e-12)
    assert sum(links["mass"]) < beam.mass
    assert r["beam"]["mass"] == pytest.approx(beam.mass)
    assert r["time_s"] >= 0


def test_single_joint_hand_value(capsys, beam_file):
    """1R uniform beam, beam law: omega^2 = k s / (m c^2 + J), s = E t^3 b / (12 L)."""
    r, _ = run_json(capsys, beam_file(UNIFORM), "--gamma", "0.4,0.6", "--k", "2.5",
                    "--poses", "linear")
    E, rho, b, t = 205e9, 7850.0, 0.3624, 0.040532
    h = 0.6
    m = rho * t * b * h
    s = E * (b * t ** 3 / 12) / 1.0
    omega = math.sqrt(2.5 * s / (m * (h / 2) ** 2 + m * h ** 2 / 12))
    assert r["omega"] == [[pytest.approx(omega, rel=1e-12)]]
    assert r["links"]["base_stiffness"] == [pytest.approx(s, rel=1e-12)]
    assert r["poses"] == [[0.0]]


def test_single_k_applies_to_every_pose(capsys, beam_file):
    path = beam_file()
    one, _ = run_json(capsys, path, "--gamma", PAPER_3R, "--k", "3")
    many, _ = run_json(capsys, path, "--gamma", PAPER_3R, "--k", ",".join(["3"] * 9))
    assert one["k"] == [3.0] * 9
    assert one["omega"] == many["omega"]
    assert len(one["omega"]) == 9 and all(len(o) == 3 for o in one["omega"])


def test_paper_law_and_explicit_poses(capsys, beam_file):
    path = beam_file()
    r, err = run_json(capsys, path, "--gamma", PAPER_3R, "--k", "1,2", "--law", "paper",
                      "--poses", "0,0.2")
    assert err == "" and r["law"] == "paper"
    assert r["poses"] == [[0.0] * 3, [0.2] * 3]
    gamma = torch.tensor([0.7447, 0.0466, 0.0725, 0.1362], dtype=torch.float64)
    lam = model.eigenvalues(Beam.from_dict(UNIFORM), gamma, torch.tensor([1.0, 2.0]), [0.0, 0.2],
                            "paper")
    np.testing.assert_allclose(r["omega"], lam.sqrt().numpy(), rtol=1e-12)


def test_pose_beyond_quarter_turn_warns_on_stderr(capsys, beam_file):
    r, err = run_json(capsys, beam_file(), "--gamma", PAPER_3R, "--k", "1", "--poses", "0.6")
    assert "warning" in err and "--poses" in err and "Traceback" not in err
    assert r["warnings"] and len(r["omega"]) == 1


def test_gamma_outside_paper_bounds_warns(capsys, beam_file):
    r, err = run_json(capsys, beam_file(), "--gamma", "0.01,0.99", "--k", "1")
    assert "--gamma" in err and "0.025" in err


def test_table_output(capsys, beam_file):
    rc, out, err = run(capsys, beam_file(), "--gamma", PAPER_3R, "--k", "3")
    assert rc == 0 and err == ""
    assert "eigenfrequencies [Hz]" in out and "f3" in out and "s [N m/rad]" in out
    assert len([line for line in out.splitlines() if line.strip().startswith("8 ")]) == 1


def test_beam_from_stdin(capsys, monkeypatch):
    monkeypatch.setattr("sys.stdin", io.StringIO(json.dumps(UNIFORM)))
    r, _ = run_json(capsys, "-", "--gamma", "0.5,0.5", "--k", "1", "--poses", "linear")
    assert r["beam"]["name"] == "paper uniform beam"


# ----------------------------------------------------------------------------- bad flags
@pytest.mark.parametrize("gamma, words", [
    ("0.5,abc", ["--gamma", "numbers"]),
    ("1.0", ["--gamma", "n + 1 >= 2"]),
    ("0.5,0.4", ["--gamma", "sum to 1", "1e-06", "0.9"]),
    ("0.5,0.5000011", ["--gamma", "sum to 1"]),
    ("0.6,0.6,-0.2", ["--gamma", "> 0"]),
    ("0,1", ["--gamma", "> 0"]),
    ("0.5,nan", ["--gamma", "finite"]),
    ("inf,0.5", ["--gamma", "finite"]),
    ("", ["--gamma"]),
    (",", ["--gamma", "empty"]),
    ("0.5,0.5,,", ["--gamma", "empty field"]),
    ("0.5,,0.5", ["--gamma", "empty field"]),
    (",0.5,0.5", ["--gamma", "empty field"]),
])
def test_bad_gamma(capsys, beam_file, gamma, words):
    assert_bad(*run(capsys, beam_file(), "--gamma", gamma, "--k", "1"), *words)


def test_gamma_sum_within_tolerance_is_accepted(capsys, beam_file):
    r, _ = run_json(capsys, beam_file(), "--gamma", "0.5,0.5000009", "--k", "1", "--poses",
                    "linear")
    assert math.fsum(r["gamma"]) == pytest.approx(1.0, abs=1e-15)


@pytest.mark.parametrize("k, words", [
    ("1,2", ["--k", "9", "got 2"]),                 # paper poses for n = 3: 9
    (",".join(["1"] * 10), ["--k", "9", "got 10"]),
    ("0", ["--k", "> 0"]),
    ("1,-1,1,1,1,1,1,1,1", ["--k", "> 0"]),
    ("nan", ["--k", "finite"]),
    ("stiff", ["--k", "numbers"]),
    ("1,1,1,1,1,1,1,1,1,", ["--k", "empty field"]),
])
def test_bad_k(capsys, beam_file, k, words):
    assert_bad(*run(capsys, beam_file(), "--gamma", PAPER_3R, "--k", k), *words)


def test_bad_k_count_with_explicit_poses(capsys, beam_file):
    assert_bad(*run(capsys, beam_file(), "--gamma", PAPER_3R, "--k", "1,2,3", "--poses",
                    "0.1,0.2"), "--k", "2", "got 3")
    assert_bad(*run(capsys, beam_file(), "--gamma", PAPER_3R, "--k", "1,2", "--poses",
                    "linear"), "--k", "exactly 1")


@pytest.mark.parametrize("poses, words", [
    ("sideways", ["--poses", "paper", "linear"]),
    ("-0.1", ["--poses", ">= 0"]),
    ("0.1,-0.2", ["--poses", ">= 0"]),
    ("0.1,nan", ["--poses", "finite"]),
    ("inf", ["--poses", "finite"]),
    ("", ["--poses"]),
])
def test_bad_poses(capsys, beam_file, poses, words):
    assert_bad(*run(capsys, beam_file(), "--gamma", PAPER_3R, "--k", "1", f"--poses={poses}"),
               *words)


@pytest.mark.parametrize("argv, words", [
    (["--law", "rubber"], ["--law", "rubber"]),
    (["--gamma", "0.5,0.5"], ["--k"]),                     # --k missing
    (["--k", "1"], ["--gamma"]),                           # --gamma missing
    (["--gamma", "0.5,0.5", "--k", "1", "--bogus"], ["--bogus"]),
])
def test_bad_or_missing_flags(capsys, beam_file, argv, words):
    if "--law" in argv:
        argv = ["--gamma", "0.5,0.5", "--k", "1", *argv]
    assert_bad(*run(capsys, beam_file(), *argv), *words)


# ----------------------------------------------------------------------------- bad beams via CLI
@pytest.mark.parametrize("data, field", [(d, f) for _, d, f in BAD_BEAMS],
                         ids=[i for i, _, _ in BAD_BEAMS])
def test_bad_beam_file(capsys, beam_file, data, field):
    assert_bad(*run(capsys, beam_file(data), "--gamma", "0.5,0.5", "--k", "1"), field)


@pytest.mark.parametrize("text, field", [(t, f) for _, t, f in BAD_FILES],
                         ids=[i for i, _, _ in BAD_FILES])
def test_bad_json_text(capsys, beam_file, text, field):
    assert_bad(*run(capsys, beam_file(text=text), "--gamma", "0.5,0.5", "--k", "1"), field,
               "JSON")


def test_bad_beam_messages_show_plain_numbers(capsys, beam_file):
    """Values from the beam file appear as plain floats, e.g. ``x[0] = 0.1``."""
    rc, out, err = run(capsys, beam_file(dict(UNIFORM, x=[0.1, 1.0])), "--gamma", "0.5,0.5",
                       "--k", "1")
    assert_bad(rc, out, err, "x[0] = 0.1")
    rc, out, err = run(capsys, beam_file(dict(UNIFORM, half_width=[0.1, -0.12])), "--gamma",
                       "0.5,0.5", "--k", "1")
    assert_bad(rc, out, err, "half_width[1] = -0.12")


def test_missing_beam_file(capsys, tmp_path):
    assert_bad(*run(capsys, tmp_path / "none.json", "--gamma", "0.5,0.5", "--k", "1"),
               "BEAM", "no such file")


# ----------------------------------------------------------------------------- real processes
def _proc(*argv, stdin=None):
    return subprocess.run([sys.executable, "-m", "prbdm.cli", "eval", *map(str, argv)],
                          capture_output=True, text=True, input=stdin, timeout=120)


def test_subprocess_json_and_exit_codes(tmp_path):
    good = tmp_path / "good.json"
    good.write_text(json.dumps(UNIFORM))
    p = _proc(good, "--gamma", PAPER_3R, "--k", "3", "--json")
    assert p.returncode == 0, p.stderr
    assert p.stderr == ""
    r = json.loads(p.stdout)
    assert len(r["omega"]) == 9

    p = _proc("-", "--gamma", "0.5,0.5", "--k", "1", "--poses", "linear", "--json",
              stdin=json.dumps(UNIFORM))
    assert p.returncode == 0 and json.loads(p.stdout)["poses"] == [[0.0]]


@pytest.mark.parametrize("case", ["nu", "unknown-key", "missing-file", "bad-json", "k-count",
                                  "law"])
def test_subprocess_bad_input(tmp_path, case):
    good = tmp_path / "good.json"
    good.write_text(json.dumps(UNIFORM))
    bad = tmp_path / "bad.json"
    args, word = {
        "nu": (lambda: bad.write_text(json.dumps({**UNIFORM, "material": {"nu": 0.5}})),
               "material.nu"),
        "unknown-key": (lambda: bad.write_text(json.dumps({**UNIFORM, "length": 1})), "length"),
        "missing-file": (lambda: None, "no such file"),
        "bad-json": (lambda: bad.write_text("{not json"), "JSON"),
        "k-count": (lambda: None, "--k"),
        "law": (lambda: None, "--law"),
    }[case]
    args()
    path = good if case in ("k-count", "law") else bad
    extra = {"k-count": ["--k", "1,2"], "law": ["--k", "1", "--law", "x"]}.get(case, ["--k", "1"])
    p = _proc(path, "--gamma", PAPER_3R, *extra, "--json")
    assert p.returncode == 2
    assert p.stdout == ""
    assert p.stderr.count("\n") == 1 and "Traceback" not in p.stderr
    assert word in p.stderr
