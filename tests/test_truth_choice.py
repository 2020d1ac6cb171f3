"""--truth auto: the rule against the recorded measurements and against live solves."""
import json
from pathlib import Path

import numpy as np

from prbdm.geometry import Beam, random_beam
from prbdm.truth import bending_frequencies
from prbdm.truth.choice import AUTO_BEAM_MAX_WIDTH, AUTO_TOLERANCE, choose_truth, width_ratio

MEASURED = Path(__file__).resolve().parents[1] / "docs" / "truth-choice.json"


def test_threshold_is_what_the_measurements_support():
    rows = json.loads(MEASURED.read_text())["rows"]
    wr = np.array([r["width_ratio"] for r in rows])
    worst = np.array([max(r["diff"]) for r in rows])
    inside = wr <= AUTO_BEAM_MAX_WIDTH
    assert inside.sum() >= 50
    assert np.percentile(worst[inside], 95) <= AUTO_TOLERANCE
    # and the next-wider band would break the tolerance: the threshold is not needlessly low
    wider = wr <= 1.4 * AUTO_BEAM_MAX_WIDTH
    assert np.percentile(worst[wider], 95) > AUTO_TOLERANCE


def test_a_2cm_strip_is_a_beam_and_a_wide_panel_a_plate():
    strip = Beam(x=[0, 1], half_width=[0.01, 0.01], thickness=0.005)
    truth, why = choose_truth(strip)
    assert truth == "beam" and "0.02 L" in why
    thin = Beam(x=[0, 0.5, 1], half_width=[0.3, 0.25, 0.2], thickness=0.005)
    truth, why = choose_truth(thin)
    assert truth == "plate" and f"{width_ratio(thin):.3g} L" in why
    # the paper's panels are thick and necked: the shear-deformable plate
    wide = random_beam(1, 0, min_half_width=0.01)
    truth, why = choose_truth(wide)
    assert truth == "mindlin" and f"{width_ratio(wide):.3g} L" in why and "Mindlin" in why
    assert choose_truth(wide, "beam") == ("beam", "--truth beam as asked")
    assert choose_truth(wide, "plate") == ("plate", "--truth plate as asked")


def test_live_differences_agree_with_the_choice():
    strip = Beam(x=[0, 0.5, 1], half_width=[0.012, 0.01, 0.006], thickness=0.004)
    b = bending_frequencies(strip, "beam", 4).omega
    p = bending_frequencies(strip, "plate", 4).omega
    assert np.abs(b / p - 1).max() < AUTO_TOLERANCE
    wide = random_beam(1, 0, min_half_width=0.01)
    b = bending_frequencies(wide, "beam", 4).omega
    p = bending_frequencies(wide, "plate", 4).omega
    assert np.abs(b / p - 1).max() > AUTO_TOLERANCE


def test_a_panel_the_plate_cannot_take_is_a_beam_with_the_reason():
    """Wider than 0.05 L but thicker than half its width (thin-plate theory fails; a bar): `auto`
    once chose the plate and then refused the panel (exit 2) that `--truth beam` solves."""
    bar = Beam(x=[0, 1], half_width=[0.04, 0.03], thickness=0.045)
    truth, why = choose_truth(bar)
    assert truth == "beam" and "thin-plate theory" in why and "0.5 x its full width" in why
    # a plate refusal for another reason (a width varying too much for its mesh) stands
    jagged = Beam(x=[0, 0.5, 1], half_width=[0.4, 2e-5, 0.4], thickness=0.01)
    assert choose_truth(jagged)[0] == "mindlin"          # the plate's mesh and limits
    # a panel neither truth accepts keeps the plate (whose refusal names the limit)
    wide_thick = Beam(x=[0, 1], half_width=[0.2, 0.2], thickness=0.25)
    assert choose_truth(wide_thick)[0] == "plate"


MINDLIN_VS_PLATE = Path(__file__).resolve().parents[1] / "docs" / "mindlin-vs-plate.json"


def test_shear_caveat_rule_against_the_recorded_kirchhoff_mindlin_differences():
    """On the recorded random panels (docs/mindlin-vs-plate.json), which differ from Mindlin by
    1-6 % median, the plate caveat flags (nearly) all, and the flagged differ by more than 2 %
    median."""
    from prbdm.truth.choice import shear_caveat
    rows = json.loads(MINDLIN_VS_PLATE.read_text())["rows"]
    flagged, spared = [], []
    for r in rows:
        b = random_beam(7, r["index"], min_half_width=0.01)
        assert abs(b.thickness / b.length - r["t_over_L"]) < 1e-12
        worst = np.max(np.abs(np.array(r["plate"]) / np.array(r["mindlin"]) - 1))
        (flagged if shear_caveat(b, "plate") else spared).append(worst)
    assert len(flagged) >= 60 and np.median(flagged) > 0.02 and len(spared) <= len(rows) // 10


def test_shear_caveat_spares_thin_smooth_panels_and_uniform_strips_and_flags_necks():
    from prbdm.truth.choice import shear_caveat
    thin_square = Beam(x=[0, 1], half_width=[0.5, 0.5], thickness=0.005)
    strip = Beam(x=[0, 1], half_width=[0.02, 0.02], thickness=0.01)     # 4 t wide, no neck
    assert shear_caveat(thin_square, "plate") is None and shear_caveat(strip, "plate") is None
    # a thin panel with a wide neck: measured 0.4-1.3 % (docs/howto/choose-a-truth.md), spared
    wide_neck = Beam(x=[0, 0.4, 0.5, 0.6, 1], half_width=[0.4, 0.4, 0.1, 0.4, 0.4],
                     thickness=0.005)
    assert shear_caveat(wide_neck, "plate") is None
    assert shear_caveat(Beam(x=wide_neck.x, half_width=wide_neck.half_width, thickness=0.01),
                        "plate")
    thick = Beam(x=[0, 1], half_width=[0.5, 0.5], thickness=0.03)
    necked = Beam(x=[0, 0.4, 0.5, 0.6, 1], half_width=[0.4, 0.4, 0.02, 0.4, 0.4],
                  thickness=0.006)                                       # a neck 6.7 t wide
    for b in (thick, necked):
        text = shear_caveat(b, "plate")
        assert text and "mindlin" in text and "docs/howto/choose-a-truth.md" in text
    assert shear_caveat(thick, "mindlin") is None
    # the beam: from t/L where its mode 4 is ~1 % high on a smooth panel
    assert shear_caveat(Beam(x=[0, 1], half_width=[0.02, 0.02], thickness=0.01), "beam") is None
    assert "high" in shear_caveat(Beam(x=[0, 1], half_width=[0.02, 0.02], thickness=0.03), "beam")


def test_shear_caveat_reaches_the_commands(tmp_path):
    import subprocess
    import sys
    path = tmp_path / "thick.json"
    path.write_text(json.dumps({"x": [0, 1], "half_width": [0.5, 0.5], "thickness": 0.03}))
    proc = subprocess.run([sys.executable, "-m", "prbdm.cli", "truth", str(path), "--model",
                           "plate", "--json"], capture_output=True, text=True)
    assert proc.returncode == 0
    assert "leaves out transverse shear" in json.loads(proc.stdout)["warnings"][0]
    assert "prbdm truth: warning: the Kirchhoff plate leaves out" in proc.stderr


def test_a_mindlin_panel_without_a_plate_network_names_the_shear_deformable_plate():
    """predict's reason and warning when `auto` wants Mindlin and only the beam network is
    there: the faithful truth named, and the remedy with --truth mindlin."""
    from types import SimpleNamespace

    from prbdm.surrogate.selection import truth_reason
    wide = random_beam(1, 0, min_half_width=0.01)
    choice = choose_truth(wide)
    assert choice[0] == "mindlin"
    sur = SimpleNamespace(name="beam-n4.safetensors", truth="beam", joints=4)
    reason, warning = truth_reason(wide, sur, None, choice)
    assert "Mindlin" in reason and "no mindlin or plate network for 4 joints" in warning
    assert "shear-deformable (mindlin) plate" in warning and "--truth mindlin" in warning
