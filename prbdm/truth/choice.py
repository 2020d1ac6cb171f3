"""``--truth auto``: the Euler-Bernoulli beam for a slender strip, the Kirchhoff plate otherwise.

The rule is read off measured beam-vs-plate differences (``benchmarks/truth_choice.py``, table in
docs/truth.md, data in docs/truth-choice.json): 220 random planforms of the paper's generator
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
TRUTHS = ("beam", "plate")
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
                        "95 % of measured panels this narrow (docs/truth.md)")
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
                        "theory: solved as a beam (docs/truth.md)")
    return "plate", (f"auto: full width {b:.3g} L > {AUTO_BEAM_MAX_WIDTH:g} L: a beam model would "
                     f"differ from the plate by more than {AUTO_TOLERANCE:.0%} on 1 panel in 20 "
                     "or more this wide (docs/truth.md)")
