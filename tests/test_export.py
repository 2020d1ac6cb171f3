"""``prbdm.export`` and ``prbdm export``: the description against the PRBDM (the NumPy chain it
is built from, the torch model the fit used) and independent integrals, the URDF and MJCF as
XML, MuJoCo's own linearisation and free vibration of the MJCF (skipped without mujoco), atomic
writes and bad input (exit 2, one line)."""
import json
import os
import subprocess
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import torch
from scipy.integrate import quad

from prbdm.chain import BeamBatch, link_table
from prbdm.errors import BadInput
from prbdm.export import URDF_NS, prbdm_from_fit, to_json, to_mjcf, to_urdf
from prbdm.geometry import Beam
from prbdm.model import BeamTensors, base_stiffness, eigenvalues, links_from_gamma, make_poses

TAPERED = Beam(x=[0.0, 0.35, 1.2], half_width=[0.18, 0.12, 0.05], thickness=0.02,
               name="tapered")
UNIFORM = Beam(x=[0.0, 1.0], half_width=[0.1812, 0.1812], thickness=0.040532, name="uniform")
# a hand-made PRBDM (no fit needed): the description only reads gamma, k, law and poses
GAMMA = [0.3, 0.2, 0.25, 0.25]
FIT = {"gamma": GAMMA, "k": [1.05, 1.1, 1.2, 1.3, 1.35, 1.4, 1.45, 1.5, 1.55],
       "law": "beam", "poses": make_poses("paper", 3).tolist()}
LINEAR_FIT = {"gamma": GAMMA, "k": [0.97], "law": "beam", "poses": [[0.0, 0.0, 0.0]]}


def physical(beam, gamma):
    """The chain's SI link table (prbdm.chain, what the description is built from), and the torch
    model's (the fit's) BeamTensors and Links."""
    table = link_table(BeamBatch.from_beams(beam), np.asarray(gamma)[None], direct=True)
    bt = BeamTensors.from_beams(beam)
    with torch.no_grad():
        links = links_from_gamma(bt, torch.tensor(gamma, dtype=torch.float64))
    return {k: v[0] for k, v in table.items() if k != "base_stiffness"}, bt, links


def gauss_lamina(beam, a: float, b: float) -> dict:
    """Lamina integrals of the span [a, b] [m] of ``beam`` by Gauss-Legendre quadrature, the
    independent check of the chain's Simpson integrals (prbdm.chain.span_integrals): mass [kg],
    ``com`` (m from ``a``), ``J`` = ∫ (x - x_c)^2 dm and ``Ixx`` = ∫ y^2 dm = rho t ∫ (2/3) w^3 dx
    [kg m^2], mean half-width [m]. On each piece between stations the half-width is linear and
    the integrands are polynomials of degree <= 3, which 3-point Gauss-Legendre integrates
    exactly; moments about ``a``."""
    xs, ws = np.asarray(beam.x, float), np.asarray(beam.half_width, float)
    cuts = np.unique(np.concatenate([[a, b], xs[(xs > a) & (xs < b)]]))
    g, wg = np.polynomial.legendre.leggauss(3)
    lo, hi = cuts[:-1, None], cuts[1:, None]
    xq = (lo + hi) / 2 + (hi - lo) / 2 * g
    wq = (hi - lo) / 2 * wg
    w = np.interp(xq, xs, ws)
    s = xq - a
    rho_t = beam.material.rho * beam.thickness
    mass = rho_t * np.sum(wq * 2 * w)
    first = rho_t * np.sum(wq * 2 * w * s)
    second = rho_t * np.sum(wq * 2 * w * s * s)
    com = first / mass
    return {"mass": mass, "com": com, "J": second - first * com,
            "Ixx": rho_t * np.sum(wq * 2.0 / 3.0 * w ** 3),
            "mean_half_width": mass / (2 * rho_t * (b - a))}


# ----------------------------------------------------------------------------- description
def test_json_link_table_is_the_chains_and_bodies_are_consistent():
    desc = json.loads(to_json(prbdm_from_fit(TAPERED, FIT)))
    phys, bt, links = physical(TAPERED, GAMMA)
    assert list(desc["links"]) == ["joint_x", "length", "mass", "com", "inertia", "area_moment"]
    for key, v in phys.items():
        assert desc["links"][key] == v.tolist(), key          # bit for bit
    # the torch model's (the fit's) link table, to round-off
    for key, v in links.physical(bt).items():
        np.testing.assert_allclose(desc["links"][key], v.numpy(), rtol=1e-14, atol=0, err_msg=key)
    bodies = desc["bodies"]
    assert [b["name"] for b in bodies] == ["link_0", "link_1", "link_2", "link_3"]
    for j, b in enumerate(bodies[1:]):
        assert b["mass"] == phys["mass"][j] and b["com"] == [phys["com"][j], 0, 0]
        assert b["inertia"][1] == phys["inertia"][j]           # I_yy is exactly the PRBDM's J
        ixx, iyy, izz = b["inertia"]
        assert izz == ixx + iyy and ixx > 0
    # every body, the clamped link 0 and the roll inertia I_xx included, against independent
    # integrals (Gauss-Legendre)
    cuts = np.concatenate([[0], phys["joint_x"], [TAPERED.length]])
    for j, b in enumerate(bodies):
        ref = gauss_lamina(TAPERED, cuts[j], cuts[j + 1])
        assert b["x_start"] == cuts[j]
        assert b["mass"] == pytest.approx(ref["mass"], rel=1e-14)
        assert b["com"][0] == pytest.approx(ref["com"], rel=1e-14)
        assert b["inertia"][:2] == pytest.approx([ref["Ixx"], ref["J"]], rel=1e-13)
        assert b["mean_half_width"] == pytest.approx(ref["mean_half_width"], rel=1e-14)
    # positions in the parent frames add up to the joint positions; the masses to the beam's
    xs = np.cumsum([b["pos"][0] for b in bodies])
    assert xs[1:] == pytest.approx(phys["joint_x"], rel=1e-15)
    assert sum(b["mass"] for b in bodies) == pytest.approx(TAPERED.mass, rel=1e-13)
    assert [h["axis"] for h in desc["hinges"]] == [[0, -1, 0]] * 3


def test_lamina_inertia_of_a_uniform_link_by_hand():
    # a uniform rectangular lamina b x len: J = m len^2 / 12, I_xx = m b^2 / 12
    desc = prbdm_from_fit(UNIFORM, LINEAR_FIT)
    b = 2 * 0.1812
    for body in desc["bodies"]:
        m, ln = body["mass"], body["length"]
        assert m == pytest.approx(7850 * 0.040532 * b * ln, rel=1e-13)
        assert body["com"][0] == pytest.approx(ln / 2, rel=1e-13)
        assert body["inertia"] == pytest.approx([m * b * b / 12, m * ln * ln / 12,
                                                 m * (b * b + ln * ln) / 12], rel=1e-12)


def test_stiffness_springref_and_frequencies_of_the_chosen_pose():
    phys, bt, links = physical(TAPERED, GAMMA)
    E, t, L = TAPERED.material.E, TAPERED.thickness, TAPERED.length
    # the `beam` law by an independent quadrature: 1 / int dx / EI over the tributary spans
    cuts = np.concatenate([[0], phys["joint_x"], [L]])
    mids = (cuts[1:] + cuts[:-1]) / 2
    spans = [(0.0, mids[1]), (mids[1], mids[2]), (mids[2], L)]

    def EI(x):
        return E * 2 * np.interp(x, TAPERED.x, TAPERED.half_width) * t ** 3 / 12
    s_ref = [1 / sum(quad(lambda x: 1 / EI(x), a2, b2, epsrel=1e-13)[0]
                     for a2, b2 in [(a, min(b, 0.35)), (max(a, 0.35), b)] if b2 > a2)
             for a, b in spans]
    for i in (0, 4):
        desc = prbdm_from_fit(TAPERED, FIT, pose=i)
        K = [h["stiffness"] for h in desc["hinges"]]
        assert K == pytest.approx(np.multiply(FIT["k"][i], s_ref), rel=1e-10)
        assert [h["springref"] for h in desc["hinges"]] == FIT["poses"][i]
        lam = eigenvalues(TAPERED, torch.tensor(GAMMA, dtype=torch.float64),
                          torch.tensor([FIT["k"][i]], dtype=torch.float64),
                          poses=[FIT["poses"][i][0]])[0]
        # the fit's torch model, to the eigensolvers' round-off (eps lam_3 / lam_1)
        assert desc["omega"] == pytest.approx(np.sqrt(lam.numpy()), rel=1e-13)
        assert desc["pose"]["index"] == i and desc["pose"]["k"] == FIT["k"][i]
    flat = prbdm_from_fit(TAPERED, FIT, pose=4, springref="zero")
    assert [h["springref"] for h in flat["hinges"]] == [0, 0, 0]
    # law 'paper' goes through base_stiffness too
    paper = prbdm_from_fit(TAPERED, {**FIT, "law": "paper"})
    s = base_stiffness(bt, links, "paper").numpy() * float(bt.rho * bt.thickness * bt.length ** 4
                                                           * bt.lambda0)
    assert [h["stiffness"] for h in paper["hinges"]] == pytest.approx(FIT["k"][0] * s, rel=1e-14)


def test_damping_is_stiffness_proportional_first_mode_ratio():
    desc = prbdm_from_fit(TAPERED, FIT, damping=0.05)
    w1 = desc["omega"][0]
    for h in desc["hinges"]:
        assert h["damping"] == pytest.approx(2 * 0.05 / w1 * h["stiffness"], rel=1e-14)


def test_pose_selection():
    assert prbdm_from_fit(TAPERED, FIT)["pose"]["index"] == 0
    assert prbdm_from_fit(TAPERED, FIT, pose="3")["pose"]["index"] == 3
    assert prbdm_from_fit(TAPERED, LINEAR_FIT, pose="linear")["pose"]["theta"] == [0, 0, 0]
    with pytest.raises(BadInput, match="--pose: 'linear' needs"):
        prbdm_from_fit(TAPERED, FIT, pose="linear")
    with pytest.raises(BadInput, match=r"--pose: must be 'rest', 'linear' or a pose index in \[0, 8\]"):
        prbdm_from_fit(TAPERED, FIT, pose=9)


@pytest.mark.parametrize("change, message", [
    ({"gamma": None}, "gamma must be a list"),
    ({"gamma": [0.5, 0.6]}, "gamma must sum to 1"),
    ({"gamma": [0.99, 0.01]}, "every gamma must lie in"),
    ({"k": [1.0]}, "k needs one SCF per pose"),
    ({"k": [-1.0] * 9}, "every SCF k must be > 0"),
    ({"law": "spring"}, "law must be one of"),
    ({"poses": [[0.1, 0.1]]}, "poses must be m lists of n = 3"),
    ({"links": {"joint_x": [0.1, 0.2, 0.3]}}, "different beam"),
])
def test_bad_fit_dicts(change, message):
    fit = {**FIT, **change}
    if change.get("gamma", 0) is None:
        del fit["gamma"]
        message = "missing key 'gamma'"
    with pytest.raises(BadInput, match=message):
        prbdm_from_fit(TAPERED, fit)


# ----------------------------------------------------------------------------- URDF / MJCF
def test_urdf_parses_and_its_inertials_match():
    desc = prbdm_from_fit(TAPERED, FIT, pose=2, damping=0.02)
    root = ET.fromstring(to_urdf(desc))
    phys, _, _ = physical(TAPERED, GAMMA)
    assert root.tag == "robot"
    links = {el.get("name"): el for el in root.findall("link")}
    assert set(links) == {"world", "link_0", "link_1", "link_2", "link_3"}
    for j in range(1, 4):
        inertial = links[f"link_{j}"].find("inertial")
        assert float(inertial.find("mass").get("value")) == phys["mass"][j - 1]
        xyz = [float(v) for v in inertial.find("origin").get("xyz").split()]
        assert xyz == [phys["com"][j - 1], 0, 0]
        inertia = inertial.find("inertia").attrib
        assert float(inertia["iyy"]) == phys["inertia"][j - 1]
        assert float(inertia["izz"]) == float(inertia["ixx"]) + float(inertia["iyy"])
        assert all(float(inertia[k]) == 0 for k in ("ixy", "ixz", "iyz"))
    joints = {el.get("name"): el for el in root.findall("joint")}
    assert joints["clamp"].get("type") == "fixed"
    x = 0.0
    for j, h in enumerate(desc["hinges"], start=1):
        el = joints[f"joint_{j}"]
        assert el.get("type") == "revolute"
        assert el.find("parent").get("link") == f"link_{j - 1}"
        assert el.find("child").get("link") == f"link_{j}"
        assert [float(v) for v in el.find("axis").get("xyz").split()] == [0, -1, 0]
        x += float(el.find("origin").get("xyz").split()[0])
        assert x == pytest.approx(phys["joint_x"][j - 1], rel=1e-15)
        spring = el.find(f"{{{URDF_NS}}}spring")
        assert float(spring.get("stiffness")) == h["stiffness"]
        assert float(spring.get("reference")) == FIT["poses"][2][j - 1]
        assert float(el.find("dynamics").get("damping")) == h["damping"]
        gz = root.find(f"gazebo[@reference='joint_{j}']")
        assert float(gz.find("springStiffness").text) == h["stiffness"]
        assert float(gz.find("springReference").text) == h["springref"]


def test_mjcf_structure_without_mujoco():
    desc = prbdm_from_fit(TAPERED, FIT, pose=1)
    root = ET.fromstring(to_mjcf(desc))
    body = root.find("worldbody/body")
    assert body.get("name") == "link_0" and body.find("joint") is None     # welded to the world
    for j, h in enumerate(desc["hinges"], start=1):
        body = body.find("body")
        joint = body.find("joint")
        assert body.get("name") == f"link_{j}" and joint.get("type") == "hinge"
        assert float(joint.get("stiffness")) == h["stiffness"]
        assert float(joint.get("springref")) == FIT["poses"][1][j - 1]
        inertial = body.find("inertial")
        assert float(inertial.get("diaginertia").split()[1]) == desc["bodies"][j]["inertia"][1]
    assert body.find("site").get("name") == "tip"
    qpos = [float(v) for v in root.find("keyframe/key").get("qpos").split()]
    assert qpos == FIT["poses"][1]


# ----------------------------------------------------------------------------- MuJoCo
@pytest.fixture(scope="module")
def mujoco():
    return pytest.importorskip("mujoco", reason="mujoco is not installed (pip install "
                                                "prbdm[sim]): MuJoCo checks skipped")


@pytest.mark.parametrize("pose, springref", [(0, "pose"), (6, "pose"), (3, "zero")])
def test_mujoco_linearised_frequencies_equal_the_prbdm(mujoco, pose, springref):
    from prbdm.export import mujoco_linear_frequencies

    desc = prbdm_from_fit(TAPERED, FIT, pose=pose, springref=springref)
    omega, _ = mujoco_linear_frequencies(to_mjcf(desc))
    assert omega == pytest.approx(desc["omega"], rel=1e-6)
    # and by hand: mj_fullM at the spring reference, stiffness from the model
    model = mujoco.MjModel.from_xml_string(to_mjcf(desc))
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    mujoco.mj_forward(model, data)
    M = np.zeros((3, 3))
    try:
        mujoco.mj_fullM(model, data, M)
    except TypeError:
        mujoco.mj_fullM(model, M, data.qM)
    from scipy.linalg import eigh
    lam = eigh(np.diag(model.jnt_stiffness), M, eigvals_only=True)
    assert np.sqrt(lam) == pytest.approx(desc["omega"], rel=1e-6)
    # the tip rises along +z for positive angles
    data.qpos[:] = 0.05
    mujoco.mj_forward(model, data)
    assert data.site("tip").xpos[2] > 0


def test_mujoco_free_vibration_first_frequency(mujoco):
    from prbdm.export import mujoco_free_vibration

    desc = prbdm_from_fit(TAPERED, FIT, pose=2)
    t, y, measured, predicted = mujoco_free_vibration(to_mjcf(desc), periods=8)
    assert predicted == pytest.approx(desc["omega"][0], rel=1e-6)
    assert abs(measured / predicted - 1) < 0.01
    assert abs(measured / predicted - 1) < 1e-4          # what it actually achieves


def test_mujoco_loads_the_urdf_with_the_same_mass_matrix(mujoco):
    desc = prbdm_from_fit(TAPERED, FIT, pose=1)
    mats = []
    for xml in (to_urdf(desc), to_mjcf(desc)):
        model = mujoco.MjModel.from_xml_string(xml)
        data = mujoco.MjData(model)
        data.qpos[:] = [0.2, -0.1, 0.3]
        mujoco.mj_forward(model, data)
        M = np.zeros((3, 3))
        try:
            mujoco.mj_fullM(model, data, M)
        except TypeError:
            mujoco.mj_fullM(model, M, data.qM)
        mats.append(M)
    assert mats[0] == pytest.approx(mats[1], rel=1e-12)


# ----------------------------------------------------------------------------- command line
@pytest.fixture
def files(tmp_path):
    beam = tmp_path / "beam.json"
    beam.write_text(TAPERED.to_json())
    fit = tmp_path / "fit.json"
    fit.write_text(json.dumps(FIT))
    return tmp_path, str(beam), str(fit)


def test_cli_export_every_format(run, files):
    tmp, beam, fit = files
    for name, fmt in (("m.xml", "mjcf"), ("m.urdf", "urdf"), ("m.json", "json")):
        rc, out, err = run("export", beam, "--from", fit, "-o", tmp / name, "--json",
                           "--pose", 0)
        assert rc == 0, err
        rep = json.loads(out)
        assert rep["format"] == fmt and rep["pose"]["index"] == 0
        text = (tmp / name).read_text()
        assert text == {"mjcf": to_mjcf, "urdf": to_urdf, "json": to_json}[fmt](
            prbdm_from_fit(TAPERED, FIT))
    rc, out, err = run("export", beam, "--from", fit, "-o", "-", "--format", "urdf", "--pose", 3)
    assert rc == 0 and ET.fromstring(out.split("\n", 1)[1]).tag == "robot"


def test_cli_export_from_a_file_imports_no_torch(files):
    """Exporting a given result (no refit: a pose of its own, or its theta = 0 pose for 'rest') is
    NumPy only, for both stiffness laws: a fresh interpreter never imports torch."""
    tmp, beam, fit = files
    paper = tmp / "paper.json"
    paper.write_text(json.dumps({**LINEAR_FIT, "law": "paper", "k": [2.0e3]}))
    code = ("import sys; from prbdm import cli; rc = cli.main(sys.argv[1:]); "
            "assert 'torch' not in sys.modules, 'torch imported'; sys.exit(rc)")
    for args in (["--from", fit, "--pose", "2", "-o", str(tmp / "m.xml")],
                 ["--from", str(paper), "-o", str(tmp / "m.urdf")]):
        r = subprocess.run([sys.executable, "-c", code, "export", beam, *args],
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr


def test_cli_export_runs_the_fit_with_joints(run, files):
    tmp, beam, _ = files
    rc, out, err = run("export", beam, "--joints", 2, "--starts", 4, "--poses", "linear",
                       "--pose", "linear", "-o", tmp / "p.json", "--json")
    assert rc == 0, err
    rep = json.loads(out)
    assert rep["source"]["fit"] == "run here" and rep["pose"]["theta"] == [0, 0]
    desc = json.loads((tmp / "p.json").read_text())
    assert desc["joints"] == 2 and len(desc["bodies"]) == 3


def test_cli_export_carries_the_truths_shear_caveat(run, tmp_path):
    """The export checks the model against its result's truth, which cannot see what that truth
    leaves out: a thick strip's Euler-Bernoulli result (run here, or a saved `prbdm fit` or
    `prbdm predict` JSON) is exported with the shear caveat; a thin one's without."""
    thick = tmp_path / "thick.json"
    thick.write_text(json.dumps({"x": [0, 1], "half_width": [0.024, 0.012], "thickness": 0.03}))
    rc, out, err = run("export", thick, "--joints", 2, "--starts", 4, "-o", tmp_path / "a.json",
                       "--json")
    assert rc == 0, err
    assert any("leaves out shear" in w for w in json.loads(out)["warnings"])
    assert "leaves out shear" in err
    fit = tmp_path / "fit.json"
    fit.write_text(json.dumps({**FIT, "truth": "beam"}))        # a predict JSON names it so
    rc, out, err = run("export", thick, "--from", fit, "--ignore-fingerprint", "-o",
                       tmp_path / "b.json", "--json")
    assert rc == 0 and any("leaves out shear" in w for w in json.loads(out)["warnings"]), err
    thin = tmp_path / "thin.json"
    thin.write_text(json.dumps({"x": [0, 1], "half_width": [0.024, 0.012], "thickness": 0.004}))
    rc, out, err = run("export", thin, "--joints", 2, "--starts", 4, "-o", tmp_path / "c.json",
                       "--json")
    assert rc == 0 and not any("shear" in w for w in json.loads(out)["warnings"]), err


def test_cli_export_writes_atomically(run, files, monkeypatch):
    tmp, beam, fit = files
    target = tmp / "m.xml"
    target.write_text("previous")

    def fail(src, dst):
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(os, "replace", fail)
    rc, out, err = run("export", beam, "--from", fit, "-o", target)
    assert rc == 2 and err.count("\n") == 1 and "No space left" in err
    assert target.read_text() == "previous"
    assert sorted(p.name for p in tmp.iterdir()) == ["beam.json", "fit.json", "m.xml"]


def test_cli_export_file_permissions_follow_the_umask(run, files):
    """A new file gets 0o666 less the umask (0o644 under the usual 022), not mkstemp's 0o600."""
    tmp, beam, fit = files
    old = os.umask(0o022)
    try:
        rc, out, err = run("export", beam, "--from", fit, "-o", tmp / "m.xml")
        assert rc == 0, err
        assert (tmp / "m.xml").stat().st_mode & 0o777 == 0o644
        os.umask(0o027)
        rc, out, err = run("export", beam, "--from", fit, "-o", tmp / "m.urdf")
        assert rc == 0, err
        assert (tmp / "m.urdf").stat().st_mode & 0o777 == 0o640
    finally:
        os.umask(old)


def test_cli_export_refuses_a_missing_output_folder(run, files):
    tmp, beam, fit = files
    target = tmp / "no" / "such" / "m.xml"
    rc, out, err = run("export", beam, "--from", fit, "-o", target)
    assert rc == 2 and out == "" and err.count("\n") == 1 and "Traceback" not in err
    assert "-o/--output" in err and "does not exist" in err, err
    assert not (tmp / "no").exists()                 # no folder made on the way
    # refused before any fit is run: --joints fails as fast
    rc, out, err = run("export", beam, "--joints", 2, "--starts", 4, "-o", target)
    assert rc == 2 and "-o/--output" in err and not (tmp / "no").exists()


@pytest.mark.parametrize("args, message", [
    (["--from", "FIT", "-o", "x.txt"], "--format: not given"),
    (["--from", "FIT", "-o", "x.xml", "--pose", "9"], "--pose: must be 'rest', 'linear' or a pose index"),
    (["--from", "FIT", "-o", "x.xml", "--pose", "linear"], "--pose: 'linear' needs"),
    (["--from", "FIT", "-o", "x.xml", "--law", "paper"], "--law: a fit option"),
    (["--from", "nofile.json", "-o", "x.xml"], "--from: no such file"),
    (["--from", "BAD", "-o", "x.xml"], "--from: .* is not valid JSON"),
    (["--from", "OTHER", "-o", "x.xml"], "different beam"),
    (["--from", "FIT", "-o", "x.xml", "--damping", "-0.1"], "--damping"),
    (["--from", "FIT", "-o", "x.xml", "--format", "sdf"], "--format"),
    (["-o", "x.xml"], "one of the arguments --joints/-n --from is required"),
    (["--from", "FIT", "--joints", "3", "-o", "x.xml"], "not allowed with"),
    (["--from", "FIT", "-o", "-", "--format", "json", "--json"], "cannot be combined"),
    (["--from", "FIT", "-o", "x.xml", "--tolerance", "0"], "--tolerance"),
    (["--from", "FIT", "-o", "x.xml", "--tolerance", "nan"], "--tolerance"),
    (["--from", "FPBAD", "-o", "x.xml"], "beam_fingerprint must be a string"),
    (["--from", "FPOTHER", "-o", "x.xml"], "made for a different beam .*0123456789abcdef"),
])
def test_cli_export_bad_input(run, files, args, message):
    tmp, beam, fit = files
    (tmp / "bad.json").write_text("{not json")
    other = dict(FIT, links={"joint_x": [0.1, 0.2, 0.3]})
    (tmp / "other.json").write_text(json.dumps(other))
    (tmp / "fpbad.json").write_text(json.dumps(dict(FIT, beam_fingerprint=123)))
    (tmp / "fpother.json").write_text(json.dumps(dict(FIT, beam_fingerprint="0123456789abcdef")))
    subst = {"FIT": fit, "BAD": str(tmp / "bad.json"), "OTHER": str(tmp / "other.json"),
             "FPBAD": str(tmp / "fpbad.json"), "FPOTHER": str(tmp / "fpother.json")}
    args = [subst.get(a, a) for a in args]
    args = [str(tmp / a) if a.startswith("x.") else a for a in args]
    rc, out, err = run("export", beam, *args)
    assert rc == 2 and out == ""
    assert err.count("\n") == 1 and "Traceback" not in err
    import re
    assert re.search(message, err), err
    assert not any(p.name.startswith("x.") for p in tmp.iterdir())


# ----------------------------------------------------------------------------- checks before use
@pytest.fixture(scope="module")
def paper_fit():
    """A 3R fit of TAPERED for the paper's poses (none at theta = 0), as prbdm fit --json."""
    from prbdm.export import run_fit

    return run_fit(TAPERED, 3, starts=8)


@pytest.fixture
def paper_files(tmp_path, paper_fit):
    beam = tmp_path / "beam.json"
    beam.write_text(TAPERED.to_json())
    fit = tmp_path / "fit.json"
    fit.write_text(json.dumps(paper_fit))
    return tmp_path, str(beam), str(fit)


def test_cli_export_refits_a_paper_pose_fit_at_rest_without_fem(run, paper_files, paper_fit,
                                                               monkeypatch):
    import prbdm.truth

    tmp, beam, fit = paper_files
    # the refit uses the result's own omega_truth: any truth solve here would be a bug
    monkeypatch.setattr(prbdm.truth, "bending_frequencies",
                        lambda *a, **k: pytest.fail("a truth solve ran during export"))
    rc, out, err = run("export", beam, "--from", fit, "-o", tmp / "m.json", "--json")
    assert rc == 0, err
    rep = json.loads(out)
    assert rep["pose"]["theta"] == [0, 0, 0] and rep["pose"]["springref"] == "pose"
    refit = rep["refit"]
    assert refit["truth"] == "omega_truth" and refit["poses_given"] == paper_fit["poses"]
    assert refit["gamma"] != paper_fit["gamma"] and len(refit["k"]) == 1
    # 3 modes, 4 parameters: the small-vibration model matches the truth
    assert rep["check"]["ok"] and rep["check"]["modes"] == 3
    assert rep["check"]["max_error"] < 1e-6
    assert np.asarray(rep["omega"]) == pytest.approx(paper_fit["omega_truth"][:3], rel=1e-6)
    assert rep["warnings"] == [] and err == ""
    assert rep["beam_fingerprint"]["match"] is True
    desc = json.loads((tmp / "m.json").read_text())
    assert desc["gamma"] == pytest.approx(refit["gamma"], rel=1e-12)


def test_cli_export_warns_when_the_exported_model_is_off(run, paper_files, paper_fit):
    tmp, beam, fit = paper_files
    # pose 0's SCF at rest straight: the paper fit's stiffness for a deflected pose
    rc, out, err = run("export", beam, "--from", fit, "-o", tmp / "m.xml", "--json",
                       "--pose", 0, "--springref", "zero")
    assert rc == 0, err
    rep = json.loads(out)
    desc = prbdm_from_fit(TAPERED, paper_fit, pose=0, springref="zero")
    expected = np.asarray(desc["omega"][:3]) / np.asarray(paper_fit["omega_truth"][:3]) - 1
    assert rep["refit"] is None and not rep["check"]["ok"]
    assert rep["check"]["error"] == pytest.approx(expected, rel=1e-12)
    bad = [j + 1 for j, e in enumerate(expected) if abs(e) > 0.05]
    assert bad and len(rep["warnings"]) == len(bad)
    for j, w in zip(bad, rep["warnings"]):
        assert w.startswith(f"mode {j}:") and f"{100 * abs(expected[j - 1]):.3g} %" in w
        assert "--poses linear" in w and "--objective frequency" in w
        assert w in err                                # on stderr as well
    # a looser tolerance silences it; the check is still reported
    rc, out, err = run("export", beam, "--from", fit, "-o", tmp / "m.xml", "--json",
                       "--pose", 0, "--springref", "zero", "--tolerance", 100)
    rep = json.loads(out)
    assert rc == 0 and rep["warnings"] == [] and rep["check"]["ok"]
    assert rep["check"]["tolerance"] == 1.0
    # the pose's own model (springs at rest at the pose) is checked about that pose
    rc, out, err = run("export", beam, "--from", fit, "-o", tmp / "m.xml", "--json",
                       "--pose", 0)
    rep = json.loads(out)
    ref = np.asarray(paper_fit["freq_error"][0])
    assert np.abs(rep["check"]["error"]) == pytest.approx(ref, rel=1e-6, abs=1e-12)


def test_cli_export_refuses_a_result_for_another_beam(run, paper_files, paper_fit):
    from prbdm.fingerprint import beam_fingerprint

    tmp, beam, fit = paper_files
    other = Beam(x=TAPERED.x, half_width=TAPERED.half_width, thickness=0.021)
    (tmp / "other.json").write_text(other.to_json())
    rc, out, err = run("export", str(tmp / "other.json"), "--from", fit, "-o", tmp / "x.xml")
    ours, theirs = beam_fingerprint(other), paper_fit["beam_fingerprint"]
    assert rc == 2 and out == "" and err.count("\n") == 1 and "Traceback" not in err
    assert ours in err and theirs in err and "--ignore-fingerprint" in err
    assert not (tmp / "x.xml").exists()
    # told to, it applies the result, checked against the other beam's own truth
    rc, out, err = run("export", str(tmp / "other.json"), "--from", fit, "-o", tmp / "x.xml",
                       "--json", "--ignore-fingerprint")
    assert rc == 0, err
    rep = json.loads(out)
    assert rep["beam_fingerprint"] == {"beam": ours, "result": theirs, "match": False,
                                       "ignored": True}
    assert rep["refit"]["truth"].startswith("beam (Euler-Bernoulli FEM")
    assert any("a different beam" in w for w in rep["warnings"])
    # a result without a fingerprint is used, with a warning
    (tmp / "old.json").write_text(json.dumps({k: v for k, v in paper_fit.items()
                                              if k != "beam_fingerprint"}))
    rc, out, err = run("export", beam, "--from", tmp / "old.json", "-o", tmp / "y.xml", "--json")
    assert rc == 0 and "carries no beam_fingerprint" in err
    assert json.loads(out)["beam_fingerprint"]["match"] is None


def test_cli_export_with_joints_fits_the_linear_pose_by_default(run, files):
    tmp, beam, _ = files
    rc, out, err = run("export", beam, "--joints", 2, "--starts", 4, "-o", tmp / "p.json",
                       "--json")
    assert rc == 0, err
    rep = json.loads(out)
    assert rep["refit"] is None and rep["pose"]["theta"] == [0, 0]
    assert json.loads((tmp / "p.json").read_text())["pose"]["poses"] == [[0, 0]]
    assert rep["check"]["ok"] and rep["warnings"] == []
