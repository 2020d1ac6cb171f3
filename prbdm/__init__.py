"""prbdm: Pseudo-Rigid Body Dynamic Models of flexible cantilever panels.

The entry points a user calls: a panel (:class:`Beam`, :func:`load_beam`, :func:`random_beam`
here), its truth (:func:`prbdm.truth.bending_frequencies`), a PRBDM fitted to it
(:func:`prbdm.fit.fit_prbdm`) or predicted by a network (:func:`prbdm.surrogate.predict`), and
the PRBDM in a simulator (:func:`prbdm.export.export`, :func:`prbdm.simulate.simulate`).

Modules, read in this order:
geometry (the beam), chain (the PRBDM in NumPy), sections and model (the differentiable PRBDM,
torch), truth (scikit-fem bending frequencies), fit (multistart optimisation), surrogate (the
network), export and simulate (the PRBDM in a simulator), cli (the command line).

Importing ``prbdm`` imports neither torch nor scikit-fem: each command pulls in only what it needs.
"""
from .errors import BadInput
from .geometry import STEEL, Beam, Material, load_beam, random_beam

__version__ = "0.1.0"
__all__ = ["BadInput", "Beam", "Material", "STEEL", "load_beam", "random_beam", "__version__"]
