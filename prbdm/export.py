"""A PRBDM in the user's simulator: MJCF (MuJoCo), URDF and a plain JSON of physical parameters.

Two steps, so that any source of a PRBDM can feed the writers:

1. :func:`prbdm_from_fit` turns ``{gamma, k, law, poses}`` (what ``prbdm fit --json`` prints;
   later also what the trained network predicts) and the beam into a *description*: a plain,
   JSON-ready dict of bodies, hinges and SI parameters. No file format is involved yet.
2. :func:`to_mjcf`, :func:`to_urdf`, :func:`to_json` write a description in one format;
   :func:`export` does both steps and writes the file atomically.

Conventions (docs/export.md has the full list):

- Frames: x along the beam (clamp at the origin), z normal to the panel, deflection in the x-z
  plane. Link 0 is welded to the world; link j's body frame sits at joint j, its x axis along the
  link. Hinge axes are ``(0, -1, 0)``, so a positive joint angle lifts the tip towards +z (the
  PRBDM's angles, measured from x towards z).
- Stiffness: hinge j has ``K_j = k_i s_j`` [N m/rad] with the SCF ``k_i`` of the chosen pose
  ``i``. The spring reference (``springref``) is the pose's angles by default, so that the
  exported chain at rest *is* the PRBDM at pose i and its small vibrations have exactly the
  PRBDM's frequencies at that pose; ``springref="zero"`` puts the rest at the straight beam
  instead (same stiffness).
- Inertia: each link is a thin lamina in its x-y plane. About the centre of mass, in body axes:
  ``I_yy = J_j`` (exactly the PRBDM's rotary inertia: bending plane, docs/conventions.md §3),
  ``I_xx = ∫ y^2 dm`` (rolling about the link axis; ``rho t ∫ (2/3) w^3 dx``),
  ``I_zz = I_xx + I_yy`` (perpendicular axis theorem). The section's own ``m t^2 / 12`` is
  dropped on every axis, as the PRBDM drops
  it from J. Products of inertia vanish (symmetry about x; lamina in z = 0).
- Damping (optional): a damping ratio ``zeta`` becomes stiffness-proportional joint damping
  ``d_j = (2 zeta / omega_1) K_j``: ratio ``zeta`` on the first mode, ``zeta omega_r / omega_1``
  on mode r. K is diagonal, so this is plain per-joint viscous damping.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from .errors import BadInput
from .signals import zero_crossing_period

__all__ = ["FORMATS", "AXIS", "prbdm_from_fit", "run_fit", "load_fit", "to_mjcf", "to_urdf",
           "to_json", "export", "format_from_path", "plate_integrals", "URDF_NS",
           "mujoco_linear_frequencies", "mujoco_free_vibration"]

FORMATS = ("mjcf", "urdf", "json")
SUFFIXES = {".xml": "mjcf", ".mjcf": "mjcf", ".urdf": "urdf", ".json": "json"}
#: hinge axis in every body frame: positive angles rotate x towards +z
AXIS = (0.0, -1.0, 0.0)
#: XML namespace of the URDF extension tag ``<prbdm:spring>``
URDF_NS = "https://prbdm.readthedocs.io/export/urdf-spring"
DESCRIPTION_FORMAT = "prbdm-physical"
DESCRIPTION_VERSION = 1
GAMMA_SUM_TOL = 1e-6
#: relative tolerance on a FIT.json's link positions against the beam they are applied to
LINK_MATCH_RTOL = 1e-6


# ----------------------------------------------------------------------------- sources
def run_fit(beam, joints: int, *, modes: int | None = None, law: str = "beam", poses="paper",
            starts: int | None = None, seed: int = 0, truth: str = "auto") -> dict:
    """Fit a PRBDM to ``beam`` (truth + multistart fit) and return what ``prbdm fit --json``
    prints: :meth:`prbdm.fit.FitResult.to_dict` plus ``truth`` and ``links``. ``truth``: a truth
    model, or ``auto`` (:func:`prbdm.truth.choice.choose_truth`: the plate for a wide panel)."""
    import torch

    from .fingerprint import beam_fingerprint
    from .fit import fit_prbdm
    from .model import BeamTensors, links_from_gamma
    from .truth import bending_frequencies, modes_for_fit
    from .truth.choice import choose_truth

    r = modes or joints
    model, reason = choose_truth(beam, truth)
    tr = bending_frequencies(beam, model=model, modes=modes_for_fit(model, joints, r))
    res = fit_prbdm(beam, tr.omega, joints=joints, modes=r, law=law, poses=poses,
                    starts=starts, seed=seed)
    bt = BeamTensors.from_beams(beam)
    with torch.no_grad():
        links = links_from_gamma(bt, torch.as_tensor(res.gamma)).physical(bt)
    out = res.to_dict()
    out["truth"] = {"model": tr.model, "time_s": tr.time_s, "reason": reason}
    out["links"] = {key: v.tolist() for key, v in links.items()}
    out["beam_fingerprint"] = beam_fingerprint(beam)
    return out


def load_fit(source) -> dict:
    """A fit dictionary from a path (the JSON that ``prbdm fit --json`` prints), ``'-'`` for
    standard input, or a dict (returned as is)."""
    if isinstance(source, dict):
        return source
    if str(source) == "-":
        import sys

        text, label = sys.stdin.read(), "standard input"
    else:
        path = Path(source)
        if not path.is_file():
            raise BadInput(f"--from: no such file {str(source)!r}")
        try:
            text = path.read_text()
        except (OSError, UnicodeDecodeError) as exc:
            raise BadInput(f"--from: cannot read {str(source)!r} ({exc})") from None
        label = str(source)
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise BadInput(f"--from: {label} is not valid JSON ({exc.msg} at line {exc.lineno})") \
            from None
    if not isinstance(data, dict):
        raise BadInput(f"--from: {label} must hold a JSON object (the output of prbdm fit --json)")
    return data


def _numbers(value, name, ndim):
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise BadInput(f"fit: {name} must be {'a list' if ndim == 1 else 'a list of lists'} "
                       "of numbers") from None
    if arr.ndim != ndim or arr.size == 0:
        raise BadInput(f"fit: {name} must be {'a list' if ndim == 1 else 'a list of lists'} "
                       f"of numbers, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise BadInput(f"fit: all values of {name} must be finite")
    return arr


def check_fit(fit: dict):
    """(gamma, k, law, poses) of a fit dictionary, validated; BadInput naming the key."""
    from .model import GAMMA_MAX, GAMMA_MIN, LAWS

    if not isinstance(fit, dict):
        raise BadInput("fit: must be a dict with keys gamma, k, law, poses")
    missing = [key for key in ("gamma", "k", "poses") if key not in fit]
    if missing:
        raise BadInput(f"fit: missing key {missing[0]!r} (need gamma, k, law, poses, as printed by "
                       "prbdm fit --json)")
    gamma = _numbers(fit["gamma"], "gamma", 1)
    n = gamma.size - 1
    if n < 1:
        raise BadInput(f"fit: gamma needs n + 1 >= 2 link fractions, got {gamma.size}")
    if np.any(gamma <= 0):
        raise BadInput("fit: every gamma must be > 0")
    total = math.fsum(gamma)
    if abs(total - 1.0) > GAMMA_SUM_TOL:
        raise BadInput(f"fit: gamma must sum to 1 (within {GAMMA_SUM_TOL:g}), got {total:.9g}")
    gamma = gamma / total
    if np.any(gamma < GAMMA_MIN * (1 - 1e-9)) or np.any(gamma > GAMMA_MAX * (1 + 1e-9)):
        raise BadInput(f"fit: every gamma must lie in [{GAMMA_MIN}, {GAMMA_MAX}] (Eq. 13)")
    law = fit.get("law", "beam")
    if law not in LAWS:
        raise BadInput(f"fit: law must be one of {', '.join(LAWS)}, got {law!r}")
    poses = _numbers(fit["poses"], "poses", 2)
    if poses.shape[1] != n:
        raise BadInput(f"fit: poses must be m lists of n = {n} angles (one per joint), got "
                       f"shape {poses.shape}")
    k = _numbers(fit["k"], "k", 1)
    if k.size != poses.shape[0]:
        raise BadInput(f"fit: k needs one SCF per pose ({poses.shape[0]}), got {k.size}")
    if np.any(k <= 0):
        raise BadInput("fit: every SCF k must be > 0")
    return gamma, k, law, poses


def _pick_pose(poses: np.ndarray, pose) -> int:
    """Index of the exported pose: None -> 0 (the first; the only one of a linear fit);
    an integer index; or 'linear' / 'rest' -> the pose with every angle 0 (here refused for a fit
    without one: :func:`prbdm.preflight.prepare` refits such a fit at rest first)."""
    m = poses.shape[0]
    if pose is None:
        return 0
    if isinstance(pose, str):
        text = pose.strip()
        if text in ("linear", "rest"):
            zero = np.flatnonzero(np.all(poses == 0.0, axis=1))
            if zero.size == 0:
                raise BadInput(f"--pose: {text!r} needs a fit with the linear pose (theta = 0, "
                               "prbdm fit --poses linear); this fit's poses start at theta = "
                               f"{poses[0, 0]:g} rad")
            return int(zero[0])
        try:
            pose = int(text)
        except ValueError:
            raise BadInput(f"--pose: must be 'rest', 'linear' or a pose index in [0, {m - 1}], "
                           f"got {text!r}") from None
    if isinstance(pose, bool) or not isinstance(pose, (int, np.integer)) or not 0 <= pose < m:
        raise BadInput(f"--pose: must be 'rest', 'linear' or a pose index in [0, {m - 1}], "
                       f"got {pose!r}")
    return int(pose)


# ----------------------------------------------------------------------------- integrals
def plate_integrals(beam, a: float, b: float) -> dict:
    """Exact lamina integrals of the span [a, b] [m] of ``beam``, independent of the torch code.

    Returns mass [kg], ``com`` (centre of mass, m from ``a``), ``J`` = ∫ (x - x_c)^2 dm and
    ``Ixx`` = ∫ y^2 dm [kg m^2]. On each piece between stations the half-width is linear and the
    integrands are polynomials of degree <= 3, which 3-point Gauss-Legendre integrates exactly;
    moments are taken about ``a`` (no cancellation far from the root).
    """
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
    ixx = rho_t * np.sum(wq * 2.0 / 3.0 * w ** 3)
    com = first / mass
    return {"mass": float(mass), "com": float(com), "J": float(second - first * com),
            "Ixx": float(ixx), "mean_half_width": float(mass / (2 * rho_t * (b - a)))}


# ----------------------------------------------------------------------------- description
def prbdm_from_fit(beam, fit: dict, pose=None, springref: str = "pose",
                   damping: float = 0.0) -> dict:
    """Plain description of a PRBDM in SI units, ready for :func:`to_mjcf` / :func:`to_urdf` /
    :func:`to_json`.

    beam: :class:`prbdm.geometry.Beam`. fit: a dict with ``gamma`` (n+1), ``k`` (m), ``poses``
    (m lists of n angles, rad) and ``law`` (default 'beam') -- what ``prbdm fit --json`` prints,
    or any other source of a PRBDM (the trained network) in the same keys. If the dict carries
    ``links`` (as ``prbdm fit --json`` does), its joint positions must match this beam.
    pose: which pose's SCF the springs use: None (the first pose; the only one of a linear fit),
    an index, or 'linear' (the theta = 0 pose). springref: 'pose' (springs at rest at the pose's
    angles: small vibrations about the rest have the PRBDM's frequencies at that pose) or 'zero'
    (at rest straight). damping: damping ratio zeta >= 0 of the first mode (stiffness-
    proportional joint damping, module docstring).

    Returns a JSON-ready dict: ``beam``, ``joints`` (n), ``law``, ``gamma``, ``pose`` (index,
    theta, k, springref), ``links`` (exactly :meth:`prbdm.model.Links.physical`), ``bodies``
    (links 0..n: parent, position in the parent frame, mass, centre, diagonal inertia about the
    centre), ``hinges`` (joints 1..n: axis, stiffness, springref, damping, base stiffness),
    ``omega`` / ``freq_hz`` (small-vibration frequencies about the spring reference),
    ``damping_ratio``, ``conventions`` and ``units``.
    """
    import torch

    from .geometry import Beam
    from .model import BeamTensors, base_stiffness, eigenvalues, links_from_gamma

    if not isinstance(beam, Beam):
        raise BadInput(f"beam: must be a prbdm.geometry.Beam, got {type(beam).__name__}")
    gamma, k, law, poses = check_fit(fit)
    i = _pick_pose(poses, pose)
    if springref not in ("pose", "zero"):
        raise BadInput(f"--springref: must be 'pose' or 'zero', got {springref!r}")
    if isinstance(damping, bool) or not isinstance(damping, (int, float)) \
            or not math.isfinite(damping) or damping < 0:
        raise BadInput(f"--damping: must be a damping ratio >= 0, got {damping!r}")
    n = gamma.size - 1
    bt = BeamTensors.from_beams(beam)
    g = torch.as_tensor(gamma)
    with torch.no_grad():
        links = links_from_gamma(bt, g)
        phys = {key: v.numpy().copy() for key, v in links.physical(bt).items()}
        scale = float(bt.rho * bt.thickness * bt.length ** 4 * bt.lambda0)   # N m/rad
        s_si = base_stiffness(bt, links, law).numpy() * scale
    _check_links_match(fit, phys)
    theta_pose = poses[i]
    ref = theta_pose.copy() if springref == "pose" else np.zeros(n)
    with torch.no_grad():
        lam = eigenvalues(bt, g, torch.tensor([float(k[i])], dtype=torch.float64),
                          poses=torch.as_tensor(ref[None, :]), law=law)[0].numpy()
    omega = np.sqrt(lam)
    stiffness = float(k[i]) * s_si
    joint_damping = 2.0 * float(damping) / omega[0] * stiffness

    L = beam.length
    cuts = np.concatenate([[0.0], phys["joint_x"], [L]])
    bodies = []
    for j in range(n + 1):
        a, b = float(cuts[j]), float(cuts[j + 1])
        lam_int = plate_integrals(beam, a, b)
        if j == 0:
            mass, com, iyy = lam_int["mass"], lam_int["com"], lam_int["J"]
        else:   # the PRBDM's own numbers, exactly
            mass = float(phys["mass"][j - 1])
            com = float(phys["com"][j - 1])
            iyy = float(phys["inertia"][j - 1])
        ixx = lam_int["Ixx"]
        bodies.append({
            "name": f"link_{j}",
            "parent": "world" if j == 0 else f"link_{j - 1}",
            "joint": None if j == 0 else f"joint_{j}",
            "pos": [0.0 if j == 0 else (a if j == 1 else float(phys["length"][j - 1])), 0.0, 0.0],
            "x_start": a, "length": float(phys["length"][j]),
            "mass": mass, "com": [com, 0.0, 0.0], "inertia": [ixx, iyy, ixx + iyy],
            "mean_half_width": lam_int["mean_half_width"]})
    hinges = [{"name": f"joint_{j}", "parent": f"link_{j - 1}", "child": f"link_{j}",
               "x": float(cuts[j]), "axis": list(AXIS),
               "stiffness": float(stiffness[j - 1]), "springref": float(ref[j - 1]),
               "damping": float(joint_damping[j - 1]),
               "base_stiffness": float(s_si[j - 1])} for j in range(1, n + 1)]
    return {
        "format": DESCRIPTION_FORMAT, "version": DESCRIPTION_VERSION,
        "beam": {**beam.to_dict(), "length": L, "mass": beam.mass},
        "source": str(fit.get("source", "fit")),
        "joints": n, "law": law, "gamma": gamma.tolist(),
        "pose": {"index": i, "theta": theta_pose.tolist(), "k": float(k[i]),
                 "springref": springref, "poses": poses.tolist(), "k_all": k.tolist()},
        "links": {key: v.tolist() for key, v in phys.items()},
        "bodies": bodies, "hinges": hinges,
        "omega": omega.tolist(), "freq_hz": (omega / (2 * math.pi)).tolist(),
        "damping_ratio": float(damping),
        "conventions": {
            "frame": "x along the beam from the clamp, z normal to the panel, deflection in the "
                     "x-z plane; link 0 welded to the world; link j's body frame at joint j, "
                     "x along the link",
            "axis": "hinges about (0, -1, 0): a positive angle lifts the tip towards +z",
            "stiffness": "K_j = k_i s_j [N m/rad], k_i the SCF of the chosen pose",
            "springref": "spring rest angles: the pose's angles ('pose') or 0 ('zero')",
            "inertia": "thin lamina, diagonal about the centre of mass in body axes: "
                       "I_yy = J (the PRBDM's), I_xx = int y^2 dm, I_zz = I_xx + I_yy",
            "damping": "d_j = 2 zeta K_j / omega_1 (stiffness-proportional)",
            "omega": "small-vibration frequencies about the spring reference"},
        "units": {"length": "m", "mass": "kg", "inertia": "kg m^2", "angle": "rad",
                  "stiffness": "N m/rad", "damping": "N m s/rad", "omega": "rad/s",
                  "freq_hz": "Hz"},
    }


def check_fit_links(beam, fit: dict) -> None:
    """BadInput unless the ``links.joint_x`` a fit dict carries (as ``prbdm fit --json`` prints)
    are this beam's cuts at its gamma: a FIT.json applied to a different panel."""
    import torch

    from .model import BeamTensors, links_from_gamma

    gamma = check_fit(fit)[0]
    bt = BeamTensors.from_beams(beam)
    with torch.no_grad():
        phys = {key: v.numpy() for key, v in
                links_from_gamma(bt, torch.as_tensor(gamma)).physical(bt).items()}
    _check_links_match(fit, phys)


def _check_links_match(fit, phys):
    links = fit.get("links")
    if not isinstance(links, dict) or "joint_x" not in links:
        return
    try:
        given = np.asarray(links["joint_x"], dtype=float)
    except (TypeError, ValueError):
        raise BadInput("fit: links.joint_x must be a list of numbers") from None
    ours = phys["joint_x"]
    L = float(phys["length"].sum())
    if given.shape != ours.shape or not np.allclose(given, ours, rtol=0, atol=LINK_MATCH_RTOL * L):
        raise BadInput("fit: its links.joint_x do not match this beam's cuts at gamma (the fit "
                       "was made for a different beam?)")


# ----------------------------------------------------------------------------- writers
def _f(v) -> str:
    """A float as XML text, round-tripping exactly."""
    v = float(v)
    if v == int(v) and abs(v) < 1e15:
        return str(int(v))
    return repr(v)


def _vec(vs) -> str:
    return " ".join(_f(v) for v in vs)


def _model_name(desc) -> str:
    name = desc["beam"].get("name") or "beam"
    return f"{desc['joints']}R-PRBDM of {name}"


def _header(desc) -> str:
    p = desc["pose"]
    return (f" generated by prbdm: {_model_name(desc)}; law {desc['law']}; pose {p['index']} "
            f"(theta {_vec(p['theta'])} rad), SCF k = {_f(p['k'])}; springs at rest at "
            f"{'the pose' if p['springref'] == 'pose' else 'theta = 0'}; hinges about (0 -1 0), "
            f"positive angles lift the tip to +z; inertias of thin laminae (docs/export.md) ")


def _suggested_timestep(desc) -> float:
    # a hundred steps per period of the highest mode, at most MuJoCo's default 2 ms
    dt = min(0.002, 2 * math.pi / max(desc["omega"]) / 100)
    return float(f"{dt:.3g}")


def to_mjcf(desc: dict) -> str:
    """MuJoCo MJCF text of a description: nested bodies with explicit inertials, hinge joints with
    ``stiffness``, ``springref`` and ``damping``, box geoms for display only (no contacts, no
    mass), a ``tip`` site, and a keyframe ``rest`` at the spring reference. Gravity is MuJoCo's
    default (0 0 -9.81, along -z); the integrator RK4 at a hundredth of the shortest period."""
    import xml.etree.ElementTree as ET

    root = ET.Element("mujoco", model=_model_name(desc))
    root.append(ET.Comment(_header(desc)))
    ET.SubElement(root, "compiler", angle="radian", inertiafromgeom="false", autolimits="true")
    ET.SubElement(root, "option", timestep=_f(_suggested_timestep(desc)), integrator="RK4",
                  gravity="0 0 -9.81")
    default = ET.SubElement(root, "default")
    ET.SubElement(default, "geom", contype="0", conaffinity="0", rgba="0.62 0.66 0.72 1")
    parent = ET.SubElement(root, "worldbody")
    t = desc["beam"]["thickness"]
    hinge = {h["child"]: h for h in desc["hinges"]}
    for body in desc["bodies"]:
        el = ET.SubElement(parent, "body", name=body["name"], pos=_vec(body["pos"]))
        h = hinge.get(body["name"])
        if h is not None:
            ET.SubElement(el, "joint", name=h["name"], type="hinge", pos="0 0 0",
                          axis=_vec(h["axis"]), stiffness=_f(h["stiffness"]),
                          springref=_f(h["springref"]), damping=_f(h["damping"]))
        ET.SubElement(el, "inertial", pos=_vec(body["com"]), mass=_f(body["mass"]),
                      diaginertia=_vec(body["inertia"]))
        ET.SubElement(el, "geom", name=f"{body['name']}_plate", type="box",
                      pos=_vec([body["length"] / 2, 0, 0]),
                      size=_vec([body["length"] / 2, body["mean_half_width"], t / 2]))
        parent = el
    ET.SubElement(parent, "site", name="tip", pos=_vec([desc["bodies"][-1]["length"], 0, 0]))
    keyframe = ET.SubElement(root, "keyframe")
    ET.SubElement(keyframe, "key", name="rest", qpos=_vec(h["springref"] for h in desc["hinges"]))
    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="unicode") + "\n"


def to_urdf(desc: dict) -> str:
    """URDF text of a description: a ``world`` link, a fixed joint ``clamp`` to ``link_0``,
    links with ``<inertial>`` (origin at the centre of mass, diagonal inertia), revolute joints
    about (0 -1 0) with ``<dynamics damping>``. URDF has no field for a joint spring; it goes in
    two places: the extension tag ``<prbdm:spring stiffness=".." reference=".."/>`` inside each
    joint (namespace :data:`URDF_NS`; URDF parsers ignore unknown elements), and a Gazebo/SDFormat
    extension ``<gazebo reference="joint_j"><springStiffness/><springReference/></gazebo>``, which
    the URDF-to-SDFormat converter turns into ``axis/dynamics/spring_stiffness`` and
    ``spring_reference``. Joint limits are placeholders that URDF requires (+-pi/2 rad, effort 0:
    passive, velocity 1e9)."""
    import xml.etree.ElementTree as ET

    ET.register_namespace("prbdm", URDF_NS)
    root = ET.Element("robot", name=_model_name(desc))
    root.append(ET.Comment(_header(desc)))
    ET.SubElement(root, "link", name="world")
    clamp = ET.SubElement(root, "joint", name="clamp", type="fixed")
    ET.SubElement(clamp, "parent", link="world")
    ET.SubElement(clamp, "child", link="link_0")
    ET.SubElement(clamp, "origin", xyz="0 0 0", rpy="0 0 0")
    t = desc["beam"]["thickness"]
    hinge = {h["child"]: h for h in desc["hinges"]}
    for body in desc["bodies"]:
        h = hinge.get(body["name"])
        if h is not None:
            j = ET.SubElement(root, "joint", name=h["name"], type="revolute")
            ET.SubElement(j, "parent", link=h["parent"])
            ET.SubElement(j, "child", link=h["child"])
            ET.SubElement(j, "origin", xyz=_vec(body["pos"]), rpy="0 0 0")
            ET.SubElement(j, "axis", xyz=_vec(h["axis"]))
            ET.SubElement(j, "limit", lower=_f(-math.pi / 2), upper=_f(math.pi / 2), effort="0",
                          velocity="1e9")
            ET.SubElement(j, "dynamics", damping=_f(h["damping"]), friction="0")
            ET.SubElement(j, f"{{{URDF_NS}}}spring", stiffness=_f(h["stiffness"]),
                          reference=_f(h["springref"]), unit="N m/rad")
        link = ET.SubElement(root, "link", name=body["name"])
        inertial = ET.SubElement(link, "inertial")
        ET.SubElement(inertial, "origin", xyz=_vec(body["com"]), rpy="0 0 0")
        ET.SubElement(inertial, "mass", value=_f(body["mass"]))
        ixx, iyy, izz = body["inertia"]
        ET.SubElement(inertial, "inertia", ixx=_f(ixx), ixy="0", ixz="0", iyy=_f(iyy), iyz="0",
                      izz=_f(izz))
        visual = ET.SubElement(link, "visual")
        ET.SubElement(visual, "origin", xyz=_vec([body["length"] / 2, 0, 0]), rpy="0 0 0")
        geometry = ET.SubElement(visual, "geometry")
        ET.SubElement(geometry, "box", size=_vec([body["length"], 2 * body["mean_half_width"], t]))
    for h in desc["hinges"]:
        gz = ET.SubElement(root, "gazebo", reference=h["name"])
        ET.SubElement(gz, "springStiffness").text = _f(h["stiffness"])
        ET.SubElement(gz, "springReference").text = _f(h["springref"])
    ET.indent(root, space="  ")
    return '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def to_json(desc: dict) -> str:
    """The description itself, as JSON."""
    return json.dumps(desc, indent=1, allow_nan=False) + "\n"


WRITERS = {"mjcf": to_mjcf, "urdf": to_urdf, "json": to_json}


def format_from_path(path) -> str:
    suffix = Path(str(path)).suffix.lower()
    if suffix not in SUFFIXES:
        raise BadInput(f"--format: not given and the suffix of {str(path)!r} does not tell "
                       f"(.xml/.mjcf -> mjcf, .urdf -> urdf, .json -> json)")
    return SUFFIXES[suffix]


def export(beam, fit: dict, fmt: str, path=None, **options) -> str:
    """Describe (:func:`prbdm_from_fit`, ``options`` go there) and write in format ``fmt``;
    returns the text, and writes it to ``path`` atomically when given (no half-written file)."""
    if fmt not in FORMATS:
        raise BadInput(f"--format: must be one of {', '.join(FORMATS)}, got {fmt!r}")
    text = WRITERS[fmt](prbdm_from_fit(beam, fit, **options))
    if path is not None:
        from .files import atomic_write

        try:
            atomic_write(path, text)
        except OSError as exc:
            raise BadInput(f"-o: cannot write {str(path)!r} ({exc.strerror or exc})") from None
    return text


# ----------------------------------------------------------------------------- MuJoCo checks
def mujoco_linear_frequencies(xml: str, qpos=None):
    """Small-vibration frequencies [rad/s] of an MJCF chain of spring hinges about ``qpos``
    (default: the ``rest`` keyframe, i.e. the spring reference): mass matrix from
    ``mujoco.mj_fullM`` at that pose, stiffness from ``model.jnt_stiffness``. Needs mujoco."""
    import mujoco
    from scipy.linalg import eigh

    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    data.qpos[:] = model.qpos_spring if qpos is None else qpos
    mujoco.mj_forward(model, data)
    M = np.zeros((model.nv, model.nv))
    if hasattr(data, "qM"):                 # MuJoCo 3: mj_fullM(m, dst, qM)
        mujoco.mj_fullM(model, M, data.qM)
    else:                                   # MuJoCo 4: mj_fullM(m, d, dst)
        mujoco.mj_fullM(model, data, M)
    K = np.diag(model.jnt_stiffness.copy())
    lam, vec = eigh(K, M)
    return np.sqrt(lam), vec


def mujoco_free_vibration(xml: str, amplitude: float = 1e-4, periods: float = 10.0,
                          steps_per_period: int = 200, mode: int = 0):
    """Free vibration in MuJoCo: gravity off, no damping, released from the spring reference
    plus ``amplitude`` (rad, largest joint) times linear mode ``mode``; RK4 with
    ``steps_per_period`` steps per period of the highest mode. Returns (t, q_tip_angle_sum,
    measured omega of the tracked mode by zero crossings, predicted omega)."""
    import mujoco

    omega, vec = mujoco_linear_frequencies(xml)
    model = mujoco.MjModel.from_xml_string(xml)
    model.opt.gravity[:] = 0.0
    model.dof_damping[:] = 0.0
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
    model.opt.timestep = 2 * math.pi / omega.max() / steps_per_period
    data = mujoco.MjData(model)
    v = vec[:, mode] / np.abs(vec[:, mode]).max()
    data.qpos[:] = model.qpos_spring + amplitude * v
    steps = int(math.ceil(periods * 2 * math.pi / omega[mode] / model.opt.timestep))
    y = np.empty(steps + 1)
    w = v / (v @ v)                         # the mode's coordinate of the joint deflection
    y[0] = (data.qpos - model.qpos_spring) @ w
    for s in range(steps):
        mujoco.mj_step(model, data)
        y[s + 1] = (data.qpos - model.qpos_spring) @ w
    t = np.arange(steps + 1) * model.opt.timestep
    return t, y, 2 * math.pi / zero_crossing_period(t, y), float(omega[mode])
