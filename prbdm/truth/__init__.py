"""Truth: bending natural frequencies of a beam (docs/conventions.md §2), four models.

``analytic``
    uniform cantilevers only, ``cos(a) cosh(a) = -1`` (:mod:`prbdm.truth.analytic`).
``beam``
    Euler-Bernoulli, variable width, cubic Hermite elements (:mod:`prbdm.truth.beam`).
``plate``
    Kirchhoff plate on the planform, clamped at the root, Argyris triangles on an unstructured
    half mesh; bending modes picked by their transverse participation
    (:mod:`prbdm.truth.plate`, :mod:`prbdm.truth.modes`).
``mindlin``
    Reissner-Mindlin plate (transverse shear and rotary inertia, which Kirchhoff leaves out) on
    the plate's half mesh, P4 Lagrange triangles, symmetric family only; the same mode selection
    (:mod:`prbdm.truth.mindlin`). Its nondimensional eigenvalues depend on t/L.

>>> from prbdm.truth import bending_frequencies
>>> res = bending_frequencies(beam, model="beam", modes=5)      # doctest: +SKIP
>>> res.omega, res.freq_hz, res.time_s, res.all_modes, res.to_dict()   # doctest: +SKIP

Every model solves in nondimensional form (x by L, frequencies by ``(t/L^2) sqrt(E/(12 rho))``),
so a 5 MPa rubber strip and a 205 GPa steel panel get the same relative accuracy. The functions
hold no global state and are safe to call from threads, process pools and Dask workers. This
package imports neither torch nor matplotlib.
"""
from __future__ import annotations

import math
import time

import numpy as np

from ..errors import BadInput

# the beam limits (thin theory, width ratio, the plate's own) have their one home in
# prbdm.geometry, shared with every command; re-exported here under their old names
from ..geometry import (  # noqa: F401
    MAX_BEAM_WIDTH_RATIO,
    MAX_PLATE_THICKNESS_RATIO,
    MAX_PLATE_WIDTH_RATIO,
    MAX_THICKNESS_RATIO,
    MAX_WIDTH_RATIO,
    Beam,  # noqa: F401
    check_beam,
)
from .result import TruthResult, check_frequencies

__all__ = ["bending_frequencies", "modes_for_fit", "TruthResult", "MODELS", "MAX_MODES"]

MODELS = ("analytic", "beam", "plate", "mindlin")
#: the most modes each model may be asked for
MAX_MODES = {"analytic": 200, "beam": 100, "plate": 30, "mindlin": 30}
#: the plate's mesh options, shared by the Mindlin plate (it meshes with plate_mesh)
_MESH_OPTIONS = {"mesher", "grade", "corner_ratio", "across", "smooth", "kappa", "chord_elements"}


def _check_modes(model, modes):
    if isinstance(modes, bool) or not isinstance(modes, (int, np.integer)):
        raise BadInput(f"modes: must be an integer >= 1, got {modes!r}")
    top = MAX_MODES[model]
    if not 1 <= int(modes) <= top:
        raise BadInput(f"modes: must be an integer in [1, {top}] for model {model!r}, "
                       f"got {modes!r}")
    return int(modes)


#: the most truth modes beyond the mapped ones a plate fit asks for (reported beside the fit)
PLATE_EXTRA_MODES = 4


def modes_for_fit(model: str, joints: int, modes: int) -> int:
    """How many truth modes a fit of ``joints`` joints mapping ``modes`` modes asks ``model`` for:
    the mapped r = min(joints, modes), and up to max(joints, modes) where the model gives that
    many (the rest are reported beside the fit; a plate at most PLATE_EXTRA_MODES more).
    BadInput naming --modes when the mapped modes are more than the model gives."""
    r = min(joints, modes)
    top = MAX_MODES[model]
    if r > top:
        raise BadInput(f"--modes {r} (the modes mapped, min(--joints, --modes)): the {model} "
                       f"truth gives at most {top} modes; map at most {top}")
    if model in ("plate", "mindlin"):
        # a plate's higher bending modes cost a longer eigen-search and may not exist (a panel
        # whose modes are mostly chordwise has few): at most PLATE_EXTRA_MODES beyond the mapped
        return max(r, min(max(joints, modes), r + PLATE_EXTRA_MODES))
    return max(r, min(max(joints, modes), top))


def bending_frequencies(beam: Beam, model: str = "beam", modes: int = 5, *,
                        all_modes: bool = False, elements: int | None = None,
                        **options) -> TruthResult:
    """Bending natural frequencies of ``beam`` (docs/conventions.md §2).

    Parameters
    ----------
    beam : prbdm.geometry.Beam
    model : ``"analytic"`` (uniform beams only), ``"beam"``, ``"plate"`` or ``"mindlin"``
    modes : number of bending modes R (>= 1)
    all_modes : plate only: also solve the antisymmetric (torsional) family, so that
        ``all_modes`` lists every mode up to the highest kept one, kept or not (mindlin solves
        the symmetric family only: ``all_modes`` lists every computed symmetric mode either way)
    elements : mesh resolution along the span (``None``: automatic, see docs/validation.md); beam:
        base number of elements before the width grading; plate, mindlin: ``1/h0`` for the mesh
        size h0
    options : beam: ``grading`` (bool, default True); plate: ``selection`` ("section" or
        "participation"), and the mesh options ``grade``, ``corner_ratio``, ``across``; mindlin:
        the plate's, plus ``degree`` (2, 3 or 4, default 4) and ``shear_factor`` (default 5/6)

    Returns
    -------
    TruthResult with ``omega`` [rad/s] ascending, ``freq_hz``, ``time_s``, ``all_modes``, ...

    Raises
    ------
    prbdm.errors.BadInput for an unknown model, invalid ``modes``, ``analytic`` on a
    non-uniform beam, a beam outside thin theory (thickness > ``MAX_THICKNESS_RATIO`` L; beam and
    analytic: full width > ``MAX_BEAM_WIDTH_RATIO`` L; plate: thickness >
    ``MAX_PLATE_THICKNESS_RATIO`` x full width; mindlin: the plate's limits), or a beam too
    degenerate to be solved reliably.
    """
    if model not in MODELS:
        raise BadInput(f"model: must be one of {', '.join(MODELS)}, got {model!r}")
    bending = None
    modes = _check_modes(model, modes)
    check_beam(beam, model)
    if elements is not None:
        if isinstance(elements, bool) or not isinstance(elements, (int, np.integer)) \
                or elements < 2:
            raise BadInput(f"elements: must be an integer >= 2 or None, got {elements!r}")
    # the solver modules are imported lazily (scikit-fem only when a FEM model runs); the clock
    # starts after the imports, so time_s is the time of the solve itself
    if model == "analytic":
        from .analytic import beam_omega_scale, solve_analytic
        t0 = time.perf_counter()
        if options:
            raise BadInput(f"model 'analytic' takes no options, got {sorted(options)}")
        out = solve_analytic(beam, modes)
        scale = beam_omega_scale(beam)
        symmetric_entries = None
    elif model == "beam":
        from .analytic import beam_omega_scale
        from .beam import solve_beam
        t0 = time.perf_counter()
        unknown = set(options) - {"grading"}
        if unknown:
            raise BadInput(f"model 'beam': unknown option {sorted(unknown)[0]!r}")
        out = solve_beam(beam, modes, elements=elements, **options)
        scale = beam_omega_scale(beam)
        symmetric_entries = None
    else:
        # plate and mindlin: the same half mesh, mesh options, mode selection and scale
        from .modes import SELECTIONS
        from .plate import plate_omega_scale
        if model == "mindlin":
            from .mindlin import DEGREES
            from .mindlin import solve_mindlin as solve
            own, extra = {"degree", "shear_factor"}, {}
        else:
            from .plate import solve_plate as solve
            own, extra = set(), {"all_modes": all_modes}
        t0 = time.perf_counter()
        if model == "mindlin" and "kappa" in options:   # the mesher's, not the shear factor
            raise BadInput("model 'mindlin': option 'kappa' is the plate mesher's, not the "
                           "shear factor; the shear factor is 'shear_factor' (default 5/6)")
        unknown = set(options) - _MESH_OPTIONS - {"selection"} - own
        if unknown:
            raise BadInput(f"model {model!r}: unknown option {sorted(unknown)[0]!r}")
        options.setdefault("selection", "spectrum")
        if options["selection"] not in SELECTIONS:
            raise BadInput(f"selection: must be one of {', '.join(SELECTIONS)}, "
                           f"got {options['selection']!r}")
        if model == "mindlin":
            degree = options.get("degree", 4)
            if isinstance(degree, bool) or degree not in DEGREES:
                raise BadInput(f"degree: must be one of {', '.join(map(str, DEGREES))}, "
                               f"got {degree!r}")
            kappa = options.get("shear_factor", 5.0 / 6.0)
            if isinstance(kappa, bool) or not isinstance(kappa, (int, float, np.floating)) \
                    or not 0 < kappa <= 1:
                raise BadInput(f"shear_factor: must be a number in (0, 1], got {kappa!r}")
        try:
            out = solve(beam, modes, elements=elements, **extra, **options)
        except (ValueError, ArithmeticError, RuntimeError) as exc:
            raise BadInput(f"model {model!r}: this planform cannot be solved reliably ({exc})") \
                from None
        # lambda = (omega / omega_p)^2 for both (for mindlin a function of t/L too)
        scale = plate_omega_scale(beam)
        symmetric_entries = out["entries"]
        if options["selection"] == "spectrum":
            bending = _spectrum(model, out, modes)
    omega = check_frequencies(model, out["lam"], scale)
    if symmetric_entries is None:
        entries = [{"omega": float(o), "freq_hz": float(o / (2 * math.pi)), "lambda": float(l),
                    "participation": float(p), "symmetry": "symmetric", "kept": True}
                   for o, l, p in zip(omega, out["lam"], out["participation"])]
    else:
        entries = []
        for e in symmetric_entries:
            o = scale * math.sqrt(max(e["lambda"], 0.0))
            entries.append({"omega": o, "freq_hz": o / (2 * math.pi), **e})
    if bending is not None:
        for b in bending:
            b["omega"] = float(scale * math.sqrt(b["lambda"]))
            b["freq_hz"] = b["omega"] / (2 * math.pi)
    return TruthResult(model=model, omega=omega, freq_hz=omega / (2 * math.pi),
                       time_s=time.perf_counter() - t0, all_modes=entries, mesh=out["mesh"],
                       omega_scale=scale, shapes=out.get("shapes"), bending=bending)


def _spectrum(model: str, out: dict, modes: int) -> list:
    """Replace the solver's picked eigenvalues ``out["lam"]`` by the bending spectrum of its
    symmetric modes (:func:`prbdm.truth.modes.bending_spectrum`; the picked ones stay in the
    entries as ``kept``), and return each bending mode's composition. BadInput where the modes
    computed do not add up to enough bending weight."""
    from .modes import bending_spectrum, bending_weight

    sym = [e for e in out["entries"] if e["symmetry"] == "symmetric"]
    lam = np.array([e["lambda"] for e in sym])
    frac = np.array([e["section_fraction"] for e in sym])
    for e, p in zip(sym, bending_weight(frac)):
        e["bending_weight"] = float(p)
    values, composition, length = bending_spectrum(lam, frac, modes)
    if not length > modes:
        raise BadInput(f"model {model!r}: the {len(sym)} symmetric modes computed add up to a "
                       f"bending weight of {length:.3g}, and {modes} bending modes need more "
                       f"than {modes}: this planform's modes are mostly chordwise (at most "
                       f"{max(int(np.ceil(length)) - 1, 0)} bending modes can be given)")
    out["lam"] = values
    out["mesh"]["selection"] = "spectrum"
    return [{"mode": j + 1, "lambda": float(values[j]),
             "composition": [{"symmetric_mode": i + 1, "weight": w,
                              "section_fraction": float(frac[i])} for i, w in comp]}
            for j, comp in enumerate(composition)]
