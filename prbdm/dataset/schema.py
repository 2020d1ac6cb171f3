"""What decides a data set's records (the spec) and what a record holds (the columns).

Imports neither torch nor scikit-fem: the parent process of a run checks the spec before any
worker starts.
"""
from __future__ import annotations

import math

import numpy as np

from ..constants import DEFAULT_STARTS, OBJECTIVES  # noqa: F401  (re-exported)
from ..errors import BadInput
from ..geometry import MAX_THICKNESS_RATIO, RANDOM_DEFAULTS, Beam, Material, random_beam

MANIFEST = "_manifest.json"
FORMAT = "prbdm-dataset"
FORMAT_VERSION = 1

TRUTH_MODELS = ("beam", "plate", "mindlin")
LAWS = ("beam", "paper")
#: what the fit minimises (prbdm.constants.OBJECTIVES); a spec without ``objective`` (made
#: before the choice existed) is ``eigenvalue``, the only objective there was
DEFAULT_OBJECTIVE = "eigenvalue"
#: what a plate or mindlin truth gives a new set: the bending spectrum (docs/conventions.md); a set
#: made before the spectrum has no ``target`` in its spec and keeps the section rule's pick
TARGETS = ("spectrum", "section")
DEFAULT_TARGET = "spectrum"
OLD_TARGET = "section"
#: beams per batched fit (one task) for a new data set when --fit-batch is not given: measured
#: best on 2 cores (benchmarks/bench_dataset.py); a set without ``fit_batch`` in its spec (made
#: before chunking) is labelled one beam per task, as it was
DEFAULT_FIT_BATCH = 8
MAX_FIT_BATCH = 256
#: default number of records per part file, and the longest a record waits in memory [s]
PART_SIZE = 256
FLUSH_S = 60.0
#: fit multistart points when --starts is not given: prbdm.constants.DEFAULT_STARTS (a spec
#: records the number it used)

#: spec field -> the command-line flag that sets it (for error messages)
FLAGS = {"seed": "--seed", "joints": "--joints", "modes": "--modes", "truth": "--truth",
         "truth_modes": "--modes", "law": "--law", "poses": "--poses", "starts": "--starts",
         "beam.p": "--stations", "beam.min_half_width": "--min-half-width",
         "beam.max_half_width": "--max-half-width", "beam.min_thickness": "--thickness",
         "beam.max_thickness": "--thickness",
         "fit_batch": "--fit-batch", "objective": "--objective", "target": "--target",
         "beam.family": "--family"}


def make_spec(joints: int, modes: int | None = None, truth: str = "beam", law: str = "beam",
              poses="paper", starts: int | None = None, seed: int = 0, p: int | None = None,
              min_half_width: float | None = None, truth_modes: int | None = None,
              material: Material | None = None, fit_batch: int | None = None,
              objective: str | None = None, max_half_width=None,
              target: str | None = None, family: str = "paper", thickness=None) -> dict:
    """The JSON-able description of a data set: everything that decides a record.

    ``modes`` (default ``joints``) is the number of truth modes the fit maps; the truth is computed
    with ``truth_modes = max(modes, joints) + 1`` modes (all stored). ``poses`` is ``"paper"``,
    ``"linear"`` or a list of joint angles [rad]. ``starts=None`` means :data:`DEFAULT_STARTS`;
    ``starts=0`` makes a *truth-only* set: geometry and truth frequencies, no fit (the fit columns
    are null). That is all the surrogate's physics training needs, at about 1/100 of the cost.
    ``max_half_width``: the generator's bound on the half-widths [m], a number (the paper's 0.5 L
    when None) or a pair (lo, hi): each beam's bound drawn log-uniformly between them
    (:func:`prbdm.geometry.random_beam`). ``thickness``: its thickness bounds (lo, hi) [m] (the
    paper's 0.01, 0.05 when None). ``fit_batch``: beams per batched fit; ``objective``:
    what the fit minimises (one of
    :data:`OBJECTIVES`). For both, None (the key is then absent) means the folder's value for an
    existing set (1 and ``eigenvalue`` if it has none) and :data:`DEFAULT_FIT_BATCH` and
    :data:`DEFAULT_OBJECTIVE` for a new one.
    """
    def integer(name, v, lo):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < lo:
            raise BadInput(f"{FLAGS.get(name, name)}: must be an integer >= {lo}, got {v!r}")
        return int(v)

    joints = integer("joints", joints, 1)
    modes = joints if modes is None else integer("modes", modes, 1)
    truth_modes = (max(modes, joints) + 1 if truth_modes is None
                   else integer("truth_modes", truth_modes, max(modes, joints)))
    if truth not in TRUTH_MODELS:
        raise BadInput(f"--truth: must be one of {', '.join(TRUTH_MODELS)} for random beams, "
                       f"got {truth!r}")
    if law not in LAWS:
        raise BadInput(f"--law: must be one of {', '.join(LAWS)}, got {law!r}")
    if isinstance(poses, str):
        if poses not in ("paper", "linear"):
            raise BadInput(f"--poses: must be paper, linear or a list of angles, got {poses!r}")
    else:
        poses = [float(t) for t in poses]
        if not poses or not all(math.isfinite(t) for t in poses):
            raise BadInput("--poses: must be a non-empty list of finite angles [rad]")
    starts = DEFAULT_STARTS if starts is None else integer("starts", starts, 0)
    seed = integer("seed", seed, 0)
    if family == "smooth":
        # prbdm.planforms.smooth_beam: its own ranges; the paper generator's options do not apply
        given = [n for n, v in (("--stations", p), ("--min-half-width", min_half_width),
                                ("--max-half-width", max_half_width),
                                ("--thickness", thickness)) if v is not None]
        if given:
            raise BadInput(f"{given[0]}: an option of the paper's generator, not of --family "
                           "smooth (uniform, tapered, trapezoidal and necked planforms, full "
                           "width 0.02-1 L, t/L 0.002-0.05, nu 0.2-0.45)")
        from ..planforms import SMOOTH_DEFAULTS

        gen = {"family": "smooth", **{k: list(v) if isinstance(v, tuple) else v
                                      for k, v in SMOOTH_DEFAULTS.items()}}
    elif family == "paper":
        gen = _paper_generator(p, min_half_width, max_half_width, integer, thickness)
    else:
        raise BadInput(f"--family: must be paper or smooth, got {family!r}")
    gen["material"] = (material or Material()).to_dict()
    spec = {"seed": seed, "beam": gen, "truth": truth, "truth_modes": truth_modes,
            "joints": joints, "modes": modes, "law": law, "poses": poses, "starts": starts}
    if fit_batch is not None:
        spec["fit_batch"] = check_fit_batch(fit_batch)
    if objective is not None:
        spec["objective"] = check_objective(objective)
    if target is not None:
        if target not in TARGETS:
            raise BadInput(f"--target: must be one of {', '.join(TARGETS)}, got {target!r}")
        spec["target"] = target
    return spec


def _paper_generator(p, min_half_width, max_half_width, integer, thickness=None) -> dict:
    """The paper generator's options of a spec (:func:`prbdm.geometry.random_beam`), checked."""
    gen = dict(RANDOM_DEFAULTS)
    if p is not None:
        gen["p"] = integer("beam.p", p, 0)
    if max_half_width is not None:
        bounds = [max_half_width] if np.ndim(max_half_width) == 0 else list(max_half_width)
        if not (1 <= len(bounds) <= 2 and
                all(isinstance(v, (int, float)) and not isinstance(v, bool) and
                    math.isfinite(v) and v > 0 for v in bounds) and bounds[0] <= bounds[-1]):
            raise BadInput(f"--max-half-width: a length > 0 [m], or two (lo,hi) with "
                           f"0 < lo <= hi, got {max_half_width!r}")
        gen["max_half_width"] = (float(bounds[0]) if len(bounds) == 1
                                 else [float(v) for v in bounds])
    lowest = np.min(gen["max_half_width"])
    if min_half_width is not None:
        if not (isinstance(min_half_width, (int, float)) and
                0 <= min_half_width < lowest):
            raise BadInput(f"--min-half-width: must lie in [0, {lowest}) m (below the "
                           f"smallest --max-half-width), got {min_half_width!r}")
        gen["min_half_width"] = float(min_half_width)
    if thickness is not None:
        top = MAX_THICKNESS_RATIO * gen["length"]
        t = list(thickness) if np.ndim(thickness) else [thickness]
        if not (len(t) == 2 and all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                    and math.isfinite(v) for v in t) and 0 < t[0] <= t[1] <= top):
            raise BadInput(f"--thickness: two bounds LO,HI [m] with 0 < LO <= HI <= {top:g} "
                           f"(t/L up to {MAX_THICKNESS_RATIO:g}), got {thickness!r}")
        gen["min_thickness"], gen["max_thickness"] = float(t[0]), float(t[1])
    return gen


def check_fit_batch(value) -> int:
    if (isinstance(value, bool) or not isinstance(value, (int, np.integer))
            or not 1 <= value <= MAX_FIT_BATCH):
        raise BadInput(f"--fit-batch: must be an integer in [1, {MAX_FIT_BATCH}], got {value!r}")
    return int(value)


def check_objective(value) -> str:
    if value not in OBJECTIVES:
        raise BadInput(f"--objective: must be one of {', '.join(OBJECTIVES)}, got {value!r}")
    return value


def flatten(d: dict, prefix: str = "") -> dict:
    out = {}
    for key, value in d.items():
        if isinstance(value, dict):
            out.update(flatten(value, f"{prefix}{key}."))
        else:
            out[f"{prefix}{key}"] = value
    return out


def spec_difference(old: dict, new: dict) -> str | None:
    """The first field (dotted name) where two specs differ; None when equal."""
    a, b = flatten(old), flatten(new)
    for key in sorted(set(a) | set(b)):
        if a.get(key, "<absent>") != b.get(key, "<absent>"):
            return key
    return None


def beam_for(spec: dict, index: int):
    """Beam ``index`` of a data set: a pure function of (spec seed, generator options, index):
    the paper's generator, or with ``beam.family = "smooth"`` :func:`prbdm.planforms.smooth_beam`
    (other shapes, thicknesses and Poisson's ratios)."""
    gen = dict(spec["beam"])
    material = Material(**gen.pop("material"))
    if gen.pop("family", "paper") == "smooth":
        from ..planforms import smooth_beam

        return smooth_beam(spec["seed"], index, material=material, **gen)
    return random_beam(spec["seed"], index, material=material, **gen)


def record_beam(x, half_width, thickness, material: Material):
    """The beam of a stored record, from its ``x``, ``half_width`` and ``thickness`` columns."""
    return Beam(x=np.asarray(x), half_width=np.asarray(half_width), thickness=float(thickness),
                material=material)


def refused_by_truth(table, spec: dict) -> np.ndarray:
    """(N,) bool: the records of a stored set whose beam today's truth model refuses
    (:func:`prbdm.geometry.check_beam` with the spec's truth), from their ``x``, ``half_width``
    and ``thickness`` columns. A set labelled before a limit was added keeps those records as
    ``ok`` (e.g. plate panels with a corner sharper than ``MIN_PLATE_CORNER_DEGREES``, whose
    stored plate frequencies can be wrong): training and evaluation leave them out."""
    from ..geometry import check_beam

    material = Material(**spec["beam"]["material"])
    out = np.zeros(len(table), dtype=bool)
    for i, (x, w, t) in enumerate(zip(table["x"], table["half_width"], table["thickness"])):
        try:
            check_beam(record_beam(x, w, t, material), spec["truth"])
        except BadInput:
            out[i] = True
    return out


#: the record columns of a new set, in order: name -> (pyarrow type name, meaning). A set keeps
#: the columns its manifest lists (``frequency_percent`` is absent from sets made before it)
COLUMNS = {
    "index": ("int64", "beam number; the beam is random_beam(seed, index, **spec.beam)"),
    "status": ("string", "ok, or error (then `error` says which stage failed and why)"),
    "error": ("string", "'stage: ExceptionType: message', null when ok"),
    "x": ("list<double>", "planform stations [m], x[0] = 0, x[-1] = L"),
    "half_width": ("list<double>", "half-width at each station [m]"),
    "thickness": ("double", "uniform thickness [m]"),
    "nu": ("double", "Poisson's ratio of the beam (the smooth family draws one per beam)"),
    "length": ("double", "L [m]"),
    "mass": ("double", "beam mass [kg]"),
    "omega_truth": ("list<double>", "truth bending frequencies, ascending [rad/s] (truth_modes)"),
    "truth_time_s": ("double", "wall time of the truth solve [s]"),
    # plate and mindlin: every computed symmetric mode, so that any target (the bending spectrum,
    # the section rule's pick) is recomputed without a FEM; null for the beam truths
    "symmetric_lambda": ("list<double>", "plate, mindlin: every computed symmetric mode's "
                         "nondimensional eigenvalue (omega / omega_p)^2, ascending, omega_p = "
                         "t / L^2 sqrt(E / (12 rho (1 - nu^2)))"),
    "symmetric_section_fraction": ("list<double>", "plate, mindlin: each symmetric mode's section "
                                   "fraction s (its bending weight is clip((s - 1/2) / 0.6 + "
                                   "1/2, 0, 1))"),
    "symmetric_participation": ("list<double>", "plate, mindlin: each symmetric mode's transverse "
                                "mass participation"),
    "gamma": ("list<double>", "fitted link lengths / L (joints + 1), sum 1"),
    "k": ("list<double>", "fitted stiffness correction factor per pose"),
    "loss_percent": ("double", "the paper's loss of the fit, docs/conventions.md §3 [%], whatever objective "
                     "was minimised"),
    "gamma_spread": ("double", "spread of gamma among near-best starts (ambiguity of the label)"),
    "n_near_best": ("int64", "starts within 1 % of the best loss"),
    "freq_error_max": ("list<double>", "per mapped mode, worst relative frequency error of the "
                       "poses"),
    "frequency_percent": ("double", "worst per-mode frequency error of the fit over modes and "
                          "poses, 100 max |omega / omega_T - 1| [%], whatever objective was "
                          "minimised"),
    "fit_time_s": ("double", "wall time of the fit [s]"),
    "fit_seed": ("int64", "seed given to the fit's multistart"),
    "time_s": ("double", "wall time to label the beam, all stages [s]"),
    "cpu_s": ("double", "CPU time of the labelling thread [s]; 1 / cpu_s is the rate of a free "
              "core"),
    "worker": ("string", "host:pid that labelled it"),
}


def arrow_schema(names=None, metadata: dict | None = None):
    """The pyarrow schema of the columns ``names`` (default: a new set's, :data:`COLUMNS`)."""
    import pyarrow as pa

    types = {"int64": pa.int64(), "string": pa.string(), "double": pa.float64(),
             "list<double>": pa.list_(pa.float64())}
    names = list(COLUMNS) if names is None else list(names)
    unknown = [n for n in names if n not in COLUMNS]
    if unknown:
        raise BadInput(f"DIR: the manifest lists columns this prbdm does not know: {unknown}; "
                       f"upgrade prbdm")
    return pa.schema([pa.field(n, types[COLUMNS[n][0]]) for n in names], metadata=metadata)


def manifest_columns(names=None) -> dict:
    """The ``columns`` entry of a manifest: name -> {type, meaning}."""
    names = list(COLUMNS) if names is None else names
    return {k: {"type": COLUMNS[k][0], "meaning": COLUMNS[k][1]} for k in names}
