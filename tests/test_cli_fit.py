"""`prbdm fit` and `prbdm demo` through the command line."""
import json
import subprocess
import sys

import pytest

from prbdm.cli import main

UNIFORM = {"name": "uniform", "x": [0.0, 1.0], "half_width": [0.1812, 0.1812],
           "thickness": 0.040532}
TAPERED = {"x": [0.0, 0.4, 1.0], "half_width": [0.2, 0.1, 0.05], "thickness": 0.02}


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


@pytest.mark.parametrize("truth", ["analytic"])
def test_fit_truth_message_names_the_fit_flag(beam_file, capsys, truth):
    """The truth library's advice says --model (the flag of `prbdm truth`); `fit` says --truth."""
    code = main(["fit", beam_file(TAPERED), "--joints", "2", "--truth", truth, "--starts", "2"])
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "Traceback" not in err[0]
    assert "--truth analytic" in err[0] and "use --truth beam or plate" in err[0], err[0]
    assert "--model" not in err[0]


def test_fit_with_more_modes_than_joints_in_the_json(beam_file, capsys):
    """--modes 3 with n = 2: r = min(n, modes) = 2 modes mapped, 3 truth frequencies computed
    (max(modes, n)); every pose reports its errors for the mapped modes only."""
    code = main(["fit", beam_file(TAPERED), "--joints", "2", "--modes", "3", "--starts", "4",
                 "--pose-target", "straight", "--json"])
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    assert out["joints"] == 2 and out["modes"] == 2 and out["pose_target"] == "straight"
    assert len(out["omega_truth"]) == 3
    m = len(out["k"])
    assert len(out["freq_error"]) == len(out["omega"]) == len(out["poses"]) == m > 1
    assert all(len(e) == 2 for e in out["freq_error"])
    assert all(len(w) == 2 for w in out["omega"])      # an nR-PRBDM has n frequencies
    assert out["max_freq_error"] == max(max(e) for e in out["freq_error"])
    # the errors are those of the mapped modes against the truth
    for w, e in zip(out["omega"], out["freq_error"]):
        for j in range(2):
            assert e[j] == pytest.approx(abs(w[j] / out["omega_truth"][j] - 1), rel=1e-9,
                                         abs=1e-15)


def test_fit_default_is_the_shape_target(beam_file, capsys):
    """The default fit is made at rest and keeps its stiffness at every pose: one SCF repeated,
    its answer at rest against the truth in ``rest``, the loss that of rest."""
    code = main(["fit", beam_file(TAPERED), "--joints", "2", "--starts", "4", "--json"])
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    assert out["pose_target"] == "shape" and len(out["poses"]) > 1
    assert len(set(out["k"])) == 1 and out["k"][0] == out["rest"]["k"]
    for j in range(2):
        assert out["rest"]["freq_error"][j] == pytest.approx(
            abs(out["rest"]["omega"][j] / out["omega_truth"][j] - 1), rel=1e-9, abs=1e-15)
    # the chain's frequencies change with the pose (its inertia does), its stiffness does not
    assert out["omega"][0] != out["omega"][-1]
    check = out["self_check"]["poses"]
    if check["checked"]:
        assert len(out["freq_error"]) == len(out["poses"])
    else:
        assert out["freq_error"] is None and "shell" in check["why"]


def test_fit_subprocess_exit_code(beam_file):
    r = subprocess.run([sys.executable, "-m", "prbdm.cli", "fit", beam_file(TAPERED),
                        "--joints", "2", "--truth", "analytic"], capture_output=True, text=True)
    assert r.returncode == 2
    assert len(r.stderr.strip().splitlines()) == 1 and "Traceback" not in r.stderr


def test_demo_runs(capsys):
    assert main(["demo", "--joints", "2", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["fit"]["loss_percent"] < out["uniform_chain"]["loss_percent"]
    # both objectives side by side: each fit is best at what it minimises (issue 18 item 4)
    eig, freq = out["fit"], out["fit_frequency"]
    assert eig["objective"] == "eigenvalue" and freq["objective"] == "frequency"
    assert eig["loss_percent"] <= freq["loss_percent"] * (1 + 1e-6)
    assert freq["max_freq_error"] <= eig["max_freq_error"] * (1 + 1e-6)


@pytest.mark.parametrize("half_width, model", [(0.2, "plate"), (0.01, "beam")])
def test_truth_auto_is_the_default_and_says_why(beam_file, capsys, half_width, model):
    """`prbdm fit` without --truth: the plate for a wide panel, the beam for a 2 cm strip on 1 m
    (full width <= 0.05 L, where the beam is within 1 % of the plate; issue 16 item 5)."""
    path = beam_file({"x": [0.0, 1.0], "half_width": [half_width, half_width / 2],
                      "thickness": 0.004})
    assert main(["fit", path, "--joints", "2", "--starts", "4", "--json"]) == 0
    truth = json.loads(capsys.readouterr().out)["truth"]
    assert truth["model"] == model and truth["reason"].startswith("auto:")


def test_fit_to_the_shear_deformable_plate(beam_file, capsys):
    """`--truth mindlin` fits to the Reissner-Mindlin plate: on a panel 0.04 L thick its
    frequencies lie below the Kirchhoff plate's by the transverse shear and rotary inertia the
    Kirchhoff plate leaves out, more on higher modes (docs/howto/choose-a-truth.md: about 0.3 / 1 / 2 % on modes
    1-3 at this thickness, within 0.3 % of 3-D elasticity)."""
    path = beam_file({"x": [0.0, 1.0], "half_width": [0.25, 0.25], "thickness": 0.04})
    omega = {}
    for truth in ("plate", "mindlin"):
        assert main(["fit", path, "--joints", "3", "--starts", "4", "--truth", truth,
                     "--json"]) == 0
        out = json.loads(capsys.readouterr().out)
        assert out["truth"]["model"] == truth
        omega[truth] = out["omega_truth"][:3]
    drop = [1 - m / p for m, p in zip(omega["mindlin"], omega["plate"])]
    assert 0.001 < drop[0] < drop[1] < drop[2] < 0.05, drop
