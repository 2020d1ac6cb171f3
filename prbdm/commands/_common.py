"""Small helpers shared by the subcommands: beam argument, number lists, JSON output, tables."""
from __future__ import annotations

import json
import math
import os
import sys
import tempfile
from pathlib import Path

from ..errors import BadInput


def add_beam_argument(parser):
    parser.add_argument("beam", metavar="BEAM", help="beam file (JSON, SPEC §1), or - for stdin")


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


def positive_int(minimum: int = 1, maximum: int | None = None):
    """argparse type: an integer in [minimum, maximum]; argparse prints the flag and our range."""
    import argparse

    allowed = f">= {minimum}" if maximum is None else f"in [{minimum}, {maximum}]"

    def parse(text):
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be an integer {allowed}, got {text!r}") from None
        if value < minimum or (maximum is not None and value > maximum):
            raise argparse.ArgumentTypeError(f"must be an integer {allowed}, got {value}")
        return value
    return parse


def print_json(obj) -> None:
    sys.stdout.write(json.dumps(obj, allow_nan=False) + "\n")


def table(rows, header) -> str:
    """A plain fixed-width text table."""
    cells = [list(map(str, header))] + [[str(c) for c in r] for r in rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(header))]
    lines = ["  ".join(c.rjust(w) for c, w in zip(r, widths)) for r in cells]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def atomic_write(path, data: bytes | str, *, make_parents: bool = True) -> None:
    """Write a file whole or not at all: temporary file in the same folder, then rename.

    The file gets the usual permissions of a new file (0o666 less the umask), not mkstemp's
    0o600. ``make_parents=False``: a missing folder is an error (FileNotFoundError) instead of
    being created."""
    path = Path(path)
    if make_parents:
        path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data.encode() if isinstance(data, str) else data)
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
