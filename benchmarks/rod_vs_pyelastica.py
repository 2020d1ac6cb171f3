"""The rod truth (prbdm.truth.rod) against PyElastica's Cosserat rod: free vibration after release
from a large static deflection (docs/large-deflection.md).

PyElastica (``pip install pyelastica``; not a dependency of prbdm) integrates a shearable,
extensible Cosserat rod with a symplectic position-Verlet stepper. To approximate the inextensible,
unshearable rod it is given a slender strip (t/L = 0.02: axial and shear strains are of order
(t/L)^2 times the load, ~4e-4) with the strip's own axial stiffness E A, shear stiffness
(5/6) G A, bending stiffness E I(s) = E 2 w(s) t^3 / 12 and mass rho 2 w(s) t per length,
element by element (the taper included), and the section's rotary inertia rho I; the rod truth
runs with ``rotary=True`` to match. Both start at rest in the rod truth's static shape under a
perpendicular tip force (PyElastica: nodes and directors set to that shape, its rest shape
straight), the clamp fixing node 0 and element 0's director. Compared: the periods (successive
downward crossings of the tip through z = 0) and the tip trajectory over ``--periods`` periods
(the largest distance between the two tips at equal times, relative to the release deflection).

    python benchmarks/rod_vs_pyelastica.py [--elements 50,100] [--periods 2] [--angle 0.8]
"""
from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np

from prbdm.geometry import Beam, Material
from prbdm.truth.rod import rod_response

MAT = Material(E=1.0e6, rho=1000.0, nu=0.3)
STRIPS = {
    "uniform": Beam(x=[0.0, 1.0], half_width=[0.02, 0.02], thickness=0.02, material=MAT),
    "tapered": Beam(x=[0.0, 0.35, 1.0], half_width=[0.04, 0.024, 0.01], thickness=0.02,
                    material=MAT),
}


def pyelastica_release(beam: Beam, eq, n_elem: int, t_end: float, dt_factor: float = 0.4):
    """Tip history of PyElastica's rod released from the shape ``eq`` (rod_static)."""
    import elastica as ea

    class Sim(ea.BaseSystemCollection, ea.Constraints):
        pass

    L, t, m = beam.length, beam.thickness, beam.material
    sim = Sim()
    rod = ea.CosseratRod.straight_rod(n_elem, np.zeros(3), np.array([1.0, 0, 0]),
                                      np.array([0, 0, 1.0]), L, 0.01, m.rho,
                                      youngs_modulus=m.E, shear_modulus=m.E / (2 * (1 + m.nu)))
    dl = L / n_elem
    s_el = (np.arange(n_elem) + 0.5) * dl
    b = 2 * np.interp(s_el, beam.x, beam.half_width)          # full width per element
    A, I2, I1 = b * t, b * t ** 3 / 12, b ** 3 * t / 12
    G = m.E / (2 * (1 + m.nu))
    for i in range(n_elem):
        rod.shear_matrix[..., i] = np.diag([5 / 6 * G * A[i], 5 / 6 * G * A[i], m.E * A[i]])
        J = m.rho * dl * np.array([I1[i], I2[i], I1[i] + I2[i]])
        rod.mass_second_moment_of_inertia[..., i] = np.diag(J)
        rod.inv_mass_second_moment_of_inertia[..., i] = np.diag(1 / J)
    Be = np.array([np.diag([m.E * I1[i], m.E * I2[i], G * (I1[i] + I2[i])])
                   for i in range(n_elem)])
    rod.bend_matrix[:] = np.moveaxis(0.5 * (Be[1:] + Be[:-1]), 0, -1)
    mass = np.zeros(n_elem + 1)
    mass[:-1] += 0.5 * m.rho * A * dl
    mass[1:] += 0.5 * m.rho * A * dl
    rod.mass[:] = mass
    # release shape: the rod truth's static equilibrium, nodes and element directors
    s_nodes = np.arange(n_elem + 1) * dl
    rod.position_collection[0] = np.interp(s_nodes, eq.s, eq.x)
    rod.position_collection[2] = np.interp(s_nodes, eq.s, eq.z)
    th = np.interp(s_el, eq.s, eq.theta)
    for i in range(n_elem):
        c, sn = math.cos(th[i]), math.sin(th[i])
        rod.director_collection[..., i] = np.array([[-sn, 0, c], [0, -1.0, 0], [c, 0, sn]])
    sim.append(rod)
    sim.constrain(rod).using(ea.OneEndFixedBC, constrained_position_idx=(0,),
                             constrained_director_idx=(0,))
    sim.finalize()
    stepper = ea.PositionVerlet()
    # explicit stepping: below the axial wave's element crossing time and the period of an
    # element's shear-rotation oscillation, omega^2 = (5/6) G A / (rho I2) = 10 G / (rho t^2)
    c_axial = math.sqrt(m.E / m.rho)
    omega_rot = math.sqrt(10.0 * G / m.rho) / t
    dt = dt_factor * min(dl / c_axial, 2.0 / omega_rot)
    steps = int(math.ceil(t_end / dt))
    every = max(1, steps // 4000)
    ts, tip = [0.0], [rod.position_collection[:, -1].copy()]
    time_ = 0.0
    for k in range(steps):
        time_ = stepper.step(sim, time_, dt)
        if (k + 1) % every == 0:
            ts.append(time_)
            tip.append(rod.position_collection[:, -1].copy())
    tip = np.array(tip)
    return np.array(ts), tip[:, 0], tip[:, 2], dt, steps


def downward_crossings(t, z):
    i = np.nonzero((z[:-1] > 0) & (z[1:] <= 0))[0]
    return t[i] + (t[i + 1] - t[i]) * z[i] / (z[i] - z[i + 1])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--elements", default="50,100", help="PyElastica element counts")
    ap.add_argument("--periods", type=int, default=2)
    ap.add_argument("--angle", type=float, default=0.8, help="release tip angle [rad]")
    ap.add_argument("--strips", default="uniform,tapered")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    out = []
    for name in args.strips.split(","):
        beam = STRIPS[name]
        t0 = time.perf_counter()
        ref = rod_response(beam, args.angle, periods=args.periods, rotary=True)
        t_rod = time.perf_counter() - t0
        row = {"strip": name, "tip_angle": args.angle, "rod_period_s": ref.period,
               "rod_periods_s": ref.periods.tolist(), "rod_period_error": ref.period_error,
               "rod_linear_period_s": ref.linear_period, "rod_energy_drift": ref.energy_drift,
               "rod_time_s": t_rod, "pyelastica": []}
        print(f"{name}: rod truth period {ref.period:.6f} s (periods "
              f"{', '.join(f'{p:.6f}' for p in ref.periods)}; est. error "
              f"{ref.period_error:.1e}; linear {ref.linear_period:.6f} s; energy drift "
              f"{ref.energy_drift:.1e}; {t_rod:.1f} s)", flush=True)
        d0 = math.hypot(ref.tip_x[0] - beam.length, ref.tip_z[0])
        runs = []
        for n in map(int, args.elements.split(",")):
            t0 = time.perf_counter()
            ts, tx, tz, dt, steps = pyelastica_release(beam, ref.equilibrium, n,
                                                       ref.t[-1] * 1.02)
            t_el = time.perf_counter() - t0
            cr = downward_crossings(ts, tz)[:args.periods + 1]
            per = np.diff(cr)
            # the trajectories at equal times (PyElastica's samples interpolated)
            gx = np.interp(ref.t, ts, tx)
            gz = np.interp(ref.t, ts, tz)
            dev = float(np.max(np.hypot(gx - ref.tip_x, gz - ref.tip_z)) / d0)
            rel = (per / ref.periods[:per.size] - 1).tolist()
            runs.append((n, per, gx, gz))
            row["pyelastica"].append({"elements": n, "dt_s": dt, "steps": steps,
                                      "periods_s": per.tolist(), "period_rel_diff": rel,
                                      "max_tip_distance_rel": dev, "time_s": t_el})
            print(f"  PyElastica {n:4d} elements (dt {dt:.2e} s, {steps} steps, {t_el:.0f} s): "
                  f"periods {', '.join(f'{p:.6f}' for p in per)} s, relative to the rod "
                  f"{', '.join(f'{r:+.2e}' for r in rel)}; largest tip distance "
                  f"{dev:.2e} of the release deflection", flush=True)
        if len(runs) >= 2:
            # PyElastica's error is first order in its element length (the clamp holds element
            # 0's director: the first half element is rigid): Richardson on the last two runs
            (n1, p1, x1, z1), (n2, p2, x2, z2) = runs[-2], runs[-1]
            r = n2 / n1
            k = min(p1.size, p2.size)
            pe = (r * p2[:k] - p1[:k]) / (r - 1)
            xe, ze = (r * x2 - x1) / (r - 1), (r * z2 - z1) / (r - 1)
            dev = float(np.max(np.hypot(xe - ref.tip_x, ze - ref.tip_z)) / d0)
            rel = (pe / ref.periods[:k] - 1).tolist()
            row["pyelastica_extrapolated"] = {"from": [n1, n2], "periods_s": pe.tolist(),
                                              "period_rel_diff": rel,
                                              "max_tip_distance_rel": dev}
            print(f"  PyElastica extrapolated ({n1}, {n2} elements, first order): periods "
                  f"{', '.join(f'{p:.6f}' for p in pe)} s, relative to the rod "
                  f"{', '.join(f'{v:+.2e}' for v in rel)}; largest tip distance {dev:.2e}",
                  flush=True)
        out.append(row)
    if args.json:
        print(json.dumps(out))


if __name__ == "__main__":
    main()
