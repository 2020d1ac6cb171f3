"""Large-deflection accuracy of rigid-link chains against the geometrically exact rod (issue 37
item 3; docs/large-deflection-accuracy.md).

Every method is a planar chain of rigid links cut from the beam (link masses, centres and
rotary inertias the exact integrals of the planform, :func:`prbdm.model.links_from_gamma`) with
torsional springs at the joints; the truth is :mod:`prbdm.truth.rod` (the inextensible,
unshearable Euler-Bernoulli rod, exact kinematics). The panels are treated as strips (1-D).

Methods:

- ``howell-1r``, ``su-3r``: :mod:`prbdm.classical` (``ei="tip"``), constant springs.
- ``rfe-4`` (and ``rfe-20``, a convergence reference): equal links
  :func:`prbdm.model.uniform_gamma`, the ``beam`` stiffness law, SCF 1.
- ``fit-paper``: :func:`prbdm.fit.fit_prbdm` (4 joints, paper poses, one SCF per pose, matched
  to the straight beam's ``beam`` truth), with the *energy-consistent* spring law below.
- ``fit-const``: :func:`prbdm.fit.fit_prbdm` with ``poses="linear"`` (one SCF, fitted at rest),
  constant stiffness at every angle.
- ``network``: the shipped ``beam-n4`` network's gamma and SCFs, with the spring law of its pose
  target (:func:`prbdm.springs.fitted_springs`: constant stiffness for a network trained at rest,
  ``shape``; the interpolated law below for one trained on the paper's poses, ``straight``).

Every fitted chain gets its springs from :func:`prbdm.springs.fitted_springs`, the law
``prbdm simulate`` gives the same result at large amplitude. The spring law of per-pose SCFs
(:class:`prbdm.springs.InterpolatedSprings`): joint j has the potential

    V_j(theta) = s_j * int_0^|theta| k(u) u du,   torque  dV_j/dtheta = s_j k(|theta|) theta,

with ``s_j`` the ``beam`` law's base stiffness and ``k(u)`` the pose SCFs interpolated linearly
in the joint angle ``u`` between the pose angles (0.10 ... 0.35 rad for n = 4) and held constant
outside them (below the first pose, ``k(0.10)``; above the last, ``k(0.35)``). Each joint's SCF
follows its own angle; the torque is the gradient of a potential, so the free vibration
conserves energy (checked: ``energy_drift`` in the JSON).

Tests:

1. Statics: a dead tip force, vertical (perpendicular to the undeformed beam, ``force_angle``
   90 deg) and at 45 deg to the beam axis (pulling outward and up: the tip then turns towards
   the force and cannot pass 45 deg, so that path stops at 40 deg). The loads are the rod's
   loads for tip angles 5, 10, ..., 75 deg (40 deg at 45 deg); each chain is solved at the same
   load (matched load; minimum of the potential energy, by continuation along the loads).
   Error: ``|r_tip(chain) - r_tip(rod)| / L``.
2. Free vibration released from rest in the static shape under a vertical tip force with a tip
   angle of 10, 30, 60 deg, each model from its own equilibrium at that tip angle (the chain's
   tip angle is its last link's angle). Period: the mean time between successive downward
   crossings of z = 0 by the tip over the first 5 periods (the rod's and ``prbdm simulate``'s
   definition; the first period alone, ``first_period_error``, moves with the excited higher
   modes); errors ``|T / T_rod - 1|`` and the RMS over ``t in [0, 5 T_rod]`` of
   ``|r_tip(chain, t) - r_tip(rod, t)|`` divided by the rod's initial tip deflection
   ``z_tip(0)``. The rod: :func:`prbdm.truth.rod.rod_response` at the discretisation
   ``prbdm simulate`` uses (:class:`prbdm.simulate.ReferenceSettings`), run again at half the
   steps: the change of its mean period is the release's ``resolution``.

Run:  python benchmarks/large_deflection.py [--quick] [--json FILE] [--plot FILE]
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
import warnings
from dataclasses import dataclass

import numpy as np
import torch
from scipy.integrate import solve_ivp

from prbdm.chain import ChainDynamics, TipLoadStatics, joint_accelerations
from prbdm.classical import HOWELL_1R, SU_3R, joint_stiffness
from prbdm.errors import BadInput
from prbdm.geometry import Beam, Material, random_beam
from prbdm.model import BeamTensors, base_stiffness, links_from_gamma, uniform_gamma
from prbdm.simulate import ReferenceSettings
from prbdm.springs import LinearSprings, fitted_springs
from prbdm.truth.rod import rod_response, rod_static

DEG = math.pi / 180.0
STATIC_ANGLES = {"vertical": (90.0, list(range(5, 80, 5))), "45deg": (45.0, list(range(5, 45, 5)))}
REPORT_STATIC = {"vertical": (30, 60, 75), "45deg": (15, 30, 40)}
RELEASE_ANGLES = (10.0, 30.0, 60.0)
PERIODS = 5
METHODS = ("howell-1r", "su-3r", "rfe-4", "fit-paper", "fit-const", "network", "rfe-20")
#: the rod's dynamics: the discretisation and steps per linear period of ``prbdm simulate``'s
#: large-amplitude reference (one home: prbdm.simulate.ReferenceSettings), with its check at half
#: the steps (``resolution`` in the JSON)
_REF = ReferenceSettings()
ROD_DYNAMICS = {"elements": _REF.rod_elements, "degree": _REF.rod_degree,
                "steps": _REF.rod_steps}


def _log(msg):
    print(msg, file=sys.stderr, flush=True)


# ----------------------------------------------------------------------------- beams
def table2_beam() -> Beam:
    return Beam(x=np.array([0.0, 1.0]), half_width=np.array([0.3624, 0.3624]) / 2,
                thickness=0.040532, material=Material(E=205e9, rho=7850.0, nu=0.28),
                name="Table 2 uniform beam")


def tapered_beam() -> Beam:
    return Beam(x=np.array([0.0, 0.35, 1.0]), half_width=np.array([0.18, 0.12, 0.05]),
                thickness=0.03, material=Material(E=205e9, rho=7850.0, nu=0.28),
                name="README tapered panel")


def beams(count: int, seed: int = 0) -> list:
    out = [table2_beam(), tapered_beam()]
    out += [random_beam(seed, i) for i in range(count)]
    return out


# ----------------------------------------------------------------------------- the chain
@dataclass
class Chain:
    """Rigid links 1..n of a chain cut from ``beam`` at ``gamma`` (SI), springs ``springs``."""

    name: str
    x1: float                     # link 0's length [m] (joint 1 at (x1, 0))
    dyn: ChainDynamics            # links (its stiffness unused: springs below)
    springs: object
    L: float
    info: dict

    @property
    def n(self):
        return self.dyn.n

    def tip(self, th):
        x, z = self.dyn.tip(th)
        return np.array([x + self.x1, z])

    def tip_angle(self, th):
        return float(np.sum(th))

    # statics: prbdm.chain.TipLoadStatics -----------------------------------------------
    @property
    def statics(self) -> TipLoadStatics:
        return TipLoadStatics(self.dyn.length, self.springs, self.x1, self.name)

    def equilibrium(self, F, th0):
        """Minimum of the potential energy under the dead tip force F [N] near ``th0``."""
        return self.statics.equilibrium(F, th0)

    def step_to(self, F0, th0, F1):
        """Equilibrium under F1 continued from (F0, th0), with sub-steps where needed."""
        return self.statics.step_to(F0, th0, F1)

    def path(self, forces):
        """Equilibria along a sequence of forces (rows), by continuation from the unloaded chain."""
        return self.statics.path(forces)

    def release_shape(self, target, force_angle=math.pi / 2, load_guess=None):
        """Equilibrium under a tip force at ``force_angle`` whose tip angle is ``target`` [rad];
        returns (theta, force magnitude). ``load_guess`` [N] sets the load steps."""
        return self.statics.release_shape(target, force_angle, load_guess)

    # dynamics -------------------------------------------------------------------------
    def rhs(self, t, y):
        n = self.n
        th, thd = y[:n], y[n:]
        return np.concatenate([thd, joint_accelerations(self.dyn.A, th, thd,
                                                        -self.springs.torque(th))])

    def energy(self, th, thd):
        return float(0.5 * thd @ self.dyn.mass_matrix(th) @ thd) + self.springs.energy(th)

    def release(self, th0, t_eval, periods=PERIODS, rtol=1e-10):
        """Free vibration from rest at ``th0``: tip at ``t_eval`` and the periods (times between
        successive downward crossings of the tip through z = 0)."""
        n = self.n
        y0 = np.concatenate([th0, np.zeros(n)])
        sign = 1.0 if self.tip(th0)[1] > 0 else -1.0

        def crossing(t, y):
            return sign * self.tip(y[:n])[1]
        crossing.direction = -1
        T_guess = t_eval[-1] / periods
        crossing.terminal = False
        scale = float(np.max(np.abs(th0)))
        for extra in (1.5, 3.0, 10.0, 30.0):      # long enough for periods + 1 crossings
            t_end = t_eval[-1] + extra * T_guess
            sol = solve_ivp(self.rhs, (0.0, t_end), y0, method="DOP853", rtol=rtol,
                            atol=rtol * scale * 1e-2, events=crossing, dense_output=True)
            if not sol.success:
                raise RuntimeError(f"{self.name}: integration failed: {sol.message}")
            tc = sol.t_events[0]
            if tc.size >= periods + 1:
                break
        else:
            raise RuntimeError(f"{self.name}: {max(tc.size - 1, 0)} of {periods} periods within "
                               f"{t_end / T_guess:.0f} rod periods")
        Y = sol.sol(t_eval)
        tips = np.array([self.tip(Y[:n, i]) for i in range(t_eval.size)])
        E = [self.energy(Y[:n, i], Y[n:, i]) for i in range(0, t_eval.size, 10)]
        drift = float(np.max(np.abs(np.array(E) - E[0])) / E[0])
        return tips, np.diff(tc), drift


def make_chain(beam: Beam, name: str, gamma, springs_fn, info=None) -> Chain:
    """Cut the chain at ``gamma`` (n+1) from ``beam``; ``springs_fn(s_si)`` gives the springs
    from the ``beam`` law's base stiffness s_j [N m/rad]."""
    bt = BeamTensors.from_beams(beam)
    g = torch.as_tensor(np.asarray(gamma, float), dtype=torch.float64)
    links = links_from_gamma(bt, g)
    ph = {k: v.numpy() for k, v in links.physical(bt).items()}
    s_si = base_stiffness(bt, links, "beam").numpy() * beam.material.E * beam.thickness ** 3
    n = g.numel() - 1
    springs = springs_fn(s_si)
    dyn = ChainDynamics(length=ph["length"][1:], com=ph["com"], mass=ph["mass"],
                        inertia=ph["inertia"], stiffness=np.zeros(n), damping=np.zeros(n),
                        springref=np.zeros(n))
    return Chain(name=name, x1=float(ph["length"][0]), dyn=dyn, springs=springs,
                 L=beam.length, info=dict(info or {}, gamma=[float(v) for v in gamma]))


def make_fitted_chain(beam: Beam, name: str, result: dict, info: dict) -> Chain:
    """The chain of a fit result (gamma, k, poses, pose_target) with the spring law it was
    fitted with (:func:`prbdm.springs.fitted_springs`); ``info`` gains that law's record."""
    law = {}

    def springs(s):
        sp, law["springs"] = fitted_springs(result, s)
        return sp
    ch = make_chain(beam, name, np.asarray(result["gamma"], float), springs,
                    dict(info, k=np.atleast_1d(np.asarray(result["k"], float)).tolist()))
    ch.info.update(law)
    return ch


def build_methods(beam: Beam, methods=METHODS, starts=None, seed=0, sur=None) -> dict:
    """The chains of ``methods`` for ``beam``."""
    from prbdm.fit import fit_prbdm
    from prbdm.truth import bending_frequencies

    out = {}
    omega = None
    for m in methods:
        t0 = time.perf_counter()
        if m in ("howell-1r", "su-3r"):
            prbm = HOWELL_1R if m == "howell-1r" else SU_3R
            K = joint_stiffness(beam, prbm, "tip")
            ch = make_chain(beam, m, prbm.gamma, lambda s, K=K: LinearSprings(K),
                            {"K": K.tolist()})
        elif m.startswith("rfe-"):
            n = int(m.split("-")[1])
            ch = make_chain(beam, m, uniform_gamma(n).numpy(), LinearSprings, {"k": 1.0})
        elif m in ("fit-paper", "fit-const"):
            if omega is None:
                omega = bending_frequencies(beam, "beam", modes=4).omega
            kw = {} if m == "fit-paper" else {"poses": "linear"}
            if starts:
                kw["starts"] = starts
            fit = fit_prbdm(beam, omega, joints=4,
                            seed=seed, **kw)
            result = {"gamma": fit.gamma, "k": fit.k, "poses": fit.poses,
                      "pose_target": "straight" if m == "fit-paper" else "shape"}
            ch = make_fitted_chain(beam, m, result, {"loss_percent": float(fit.loss_percent)})
        elif m == "network":
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                pred = sur.predict([beam])
            result = {"gamma": pred.gamma[0], "k": pred.k[0], "poses": pred.poses,
                      "pose_target": sur.pose_target}
            ch = make_fitted_chain(beam, m, result, {
                "checkpoint": sur.name, "objective": sur.objective,
                "warnings": [str(w.message)[:200] for w in caught]
                + list(map(str, pred.warnings))})
        else:
            raise ValueError(m)
        ch.info["build_s"] = time.perf_counter() - t0
        out[m] = ch
    return out


# ----------------------------------------------------------------------------- the tests
def static_paths(beam: Beam, chains: dict) -> dict:
    """Tip paths under a dead tip force (vertical and at 45 deg) at the rod's loads."""
    L = beam.length
    res = {}
    for key, (fa_deg, angles) in STATIC_ANGLES.items():
        fa = fa_deg * DEG
        rods = [rod_static(beam, tip_angle=a * DEG, force_angle=fa) for a in angles]
        forces = np.array([r.force for r in rods])
        entry = {"force_angle_deg": fa_deg, "rod_tip_angle_deg": list(angles),
                 "force_N": forces.tolist(),
                 "rod": {"tip_x": [r.tip_x for r in rods], "tip_z": [r.tip_z for r in rods],
                         "tip_angle": [r.tip_angle for r in rods]}, "methods": {}}
        rod_tip = np.array([[r.tip_x, r.tip_z] for r in rods])
        for name, ch in chains.items():
            ths = ch.path(forces)
            tips = np.array([ch.tip(t) for t in ths])
            err = np.linalg.norm(tips - rod_tip, axis=1) / L
            entry["methods"][name] = {
                "tip_x": tips[:, 0].tolist(), "tip_z": tips[:, 1].tolist(),
                "tip_angle": [ch.tip_angle(t) for t in ths],
                "tip_error": err.tolist()}
        res[key] = entry
    return res


#: how the rod's implicit midpoint iteration fails at too coarse a step (no convergence: BadInput
#: naming ``steps``; divergence to inf: ValueError from the linear solve)
ROD_FAILURES = (BadInput, ArithmeticError, ValueError)


def _rod_release(beam, angle, rod_kw):
    """(rod, kw, failures): the release at ``rod_kw``'s steps or, where its implicit midpoint
    iteration fails, at twice the steps (rod_response's own default for 512); BadInput naming
    both failures where both fail."""
    failures = []
    for steps in (rod_kw["steps"], 2 * rod_kw["steps"]):
        kw = dict(rod_kw, steps=steps)
        try:
            return rod_response(beam, angle, periods=PERIODS, check=False, **kw), kw, failures
        except ROD_FAILURES as exc:
            failures.append(f"at {steps} steps: {str(exc)[:160]}")
    raise BadInput("; ".join(failures))


def _rod_resolution(beam, angle, rod, rod_kw):
    """(resolution, first, note): the relative change of the mean period (``resolution``, as
    ``prbdm simulate`` measures it) and of the first period (``first``) when the release ``rod``
    runs again at half the steps; None, None and the reason where that run fails (its implicit
    midpoint iteration does not converge at the coarser step)."""
    kw = dict(rod_kw, steps=max(16, rod_kw["steps"] // 2))
    try:
        half = rod_response(beam, angle, periods=PERIODS, check=False, **kw)
    except ROD_FAILURES as exc:
        return None, None, f"at {kw['steps']} steps: {exc}"
    return (abs(half.period / rod.period - 1.0), abs(half.periods[0] / rod.periods[0] - 1.0),
            None)


def vibrations(beam: Beam, chains: dict, angles=RELEASE_ANGLES, rod_kw=None) -> dict:
    """Free vibration released from the static shape at each tip angle."""
    rod_kw = dict(rod_kw or {})
    out = {}
    for a in angles:
        t0 = time.perf_counter()
        try:
            rod, used, failures = _rod_release(beam, a * DEG, rod_kw)
        except BadInput as exc:                  # recorded; the other releases go on
            out[f"{a:g}"] = {"rod": {"error": str(exc), "time_s": time.perf_counter() - t0},
                             "methods": {}}
            _log(f"  {a:g} deg rod: {exc}")
            continue
        resolution, res_first, note = _rod_resolution(beam, a * DEG, rod, used)
        T_rod, T1_rod = float(rod.period), float(rod.periods[0])
        sel = rod.t <= PERIODS * float(rod.period) * (1 + 1e-12)
        t = rod.t[sel]
        rod_tip = np.stack([rod.tip_x[sel], rod.tip_z[sel]], axis=1)
        z0 = float(rod.tip_z[0])
        entry = {"rod": {"period_s": T_rod, "first_period_s": T1_rod,
                         "periods_s": rod.periods.tolist(), "tip0": rod_tip[0].tolist(),
                         "load_N": float(np.hypot(*rod.equilibrium.force)),
                         "resolution": resolution, "resolution_first_period": res_first,
                         "resolution_note": note, "failures": failures,
                         "energy_drift": rod.energy_drift, "mesh": rod.mesh,
                         "time_s": time.perf_counter() - t0}, "methods": {}}
        _log(f"  {a:g} deg rod: period {T_rod:.6g} s, resolution {resolution}, "
             f"{entry['rod']['time_s']:.1f} s")
        for name, ch in chains.items():
            t1 = time.perf_counter()
            try:
                th0, P = ch.release_shape(a * DEG, load_guess=entry["rod"]["load_N"])
                tips, periods, drift = ch.release(th0, t)
            except RuntimeError as exc:            # recorded; not in the summary
                entry.setdefault("errors", {})[name] = str(exc)
                _log(f"  {a:g} deg {name}: {exc}")
                continue
            T = float(np.mean(periods[:PERIODS])) if periods.size >= PERIODS else math.nan
            T1 = float(periods[0]) if periods.size else math.nan
            diff = np.linalg.norm(tips - rod_tip, axis=1)
            entry["methods"][name] = {
                "period_s": T, "periods_s": periods.tolist(),
                "period_error": abs(T / T_rod - 1.0),
                "first_period_error": abs(T1 / T1_rod - 1.0),
                "trajectory_rms": float(np.sqrt(np.mean(diff ** 2)) / z0),
                "tip0": tips[0].tolist(), "load_N": P, "energy_drift": drift,
                "time_s": time.perf_counter() - t1}
            _log(f"  {a:g} deg {name}: period error {abs(T / T_rod - 1):.2e}, "
                 f"{time.perf_counter() - t1:.1f} s")
        out[f"{a:g}"] = entry
    return out


def run_static(beam: Beam, methods=METHODS, starts=None, sur=None):
    """(record, chains) of the static test."""
    t0 = time.perf_counter()
    chains = build_methods(beam, methods, starts=starts, sur=sur)
    rec = {"beam": beam.to_dict(), "methods": {k: c.info for k, c in chains.items()}}
    rec["static"] = static_paths(beam, chains)
    rec["static_time_s"] = time.perf_counter() - t0
    return rec, chains


def run_dynamics(beam: Beam, rec: dict, chains: dict, methods, rod_kw=None,
                 release_angles=RELEASE_ANGLES) -> dict:
    """The free-vibration test at ``release_angles``, added to ``rec``'s."""
    t0 = time.perf_counter()
    rec.setdefault("vibration", {}).update(
        vibrations(beam, {m: chains[m] for m in methods}, release_angles, rod_kw))
    rec["dynamics_time_s"] = rec.get("dynamics_time_s", 0.0) + time.perf_counter() - t0
    return rec


def _missing_releases(rec: dict) -> list:
    """The release angles of RELEASE_ANGLES that ``rec`` has no chain results for."""
    return [a for a in RELEASE_ANGLES
            if not rec.get("vibration", {}).get(f"{a:g}", {}).get("methods")]


def _previous_records(path) -> dict:
    """``--resume``: the records of ``path`` by beam (empty where it does not exist)."""
    try:
        with open(path) as f:
            doc = json.load(f)
    except FileNotFoundError:
        return {}
    return {json.dumps(r["beam"], sort_keys=True): r for r in doc["beams"]}


def _rebuild(beam, rec, methods, starts, sur) -> dict:
    """The chains of a resumed record, made again (seeded: the same gamma, checked)."""
    chains = build_methods(beam, methods, starts=starts, sur=sur)
    for m, ch in chains.items():
        if ch.info["gamma"] != rec["methods"][m]["gamma"]:
            raise RuntimeError(f"--resume: {beam.name} {m}: the chain made again differs from "
                               "the recorded one (another fit or network): run without --resume")
    return chains


# ----------------------------------------------------------------------------- summary
def summarise(records: list, methods) -> dict:
    summ = {}
    for m in methods:
        s = {}
        for key, rep in REPORT_STATIC.items():
            for a in rep:
                vals = []
                for r in records:
                    e = r["static"][key]
                    i = e["rod_tip_angle_deg"].index(a)
                    vals.append(e["methods"][m]["tip_error"][i])
                s[f"static_{key}_{a}"] = {"median": float(np.median(vals)),
                                          "worst": float(np.max(vals)), "beams": len(vals)}
        for a in RELEASE_ANGLES:
            for q in ("period_error", "trajectory_rms"):
                vals = [r["vibration"][f"{a:g}"]["methods"][m][q] for r in records
                        if "vibration" in r and f"{a:g}" in r["vibration"]
                        and m in r["vibration"][f"{a:g}"]["methods"]]
                if vals:
                    s[f"{q}_{a:g}"] = {"median": float(np.median(vals)),
                                       "worst": float(np.max(vals)), "beams": len(vals)}
        summ[m] = s
    return summ


def rod_summary(records: list) -> dict:
    """Per release angle, over the beams with dynamics: the rod's resolution (its largest period
    change at half the steps) and run time, median and worst."""
    out = {}
    for a in RELEASE_ANGLES:
        rods = [r["vibration"][f"{a:g}"]["rod"] for r in records
                if "vibration" in r and f"{a:g}" in r["vibration"]]
        ok = [v for v in rods if "error" not in v]
        if not ok:
            continue
        e = out[f"{a:g}"] = {"beams": len(ok), "failed": len(rods) - len(ok)}
        for q in ("resolution", "time_s"):
            vals = [v[q] for v in ok if v[q] is not None]
            e[q] = ({"median": float(np.median(vals)), "worst": float(np.max(vals)),
                     "beams": len(vals)} if vals else None)
    return out


def table(summ: dict, count: int, rods: dict | None = None) -> str:
    cols = [("static_vertical_30", "tip 30°"), ("static_vertical_60", "tip 60°"),
            ("static_vertical_75", "tip 75°"), ("static_45deg_40", "45° F, 40°")]
    lines = [f"Static tip-position error / L at matched load, median over {count} beams "
             "(worst in brackets)", "",
             "| method | " + " | ".join(c[1] for c in cols) + " |",
             "|---|" + "---|" * len(cols)]
    for m, s in summ.items():
        lines.append(f"| {m} | " + " | ".join(
            f"{s[c]['median']:.2e} ({s[c]['worst']:.1e})" for c, _ in cols) + " |")
    dyn = max([v["beams"] for s in summ.values() for k, v in s.items()
               if k.startswith("period")] or [0])
    lines += ["", f"Free vibration (released from the static shape), median over {dyn} beams "
              "(worst in brackets): period error (mean of 5) | tip-trajectory RMS / initial deflection",
              "",
              "| method | " + " | ".join(f"period {a:g}°" for a in RELEASE_ANGLES) + " | "
              + " | ".join(f"RMS {a:g}°" for a in RELEASE_ANGLES) + " |",
              "|---|" + "---|" * (2 * len(RELEASE_ANGLES))]
    for m, s in summ.items():
        cells = []
        for q in ("period_error", "trajectory_rms"):
            for a in RELEASE_ANGLES:
                v = s.get(f"{q}_{a:g}")
                cells.append(f"{100 * v['median']:.2f} % ({100 * v['worst']:.2f} %)" if v
                             else "-")
        lines.append(f"| {m} | " + " | ".join(cells) + " |")
    if rods:
        cells = [f"{100 * rods[f'{a:g}']['resolution']['median']:.3f} % "
                 f"({100 * rods[f'{a:g}']['resolution']['worst']:.3f} %)"
                 if rods.get(f"{a:g}", {}).get("resolution") else "-" for a in RELEASE_ANGLES]
        lines.append("| rod resolution | " + " | ".join(cells) + " |"
                     + " |" * len(RELEASE_ANGLES))
    return "\n".join(lines)


def plot(records: list, methods, path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(10.5, 3.4), constrained_layout=True)
    for ci, m in enumerate(methods):
        c = f"C{ci}"
        for ax, key in ((axes[0], "vertical"), (axes[1], "45deg")):
            ang = records[0]["static"][key]["rod_tip_angle_deg"]
            err = np.array([r["static"][key]["methods"][m]["tip_error"] for r in records])
            ax.semilogy(ang, np.median(err, 0), "-o", color=c, ms=3, label=m)
            ax.semilogy(ang, err.max(0), ":", color=c, lw=0.8)
        pe = [[r["vibration"][f"{a:g}"]["methods"][m]["period_error"] for r in records
               if m in r.get("vibration", {}).get(f"{a:g}", {}).get("methods", {})]
              for a in RELEASE_ANGLES]
        if all(pe):
            axes[2].semilogy(RELEASE_ANGLES, [np.median(v) for v in pe], "-o", color=c, ms=3,
                             label=m)
            axes[2].semilogy(RELEASE_ANGLES, [max(v) for v in pe], ":", color=c, lw=0.8)
    axes[0].set_title("tip force perpendicular to the beam", fontsize=9)
    axes[1].set_title("tip force at 45° to the beam", fontsize=9)
    for ax in axes[:2]:
        ax.set_xlabel("rod tip angle [deg]")
        ax.set_ylabel("|tip position error| / L")
    nvib = sum(bool(r.get("vibration")) for r in records)
    axes[2].set_title(f"free vibration from a static shape ({nvib} beams)", fontsize=9)
    axes[2].set_xlabel("release tip angle [deg]")
    axes[2].set_ylabel("period error (mean of 5 periods)")
    res = rod_summary(records)
    if all(res.get(f"{a:g}", {}).get("resolution") for a in RELEASE_ANGLES):
        axes[2].semilogy(RELEASE_ANGLES, [res[f"{a:g}"]["resolution"]["worst"]
                                          for a in RELEASE_ANGLES], "k--", lw=0.8,
                         label="rod resolution (worst)")
        axes[2].legend(fontsize=7)
    for ax in axes:
        ax.grid(alpha=0.3, which="both")
    axes[0].legend(fontsize=7)
    fig.suptitle(f"statics: {len(records)} beams; median (solid), worst (dotted)", fontsize=9)
    fig.savefig(path, dpi=90)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true",
                    help="the Table-2 and tapered beams and 2 random strips")
    ap.add_argument("--random", type=int, default=None, help="random strips (default 20; quick 2)")
    ap.add_argument("--seed", type=int, default=0, help="random_beam seed (default 0)")
    ap.add_argument("--beams", type=int, default=None,
                    help="use only the first N beams of the list (smoke tests)")
    ap.add_argument("--release", default=None,
                    help="release tip angles [deg], comma separated (default 10,30,60)")
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--dynamics-methods", default=",".join(m for m in METHODS if m != "rfe-20"),
                    help="methods of the free-vibration test (default all but rfe-20, whose "
                         "stiff 20-link chain costs minutes per release)")
    ap.add_argument("--no-dynamics", action="store_true")
    ap.add_argument("--dynamics-beams", type=int, default=None,
                    help="the free-vibration test on the first N beams of the list only "
                         "(default all; the rod costs minutes per release on a random strip)")
    ap.add_argument("--starts", type=int, default=None, help="fit starts (default the fit's)")
    ap.add_argument("--rod-elements", type=int, default=None,
                    help=f"rod elements per unit length (default {ROD_DYNAMICS['elements']})")
    ap.add_argument("--rod-degree", type=int, default=None,
                    help=f"rod element degree (default {ROD_DYNAMICS['degree']})")
    ap.add_argument("--rod-steps", type=int, default=None,
                    help=f"rod steps per linear period (default {ROD_DYNAMICS['steps']})")
    ap.add_argument("--json", default=None)
    ap.add_argument("--resume", action="store_true",
                    help="keep the beams already in --json (statics, and the releases whose "
                         "chains were run) and run only what is missing")
    ap.add_argument("--plot", default=None)
    args = ap.parse_args(argv)
    args.argv = list(sys.argv[1:] if argv is None else argv)
    global RELEASE_ANGLES
    if args.release:
        RELEASE_ANGLES = tuple(float(v) for v in args.release.split(","))
    count = args.random if args.random is not None else (2 if args.quick else 20)
    rod_kw = dict(ROD_DYNAMICS)
    for k, v in (("elements", args.rod_elements), ("degree", args.rod_degree),
                 ("steps", args.rod_steps)):
        if v is not None:
            rod_kw[k] = v
    methods = tuple(args.methods.split(","))
    torch.manual_seed(0)
    np.random.seed(0)
    sur = None
    if "network" in methods:
        from prbdm import surrogate
        sur = surrogate.load_checkpoint(surrogate.default_checkpoint(4, "beam", "eigenvalue"))
    blist = beams(count, args.seed)
    if args.beams:
        blist = blist[:args.beams]
    t0 = time.perf_counter()
    records, chain_sets = [], []
    previous = _previous_records(args.json) if args.resume and args.json else {}
    for b in blist:                                   # statics first, every beam
        rec = previous.get(json.dumps(b.to_dict(), sort_keys=True))
        if rec is not None and set(rec["methods"]) == set(methods):
            records.append(rec)
            chain_sets.append(None)
            _log(f"{b.name}: statics from {args.json}")
            continue
        rec, chains = run_static(b, methods, starts=args.starts, sur=sur)
        records.append(rec)
        chain_sets.append(chains)
        st = rec["static"]["vertical"]
        i = st["rod_tip_angle_deg"].index(60)
        print(f"{b.name}: {rec['static_time_s']:.1f} s; static error at 60 deg: " + ", ".join(
            f"{m} {st['methods'][m]['tip_error'][i]:.1e}" for m in methods), flush=True)
        if args.json:                       # save as we go
            _save(args, records, methods, rod_kw, count, time.perf_counter() - t0)
    dyn_methods = [m for m in args.dynamics_methods.split(",") if m in methods]
    if not args.no_dynamics:
        last = f"{RELEASE_ANGLES[-1]:g}"
        for b, rec, chains in list(zip(blist, records, chain_sets))[:args.dynamics_beams]:
            todo = _missing_releases(rec)
            if not todo:
                continue
            if chains is None:
                chains = _rebuild(b, rec, methods, args.starts, sur)
            run_dynamics(b, rec, chains, dyn_methods, rod_kw, todo)
            got = rec["vibration"][last]["methods"]
            print(f"{b.name}: dynamics {rec['dynamics_time_s']:.1f} s; period error at "
                  f"{last} deg: " + ", ".join(f"{m} {got[m]['period_error']:.1e}" for m in got),
                  flush=True)
            if args.json:
                _save(args, records, methods, rod_kw, count, time.perf_counter() - t0)
    summ = summarise(records, methods)
    print(table(summ, len(records), rod_summary(records)))
    print(f"total {time.perf_counter() - t0:.0f} s")
    if args.json:
        _save(args, records, methods, rod_kw, count, time.perf_counter() - t0, summ)
    if args.plot:
        plot(records, methods, args.plot)
    return 0


def _save(args, records, methods, rod_kw, count, elapsed, summ=None):
    doc = {"command": "python benchmarks/large_deflection.py " + " ".join(args.argv),
           "methods": list(methods), "rod_dynamics": rod_kw, "random_beams": count,
           "random_seed": args.seed, "release_angles_deg": list(RELEASE_ANGLES),
           "periods": PERIODS, "time_s": elapsed,
           # the beams' own times, summed (with --resume, over the runs that made them)
           "beams_time_s": sum(r.get("static_time_s", 0.0) + r.get("dynamics_time_s", 0.0)
                               for r in records),
           "summary": summ if summ is not None else summarise(records, methods),
           "rod_summary": rod_summary(records),
           "beams": records}
    with open(args.json, "w") as f:
        json.dump(doc, f, indent=1)


if __name__ == "__main__":
    sys.exit(main())
