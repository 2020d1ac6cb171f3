"""``prbdm predict BEAM --joints N``: the PRBDM of a beam from the trained surrogate, no FEM.

A network (:mod:`prbdm.surrogate`) maps the planform to the link fractions gamma, one stiffness
correction factor per pose, and the beam's own truth frequencies; the PRBDM built from gamma and k
then gives the frequencies per pose. Neither torch nor scikit-fem is imported: the network and the
PRBDM run in NumPy, so the command answers in well under a second.

The checkpoint is ``--checkpoint PATH``, or the default one for (``--joints``, ``--truth``)
(:func:`prbdm.surrogate.default_checkpoint`), checked on load (exit 2 naming the file if it is
corrupt or inconsistent). A beam whose features fall outside the range seen in training gets a
warning naming the feature (stderr; also in ``warnings`` of the JSON), and so does one whose every
feature is in range but which is unlike every training panel the checkpoint keeps (its nearest
distance beyond the held-out panels', :mod:`prbdm.surrogate.neighbours`); a feature that did not vary
in training at all (e.g. nu for a plate network trained on one material) is refused (exit 2)
unless ``--allow-extrapolation``; when ``--truth auto`` (the default) chose that network, the next
one answers instead (a Mindlin network's panel goes to the Kirchhoff plate's, the nearer physics,
then to the beam's) and the warning says why. A prediction that is non-finite or outside physical ranges
(:func:`prbdm.surrogate.prediction.physical_problems`) is an error: exit 2 when the beam lies outside the
training range, exit 1 otherwise (the checkpoint's fault), one line on stderr, never a number.
Any other failure is one line and exit 1 too, with or without ``--json``.

JSON (``--json``): ``gamma``, ``k`` (one per pose), ``law``, ``poses``, ``omega`` and ``freq_hz``
(the PRBDM's frequencies per pose), ``omega_truth_predicted`` and ``freq_hz_truth_predicted`` (the
network's direct prediction of the truth frequencies), ``links`` (the SI link table: ``joint_x``,
``length``, ``mass``, ``com``, ``inertia``, ``area_moment``, ``base_stiffness`` s_j and
``stiffness`` k_i s_j per pose [N m/rad]), ``checkpoint`` (path, name, truth, joints, data set
size, ``held_out_accuracy``: its whole test), ``held_out_accuracy_at_this_width`` (its test panels
of this panel's width band, ``full_width``; the whole test, ``full_width`` null, where it recorded
no such band: what the rough-estimate warning judges by), ``truth``, ``joints``, ``modes``,
``beam``, ``source`` (``network CHECKPOINT``), ``warnings``, ``time_s`` (the prediction itself,
start-up excluded). The output is a valid ``prbdm export BEAM --from PREDICT.json`` input, like
``prbdm fit --json``'s. Which network answers, and why, is decided in the library
(:mod:`prbdm.surrogate.selection`); this command reads the beam once, prints and exits.
"""
from __future__ import annotations

import sys

from ..constants import OBJECTIVES
from ..errors import BadInput
from ..surrogate.selection import TRUTHS, PredictionError
from ._common import add_beam_argument, beam_from_file, positive_int, print_json, read_beam, table


def add_arguments(parser):
    add_beam_argument(parser)
    parser.add_argument("--joints", "-n", type=positive_int(1, 39), required=True,
                        help="number of revolute joints n (a checkpoint must exist for it)")
    parser.add_argument("--truth", choices=(*TRUTHS, "auto"), default=None,
                        help="truth model the network was trained on (default auto: for a "
                             "panel wider than 0.1 L the network of the truth it needs, the "
                             "Mindlin plate's (thick or necked) or the Kirchhoff plate's, when "
                             "one is found and covers it, else the next: Mindlin, plate, beam "
                             "(plate, Mindlin, beam for a thin one); "
                             "the beam's for a strip, and on plate panels 0.05-0.1 L wide, "
                             "where its PRBDM is the closer to the plate; with --checkpoint, "
                             "the checkpoint's)")
    parser.add_argument("--checkpoint", metavar="PATH", default=None,
                        help="surrogate checkpoint (.safetensors); default: the packaged one for "
                             "--joints and --truth")
    add_objective_argument(parser)
    add_extrapolation_argument(parser)
    parser.add_argument("--json", action="store_true", help="print one JSON object on stdout")


def add_objective_argument(parser):
    parser.add_argument("--objective", choices=OBJECTIVES, default=None,
                        help="what the network was trained to minimise: the paper's eigenvalue "
                             "loss, or the worst frequency error per pose (every mode right); "
                             "default: the checkpoint's, or 'eigenvalue' to pick the default "
                             "checkpoint (TRUTH-nJOINTS, which answers either objective when it "
                             "was trained at rest; else TRUTH-nJOINTS-frequency for 'frequency')")


def add_extrapolation_argument(parser):
    parser.add_argument("--allow-extrapolation", action="store_true",
                        help="predict even for a beam outside the range of a feature that did "
                             "not vary in training (a warning is printed); refused by default")


def run(args) -> int:
    """The command, with every failure turned into one line: BadInput goes on to the CLI (exit
    2); anything else, even with --json, is one line here and exit 1, never a traceback."""
    try:
        return predict_command(args)
    except (BadInput, KeyboardInterrupt, BrokenPipeError):
        raise
    except Exception as exc:            # noqa: BLE001 - the command boundary
        text = " ".join(str(exc).split())[:500]
        kind = ("" if isinstance(exc, PredictionError)
                else f"internal error ({type(exc).__name__}): ")
        sys.stderr.write(f"prbdm predict: error: {kind}{text}\n")
        return 1


def predict_command(args) -> int:
    import time

    from ..surrogate import selection

    request = selection.Request.from_args(args)
    # the beam is read once: `--truth auto` chooses the network from its width, then it is
    # checked against the limits of that network's truth (what `prbdm truth --model TRUTH`
    # refuses, with the same message)
    beam = beam_from_file(args)
    plan = selection.plan(beam, request)
    beam, info = read_beam(args, "predict", model=plan.surrogate.truth, beam=beam)
    t0 = time.perf_counter()
    # `--truth auto` may have chosen a network that cannot answer this panel (a feature it never
    # saw vary, such as nu): the next network answers then, and says which physics it follows
    chosen = selection.answer(plan, beam, lambda s: selection.network_answer(
        s, beam, request.allow_extrapolation))
    out = chosen.answer
    out["time_s"] = time.perf_counter() - t0
    out["input"] = info
    out["truth_reason"] = chosen.reason
    out["warnings"] += chosen.warnings
    for w in out["warnings"]:
        sys.stderr.write(f"prbdm predict: warning: {w}\n")
    if args.json:
        print_json(out)
    else:
        print(render(out))
    return 0


def render(r: dict) -> str:
    b, L, c = r["beam"], r["links"], r["checkpoint"]
    n = r["joints"]
    lines = [f"beam: {b['name'] or '(unnamed)'}  L = {b['length']:.6g} m, "
             f"t = {b['thickness']:.6g} m, mass = {b['mass']:.6g} kg",
             f"{n}R-PRBDM predicted by checkpoint {c['name']} (truth {r['truth']}, law "
             f"{r['law']}, trained on {c['dataset_size']} beams); no FEM was run",
             f"gamma: {', '.join(f'{g:.4f}' for g in r['gamma'])}", "",
             "links (SI; centre of mass measured from the link's joint):"]
    rows = [["0", "-", f"{L['length'][0]:.5g}", "(clamped)", "", "", ""]]
    for j in range(n):
        rows.append([str(j + 1), f"{L['joint_x'][j]:.5g}", f"{L['length'][j + 1]:.5g}",
                     f"{L['mass'][j]:.5g}", f"{L['com'][j]:.5g}", f"{L['inertia'][j]:.5g}",
                     f"{L['base_stiffness'][j]:.5g}"])
    lines.append(table(rows, ["link", "joint x [m]", "length [m]", "mass [kg]", "com [m]",
                              "J [kg m^2]", "s [N m/rad]"]))
    lines += ["", "per pose: SCF k, joint stiffness k s_j [N m/rad], PRBDM frequencies [Hz]:"]
    rows = []
    if r.get("rest"):
        # trained at rest (the shape pose target): its answer there, then held at the poses
        rows.append(["rest", "0", f"{r['rest']['k']:.5g}", " ".join(f"{v:.4g}" for v in
                                                                 L["stiffness"][0]),
                     *(f"{v:.5g}" for v in r["rest"]["freq_hz"])])
    for i, (pose, k, f, ks) in enumerate(zip(r["poses"], r["k"], r["freq_hz"],
                                             L["stiffness"])):
        rows.append([str(i), f"{pose[0]:.4g}", f"{k:.5g}", " ".join(f"{v:.4g}" for v in ks),
                     *(f"{v:.5g}" for v in f)])
    lines.append(table(rows, ["pose", "theta [rad]", "k", "stiffness [N m/rad]",
                              *(f"f{j + 1}" for j in range(n))]))
    if r.get("rest"):
        lines.append("(fitted at rest, its stiffness held at the poses, where the chain follows "
                     "the panel bent into each pose's shape; predict checks it at rest only)")
    ft = r["freq_hz_truth_predicted"]
    lines.append(f"\ntruth frequencies predicted by the network [Hz]: "
                 f"{', '.join(f'{v:.5g}' for v in ft)}")
    lines.append(f"({r['time_s'] * 1e3:.1f} ms)")
    return "\n".join(lines)
