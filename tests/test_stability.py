"""Stability on stiff and extreme cases (issue 7): every case of the suite as a pytest case, plus
the library fixes the suite led to (each checked directly, so a revert fails here).

The cases (prbdm/report/stability_cases.py) compare against independent references (analytic
cantilever, shooting ODE solution, exact scaling laws, a hand-written 2R model, finite
differences, float64); the harness is prbdm/report/stability_checks.py. The quick cases run by default
(~15 s); the rest (plate truth, every n, every corner) under ``-m slow``, a known failure as an
xfail with its reason. The table of docs/stability.md is ``python benchmarks/stability.py
--details`` (a thin script over :mod:`prbdm.report.stability`).
"""
import math
import warnings

import numpy as np
import pytest

from prbdm.errors import BadInput
from prbdm.geometry import MAX_PRBDM_WIDTH_RATIO, Beam
from prbdm.report import stability as writer
from prbdm.report import stability_cases
from prbdm.report.stability_checks import Case, run_case

QUICK = [c for c in stability_cases.CASES if c.quick]
SLOW = [pytest.param(c, id=c.name, marks=[pytest.mark.xfail(reason=c.known_failure, strict=True)]
                     if c.known_failure else [])
        for c in stability_cases.CASES if not c.quick]


def _assert_row(row):
    assert row["n_checks"] > 0
    assert row["passed"], (f"{row['name']}: failed {row['failed']}; "
                           + "; ".join(f"{c['check']} = {c['value']} (tol {c['tol']})"
                                       for c in row["checks"] if not c["passed"])
                           + f"; note: {row['note']}")
    assert row["grad_finite"] in (True, None)
    for key in ("cond_M", "cond_K", "cond_A"):
        assert row[key] is None or (math.isfinite(row[key]) and row[key] >= 1 - 1e-9)


@pytest.mark.parametrize("case", QUICK, ids=[c.name for c in QUICK])
def test_quick_case(case):
    assert not case.known_failure, "a known failure belongs to the slow cases, as an xfail"
    _assert_row(run_case(case))


@pytest.mark.slow
@pytest.mark.parametrize("case", SLOW)
def test_slow_case(case):
    _assert_row(run_case(case))


# ----------------------------------------------------------------------------- the harness
def test_a_failing_check_fails_the_row_and_an_exception_is_caught():
    def bad(row):
        row.check("2 <= 1", 2.0, 1.0)
        row.check("fine", 0.5, 1.0)

    def boom(row):
        raise RuntimeError("kaboom")

    r = run_case(Case("bad", "nothing", bad, {}))
    assert not r["passed"] and r["failed"] == ["2 <= 1"]
    assert r["accuracy"] == 2.0 and r["tolerance"] == 1.0
    r = run_case(Case("boom", "nothing", boom, {}))
    assert not r["passed"] and "kaboom" in r["note"]
    # a NaN never passes a tolerance
    r = run_case(Case("nan", "nothing", lambda row: row.check("nan", float("nan"), 1.0), {}))
    assert not r["passed"]


def test_markdown_section():
    rows = [run_case(c) for c in QUICK if c.name in ("n = 4", "bad input")]
    rows.append(run_case(Case("broken", "nothing", lambda row: row.check("x", 3.0, 1.0), {})))
    rows.append(run_case(Case("known", "nothing", lambda row: row.check("y", 3.0, 1.0), {},
                              known_failure="y is too big")))
    md = writer.format_markdown(rows)
    assert md.startswith("## Stability on stiff and extreme cases")
    assert "2 of 4 cases pass" in md
    lines = [ln for ln in md.splitlines() if ln.startswith("| ")]
    assert len(lines) == 1 + len(rows)                       # header + one row per case
    assert "| n = 4 |" in md and "**0/1**" in md and "- broken: x" in md
    assert "- known: y" in md and md.count("*Known failure*") == 1
    assert "K^-1/2 M K^-1/2" in md and "eigvalsh" in md
    table = writer.details(rows[-2:]).splitlines()
    assert table[2] == "| broken | x | 3 | 1 | **NO** |" and len(table) == 4


def test_run_suite_interface():
    keys = {"name", "varied", "passed", "failed", "checks", "accuracy", "tolerance", "cond_M",
            "cond_K", "cond_A", "grad_finite", "time_s", "known_failure"}
    assert keys <= set(run_case(QUICK[0]))
    names = [c.name for c in stability_cases.CASES]
    assert len(set(names)) == len(names)
    # the known failure stays reported (docs/stability.md, Limitations), not dropped
    assert [c.name for c in stability_cases.CASES if c.known_failure] == [
        "fit from all gamma corners"]


# ----------------------------------------------------------------------------- library fixes
def test_fit_started_on_a_corner_leaves_the_bounds():
    """init_gamma on the bounds used to keep z_j = 0, a zero gradient: the fit stopped after 4
    iterations with gamma unchanged (19 % loss here, best 0.10 %)."""
    from prbdm.fit import fit_prbdm
    from prbdm.geometry import random_beam
    from prbdm.truth import bending_frequencies
    beam = random_beam(0, 3)
    truth = bending_frequencies(beam, "beam", 5).omega
    g0 = [0.025, 0.025, 0.025, 0.025, 0.9]
    f = fit_prbdm(beam, truth, 4, init_gamma=[g0])
    assert np.abs(f.gamma - g0).max() > 0.1
    assert f.loss_percent < 1.0


def test_prbdm_refuses_extreme_width_ratio():
    from prbdm import model, surrogate
    beam = Beam(x=[0, 1], half_width=[0.1, 1e-18], thickness=0.02)
    with pytest.raises(BadInput, match="half_width"):
        model.eigenvalues(beam, model.uniform_gamma(4))
    with pytest.raises(BadInput, match="half_width"):
        surrogate.predict([beam], joints=4)
    ok = Beam(x=[0, 1], half_width=[0.1, 0.2 / MAX_PRBDM_WIDTH_RATIO], thickness=0.02)
    lam = model.eigenvalues(ok, model.uniform_gamma(4)).numpy()
    assert np.isfinite(lam).all() and (lam > 0).all()


def test_cli_eval_extreme_width_is_exit_2(capsys, tmp_path):
    from prbdm.cli import main
    path = tmp_path / "needle.json"
    Beam(x=[0, 1], half_width=[0.1, 1e-30], thickness=0.02).to_json(path)
    rc = main(["eval", str(path), "--gamma", "0.2,0.2,0.2,0.2,0.2", "--k", "1"])
    out, err = capsys.readouterr()
    assert rc == 2 and out == ""
    assert err.count("\n") == 1 and "half_width" in err and "Traceback" not in err


def test_plate_refuses_a_needle_it_cannot_solve():
    """At 1e5:1 the plate FEM returned a first frequency 3.5x the beam's; now a clear error."""
    from prbdm.truth import bending_frequencies
    with pytest.raises(BadInput, match="half_width.*plate"):
        bending_frequencies(Beam(x=[0, 1], half_width=[0.1, 1e-6], thickness=0.02), "plate")


def test_network_ood_warning_names_the_feature():
    from prbdm import surrogate
    # a 1e4:1 step over 1 % of the span: outside the training range (a 100:1 step is not, since
    # the 80,000-beam checkpoint)
    step = Beam(x=[0, 0.5, 0.51, 1], half_width=[0.2, 0.2, 2e-5, 2e-5], thickness=0.02)
    with pytest.warns(surrogate.OutOfDistributionWarning, match=r"log_(h)?mean\[\d+\]"):
        surrogate.predict([step], joints=4)
    with warnings.catch_warnings():
        warnings.simplefilter("error", surrogate.OutOfDistributionWarning)
        from prbdm.geometry import random_beam
        surrogate.predict([random_beam(0, 100000)], joints=4)


def test_float32_precision_warning():
    """float32 eigenvalues used to come back 2.6 % off (n = 4) or not even positive (n = 39)
    without a word: now a PrecisionWarning naming the dtype, the condition estimate and float64.
    Autograd and batching are untouched; float64 and well-conditioned float32 stay silent."""
    import torch

    from prbdm import model
    from prbdm.geometry import random_beam
    beams = [random_beam(7, i) for i in range(3)]
    bt32 = model.BeamTensors.from_beams(beams, dtype=torch.float32)
    g = model.uniform_gamma(8, dtype=torch.float32).expand(3, -1).clone().requires_grad_(True)
    with pytest.warns(model.PrecisionWarning, match=r"float32.*lam_max / lam_min = .*float64"):
        lam = model.eigenvalues(bt32, g)
    assert lam.shape == (3, model.paper_poses(8).shape[0], 8)
    (grad,) = torch.autograd.grad(lam[..., 0].sum(), g)
    assert torch.isfinite(grad).all()
    with warnings.catch_warnings():
        warnings.simplefilter("error", model.PrecisionWarning)
        model.eigenvalues(model.BeamTensors.from_beams(beams), g.detach().double())
        model.eigenvalues(bt32, model.uniform_gamma(1, dtype=torch.float32).expand(3, -1))
    with pytest.warns(model.PrecisionWarning, match="float64.*not finite or not positive"):
        model._check_precision(torch.tensor([[-1.0, 2.0]], dtype=torch.float64))
