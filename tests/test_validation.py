"""One validation for every command (issue 19): the same beams refused by all seven beam-reading
commands with the same one-line message, the material block all or nothing, the hard limits,
unit-mistake warnings, large planforms simplified within the stated tolerance, progress, and
missing optional extras answered with the exact pip line."""
from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import numpy as np
import pytest
import tomllib

from prbdm import geometry
from prbdm.commands import _common
from prbdm.errors import BadInput
from prbdm.geometry import (
    HARD_LIMITS,
    MAX_THICKNESS_RATIO,
    MAX_WIDTH_RATIO,
    SIMPLIFY_ABOVE,
    SIMPLIFY_RTOL,
    Beam,
    check_beam,
    random_beam,
    simplify_planform,
    unit_warnings,
)

ROOT = Path(__file__).resolve().parents[1]
TAPER = {"x": [0.0, 0.35, 1.0], "half_width": [0.18, 0.12, 0.05], "thickness": 0.03}
STEEL = {"E": 205e9, "rho": 7850.0, "nu": 0.28}

#: every command that reads a beam, with the flags it needs (refusals happen before any work)
COMMANDS = {
    "truth": [],
    "fit": ["--joints", "2", "--starts", "2"],
    "eval": ["--gamma", "0.5,0.5", "--k", "1"],
    "predict": ["--joints", "4"],
    "compare": ["--joints", "4", "--starts", "2"],
    "export": ["--joints", "2", "--starts", "2", "-o", "{tmp}/out.json"],
    "simulate": ["--joints", "2", "--starts", "2"],
}


def _args(command, tmp_path):
    return [a.replace("{tmp}", str(tmp_path)) for a in COMMANDS[command]]


def _one_error_line(err: str, command: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert "Traceback" not in err
    prefix = f"prbdm {command}: error: "
    assert lines[0].startswith(prefix), lines[0]
    return lines[0][len(prefix):]


# ------------------------------------------------------------------ one validation everywhere
REFUSED = [
    ("thick", {**TAPER, "thickness": 0.625}, "thickness: must be at most 0.2 L"),
    ("width-ratio", {"x": [0, 1], "half_width": [0.15, 1e-9], "thickness": 0.01},
     "half_width: varies by a factor 1.5e+08"),
    ("partial-material", {**TAPER, "material": {"E": 69e9}}, "material: missing key(s) rho, nu"),
    ("L-huge", {"x": [0, 2e9], "half_width": [1e8, 1e8], "thickness": 1e7}, "L: must lie in"),
    ("E-huge", {**TAPER, "material": {**STEEL, "E": 1e16}}, "material.E: must lie in"),
    ("rho-tiny", {**TAPER, "material": {**STEEL, "rho": 1e-4}}, "material.rho: must lie in"),
]


@pytest.mark.parametrize("data, needle", [(d, n) for _, d, n in REFUSED],
                         ids=[i for i, _, _ in REFUSED])
def test_every_command_refuses_the_same_beam_with_the_same_line(run, beam_file, tmp_path, data,
                                                                 needle):
    path = beam_file(data)
    messages = {}
    for command in COMMANDS:
        rc, out, err = run(command, path, *_args(command, tmp_path))
        assert rc == 2, (command, err)
        assert out == ""
        messages[command] = _one_error_line(err, command)
    assert len(set(messages.values())) == 1, messages          # word for word the same
    assert needle in messages["truth"]
    assert not (tmp_path / "out.json").exists()                # export wrote nothing


def test_predict_refuses_what_truth_refuses_at_the_edge_of_thin_theory(run, beam_file):
    """Just inside the thin-theory limit both answer; just outside both refuse."""
    for t, ok in ((0.999 * MAX_THICKNESS_RATIO, True), (1.001 * MAX_THICKNESS_RATIO, False)):
        path = beam_file({"x": [0, 1], "half_width": [0.2, 0.1], "thickness": t})
        rc_truth, _, err_truth = run("truth", path, "--json")
        rc_pred, _, err_pred = run("predict", path, "--joints", "4", "--json")
        assert (rc_truth, rc_pred) == ((0, 0) if ok else (2, 2))
        if not ok:
            assert err_truth.split("error: ")[1] == err_pred.split("error: ")[1]


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_every_command_reports_the_input_block(run, beam_file, tmp_path, command):
    """The unit warning reaches stderr and the JSON's ``input`` of every beam command."""
    data = {**TAPER, "material": {"E": 69e9, "rho": 2.7, "nu": 0.33}}
    rc, out, err = run(command, beam_file(data), *_args(command, tmp_path), "--json")
    assert rc == 0, err
    block = json.loads(out)["input"]
    assert block["stations"] == 3 and block["simplified"] is None
    assert len(block["warnings"]) == 1 and "g/cm^3" in block["warnings"][0]
    assert f"prbdm {command}: warning: material.rho" in err


def test_width_ratio_limit_is_the_same_for_the_library_and_commands():
    ok = Beam(x=[0, 1], half_width=[0.1, 0.1 / (0.99 * MAX_WIDTH_RATIO)], thickness=0.01)
    check_beam(ok)
    bad = Beam(x=[0, 1], half_width=[0.1, 0.1 / (1.01 * MAX_WIDTH_RATIO)], thickness=0.01)
    with pytest.raises(BadInput, match="half_width"):
        check_beam(bad)


def test_plate_checkpoint_limits_come_from_check_beam():
    """``model='plate'`` adds the plate's limits (what `predict` with a plate network applies)."""
    needle = Beam(x=[0, 1], half_width=[0.1, 0.1 / 2e4], thickness=0.01)
    check_beam(needle, "beam")
    with pytest.raises(BadInput, match="model 'plate' accepts at most"):
        check_beam(needle, "plate")


def test_no_command_reads_a_beam_another_way():
    """read_beam is the one way: no command module calls load_beam itself."""
    for path in (ROOT / "prbdm" / "commands").glob("*.py"):
        if path.name == "_common.py":
            continue
        assert "load_beam" not in path.read_text(), path.name


# ------------------------------------------------------------------ material all or nothing
@pytest.mark.parametrize("given, missing", [({"E": 69e9}, "rho, nu"), ({"rho": 2700}, "E, nu"),
                                            ({"E": 69e9, "rho": 2700}, "nu"), ({}, "E, rho, nu")])
def test_partial_material_names_the_missing_keys(run, beam_file, given, missing):
    rc, out, err = run("truth", beam_file({**TAPER, "material": given}))
    assert rc == 2
    line = _one_error_line(err, "truth")
    assert line.startswith(f"material: missing key(s) {missing};")


def test_full_material_or_none_is_accepted(run, beam_file):
    alu = {"E": 69e9, "rho": 2700.0, "nu": 0.33}
    rc, out, _ = run("truth", beam_file({**TAPER, "material": alu}), "--model", "beam", "--json")
    assert rc == 0
    rc, out_steel, _ = run("truth", beam_file(TAPER, "steel.json"), "--model", "beam", "--json")
    assert rc == 0
    # the beam's frequencies scale with sqrt(E / rho): the aluminium was read, not steel
    a, s = json.loads(out)["omega"][0], json.loads(out_steel)["omega"][0]
    expected = ((alu["E"] / alu["rho"]) / (STEEL["E"] / STEEL["rho"])) ** 0.5
    assert a / s == pytest.approx(expected, rel=1e-9) and abs(expected - 1) > 1e-3


def test_a_bad_value_is_named_before_the_missing_keys():
    with pytest.raises(BadInput, match=r"material\.nu"):
        Beam.from_dict({**TAPER, "material": {"nu": 0.5}})


# ------------------------------------------------------------------ hard limits
@pytest.mark.parametrize("field", sorted(HARD_LIMITS))
@pytest.mark.parametrize("side", ["low", "high"])
def test_hard_limits(field, side):
    lo, hi, unit = HARD_LIMITS[field]
    value = lo / 10 if side == "low" else hi * 10
    # a beam that is fine except for `field`: all sizes scaled with L so that thin theory and
    # the width ratio hold
    if field in ("L", "thickness", "max(half_width)"):
        if field == "L":
            beam = Beam(x=[0, value], half_width=[0.1 * value] * 2, thickness=0.01 * value)
        elif field == "thickness":
            L = value / 0.01
            beam = Beam(x=[0, L], half_width=[0.1 * L] * 2, thickness=value)
        else:
            L = value / 0.1
            beam = Beam(x=[0, L], half_width=[value] * 2, thickness=0.01 * L)
    else:
        key = field.split(".")[1]
        mat = geometry.Material(**{**STEEL, key: value})
        beam = Beam(x=[0, 1], half_width=[0.1, 0.1], thickness=0.01, material=mat)
    with pytest.raises(BadInput) as exc:
        check_beam(beam)
    msg = str(exc.value)
    if field == "max(half_width)" or (field == "thickness" and side == "high"):
        # beyond the hard limit of one length, another length's limit may answer first
        assert re.match(r"(L|thickness|max\(half_width\)): must lie in", msg), msg
    else:
        assert msg.startswith(f"{field}: must lie in [{lo:g}, {hi:g}] {unit}"), msg


def test_hard_limits_admit_their_ends():
    lo, hi, _ = HARD_LIMITS["material.E"]
    for E in (lo, hi):
        mat = geometry.Material(E=E, rho=7850.0, nu=0.3)
        check_beam(Beam(x=[0, 1], half_width=[0.1, 0.1], thickness=0.01, material=mat))


# ------------------------------------------------------------------ unit mistakes
@pytest.mark.parametrize("data, needle", [
    ({"x": [0, 350, 800], "half_width": [180, 120, 50], "thickness": 30},
     "if it was meant in millimetres, L = 0.8 m"),
    ({**TAPER, "material": {"E": 69, "rho": 2700, "nu": 0.33}}, "if it was meant in GPa, E = 6.9e+10 Pa"),
    ({**TAPER, "material": {"E": 69000, "rho": 2700, "nu": 0.33}}, "if it was meant in MPa, E = 6.9e+10 Pa"),
    ({**TAPER, "material": {"E": 69e9, "rho": 2.7, "nu": 0.33}},
     "if it was meant in g/cm^3, rho = 2700 kg/m^3"),
    ({**TAPER, "thickness": 3e-6}, "1000x too small"),
])
def test_unit_mistake_warns_on_stderr_and_in_json(run, beam_file, data, needle):
    for command, extra in (("truth", []), ("predict", ["--joints", "4"]),
                           ("eval", ["--gamma", "0.5,0.5", "--k", "1"])):
        rc, out, err = run(command, beam_file(data), "--json", *extra)
        assert rc == 0, err
        assert needle in err and f"prbdm {command}: warning:" in err
        warnings = json.loads(out)["input"]["warnings"]
        assert any(needle in w for w in warnings), warnings


def test_thickness_in_millimetres_is_refused_with_the_hint(run, beam_file):
    rc, _, err = run("predict", beam_file({**TAPER, "thickness": 3}), "--joints", "4")
    assert rc == 2
    line = _one_error_line(err, "predict")
    assert line.startswith("thickness: must be at most 0.2 L")
    assert line.endswith("if it was meant in millimetres, thickness = 0.003 m")


def test_plausible_beams_get_no_unit_warning():
    for i in range(200):
        assert unit_warnings(random_beam(0, i)) == []
    alu = geometry.Material(E=69e9, rho=2700.0, nu=0.33)
    assert unit_warnings(Beam(x=[0, 0.05], half_width=[0.005] * 2, thickness=5e-4,
                              material=alu)) == []


# ------------------------------------------------------------------ large planforms
def _resampled(beam: Beam, count: int) -> Beam:
    x = np.union1d(np.linspace(0, beam.length, count - beam.x.size + 2), beam.x)
    return Beam(x=x, half_width=np.interp(x, beam.x, beam.half_width),
                thickness=beam.thickness, material=beam.material)


def test_simplify_recovers_a_resampled_polyline():
    small = random_beam(2019, 0, p=18)
    simple, info = simplify_planform(_resampled(small, 10_000))
    assert info["stations_in"] >= 10_000
    assert info["stations_out"] <= small.x.size
    assert info["max_deviation"] <= SIMPLIFY_RTOL
    fine = np.linspace(0, small.length, 50_001)
    w0 = np.interp(fine, small.x, small.half_width)
    assert np.max(np.abs(simple.width_at(fine) / 2 - w0) / w0) <= SIMPLIFY_RTOL


def test_simplify_keeps_the_tolerance_between_stations_on_a_curve():
    x = np.linspace(0, 1, 5000)
    w = 0.1 + 0.05 * np.sin(2 * np.pi * x) + 0.02 * np.cos(17 * x)
    beam = Beam(x=x, half_width=w, thickness=0.01)
    simple, info = simplify_planform(beam)
    assert SIMPLIFY_ABOVE / 4 < info["stations_out"] < info["stations_in"] / 5
    assert simple.x[0] == 0 and simple.x[-1] == 1 and np.all(np.isin(simple.x, x))
    fine = np.linspace(0, 1, 40_001)
    dev = np.abs(simple.width_at(fine) - beam.width_at(fine)) / beam.width_at(fine)
    assert dev.max() <= SIMPLIFY_RTOL * (1 + 1e-9)
    # the reported deviation is the largest (it sits at an original station, which the fine
    # grid need not hit)
    assert dev.max() <= info["max_deviation"] * (1 + 1e-9)
    assert info["max_deviation"] == pytest.approx(dev.max(), rel=1e-3)
    # a small planform is left alone
    same, none = simplify_planform(random_beam(0, 1))
    assert none is None and same.x.size == 12


def test_simplified_prbdm_frequencies_within_the_stated_tolerance(run, beam_file):
    """Mass and stiffness per unit length are both proportional to the width: frequencies move
    by at most ~SIMPLIFY_RTOL (the PRBDM's section integrals are exact on both planforms)."""
    x = np.linspace(0, 1, 3000)
    w = 0.1 + 0.05 * np.sin(2 * np.pi * x)
    path = beam_file(Beam(x=x, half_width=w, thickness=0.01).to_dict())
    flags = ["--gamma", "0.2,0.3,0.5", "--k", "1", "--json"]
    rc, out, err = run("eval", path, *flags)
    assert rc == 0 and "simplified from 3000" in err
    rc, raw, _ = run("eval", path, *flags, "--all-stations")
    assert rc == 0
    s, r = json.loads(out), json.loads(raw)
    assert s["input"]["simplified"]["stations_out"] < 300 and r["input"]["simplified"] is None
    rel = np.abs(np.array(s["omega"]) / np.array(r["omega"]) - 1)
    assert rel.max() <= 2 * SIMPLIFY_RTOL
    assert rel.max() > 0          # the simplification did change the beam (the test can fail)


def test_fit_on_many_stations_reports_the_simplification(run, beam_file):
    big = _resampled(random_beam(2019, 0, p=18), 2000)
    rc, out, err = run("fit", beam_file(big.to_dict()), "--joints", "2", "--starts", "2",
                       "--json")
    assert rc == 0
    s = json.loads(out)["input"]["simplified"]
    assert s["stations_in"] == big.x.size and s["stations_out"] <= 20
    assert "planform simplified" in err


def test_fit_progress_callback_counts_iterations():
    import torch  # noqa: F401  (prbdm.fit needs it)

    from prbdm.fit import StopRules, fit_prbdm
    from prbdm.truth import bending_frequencies

    beam = random_beam(0, 2)
    omega = bending_frequencies(beam, "beam", modes=3).omega
    seen = []
    fit_prbdm(beam, omega, joints=3, starts=4, stop=StopRules(max_iter=20),
              progress=lambda i, total: seen.append((i, total)))
    assert seen and seen[0] == (1, 20)
    assert [i for i, _ in seen] == list(range(1, len(seen) + 1))
    assert all(total == 20 for _, total in seen)


def test_no_progress_bar_when_stderr_is_not_a_terminal(capsys):
    update, close = _common.progress_bar("x")
    assert update is None
    close()


def test_progress_bar_on_a_terminal(monkeypatch):
    import io

    class Terminal(io.StringIO):
        def isatty(self):
            return True
    screen = Terminal()
    monkeypatch.setattr(sys, "stderr", screen)
    update, close = _common.progress_bar("prbdm fit", delay=0.0)
    import time

    for i in range(1, 31):
        update(i, 150)
    time.sleep(0.2)             # past tqdm's minimum refresh interval (0.1 s)
    update(31, 150)
    close()
    assert "prbdm fit" in screen.getvalue() and "/150" in screen.getvalue()


# ------------------------------------------------------------------ missing extras
def test_dataset_without_pyarrow_names_the_extra(run, monkeypatch, tmp_path):
    monkeypatch.setitem(sys.modules, "pyarrow", None)
    rc, out, err = run("dataset", "generate", "--out", tmp_path / "d", "--count", "1",
                       "--joints", "2")
    assert rc == 2
    assert _one_error_line(err, "dataset").endswith('pip install "prbdm[data]"')
    assert not (tmp_path / "d").exists()


def test_plot_without_matplotlib_names_the_extra(run, monkeypatch, beam_file, tmp_path):
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    rc, out, err = run("truth", beam_file(TAPER), "--plot", tmp_path / "f.png")
    assert rc == 2
    assert _one_error_line(err, "truth").endswith('pip install "prbdm[plot]"')
    assert out == "" and not (tmp_path / "f.png").exists()


def test_a_late_missing_extra_is_still_one_line(run, monkeypatch, beam_file):
    """The CLI's backstop: an optional module missing deep inside a command (here mujoco)."""
    from prbdm.commands import eval as eval_cmd

    def boom(args):
        raise ModuleNotFoundError("No module named 'mujoco'", name="mujoco")
    monkeypatch.setattr(eval_cmd, "run", boom)
    rc, out, err = run("eval", beam_file(TAPER), "--gamma", "0.5,0.5", "--k", "1")
    assert rc == 2
    assert _one_error_line(err, "eval").endswith('pip install "prbdm[sim]"')

    def other(args):
        raise ModuleNotFoundError("No module named 'nonesuch'", name="nonesuch")
    monkeypatch.setattr(eval_cmd, "run", other)
    with pytest.raises(ModuleNotFoundError):    # a real bug is not dressed up as an extra
        run("eval", beam_file(TAPER), "--gamma", "0.5,0.5", "--k", "1")


def test_extras_table_matches_pyproject_and_the_readme_installs_them_all():
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    extras = meta["optional-dependencies"]
    for module, extra in _common.EXTRAS.items():
        package = {"distributed": "dask"}.get(module, module)
        assert any(req.startswith(package) for req in extras[extra]), (module, extra)
    # the README's first command installs every extra the three jobs (train, predict, compare)
    # and the dataset/plot/export commands need
    first = next(line for line in (ROOT / "README.md").read_text().splitlines()
                 if line.startswith("pip install"))
    m = re.search(r'\.\[([a-z,]+)\]', first)
    assert m, first
    asked = set(m.group(1).split(","))
    if "all" in asked:
        asked |= set(re.search(r"\[(.*)\]", extras["all"][0]).group(1).split(","))
    assert set(_common.EXTRAS.values()) <= asked
    assert any(d.startswith("tqdm") for d in meta["dependencies"])   # the progress bars
