"""Moved: the NumPy PRBDM chain lives in :mod:`prbdm.chain` (one home for the chain's physics);
this module keeps the old import path working."""
from __future__ import annotations

from ..chain import (  # noqa: F401  (re-exported)
    BeamBatch,
    link_table,
    links_from_gamma,
    loss_percent_np,
    mass_matrix,
    prbdm_eigenvalues,
    span_integrals,
    straight_generators,
    straight_mass_matrix,
    straight_projected_mass,
    uniform_gamma,
)
