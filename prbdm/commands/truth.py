"""``prbdm truth BEAM --model analytic|beam|plate|mindlin [--modes R] [--all-modes] [--json] [--plot FILE]``

Bending natural frequencies of a beam (docs/conventions.md §2, §4). Prints a table by default; ``--json`` prints
one JSON object (``model``, ``omega``, ``freq_hz``, ``time_s``, ``participation``, ``mesh`` and,
with ``--all-modes``, ``all_modes``: every computed mode with its ``participation``). ``--plot``
draws the planform and the kept mode shapes (the idea of the paper's Fig. 13). Never imports torch.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

from ..errors import BadInput
from ._common import add_beam_argument, positive_int, print_json, read_beam, require, table


def add_arguments(parser):
    add_beam_argument(parser)
    parser.add_argument("--model", choices=("auto", "analytic", "beam", "plate", "mindlin",
                                            "rod"),
                        default="auto",
                        help="auto (default: the truth `prbdm fit` takes for this panel, with "
                             "its reason: the beam for a strip up to 0.05 L wide, the Kirchhoff "
                             "or, thick or necked, the Mindlin plate beyond), analytic (uniform "
                             "beams), beam (Euler-Bernoulli FEM), plate (Kirchhoff plate FEM) or "
                             "mindlin (Reissner-Mindlin plate FEM: with transverse shear and "
                             "rotary inertia), or rod (the geometrically exact strip: at rest, "
                             "bent by a tip force to --tip-angle, or bent stress-free into an "
                             "--arc; docs/large-deflection.md)")
    parser.add_argument("--tip-angle", type=float, default=None, metavar="RAD",
                        help="rod: about the equilibrium under a perpendicular tip force that "
                             "turns the tip by RAD (the load's geometric stiffness included)")
    parser.add_argument("--arc", type=float, default=None, metavar="RAD",
                        help="rod: about a stress-free circular arc whose tip turns by RAD")
    parser.add_argument("--modes", type=positive_int(1), default=5, metavar="R",
                        help="number of bending modes (default 5)")
    parser.add_argument("--all-modes", action="store_true",
                        help="list every computed mode with its transverse participation, "
                             "symmetry and whether it was kept (plate: also solves the "
                             "antisymmetric family; mindlin: symmetric family only)")
    parser.add_argument("--elements", type=positive_int(2), default=None, metavar="N",
                        help="mesh resolution along the span (default: automatic)")
    parser.add_argument("--selection", choices=("section", "participation"), default=None,
                        help="plate, mindlin: bending-mode rule (default section; participation = the "
                             "paper's highest-participation rule)")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--plot", metavar="FILE", default=None,
                        help="save a figure of the planform and the kept mode shapes "
                             "(needs matplotlib; format from the extension, e.g. .png, .pdf)")


def run(args) -> int:
    from ..truth import bending_frequencies
    from ..truth.choice import beam_gap_warning, choose_truth

    if args.model == "rod" or args.tip_angle is not None or args.arc is not None:
        return _rod(args)
    from ._common import beam_from_file

    # read once; `auto` chooses from the panel, then the beam is checked against the chosen
    # truth's limits before anything is printed (a refusal is one line)
    beam = beam_from_file(args)
    args.model, reason = choose_truth(beam, args.model)
    beam, info = read_beam(args, "truth", model=args.model, beam=beam)
    options = {}
    if args.selection is not None:
        if args.model not in ("plate", "mindlin"):
            raise BadInput("--selection: applies to --model plate or mindlin only")
        options["selection"] = args.selection
    if args.plot is not None:
        _check_plot_path(args.plot)
        require("matplotlib", purpose="--plot")
    res = bending_frequencies(beam, model=args.model, modes=args.modes,
                              all_modes=args.all_modes, elements=args.elements, **options)
    if args.plot is not None:
        plot_modes(beam, res, args.plot)
    from ..truth.choice import shear_caveat
    caveat = shear_caveat(beam, res.model)
    warnings = [caveat] if caveat else []
    if res.model in ("beam", "analytic"):
        gap = beam_gap_warning(beam, "`--model auto` solves it",
                               modes=min(4, len(res.omega)))
        warnings += [gap] if gap else []
    for w in warnings:
        sys.stderr.write(f"prbdm truth: warning: {w}\n")
    if args.json:
        print_json({**res.to_dict(all_modes=args.all_modes), "reason": reason, "input": info,
                    "warnings": warnings})
        return 0
    print(f"truth: {res.model} ({reason})")
    print(_report(beam, res, args.all_modes))
    if args.plot is not None:
        print(f"plot written to {args.plot}")
    return 0


def _rod(args) -> int:
    """``--model rod``: the strip's frequencies at rest, about a loaded equilibrium or about a
    stress-free arc (prbdm.truth.rod)."""
    import math

    if args.model != "rod":
        raise BadInput("--tip-angle, --arc: apply to --model rod only")
    if args.tip_angle is not None and args.arc is not None:
        raise BadInput("--tip-angle, --arc: give one (a loaded or a stress-free bent strip)")
    for flag in ("all_modes", "selection", "plot", "elements"):
        if getattr(args, flag) not in (None, False):
            raise BadInput(f"--{flag.replace('_', '-')}: does not apply to --model rod")
    from ..truth.rod import arc_shape, rod_frequencies, rod_static

    beam, info = read_beam(args, "truth", model="beam")
    about, what = None, "at rest (straight, unloaded)"
    if args.tip_angle is not None:
        about = rod_static(beam, tip_angle=args.tip_angle)
        what = (f"held by a perpendicular tip force of {about.force[1]:.6g} N at a tip angle of "
                f"{about.tip_angle:.6g} rad")
    elif args.arc is not None:
        about = arc_shape(beam, args.arc)
        what = f"bent stress-free into an arc with a tip angle of {args.arc:g} rad"
    res = rod_frequencies(beam, about=about, modes=args.modes)
    out = {**res.to_dict(), "reason": f"--model rod as asked: {what}", "input": info,
           "warnings": []}
    if args.json:
        print_json(out)
        return 0
    print(f"truth: rod, {what}")
    rows = [[j + 1, f"{w:.6g}", f"{w / (2 * math.pi):.6g}"] for j, w in enumerate(res.omega)]
    print(table(rows, ["mode", "omega [rad/s]", "f [Hz]"]))
    print(f"({res.mesh['elements']} elements of degree {res.mesh['degree']}, "
          f"{1e3 * res.time_s:.1f} ms)")
    return 0


def _check_plot_path(path):
    p = Path(path)
    if p.suffix.lower() not in (".png", ".pdf", ".svg", ".jpg", ".jpeg"):
        raise BadInput(f"--plot: unsupported file type {p.suffix!r}; use .png, .pdf, .svg or .jpg")
    if p.parent != Path("") and not p.parent.is_dir():
        raise BadInput(f"--plot: no such directory {str(p.parent)!r}")


def _report(beam, res, all_modes: bool) -> str:
    name = f" {beam.name!r}" if beam.name else ""
    mesh = res.mesh
    if res.model == "analytic":
        how = "closed form"
    elif res.model == "beam":
        how = f"{mesh['elements']} Hermite elements"
    elif res.model == "mindlin":
        how = (f"{mesh['triangles']} Reissner-Mindlin P{mesh['degree']} triangles "
               f"({mesh['mesher']}), {mesh['dofs']} DOFs")
    else:
        how = f"{mesh['triangles']} Argyris triangles ({mesh['mesher']}), {mesh['dofs']} DOFs"
    lines = [f"beam{name}: L = {beam.length:.6g} m, t = {beam.thickness:.6g} m, "
             f"E = {beam.material.E:.6g} Pa, rho = {beam.material.rho:.6g} kg/m^3",
             f"model {res.model}: {how}, {res.time_s * 1e3:.1f} ms", ""]
    kept = [m for m in res.all_modes if m["kept"]]
    rows = [(i + 1, f"{m['omega']:.6g}", f"{m['freq_hz']:.6g}", f"{m['participation']:.4f}")
            for i, m in enumerate(kept)]
    lines.append(table(rows, ("mode", "omega [rad/s]", "f [Hz]", "participation")))
    if all_modes:
        lines += ["", "all computed modes:"]
        rows = []
        for m in res.all_modes:
            frac = m.get("section_fraction")
            mark = ("kept" if m["kept"] else "") + (" ~" if m.get("ambiguous") else "")
            rows.append((f"{m['freq_hz']:.6g}", m["symmetry"], f"{m['participation']:.4f}",
                         "" if frac is None else f"{frac:.3f}", mark.strip()))
        lines.append(table(rows, ("f [Hz]", "symmetry", "participation", "section frac.",
                                  "bending")))
        if any(m.get("ambiguous") for m in res.all_modes):
            lines.append("~ section fraction within 0.1 of the 1/2 threshold: a mode mixing "
                         "bending and chordwise motion")
    return "\n".join(lines)


def plot_modes(beam, res, path) -> None:
    """Planform and kept mode shapes, one panel each, titled with the frequency."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    shapes = res.shapes or {}
    n = len(res.omega)
    cols = min(3, n + 1)
    rows = math.ceil((n + 1) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.0 * rows), squeeze=False)
    axes = axes.ravel()
    L = beam.length
    xs = np.concatenate([beam.x, beam.x[::-1], beam.x[:1]])
    ys = np.concatenate([beam.half_width, -beam.half_width[::-1], beam.half_width[:1]])
    ax = axes[0]
    ax.fill(xs, ys, color="0.85", edgecolor="k", lw=1)
    ax.plot([0, 0], [-beam.half_width[0], beam.half_width[0]], color="k", lw=4)
    ax.set_aspect("equal")
    ax.set_title(f"planform ({res.model}), clamped at x = 0", fontsize=9)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    for i in range(n):
        ax = axes[i + 1]
        title = f"mode {i + 1}: {res.freq_hz[i]:.4g} Hz"
        if shapes.get("kind") == "plate":
            p, t, w = shapes["p"] * L, shapes["t"], shapes["w"][i]
            # mirror the half model (symmetric modes)
            P = np.hstack([p, p * np.array([[1.0], [-1.0]])])
            T = np.hstack([t, t[[0, 2, 1]] + p.shape[1]])
            W = np.concatenate([w, w])
            tc = ax.tripcolor(P[0], P[1], T.T, W, shading="gouraud", cmap="RdBu_r",
                              vmin=-1, vmax=1)
            ax.tricontour(P[0], P[1], T.T, W, levels=[0.0], colors="k", linewidths=0.6)
            ax.set_aspect("equal")
            ax.set_xlabel("x [m]")
            if i == n - 1:
                fig.colorbar(tc, ax=ax, shrink=0.8, label="w / max|w|")
        else:
            ax.plot(shapes["x"] * L, shapes["w"][i], color="C0")
            ax.axhline(0.0, color="0.6", lw=0.6)
            ax.set_xlabel("x [m]")
            ax.set_ylabel("w / max|w|")
        ax.set_title(title, fontsize=9)
    for ax in axes[n + 1:]:
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
