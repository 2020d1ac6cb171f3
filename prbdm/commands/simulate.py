"""``prbdm simulate BEAM (--joints N | --from FIT.json)``: time response of the PRBDM vs the truth.

Integrates the PRBDM's full nonlinear equations of motion (springs at rest straight;
:mod:`prbdm.simulate`) from a tip deflection or a tip impulse, and the truth from the same
initial condition; compares the tip motions and their first-mode periods. The truth:

- up to a tip deflection of 0.01 L (the default is 0.001 L), a tip impulse, or with
  ``--damping``: the Euler-Bernoulli beam's modal superposition; the chain has the stiffness of
  one pose at every angle, and both periods are measured by the same windowed least-squares
  sinusoid fit;
- an undamped release beyond 0.01 L: the geometrically exact rod (:mod:`prbdm.large_amplitude`),
  each model released from its own static shape under a tip force with its tip at D, the chain
  with the stiffness law its result was fitted with (constant for ``pose_target`` ``shape``, the
  per-pose SCFs interpolated for ``straight``, as fitted); periods from downward zero crossings,
  5 periods by default. A deflection the rod does not reach under the loads it accepts exits 2.

With ``--joints`` the fit uses the linear pose set by default (``--poses linear``): small
vibrations about the straight beam, one stiffness at every angle. With ``--from``, ``--pose rest``
(default) is the small-vibration model about theta = 0 at small amplitude: a result made for the
paper's deflected poses is refitted at theta = 0 against its own truth frequencies first (no FEM;
``refit`` in the JSON); a ``shape`` result keeps its rest stiffness. At large amplitude
``--pose rest`` simulates the result as fitted (no refit). The result's ``beam_fingerprint``
must be the beam's (exit 2 otherwise, unless ``--ignore-fingerprint``). The chain's
small-vibration frequencies at rest are compared with the truth before the run (``check``; a
warning per mode beyond ``--tolerance``, default 5 %).

JSON (``--json``): ``reference`` (``modal`` or ``rod``), ``pose_target``, ``springs`` (the spring
law: ``law`` constant or interpolated, its SCFs), ``period_prbdm_s``, ``period_truth_s``,
``period_error`` (relative; all three null, with a warning, where a period cannot be measured:
damping above about 0.72), ``period_resolution`` (the truth's measured against its exact period;
against the rod, its period change at half its steps), ``fit_freq_error_mode1`` (the fit's
first-mode frequency error at that pose, when known), ``fit_truth_difference_mode1`` (the fit's
truth omega_1 against this truth's, when known), ``period_prbdm_linear_s`` /
``period_truth_exact_s`` (linear theory, damped), ``omega_prbdm_linear``, ``omega_truth``,
``max_tip_difference`` / ``rms_tip_difference`` (relative to the largest truth deflection),
``energy_drift`` (undamped), ``release`` (against the rod: each model's released shape),
``truth``, ``solver``, ``initial``, ``damping_ratio``, ``duration_s``, ``refit``, ``check``,
``beam_fingerprint``, ``warnings``, ``time_s``, and the series ``t`` [s], ``tip_prbdm``,
``tip_truth`` [m].
"""
from __future__ import annotations

import sys

from ..errors import BadInput
from ._common import check_plot_path, positive_int, print_json, read_beam, require, table
from .export import add_source_arguments, finite_float, fit_from_args


def add_arguments(parser):
    # the fit is made to the truth simulated here: the Euler-Bernoulli beam (its modal
    # superposition is the reference); a wide panel is told its measured beam-plate gap
    add_source_arguments(parser, default_poses="linear", truths=("beam",), default_truth="beam")
    ic = parser.add_mutually_exclusive_group()
    ic.add_argument("--tip-deflection", type=finite_float(), default=None, metavar="D",
                    help="release from rest in the static shape of a tip force with tip "
                         "deflection D [m] (default 0.001 L); beyond 0.01 L, undamped, the "
                         "truth is the geometrically exact rod")
    ic.add_argument("--tip-impulse", type=finite_float(), default=None, metavar="P",
                    help="strike the straight beam at the tip with impulse P [N s] (against the "
                         "linear truth)")
    parser.add_argument("--damping", type=finite_float(minimum=0.0), default=0.0, metavar="ZETA",
                        help="first-mode damping ratio in [0, 1) (stiffness-proportional; default "
                             "0; against the linear truth)")
    parser.add_argument("--duration", type=finite_float(positive=True), default=None,
                        metavar="T",
                        help="simulated time [s]: 3 damped to 500 first-mode periods, 40 against "
                             "the rod (default 20, at least 4 damped; 5 against the rod)")
    parser.add_argument("--truth-modes", type=positive_int(1, 100), default=20, metavar="R",
                        help="modes of the truth's modal superposition (default 20)")
    parser.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    parser.add_argument("--plot", metavar="FILE", default=None,
                        help="plot both tip motions (PNG/PDF/SVG)")


def run(args) -> int:
    from ..simulate import (
        CheckSettings,
        InitialCondition,
        ReferenceSettings,
        RunSettings,
        check_damping,
        plot_simulation,
        prepare_reference,
        simulate,
    )

    check_damping(args.damping)           # before the fit: an overdamped beam has no period
    if args.plot:
        check_plot_path(args.plot)
        require("matplotlib", purpose="--plot")
    beam, beam_info = read_beam(args, "simulate")
    from ..truth.choice import beam_gap_warning

    gap = beam_gap_warning(beam, "simulate's reference and its fit are the beam's; for the "
                           "plate's dynamics export the plate fit (`prbdm export BEAM --joints N`) "
                           "and simulate it in MuJoCo")
    initial = InitialCondition(args.tip_deflection, args.tip_impulse)
    settings = RunSettings(damping=args.damping, duration=args.duration)
    reference = ReferenceSettings(truth_modes=args.truth_modes)
    # before the fit (seconds): the truth's first period bounds --duration, and the rod's static
    # shape (large amplitude) bounds --tip-deflection
    prepared = prepare_reference(beam, initial, settings, reference)
    fit, warnings = fit_from_args(args, beam)
    res = simulate(beam, fit, args.pose, initial, settings, reference,
                   CheckSettings(tolerance=args.tolerance / 100,
                                 ignore_fingerprint=args.ignore_fingerprint,
                                 check_beam=args.fit_file is not None),
                   prepared=prepared)
    res.info["warnings"] = ([gap] if gap else []) + warnings + res.info["warnings"]
    for w in res.info["warnings"]:
        sys.stderr.write(f"warning: {w}\n")
    if args.plot:
        try:
            plot_simulation(res, args.plot)
        except OSError as exc:
            raise BadInput(f"--plot: cannot write {args.plot!r} ({exc})") from None
    info = res.info
    if args.json:
        print_json({**res.to_dict(), "input": beam_info})
        return 0
    (kind, amount), = info["initial"].items()
    rod = info["reference"] == "rod"
    springs = info["springs"]
    model = (f"{info['joints']}R-PRBDM (law {info['law']}, "
             + (f"springs {springs['law']}, pose target {springs['pose_target']}" if rod else
                f"pose {info['pose']}, SCF k = {info['k']:.6g}") + ")")
    truth = "the geometrically exact rod" if rod else \
        f"Euler-Bernoulli modes ({info['truth']['modes']})"
    print(f"{model} vs {truth}: {kind.replace('_', ' ')} {amount:g} "
          f"{'m' if kind == 'tip_deflection' else 'N s'}, damping ratio "
          f"{info['damping_ratio']:g}, {info['duration_s']:.4g} s")
    fe = info["fit_freq_error_mode1"]
    def shown(v):
        return "-" if v is None else f"{v:.8g}"

    rows = [["PRBDM (nonlinear)", shown(info["period_prbdm_s"]),
             shown(info["period_prbdm_linear_s"])],
            ["truth", shown(info["period_truth_s"]), shown(info["period_truth_exact_s"])]]
    print(table(rows, ["first-mode period", "measured s", "linear theory s"]))
    td = info["fit_truth_difference_mode1"]
    notes = ([f"fit's first-mode frequency error {100 * fe:.4g} %"] if fe is not None else []) \
        + ([f"fit's truth vs this truth {100 * td:.2g} %"] if td is not None else [])
    pe, res_ = info["period_error"], info["period_resolution"]
    how = ("the rod's period at half its steps" if rod
           else "the truth's measured against its exact period")
    print(("period error " + ("not measured (see the warning)" if pe is None else
                              f"{100 * pe:.4g} %" + ("" if res_ is None else
                                                    f" (resolution {100 * res_:.2g} %: {how})")))
          + (f" ({'; '.join(notes)})" if notes else ""))
    print(f"tip difference: max {100 * info['max_tip_difference']:.3g} %, rms "
          f"{100 * info['rms_tip_difference']:.3g} % of the largest deflection; "
          f"{info['solver']['nfev']} evaluations, {info['time_s']:.2f} s")
    if info["refit"] is not None:
        print(f"refitted at theta = 0 against the result's {info['refit']['truth']} "
              f"({info['refit']['time_s']:.2f} s): the given fit was made for deflected poses")
    c = info["check"]
    print(f"check against the truth ({c['truth']}), modes 1-{c['modes']}: worst mode "
          f"{c['worst_mode']}, {100 * c['max_error']:.3g} % "
          f"({'within' if c['ok'] else 'BEYOND'} {100 * c['tolerance']:g} %)")
    if args.plot:
        print(f"plot written to {args.plot}")
    return 0
