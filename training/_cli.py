"""Command-line handling shared by the training scripts (train, evaluate, pack).

Every setting is a flag, ``--name value`` or ``--name=value`` (``-`` and ``_`` alike in names);
``--config FILE`` reads settings from a TOML or JSON file with the same keys, and flags given on
the command line override it. ``--help`` prints every setting with its default. Bad input (an
unknown flag, a value of the wrong type, an unreadable config, a missing required setting) ends
the script with ONE line on stderr and exit status 2, before anything is written, as the
``prbdm`` commands do.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
from dataclasses import dataclass
from pathlib import Path

# One BLAS thread per process: every training script imports this module before NumPy loads,
# so the setting reaches the script's own process and every process it starts. The scripts
# spread work over processes and threads themselves, and OpenBLAS's own threads on top made
# training/retest.py 3x slower on 2 cores (mindlin-n4: 1.6 min with one BLAS thread, over 7
# without). An explicit OPENBLAS_NUM_THREADS in the environment still wins.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

#: the repository root (paths recorded in metadata are made relative to it)
REPO = Path(__file__).resolve().parent.parent


@dataclass(frozen=True)
class Setting:
    """One setting: its default (whose type is the setting's type), help text, and, where the
    values are a closed set, the choices."""

    default: object
    help: str
    choices: tuple = ()


def fail(prog: str, message: str):
    """Bad input: one line on stderr, exit status 2."""
    print(f"{prog}: {message}", file=sys.stderr)
    sys.exit(2)


class _Parser(argparse.ArgumentParser):
    def error(self, message):           # argparse prints the usage too: one line only
        fail(self.prog, f"{message} (see --help)")


def _parse_bool(text):
    low = str(text).lower()
    if low in ("1", "true", "yes", "on"):
        return True
    if low in ("0", "false", "no", "off"):
        return False
    raise argparse.ArgumentTypeError(f"not a yes/no value: {text!r}")


def _converter(default):
    if isinstance(default, bool):
        return _parse_bool
    if isinstance(default, (int, float)):
        return type(default)
    return str


def _check_value(prog, key, value, setting: Setting):
    """A value from a config file, converted to the setting's type (exit 2 if it does not fit)."""
    d = setting.default
    if isinstance(d, bool):
        ok = isinstance(value, bool)
    elif isinstance(d, int):
        ok = isinstance(value, int) and not isinstance(value, bool)
    elif isinstance(d, float):
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
    else:
        ok = isinstance(value, str)
    if not ok:
        fail(prog, f"config: {key} must be a {type(d).__name__}, got {value!r}")
    value = type(d)(value)
    if setting.choices and value not in setting.choices:
        fail(prog, f"config: {key} must be one of {', '.join(map(str, setting.choices))}, "
                   f"got {value!r}")
    return value


def read_config(prog: str, path, settings: dict) -> dict:
    """Settings from a TOML (``.toml``) or JSON file: a flat table of setting names."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        fail(prog, f"--config: cannot read {str(path)!r} ({exc.strerror})")
    try:
        if path.suffix.lower() == ".toml":
            try:
                import tomllib
            except ImportError:         # Python 3.10
                try:
                    import tomli as tomllib
                except ImportError:
                    fail(prog, "--config: a TOML file needs Python 3.11 or `pip install tomli`; "
                               "or give the settings as JSON")
            data = tomllib.loads(text)
        else:
            data = json.loads(text)
    except ValueError as exc:           # tomllib.TOMLDecodeError and JSONDecodeError both are
        kind = "TOML" if path.suffix.lower() == ".toml" else "JSON"
        fail(prog, f"--config: {str(path)!r} is not valid {kind} ({str(exc).splitlines()[0]})")
    if not isinstance(data, dict):
        fail(prog, f"--config: {str(path)!r} must hold a table of settings")
    out = {}
    for key, value in data.items():
        name = key.replace("-", "_")
        if name not in settings:
            fail(prog, f"config: unknown setting {key!r} in {str(path)!r}; known: "
                       f"{', '.join(sorted(settings))}")
        out[name] = _check_value(prog, key, value, settings[name])
    return out


def parse(prog: str, description: str, settings: dict, argv=None, positional=(),
          required=(), config=True) -> dict:
    """The settings {name: value} from ``argv`` (default ``sys.argv[1:]``).

    settings: {name: Setting}; positional: names taken as positional arguments (required);
    required: names that must be given (by flag or config) and have no usable default;
    config: whether ``--config FILE`` is offered."""
    ap = _Parser(prog=prog, description=description, allow_abbrev=False,
                 formatter_class=argparse.RawDescriptionHelpFormatter)
    for name in positional:
        s = settings[name]
        ap.add_argument(name, type=_converter(s.default), help=s.help.replace("%", "%%"))
    if config:
        ap.add_argument("--config", metavar="FILE", default=None,
                        help="TOML or JSON file with settings by name; flags override it")
    for name, s in settings.items():
        if name in positional:
            continue
        flags = [f"--{name}"] + ([f"--{name.replace('_', '-')}"] if "_" in name else [])
        text = f"{s.help} (required)" if name in required else f"{s.help} (default: {s.default!r})"
        kw = dict(dest=name, type=_converter(s.default), default=None,
                  help=text.replace("%", "%%"))        # argparse formats help with %
        if s.choices:
            kw["choices"] = s.choices
        if isinstance(s.default, bool):
            kw.update(nargs="?", const=True, metavar="yes|no")
        ap.add_argument(*flags, **kw)
    args = vars(ap.parse_args(sys.argv[1:] if argv is None else argv))
    values = {name: s.default for name, s in settings.items()}
    if config and args.get("config"):
        values.update(read_config(prog, args["config"], settings))
    for name in settings:
        if args.get(name) is not None:
            values[name] = args[name]
    for name in required:
        if values[name] in ("", None):
            fail(prog, f"--{name}: required: {settings[name].help}")
    if config:
        values["config"] = args.get("config") or ""
    return values


def portable_path(path) -> str:
    """``path`` as it is best recorded in committed metadata: relative to the repository when
    it lies inside it (no machine paths), else as given; several, comma-separated, each so."""
    if "," in str(path):
        return ",".join(portable_path(part) for part in str(path).split(","))
    p = Path(path)
    try:
        return p.resolve().relative_to(REPO).as_posix()
    except ValueError:
        return str(path)


def output_path(path) -> str:
    """Where a run wrote its output, as recorded in committed metadata, never a machine path:
    relative to the repository when inside it, else relative to the working directory when
    inside that (where the run was), else the file name. (Inputs keep :func:`portable_path`:
    they must be found again.)"""
    p = Path(path)
    for base in (REPO, Path.cwd()):
        try:
            return p.resolve().relative_to(base.resolve()).as_posix()
        except ValueError:
            pass
    return p.name


def find_path(path) -> Path:
    """A recorded path: as given when it exists from here, else relative to the repository."""
    p = Path(path)
    if p.exists() or p.is_absolute():
        return p
    return REPO / p
