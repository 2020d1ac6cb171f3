"""A short fingerprint of a beam's geometry and material, so that a fit result knows its beam.

``prbdm fit --json`` and ``prbdm predict --json`` write it as ``beam_fingerprint``;
``prbdm export`` and ``prbdm simulate`` (``--from``) refuse a result whose fingerprint differs from
the beam's (docs/howto/export-and-simulate.md). The fingerprint is the first 16 hex digits of the SHA-256 of a
canonical text: the stations ``x``, the ``half_width`` values, the ``thickness`` and the material's
``E``, ``rho``, ``nu``, each number rounded to 12 significant digits, so that the same beam read
back from a JSON file, or written by another program with a last-digit rounding difference, gets
the same fingerprint, while any change an engineer would make does not. The beam's ``name`` is not
part of it (renaming a file does not change the panel). Imports only the standard library.
"""
from __future__ import annotations

import hashlib
import math

__all__ = ["beam_fingerprint", "SIGNIFICANT_DIGITS", "FINGERPRINT_HEX"]

#: digits each number keeps in the canonical text
SIGNIFICANT_DIGITS = 12
#: hex digits of the SHA-256 kept (64 bits: a collision between two different beams is negligible)
FINGERPRINT_HEX = 16


def _number(v) -> str:
    v = float(v)
    if not math.isfinite(v):
        raise ValueError(f"beam_fingerprint: non-finite number {v!r}")
    # + 0.0 turns -0.0 into 0.0: the same panel, the same text
    return f"{float(f'{v:.{SIGNIFICANT_DIGITS}g}') + 0.0:.{SIGNIFICANT_DIGITS}g}"


def beam_fingerprint(beam) -> str:
    """16 hex digits identifying ``beam``'s geometry and material (:class:`prbdm.geometry.Beam`,
    or anything with ``x``, ``half_width``, ``thickness`` and ``material.E/rho/nu``)."""
    m = beam.material
    text = ";".join([
        "x=" + ",".join(_number(v) for v in beam.x),
        "half_width=" + ",".join(_number(v) for v in beam.half_width),
        "thickness=" + _number(beam.thickness),
        "E=" + _number(m.E), "rho=" + _number(m.rho), "nu=" + _number(m.nu)])
    return hashlib.sha256(text.encode("ascii")).hexdigest()[:FINGERPRINT_HEX]
