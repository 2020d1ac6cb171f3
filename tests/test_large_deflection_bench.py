"""Smoke test of benchmarks/large_deflection.py (issue 37 item 3) and an independent check of its
chain statics: the rigid-finite-element chain converges to the geometrically exact rod."""
import importlib.util
import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def bench():
    spec = importlib.util.spec_from_file_location("large_deflection",
                                                  ROOT / "benchmarks" / "large_deflection.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod          # dataclasses look their module up there
    spec.loader.exec_module(mod)
    return mod


def test_interpolated_springs_are_conservative():
    from prbdm.springs import InterpolatedSprings

    sp = InterpolatedSprings([2.0, 3.0], [0.1, 0.2, 0.3], [1.2, 1.5, 1.4])
    rng = np.random.default_rng(0)
    for _ in range(20):
        th = rng.uniform(-0.6, 0.6, 2)
        h = 1e-6
        grad = [(sp.energy(th + h * e) - sp.energy(th - h * e)) / (2 * h) for e in np.eye(2)]
        assert np.allclose(grad, sp.torque(th), rtol=1e-7, atol=1e-9)
        hess = [(sp.torque(th + h * e) - sp.torque(th - h * e))[i] / (2 * h)
                for i, e in enumerate(np.eye(2))]
        assert np.allclose(hess, sp.dtorque(th), rtol=1e-6)
    # held at the end poses' SCFs outside the pose range
    assert np.allclose(sp.torque(np.array([0.01, 1.0])), [2 * 1.2 * 0.01, 3 * 1.4 * 1.0])


@pytest.mark.parametrize("make", ["table2_beam", "tapered_beam"])
def test_rfe_chain_statics_converge_to_the_rod(bench, make):
    from prbdm.truth.rod import rod_static

    beam = getattr(bench, make)()
    rod = rod_static(beam, tip_angle=60 * bench.DEG)
    errs = {}
    for n in (4, 10, 40):
        ch = bench.build_methods(beam, (f"rfe-{n}",))[f"rfe-{n}"]
        th = ch.path(np.linspace(0, 1, 7)[1:, None] * np.array(rod.force))[-1]
        errs[n] = float(np.hypot(*(ch.tip(th) - [rod.tip_x, rod.tip_z]))) / beam.length
    assert errs[40] < 1e-3, errs
    assert errs[40] < errs[10] < errs[4], errs


def test_network_chain_has_the_spring_law_of_its_pose_target(bench):
    from prbdm import surrogate
    from prbdm.springs import LAW_OF_POSE_TARGET, InterpolatedSprings, LinearSprings

    sur = surrogate.load_checkpoint(surrogate.default_checkpoint(4, "beam", "eigenvalue"))
    ch = bench.build_methods(bench.tapered_beam(), ("network",), sur=sur)["network"]
    law = LAW_OF_POSE_TARGET[sur.pose_target]
    assert ch.info["springs"]["law"] == law
    assert ch.info["springs"]["pose_target"] == sur.pose_target
    assert isinstance(ch.springs, LinearSprings if law == "constant" else InterpolatedSprings)


@pytest.mark.slow
def test_quick_run_on_one_beam(bench, tmp_path):
    out = tmp_path / "ld.json"
    assert bench.main(["--quick", "--beams", "1", "--release", "10", "--starts", "8",
                       "--methods", "howell-1r,su-3r,rfe-4,fit-paper,fit-const,network",
                       "--json", str(out)]) == 0
    doc = json.loads(out.read_text())
    (rec,) = doc["beams"]
    for m in doc["methods"]:
        err = rec["static"]["vertical"]["methods"][m]["tip_error"]
        assert all(math.isfinite(e) for e in err) and max(err) < 0.5
        v = rec["vibration"]["10"]["methods"][m]
        assert v["period_error"] < 0.5 and math.isfinite(v["trajectory_rms"])
        assert v["energy_drift"] < 1e-6
        s = doc["summary"][m]
        assert set(s) >= {"static_vertical_60", "period_error_10", "trajectory_rms_10"}
    rod = rec["vibration"]["10"]["rod"]
    assert rod["mesh"]["steps"] == bench.ROD_DYNAMICS["steps"]
    assert 0 < rod["resolution"] < 1e-2 and rod["resolution_note"] is None
