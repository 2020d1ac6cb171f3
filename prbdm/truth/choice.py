"""``--truth auto``: the Euler-Bernoulli beam for a slender strip, the Kirchhoff plate otherwise,
and the shear-deformable (Reissner-Mindlin) plate for a plate panel thick or necked enough that
the Kirchhoff plate would be more than 1 % off (:func:`shear_caveat`, measured below).

The rule is read off measured beam-vs-plate differences (``benchmarks/truth_choice.py``, table in
docs/howto/choose-a-truth.md, data in docs/truth-choice.json): 220 random planforms of the paper's generator
with the half-width scaled to 0.005-0.5 L, both truths solved, ``|omega_beam / omega_plate - 1|``
on modes 1-4 against the full width ratio ``b / L = 2 max(w) / L``. The difference grows about in
proportion to b / L, with a shape factor that varies by 20x between planforms (abrupt width
changes and a narrow root cost most). Among the panels with b / L <= 0.05, 95 % have every one of
modes 1-4 within 0.65 % of the plate (the worst 2.2 %); at b / L <= 0.07 the 95th percentile is
1.6 %, at 0.1 it is 2.2 %. So a panel up to 5 % of its length wide is a beam to within the stated
1 % for 19 panels in 20, and anything wider is solved as a plate.

This module needs neither scikit-fem nor torch.
"""
from __future__ import annotations

#: beam-vs-plate frequency difference that ``auto`` accepts from the beam (fraction), on modes
#: 1-4, for 95 % of the measured panels of a width
AUTO_TOLERANCE = 0.01
#: the widest full-width ratio 2 max(w) / L solved as a beam by ``auto`` (see the module text)
AUTO_BEAM_MAX_WIDTH = 0.05
TRUTHS = ("beam", "plate", "mindlin")
CHOICES = ("auto",) + TRUTHS


def width_ratio(beam) -> float:
    """Full width over length, ``2 max(half_width) / L``."""
    return float(2 * beam.half_width.max() / beam.length)


def choose_truth(beam, truth: str = "auto") -> tuple[str, str]:
    """(truth model, reason) for ``beam``: ``truth`` itself unless it is ``"auto"``."""
    if truth != "auto":
        return truth, f"--truth {truth} as asked"
    b = width_ratio(beam)
    if b <= AUTO_BEAM_MAX_WIDTH:
        return "beam", (f"auto: full width {b:.3g} L <= {AUTO_BEAM_MAX_WIDTH:g} L, a slender strip: "
                        f"the beam is within {AUTO_TOLERANCE:.0%} of the plate on modes 1-4 for "
                        "95 % of measured panels this narrow (docs/howto/choose-a-truth.md)")
    from ..errors import BadInput
    from ..geometry import MAX_PLATE_THICKNESS_RATIO, check_beam

    if beam.thickness > MAX_PLATE_THICKNESS_RATIO * 2 * float(beam.half_width.max()):
        # thicker than half its width: a bar, outside thin-plate theory (the plate refuses it);
        # the beam when it accepts the panel, else the plate's refusal stands. Other plate
        # limits (a width varying too much for its mesh) are not a reason to answer a wide
        # panel with the beam's physics: their refusal stands
        try:
            check_beam(beam, "beam")
        except BadInput:
            return "plate", f"auto: full width {b:.3g} L > {AUTO_BEAM_MAX_WIDTH:g} L"
        return "beam", (f"auto: full width {b:.3g} L > {AUTO_BEAM_MAX_WIDTH:g} L, but thicker "
                        f"than {MAX_PLATE_THICKNESS_RATIO:g} x its full width, outside thin-plate "
                        "theory: solved as a beam (docs/howto/choose-a-truth.md)")
    wide = (f"auto: full width {b:.3g} L > {AUTO_BEAM_MAX_WIDTH:g} L: a beam model would differ "
            f"from the plate by more than {AUTO_TOLERANCE:.0%} on 1 panel in 20 or more this "
            "wide")
    if shear_caveat(beam, "plate"):
        # thick or necked: the Kirchhoff plate would be more than the tolerance above the
        # shear-deformable plate, which 3-D elasticity supports (the measurement below)
        tl, neck, _ = _shear_inputs(beam)
        return "mindlin", (f"{wide}; t/L = {tl:.2g} with a narrowest full width of {neck:.2g} t: "
                           f"the Kirchhoff plate would be more than {AUTO_TOLERANCE:.0%} above "
                           "the shear-deformable (Mindlin) plate, which 3-D elasticity supports "
                           "(docs/howto/choose-a-truth.md)")
    return "plate", f"{wide} (docs/howto/choose-a-truth.md)"


# ------------------------------------------------------------------ what the thin models leave out
#: The Euler-Bernoulli beam and the Kirchhoff plate leave out transverse shear and rotary inertia.
#: Measured (docs/howto/choose-a-truth.md, "What the Kirchhoff plate leaves out"): on the paper's random panels
#: the Kirchhoff plate is above the Reissner-Mindlin plate by more than 1 % on some mode 1-4 for
#: 97 % of the panels 0.01 L thick or more (1.3-6 % median per mode, most where a neck is a few
#: thicknesses wide; 3-D elasticity is on Mindlin's side on the six random panels solved), and
#: for half of those 0.005 L thick (the ones with a neck narrower than ~8 t). A uniform strip
#: 4-6 t wide is not a neck: Kirchhoff is within 0.35 % of Mindlin there. Smooth planforms (the
#: uniform beam, the square, a trapezoid) reach 1 % on mode 4 at t/L = 0.02, growing like
#: (t/L)^2: per mode 0.29, 0.99, 2.27, 4.08 % at t/L = 0.0405 (3-D).
SHEAR_PLATE_THICKNESS = 0.02         # t / L from which every plate answer carries the caveat
SHEAR_NECKED_THICKNESS = 0.01        # ... from which a panel with a neck (below) does
SHEAR_PLATE_NECK = 8.0               # ... and a neck narrower than this many t at any thickness
SHEAR_NECK_RATIO = 0.5               # a neck: narrowest half-width below this x the widest
SHEAR_SMOOTH_PERCENT = (0.29, 0.99, 2.27, 4.08)    # modes 1-4 at t/L = SHEAR_SMOOTH_AT, 3-D
SHEAR_SMOOTH_AT = 0.0405


def _shear_inputs(beam) -> tuple[float, float, bool]:
    """t / L, the narrowest full width in thicknesses, and whether that is a neck."""
    w = beam.half_width
    return (float(beam.thickness / beam.length), float(2 * w.min() / beam.thickness),
            bool(w.min() < SHEAR_NECK_RATIO * w.max()))


def _smooth_estimate(tl: float) -> list[float]:
    """Per-mode shear excess [%] of a thin model on a smooth panel at t / L = ``tl``."""
    return [p * (tl / SHEAR_SMOOTH_AT) ** 2 for p in SHEAR_SMOOTH_PERCENT]


def shear_caveat(beam, model: str) -> str | None:
    """A warning when the thin model ``model`` (``beam``, ``analytic``, ``plate``) is likely more
    than 1 % above a shear-deformable answer for this panel, None otherwise (and for ``mindlin``,
    which has the shear). The rule is the measurement above; the text says how much and what to
    use instead."""
    tl, neck, has_neck = _shear_inputs(beam)
    if model == "plate":
        if not (tl >= SHEAR_PLATE_THICKNESS
                or has_neck and (tl >= SHEAR_NECKED_THICKNESS or neck < SHEAR_PLATE_NECK)):
            return None
        remedy = ("(docs/howto/choose-a-truth.md); `prbdm fit --truth mindlin` and `prbdm truth --model "
                  "mindlin` include the shear")
        if not has_neck:
            est = _smooth_estimate(tl)
            return (f"the Kirchhoff plate leaves out transverse shear and rotary inertia: at t/L "
                    f"= {tl:.2g} its modes 1-4 are about {', '.join(f'{e:.2g}' for e in est)} % "
                    f"high (3-D elasticity on smooth panels, scaled by (t/L)^2) {remedy}")
        return (f"the Kirchhoff plate leaves out transverse shear: this panel is {tl:.2g} L "
                f"thick and its narrowest full width {neck:.2g} times the thickness; on "
                "measured panels like it the Kirchhoff frequencies were 1-6 % above the "
                f"shear-deformable (Reissner-Mindlin) plate's and 3-D elasticity's {remedy}")
    if model in ("beam", "analytic"):
        est = _smooth_estimate(tl)
        if est[-1] <= 1.0:
            return None
        return (f"Euler-Bernoulli leaves out shear and rotary inertia: at t/L = {tl:.2g} its "
                f"modes 1-4 are about {', '.join(f'{e:.2g}' for e in est)} % high (3-D "
                "elasticity on smooth panels, scaled by (t/L)^2; docs/howto/choose-a-truth.md)")
    return None


# ------------------------------------------------------------------ the beam's gap on this panel
def beam_gap(beam, modes: int = 4) -> tuple[str, list[float]] | None:
    """(model, gaps): this panel's truth by ``auto`` and the Euler-Bernoulli beam's relative
    frequency difference from it on modes 1..``modes`` (``omega_beam / omega_model - 1``), both
    solved here (milliseconds for the beam and the Kirchhoff plate, a fraction of a second for the
    Mindlin plate); None where ``auto`` takes the beam itself."""
    model, _ = choose_truth(beam, "auto")
    if model == "beam":
        return None
    from . import bending_frequencies

    other = bending_frequencies(beam, model=model, modes=modes).omega
    ours = bending_frequencies(beam, model="beam", modes=modes).omega
    r = min(len(other), len(ours), modes)
    return model, [float(ours[j] / other[j] - 1.0) for j in range(r)]


def beam_gap_warning(beam, remedy: str, modes: int = 4) -> str | None:
    """The one wording, in every command, for an answer that follows the beam on a panel whose
    truth (``auto``) is a plate: the panel's width and its measured gap, mode by mode. None where
    ``auto`` takes the beam, or where this panel's gap is within AUTO_TOLERANCE on every mode."""
    gap = beam_gap(beam, modes)
    if gap is None:
        return None
    model, gaps = gap
    label = "shear-deformable (mindlin) plate" if model == "mindlin" else "Kirchhoff plate"
    worst = max(abs(g) for g in gaps)
    if worst <= AUTO_TOLERANCE:         # the beam is as good as `auto` asks of it: nothing to say
        return None
    return (f"this panel is {width_ratio(beam):.3g} L wide: its truth (`--truth auto`) is the "
            f"{label}, and the Euler-Bernoulli beam used here differs from it by "
            f"{', '.join(f'{100 * g:+.2g}' for g in gaps)} % on modes 1-{len(gaps)} "
            f"(both solved for this panel; worst {100 * worst:.2g} %); {remedy}")


#: the beam's gap from the plate on the worst of modes 1-4, median and p95 [%], over the paper's
#: random panels of each full-width band (lo, hi] (``python benchmarks/truth_choice.py --panels 20
#: --json docs/truth-choice.json``, 157 panels): what a command that runs no FEM can say of a
#: panel's gap; a smooth panel's is smaller (a uniform strip 0.3 L wide: 2.6-5.7 % on modes 1-4)
BAND_GAPS = ((0.05, 0.1, 0.58, 4.0), (0.1, 0.2, 1.9, 10.5), (0.2, 0.4, 6.4, 20.8),
             (0.4, 0.7, 34.0, 74.0), (0.7, None, 101.0, 194.0))


def band_gap_words(beam) -> str:
    """The one wording, without a FEM, of how far the beam's physics is from the plate's for a
    panel this wide (:data:`BAND_GAPS`), and how to measure this panel's own gap."""
    b = width_ratio(beam)
    for lo, hi, median, p95 in BAND_GAPS:
        if b > lo and (hi is None or b <= hi):
            span = f"{lo:g}-{hi:g} L" if hi is not None else f"over {lo:g} L"
            return (f"on the paper's panels {span} wide the beam is a median {median:g} % (p95 "
                    f"{p95:g} %) off the plate on the worst of modes 1-4; `prbdm truth BEAM "
                    "--model beam` measures this panel's own gap")
    return ("`prbdm truth BEAM --model beam` measures how far the beam is from the plate for "
            "this panel")
