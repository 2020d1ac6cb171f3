"""Every script in examples/ runs to the end (a fresh interpreter, exit 0), and the numbers its
``main`` returns are sane: checked against the accuracy the docs state, not against an earlier
run, and through the values, not by reading its printed text."""
from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
SCRIPTS = sorted(EXAMPLES.glob("*.py"))


def load(script: Path):
    """The example as a module (its ``main`` not yet run)."""
    spec = importlib.util.spec_from_file_location(script.stem, script)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("script", SCRIPTS, ids=[s.name for s in SCRIPTS])
def test_example_runs_in_a_fresh_interpreter(script, tmp_path):
    quick = {"design_study_taper.py": ["--designs", "20", "--fits", "2", "--out", str(tmp_path)]}
    r = subprocess.run([sys.executable, str(script), *quick.get(script.name, [])],
                       capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "Traceback" not in r.stderr


def check_design_study(tmp_path):
    """The design study at full size (about 5 s), checked through the numbers ``main`` returns
    against what docs/howto/design-study.md, docs/validation.md and docs/howto/fit.md state."""
    res = load(EXAMPLES / "design_study_taper.py").main(["--out", str(tmp_path)])
    assert res["ood"] == 0 and res["warnings"] == 0
    # where the network's choice among its candidate segmentations flips, gamma jumps; the
    # switch count is reported, not bounded (a property of the checkpoint, not a bug)
    assert res["flips"] >= 0
    # shape invariance: twice the thickness, same gamma and k, twice the frequencies
    assert res["thick_gamma_change"] < 1e-6 and res["thick_k_change"] < 1e-6
    assert all(abs(v - 2) < 1e-8 for v in res["thick_ratio"])
    # docs/validation.md: direct frequency prediction, median 0.07-0.35 % per mode on held-out
    # random beams, p95 0.4-1.6 %; a smooth taper family is easier than random beams
    direct = res["err_direct"]
    assert direct.shape[1] == 4
    assert np.median(direct, axis=0).max() < 0.5 and direct.max() < 1.5
    # the PRBDMs follow the paper's loss, which the highest mapped mode dominates: mode 4 and the
    # loss are tight, mode 1 is not (20-25 % here, docs/howto/fit.md), so only mode 4 is bounded
    assert np.median(res["err_network"][:, 3]) < 1.0
    assert np.median(res["loss_network"]) < 2.0 and res["loss_network"].max() < 3.2
    assert res["loss_fit"].max() < 0.5           # docs/howto/fit.md: max 0.36 % over random beams
    cpu = res["cpu_s"]
    assert 0 < cpu["network"] < cpu["fem"] < cpu["fem_fit"]
    # the chosen design: the network's first frequency against the FEM, and the target
    c = res["chosen"]
    assert abs(c["f1_network"] / c["f1_fem"] - 1) < 5e-3 and abs(c["f1_fem"] / 20 - 1) < 0.01
    assert (tmp_path / "design_study_taper.xml").is_file()
    assert (tmp_path / "design_study_taper.png").stat().st_size > 10_000
    # the exported model is the small-vibration (theta = 0) PRBDM: its first frequency is the
    # network's, hence within 1 % of the FEM (issue 8: fit for small vibration, not 15 % high)
    assert abs(c["f1_exported"] / c["f1_fem"] - 1) < 0.01
    if importlib.util.find_spec("mujoco") is not None:
        assert abs(c["f1_mujoco"] / c["f1_exported"] - 1) < 1e-6
        assert abs(c["f1_mujoco"] / c["f1_fem"] - 1) < 0.01


CHECKS = {"design_study_taper.py": check_design_study}


@pytest.mark.parametrize("name", sorted(CHECKS))
def test_example_results(name, tmp_path):
    CHECKS[name](tmp_path)


def test_every_example_is_checked():
    assert SCRIPTS, "no examples found"
    missing = [s.name for s in SCRIPTS if s.name not in CHECKS]
    assert not missing, f"examples without checks of their output: {missing}"
