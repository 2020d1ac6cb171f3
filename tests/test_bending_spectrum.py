"""The bending spectrum (SPEC §2.1, prbdm.truth.modes.bending_spectrum): its definition on
hand-made spectra, equality with the section rule where the modes are clean, the composition
reported, the refusal of a panel without enough bending weight, and continuity where the section
rule jumps."""
import json
import math

import numpy as np
import pytest

from prbdm.errors import BadInput
from prbdm.geometry import Beam, random_beam
from prbdm.truth import bending_frequencies
from prbdm.truth.modes import bending_spectrum, bending_weight


def test_the_weight_ramps_from_0_2_to_0_8():
    s = np.array([0.0, 0.2, 0.35, 0.5, 0.65, 0.8, 1.0])
    np.testing.assert_allclose(bending_weight(s), [0, 0, 0.25, 0.5, 0.75, 1, 1], atol=1e-15)


def test_the_spectrum_by_hand():
    """Clean modes are kept as they are; a bending unit split over two modes is their weighted
    geometric mean; a chordwise mode (s <= 0.2) takes no part."""
    lam = np.array([1.0, 10.0, 20.0, 40.0, 80.0, 160.0])
    frac = np.array([1.0, 0.95, 0.1, 0.5, 0.5, 0.9])        # weights 1, 1, 0, 0.5, 0.5, 1
    out, comp, length = bending_spectrum(lam, frac, 4)
    assert length == pytest.approx(4.0)
    np.testing.assert_allclose(out[:3], [1.0, 10.0, math.sqrt(40 * 80)], rtol=1e-14)
    assert comp[2] == [(3, 0.5), (4, 0.5)]
    # the line is exactly 4 long: unit 4 is mode 6 alone, but a caller needs it longer than 4
    # (a mode not computed could still belong to it) and refuses
    assert out[3] == 160.0
    out, comp, length = bending_spectrum(lam[:5], frac[:5], 4)
    assert length == pytest.approx(3.0) and math.isnan(out[3])


def test_every_unit_is_made_of_exactly_one_unit_of_weight():
    rng = np.random.default_rng(0)
    lam = np.sort(rng.uniform(1, 1e4, 30))
    frac = rng.uniform(0, 1, 30)
    out, comp, length = bending_spectrum(lam, frac, int(length_of(frac)) - 1)
    for j, parts in enumerate(comp):
        assert sum(w for _, w in parts) == pytest.approx(1.0, abs=1e-12)
        lo, hi = lam[parts[0][0]], lam[parts[-1][0]]
        assert lo <= out[j] <= hi                            # a mean of its modes
    assert np.all(np.diff(out) >= 0)                        # ascending


def length_of(frac):
    return bending_weight(frac).sum()


def test_a_slender_panel_gets_the_section_rules_modes_exactly():
    beam = Beam(x=np.array([0.0, 1.0]), half_width=np.array([0.05, 0.03]), thickness=0.01)
    spec = bending_frequencies(beam, "plate", modes=4)
    rule = bending_frequencies(beam, "plate", modes=4, selection="section")
    np.testing.assert_array_equal(spec.omega, rule.omega)
    assert all(len(b["composition"]) == 1 and b["composition"][0]["weight"] == 1.0
               for b in spec.bending)


def test_the_truth_command_shows_each_bending_modes_composition(run, beam_file):
    path = beam_file({"x": [0.0, 0.13, 0.31, 0.52, 0.7, 1.0],
                      "half_width": [0.42, 0.15, 0.38, 0.09, 0.33, 0.2], "thickness": 0.02})
    rc, out, err = run("truth", path, "--model", "mindlin", "--modes", 4, "--json")
    assert rc == 0, err
    d = json.loads(out)
    assert [b["mode"] for b in d["bending_modes"]] == [1, 2, 3, 4]
    assert [b["omega"] for b in d["bending_modes"]] == d["omega"]
    for b in d["bending_modes"]:
        w = [c["weight"] for c in b["composition"]]
        assert sum(w) == pytest.approx(1.0) and all(0 < v <= 1 for v in w)
    assert len(d["section_rule"]["omega"]) == 4
    # this panel's mode 4 is a blend of three physical modes; the section rule keeps one
    assert len(d["bending_modes"][3]["composition"]) > 1


def test_a_panel_without_enough_bending_weight_is_refused(monkeypatch):
    import prbdm.truth.plate as plate

    monkeypatch.setattr(plate, "MAX_MODES_COMPUTED", 12)
    beam = random_beam(0, 0)
    with pytest.raises(BadInput, match="bending weight") as exc:
        bending_frequencies(beam, "plate", modes=10)
    assert "at most" in str(exc.value)


@pytest.mark.parametrize("index", [10, 13])
def test_the_spectrum_moves_little_where_the_section_rule_jumps(index):
    """A 1 % tilt of the half-widths of a paper panel (random_beam(7, 10), (7, 13), Kirchhoff
    plate) moves the section rule's mode 4 by 28 % and 70 % between neighbouring steps (it jumps
    to another physical mode); the spectrum's by under 0.2 %."""
    base = random_beam(7, index)
    rule, spec = [], []
    for f in np.linspace(0.99, 1.01, 5):
        w = base.half_width * f ** np.linspace(-1, 1, len(base.half_width))
        b = Beam(x=base.x, half_width=w, thickness=base.thickness)
        rule.append(bending_frequencies(b, "plate", modes=4, selection="section").omega[3])
        spec.append(bending_frequencies(b, "plate", modes=4).omega[3])
    assert np.abs(np.diff(np.log(rule))).max() > 0.2         # the jump the spectrum removes
    assert np.abs(np.diff(np.log(spec))).max() < 0.005
