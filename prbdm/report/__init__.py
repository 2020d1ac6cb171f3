"""Error against run time for every way prbdm (and the classical alternatives) produces a model.

:func:`run_report` evaluates on held-out beams and returns the numbers; :func:`write_report`
renders them as ``report.md`` + PNG plots (+ ``report.json``), every file written atomically and
only after everything has been computed, so a failed run leaves no half-written file.
Modules: :mod:`~prbdm.report.measure` (held-out beams, timings, errors, scaling studies),
:mod:`~prbdm.report.tables` (the Markdown), :mod:`~prbdm.report.figures` (the PNGs),
:mod:`~prbdm.report.stability` (the stability suite's section; cases in
:mod:`~prbdm.report.stability_cases`); this one puts them together.

Methods (docs/conventions.md §3 model, n = 4, 4 modes, paper poses, ``beam`` law unless noted):

==================  ==========================================================================
plate truth         Kirchhoff plate FEM (:mod:`prbdm.truth`), the issue's reference
beam truth          Euler-Bernoulli FEM, what the fits and the network target
RFE chain           rigid-finite-element chain: ``gamma = [1/2, 1, 1, 1, 1/2]/4``, k = 1, no fit
Howell 1R, Su 3R    classical static PRBMs with their own springs (:mod:`prbdm.classical`)
fit, S starts       :func:`prbdm.fit.fit_many` to the beam truth (S = 8, 16, 32, 64)
fit to plate        the same, 64 starts, to the plate truth
network             :func:`prbdm.surrogate.Surrogate.predict` (checkpoint ``beam-n4``)
network + refined   ``fit_many`` from the network's best 4 candidate gammas and the fit's four
                    fixed starts, 15 iterations, the best kept (``prbdm.fit.REFINE_*``)
network (direct)    the network's own prediction of the beam-truth frequencies
plate network       the same three rows for the plate network (``plate-n4``), refined against
                    the plate truth; absent when no plate network is found
Mindlin plate       the shear-deformable plate (:mod:`prbdm.truth.mindlin`), a third reference:
                    its truth, a 64-start fit to it and the Mindlin network's rows
                    (``mindlin-n4``), like the plate's
==================  ==========================================================================

Errors of a model against a reference truth: the docs/conventions.md §3 loss over the first
``r = min(n, 4)`` modes (mean over the model's poses of the relative eigenvalue error norm) and
the worst per-mode relative frequency error over those modes and poses. A truth or the direct
prediction is one "pose" with k = 1. Time per beam: wall time of the method alone, per beam; a
batched method (network, RFE chain, classical models, fits: all beams in one call) is timed as the
batch divided by the number of beams; truths are solved one beam at a time. "From geometry" adds
the truth a method needs (fits, refinement).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .figures import plot_error_vs_time, plot_scaling
from .measure import DEFAULT_STARTS, JOINTS, MODES, ReportConfig, held_out_beams, run_report
from .tables import method_table, per_mode_table, render_markdown

__all__ = ["ReportConfig", "run_report", "write_report", "render_markdown", "held_out_beams",
           "method_table", "per_mode_table", "plot_error_vs_time", "plot_scaling",
           "stability_section", "DEFAULT_STARTS", "JOINTS", "MODES"]


def stability_section(cfg: ReportConfig) -> tuple[str | None, str]:
    """The stability suite's Markdown (:func:`prbdm.report.stability.section`), or None and a
    note saying why it is absent."""
    if not cfg.stability:
        return None, "Skipped (`--no-stability`)."
    try:
        from . import stability

        return stability.section(quick=cfg.quick), ""
    except Exception as exc:          # the report stands on its own; say what failed
        return None, f"Not included: the stability suite failed ({type(exc).__name__}: {exc})."


def write_report(cfg: ReportConfig, out) -> dict:
    """Run everything, then write ``out``/report.md, report.json and the PNGs (atomically)."""
    from ..files import atomic_write

    res = run_report(cfg)
    stab_md, stab_note = stability_section(cfg)
    res["stability"] = {"included": stab_md is not None, "note": stab_note, "markdown": stab_md}
    files = {"error_vs_time.png": plot_error_vs_time(res), **plot_scaling(res)}
    files["report.md"] = render_markdown(res, stab_md, stab_note)
    files["report.json"] = json.dumps(res, indent=1, default=_jsonable) + "\n"
    out = Path(out)
    for name, data in files.items():
        atomic_write(out / name, data)
    return res


def _jsonable(v):
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, np.ndarray):
        return v.tolist()
    return str(v)
