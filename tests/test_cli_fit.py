"""`prbdm fit` and `prbdm demo` through the command line."""
import json
import subprocess
import sys

import pytest

from prbdm.cli import main

UNIFORM = {"name": "uniform", "x": [0.0, 1.0], "half_width": [0.1812, 0.1812],
           "thickness": 0.040532}
TAPERED = {"x": [0.0, 0.4, 1.0], "half_width": [0.2, 0.1, 0.05], "thickness": 0.02}


@pytest.fixture
def beam_file(tmp_path):
    def write(data, name="beam.json"):
        path = tmp_path / name
        path.write_text(json.dumps(data))
        return str(path)
    return write


def test_fit_json_has_the_spec_keys(beam_file, capsys):
    code = main(["fit", beam_file(UNIFORM), "--joints", "2", "--truth", "analytic", "--starts", "8",
                 "--json"])
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    for key in ("gamma", "k", "law", "poses", "omega_truth", "omega", "loss_percent", "time_s"):
        assert key in out
    assert len(out["gamma"]) == 3 and abs(sum(out["gamma"]) - 1) < 1e-12
    assert len(out["omega"]) == len(out["k"]) == len(out["poses"])
    assert out["truth"]["model"] == "analytic"


def test_fit_table_and_plot(beam_file, tmp_path, capsys):
    plot = tmp_path / "fit.png"
    code = main(["fit", beam_file(TAPERED), "--joints", "2", "--starts", "8", "--poses", "0.1,0.2",
                 "--plot", str(plot)])
    assert code == 0
    text = capsys.readouterr().out
    assert "loss" in text and "SCF k" in text
    assert plot.stat().st_size > 10_000


@pytest.mark.parametrize("args, field", [
    (["--joints", "0"], "--joints"),
    (["--joints", "40"], "--joints"),
    (["--joints", "2", "--truth", "fem"], "--truth"),
    (["--joints", "2", "--law", "spring"], "--law"),
    (["--joints", "2", "--starts", "0"], "--starts"),
    (["--joints", "2", "--poses", "0.1,x"], "--poses"),
    (["--joints", "2", "--plot", "out.txt"], "--plot"),
    (["--joints", "2", "--truth", "analytic"], "analytic"),
])
def test_fit_bad_input_is_one_line(beam_file, capsys, args, field):
    try:
        code = main(["fit", beam_file(TAPERED), *args])
    except SystemExit as exc:          # argparse rejects a flag before the command runs
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and field in err[0] and "Traceback" not in err[0]


def test_fit_subprocess_exit_code(beam_file):
    r = subprocess.run([sys.executable, "-m", "prbdm.cli", "fit", beam_file(TAPERED),
                        "--joints", "2", "--truth", "analytic"], capture_output=True, text=True)
    assert r.returncode == 2
    assert len(r.stderr.strip().splitlines()) == 1 and "Traceback" not in r.stderr


def test_demo_runs(capsys):
    assert main(["demo", "--joints", "2", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["fit"]["loss_percent"] < out["uniform_chain"]["loss_percent"]
