"""``prbdm simulate`` at large amplitude (issue 37 item 4): which truth a run is compared with,
the rod's release at a tip deflection (against the elastica's closed form), the chain's own
release under a tip force, the spring law a fit result was made with, and the constant-stiffness
rest fit against the geometrically exact rod at 0.2 L; bad input exits 2 with one line."""
import json
import math

import numpy as np
import pytest

from prbdm.errors import BadInput
from prbdm.export import prbdm_from_fit, run_fit
from prbdm.geometry import Beam
from prbdm.simulate import (
    SMALL_DEFLECTION,
    ChainDynamics,
    InitialCondition,
    ReferenceSettings,
    RunSettings,
    model_pose,
    prepare_reference,
    reference_kind,
    simulate,
)
from prbdm.springs import InterpolatedSprings, LinearSprings, fitted_springs

TAPERED = Beam(x=[0.0, 0.35, 1.2], half_width=[0.18, 0.12, 0.05], thickness=0.02,
               name="tapered")
UNIFORM = Beam(x=[0.0, 1.0], half_width=[0.1812, 0.1812], thickness=0.040532, name="uniform")
#: 4 elements of degree 3, 256 steps a period: at 0.2 L on TAPERED the rod's period is within
#: 2e-4 of the rod_response defaults' (docs/howto/export-and-simulate.md), in a second or two
CHEAP_ROD = ReferenceSettings(rod_elements=4, rod_degree=3, rod_steps=256)


@pytest.fixture(scope="module")
def linear_fit():
    """A 3R PRBDM fitted at rest (one SCF: constant stiffness at every angle)."""
    return run_fit(TAPERED, 3, poses="linear", starts=8, truth="beam")


def test_the_reference_rule():
    L = 1.2
    small = SMALL_DEFLECTION * L
    assert reference_kind("tip_deflection", small, 0.0, L) == ("modal", [])
    assert reference_kind("tip_deflection", -1.001 * small, 0.0, L) == ("rod", [])
    kind, warnings = reference_kind("tip_deflection", 0.2 * L, 0.05, L)
    assert kind == "modal" and "undamped" in warnings[0]
    assert reference_kind("tip_impulse", 100.0, 0.0, L) == ("modal", [])


def test_the_rod_released_at_a_tip_deflection_is_the_elastica():
    """Bisshopp and Drucker's closed form for a uniform strip under a perpendicular dead tip
    load P L^2 / EI = 1: tip z = 0.301721 L (6 digits), tip angle 0.461352 rad; asked for that
    deflection, the rod finds that load."""
    ref = prepare_reference(UNIFORM, InitialCondition(tip_deflection=0.301721 * UNIFORM.length))
    assert ref.kind == "rod"
    eq = ref.rod
    assert eq.tip_z == pytest.approx(0.301721, rel=1e-12)
    assert eq.load == pytest.approx(1.0, abs=5e-6)            # the table's 6 digits
    assert eq.tip_angle == pytest.approx(0.461352, abs=2e-6)
    down = prepare_reference(UNIFORM, InitialCondition(tip_deflection=-0.2)).rod
    assert down.tip_z == pytest.approx(-0.2, rel=1e-12) and down.force[1] < 0


def test_the_chain_released_by_a_tip_force_is_its_static_shape(linear_fit):
    """The chain's own equilibrium under a dead tip force along z with its tip at D: at a small
    D the linear static shape (the small-amplitude release) to first order; a stable minimum of
    its potential with the tip at D at 0.3 L."""
    desc = prbdm_from_fit(TAPERED, linear_fit, springref="zero")
    chain = ChainDynamics.from_description(desc)
    x1 = desc["bodies"][0]["length"]
    D = 1e-5 * TAPERED.length
    th, P = chain.statics(x1).release_shape(D, load_guess=1.0, measure="tip_z")
    assert chain.tip(th)[1] == pytest.approx(D, rel=1e-12)
    assert th == pytest.approx(chain.static_tip_shape(D), rel=1e-6)
    D = 0.3 * TAPERED.length
    th, P = chain.statics(x1).release_shape(D, load_guess=1e4, measure="tip_z")
    assert chain.tip(th)[1] == pytest.approx(D, rel=1e-12)
    g, H = chain.statics(x1).gradient_hessian(th, np.array([0.0, P]))
    assert np.abs(g).max() < 1e-9 * P * TAPERED.length and np.linalg.eigvalsh(H)[0] > 0


def test_the_spring_law_of_a_fit_result(linear_fit):
    from prbdm.pose_target import POSE_TARGETS
    from prbdm.springs import LAW_OF_POSE_TARGET

    assert set(LAW_OF_POSE_TARGET) == set(POSE_TARGETS)      # a law for every pose target
    s = np.array([2.0, 3.0, 4.0])
    springs, info = fitted_springs(linear_fit, s)
    assert isinstance(springs, LinearSprings) and info["law"] == "constant"
    assert springs.K == pytest.approx(linear_fit["k"][0] * s, rel=1e-15)
    paper = dict(linear_fit, poses=[[0.2] * 3, [0.1] * 3], k=[1.3, 1.1])      # unsorted
    springs, info = fitted_springs(paper, s)
    assert isinstance(springs, InterpolatedSprings) and info["pose_target"] == "straight"
    assert info["pose_angles"] == [0.1, 0.2] and info["k"] == [1.1, 1.3]
    # the torque at a joint angle between the poses: s k(u) u, k linear in u
    assert springs.torque(np.array([0.15, 0.0, 0.3])) == pytest.approx(
        s * np.array([1.2, 0.0, 1.3]) * np.array([0.15, 0.0, 0.3]), rel=1e-14)
    shape = dict(paper, k=[1.1, 1.1], pose_target="shape")
    assert isinstance(fitted_springs(shape, s)[0], LinearSprings)
    for bad, message in ((dict(paper, pose_target="bent"), "pose_target must be one of"),
                         (dict(paper, poses=[[0.1, 0.2, 0.1], [0.2] * 3]), "one angle >= 0"),
                         (dict(paper, poses=[[0.1] * 3, [0.1] * 3]), "the same angle")):
        with pytest.raises(BadInput, match=message):
            fitted_springs(bad, s)
    # which pose the chain takes its stiffness from
    assert model_pose(paper, "rest", "straight", "rod") == (1, True)      # smallest angle
    assert model_pose(paper, "rest", "straight", "modal") == ("rest", False)
    assert model_pose(linear_fit, "rest", "straight", "rod") == ("rest", False)
    assert model_pose(shape, "rest", "shape", "modal") == (0, True)
    assert model_pose(paper, 0, "straight", "rod") == (0, False)


def test_the_rest_fit_follows_the_rod_at_a_fifth_of_the_length(linear_fit):
    """Released at 0.2 L (33 times the small-deflection limit) the 3R chain fitted at rest, its
    stiffness constant, has the rod's period to 0.055 % (measured; 0.033 % against the default
    rod_response discretisation, the rod's own resolution here 0.07 %) and its tip trajectory
    to 1.4 % rms of the release deflection; the bound (0.5 %) is ten times the measurement and a
    twentieth of a paper-pose fit's error (tests/test_simulate.py). Both start at the same tip
    deflection, each from its own static shape under a tip force."""
    D = 0.2 * TAPERED.length
    res = simulate(TAPERED, linear_fit, initial=InitialCondition(tip_deflection=D),
                   run=RunSettings(periods=3), reference=CHEAP_ROD)
    info = res.info
    assert info["reference"] == "rod" and info["springs"]["law"] == "constant"
    assert res.tip_prbdm[0] == pytest.approx(D, rel=1e-12)
    assert res.tip_truth[0] == pytest.approx(D, rel=1e-6)      # the discretised rod's start
    assert info["release"]["prbdm"]["force_N"] == pytest.approx(
        info["release"]["truth"]["force_N"], rel=0.02)         # the chain's static error
    assert info["period_error"] < 5e-3
    assert 0 < info["period_resolution"] < 2e-3
    assert info["rms_tip_difference"] < 0.05
    assert info["energy_drift"] < 1e-7
    assert "geometrically exact rod" in info["truth"]["model"]
    json.dumps(res.to_dict(), allow_nan=False)


# ----------------------------------------------------------------------------- command line
def test_cli_a_deflection_the_rod_does_not_reach_exits_2_before_the_fit(run, tmp_path,
                                                                         monkeypatch):
    """1.19 m on the 1.2 m strip: past what the rod reaches up to its largest load (0.94 L):
    one line naming --tip-deflection and the limit, before any fit."""
    import prbdm.export

    def no_fit(*a, **k):
        raise AssertionError("fitted before refusing --tip-deflection")

    monkeypatch.setattr(prbdm.export, "run_fit", no_fit)
    beam = tmp_path / "beam.json"
    beam.write_text(TAPERED.to_json())
    rc, out, err = run("simulate", beam, "--joints", 3, "--tip-deflection", 1.19)
    assert rc == 2 and out == "" and err.count("\n") == 1 and "Traceback" not in err, err
    assert "error: --tip-deflection: beyond what the large-amplitude reference" in err, err
    assert "at most 1.13 m (0.9414 L)" in err and "P L^2/(E I_max) = 100" in err, err
    rc, out, err = run("simulate", beam, "--joints", 3, "--tip-deflection", 0.24,
                       "--duration", 100)
    assert rc == 2 and "at most 40 first-mode periods" in err and "against the rod" in err, err


def test_cli_a_large_impulse_or_damped_release_is_compared_with_the_linear_truth(run, tmp_path,
                                                                                  linear_fit):
    """The rod starts from rest and is undamped: a damped release beyond 0.01 L and an impulse
    that swings the tip beyond it are compared with the linear truth, each with a warning."""
    beam = tmp_path / "beam.json"
    beam.write_text(TAPERED.to_json())
    fit = tmp_path / "fit.json"
    fit.write_text(json.dumps(linear_fit))
    T1 = 2 * math.pi / linear_fit["omega_truth"][0]
    rc, out, err = run("simulate", beam, "--from", fit, "--tip-deflection", 0.05, "--damping",
                       0.01, "--duration", 4 * T1, "--json")
    assert rc == 0, err
    rep = json.loads(out)
    assert rep["reference"] == "modal" and "is undamped" in rep["warnings"][0]
    rc, out, err = run("simulate", beam, "--from", fit, "--tip-impulse", 500,
                       "--duration", 4 * T1, "--json")
    rep = json.loads(out)
    assert rc == 0 and rep["reference"] == "modal"
    assert max(map(abs, rep["tip_truth"])) > SMALL_DEFLECTION * TAPERED.length
    assert any("starts from rest" in w for w in rep["warnings"]), rep["warnings"]
