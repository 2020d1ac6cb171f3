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
from collections.abc import Callable
from dataclasses import dataclass, field

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

__all__ = ["bending_frequencies", "modes_for_fit", "TruthResult", "MODELS", "MAX_MODES",
           "SOLVERS"]


# ----------------------------------------------------------------------------- the solver table
# The solver modules are imported lazily (scikit-fem only when a FEM model runs): an entry's
# ``load`` imports its solver and frequency scale when its model is asked for.
def _load_analytic():
    from .analytic import beam_omega_scale, solve_analytic
    return solve_analytic, beam_omega_scale


def _load_beam():
    from .analytic import beam_omega_scale
    from .beam import solve_beam
    return solve_beam, beam_omega_scale


def _load_plate():
    from .plate import plate_omega_scale, solve_plate
    return solve_plate, plate_omega_scale


def _load_mindlin():
    from .mindlin import solve_mindlin
    from .plate import plate_omega_scale
    return solve_mindlin, plate_omega_scale


# the option checks: each raises BadInput naming its option
def _check_selection(value):
    from .modes import SELECTIONS
    if value not in SELECTIONS:
        raise BadInput(f"selection: must be one of {', '.join(SELECTIONS)}, got {value!r}")


def _check_degree(value):
    from .mindlin import DEGREES
    if isinstance(value, bool) or value not in DEGREES:
        raise BadInput(f"degree: must be one of {', '.join(map(str, DEGREES))}, got {value!r}")


def _check_shear_factor(value):
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating)) \
            or not 0 < value <= 1:
        raise BadInput(f"shear_factor: must be a number in (0, 1], got {value!r}")


@dataclass(frozen=True)
class Solver:
    """One truth model of :data:`SOLVERS`.

    load: () -> (solve, omega_scale), the imports done when the model runs. options: the keyword
    options it takes, each with its check (None: the solver checks it); ``defaults``: the values
    some of them get when not given. max_modes: the most modes it may be asked for. takes: which
    of :func:`bending_frequencies`' own arguments (``elements``, ``all_modes``) its solve takes.
    plate_mesh: solved on the plate's half mesh (its entries list every symmetric mode, the
    bending spectrum is taken from them, and a failed solve is a planform that cannot be solved
    reliably). hints: options it refuses with a message of their own rather than as unknown."""

    load: Callable[[], tuple[Callable, Callable]]
    options: dict = field(default_factory=dict)
    max_modes: int = 100
    takes: tuple = ()
    plate_mesh: bool = False
    defaults: dict = field(default_factory=dict)
    hints: dict = field(default_factory=dict)


#: the plate's mesh options, checked by the mesher; the Mindlin plate meshes with it too
_MESH_OPTIONS = dict.fromkeys(("mesher", "grade", "corner_ratio", "across", "smooth", "kappa",
                               "chord_elements"))
_PLATE_OPTIONS = {**_MESH_OPTIONS, "selection": _check_selection}

#: model name -> its solver, the options it takes with their checks, its mode limit
SOLVERS = {
    "analytic": Solver(_load_analytic, max_modes=200),
    "beam": Solver(_load_beam, {"grading": None}, max_modes=100, takes=("elements",)),
    "plate": Solver(_load_plate, _PLATE_OPTIONS, max_modes=30,
                    takes=("elements", "all_modes"), plate_mesh=True,
                    defaults={"selection": "spectrum"}),
    "mindlin": Solver(
        _load_mindlin,
        {**{k: v for k, v in _PLATE_OPTIONS.items() if k != "kappa"},
         "degree": _check_degree, "shear_factor": _check_shear_factor},
        max_modes=30, takes=("elements",), plate_mesh=True, defaults={"selection": "spectrum"},
        hints={"kappa": "option 'kappa' is the plate mesher's, not the shear factor; the shear "
                        "factor is 'shear_factor' (default 5/6)"}),
}
MODELS = tuple(SOLVERS)
#: the most modes each model may be asked for
MAX_MODES = {name: s.max_modes for name, s in SOLVERS.items()}


def _check_options(model: str, solver: Solver, options: dict) -> dict:
    """The options with the solver's defaults filled in, each checked; BadInput naming the first
    one refused."""
    for name in options:
        if name in solver.hints:
            raise BadInput(f"model {model!r}: {solver.hints[name]}")
    unknown = set(options) - set(solver.options)
    if unknown and not solver.options:
        raise BadInput(f"model {model!r} takes no options, got {sorted(options)}")
    if unknown:
        raise BadInput(f"model {model!r}: unknown option {sorted(unknown)[0]!r}")
    options = {**solver.defaults, **options}
    for name, check in solver.options.items():
        if check is not None and name in options:
            check(options[name])
    return options


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
    options : beam: ``grading`` (bool, default True); plate: ``selection`` ("spectrum", the
        default, "section" or "participation"), and the mesh options ``grade``,
        ``corner_ratio``, ``across``; mindlin: the plate's, plus ``degree`` (2, 3 or 4, default
        4) and ``shear_factor`` (default 5/6). Each model's options and their checks: the table
        :data:`SOLVERS`.

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
    if model not in SOLVERS:
        raise BadInput(f"model: must be one of {', '.join(MODELS)}, got {model!r}")
    solver = SOLVERS[model]
    modes = _check_modes(model, modes)
    check_beam(beam, model)
    if elements is not None:
        if isinstance(elements, bool) or not isinstance(elements, (int, np.integer)) \
                or elements < 2:
            raise BadInput(f"elements: must be an integer >= 2 or None, got {elements!r}")
    solve, omega_scale = solver.load()
    t0 = time.perf_counter()     # after the imports: time_s is the time of the solve itself
    options = _check_options(model, solver, options)
    given = {"elements": elements, "all_modes": all_modes}
    args = {name: given[name] for name in solver.takes}
    bending = symmetric_entries = None
    if not solver.plate_mesh:
        out = solve(beam, modes, **args, **options)
    else:
        try:
            out = solve(beam, modes, **args, **options)
        except (ValueError, ArithmeticError, RuntimeError) as exc:
            raise BadInput(f"model {model!r}: this planform cannot be solved reliably ({exc})") \
                from None
        symmetric_entries = out["entries"]
        if options["selection"] == "spectrum":
            bending = _spectrum(model, out, modes)
    # lambda = (omega / omega_scale)^2 (for mindlin a function of t/L too)
    scale = omega_scale(beam)
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
