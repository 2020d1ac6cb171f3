"""The rod truth's checks that need no PyElastica (docs/large-deflection.md): the elastica closed
form, the beam truths at rest, the SPEC §3 stress-free arc, convergence about bent shapes, and
the runtime of each public function.

    python benchmarks/rod_checks.py
"""
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from test_truth_rod import EI, TABLE2, TAPERED, UNIFORM, bisshopp_drucker  # noqa: E402

from prbdm.truth import bending_frequencies  # noqa: E402
from prbdm.truth.rod import arc_shape, chain_shape, rod_frequencies, rod_response, rod_static  # noqa: E402

print("1. elastica, perpendicular tip load (Bisshopp & Drucker), uniform strip, "
      "|rod - closed form|:")
for a in (1, 2, 5, 10, 50, 100):
    phi0, dh, dv = bisshopp_drucker(a)
    t = time.perf_counter()
    eq = rod_static(UNIFORM, force=a * EI(UNIFORM))
    dt = time.perf_counter() - t
    print(f"   alpha {a:5g}: tip angle {phi0:.6f} rad, dh/L {dh:.6f}, dv/L {dv:.6f};"
          f" errors {abs(eq.tip_angle - phi0):.1e}, {abs(1 - eq.tip_x - dh):.1e}, "
          f"{abs(eq.tip_z - dv):.1e}; rod_static {dt:.2f} s")
print("2. straight rod at rest against the beam truths (omega_rod / omega_ref - 1, modes 1-4):")
for name, beam in (("uniform", UNIFORM), ("tapered", TAPERED)):
    r = rod_frequencies(beam, modes=4)
    b = bending_frequencies(beam, model="beam", modes=4)
    print(f"   {name} vs beam: {np.array2string(r.omega / b.omega - 1, precision=2)}; "
          f"rod_frequencies {r.time_s:.3f} s")
    if name == "uniform":
        a = bending_frequencies(beam, model="analytic", modes=4)
        print(f"   uniform vs analytic: {np.array2string(r.omega / a.omega - 1, precision=2)}")
print("3. Table-2 beam, stress-free arc of 1.4 rad vs straight (SPEC §3: +4/-16/-7/-4 %):")
s = rod_frequencies(TABLE2, modes=4).omega
arc = rod_frequencies(TABLE2, about=arc_shape(TABLE2, 1.4), modes=4).omega
mom = rod_frequencies(TABLE2, about=rod_static(TABLE2, tip_angle=1.4, load="moment"),
                      modes=4).omega
print(f"   arc: {np.array2string(100 * (arc / s - 1), precision=2)} %; end-moment "
      f"equilibrium - arc: {np.max(np.abs(mom / arc - 1)):.1e}")
print("4. convergence (tapered strip), lam relative to elements 48 x degree 8:")
shapes = {"equilibrium, tip force, 1.2 rad": rod_static(TAPERED, tip_angle=1.2),
          "stress-free 4R chain pose, 0.3 rad/joint":
              chain_shape(TAPERED, [0.125, 0.25, 0.25, 0.25, 0.125], 0.3)}
for label, about in shapes.items():
    ref = rod_frequencies(TAPERED, about=about, modes=6, elements=48, degree=8).lam
    print(f"   {label}:")
    for e, p in ((12, 2), (24, 2), (48, 2), (6, 4), (12, 6), (24, 6)):
        r = rod_frequencies(TAPERED, about=about, modes=6, elements=e, degree=p)
        print(f"     elements {e:2d} degree {p} ({r.mesh['unknowns']:3d} unknowns): max "
              f"|rel. diff| modes 1-6 {np.max(np.abs(r.lam / ref - 1)):.1e} ({r.time_s:.3f} s)")
print("5. rod_response (uniform strip, release at 0.8 rad, 3 periods, defaults):")
r = rod_response(UNIFORM, 0.8)
print(f"   period {r.period:.6f} s (periods {np.array2string(r.periods, precision=6)}), "
      f"linear {r.linear_period:.6f} s, est. error {r.period_error:.1e}, energy drift "
      f"{r.energy_drift:.1e}, {r.time_s:.1f} s")
