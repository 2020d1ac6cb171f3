"""Which plate modes are bending modes.

Every symmetric mode ``phi`` of the half model gets two numbers (antisymmetric modes have exactly
zero of both, by symmetry):

``participation``
    the transverse mass participation of the paper, ``(phi^T M 1)^2 / (phi^T M phi * m)``: the
    fraction of the total mass ``m`` that moves with the mode under a uniform transverse
    acceleration (the effective-mass fraction; it sums to 1 over all modes).

``section_fraction``
    the same participation measured section by section: the fraction of the mode's modal mass
    carried by the transverse translation of its chord sections, ``|P phi|^2_M / |phi|^2_M``,
    where ``P phi (x)`` is the mass-weighted average of ``phi`` across the chord at ``x``. A
    beam-like (bending) mode moves each section almost rigidly (``section_fraction`` near 1); a
    chordwise-bending mode moves the middle of the chord against its edges (near 0). It is the
    sum of the mode's participations in every span-wise translation pattern ``g(x)``, the uniform
    one (the paper's participation) included.

Rules (``selection``):

``"section"`` (the section rule; the default is the spectrum, below)
    walk the symmetric modes upward; a mode is a bending mode when ``section_fraction >= 1/2``:
    more than half of its modal mass moves with its chord sections. The whole-body participation
    alone cannot tell chordwise modes from higher bending modes, because bending participation
    falls like ``4 / alpha_n^2`` (61 %, 19 %, 6.5 %, 3.3 %, 2.0 % for a uniform cantilever): on the
    square plate the first chordwise mode (lambda^0.5 = 27.2) has 1.5 % participation, more than
    the fifth bending mode (1.1 %). If fewer than the requested number of modes reach 1/2 among
    all the modes computed (planforms so jagged that their modes are mostly chordwise), the
    remaining ones are filled with the modes of highest section fraction, in ascending order.

``"participation"``
    the paper's rule: among the first ``max(2 R + 4, 12)`` symmetric modes, the ``R`` with the
    highest participation, listed in ascending frequency (the paper took them from its first 40
    modes of both families, i.e. about 20 symmetric ones).

``"spectrum"`` (default)
    the bending spectrum (:func:`bending_spectrum`): every symmetric mode counts as bending with
    the weight :func:`bending_weight` of its section fraction, and the j-th bending eigenvalue is
    the weighted geometric mean of the modes over the j-th unit of that weight. Where the modes
    are clean it is exactly the section rule's mode; where bending and chordwise modes mix it is
    continuous in the planform, where the section rule's pick jumps (docs/method.md).
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["section_fraction", "select_bending", "bending_weight", "bending_spectrum",
           "SECTION_THRESHOLD", "SELECTIONS"]

SECTION_THRESHOLD = 0.5
#: span-wise functions of the section projection: piecewise-linear hats on SECTION_HATS equal
#: spans of the length, whatever the mesh, so that a section fraction is one number that mesh
#: refinement converges to (hats tied to the mesh, 4 per element, moved s by 0.007 between the
#: default and a fine mesh on random_beam(0, 0) and a blended plate mode 5 by 0.8 %; with 64
#: fixed hats both meshes agree to 3e-4 in s and 0.09 % in the spectrum; hats much finer than
#: the elements fit the discretisation's own wiggles, ~16 per element moved s by 0.1)
SECTION_HATS = 64
#: ``spectrum`` (the default of plate and mindlin): the bending spectrum of ../SPEC §2.1, below;
#: ``section`` and ``participation``: physical modes picked by the rules above
SELECTIONS = ("spectrum", "section", "participation")
#: a mode counts as bending with weight clip((s - 1/2) / BENDING_RAMP + 1/2, 0, 1): fully from
#: s = 0.8, not at all below s = 0.2 (docs/conventions.md, "The bending spectrum")
BENDING_RAMP = 0.6


def bending_weight(fraction) -> np.ndarray:
    """How much of one unit of section motion each mode carries: ``clip((s - 1/2) / 0.6 + 1/2,
    0, 1)`` of its section fraction ``s``."""
    s = np.asarray(fraction, dtype=np.float64)
    return np.clip((s - SECTION_THRESHOLD) / BENDING_RAMP + 0.5, 0.0, 1.0)


def bending_spectrum(lam, fraction, modes: int):
    """The bending spectrum (docs/conventions.md): (lam_bend (R,), composition, length).

    The symmetric modes, ascending, are laid end to end on a line, mode ``i`` occupying its
    :func:`bending_weight` ``p_i``; bending eigenvalue ``j`` is the weighted geometric mean of the
    ``lam_i`` over the unit interval ``[j - 1, j]``, each weighted by the length of its piece
    there. ``composition[j]`` lists ``(i, w_ij)`` (0-based symmetric mode, weight) of the modes
    that make it; ``length`` is the line's length ``sum p_i``. The modes computed must make a
    line longer than ``modes`` (the caller checks ``length > modes``): otherwise the bending
    eigenvalues it cannot complete are NaN."""
    lam = np.asarray(lam, dtype=np.float64)
    p = bending_weight(fraction)
    ends = np.cumsum(p)
    starts = ends - p
    out = np.full(int(modes), np.nan)
    composition = []
    for j in range(int(modes)):
        w = np.clip(np.minimum(ends, j + 1.0) - np.maximum(starts, float(j)), 0.0, None)
        used = np.flatnonzero(w > 0)
        composition.append([(int(i), float(w[i])) for i in used])
        if w.sum() >= 1.0 - 1e-9:
            # one mode alone is itself, bit for bit (a beam's or a slender panel's modes)
            out[j] = (lam[used[0]] if len(used) == 1 else
                      math.exp(float(w[used] @ np.log(lam[used])) / float(w[used].sum())))
    return out, composition, float(ends[-1]) if len(ends) else 0.0


def section_fraction(s: np.ndarray, G_lu, modal_mass: np.ndarray) -> np.ndarray:
    """``|P phi|^2 / |phi|^2`` for each column of ``s = B phi`` (``B_ik = int hat_i(x) phi_k``):
    the projection onto span-wise functions has coefficients ``G^-1 s``, where ``G`` (given as
    its LU factorisation) is the Gram matrix of the hats."""
    s = np.asarray(s)
    c = G_lu.solve(s)
    return np.clip(np.einsum("ik,ik->k", s, c) / modal_mass, 0.0, 1.0)


def select_bending(participation, fraction, modes: int, selection: str = "section"):
    """Boolean mask of the kept modes (exactly ``modes`` of them when possible) and whether the
    search is complete (enough modes computed to decide)."""
    participation = np.asarray(participation)
    fraction = np.asarray(fraction)
    n = len(fraction)
    if selection == "spectrum":
        # the section rule's modes are reported beside the spectrum: complete when both are
        kept, complete = select_bending(participation, fraction, modes, "section")
        return kept, complete and float(bending_weight(fraction).sum()) > modes
    kept = np.zeros(n, dtype=bool)
    if selection == "participation":
        order = np.argsort(-participation, kind="stable")[:modes]
        kept[order] = True
        # complete when the computed band is wide enough to hold R modes and a margin
        return kept, n >= max(2 * modes + 4, 12)
    strong = np.flatnonzero(fraction >= SECTION_THRESHOLD)
    if len(strong) >= modes:
        kept[strong[:modes]] = True
        return kept, True
    # not enough clear bending modes among those computed: the caller computes more; when it
    # cannot, fill with the modes of highest section fraction
    kept[strong] = True
    rest = np.setdiff1d(np.arange(n), strong)
    fill = rest[np.argsort(-fraction[rest], kind="stable")[: modes - len(strong)]]
    kept[fill] = True
    return kept, False
