"""Random panels of the kinds users have: smooth planforms, other materials, thin panels.

The paper's generator (:func:`prbdm.geometry.random_beam`) draws jagged planforms of steel, 10 to
50 mm thick on a 1 m span: every surrogate trained only on it meets an aluminium fin, a uniform
strip or a 3 mm panel as something it never saw. :func:`smooth_beam` draws the others, each a pure
function of ``(seed, index)`` like ``random_beam``, so a data set of them can be rebuilt beam by
beam:

- the **shape**, one of :data:`SHAPES` with equal odds: ``uniform``; ``tapered`` (linear from
  the root width to a tip width 0.1-1 of it); ``trapezoidal`` (constant, then linear to a
  narrower or wider tip from a station at 0.2-0.8 L); ``necked`` (a smooth Gaussian neck, 15-60 %
  narrower, centred at 0.2-0.8 L, standard deviation 0.05-0.25 L, sampled at
  :data:`NECK_STATIONS` equally spaced stations and at its centre: the piecewise-linear planform
  through them is the panel);
- the **full width** of the widest section, ``2 max(w) / L``, log-uniform in ``width``
  (default 0.02-1.0: strips to square panels);
- the **thickness** ``t / L`` log-uniform in ``thickness`` (default 0.002-0.05: a 3 mm panel
  0.6 m long has t/L = 0.005), at most 0.4 of the full width (a plate, not a bar);
- **Poisson's ratio** uniform in ``nu`` (default 0.2-0.45: glass and ceramics to polymers);
  E and rho are the ``material``'s (frequencies scale with sqrt(E / rho), which the
  nondimensional targets divide out).
"""
from __future__ import annotations

import numpy as np

from .errors import BadInput
from .geometry import Beam, Material, _show

__all__ = ["SHAPES", "SMOOTH_DEFAULTS", "smooth_beam"]

SHAPES = ("uniform", "tapered", "trapezoidal", "necked")
#: the defaults of :func:`smooth_beam` (a data set's ``spec.beam`` records them)
SMOOTH_DEFAULTS = dict(length=1.0, width=(0.02, 1.0), thickness=(0.002, 0.05), nu=(0.2, 0.45))
#: the thickest panel drawn, as a fraction of its full width
PLATE_THICKNESS = 0.4
#: stations of a necked planform (the Gaussian neck sampled at this many points)
NECK_STATIONS = 17


def _range(name, value, lo_limit, hi_limit):
    v = [float(x) for x in np.atleast_1d(value)]
    if len(v) == 1:
        v = v * 2
    if not (len(v) == 2 and lo_limit <= v[0] <= v[1] <= hi_limit):
        raise BadInput(f"{name}: a number or a pair lo <= hi in [{lo_limit:g}, {hi_limit:g}], "
                       f"got {_show(value)}")
    return v


def smooth_beam(seed: int, index: int, length: float = 1.0, width=(0.02, 1.0),
                thickness=(0.002, 0.05), nu=(0.2, 0.45),
                material: Material | None = None) -> Beam:
    """Smooth random panel ``index`` of the stream ``seed`` (see the module text): a pure function
    of its arguments, its draws from ``numpy.random.default_rng([seed, index, 5])``. ``width``
    (full width over length), ``thickness`` (over length) and ``nu``: a value or a (lo, hi)
    range."""
    for name, v in (("seed", seed), ("index", index)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 0:
            raise BadInput(f"{name}: must be an integer >= 0, got {_show(v)}")
    if not (isinstance(length, (int, float)) and 0 < length < np.inf):
        raise BadInput(f"length: must be a length > 0 [m], got {_show(length)}")
    b_lo, b_hi = _range("width", width, 1e-3, 2.0)
    t_lo, t_hi = _range("thickness", thickness, 1e-4, 0.1)
    n_lo, n_hi = _range("nu", nu, 0.0, 0.49)
    rng = np.random.default_rng([int(seed), int(index), 5])
    shape = SHAPES[int(rng.integers(len(SHAPES)))]
    full = b_lo * (b_hi / b_lo) ** rng.random()           # widest full width / L
    # at most PLATE_THICKNESS of the full width: a plate, not a bar (the plate truths' limit is
    # 0.5); a narrow strip draws its thickness from the part of the range that allows
    top = max(min(t_hi, PLATE_THICKNESS * full), t_lo)
    tl = t_lo * (top / t_lo) ** rng.random()
    poisson = n_lo + (n_hi - n_lo) * rng.random()
    if shape == "uniform":
        x, rel = np.array([0.0, 1.0]), np.array([1.0, 1.0])
    elif shape == "tapered":
        tip = 0.1 + 0.9 * rng.random()
        x, rel = np.array([0.0, 1.0]), np.array([1.0, tip])
        if rng.random() < 0.25:                           # a quarter widen towards the tip
            rel = rel[::-1].copy()
    elif shape == "trapezoidal":
        knee = 0.2 + 0.6 * rng.random()
        tip = 0.1 + 0.9 * rng.random()
        x, rel = np.array([0.0, knee, 1.0]), np.array([1.0, 1.0, tip])
        if rng.random() < 0.25:
            rel = np.array([tip, tip, 1.0])
    else:                                                 # necked
        depth = 0.15 + 0.45 * rng.random()
        centre = 0.2 + 0.6 * rng.random()
        sigma = 0.05 + 0.2 * rng.random()
        x = np.linspace(0.0, 1.0, NECK_STATIONS)
        x = np.unique(np.concatenate([x, [centre]]))
        rel = 1.0 - depth * np.exp(-0.5 * ((x - centre) / sigma) ** 2)
        rel = rel / rel.max()
    m = material or Material()
    mat = Material(E=m.E, rho=m.rho, nu=float(poisson))
    L = float(length)
    return Beam(x=L * x, half_width=0.5 * full * L * rel, thickness=tl * L, material=mat,
                name=f"smooth {shape} seed={seed} index={index}")
