"""``prbdm eval BEAM --gamma g0,...,gn --k k1,...,km``: eigenfrequencies of a given PRBDM.

docs/conventions.md §3 (the model) and §4 (the command line).

The PRBDM is given, not fitted: link-length fractions ``gamma`` (n + 1 values summing to 1), one
stiffness correction factor per pose (``--k``, or a single value for every pose), a stiffness law
and a pose set. Prints, per pose, the n eigenfrequencies of ``K v = lambda M v`` and the link table
in SI units.

JSON (``--json``): ``beam`` (name, length [m], thickness [m], mass [kg]), ``n``, ``law``, ``gamma``,
``k`` (one per pose), ``poses`` (m lists of n joint angles [rad]), ``omega`` (m lists of n, rad/s,
ascending), ``freq_hz`` (same, Hz), ``links`` (``joint_x`` [m] for joints 1..n, ``length`` [m] for
links 0..n, and for links 1..n: ``mass`` [kg], ``com`` [m from the joint], ``inertia`` [kg m^2]
about the centre of mass, ``area_moment`` [m^4], ``base_stiffness`` s_j [N m/rad]), ``units``,
``warnings`` and ``time_s`` (wall time of the evaluation: links, stiffness, mass matrices and
eigenvalues; reading the beam and the torch import are start-up and not counted).
"""
from __future__ import annotations

import math
import sys
import time

from ..errors import BadInput
from ..parsing import float_list, parse_poses
from ._common import add_beam_argument, print_json, read_beam, table

GAMMA_SUM_TOL = 1e-6


def add_arguments(parser):
    add_beam_argument(parser)
    parser.add_argument("--gamma", required=True, metavar="G0,...,GN",
                        help="link lengths as fractions of L, n + 1 >= 2 values > 0 summing to 1 "
                             f"(within {GAMMA_SUM_TOL:g}); n joints")
    parser.add_argument("--k", required=True, metavar="K1,...,KM",
                        help="stiffness correction factors > 0: one per pose, or a single value "
                             "for every pose")
    parser.add_argument("--law", choices=("beam", "paper"), default="beam",
                        help="base joint stiffness: 'beam' series compliance of the tributary span "
                             "(default) or 'paper' sqrt(E I / m) (Eq. 11 as printed)")
    parser.add_argument("--poses", default="paper", metavar="paper|linear|T1,T2,...",
                        help="pose set: 'paper' (theta = 0.1 + 0.05 i while n theta <= pi/2, the "
                             "default), 'linear' (theta = 0), or angles in rad, each pose putting "
                             "every joint at that angle")
    parser.add_argument("--json", action="store_true", help="print one JSON object on stdout")


def parse_gamma(text: str) -> list[float]:
    gamma = float_list(text, "--gamma", positive=True)
    if len(gamma) < 2:
        raise BadInput(f"--gamma: needs n + 1 >= 2 link fractions (n >= 1 joint), got {len(gamma)}")
    total = math.fsum(gamma)
    if abs(total - 1.0) > GAMMA_SUM_TOL:
        raise BadInput(f"--gamma: the link fractions must sum to 1 (within {GAMMA_SUM_TOL:g}), "
                       f"got sum {total:.9g}")
    return [g / total for g in gamma]


def parse_k(text: str, m: int) -> list[float]:
    k = float_list(text, "--k", positive=True)
    if len(k) == 1:
        return k * m
    if len(k) != m:
        expected = "exactly 1 value" if m == 1 else f"1 value or exactly {m} (one per pose)"
        raise BadInput(f"--k: needs {expected}; the pose set has {m} pose(s), got {len(k)} values")
    return k


def evaluate(beam, gamma, k_text, poses_spec, law):
    """Everything the command prints, as a JSON-ready dict (no timing)."""
    import torch

    from .. import model

    n = len(gamma) - 1
    bt = model.BeamTensors.from_beams(beam)
    g = torch.tensor(gamma, dtype=torch.float64)
    poses = model.make_poses(poses_spec, n)
    m = poses.shape[0]
    k = parse_k(k_text, m)
    with torch.no_grad():
        lam = model.eigenvalues(bt, g, torch.tensor(k, dtype=torch.float64), poses, law)
        links = model.links_from_gamma(bt, g)
        table_si = links.physical(bt)
        s_si = model.base_stiffness(bt, links, law) * bt.E * bt.thickness ** 3
    if not torch.isfinite(lam).all() or not (lam > 0).all():
        raise RuntimeError("non-finite or non-positive eigenvalue")
    omega = lam.sqrt()
    links_out = {key: v.tolist() for key, v in table_si.items()}
    links_out["base_stiffness"] = s_si.tolist()
    return {
        "beam": {"name": beam.name, "length": beam.length, "thickness": beam.thickness,
                 "mass": beam.mass, "stations": len(beam.x)},
        "n": n,
        "law": law,
        "gamma": list(gamma),
        "k": k,
        "poses": poses.tolist(),
        "omega": omega.tolist(),
        "freq_hz": (omega / (2 * math.pi)).tolist(),
        "links": links_out,
    }


UNITS = {"omega": "rad/s", "freq_hz": "Hz", "poses": "rad", "joint_x": "m", "length": "m",
         "mass": "kg", "com": "m from the link's joint",
         "inertia": "kg m^2 about the centre of mass", "area_moment": "m^4",
         "base_stiffness": "N m/rad"}


def run(args) -> int:
    # validate the flags and the beam before paying for the torch import
    gamma = parse_gamma(args.gamma)
    n = len(gamma) - 1
    poses_spec, warnings = parse_poses(args.poses, n)
    beam, info = read_beam(args, "eval")
    from .. import model  # noqa: F401  (torch start-up is not part of time_s)

    t0 = time.perf_counter()
    out_of_bounds = [g for g in gamma if not 0.025 <= g <= 0.975]
    if out_of_bounds:
        warnings.append(f"--gamma: {len(out_of_bounds)} value(s) outside the paper's bounds "
                        f"[0.025, 0.975] (e.g. {out_of_bounds[0]:g})")
    result = evaluate(beam, gamma, args.k, poses_spec, args.law)
    result["units"] = UNITS
    result["warnings"] = warnings
    result["input"] = info
    result["time_s"] = time.perf_counter() - t0
    for w in warnings:
        sys.stderr.write(f"prbdm eval: warning: {w}\n")
    if args.json:
        print_json(result)
    else:
        print(render(result, args.poses))
    return 0


def render(r: dict, poses_label: str) -> str:
    b, L = r["beam"], r["links"]
    n = r["n"]
    lines = [f"beam: {b['name'] or '(unnamed)'}  L = {b['length']:.6g} m, "
             f"t = {b['thickness']:.6g} m, mass = {b['mass']:.6g} kg, {b['stations']} stations",
             f"PRBDM: {n}R, law {r['law']}, {len(r['poses'])} pose(s) ({poses_label})",
             f"gamma: {', '.join(f'{g:.6g}' for g in r['gamma'])}",
             "", "links (SI; centre of mass measured from the link's joint):"]
    rows = [["0", "-", f"{L['length'][0]:.6g}", "(clamped)", "", "", "", ""]]
    for j in range(n):
        rows.append([str(j + 1), f"{L['joint_x'][j]:.6g}", f"{L['length'][j + 1]:.6g}",
                     f"{L['mass'][j]:.6g}", f"{L['com'][j]:.6g}", f"{L['inertia'][j]:.6g}",
                     f"{L['area_moment'][j]:.6g}", f"{L['base_stiffness'][j]:.6g}"])
    lines.append(table(rows, ["link", "joint x [m]", "length [m]", "mass [kg]", "com [m]",
                              "J [kg m^2]", "I [m^4]", "s [N m/rad]"]))
    lines += ["", "eigenfrequencies [Hz] (omega = 2 pi f [rad/s]):"]
    rows = []
    for i, (pose, k, f) in enumerate(zip(r["poses"], r["k"], r["freq_hz"])):
        same = all(abs(a - pose[0]) < 1e-15 for a in pose)
        theta = f"{pose[0]:.4g}" if same else ",".join(f"{a:.3g}" for a in pose)
        rows.append([str(i), theta, f"{k:.6g}", *(f"{v:.6g}" for v in f)])
    lines.append(table(rows, ["pose", "theta [rad]", "k", *(f"f{j + 1}" for j in range(n))]))
    lines.append(f"\n({r['time_s']:.3f} s)")
    return "\n".join(lines)
