"""The beam (prbdm.geometry): validation (BadInput naming the field), JSON and polygon round trips,
random beams as a pure function of (seed, index) within the ranges of docs/conventions.md §1.

``BAD_BEAMS`` is shared with tests/test_cli_eval.py, which feeds the same files to ``prbdm eval``.
"""
import io
import json
import math

import numpy as np
import pytest
from shapely.geometry import Polygon

from prbdm import STEEL, Beam, Material, load_beam, random_beam
from prbdm.errors import BadInput

GOOD = {"name": "panel", "x": [0.0, 0.35, 1.0], "half_width": [0.18, 0.12, 0.05],
        "thickness": 0.03, "material": {"E": 205e9, "rho": 7850, "nu": 0.28}}


def _with(**changes):
    d = json.loads(json.dumps(GOOD))
    for key, value in changes.items():
        if key.startswith("material_"):
            key = key[len("material_"):]
            if value is _DROP:
                d["material"].pop(key)
            else:
                d["material"][key] = value
        elif value is _DROP:
            d.pop(key)
        else:
            d[key] = value
    return d


_DROP = object()

#: (id, beam-file text, word the one-line message must contain)
BAD_BEAMS = [
    ("x-not-at-zero", _with(x=[0.1, 0.35, 1.0]), "x"),
    ("x-repeated", _with(x=[0.0, 0.35, 0.35]), "x"),
    ("x-decreasing", _with(x=[0.0, 0.7, 0.5]), "x"),
    ("x-one-station", _with(x=[0.0], half_width=[0.1]), "x"),
    ("x-not-numbers", _with(x=["a", "b", "c"]), "x"),
    ("x-nested", _with(x=[[0.0, 0.5, 1.0]]), "x"),
    ("x-nan", _with(x=[0.0, float("nan"), 1.0]), "x"),
    ("x-inf", _with(x=[0.0, 0.5, float("inf")]), "x"),
    ("hw-zero", _with(half_width=[0.18, 0.0, 0.05]), "half_width"),
    ("hw-negative", _with(half_width=[0.18, 0.12, -0.05]), "half_width"),
    ("hw-count", _with(half_width=[0.18, 0.12]), "half_width"),
    ("hw-nan", _with(half_width=[0.18, float("nan"), 0.05]), "half_width"),
    ("t-zero", _with(thickness=0.0), "thickness"),
    ("t-negative", _with(thickness=-0.01), "thickness"),
    ("t-inf", _with(thickness=float("inf")), "thickness"),
    ("t-nan", _with(thickness=float("nan")), "thickness"),
    ("t-string", _with(thickness="thick"), "thickness"),
    ("t-bool", _with(thickness=True), "thickness"),
    ("unknown-key", _with(colour="red"), "colour"),
    ("unknown-material-key", _with(material_G=80e9), "G"),
    ("missing-x", _with(x=_DROP), "x"),
    ("missing-half-width", _with(half_width=_DROP), "half_width"),
    ("missing-thickness", _with(thickness=_DROP), "thickness"),
    ("E-negative", _with(material_E=-205e9), "material.E"),
    ("E-zero", _with(material_E=0), "material.E"),
    ("E-nan", _with(material_E=float("nan")), "material.E"),
    ("E-string", _with(material_E="steel"), "material.E"),
    ("rho-negative", _with(material_rho=-7850), "material.rho"),
    ("nu-half", _with(material_nu=0.5), "material.nu"),
    ("nu-minus-one", _with(material_nu=-1.0), "material.nu"),
    ("nu-large", _with(material_nu=0.7), "material.nu"),
    ("material-not-object", _with(material=[1, 2]), "material"),
    ("name-not-string", _with(name=3), "name"),
    ("not-an-object", [1, 2, 3], "beam"),
]

BAD_FILES = [
    ("invalid-json", "{\"x\": [0, 1], \"half_width\": [0.1, 0.1], thickness: 0.01}", "BEAM"),
    ("truncated-json", "{\"x\": [0, 1], ", "BEAM"),
    ("empty-file", "", "BEAM"),
]


def _text(d):
    return json.dumps(d)   # NaN / Infinity written as JSON's common extension, read back by json


@pytest.mark.parametrize("data, field", [(d, f) for _, d, f in BAD_BEAMS],
                         ids=[i for i, _, _ in BAD_BEAMS])
def test_bad_beam_dict(data, field):
    with pytest.raises(BadInput, match=field.replace(".", r"\.")):
        Beam.from_dict(data)


@pytest.mark.parametrize("data, field", [(d, f) for _, d, f in BAD_BEAMS],
                         ids=[i for i, _, _ in BAD_BEAMS])
def test_bad_beam_file(tmp_path, data, field):
    path = tmp_path / "beam.json"
    path.write_text(_text(data))
    with pytest.raises(BadInput, match=field.replace(".", r"\.")) as exc:
        load_beam(path)
    assert "\n" not in str(exc.value)


@pytest.mark.parametrize("kwargs, shown", [
    (dict(x=np.array([0.1, 1.0])), "x[0] = 0.1"),
    (dict(x=np.array([0.0, 0.7, 0.5]), half_width=[0.1] * 3), "x[2] = 0.5 <= x[1] = 0.7"),
    (dict(half_width=np.array([0.1, -0.12])), "half_width[1] = -0.12"),
    (dict(thickness=np.float64(-0.02)), "got -0.02"),
    (dict(material="E"), "got -1000000000.0"),
])
def test_messages_show_plain_numbers_not_numpy_reprs(kwargs, shown):
    base = dict(x=[0.0, 1.0], half_width=[0.1, 0.1], thickness=0.02)
    with pytest.raises(BadInput) as exc:
        if "material" in kwargs:     # a NumPy scalar in the material
            Material(E=np.float64(-1e9))
        else:
            Beam(**{**base, **kwargs})
    assert "np." not in str(exc.value) and shown in str(exc.value), str(exc.value)


@pytest.mark.parametrize("text, field", [(t, f) for _, t, f in BAD_FILES],
                         ids=[i for i, _, _ in BAD_FILES])
def test_bad_json_file(tmp_path, text, field):
    path = tmp_path / "beam.json"
    path.write_text(text)
    with pytest.raises(BadInput, match=field):
        load_beam(path)


def test_missing_file(tmp_path):
    with pytest.raises(BadInput, match="no such file"):
        load_beam(tmp_path / "nope.json")
    with pytest.raises(BadInput, match="no such file"):
        load_beam(tmp_path)                     # a folder is not a beam file


def test_constructor_validation():
    with pytest.raises(BadInput, match="thickness"):
        Beam(x=[0, 1], half_width=[0.1, 0.1], thickness=-1)
    with pytest.raises(BadInput, match="material"):
        Beam(x=[0, 1], half_width=[0.1, 0.1], thickness=0.01, material={"E": 1})
    with pytest.raises(BadInput, match="material.rho"):
        Material(rho=0)
    with pytest.raises(BadInput, match="material.nu"):
        Material(nu=float("inf"))


def test_defaults_and_derived_quantities():
    b = Beam.from_dict({"x": [0, 0.35, 1.0], "half_width": [0.18, 0.12, 0.05], "thickness": 0.03})
    assert b.material == STEEL
    assert (STEEL.E, STEEL.rho, STEEL.nu) == (205e9, 7850.0, 0.28)
    assert b.name == ""
    assert b.length == 1.0
    assert b.area == pytest.approx(b.to_polygon().area, rel=1e-14)
    assert b.mass == pytest.approx(7850 * 0.03 * b.area)
    np.testing.assert_allclose(b.width_at([0.0, 0.35, 0.675, 1.0]), [0.36, 0.24, 0.17, 0.1])
    assert not b.is_uniform()
    assert Beam(x=[0, 2], half_width=[0.3, 0.3], thickness=0.01).is_uniform()
    # arrays are frozen
    with pytest.raises(ValueError):
        b.x[0] = 1.0


def test_json_round_trip(tmp_path, monkeypatch):
    for beam in [Beam.from_dict(GOOD), random_beam(3, 7),
                 Beam(x=[0, 2.5], half_width=[0.4, 0.1], thickness=0.02,
                      material=Material(E=70e9, rho=2700, nu=0.33))]:
        path = tmp_path / "b.json"
        beam.to_json(path)
        back = load_beam(path)
        assert back.to_dict() == beam.to_dict()
        np.testing.assert_array_equal(back.x, beam.x)          # bit for bit
        np.testing.assert_array_equal(back.half_width, beam.half_width)
        assert back.material == beam.material and back.thickness == beam.thickness
        assert Beam.from_dict(beam.to_dict()).to_dict() == beam.to_dict()
        monkeypatch.setattr("sys.stdin", io.StringIO(beam.to_json()))
        assert load_beam("-").to_dict() == beam.to_dict()
    assert load_beam(GOOD).name == "panel"


# ----------------------------------------------------------------------------- polygons
def test_polygon_round_trip():
    for beam in [Beam.from_dict(GOOD), random_beam(1, 2), random_beam(1, 3, p=3),
                 Beam(x=[0, 1.5], half_width=[0.2, 0.2], thickness=0.01)]:
        back = Beam.from_polygon(beam.to_polygon(), beam.thickness, beam.material)
        np.testing.assert_allclose(back.x, beam.x, rtol=0, atol=1e-12)
        # end stations are read 1e-9 L inside the outline (to cut a vertical root/tip edge
        # cleanly), so the tip half-width is off by slope * 1e-9 L
        slope = np.abs(np.diff(beam.half_width) / np.diff(beam.x)).max()
        np.testing.assert_allclose(back.half_width, beam.half_width, rtol=1e-12,
                                   atol=2e-9 * beam.length * max(slope, 1e-3))
        assert back.to_polygon().symmetric_difference(beam.to_polygon()).area < 1e-8 * beam.area


def test_polygon_from_hand_drawn_outline():
    # a tapered panel with a vertical tip edge, vertices in arbitrary (clockwise) order
    poly = Polygon([(0, 0.2), (1, 0.05), (1, -0.05), (0, -0.2)])
    b = Beam.from_polygon(poly, thickness=0.01)
    np.testing.assert_allclose(b.x, [0, 1])
    np.testing.assert_allclose(b.half_width, [0.2, 0.05], rtol=1e-8)
    assert b.area == pytest.approx(poly.area, rel=1e-9)


@pytest.mark.parametrize("poly, field", [
    (Polygon([(0, 0.1), (1, 0.3), (1, -0.1), (0, -0.1)]), "symmetric"),           # not symmetric
    (Polygon([(0, 0.1), (1, -0.1), (1, 0.1), (0, -0.1)]), "self-intersecting"),   # bow tie
    (Polygon([(0.2, 0.1), (1, 0.1), (1, -0.1), (0.2, -0.1)]), "x = 0"),           # root not at 0
    (Polygon([(0, 0.3), (1, 0.3), (1, -0.3), (0, -0.3)],
             [[(0.4, 0.1), (0.6, 0.1), (0.6, -0.1), (0.4, -0.1)]]), "holes"),
    # a C-shaped outline: the upper boundary is not a function of x
    (Polygon([(0, 0.4), (1, 0.4), (1, 0.3), (0.3, 0.3), (0.3, 0.2), (1, 0.2), (1, -0.2),
              (0.3, -0.2), (0.3, -0.3), (1, -0.3), (1, -0.4), (0, -0.4)]), "function of x"),
    (Polygon(), "valid"),
])
def test_bad_polygon(poly, field):
    with pytest.raises(BadInput, match=field):
        Beam.from_polygon(poly, thickness=0.01)


def test_polygon_must_be_a_polygon():
    with pytest.raises(BadInput, match="polygon"):
        Beam.from_polygon([(0, 0), (1, 0), (1, 1)], thickness=0.01)


# ----------------------------------------------------------------------------- random beams
def test_random_beam_is_a_pure_function():
    a, b = random_beam(12, 34), random_beam(12, 34)
    assert a.to_dict() == b.to_dict()
    assert random_beam(12, 35).to_dict() != a.to_dict()
    assert random_beam(13, 34).to_dict() != a.to_dict()
    # rebuilding one beam alone does not depend on what was drawn before
    _ = [random_beam(12, i) for i in range(5)]
    assert random_beam(12, 34).to_dict() == a.to_dict()


@pytest.mark.parametrize("p", [0, 1, 10])
def test_random_beam_ranges(p):
    ts = []
    for i in range(200):
        b = random_beam(0, i, p=p)
        assert len(b.x) == p + 2 and len(b.half_width) == p + 2
        assert b.x[0] == 0.0 and b.x[-1] == 1.0
        assert np.all(np.diff(b.x) > 0)
        assert np.all(b.half_width > 0) and np.all(b.half_width <= 0.5)
        assert 0.01 <= b.thickness <= 0.05
        assert b.material == STEEL
        ts.append(b.thickness)
    assert min(ts) == 0.01 and max(ts) > 0.04       # clipped below at 10 mm, spread to 50 mm
    assert math.isclose(np.mean([random_beam(0, i, p=p).half_width.mean() for i in range(200)]),
                        0.25, abs_tol=0.03)


def test_random_beam_width_range():
    """A (lo, hi) bound: one more draw after the thickness scales the same width fractions, so
    stations, thickness and width ratios are the scalar generator's; the bound spreads
    log-uniformly over [lo, hi]; the scalar generator is unchanged by the option's existence."""
    bounds = []
    for i in range(300):
        a = random_beam(4, i)
        b = random_beam(4, i, max_half_width=(0.025, 0.25))
        assert np.array_equal(a.x, b.x) and a.thickness == b.thickness
        scale = b.half_width / a.half_width * 0.5
        assert np.allclose(scale, scale[0], rtol=1e-12) and 0.025 <= scale[0] <= 0.25
        bounds.append(scale[0])
    u = np.log(np.array(bounds) / 0.025) / np.log(10.0)      # uniform on [0, 1]
    assert abs(np.mean(u) - 0.5) < 0.05 and np.mean(u < 0.25) == pytest.approx(0.25, abs=0.06)
    c = random_beam(4, 7, max_half_width=(0.02, 0.2), min_half_width=0.01)
    assert c.half_width.min() >= 0.01 and c.half_width.max() <= 0.2
    for kwargs in (dict(max_half_width=(0.3, 0.1)), dict(max_half_width=(0.0, 0.1)),
                   dict(max_half_width=(0.1, 0.2, 0.3)),
                   dict(max_half_width=(0.02, 0.2), min_half_width=0.03)):
        with pytest.raises(BadInput, match="half_width"):
            random_beam(0, 0, **kwargs)


def test_random_beam_parameters():
    b = random_beam(1, 1, p=4, length=2.0, min_half_width=0.1, max_half_width=0.3,
                    min_thickness=0.02, max_thickness=0.04)
    assert b.length == 2.0 and np.all((b.half_width >= 0.1) & (b.half_width <= 0.3))
    assert 0.02 <= b.thickness <= 0.04
    for kwargs, field in [(dict(seed=-1, index=0), "seed"), (dict(seed=0, index=1.5), "index"),
                          (dict(seed=0, index=0, p=-1), "p"),
                          (dict(seed=0, index=0, min_half_width=0.6), "min_half_width"),
                          (dict(seed=0, index=0, min_thickness=0.0), "min_thickness")]:
        with pytest.raises(BadInput, match=field):
            random_beam(**kwargs)


def test_smallest_corner():
    from prbdm.geometry import smallest_corner
    rect = Beam(x=[0, 1], half_width=[0.2, 0.2], thickness=0.01)
    assert smallest_corner(rect)[0] == pytest.approx(90.0)
    # a spike: half-width 0.1 -> 0.5 -> 0.1 over 0.01 m each side; its corner is
    # 2 atan(0.01 / 0.4), at the spike's top
    spike = Beam(x=[0, 0.49, 0.5, 0.51, 1], half_width=[0.1, 0.1, 0.5, 0.1, 0.1],
                 thickness=0.01)
    angle, x, y = smallest_corner(spike)
    assert angle == pytest.approx(2 * math.degrees(math.atan(0.01 / 0.4)))
    assert (x, y) == (0.5, 0.5)
    # invariant to the scale, and the tip counts: a tongue rising beside the tip edge
    tongue = Beam(x=[0, 0.9984, 1], half_width=[0.2, 0.1119, 0.492], thickness=0.02)
    big = Beam(x=[0, 99.84, 100], half_width=[20, 11.19, 49.2], thickness=2)
    assert smallest_corner(tongue)[0] == pytest.approx(math.degrees(math.atan(0.0016 / 0.3801)))
    assert smallest_corner(big)[0] == pytest.approx(smallest_corner(tongue)[0])
    assert smallest_corner(tongue)[1:] == (1.0, 0.492)


def test_plate_refuses_sharp_corners_and_the_beam_does_not():
    from prbdm.geometry import MIN_PLATE_CORNER_DEGREES, check_beam, smallest_corner
    tongue = Beam(x=[0, 0.9984, 1], half_width=[0.2, 0.1119, 0.492], thickness=0.02)
    for model in ("plate", "mindlin"):
        with pytest.raises(BadInput, match=r"half_width: .* at least 1 degrees.* 0\.241 degrees"):
            check_beam(tongue, model)
    check_beam(tongue, "beam")
    check_beam(tongue)
    # just above the limit: accepted; just below: refused
    for factor, accepted in ((1.01, True), (0.99, False)):
        dx = 0.38 * math.tan(math.radians(factor * MIN_PLATE_CORNER_DEGREES))
        b = Beam(x=[0, 1 - dx, 1], half_width=[0.2, 0.11, 0.49], thickness=0.02)
        assert (smallest_corner(b)[0] > MIN_PLATE_CORNER_DEGREES) == accepted
        if accepted:
            check_beam(b, "plate")
        else:
            with pytest.raises(BadInput, match="at least 1 degrees"):
                check_beam(b, "plate")
