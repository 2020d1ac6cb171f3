"""Every script in examples/ runs to the end (a fresh interpreter, exit 0), and the numbers it
prints are sane: checked against the accuracy the docs state, not against an earlier run."""
from __future__ import annotations

import importlib.util
import re
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
SCRIPTS = sorted(EXAMPLES.glob("*.py"))
NUMBER = r"[-+]?\d+(?:\.\d*)?(?:e[-+]?\d+)?"


def args_for(script: Path, tmp_path: Path) -> list[str]:
    # the design study runs at full size (about 5 s): the test checks what docs/design-study.md shows
    return {"design_study_taper.py": ["--out", str(tmp_path)]}.get(script.name, [])


def numbers(line: str) -> list[float]:
    return [float(v) for v in re.findall(NUMBER, line)]


def line_with(out: str, start: str) -> str:
    found = [ln for ln in out.splitlines() if ln.startswith(start)]
    assert found, f"no line starting {start!r} in:\n{out}"
    return found[0]


def table_row(out: str, label: str, stat: str) -> list[float]:
    """The numbers of the error table's row ``label`` / ``stat`` (median or max): modes 1-4 and,
    for the PRBDMs, the loss."""
    lines = out.splitlines()
    i = next(i for i, ln in enumerate(lines) if ln.startswith(label))
    row = lines[i] if stat == "median" else lines[i + 1]
    assert row.split()[len(label.split()) if stat == "median" else 0] == stat, row
    return numbers(row[len(label):])


@pytest.mark.parametrize("script", SCRIPTS, ids=[s.name for s in SCRIPTS])
def test_example_runs(script, tmp_path):
    r = subprocess.run([sys.executable, str(script), *args_for(script, tmp_path)],
                       capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "Traceback" not in r.stderr
    check = CHECKS.get(script.name)
    if check:
        check(r.stdout, tmp_path)


def check_design_study(out: str, folder: Path):
    assert "0 of 200 designs outside the training range (0 warning(s))" in out
    # where the network's choice among its candidate segmentations flips, gamma jumps; the
    # switch count is reported, not bounded (a property of the checkpoint, not a bug)
    line_with(out, "the network's segmentation switches")

    # shape invariance: twice the thickness, same gamma and k, twice the frequencies
    dg, dk, r_min, r_max = numbers(line_with(out, "same panels at 40 mm").split(":", 1)[1])
    assert dg < 1e-6 and dk < 1e-6 and abs(r_min - 2) < 1e-8 and abs(r_max - 2) < 1e-8

    # docs/surrogate.md: direct frequency prediction, median 0.07-0.35 % per mode on held-out
    # random beams, p95 0.4-1.6 %; a smooth taper family is easier than random beams
    direct = "network, direct frequencies"
    assert len(table_row(out, direct, "median")) == 4
    assert max(table_row(out, direct, "median")) < 0.5
    assert max(table_row(out, direct, "max")) < 1.5
    # the PRBDMs follow the paper's loss, which the highest mapped mode dominates: mode 4 and the
    # loss are tight, mode 1 is not (20-25 % here, docs/fit.md §3), so only mode 4 is bounded
    net_med, net_max = (table_row(out, "network PRBDM, pose 0", s) for s in ("median", "max"))
    assert net_med[3] < 1.0 and net_med[4] < 2.0 and net_max[4] < 3.2   # held-out median, p95
    fit_max = table_row(out, "optimised fit PRBDM, pose 0", "max")
    assert fit_max[4] < 0.5                  # docs/fit.md §3: max 0.36 % over random beams

    t_net = numbers(line_with(out, "  network (batch of 200)").split(")", 1)[1])[0]
    t_fem = numbers(line_with(out, "  beam FEM  "))[0]
    t_fit = numbers(line_with(out, "  beam FEM + fit"))[0]
    assert 0 < t_net < t_fem < t_fit

    # the chosen design: the network's first frequency against the FEM, and the target
    chosen = line_with(out, "first frequency nearest 20 Hz")
    f_net, f_fem, rel = numbers(chosen.split("network", 1)[1])
    assert abs(rel) < 0.5 and abs(f_net / f_fem - 1) < 5e-3
    assert abs(f_fem / 20 - 1) < 0.01
    assert (folder / "design_study_taper.xml").is_file()
    assert (folder / "design_study_taper.png").stat().st_size > 10_000
    # the exported model is the small-vibration (theta = 0) PRBDM: its first frequency is the
    # network's, hence within 1 % of the FEM (issue 8: fit for small vibration, not 15 % high)
    lin = line_with(out, "small-vibration PRBDM")
    f_lin = numbers(lin.split("; f1", 1)[1])[0]
    assert abs(f_lin / f_fem - 1) < 0.01
    if importlib.util.find_spec("mujoco") is not None:
        mj = line_with(out, "MuJoCo, linearised at rest")
        f1_mj = numbers(mj.split("f1", 1)[1])[0]
        diff, f_fem_mj = numbers(mj.split("difference", 1)[1])[:2]
        assert abs(diff) < 1e-6 and f_fem_mj == f_fem
        assert abs(f1_mj / f_fem - 1) < 0.01, f"MuJoCo f1 {f1_mj} Hz vs FEM {f_fem} Hz"


CHECKS = {"design_study_taper.py": check_design_study}


def test_every_example_is_checked():
    assert SCRIPTS, "no examples found"
    missing = [s.name for s in SCRIPTS if s.name not in CHECKS]
    assert not missing, f"examples without checks of their output: {missing}"
