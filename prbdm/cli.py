"""The ``prbdm`` command line (docs/conventions.md §4).

Each subcommand lives in its own module with two functions, ``add_arguments(parser)`` and
``run(args) -> int``; the module is imported only when its subcommand runs, so ``prbdm truth``
never imports torch and ``prbdm predict`` never imports scikit-fem.

Exit status: 0 success, 2 bad input (one line on stderr naming the field), 1 internal failure.
"""
from __future__ import annotations

import argparse
import importlib
import importlib.util
import sys

from .errors import BadInput

#: subcommand -> (module, one-line help)
COMMANDS = {
    "demo": ("prbdm.commands.demo", "fit a PRBDM to a built-in beam and show the result"),
    "truth": ("prbdm.commands.truth", "bending frequencies of a beam (analytic, beam or plate FEM)"),
    "eval": ("prbdm.commands.eval", "eigenfrequencies of a given PRBDM"),
    "fit": ("prbdm.commands.fit", "optimise a PRBDM to match a beam's truth frequencies"),
    "dataset": ("prbdm.commands.dataset", "generate or inspect a labelled data set of random beams"),
    "predict": ("prbdm.commands.predict", "PRBDM and truth frequencies from the trained network (no FEM)"),
    "compare": ("prbdm.commands.compare", "truth vs network vs optimised fit vs network-then-refined"),
    "export": ("prbdm.commands.export", "write a PRBDM for a simulator: MuJoCo MJCF, URDF or JSON"),
    "simulate": ("prbdm.commands.simulate", "time response of a PRBDM against the beam's modal superposition"),
    "report": ("prbdm.commands.report", "error against run time of every way to get a model, on held-out beams"),
}


class _Parser(argparse.ArgumentParser):
    """argparse that reports bad flags in one line with exit status 2 (no usage dump)."""

    def error(self, message):
        sys.stderr.write(f"{self.prog}: error: {message}\n")
        sys.exit(2)


def _available():
    # a subcommand whose module is not written yet is not offered
    return {name: spec for name, spec in COMMANDS.items()
            if importlib.util.find_spec(spec[0]) is not None}


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    from . import __version__

    parser = _Parser(prog="prbdm", description="Pseudo-Rigid Body Dynamic Models of flexible "
                     "cantilever panels.")
    parser.add_argument("--version", action="version", version=f"prbdm {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for name, (module, help_) in _available().items():
        p = sub.add_parser(name, help=help_, description=help_)
        if only is None or only == name:
            importlib.import_module(module).add_arguments(p)
    return parser


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    # import only the module of the subcommand asked for
    command = next((a for a in argv if not a.startswith("-")), None)
    parser = build_parser(only=command if command in COMMANDS else None)
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 2
    module = importlib.import_module(COMMANDS[args.command][0])
    try:
        return int(module.run(args) or 0)
    except BadInput as exc:
        sys.stderr.write(f"prbdm {args.command}: error: {exc}\n")
        return 2
    except ModuleNotFoundError as exc:
        # an optional extra that the command checked too late (or not at all): still one line
        # with the install command, not a traceback
        from .commands._common import missing_extra_message

        msg = missing_extra_message(exc.name or "")
        if msg is None:
            raise
        sys.stderr.write(f"prbdm {args.command}: error: {msg}\n")
        return 2
    except BrokenPipeError:
        return 0
    except KeyboardInterrupt:
        sys.stderr.write("interrupted\n")
        return 130


if __name__ == "__main__":
    sys.exit(main())
