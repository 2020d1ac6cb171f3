"""Every answer checks itself (issue 35): the panels a new user met a traceback or a quiet wrong
model on, through every command that fits or evaluates, and the one rule on which truth answers."""
import json

import pytest

NECK_ON_A_CUT = {"x": [0, 0.75, 1.0], "half_width": [0.1, 0.03, 0.06], "thickness": 0.01}
THIN_STRIP_PLATE = {"x": [0, 0.6], "half_width": [0.09, 0.09], "thickness": 0.003}
ALU_PLATE = {"x": [0, 0.6], "half_width": [0.2, 0.2], "thickness": 0.003,
             "material": {"E": 70e9, "rho": 2700, "nu": 0.33}}


@pytest.mark.parametrize("argv", [
    ["fit", "--joints", 4, "--starts", 4],
    ["eval", "--gamma", "0.125,0.25,0.25,0.25,0.125", "--k", "1", "--poses", "linear"],
    ["compare", "--joints", 4],
    ["export", "--joints", 4, "--starts", 4, "-o", "{tmp}/p.xml"],
    ["simulate", "--joints", 4, "--starts", 4, "--duration", 0.5],
])
def test_a_station_on_a_cut_of_the_joints_spans_is_no_traceback(run, beam_file, argv, tmp_path):
    """The panel whose station 0.75 L falls on a cut of the equal-link layout's tributary spans
    (a NaN compliance, then torch's eigh error, exit 1, in every command)."""
    path = beam_file(NECK_ON_A_CUT)
    argv = [str(a).replace("{tmp}", str(tmp_path)) for a in argv]
    rc, out, err = run(argv[0], path, *argv[1:], "--json")
    assert rc == 0, err
    assert "Traceback" not in err and "nan" not in out.lower()


def test_fit_checks_itself_against_the_truth_it_used(run, beam_file):
    rc, out, err = run("fit", beam_file(NECK_ON_A_CUT), "--joints", 4, "--starts", 8,
                       "--pose-target", "straight", "--json")
    assert rc == 0, err
    d = json.loads(out)
    check = d["self_check"]
    assert check["truth"] == f"the {d['truth']['model']} truth" and check["modes"] == 4
    # the paper's eigenvalue loss leaves mode 1 far off at the deflected poses: said, with numbers
    assert check["max_error"] == pytest.approx(max(max(r) for r in d["freq_error"]), rel=1e-9)
    if not check["ok"]:
        assert any(w.startswith(f"mode {check['worst_mode']}:") and "--objective frequency" in w
                   for w in d["warnings"])
    rc, out, err = run("fit", beam_file(NECK_ON_A_CUT), "--joints", 4, "--poses", "linear",
                       "--json")
    assert rc == 0 and json.loads(out)["self_check"]["ok"]


def test_a_network_answer_that_misses_its_own_truth_is_not_given(run, beam_file):
    """plate-n4 answered this thin uniform plate with gamma 0.89 clamped, SCF 3.3e-4 and mode 1
    75 % below its own predicted truth, exit 0, no warning: its candidate of least loss. Now the
    physics takes its plausible candidate, which passes its self-check; and an answer with no
    plausible candidate (a panel 1.4 L wide, outside its range) is refused, one line, exit 2."""
    rc, out, err = run("predict", beam_file(THIN_STRIP_PLATE), "--joints", 4, "--json")
    assert rc == 0, err
    d = json.loads(out)
    assert d["checkpoint"]["name"] == "plate-n4.safetensors"
    assert not d["self_check"]["implausible"] and d["self_check"]["ok"]
    assert d["gamma"][0] < 0.5 and min(d["k"]) > 0.1
    wide = beam_file({"x": [0.0, 0.5, 1.0], "half_width": [0.7, 0.6, 0.5], "thickness": 0.02})
    rc, out, err = run("predict", wide, "--joints", 4, "--truth", "plate")
    assert rc == 2 and out == "" and len(err.strip().splitlines()) == 1
    assert "mode 1" in err and "prbdm fit" in err


def test_simulate_judges_a_model_by_the_truth_it_was_fitted_to(run, beam_file, tmp_path):
    path = beam_file(ALU_PLATE)
    rc, out, err = run("fit", path, "--joints", 3, "--starts", 4, "--json")
    assert rc == 0 and json.loads(out)["truth"]["model"] == "plate"
    fit = tmp_path / "fit.json"
    fit.write_text(out)
    rc, out, err = run("simulate", path, "--from", fit)
    assert rc == 2 and "plate truth" in err and "--truth beam" in err
    rc, out, err = run("simulate", path, "--joints", 3, "--starts", 4, "--json")
    assert rc == 0, err
    d = json.loads(out)
    assert d["refit"] is None and d["check"]["ok"]
    gap = [w for w in d["warnings"] if "both solved for this panel" in w]
    assert len(gap) == 1 and "0.667 L wide" in gap[0] and "Kirchhoff plate" in gap[0]


def test_truth_auto_is_the_default_with_its_reason_and_the_beam_says_its_gap(run, beam_file):
    path = beam_file(ALU_PLATE)
    rc, out, err = run("truth", path, "--modes", 4, "--json")
    d = json.loads(out)
    assert rc == 0 and d["model"] == "plate" and d["reason"].startswith("auto:")
    plate = d["omega"]
    rc, out, err = run("truth", path, "--modes", 4, "--model", "beam", "--json")
    d = json.loads(out)
    (gap,) = [w for w in d["warnings"] if "both solved for this panel" in w]
    worst = max(abs(b / p - 1) for b, p in zip(d["omega"], plate))
    assert f"worst {100 * worst:.2g} %" in gap


def test_more_joints_than_a_plate_has_modes_maps_the_modes_asked(run, beam_file):
    rc, out, err = run("fit", beam_file(ALU_PLATE), "--joints", 31, "--modes", 4, "--starts", 1,
                       "--poses", "linear", "--json")
    assert rc == 0, err
    assert json.loads(out)["modes"] == 4
    rc, out, err = run("fit", beam_file(ALU_PLATE), "--joints", 35, "--modes", 33)
    assert rc == 2 and "--modes 33" in err and "at most 30" in err


def test_best_loss_is_the_papers_loss_or_absent(run, beam_file):
    path = beam_file(NECK_ON_A_CUT)
    rc, out, err = run("fit", path, "--joints", 3, "--starts", 4, "--objective", "frequency",
                       "--truth", "beam", "--json")
    d = json.loads(out)
    assert "best_loss_percent" not in d
    assert d["best_objective_percent"] <= d["frequency_percent"] * (1 + 1e-9)
    rc, out, err = run("fit", path, "--joints", 3, "--starts", 4, "--truth", "beam", "--json")
    d = json.loads(out)
    assert d["best_loss_percent"] == d["best_objective_percent"] <= d["loss_percent"] * (1 + 1e-9)


STRIP = {"x": [0, 1], "half_width": [0.02, 0.01], "thickness": 0.005}


def test_a_shape_fit_holds_its_stiffness_and_checks_each_pose_against_the_bent_rod(run,
                                                                                     beam_file):
    """--pose-target shape: fitted at rest, the stiffness held at every paper pose, each pose
    compared with the geometrically exact rod bent into that pose's shape (the reference it was
    made for away from rest); the paper's target says which it is too."""
    path = beam_file(STRIP)
    rc, out, err = run("fit", path, "--joints", 4, "--starts", 16, "--pose-target", "shape",
                       "--json")
    assert rc == 0, err
    d = json.loads(out)
    assert d["pose_target"] == "shape" and len(d["k"]) == len(d["poses"]) == 6
    assert len(set(d["k"])) == 1                             # one stiffness, held
    poses = d["self_check"]["poses"]
    assert poses["checked"] and poses["truth"] == "the rod in the pose's shape"
    assert len(d["freq_error"]) == 6 and poses["max_error"] == pytest.approx(
        max(max(r) for r in d["freq_error"]), rel=1e-12)
    # a tapered strip held at the paper's poses follows the bent rod within a few percent, at
    # rest exactly
    assert poses["max_error"] < 0.05 and d["self_check"]["max_error"] < 1e-6
    # the same fit is the default; the paper's target is one flag away
    rc, out, err = run("fit", path, "--joints", 4, "--starts", 16, "--json")
    assert json.loads(out)["k"] == d["k"]
    rc, out, err = run("fit", path, "--joints", 4, "--starts", 16, "--pose-target", "straight",
                       "--json")
    d = json.loads(out)
    assert d["pose_target"] == "straight" and len(set(d["k"])) == 6


def test_a_shape_fit_of_a_plate_does_not_pretend_to_check_its_poses(run, beam_file):
    rc, out, err = run("fit", beam_file(ALU_PLATE), "--joints", 3, "--starts", 8,
                       "--pose-target", "shape", "--json")
    assert rc == 0, err
    poses = json.loads(out)["self_check"]["poses"]
    assert poses["checked"] is False and "shell" in poses["why"]


def test_compare_checks_every_route_against_the_truth(run, beam_file):
    rc, out, err = run("compare", beam_file(NECK_ON_A_CUT), "--joints", 4, "--starts", 4,
                       "--json")
    assert rc == 0, err
    d = json.loads(out)
    for key in ("network", "fit", "refined"):
        check = d[key]["self_check"]
        assert check["objective"] == d["objective"] and check["modes"] == d["modes"]
        assert check["loss_percent"] == pytest.approx(d[key]["loss_percent"], rel=1e-9)
