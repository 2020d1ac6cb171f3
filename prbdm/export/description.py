"""The description of a PRBDM: bodies, hinges and SI parameters of the chain a fit result makes
of a beam (:func:`prbdm_from_fit`), in no file format yet; conventions in :mod:`prbdm.export`."""
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

    from ..geometry import Beam
    from ..model import BeamTensors, base_stiffness, eigenvalues, links_from_gamma

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
    check_links_match(fit, phys)
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
