"""The surrogate: from a beam's planform straight to its PRBDM (gamma, k) and its truth frequencies.

A small network trained on a labelled data set (:mod:`prbdm.dataset`) replaces the truth solve and
the multistart fit: features of the planform in, the link fractions ``gamma``, one stiffness
correction factor ``k`` per pose and the beam's own truth frequencies out. See docs/surrogate.md.

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

from ..chain import (
    BeamBatch,
    link_table,
    loss_percent_np,
    prbdm_eigenvalues,
    span_integrals,
    uniform_gamma,
)
from .checkpoint import (
    CHECKPOINT_FORMAT,
    CHECKPOINT_VERSION,
    PACKAGE_CHECKPOINTS,
    available_checkpoints,
    checkpoint_name,
    dataset_hash,
    default_checkpoint,
    matching_training_set,
    read_checkpoint,
    save_checkpoint,
    training_sets,
    weights_sha256,
)
from .decode import (
    GAMMA_MAX,
    GAMMA_MIN,
    K_DELTA_SCALE,
    K_MODES,
    SELECT_POSES,
    candidate_losses,
    combine_members,
    decode_numpy,
    decode_torch,
    gamma_from_logits_np,
    gauss_select_poses,
    project_k,
)
from .features import (
    CHUNK,
    PROFILE_FLOOR,
    FeatureSpec,
    feature_names,
    features,
    rfe_log_omega,
)
from .neighbours import (
    LIMIT_QUANTILE,
    NEIGHBOURS_TENSOR,
    REFERENCE_COUNT,
    build_reference,
    nearest_distance,
)
from .prediction import (
    FREQ_FACTOR,
    K_RANGE,
    OOD_MARGIN,
    ImplausiblePredictionWarning,
    LowAccuracyWarning,
    OutOfDistributionWarning,
    Prediction,
    Surrogate,
    default_threads,
    load_checkpoint,
    physical_problems,
    predict,
)

__all__ = ["BeamBatch", "FeatureSpec", "features", "feature_names", "prbdm_eigenvalues",
           "link_table", "span_integrals", "loss_percent_np", "rfe_log_omega", "uniform_gamma",
           "Surrogate", "Prediction", "load_checkpoint", "predict", "physical_problems",
           "default_threads", "OutOfDistributionWarning", "ImplausiblePredictionWarning",
           "LowAccuracyWarning",
           "save_checkpoint", "read_checkpoint", "default_checkpoint", "available_checkpoints",
           "checkpoint_name", "dataset_hash", "training_sets", "matching_training_set",
           "weights_sha256", "CHECKPOINT_FORMAT", "CHECKPOINT_VERSION", "PACKAGE_CHECKPOINTS",
           "PROFILE_FLOOR", "GAMMA_MIN", "GAMMA_MAX", "K_MODES",
           "K_DELTA_SCALE", "SELECT_POSES", "gauss_select_poses", "gamma_from_logits_np",
           "decode_numpy", "decode_torch", "combine_members", "candidate_losses", "project_k",
           "CHUNK", "OOD_MARGIN", "K_RANGE", "FREQ_FACTOR", "NEIGHBOURS_TENSOR", "REFERENCE_COUNT",
           "LIMIT_QUANTILE", "build_reference", "nearest_distance"]
