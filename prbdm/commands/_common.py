"""Small helpers shared by the subcommands: beam argument, number lists, JSON output, tables."""
from __future__ import annotations

import json
import sys

from ..errors import BadInput
from ..files import atomic_write  # noqa: F401  (the commands' writer; one home: prbdm.files)
from ..parsing import float_list  # noqa: F401  (the commands' number lists; one home)


def add_beam_argument(parser):
    from ..geometry import SIMPLIFY_ABOVE, SIMPLIFY_RTOL

    parser.add_argument("beam", metavar="BEAM", help="beam file (JSON, docs/conventions.md §1), or - for stdin")
    parser.add_argument("--all-stations", action="store_true",
                        help=f"use every station of BEAM (default: a planform of more than "
                             f"{SIMPLIFY_ABOVE} stations is simplified to within "
                             f"{SIMPLIFY_RTOL:g} of its local half-width, docs/conventions.md §4)")


def beam_from_file(args):
    """The beam of ``args.beam`` (a file, or ``-``: standard input) as given: read once, not yet
    checked against any truth's limits (e.g. to choose a network by the panel's width first);
    :func:`read_beam` with ``beam=`` then checks and prepares it."""
    from ..geometry import load_beam

    return load_beam(args.beam)


def read_beam(args, command: str, model: str | None = None, beam=None):
    """The beam of ``args.beam``, checked and ready: (beam, info), the one way every command reads
    a beam (so all refuse the same beams with the same message).

    ``beam``: the beam already read by :func:`beam_from_file` (the file is not read again).
    Checks :func:`prbdm.geometry.check_beam` (``model``: the truth model's own limits too, when
    the command knows it), simplifies a planform of many stations (unless ``--all-stations``),
    and writes the unit-mistake warnings to stderr. ``info`` is the JSON ``input`` block:
    ``stations`` (as given), ``simplified`` (None, or stations before/after and the deviation)
    and ``warnings``."""
    from ..geometry import check_beam, simplify_planform, unit_warnings

    if beam is None:
        beam = beam_from_file(args)
    check_beam(beam, model)
    info = {"stations": int(beam.x.size), "simplified": None, "warnings": unit_warnings(beam)}
    if not getattr(args, "all_stations", False):
        beam, info["simplified"] = simplify_planform(beam)
    for w in info["warnings"]:
        sys.stderr.write(f"prbdm {command}: warning: {w}\n")
    s = info["simplified"]
    if s is not None:
        sys.stderr.write(f"prbdm {command}: note: planform simplified from {s['stations_in']} to "
                         f"{s['stations_out']} stations (half-width within "
                         f"{s['max_deviation']:.2g} of the local half-width, tolerance "
                         f"{s['rtol']:g}; --all-stations keeps them all)\n")
    return beam, info


def check_plot_path(path):
    """BadInput unless ``path`` is a .png, .pdf or .svg file in an existing folder (``--plot``
    of fit and simulate)."""
    from pathlib import Path

    suffix = Path(path).suffix.lower()
    if suffix not in (".png", ".pdf", ".svg"):
        raise BadInput(f"--plot: file must end in .png, .pdf or .svg, got {path!r}")
    if not Path(path).resolve().parent.is_dir():
        raise BadInput(f"--plot: folder of {path!r} does not exist")


#: optional module -> the extra of pyproject.toml that installs it
EXTRAS = {"pyarrow": "data", "pandas": "data", "dask": "data", "distributed": "data",
          "matplotlib": "plot", "mujoco": "sim"}   # safetensors is a core dependency


def missing_extra_message(module: str) -> str | None:
    """The one-line message for a missing optional module, or None if it is no extra's."""
    top = str(module).split(".")[0]
    extra = EXTRAS.get(top)
    if extra is None:
        return None
    return (f"this needs the optional package {top!r}, which is not installed; install it with: "
            f'pip install "prbdm[{extra}]"')


def require(*modules: str, purpose: str = "") -> None:
    """BadInput with the exact ``pip install "prbdm[...]"`` line if an optional module is
    missing: checked before any work, so nothing is computed and then lost."""
    import importlib.util

    for module in modules:
        try:
            found = importlib.util.find_spec(module) is not None
        except (ImportError, ValueError):
            found = False
        if not found:
            msg = missing_extra_message(module)
            raise BadInput(f"{purpose + ': ' if purpose else ''}{msg}")


def progress_bar(desc: str, delay: float = 2.0):
    """(callback, close) for a long loop: a tqdm bar on stderr when stderr is a terminal, shown
    only once the loop has run ``delay`` seconds; (None, no-op) otherwise (piped, or no tqdm)."""
    def nothing():
        pass

    if not sys.stderr.isatty():
        return None, nothing
    try:
        from tqdm import tqdm
    except ImportError:
        return None, nothing
    bar = tqdm(total=1, desc=desc, unit="it", file=sys.stderr, delay=delay, leave=False)

    def update(i, total):
        if bar.total != total:
            bar.total = total
        bar.update(i - bar.n)

    return update, bar.close


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


