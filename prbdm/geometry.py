"""The beam: a symmetric planform of uniform thickness, clamped at x = 0 (docs/conventions.md §1).

The planform is given by its half-width ``w(x)``, piecewise linear through stations
``(x_k, w_k)``; the beam bends out of plane (deflection along z). Everything here is NumPy only, so
the truth solvers can use it without importing torch; the differentiable section integrals used by
the PRBDM live in :mod:`prbdm.sections`.

Units are SI throughout: metres, pascals, kilograms per cubic metre.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import BadInput

__all__ = ["Material", "Beam", "STEEL", "random_beam", "RANDOM_DEFAULTS", "load_beam",
           "check_beam", "unit_warnings", "simplify_planform"]


def _show(v) -> str:
    """A value for a message: NumPy scalars as plain Python numbers (``0.1``, not
    ``np.float64(0.1)``), anything else by its repr."""
    if isinstance(v, (np.floating, np.integer, np.bool_)):
        v = v.item()
    return repr(v)


@dataclass(frozen=True)
class Material:
    """Isotropic linear-elastic material.

    E: Young's modulus [Pa]; rho: density [kg/m^3]; nu: Poisson's ratio [-] (plate truth only).
    """

    E: float = 205e9
    rho: float = 7850.0
    nu: float = 0.28

    def __post_init__(self):
        for name in ("E", "rho", "nu"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)):
                raise BadInput(f"material.{name}: must be a number, got {_show(v)}")
            if not math.isfinite(v):
                raise BadInput(f"material.{name}: must be finite, got {_show(v)}")
        if not self.E > 0:
            raise BadInput(f"material.E: must be > 0 Pa, got {_show(self.E)}")
        if not self.rho > 0:
            raise BadInput(f"material.rho: must be > 0 kg/m^3, got {_show(self.rho)}")
        if not -1.0 < self.nu < 0.5:
            raise BadInput(f"material.nu: must lie in (-1, 0.5), got {_show(self.nu)}")

    def to_dict(self) -> dict:
        return {"E": float(self.E), "rho": float(self.rho), "nu": float(self.nu)}


#: AISI 4340 steel, the paper's material and the default (docs/conventions.md §1).
STEEL = Material()


def _as_float_array(value, name: str) -> np.ndarray:
    if isinstance(value, (list, tuple)):
        # NumPy would read "1e-3" and True as numbers: a beam file must hold numbers only
        bad = [v for v in value if isinstance(v, (bool, str, bytes))]
        if bad:
            raise BadInput(f"{name}: must be a list of numbers, got {_show(bad[0])}")
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise BadInput(f"{name}: must be a list of numbers") from None
    if arr.ndim != 1:
        raise BadInput(f"{name}: must be a one-dimensional list of numbers")
    if not np.all(np.isfinite(arr)):
        raise BadInput(f"{name}: all values must be finite")
    return arr


@dataclass(frozen=True)
class Beam:
    """A cantilever panel: stations ``x`` [m], half-widths ``half_width`` [m] at those stations,
    uniform ``thickness`` [m], and a :class:`Material`.

    ``x[0] == 0`` (the clamp) and ``x`` strictly increasing; ``x[-1]`` is the length ``L``.
    """

    x: np.ndarray
    half_width: np.ndarray
    thickness: float
    material: Material = field(default_factory=Material)
    name: str = ""

    def __post_init__(self):
        x = _as_float_array(self.x, "x")
        w = _as_float_array(self.half_width, "half_width")
        if x.size < 2:
            raise BadInput(f"x: needs at least 2 stations (root and tip), got {x.size}")
        if w.size != x.size:
            raise BadInput(f"half_width: needs one value per station of x ({x.size}), got {w.size}")
        if x[0] != 0.0:
            raise BadInput(f"x: must start at 0 (the clamp), got x[0] = {_show(x[0])}")
        steps = np.diff(x)
        if np.any(steps <= 0):
            k = int(np.argmax(steps <= 0))
            raise BadInput(f"x: must be strictly increasing, but x[{k + 1}] = {_show(x[k + 1])} <= "
                           f"x[{k}] = {_show(x[k])}")
        if np.any(w <= 0):
            k = int(np.argmax(w <= 0))
            raise BadInput(f"half_width: must be > 0 m everywhere, got half_width[{k}] = {_show(w[k])}")
        t = self.thickness
        if isinstance(t, bool) or not isinstance(t, (int, float, np.floating, np.integer)):
            raise BadInput(f"thickness: must be a number, got {_show(t)}")
        if not math.isfinite(t) or not t > 0:
            raise BadInput(f"thickness: must be a finite number > 0 m, got {_show(t)}")
        if not isinstance(self.material, Material):
            raise BadInput("material: must be a Material")
        x.setflags(write=False)
        w.setflags(write=False)
        object.__setattr__(self, "x", x)
        object.__setattr__(self, "half_width", w)
        object.__setattr__(self, "thickness", float(t))
        object.__setattr__(self, "name", str(self.name))

    # ------------------------------------------------------------------ basic properties
    @property
    def length(self) -> float:
        """L [m]."""
        return float(self.x[-1])

    @property
    def area(self) -> float:
        """Planform area [m^2]: the integral of the full width 2 w(x)."""
        return float(np.sum(np.diff(self.x) * (self.half_width[1:] + self.half_width[:-1])))

    @property
    def mass(self) -> float:
        """Total mass [kg]."""
        return self.material.rho * self.thickness * self.area

    def width_at(self, xq) -> np.ndarray:
        """Full width b(x) = 2 w(x) [m] at stations ``xq`` (linear interpolation)."""
        return 2.0 * np.interp(xq, self.x, self.half_width)

    def is_uniform(self, rtol: float = 1e-12) -> bool:
        """True for a constant half-width (the analytic truth applies)."""
        w = self.half_width
        return bool(np.all(np.abs(w - w[0]) <= rtol * abs(w[0])))

    # ------------------------------------------------------------------ conversions
    def to_dict(self) -> dict:
        """The beam-file dictionary of docs/conventions.md §1."""
        d = {"x": self.x.tolist(), "half_width": self.half_width.tolist(),
             "thickness": self.thickness, "material": self.material.to_dict()}
        if self.name:
            d = {"name": self.name, **d}
        return d

    def to_json(self, path=None, **kwargs) -> str:
        text = json.dumps(self.to_dict(), **kwargs)
        if path is not None:
            Path(path).write_text(text + "\n")
        return text

    @classmethod
    def from_dict(cls, data) -> "Beam":
        """Build from a beam-file dictionary (docs/conventions.md §1). Unknown keys are an error."""
        if not isinstance(data, dict):
            raise BadInput("beam: must be a JSON object with keys x, half_width, thickness")
        allowed = {"name", "x", "half_width", "thickness", "material"}
        unknown = sorted(set(data) - allowed)
        if unknown:
            raise BadInput(f"beam: unknown key {unknown[0]!r}; allowed keys are "
                           f"{', '.join(sorted(allowed))}")
        for key in ("x", "half_width", "thickness"):
            if key not in data:
                raise BadInput(f"beam: missing required key {key!r}")
        mat = data.get("material", {})
        if not isinstance(mat, dict):
            raise BadInput("material: must be an object with keys E, rho, nu")
        unknown = sorted(set(mat) - {"E", "rho", "nu"})
        if unknown:
            raise BadInput(f"material: unknown key {unknown[0]!r}; allowed keys are E, nu, rho")
        material = Material(**mat)          # the values given are checked first
        # all or nothing (docs/conventions.md §6, "Material block"): a block with only E would take
        # steel's density, and a 69 GPa aluminium panel would weigh 2.9x what it does
        missing = [key for key in ("E", "rho", "nu") if key not in mat]
        if "material" in data and missing:
            raise BadInput(f"material: missing key(s) {', '.join(missing)}; give all of E [Pa], "
                           "rho [kg/m^3] and nu, or leave out the material block for steel "
                           f"(E = {STEEL.E:g} Pa, rho = {STEEL.rho:g} kg/m^3, nu = {STEEL.nu:g})")
        name = data.get("name", "")
        if not isinstance(name, str):
            raise BadInput("name: must be a string")
        return cls(x=data["x"], half_width=data["half_width"], thickness=data["thickness"],
                   material=material, name=name)

    @classmethod
    def from_polygon(cls, polygon, thickness: float, material: Material | None = None,
                     name: str = "", rtol: float = 1e-9) -> "Beam":
        """Build from a shapely polygon symmetric about the x axis, root edge on x = 0.

        The polygon must be valid (not self-intersecting) and its upper boundary must be a
        function of x (one half-width per station).
        """
        from shapely import affinity
        from shapely.geometry import Polygon  # shapely only when polygons are used

        if not isinstance(polygon, Polygon):
            raise BadInput("polygon: must be a shapely Polygon")
        if polygon.is_empty or not polygon.is_valid:
            raise BadInput("polygon: must be a valid, non-self-intersecting polygon")
        if len(polygon.interiors):
            raise BadInput("polygon: must have no holes")
        xmin, ymin, xmax, ymax = polygon.bounds
        scale = max(xmax - xmin, ymax - ymin)
        tol = rtol * scale
        if abs(xmin) > tol:
            raise BadInput(f"polygon: root edge must lie on x = 0, got min x = {_show(xmin)}")
        mirrored = affinity.scale(polygon, xfact=1.0, yfact=-1.0, origin=(0, 0))
        if polygon.symmetric_difference(mirrored).area > rtol * polygon.area + tol ** 2:
            raise BadInput("polygon: must be symmetric about the x axis")
        coords = np.asarray(polygon.exterior.coords)[:-1]
        upper = coords[coords[:, 1] > tol]
        xs = np.unique(np.concatenate([[0.0], upper[:, 0], [xmax]]))
        xs[0] = 0.0
        # half-width at each station: the top of the polygon's vertical section there
        ws = np.array([_polygon_top(polygon, xi, scale) for xi in xs])
        beam = cls(x=xs, half_width=ws, thickness=thickness,
                   material=material or Material(), name=name)
        if beam.to_polygon().symmetric_difference(polygon).area > 1e-6 * polygon.area:
            raise BadInput("polygon: the upper boundary must be a function of x "
                           "(one half-width at each station)")
        return beam

    def to_polygon(self):
        """The planform as a shapely polygon (root edge on x = 0)."""
        from shapely.geometry import Polygon

        upper = np.column_stack([self.x, self.half_width])
        lower = np.column_stack([self.x[::-1], -self.half_width[::-1]])
        return Polygon(np.vstack([upper, lower]))


def _polygon_top(polygon, xi: float, scale: float) -> float:
    from shapely.geometry import LineString

    # nudge end stations inside so that a vertical root or tip edge is cut cleanly
    eps = 1e-9 * scale
    xmin, _, xmax, _ = polygon.bounds
    xc = min(max(xi, xmin + eps), xmax - eps)
    cut = polygon.intersection(LineString([(xc, -2 * scale), (xc, 2 * scale)]))
    if cut.is_empty:
        raise BadInput(f"polygon: no material at x = {_show(xi)}")
    return float(cut.bounds[3])


#: largest max/min half-width ratio the PRBDM accepts (model and surrogate). The truth stops at
#: 1e6 (prbdm.truth.MAX_WIDTH_RATIO); the rigid links stay accurate far beyond, but past ~1e17
#: a link's end width rounds to zero or below in float64 and the eigen-solve fails with an
#: unhelpful LinAlgError (measured: a 0.1 m root tapering to 1e-18 m), so refuse well before.
MAX_PRBDM_WIDTH_RATIO = 1e12


def check_prbdm_width_ratio(beam: Beam) -> None:
    """BadInput naming ``half_width`` if ``beam`` varies in width by more than
    :data:`MAX_PRBDM_WIDTH_RATIO`."""
    w = beam.half_width
    ratio = float(w.max() / w.min())
    if not ratio <= MAX_PRBDM_WIDTH_RATIO:
        raise BadInput(f"half_width: varies by a factor {ratio:.3g} (max/min); the PRBDM accepts "
                       f"at most {MAX_PRBDM_WIDTH_RATIO:.0e}")


# ---------------------------------------------------------------------- validation
# One home for every limit a beam must meet before any command uses it (truth, fit, predict,
# eval, compare, export, simulate all call check_beam), so each command refuses the same beams
# with the same message. prbdm.truth re-exports the truth's limits under their old names.

#: planforms whose width varies more than this (max/min) are refused as degenerate, every model
MAX_WIDTH_RATIO = 1e6
#: the plate model is verified up to this width ratio (a needle tapering 0.1 m -> 1e-5 m stays
#: within 1.3e-4 of its slender-beam limit); at 1e5 its first frequency came out 3.5x (mapped
#: mesh) or 2.3x (Delaunay) too high, so it is refused beyond instead of answering wrongly
MAX_PLATE_WIDTH_RATIO = 1e4
#: thin theory only (Euler-Bernoulli beam, Kirchhoff plate: no shear, no rotary inertia): a beam
#: thicker than this fraction of its length is refused, all models. The paper's random generator
#: (``random_beam``) stays at or below 0.05 (t <= 50 mm, L = 1 m)
MAX_THICKNESS_RATIO = 0.2
#: ``beam`` and ``analytic``: largest full width over length, ``2 max(half_width) / L``. Beyond it
#: the panel is a plate clamped along its long edge, not a beam (the same bound as the plate
#: model's half-width <= 5 L); random beams reach at most 1 (half-width <= 0.5 m, L = 1 m)
MAX_BEAM_WIDTH_RATIO = 10.0
#: ``plate``: largest half-width over length (the plate mesh is verified up to it)
MAX_PLATE_ASPECT = 5.0
#: ``plate``: largest thickness over full width, ``t / (2 max(half_width))``; a panel thicker
#: than half its widest chord is no thin plate. Random beams: at most 0.11 in 20 000 (seed 0)
MAX_PLATE_THICKNESS_RATIO = 0.5
#: ``plate``: smallest interior corner of the half planform [degrees]. A sharper corner is the
#: tip of a tongue (two stations a millimetre apart with a large change of half-width between
#: them) that the plate mesh can only fill with slivers, whose stiffness matrix is numerically
#: singular: on random panels with corners below 0.61 degrees the plate's first two frequencies
#: changed by up to a factor 9 between two mesh densities, with no warning; between 1 and 1.2
#: degrees by at most 1.8e-4 (docs/validation.md, "Sharp corners"). Random beams: 2.9 % of the paper's
#: generator (seed 0)
MIN_PLATE_CORNER_DEGREES = 1.0
#: hard limits, far outside any panel, so that nothing downstream over- or underflows in float64
#: (L^4 and t^3 appear in the frequency scale): field -> (low, high, unit)
HARD_LIMITS = {"L": (1e-9, 1e9, "m"), "thickness": (1e-9, 1e9, "m"),
               "max(half_width)": (1e-9, 1e9, "m"), "material.E": (1.0, 1e15, "Pa"),
               "material.rho": (1e-3, 1e7, "kg/m^3")}
#: what a real panel plausibly has; outside, a warning names the likely unit mistake (not an
#: error: a 150 m blade or an aerogel is possible). Field -> (low, high): L from a 0.1 mm MEMS
#: cantilever to a 100 m blade; E from a soft silicone (0.1 MPa; below it a modulus in MPa, e.g.
#: 69000 for aluminium, would pass unnoticed) to diamond (1.2e12 Pa); rho from a foam
#: (10 kg/m^3) to osmium (22 600 kg/m^3); thickness relative to L from a 10 um foil on 1 m
PLAUSIBLE = {"L": (1e-4, 100.0), "E": (1e5, 1.5e12), "rho": (10.0, 2.3e4),
             "thickness/L": (1e-5, MAX_THICKNESS_RATIO)}


def smallest_corner(beam: Beam) -> tuple[float, float, float]:
    """The smallest interior angle [degrees] of the half planform (clamped root edge, axis,
    tip edge and the free edge ``y = half_width(x)``) and its vertex ``(x, y)`` [m]."""
    x, w = beam.x, beam.half_width
    # counter-clockwise: along the axis, up the tip edge, back along the free edge, down the root
    P = np.vstack([[[x[0], 0.0], [x[-1], 0.0]], np.column_stack([x[::-1], w[::-1]])])
    a = np.roll(P, 1, axis=0) - P                   # to the previous vertex
    b = np.roll(P, -1, axis=0) - P                  # to the next
    angle = np.degrees(np.arctan2(b[:, 0] * a[:, 1] - b[:, 1] * a[:, 0],
                                  np.einsum("ij,ij->i", a, b))) % 360.0
    i = int(np.argmin(angle))
    return float(angle[i]), float(P[i, 0]), float(P[i, 1])


def check_beam(beam: Beam, model: str | None = None) -> None:
    """BadInput (one line naming the field and the allowed range) unless ``beam`` is within
    thin theory, the width-ratio limit and the hard limits; ``model`` ``"beam"``/``"analytic"``
    or ``"plate"``/``"mindlin"`` adds that truth model's own limits (the Mindlin plate shares the
    Kirchhoff plate's mesh, hence its limits). ``None``: the limits every model shares
    (the PRBDM's own commands: ``eval``)."""
    if not isinstance(beam, Beam):
        raise BadInput(f"beam: must be a prbdm.geometry.Beam, got {type(beam).__name__}")
    w = beam.half_width
    L = beam.length
    ratio = float(w.max() / w.min())
    if not math.isfinite(ratio) or ratio > MAX_WIDTH_RATIO:
        raise BadInput(f"half_width: varies by a factor {ratio:.3g} (max/min); at most "
                       f"{MAX_WIDTH_RATIO:.0e} is accepted, beyond which the planform "
                       "degenerates into disconnected pieces")
    t_ratio = beam.thickness / L
    if not t_ratio <= MAX_THICKNESS_RATIO:
        # the usual cause: a thickness in millimetres beside a length in metres
        hint = (f"; if it was meant in millimetres, thickness = {beam.thickness * 1e-3:.6g} m"
                if t_ratio * 1e-3 <= MAX_THICKNESS_RATIO else "")
        raise BadInput(f"thickness: must be at most {MAX_THICKNESS_RATIO:g} L for thin-beam and "
                       f"thin-plate theory; this beam is {t_ratio:.3g} L thick "
                       f"(t = {beam.thickness:.6g} m, L = {L:.6g} m){hint}")
    if model in ("beam", "analytic"):
        b_ratio = float(2 * w.max() / L)
        if not b_ratio <= MAX_BEAM_WIDTH_RATIO:
            raise BadInput(f"half_width: model {model!r} needs a full width 2 max(half_width) of "
                           f"at most {MAX_BEAM_WIDTH_RATIO:g} L (beyond it the panel is a plate, "
                           f"not a beam); this planform is {b_ratio:.3g} L wide (L = {L:.6g} m)")
    if model in ("plate", "mindlin"):
        if ratio > MAX_PLATE_WIDTH_RATIO:
            raise BadInput(f"half_width: varies by a factor {ratio:.3g} (max/min); model {model!r} "
                           f"accepts at most {MAX_PLATE_WIDTH_RATIO:.0e} (the beam model "
                           f"accepts {MAX_WIDTH_RATIO:.0e})")
        aspect = float(w.max() / L)
        if aspect > MAX_PLATE_ASPECT:
            raise BadInput(f"half_width: the {model} model needs a half-width of at most "
                           f"{MAX_PLATE_ASPECT:g} L; this planform is {aspect:.3g} L wide "
                           f"(L = {L:.6g} m)")
        tb = float(beam.thickness / (2 * w.max()))
        if not tb <= MAX_PLATE_THICKNESS_RATIO:
            raise BadInput(f"thickness: the {model} model needs a thickness of at most "
                           f"{MAX_PLATE_THICKNESS_RATIO:g} x the full width 2 max(half_width) for "
                           f"thin-plate theory; this panel's is {tb:.3g} x (the beam model has "
                           "no such limit)")
        corner, cx, cy = smallest_corner(beam)
        if not corner >= MIN_PLATE_CORNER_DEGREES:
            raise BadInput(f"half_width: the {model} model needs every corner of the planform to "
                           f"be at least {MIN_PLATE_CORNER_DEGREES:g} degrees; this one has a "
                           f"corner of {corner:.3g} degrees at x = {cx:.6g} m, half-width "
                           f"{cy:.6g} m (a sliver its mesh cannot resolve; the beam model has no "
                           "such limit)")
    values = {"L": L, "thickness": beam.thickness, "max(half_width)": float(w.max()),
              "material.E": beam.material.E, "material.rho": beam.material.rho}
    for name, (lo, hi, unit) in HARD_LIMITS.items():
        if not lo <= values[name] <= hi:
            raise BadInput(f"{name}: must lie in [{lo:g}, {hi:g}] {unit}, got "
                           f"{values[name]:.6g} {unit}")


def _unit_guess(name, si, value, lo, hi, units) -> str:
    """The first ``(factor, unit)`` of ``units`` that brings ``value`` into ``[lo, hi]``, as a
    clause for a warning ('' when none does)."""
    for factor, unit in units:
        if lo <= value * factor <= hi:
            return f"; if it was meant in {unit}, {name} = {value * factor:.6g} {si}"
    return ""


def unit_warnings(beam: Beam) -> list[str]:
    """Warnings for sizes outside :data:`PLAUSIBLE`, each naming the likely unit mistake."""
    out = []
    L, t, mat = beam.length, beam.thickness, beam.material
    lo, hi = PLAUSIBLE["L"]
    if not lo <= L <= hi:
        units = [(1e-3, "millimetres"), (1e-2, "centimetres"), (1e-6, "micrometres")]
        guess = _unit_guess("L", "m", L, lo, hi, units if L > hi else [])
        out.append(f"L = {L:.6g} m is outside the plausible {lo:g}-{hi:g} m{guess} (every "
                   "length in a beam file is in metres)")
    lo, hi = PLAUSIBLE["thickness/L"]
    if t / L < lo:
        out.append(f"thickness = {t:.6g} m is only {t / L:.3g} L (below {lo:g} L): is it 1000x "
                   "too small, or L in the wrong unit? (every length is in metres)")
    lo, hi = PLAUSIBLE["E"]
    if not lo <= mat.E <= hi:
        units = [(1e9, "GPa"), (1e6, "MPa"), (1e3, "kPa")]
        guess = _unit_guess("E", "Pa", mat.E, 1e8, hi, units if mat.E < lo else [])
        out.append(f"material.E = {mat.E:.6g} Pa is outside the plausible {lo:g}-{hi:g} Pa"
                   f"{guess} (E is in pascals)")
    lo, hi = PLAUSIBLE["rho"]
    if not lo <= mat.rho <= hi:
        guess = _unit_guess("rho", "kg/m^3", mat.rho, lo, hi, [(1e3, "g/cm^3")] if mat.rho < lo
                            else [(1e-3, "g/m^3")])
        out.append(f"material.rho = {mat.rho:.6g} kg/m^3 is outside the plausible {lo:g}-{hi:g} "
                   f"kg/m^3{guess} (rho is in kg/m^3)")
    return out


# ---------------------------------------------------------------------- large planforms
#: planforms with more stations than this are simplified before use (every command): the section
#: integrals and the meshes cost in proportion to the stations, and a scanned outline of 10 000
#: points describes the same panel as a few dozen
SIMPLIFY_ABOVE = 200
#: the simplified half-width stays within this fraction of the original *local* half-width at
#: every x. Mass and bending stiffness per unit length are both proportional to the width, so
#: (Courant-Fischer) every beam and PRBDM eigenvalue moves by at most a factor (1 + r)/(1 - r):
#: frequencies within ~1e-4, far below any model's own error
SIMPLIFY_RTOL = 1e-4


def _simplify_indices(x: np.ndarray, w: np.ndarray, rtol: float) -> np.ndarray:
    """Douglas-Peucker on the polyline (x, w) with the *vertical* deviation relative to the local
    half-width: the stations to keep (first and last always)."""
    keep = np.zeros(x.size, dtype=bool)
    keep[[0, -1]] = True
    stack = [(0, x.size - 1)]
    while stack:
        i, j = stack.pop()
        if j - i < 2:
            continue
        xs, ws = x[i + 1:j], w[i + 1:j]
        chord = w[i] + (w[j] - w[i]) * (xs - x[i]) / (x[j] - x[i])
        dev = np.abs(chord - ws) / ws
        k = int(np.argmax(dev))
        if dev[k] > rtol:
            m = i + 1 + k
            keep[m] = True
            stack += [(i, m), (m, j)]
    return np.flatnonzero(keep)


def simplify_planform(beam: Beam, rtol: float = SIMPLIFY_RTOL,
                      above: int = SIMPLIFY_ABOVE) -> tuple[Beam, dict | None]:
    """(beam, info): ``beam`` itself and None when it has at most ``above`` stations; otherwise
    the beam on a subset of its stations whose half-width is within ``rtol`` of the original's
    local half-width everywhere (between stations too: both are piecewise linear on the original
    stations), and ``info`` = stations before and after, the tolerance and the deviation reached
    (relative and in metres)."""
    if beam.x.size <= above:
        return beam, None
    idx = _simplify_indices(beam.x, beam.half_width, rtol)
    w_new = np.interp(beam.x, beam.x[idx], beam.half_width[idx])
    dev = np.abs(w_new - beam.half_width)
    simple = Beam(x=beam.x[idx], half_width=beam.half_width[idx], thickness=beam.thickness,
                  material=beam.material, name=beam.name)
    return simple, {"stations_in": int(beam.x.size), "stations_out": int(idx.size),
                    "rtol": rtol, "max_deviation": float(np.max(dev / beam.half_width)),
                    "max_deviation_m": float(dev.max())}


def load_beam(source) -> Beam:
    """Read a beam file (docs/conventions.md §1): a path, ``'-'`` for standard input, or a dict."""
    if isinstance(source, Beam):
        return source
    if isinstance(source, dict):
        return Beam.from_dict(source)
    import sys

    if str(source) == "-":
        text, label = sys.stdin.read(), "standard input"
    else:
        path = Path(source)
        if not path.is_file():
            raise BadInput(f"BEAM: no such file {str(source)!r}")
        text, label = path.read_text(), str(source)
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise BadInput(f"BEAM: {label} is not valid JSON ({exc.msg} at line {exc.lineno})") from None
    return Beam.from_dict(data)


# ---------------------------------------------------------------------- random beams

#: Parameters of the paper's random generator (Sec. 2.1, scalings of its reference code).
RANDOM_DEFAULTS = dict(p=10, length=1.0, max_half_width=0.5, max_thickness=0.05,
                       min_thickness=0.01, min_half_width=0.0)


def random_beam(seed: int, index: int, p: int = 10, length: float = 1.0,
                max_half_width: float | tuple = 0.5, max_thickness: float = 0.05,
                min_thickness: float = 0.01, min_half_width: float = 0.0,
                material: Material | None = None) -> Beam:
    """The paper's random beam number ``index`` of the stream ``seed``: a pure function.

    ``p`` interior stations ``x = L * [0, sort(U^p), 1]``; ``p + 2`` half-widths
    ``max_half_width * U`` raised to ``min_half_width``; thickness ``max_thickness * U`` clipped
    below at ``min_thickness``. U is drawn on (0, 1] (as ``1 - random()``) so no width is exactly
    zero. The draws come from ``numpy.random.default_rng([seed, index])`` in that order, so any
    beam of a data set can be rebuilt alone.
    """
    for name, v in (("seed", seed), ("index", index)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 0:
            raise BadInput(f"{name}: must be an integer >= 0, got {_show(v)}")
    if isinstance(p, bool) or not isinstance(p, (int, np.integer)) or p < 0:
        raise BadInput(f"p: must be an integer >= 0, got {_show(p)}")
    width_range = np.ndim(max_half_width) == 1
    if width_range:
        lo, hi = (float(v) for v in max_half_width) if len(max_half_width) == 2 else (0.0, -1.0)
        if not 0 < lo <= hi:
            raise BadInput(f"max_half_width: a number or a pair 0 < lo <= hi, got "
                           f"{_show(list(max_half_width))}")
        max_half_width = lo
    if not 0 <= min_half_width < max_half_width:
        raise BadInput(f"min_half_width: must lie in [0, max_half_width = {max_half_width}), "
                       f"got {_show(min_half_width)}")
    if not 0 < min_thickness <= max_thickness:
        raise BadInput(f"min_thickness: must lie in (0, max_thickness = {max_thickness}], "
                       f"got {_show(min_thickness)}")
    rng = np.random.default_rng([int(seed), int(index)])
    interior = np.sort(1.0 - rng.random(p))
    x = length * np.concatenate([[0.0], interior, [1.0]])
    u = 1.0 - rng.random(p + 2)
    t = max(max_thickness * (1.0 - rng.random()), min_thickness)
    if width_range:
        max_half_width = lo * (hi / lo) ** rng.random()
    w = np.maximum(max_half_width * u, min_half_width)
    if np.any(np.diff(x) <= 0):  # probability ~1e-15: merge coincident stations
        keep = np.concatenate([[True], np.diff(x) > 0])
        x, w = x[keep], w[keep]
    return Beam(x=x, half_width=w, thickness=t, material=material or Material(),
                name=f"random seed={seed} index={index} p={p}")
