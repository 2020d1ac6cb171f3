"""``prbdm truth`` on the command line (docs/conventions.md §4)."""
import json
import subprocess
import sys

import pytest

from prbdm.cli import main

TAPER = {"name": "taper", "x": [0, 0.35, 1.0], "half_width": [0.18, 0.12, 0.05],
         "thickness": 0.03}
UNIFORM = {"x": [0, 1.0], "half_width": [0.1812, 0.1812], "thickness": 0.040532}


def test_default_table(beam_file, capsys):
    assert main(["truth", beam_file(TAPER), "--model", "beam"]) == 0
    out = capsys.readouterr().out
    assert "model beam" in out and "omega [rad/s]" in out and "participation" in out
    assert len([ln for ln in out.splitlines() if ln.strip()[:1].isdigit()]) == 5


def test_json_has_the_spec_keys(beam_file, capsys):
    assert main(["truth", beam_file(UNIFORM), "--model", "analytic", "--modes", "3",
                 "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert {"model", "omega", "freq_hz", "time_s"} <= set(d) and d["model"] == "analytic"
    assert len(d["omega"]) == 3 and d["omega"] == sorted(d["omega"])
    assert "all_modes" not in d


def test_plate_all_modes_json_lists_participations(beam_file, capsys):
    assert main(["truth", beam_file(TAPER), "--model", "plate", "--modes", "2", "--all-modes",
                 "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    modes = d["all_modes"]
    assert len(modes) > 2 and sum(m["kept"] for m in modes) == 2
    assert {m["symmetry"] for m in modes} == {"symmetric", "antisymmetric"}
    assert all(0 <= m["participation"] <= 1 for m in modes)
    kept = [m["omega"] for m in modes if m["kept"]]
    assert kept == pytest.approx(d["omega"])


def test_all_modes_table(beam_file, capsys):
    assert main(["truth", beam_file(TAPER), "--model", "plate", "--modes", "2",
                 "--all-modes"]) == 0
    out = capsys.readouterr().out
    assert "antisymmetric" in out and "kept" in out and "section frac." in out


@pytest.mark.parametrize("model", ["beam", "plate"])
def test_plot(beam_file, tmp_path, model, capsys):
    png = tmp_path / f"modes_{model}.png"
    assert main(["truth", beam_file(TAPER), "--model", model, "--modes", "3", "--plot",
                 str(png)]) == 0
    assert png.stat().st_size > 10_000
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_stdin(beam_file):
    proc = subprocess.run([sys.executable, "-m", "prbdm.cli", "truth", "-", "--json"],
                          input=json.dumps(TAPER), capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    from prbdm.geometry import Beam
    from prbdm.truth.choice import choose_truth

    d = json.loads(proc.stdout)
    # the default is auto: the truth `prbdm fit` takes for this panel, with its reason
    assert (d["model"], d["reason"]) == choose_truth(Beam.from_dict(TAPER), "auto")


@pytest.mark.parametrize("args, data, needle", [
    (["--model", "analytic"], TAPER, "uniform"),
    (["--modes", "0"], TAPER, "--modes"),
    (["--modes", "x"], TAPER, "--modes"),
    (["--model", "shell"], TAPER, "--model"),
    (["--model", "plate", "--modes", "99"], TAPER, "modes"),
    (["--model", "beam", "--selection", "participation"], TAPER, "--selection"),
    (["--plot", "figure.gif"], TAPER, "--plot"),
    ([], {"x": [0, 1], "half_width": [0.1, 0.0], "thickness": 0.01}, "half_width"),
    ([], {"x": [0, 1], "half_width": [0.1, 0.1], "thickness": 0.01, "colour": 1}, "colour"),
    ([], "{not json", "JSON"),
    (["--model", "beam"], {"x": [0, 1], "half_width": [0.5, 0.5], "thickness": 100},
     "thickness: must be at most 0.2 L"),
    (["--model", "analytic"], {"x": [0, 1], "half_width": [0.5, 0.5], "thickness": 100},
     "thickness: must be at most 0.2 L"),
    (["--model", "beam"], {"x": [0, 1e-9], "half_width": [0.5, 0.5], "thickness": 1e-11},
     "half_width: model 'beam' needs a full width 2 max(half_width) of at most 10 L"),
    (["--model", "plate"], {"x": [0, 1], "half_width": [0.002, 0.002], "thickness": 0.003},
     "thickness: the plate model needs a thickness of at most 0.5 x"),
    # a tongue at the tip: stations 1.6 mm apart, the half-width rising 0.11 -> 0.49 m between
    # them (random_beam(0, 219, min_half_width=0.01)'s tip; a 0.24-degree corner)
    (["--model", "plate"], {"x": [0, 0.9984, 1], "half_width": [0.2, 0.1119, 0.492],
                            "thickness": 0.02}, "corner of 0.241 degrees"),
    (["--model", "mindlin"], {"x": [0, 0.9984, 1], "half_width": [0.2, 0.1119, 0.492],
                              "thickness": 0.02}, "at least 1 degrees"),
])
def test_bad_input_is_one_line_and_exit_2(beam_file, args, data, needle):
    proc = subprocess.run([sys.executable, "-m", "prbdm.cli", "truth", beam_file(data), *args],
                          capture_output=True, text=True)
    assert proc.returncode == 2
    err = proc.stderr.strip()
    assert len(err.splitlines()) == 1 and needle in err and "Traceback" not in err
    assert proc.stdout == ""


def test_missing_file_is_exit_2(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "prbdm.cli", "truth",
                           str(tmp_path / "nope.json")], capture_output=True, text=True)
    assert proc.returncode == 2 and "no such file" in proc.stderr


def test_cli_path_does_not_import_torch(beam_file):
    code = ("import sys; from prbdm.cli import main; "
            f"assert main(['truth', {beam_file(TAPER)!r}, '--model', 'plate', '--modes', '2', "
            "'--json']) == 0; assert 'torch' not in sys.modules")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr


def test_help():
    proc = subprocess.run([sys.executable, "-m", "prbdm.cli", "truth", "--help"],
                          capture_output=True, text=True)
    assert proc.returncode == 0 and "--all-modes" in proc.stdout and "--plot" in proc.stdout
