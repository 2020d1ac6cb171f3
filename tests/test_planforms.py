"""The smooth random panels (prbdm.planforms): pure functions of (seed, index), within their
stated ranges, every shape drawn, and data sets built from them."""
import json

import numpy as np
import pytest

from prbdm.errors import BadInput
from prbdm.geometry import check_beam
from prbdm.planforms import SHAPES, smooth_beam


def test_a_smooth_panel_is_a_pure_function_of_seed_and_index():
    a, b = smooth_beam(3, 17), smooth_beam(3, 17)
    assert np.array_equal(a.x, b.x) and np.array_equal(a.half_width, b.half_width)
    assert (a.thickness, a.material.nu) == (b.thickness, b.material.nu)
    assert not np.array_equal(smooth_beam(3, 18).half_width, a.half_width)


def test_smooth_panels_stay_in_their_ranges_and_draw_every_shape():
    beams = [smooth_beam(0, i) for i in range(400)]
    full = np.array([2 * b.half_width.max() / b.length for b in beams])
    tl = np.array([b.thickness / b.length for b in beams])
    nu = np.array([b.material.nu for b in beams])
    assert full.min() >= 0.02 and full.max() <= 1.0
    assert tl.min() >= 0.002 and tl.max() <= 0.05 and np.all(tl <= 0.4 * full + 1e-15)
    assert nu.min() >= 0.2 and nu.max() <= 0.45
    # log-uniform: about as many panels below the geometric middle of the width range as above
    assert 0.4 < np.mean(full < np.sqrt(0.02 * 1.0)) < 0.6
    assert {b.name.split()[1] for b in beams} == set(SHAPES)
    for b in beams[:60]:
        check_beam(b, "mindlin")            # every one is a plate the plate truths accept


@pytest.mark.parametrize("kw, field", [({"width": (0.5, 0.1)}, "width"),
                                       ({"thickness": -1}, "thickness"),
                                       ({"nu": (0.2, 0.6)}, "nu")])
def test_bad_ranges_name_the_field(kw, field):
    with pytest.raises(BadInput, match=field):
        smooth_beam(0, 0, **kw)


def test_a_smooth_data_set_records_each_panels_poisson_ratio(run, tmp_path):
    out = tmp_path / "set"
    rc, text, err = run("dataset", "generate", "--out", out, "--count", 4, "--joints", 2,
                        "--truth", "plate", "--family", "smooth", "--starts", 0,
                        "--workers", 0, "--progress", "none", "--json")
    assert rc == 0, err
    import pandas as pd

    table = pd.concat(pd.read_parquet(p) for p in sorted(out.glob("part-*.parquet")))
    spec = json.loads((out / "_manifest.json").read_text())["spec"]
    assert spec["beam"]["family"] == "smooth" and spec["target"] == "spectrum"
    for _, rec in table.iterrows():
        assert rec["nu"] == smooth_beam(0, int(rec["index"])).material.nu
        if rec["status"] == "ok":
            assert len(rec["symmetric_lambda"]) >= 12
    # read back as training and evaluation read a set: each beam with its own nu
    from prbdm import dataset as ds
    from prbdm.chain import BeamBatch

    read = ds.read_table(out, columns=["x", "half_width", "thickness"], status="ok")
    batch = BeamBatch.from_table(read, spec["beam"]["material"])
    np.testing.assert_array_equal(
        batch.nu, [smooth_beam(0, int(i)).material.nu for i in read.column("index").to_numpy()])
    frame = read.to_pandas()
    batch = BeamBatch.from_table(frame, spec["beam"]["material"])
    assert len(set(batch.nu)) == len(batch.nu) > 1
    frame.loc[0, "nu"] = float("nan")            # e.g. a set without nu concatenated to this one
    with pytest.raises(BadInput, match="nu"):
        BeamBatch.from_table(frame, spec["beam"]["material"])
    rc, text, err = run("dataset", "generate", "--out", tmp_path / "x", "--count", 2,
                        "--joints", 2, "--family", "smooth", "--stations", 4)
    assert rc == 2 and "--stations" in err
