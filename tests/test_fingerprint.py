"""``prbdm.fingerprint``: a fit result knows its beam. The fingerprint is stable under what does not
change the panel (a JSON round trip, the name, -0.0, rounding beyond 12 digits), changes with every
field that does, and is carried by ``prbdm fit --json`` and ``prbdm predict --json``, whose output
``prbdm export --from`` accepts for the same beam (issue 19 item 3)."""
import json
import re

import pytest

from prbdm.fingerprint import FINGERPRINT_HEX, beam_fingerprint
from prbdm.geometry import Beam, Material

BEAM = Beam(x=[0.0, 0.35, 1.2], half_width=[0.18, 0.12, 0.05], thickness=0.02,
            material=Material(E=69e9, rho=2700.0, nu=0.33), name="tapered")


def changed(**kw):
    d = BEAM.to_dict()
    mat = {k: kw.pop(k) for k in ("E", "rho", "nu") if k in kw}
    d["material"] = {**d["material"], **mat}
    d.update(kw)
    return Beam.from_dict(d)


def test_format_and_what_does_not_change_it():
    fp = beam_fingerprint(BEAM)
    assert re.fullmatch(f"[0-9a-f]{{{FINGERPRINT_HEX}}}", fp)
    assert beam_fingerprint(Beam.from_dict(json.loads(BEAM.to_json()))) == fp
    assert beam_fingerprint(changed(name="renamed")) == fp
    assert beam_fingerprint(changed(x=[-0.0, 0.35, 1.2])) == fp
    # beyond 12 significant digits: a last-digit difference of another program's output
    assert beam_fingerprint(changed(thickness=0.02 * (1 + 1e-14))) == fp


@pytest.mark.parametrize("change", [
    {"x": [0.0, 0.36, 1.2]}, {"x": [0.0, 0.35, 1.21]}, {"half_width": [0.18, 0.12, 0.051]},
    {"thickness": 0.02 * (1 + 1e-9)}, {"E": 70e9}, {"rho": 2701.0}, {"nu": 0.3},
    {"x": [0.0, 0.2, 0.35, 1.2], "half_width": [0.18, 0.14, 0.12, 0.05]},
])
def test_every_field_of_the_panel_changes_it(change):
    assert beam_fingerprint(changed(**change)) != beam_fingerprint(BEAM)


def test_fit_and_predict_json_carry_it_and_export_accepts_them(run, tmp_path):
    beam = tmp_path / "beam.json"
    beam.write_text(BEAM.to_json())
    rc, out, err = run("fit", beam, "--joints", 2, "--starts", 4, "--json")
    assert rc == 0, err
    assert json.loads(out)["beam_fingerprint"] == beam_fingerprint(BEAM)
    rc, out, err = run("predict", beam, "--joints", 3, "--json")
    assert rc == 0, err
    pred = json.loads(out)
    assert pred["beam_fingerprint"] == beam_fingerprint(BEAM)
    (tmp_path / "pred.json").write_text(out)
    # a prediction of a network trained at rest (the shape target) is exported as it is, at
    # rest (gamma and its one SCF; a paper-pose prediction is refitted there), and checked
    # against the network's own predicted truth frequencies
    rc, out, err = run("export", beam, "--from", tmp_path / "pred.json", "-o",
                       tmp_path / "m.xml", "--json")
    assert rc == 0, err
    rep = json.loads(out)
    assert rep["beam_fingerprint"]["match"] is True
    if pred["pose_target"] == "shape":
        assert rep["refit"] is None and rep["pose"]["theta"] == [0.0] * 3
        assert rep["pose"]["k"] == pred["k"][0]
    else:
        assert rep["refit"]["truth"] == "omega_truth_predicted"
    assert rep["check"]["truth"] == "omega_truth_predicted"
    r = rep["check"]["modes"]
    assert r == 3 and rep["check"]["freq_hz_truth"] == pytest.approx(
        pred["freq_hz_truth_predicted"][:r], rel=1e-12)
