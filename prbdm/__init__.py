"""prbdm: Pseudo-Rigid Body Dynamic Models of flexible cantilever panels.

Modules, read in this order:
geometry (the beam), sections (exact span integrals, torch), model (the differentiable PRBDM),
truth (scikit-fem bending frequencies), fit (multistart optimisation), cli (the command line).

Importing ``prbdm`` imports neither torch nor scikit-fem: each command pulls in only what it needs.
"""
from .errors import BadInput
from .geometry import STEEL, Beam, Material, load_beam, random_beam

__version__ = "0.1.0"
__all__ = ["BadInput", "Beam", "Material", "STEEL", "load_beam", "random_beam", "__version__"]
