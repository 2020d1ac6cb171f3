"""Command-line values the library reads too: number lists and pose sets, each refused with
one line naming the flag (BadInput). One home for the commands and for prbdm.report."""
from __future__ import annotations

import math

from .errors import BadInput


def float_list(text: str, name: str, *, minimum=None, positive=False) -> list[float]:
    """Parse ``"a,b,c"`` into finite floats; BadInput naming ``name`` otherwise."""
    fields = str(text).split(",")
    if all(v.strip() == "" for v in fields):
        raise BadInput(f"{name}: must not be empty")
    if any(v.strip() == "" for v in fields):
        raise BadInput(f"{name}: empty field in {text!r}; give a comma-separated list of numbers "
                       "with no empty entries")
    try:
        values = [float(v) for v in fields]
    except ValueError:
        raise BadInput(f"{name}: must be a comma-separated list of numbers, got {text!r}") from None
    if not all(math.isfinite(v) for v in values):
        raise BadInput(f"{name}: all values must be finite, got {text!r}")
    if positive and any(v <= 0 for v in values):
        raise BadInput(f"{name}: all values must be > 0, got {text!r}")
    if minimum is not None and any(v < minimum for v in values):
        raise BadInput(f"{name}: all values must be >= {minimum}, got {text!r}")
    return values


def parse_poses(text: str, n: int) -> tuple[str | list[float], list[str]]:
    """'paper' | 'linear' | a list of angles >= 0 (rad). Returns (spec, warnings)."""
    spec = str(text).strip()
    if spec in ("paper", "linear"):
        return spec, []
    try:
        [float(v) for v in spec.split(",") if v.strip()]
    except ValueError:
        raise BadInput(f"--poses: must be 'paper', 'linear' or a comma-separated list of angles "
                       f"in rad, got {text!r}") from None
    angles = float_list(spec, "--poses", minimum=0.0)
    warnings = []
    bad = [a for a in angles if n * a > math.pi / 2 + 1e-12]
    if bad:
        warnings.append(f"--poses: {len(bad)} pose(s) have n * theta > pi/2 (n = {n}, theta = "
                        f"{bad[0]:g}); the paper keeps n * theta <= pi/2")
    return angles, warnings
