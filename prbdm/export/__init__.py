"""A PRBDM in the user's simulator: MJCF (MuJoCo), URDF and a plain JSON of physical parameters.

Two steps, so that any source of a PRBDM can feed the writers:

1. :func:`prbdm_from_fit` turns ``{gamma, k, law, poses}`` (what ``prbdm fit --json`` prints;
   later also what the trained network predicts) and the beam into a *description*: a plain,
   JSON-ready dict of bodies, hinges and SI parameters. No file format is involved yet.
2. :func:`to_mjcf`, :func:`to_urdf`, :func:`to_json` write a description in one format;
   :func:`export` does both steps and writes the file atomically.

One module per job: :mod:`.fits` (run a fit, read and check a fit file), :mod:`.description`
(the description of step 1), :mod:`.writers` (step 2) and :mod:`.verify` (the chain's
frequencies and free vibration in MuJoCo, for the checks). The names below are re-exported
here; import them from ``prbdm.export``. The physics (link table, base stiffness of either law,
eigenvalues, lamina integrals) is the chain's, :mod:`prbdm.chain`, in NumPy: exporting a given
fit needs no torch (only :func:`run_fit`, which fits, loads it).

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

from .description import AXIS, prbdm_from_fit
from .fits import check_fit, check_fit_links, load_fit, run_fit
from .verify import mujoco_free_vibration, mujoco_linear_frequencies
from .writers import (
    FORMATS,
    URDF_NS,
    WRITERS,
    export,
    format_from_path,
    to_json,
    to_mjcf,
    to_urdf,
)

__all__ = ["FORMATS", "AXIS", "prbdm_from_fit", "run_fit", "load_fit", "check_fit",
           "check_fit_links", "to_mjcf", "to_urdf", "to_json", "WRITERS", "export",
           "format_from_path", "URDF_NS", "mujoco_linear_frequencies",
           "mujoco_free_vibration"]
