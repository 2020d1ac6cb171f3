"""The result of a truth solve, and the checks every model's output goes through."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import BadInput

__all__ = ["TruthResult"]


@dataclass
class TruthResult:
    """Bending natural frequencies of one beam (docs/conventions.md §2).

    ``omega`` [rad/s] and ``freq_hz`` [Hz] hold the kept bending modes, ascending. ``all_modes``
    lists every computed mode as a dict with ``omega``, ``freq_hz``, ``lambda`` (the
    nondimensional eigenvalue), ``participation`` (transverse mass participation, 0..1),
    ``symmetry`` ('symmetric' or 'antisymmetric' about the x axis) and ``kept``; the plate adds
    ``section_fraction`` (see :mod:`prbdm.truth.modes`). ``mesh`` describes the discretisation.
    ``shapes`` carries the kept mode shapes for plotting (not part of :meth:`to_dict`).
    """

    model: str
    omega: np.ndarray
    freq_hz: np.ndarray
    time_s: float
    all_modes: list = field(default_factory=list)
    mesh: dict = field(default_factory=dict)
    omega_scale: float = float("nan")
    shapes: dict | None = field(default=None, repr=False)
    #: plate, mindlin: the bending spectrum's modes (``omega`` is theirs), each with its
    #: composition (which symmetric modes, with which weights); None for beam and analytic
    bending: list | None = None

    @property
    def lam(self) -> np.ndarray:
        """Nondimensional eigenvalues of the kept modes, ``(omega / omega_scale)^2``."""
        return (self.omega / self.omega_scale) ** 2

    def to_dict(self, all_modes: bool = False) -> dict:
        """JSON-ready dictionary: ``model``, ``omega``, ``freq_hz``, ``time_s``, ``mesh`` and,
        with ``all_modes=True``, every computed mode with its ``participation``."""
        d = {"model": self.model,
             "omega": [float(v) for v in self.omega],
             "freq_hz": [float(v) for v in self.freq_hz],
             "time_s": float(self.time_s),
             "participation": [float(m["participation"]) for m in self.all_modes if m["kept"]],
             "mesh": _jsonable(self.mesh)}
        if self.bending is not None:
            d["bending_modes"] = _jsonable(self.bending)
            # the section rule's physical modes, beside the spectrum (docs/conventions.md)
            kept = [m for m in self.all_modes if m.get("kept")]
            d["section_rule"] = {"omega": [float(m["omega"]) for m in kept],
                                 "section_fraction": [float(m["section_fraction"])
                                                      for m in kept]}
            d["participation"] = [float(m["participation"]) for m in kept]
        if all_modes:
            d["all_modes"] = [_jsonable(m) for m in self.all_modes]
        return d


def _jsonable(obj):
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return [_jsonable(v) for v in obj.tolist()]
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        v = float(obj)
        return v if math.isfinite(v) else None
    return obj


def check_frequencies(model: str, lam: np.ndarray, omega_scale: float) -> np.ndarray:
    """omega = omega_scale * sqrt(lam), refusing anything that is not finite, positive and
    ascending: a degenerate beam gets a clear error instead of a wrong number."""
    lam = np.asarray(lam, dtype=float)
    if not math.isfinite(omega_scale) or omega_scale <= 0:
        raise BadInput(f"model {model!r}: the frequency scale t/L^2*sqrt(E/rho) = {omega_scale!r} "
                       "is not a finite positive number; check thickness, length and material")
    if lam.size == 0 or not np.all(np.isfinite(lam)) or np.any(lam <= 0):
        raise BadInput(f"model {model!r}: the eigenvalue problem of this beam is degenerate "
                       f"(nondimensional eigenvalues {np.array2string(lam, precision=4)}); "
                       "the planform is too extreme to be solved reliably")
    omega = omega_scale * np.sqrt(lam)
    if not np.all(np.isfinite(omega)) or np.any(omega <= 0):
        raise BadInput(f"model {model!r}: the frequencies overflow or underflow in double "
                       "precision; check the units of E, rho, thickness and x")
    if np.any(np.diff(omega) < 0):
        raise BadInput(f"model {model!r}: internal ordering failure of the frequencies")
    return omega
