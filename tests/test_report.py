"""``prbdm report``: a tiny run (--quick, 2 beams) end to end, bad flags, the stability hook,
held-out beam selection, and no half-written files on failure."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from prbdm import cli
from prbdm import report as rp
from prbdm import surrogate as sg
from prbdm.geometry import random_beam

PNGS = ["error_vs_time.png", "fit_time_vs_n.png", "fit_time_vs_starts.png",
        "truth_time_vs_mesh.png", "network_throughput.png"]
LABELS = ["plate truth", "beam truth", "RFE chain", "Howell 1R", "Su 3R", "fit, 8 starts",
          "fit, 16 starts", "fit to plate truth", "| network |", "network + refined",
          "network (direct frequencies)", "Mindlin plate truth", "fit to Mindlin truth",
          "plate network (plate-n4", "Mindlin network (mindlin-n4", "Mindlin network + refined"]


@pytest.fixture(autouse=True)
def _command(monkeypatch):
    monkeypatch.setitem(cli.COMMANDS, "report",
                        cli.COMMANDS.get("report", ("prbdm.commands.report", "report")))


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    out = tmp_path_factory.mktemp("report")
    argv = ["report", "--quick", "--beams", "2", "--starts", "8,16", "--out", str(out),
            "--no-stability"]
    with pytest.MonkeyPatch.context() as mp:
        mp.setitem(cli.COMMANDS, "report", ("prbdm.commands.report", "report"))
        assert cli.main(argv) == 0
    return out, json.loads((out / "report.json").read_text())


def test_files_written(tiny):
    out, _ = tiny
    for name in PNGS:
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name
    md = (out / "report.md").read_text()
    for name in PNGS:
        assert f"({name})" in md
    assert "prbdm report --beams 2" in md and "--quick" in md
    assert not [p for p in out.iterdir() if p.name.startswith(".")]      # no temporaries


def test_every_method_in_both_tables(tiny):
    out, res = tiny
    md = (out / "report.md").read_text()
    plate, rest = md.split("## Against the Mindlin plate truth")
    mindlin, beam = rest.split("## Against the beam truth")
    for label in LABELS:
        assert label in plate and label in mindlin and label in beam, label
    for table in (plate.split("| method |")[1], mindlin, beam):
        assert table.count("(reference)") == 1


def test_numbers_finite_and_fit_beats_rfe(tiny):
    _, res = tiny
    by_key = {m["key"]: m for m in res["methods"]}
    for m in res["methods"]:
        assert math.isfinite(m["time_s"]) and m["time_s"] > 0, m["key"]
        for ref in ("plate", "mindlin", "beam"):
            e = m["errors"][ref]
            if e.get("reference"):
                continue
            for key in ("loss_median", "loss_p95", "worst_median", "worst_p95"):
                assert math.isfinite(e[key]) and e[key] >= 0, (m["key"], ref, key)
    # the rigid-finite-element chain (no fit) is worse than the optimised fit of the same n
    for S in (8, 16):
        assert (by_key["rfe"]["errors"]["beam"]["loss_median"]
                > 10 * by_key[f"fit_{S}"]["errors"]["beam"]["loss_median"])
    # the classical models compare only the modes they have
    assert by_key["howell-1r"]["errors"]["beam"]["modes"] == 1
    assert by_key["su-3r"]["errors"]["beam"]["modes"] == 3
    assert by_key["fit_plate"]["errors"]["plate"]["loss_median"] < \
        by_key["fit_8"]["errors"]["plate"]["loss_median"]
    # each panel fit is the closest to its own truth; refining the Mindlin network helps
    assert by_key["fit_mindlin"]["errors"]["mindlin"]["loss_median"] < \
        by_key["fit_plate"]["errors"]["mindlin"]["loss_median"]
    assert by_key["fit_plate"]["errors"]["plate"]["loss_median"] < \
        by_key["fit_mindlin"]["errors"]["plate"]["loss_median"]
    assert by_key["mindlin_refined"]["errors"]["mindlin"]["loss_median"] < \
        by_key["mindlin_network"]["errors"]["mindlin"]["loss_median"]
    sc = res["scaling"]
    assert [r["n"] for r in sc["fit_vs_n"]["rows"]] == [3, 4, 6]
    assert all(r["beams_per_s"] > 0 for r in sc["network_throughput"]["rows"])
    assert {r["model"] for r in sc["truth_vs_mesh"]["rows"]} == {"beam", "plate"}
    assert res["source"]["seed"] == 1 and res["config"]["fit_seed"] == 0


def test_config_records_the_start_counts_run(tiny):
    """config.starts is the fit start counts compared (--starts 8,16), not the refinement's
    start points (it used to be overwritten by them)."""
    _, res = tiny
    assert res["config"]["starts"] == [8, 16]
    assert [m["key"] for m in res["methods"] if m["key"].startswith("fit_")
            and m["key"] not in ("fit_plate", "fit_mindlin")] == ["fit_8", "fit_16"]


def _run(argv, capsys):
    try:
        code = cli.main(argv)
    except SystemExit as exc:
        code = exc.code
    return code, capsys.readouterr().err


@pytest.mark.parametrize("argv, field", [
    (["--beams", "1"], "--beams"),
    (["--beams", "many"], "--beams"),
    (["--seed", "-1"], "--seed"),
    (["--seed", "0"], "--seed"),          # the checkpoint's training seed
    (["--starts", "0,8"], "--starts"),
    (["--data", "/nonexistent/prbdm-data"], "--data"),
    (["--bogus"], "--bogus"),
])
def test_bad_flags_exit_2_one_line(argv, field, capsys, tmp_path):
    code, err = _run(["report", "--quick", "--out", str(tmp_path / "o"), *argv], capsys)
    assert code == 2
    assert len(err.strip().splitlines()) == 1 and field in err and "Traceback" not in err
    assert not (tmp_path / "o").exists()


def test_failure_leaves_no_files(tiny, tmp_path, monkeypatch):
    _, res = tiny
    monkeypatch.setattr(rp, "run_report", lambda cfg: res)

    def boom(res):
        raise RuntimeError("plotting failed")
    monkeypatch.setattr(rp, "plot_scaling", boom)
    with pytest.raises(RuntimeError):
        rp.write_report(rp.ReportConfig(stability=False), tmp_path / "out")
    assert not (tmp_path / "out").exists() or not list((tmp_path / "out").iterdir())


def test_stability_hook(monkeypatch):
    # the suite's writer is part of the library (prbdm.report.stability); the hook calls it
    import inspect

    from prbdm.report import stability

    assert list(inspect.signature(stability.section).parameters) == ["quick"]
    monkeypatch.setattr(stability, "section", lambda quick: f"STABILITY quick={quick}")
    md, note = rp.stability_section(rp.ReportConfig(quick=True))
    assert md == "STABILITY quick=True" and note == ""
    md, note = rp.stability_section(rp.ReportConfig(stability=False))
    assert md is None and "--no-stability" in note

    def bad(quick):
        raise ValueError("bad case")
    monkeypatch.setattr(stability, "section", bad)
    md, note = rp.stability_section(rp.ReportConfig())
    assert md is None and "ValueError" in note


def test_held_out_from_data_set(tmp_path):
    from prbdm import dataset as ds

    sur = sg.load_checkpoint(sg.default_checkpoint(4, "beam"))
    seed = sur.metadata["dataset"]["spec"]["seed"]
    # the checkpoint's own stream: only its test-split indices (index % 10 == 9) are held out
    out = tmp_path / "same"
    ds.generate(out, 11, ds.make_spec(joints=4, starts=1, seed=seed), workers=0, progress="none")
    beams, src = rp.held_out_beams(rp.ReportConfig(data=str(out), beams=5), sur)
    assert src["indices"] == [9]
    np.testing.assert_array_equal(beams[0].half_width, random_beam(seed, 9).half_width)
    # another stream: every beam is held out
    out = tmp_path / "other"
    ds.generate(out, 3, ds.make_spec(joints=4, starts=1, seed=seed + 7), workers=0,
                progress="none")
    beams, src = rp.held_out_beams(rp.ReportConfig(data=str(out), beams=2), sur)
    assert src["indices"] == [0, 1]


def test_report_objective_frequency(tmp_path):
    """`prbdm report --objective frequency`: the fits minimise it, the network measured is the
    default one for it (beam-n4, trained at rest on the frequency objective, answers either;
    before, the paper-pose beam-n4-frequency), and both are recorded (issue 18 item 1)."""
    argv = ["report", "--quick", "--beams", "2", "--starts", "8", "--out", str(tmp_path),
            "--no-stability", "--objective", "frequency"]
    with pytest.MonkeyPatch.context() as mp:
        mp.setitem(cli.COMMANDS, "report", ("prbdm.commands.report", "report"))
        assert cli.main(argv) == 0
    res = json.loads((tmp_path / "report.json").read_text())
    assert res["config"]["objective"] == "frequency"
    assert "--objective frequency" in res["config"]["command"]
    from prbdm.surrogate import default_checkpoint

    assert res["checkpoint"]["name"] == default_checkpoint(4, "beam", "frequency").name
