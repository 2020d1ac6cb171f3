"""Fuzz: seeded random corruptions of beam files through `truth`, `eval` and `predict`.

Every outcome must be one of two things (issue 19, item 8): exit 0 with finite, sorted, positive
frequencies, or exit 2 with exactly one line on stderr (``prbdm CMD: error: ...``) and no
traceback. Anything else (a traceback, exit 1, a NaN, an unsorted or non-positive frequency, two
error lines) fails. The corruptions are drawn from a fixed seed, so a failure names a case that
can be rerun alone (its id is the case number and the corruptions applied).
(Corrupted checkpoint bytes are fuzzed with the surrogate's tests.)
"""
from __future__ import annotations

import copy
import json
import math

import numpy as np
import pytest

SEED = 19
CASES = 72

BASES = [
    {"name": "tapered panel", "x": [0.0, 0.35, 1.0], "half_width": [0.18, 0.12, 0.05],
     "thickness": 0.03},
    {"x": [0.0, 0.1, 0.4, 0.7, 1.2], "half_width": [0.05, 0.04, 0.06, 0.02, 0.01],
     "thickness": 0.004, "material": {"E": 69e9, "rho": 2700.0, "nu": 0.33}},
]

#: replacement values: wrong types, non-finite, huge, tiny, zero, negative, empty
ODD_VALUES = ["steel", None, True, {}, [], [[0.1]], float("nan"), float("inf"), -float("inf"),
              1e300, -1e300, 1e-300, 0.0, -1.0, 1e12, 1e-12, 12, "1e-3"]
FIELDS = ["x", "half_width", "thickness", "name", "material", "material.E", "material.rho",
          "material.nu"]


def _set(beam: dict, field: str, value) -> None:
    if field.startswith("material."):
        mat = beam.setdefault("material", {"E": 205e9, "rho": 7850.0, "nu": 0.28})
        if isinstance(mat, dict):
            mat[field.split(".")[1]] = value
    else:
        beam[field] = value


def _corrupt(rng: np.random.Generator, beam: dict) -> str:
    """Apply one random corruption to ``beam`` in place; returns its label."""
    # weighted so that about a third of the files stay valid (answered, perhaps with a warning):
    # both outcomes are exercised
    kinds = {"value": 2, "element": 2, "scale": 3, "perturb": 6, "drop": 1, "extra": 1,
             "empty": 1, "shuffle": 1, "duplicate": 1, "truncate": 1}
    weights = np.array(list(kinds.values()), dtype=float)
    kind = rng.choice(list(kinds), p=weights / weights.sum())
    if kind == "perturb":                  # a valid number moved within or just past a limit
        key = str(rng.choice(["half_width", "thickness", "material.E", "material.rho", "x"]))
        factor = float(10.0 ** rng.uniform(-4, 4))

        def num(v):
            return isinstance(v, (int, float)) and not isinstance(v, bool)
        if key in ("half_width", "x"):
            values = beam.get(key)
            if not (isinstance(values, list) and values and all(map(num, values))):
                return "noop"
            if key == "x":
                beam[key] = [v * factor for v in values]        # a longer or shorter panel
                return f"x*{factor:.3g}"
            i = int(rng.integers(len(values)))
            values[i] = values[i] * factor
            return f"half_width[{i}]*{factor:.3g}"
        if key == "thickness":
            if not num(beam.get(key)):
                return "noop"
            beam[key] = beam[key] * factor
            return f"thickness*{factor:.3g}"
        given = beam.get("material", {})
        mat = {"E": 205e9, "rho": 7850.0, "nu": 0.28, **(given if isinstance(given, dict) else {})}
        if not num(mat[key[9:]]):
            return "noop"
        mat[key[9:]] *= factor
        beam["material"] = mat
        return f"{key}*{factor:.3g}"
    field = str(rng.choice(FIELDS))
    if kind == "value":
        value = ODD_VALUES[rng.integers(len(ODD_VALUES))]
        _set(beam, field, value)
        return f"{field}={value!r}"
    if kind == "element":                  # one entry of a station list
        key = str(rng.choice(["x", "half_width"]))
        if isinstance(beam.get(key), list) and beam[key]:
            i = int(rng.integers(len(beam[key])))
            beam[key][i] = ODD_VALUES[rng.integers(len(ODD_VALUES))]
            return f"{key}[{i}]={beam[key][i]!r}"
        return "noop"
    if kind == "scale":                    # a plausible number off by powers of ten
        factor = float(10.0 ** rng.choice([-12, -9, -6, -3, 3, 6, 9, 12]))
        key = str(rng.choice(["x", "half_width", "thickness", "material.E", "material.rho"]))
        if key in ("x", "half_width") and isinstance(beam.get(key), list):
            try:
                beam[key] = [v * factor for v in beam[key]]
            except TypeError:
                return "noop"
        elif key == "thickness" and isinstance(beam.get(key), (int, float)):
            beam[key] *= factor
        elif key.startswith("material."):
            mat = beam.get("material", {"E": 205e9, "rho": 7850.0, "nu": 0.28})
            if isinstance(mat, dict) and isinstance(mat.get(key[9:], 1.0), (int, float)):
                beam["material"] = {**{"E": 205e9, "rho": 7850.0, "nu": 0.28}, **mat}
                beam["material"][key[9:]] = beam["material"][key[9:]] * factor
        return f"{key}*{factor:g}"
    if kind == "drop":
        if "." in field:
            if isinstance(beam.get("material"), dict):
                beam["material"].pop(field[9:], None)
        else:
            beam.pop(field, None)
        return f"drop {field}"
    if kind == "extra":
        beam[str(rng.choice(["colour", "units", "X"]))] = 1
        return "extra key"
    if kind == "empty":
        key = str(rng.choice(["x", "half_width"]))
        beam[key] = []
        return f"{key}=[]"
    if kind == "shuffle":
        if isinstance(beam.get("x"), list):
            beam["x"] = list(rng.permutation(beam["x"]).tolist())
        return "shuffled x"
    if kind == "duplicate":
        if isinstance(beam.get("x"), list) and len(beam["x"]) > 2:
            beam["x"][2] = beam["x"][1]
        return "repeated station"
    key = str(rng.choice(["x", "half_width"]))          # truncate
    if isinstance(beam.get(key), list):
        beam[key] = beam[key][:-1]
    return f"{key} one short"


def _cases():
    rng = np.random.default_rng(SEED)
    out = []
    for i in range(CASES):
        beam = copy.deepcopy(BASES[i % len(BASES)])
        labels = [_corrupt(rng, beam) for _ in range(int(rng.integers(1, 3)))]
        out.append(pytest.param(beam, id=f"{i}:" + ";".join(labels)))
    return out


COMMANDS = [("truth", ["--modes", "3"], lambda o: [o["freq_hz"]]),
            ("eval", ["--gamma", "0.3,0.3,0.4", "--k", "1"], lambda o: o["freq_hz"]),
            ("predict", ["--joints", "4"],
             lambda o: o["freq_hz"] + [o["freq_hz_truth_predicted"]])]


def _check_frequencies(rows):
    for f in rows:
        assert len(f) > 0
        assert all(isinstance(v, float) and math.isfinite(v) and v > 0 for v in f), f
        assert f == sorted(f), f


@pytest.mark.parametrize("beam", _cases())
def test_corrupted_beam_is_answered_or_refused_in_one_line(run, tmp_path, beam):
    path = tmp_path / "beam.json"
    path.write_text(json.dumps(beam))        # NaN / Infinity as JSON's common extension
    for command, flags, frequencies in COMMANDS:
        rc, out, err = run(command, path, "--json", *flags)
        assert "Traceback" not in err
        if rc == 0:
            _check_frequencies(frequencies(json.loads(out)))
        else:
            assert rc == 2, (command, rc, err)
            lines = err.strip().splitlines()
            assert len(lines) == 1 and lines[0].startswith(f"prbdm {command}: error: "), \
                (command, err)
            assert out == ""


def test_the_fuzz_reaches_both_outcomes(run, tmp_path):
    """The corruptions are not all refused (nor all harmless): the test exercises both paths."""
    outcomes = set()
    for param in _cases():
        beam, = param.values
        path = tmp_path / "beam.json"
        path.write_text(json.dumps(beam))
        rc, _, _ = run("truth", path, "--json", "--modes", "3")
        outcomes.add(rc)
    assert outcomes == {0, 2}
