"""The description of a PRBDM: bodies, hinges and SI parameters of the chain a fit result makes
of a beam (:func:`prbdm_from_fit`), in no file format yet; conventions in :mod:`prbdm.export`.

Every number comes from the chain's one home, :mod:`prbdm.chain` (NumPy, no torch): the link
table, the base stiffness of either law, the small-vibration eigenvalues, and the lamina
integrals of the clamped root link 0 and of every link's roll inertia ``I_xx``
(:func:`prbdm.chain.span_integrals`), each span integrated on its own (``direct``: round-off,
the torch twin's numbers to about 1e-15). tests/test_export.py checks the bodies against an
independent Gauss-Legendre quadrature."""
from __future__ import annotations

import math

import numpy as np

from ..errors import BadInput
from .fits import check_fit, check_links_match

#: hinge axis in every body frame: positive angles rotate x towards +z
AXIS = (0.0, -1.0, 0.0)
DESCRIPTION_FORMAT = "prbdm-physical"
DESCRIPTION_VERSION = 1


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
    theta, k, springref), ``links`` (:func:`prbdm.chain.link_table`'s ``joint_x``, ``length``,
    ``mass``, ``com``, ``inertia``, ``area_moment``), ``bodies``
    (links 0..n: parent, position in the parent frame, mass, centre, diagonal inertia about the
    centre), ``hinges`` (joints 1..n: axis, stiffness, springref, damping, base stiffness),
    ``omega`` / ``freq_hz`` (small-vibration frequencies about the spring reference),
    ``damping_ratio``, ``conventions`` and ``units``.
    """
    from ..chain import BeamBatch, link_table, prbdm_eigenvalues, span_integrals
    from ..geometry import Beam

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
    bb = BeamBatch.from_beams(beam)
    table = link_table(bb, gamma[None], law=law, direct=True)
    s_si = table.pop("base_stiffness")[0]                               # N m/rad
    phys = {key: v[0] for key, v in table.items()}
    check_links_match(fit, phys)
    theta_pose = poses[i]
    ref = theta_pose.copy() if springref == "pose" else np.zeros(n)
    lam_unit = prbdm_eigenvalues(bb.x, bb.w, gamma[None], ref[None, :], law=law, batch=bb,
                                 direct=True)[0, 0]
    omega = np.sqrt(lam_unit * bb.lambda0[0] * float(k[i]))
    stiffness = float(k[i]) * s_si
    joint_damping = 2.0 * float(damping) / omega[0] * stiffness

    L = beam.length
    cuts = np.concatenate([[0.0], phys["joint_x"], [L]])
    # the lamina integrals the link table leaves out: link 0 (clamped; mass, centre, J for the
    # simulator's bodies) and every link's roll inertia, in units of rho t L^2 and rho t L^4
    rho_t = beam.material.rho * beam.thickness
    u = cuts / L
    area, first, second, _, roll = (v[0] for v in span_integrals(
        bb.x, bb.w, u[None, :-1], u[None, 1:], direct=True, roll=True))
    ixx_all = roll * rho_t * L ** 4
    root = {"mass": float(area[0]) * rho_t * L ** 2,
            "com": float(u[1] / 2 + first[0] / area[0]) * L,
            "J": float(second[0] - first[0] ** 2 / area[0]) * rho_t * L ** 4}
    bodies = []
    for j in range(n + 1):
        a, b = float(cuts[j]), float(cuts[j + 1])
        if j == 0:
            mass, com, iyy = root["mass"], root["com"], root["J"]
        else:   # the PRBDM's own numbers, exactly
            mass = float(phys["mass"][j - 1])
            com = float(phys["com"][j - 1])
            iyy = float(phys["inertia"][j - 1])
        ixx = float(ixx_all[j])
        bodies.append({
            "name": f"link_{j}",
            "parent": "world" if j == 0 else f"link_{j - 1}",
            "joint": None if j == 0 else f"joint_{j}",
            "pos": [0.0 if j == 0 else (a if j == 1 else float(phys["length"][j - 1])), 0.0, 0.0],
            "x_start": a, "length": float(phys["length"][j]),
            "mass": mass, "com": [com, 0.0, 0.0], "inertia": [ixx, iyy, ixx + iyy],
            "mean_half_width": mass / (2 * rho_t * (b - a))})
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
