"""``prbdm export BEAM (--joints N | --from FIT.json) --format mjcf|urdf|json -o FILE``.

Writes a PRBDM for a user's simulator (:mod:`prbdm.export`, docs/export.md): MuJoCo MJCF, URDF
(spring stiffness in the ``<prbdm:spring>`` extension tag and a Gazebo ``<gazebo>`` block), or a
plain JSON of the physical parameters. The PRBDM comes from ``--from FIT.json`` (what
``prbdm fit --json`` prints) or from a fit run here (``--joints N``, with the fit's options).

``--pose`` picks the pose whose SCF the springs use: ``rest`` (default) the small-vibration
model about theta = 0 -- a result fitted for the paper's deflected poses is first refitted at
theta = 0 against its own truth frequencies (:mod:`prbdm.preflight`, no FEM, about a second);
an index, or ``linear`` (the theta = 0 pose of a result that has one). ``--springref pose``
(default) sets the springs' rest angles to that pose, so the exported chain at rest is the PRBDM
at that pose and vibrates with its frequencies; ``--springref zero`` rests it straight. With
``--joints`` the fit run here uses the linear pose set by default. Before the file is written the
model's small-vibration frequencies about its spring reference are compared with the truth (the
result's ``omega_truth``, or a prediction's ``omega_truth_predicted``): beyond ``--tolerance``
(default 5 %) a warning names the mode, the error and the remedy. The ``--from`` result's own
warnings (a rough or extrapolating network's) are repeated, marked with the file's name. ``--from`` a result whose
``beam_fingerprint`` is not the beam's is refused (exit 2) unless ``--ignore-fingerprint``. The
file is written atomically.

JSON (``--json``): ``file``, ``format``, ``joints``, ``law``, ``pose`` (index, theta, k,
springref), ``stiffness`` [N m/rad], ``springref`` [rad], ``damping`` [N m s/rad], ``omega`` and
``freq_hz`` (small vibrations about the spring reference), ``damping_ratio``, ``source``
(``fit`` file or ``fit run here`` with its loss), ``refit`` (null, or what the refit at rest did),
``check`` (the frequencies against the truth: per mode ``error``, ``max_error``, ``tolerance``
(relative), ``ok``), ``beam_fingerprint`` (this beam's and the result's, ``match``),
``warnings``, ``time_s``.
"""
from __future__ import annotations

import argparse
import math
import sys
import time

from ..errors import BadInput
from ..preflight import DEFAULT_TOLERANCE
from ._common import add_beam_argument, positive_int, print_json, read_beam, table

FIT_OPTIONS = ("truth", "modes", "law", "poses", "starts", "seed")


def finite_float(minimum: float | None = None, positive: bool = False):
    """argparse type: a finite float (>= minimum, or > 0)."""
    def parse(text):
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be a number, got {text!r}") from None
        if not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"must be finite, got {text!r}")
        if positive and value <= 0:
            raise argparse.ArgumentTypeError(f"must be > 0, got {text!r}")
        if minimum is not None and value < minimum:
            raise argparse.ArgumentTypeError(f"must be >= {minimum:g}, got {text!r}")
        return value
    return parse


def add_source_arguments(parser, default_poses: str, truths=("auto", "analytic", "beam", "plate",
                                                               "mindlin"), default_truth="auto"):
    """BEAM, ``--joints N | --from FIT.json`` and the fit options (used with ``--joints``)."""
    add_beam_argument(parser)
    src = parser.add_mutually_exclusive_group(required=True)
    src.add_argument("--joints", "-n", type=positive_int(1, 39), metavar="N",
                     help=f"fit an nR-PRBDM here (to --truth, default {default_truth})")
    src.add_argument("--from", dest="fit_file", metavar="FIT.json",
                     help="use the PRBDM of a saved 'prbdm fit --json' output (- for stdin)")
    parser.add_argument("--pose", default="rest", metavar="rest|I|linear",
                        help="'rest' (default): the small-vibration model about theta = 0, a "
                             "paper-pose result refitted there against its own truth (no FEM); "
                             "or the index of a pose of the result, or 'linear' (its theta = 0 "
                             "pose)")
    parser.add_argument("--tolerance", type=finite_float(positive=True), default=100 *
                        DEFAULT_TOLERANCE, metavar="PCT",
                        help="warn when a small-vibration frequency of the model is further "
                             "than PCT %% from the truth (default %(default)g)")
    parser.add_argument("--ignore-fingerprint", action="store_true",
                        help="apply a --from result made for another beam (beam_fingerprint "
                             "differs) anyway")
    g = parser.add_argument_group("fit options (with --joints)")
    g.add_argument("--truth", choices=truths, default=None,
                   help=f"truth the fit is made to (default {default_truth}"
                        + ("" if default_truth != "auto" else
                           ": the beam for a strip up to 0.05 L wide, the Kirchhoff or Mindlin "
                           "plate beyond, as `prbdm fit`") + ")")
    g.add_argument("--modes", type=positive_int(1, 50), default=None,
                   help="truth modes to map (default n)")
    g.add_argument("--law", choices=("beam", "paper"), default=None,
                   help="base joint stiffness law (default 'beam')")
    g.add_argument("--poses", default=None, metavar="paper|linear|T1,T2,...",
                   help=f"pose set of the fit (default '{default_poses}')")
    g.add_argument("--starts", type=positive_int(1, 100000), default=None,
                   help="start points of the multistart (default 64)")
    g.add_argument("--seed", type=positive_int(0), default=None,
                   help="seed of the random start points (default 0)")
    parser.set_defaults(default_poses=default_poses, default_truth=default_truth)


def fit_from_args(args, beam) -> tuple[dict, list[str]]:
    """The fit dictionary asked for on the command line, and warnings."""
    from ..export import load_fit, run_fit
    from ..parsing import parse_poses

    if args.fit_file is not None:
        given = [name for name in FIT_OPTIONS if getattr(args, name) is not None]
        if given:
            raise BadInput(f"--{given[0]}: a fit option, only with --joints (FIT.json carries "
                           "its own fit)")
        if args.fit_file == "-" and args.beam == "-":
            raise BadInput("--from: BEAM and FIT.json cannot both be standard input")
        fit = load_fit(args.fit_file)
        caveats = truth_caveat(beam, fit)
        return fit, caveats + carried_warnings(fit, args.fit_file, caveats)
    n = args.joints
    poses, warnings = parse_poses(args.poses or args.default_poses, n)
    fit = run_fit(beam, n, modes=args.modes, law=args.law or "beam", poses=poses,
                  starts=args.starts, seed=args.seed or 0,
                  truth=args.truth or args.default_truth)
    return fit, warnings + truth_caveat(beam, fit)


def carried_warnings(fit: dict, label: str, already: list[str]) -> list[str]:
    """The warnings the ``--from`` result carries (``prbdm predict``'s rough-estimate and
    extrapolation warnings, ``prbdm fit``'s), each marked as the result's own: they are about
    the model written, and the export's own check cannot see them (it compares a prediction with
    the network's own ``omega_truth_predicted``, so a rough network passes it). Those already
    in ``already`` are not repeated."""
    given = fit.get("warnings")
    given = [given] if isinstance(given, str) else given
    if not isinstance(given, list):
        return []
    name = "standard input" if str(label) == "-" else str(label)
    # one line each (stderr prints one per line), each once
    texts = dict.fromkeys(" ".join(w.split()) for w in given if isinstance(w, str))
    return [f"{name} says: {w}" for w in texts if w and w not in already]


def truth_caveat(beam, fit: dict) -> list[str]:
    """The shear caveat (:func:`prbdm.truth.choice.shear_caveat`) of the physics the result
    follows: its truth (``prbdm fit``'s ``truth.model``) or its network's (``prbdm predict``'s
    ``truth``; as predict says it, :func:`prbdm.surrogate.selection.answer_caveat`, so that a
    narrow panel's beam-network answer keeps the plate's caveat). The export's own check
    compares the model with that truth, so it cannot see what the truth leaves out; a result
    that names no truth gets none."""
    from ..surrogate.selection import answer_caveat
    from ..truth.choice import choose_truth, shear_caveat

    truth = fit.get("truth")
    model = truth.get("model") if isinstance(truth, dict) else truth
    if model not in ("analytic", "beam", "plate", "mindlin"):
        return []
    if isinstance(truth, dict):
        caveat = shear_caveat(beam, model)
    else:                       # a prediction: the caveat predict gave it
        caveat = answer_caveat(beam, model, choose_truth(beam, "auto"), None)
    return [caveat] if caveat else []


def prepared_from_args(args, beam):
    """(fit dict as given, :class:`prbdm.preflight.Prepared`): the result asked for, its
    fingerprint checked (with ``--from``) and, for ``--pose rest``, its model at theta = 0."""
    from ..preflight import prepare

    fit, warnings = fit_from_args(args, beam)
    prep = prepare(beam, fit, pose=args.pose, ignore_fingerprint=args.ignore_fingerprint,
                   check_beam=args.fit_file is not None)
    prep.warnings[:0] = warnings
    return fit, prep


def add_arguments(parser):
    from ..export import FORMATS

    add_source_arguments(parser, default_poses="linear")
    parser.add_argument("--format", "-f", choices=FORMATS, default=None,
                        help="mjcf (MuJoCo), urdf, or json (physical parameters); default from "
                             "the suffix of FILE (.xml/.mjcf, .urdf, .json)")
    parser.add_argument("-o", "--output", required=True, metavar="FILE",
                        help="file to write (atomically), or - for standard output")
    parser.add_argument("--springref", choices=("pose", "zero"), default="pose",
                        help="springs at rest at the pose's angles (default: small vibrations "
                             "then have the PRBDM's frequencies at that pose) or straight")
    parser.add_argument("--damping", type=finite_float(minimum=0.0), default=0.0, metavar="ZETA",
                        help="first-mode damping ratio, as stiffness-proportional joint damping "
                             "(default 0)")
    parser.add_argument("--json", action="store_true", help="print one JSON object on stdout")


def run(args) -> int:
    from ..export import WRITERS, format_from_path, prbdm_from_fit
    from ..preflight import check_frequencies, where_of

    t0 = time.perf_counter()
    to_stdout = args.output == "-"
    if to_stdout and args.json:
        raise BadInput("-o: '-' (the file on stdout) cannot be combined with --json")
    if args.format is None and to_stdout:
        raise BadInput("--format: needed with -o -")
    fmt = args.format or format_from_path(args.output)
    if not to_stdout:
        from pathlib import Path

        folder = Path(args.output).parent
        if not folder.is_dir():
            raise BadInput(f"-o/--output: folder {str(folder)!r} of {args.output!r} does not "
                           "exist (it is not created)")
    beam, info = read_beam(args, "export")
    fit, prep = prepared_from_args(args, beam)
    desc = prbdm_from_fit(beam, prep.fit, pose=prep.pose, springref=args.springref,
                          damping=args.damping)
    check, bad = check_frequencies(desc["omega"], prep.truth, prep.modes,
                                   tolerance=args.tolerance / 100,
                                   truth_source=prep.truth_source, where=where_of(desc))
    warnings = prep.warnings + bad
    text = WRITERS[fmt](desc)
    if to_stdout:
        sys.stdout.write(text)
    else:
        from ._common import atomic_write

        try:
            atomic_write(args.output, text, make_parents=False)
        except OSError as exc:
            raise BadInput(f"-o: cannot write {args.output!r} ({exc.strerror or exc})") from None
    for w in warnings:
        sys.stderr.write(f"warning: {w}\n")
    if to_stdout:
        return 0
    h = desc["hinges"]
    source = ({"fit_file": args.fit_file} if args.fit_file is not None else
              {"fit": "run here", "loss_percent": fit["loss_percent"],
               "max_freq_error": fit["max_freq_error"], "starts": fit["starts"]})
    out = {"file": str(args.output), "format": fmt, "joints": desc["joints"], "law": desc["law"],
           "pose": {key: desc["pose"][key] for key in ("index", "theta", "k", "springref")},
           "stiffness": [j["stiffness"] for j in h], "springref": [j["springref"] for j in h],
           "damping": [j["damping"] for j in h], "omega": desc["omega"],
           "freq_hz": desc["freq_hz"], "damping_ratio": desc["damping_ratio"],
           "source": source, "refit": prep.refit, "check": check,
           "beam_fingerprint": prep.fingerprint, "warnings": warnings,
           "input": info,
           "time_s": time.perf_counter() - t0}
    if args.json:
        print_json(out)
        return 0
    p = desc["pose"]
    print(f"wrote {args.output} ({fmt}): {desc['joints']}R-PRBDM, law {desc['law']}, pose "
          f"{p['index']} (theta {', '.join(f'{v:.4g}' for v in p['theta'])} rad), SCF k = "
          f"{p['k']:.6g}, springs at rest at {'the pose' if p['springref'] == 'pose' else 0}")
    rows = [[j["name"], f"{j['x']:.5g}", f"{j['stiffness']:.6g}", f"{j['springref']:.4g}",
             f"{j['damping']:.4g}"] for j in h]
    print(table(rows, ["joint", "x m", "K N m/rad", "springref rad", "damping N m s/rad"]))
    print("frequencies about the spring reference: "
          + ", ".join(f"{f:.5g}" for f in desc["freq_hz"]) + " Hz")
    if prep.refit is not None:
        print(f"refitted at theta = 0 against the result's {prep.refit['truth']} "
              f"({prep.refit['time_s']:.2f} s): the given fit was made for deflected poses")
    print(f"check against the truth ({check['truth']}), modes 1-{check['modes']}: worst mode "
          f"{check['worst_mode']}, {100 * check['max_error']:.3g} % "
          f"({'within' if check['ok'] else 'BEYOND'} {100 * check['tolerance']:g} %)")
    return 0
