"""The surrogate: from a beam's planform straight to its PRBDM (gamma, k) and its truth frequencies.

A small network trained on a labelled data set (:mod:`prbdm.dataset`) replaces the truth solve and
the multistart fit: features of the planform in, the link fractions ``gamma``, one stiffness
correction factor ``k`` per pose and the beam's own truth frequencies out. See docs/surrogate.md.

The public names are the few a user calls: :func:`load_checkpoint` (or
:func:`default_checkpoint` / :func:`available_checkpoints` to find one), :class:`Surrogate` and
its :meth:`~Surrogate.predict`, :func:`predict` for the shipped networks, the
:class:`Prediction` it returns, and the warnings a prediction may raise. The rest is imported
from its module.

Read in this order:

1. :mod:`prbdm.chain`: beams as arrays (:class:`BeamBatch`) and the NumPy PRBDM
   (:func:`prbdm_eigenvalues`, :func:`link_table`, :func:`uniform_gamma`), the one home of the
   chain's physics; :mod:`prbdm.model` is its torch twin for the fit (``.numpy_model`` is the
   old import path, kept).
2. :mod:`.features`: a fixed-size, invariant description of the planform (:func:`features`).
3. :mod:`.decode`: the network's raw head to valid outputs (gamma on the bounded simplex, k > 0,
   the truth frequencies as a correction of the equal-link chain's), NumPy and torch.
4. :mod:`.net`: the torch network for training (:class:`~prbdm.surrogate.net.SurrogateNet`,
   :class:`~prbdm.surrogate.net.SurrogateEnsemble`). Import it from there: it imports torch,
   and nothing else in this package does.
5. :mod:`.checkpoint`: one safetensors file with the weights and the JSON metadata, checked on
   load (:func:`save_checkpoint`, :func:`read_checkpoint`, :func:`default_checkpoint`).
6. :mod:`.neighbours`: the training panels a checkpoint keeps as a reference, and the nearest
   distance of an input to them (no training panel like it: out of range).
7. :mod:`.prediction`: a loaded checkpoint (:class:`Surrogate`, :func:`load_checkpoint`), batched
   prediction (:func:`predict`) and the checks that refuse an extrapolation the checkpoint cannot
   make and flag a prediction outside physical ranges.

Importing this package imports NumPy and safetensors only, so ``prbdm predict`` starts fast.
"""
from __future__ import annotations

from .checkpoint import available_checkpoints, default_checkpoint
from .prediction import (
    ImplausiblePredictionWarning,
    LowAccuracyWarning,
    OutOfDistributionWarning,
    Prediction,
    Surrogate,
    load_checkpoint,
    predict,
)

__all__ = ["load_checkpoint", "predict", "Surrogate", "Prediction", "default_checkpoint",
           "available_checkpoints", "OutOfDistributionWarning", "ImplausiblePredictionWarning",
           "LowAccuracyWarning"]
