"""Prediction: a loaded checkpoint (:class:`Surrogate`, the MLP in NumPy), its result
(:class:`Prediction`), and the checks that make a result right or loud.

- Inputs outside the feature ranges seen in training get an :class:`OutOfDistributionWarning`
  naming the feature. A feature that did not vary in training at all (e.g. a plate network
  trained on nu = 0.28 only) cannot be extrapolated: another value is refused
  (:class:`BadInput`) unless ``allow_extrapolation``.
- A checkpoint that carries its training panels' reference (:mod:`.neighbours`) also checks the
  combination: an input further from every training panel than the held-out panels go
  (``neighbours.limit``) gets an :class:`OutOfDistributionWarning` saying no training panel is
  like it, whatever each feature's range says (``Prediction.unlike``, ``neighbour_distance``).
- Every prediction is checked against physical ranges (:func:`physical_problems`): finite, gamma
  in (0, 1], k in :data:`K_RANGE`, frequencies ascending and within :data:`FREQ_FACTOR` of the
  equal-link chain's (the ``log_omega_rfe`` or, for a ``spread`` network, ``log_omega_spread``
  features: :meth:`FeatureSpec.base_columns`). A prediction that fails is flagged in
  ``Prediction.implausible``, explained in ``Prediction.problems`` and warned about
  (:class:`ImplausiblePredictionWarning`); ``prbdm predict`` makes it an error.
"""
from __future__ import annotations

import copy
import math
import os
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..chain import BeamBatch, prbdm_eigenvalues
from ..constants import (
    ACCURACY_WARN_FREQ_PERCENT,
    ACCURACY_WARN_LOSS_PERCENT,
    SELF_CHECK_IMPLAUSIBLE,
)
from ..errors import BadInput
from .checkpoint import (
    check_checkpoint,
    default_checkpoint,
    member_prefixes,
    pose_target,
    read_checkpoint,
    width_band_index,
)
from .decode import SELECT_POSES, combine_members, concatenate_outputs, decode_numpy, silu
from .features import CHUNK, FeatureSpec, features
from .neighbours import NEIGHBOURS_TENSOR, nearest_distance

#: fraction of a feature's training range by which an input may exceed it before a warning
OOD_MARGIN = 0.05
#: a feature whose training range is narrower than this (relative to its size) did not vary in
#: training: the network has no information on its effect, so other values are refused
FIXED_FEATURE_TOL = 1e-9
#: beams per piece (at most) in Surrogate.predict; the pieces are spread over threads
PIECE = 1024
#: physical range of a stiffness correction factor: a PRBDM's k is of order 1 (fits on the
#: shipped data sets stay within about [0.5, 2]); far outside, the numbers are the network's
#: failure, not a beam's property
K_RANGE = (1e-6, 1e6)
#: largest factor between a predicted frequency and the equal-link chain's estimate of it (the
#: log_omega_rfe / log_omega_spread features, a rigid-finite-element model of the same beam): the truth and a PRBDM
#: of the beam are within a few tens of percent of it, so a factor of 10 is a broken prediction
FREQ_FACTOR = 10.0


class OutOfDistributionWarning(UserWarning):
    """An input lies outside the range of a feature seen in training, or is unlike every
    training panel (:mod:`.neighbours`)."""


class ImplausiblePredictionWarning(UserWarning):
    """A prediction is non-finite or outside physical ranges (see Prediction.problems)."""


class LowAccuracyWarning(UserWarning):
    """The checkpoint's own held-out test is worse than prbdm.constants.ACCURACY_WARN_*: its
    answers are rough estimates (Surrogate.accuracy_warning says how rough)."""


def default_threads() -> int:
    """Threads for batched prediction: ``$PRBDM_THREADS`` if set, else the usable cores."""
    env = os.environ.get("PRBDM_THREADS")
    if env:
        try:
            return max(1, int(env))
        except ValueError:
            raise BadInput(f"PRBDM_THREADS: must be an integer >= 1, got {env!r}") from None
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:          # not on Linux
        return os.cpu_count() or 1


@dataclass
class Prediction:
    """What :meth:`Surrogate.predict` returns for B beams.

    gamma (B, n+1); k (B, m); log_omega_hat (B, R): the network's direct prediction of the truth
    frequencies in nondimensional form, log(omega / sqrt(E t^2 / (rho L^4))); with beams:
    omega_truth (B, R) [rad/s] (the same, in SI) and, when asked, omega (B, m, n) [rad/s], the
    PRBDM's own frequencies per pose; poses (m, n) [rad]; law; ood: (B, F) bool, True where a
    feature lies outside its training range (with the margin); warnings: one text per beam and
    offending feature (at most 20 listed); time_s: wall time of the prediction; extra:
    ``gamma_candidates`` (B, H, n+1), ``selected`` (B,) and ``candidate_loss`` (B, H) (each
    candidate's docs/conventions.md §3 loss [%] against the predicted truth frequencies, on the choice poses)
    for a network with H > 1 candidates; see :meth:`ranked_candidates`; implausible (B,) bool and
    problems (one text per such beam): predictions that fail :func:`physical_problems`;
    neighbour_distance (B,): the distance of each input's normalised features to the nearest
    training panel the checkpoint keeps (None when it keeps none) and unlike (B,) bool: beyond
    its ``neighbours.limit`` (a text in ``warnings`` where no feature is out of its range).

    From features alone (no geometry) only log_omega_hat is complete: k (``projection`` mode)
    and the choice among several candidate gammas need the beam's PRBDM, so they are None (with
    one candidate, gamma is given).
    """

    gamma: np.ndarray | None
    k: np.ndarray | None
    log_omega_hat: np.ndarray
    poses: np.ndarray
    law: str
    ood: np.ndarray
    warnings: list
    omega_truth: np.ndarray | None = None
    omega: np.ndarray | None = None
    time_s: float = 0.0
    extra: dict = field(default_factory=dict)
    implausible: np.ndarray | None = None
    problems: list = field(default_factory=list)
    neighbour_distance: np.ndarray | None = None
    unlike: np.ndarray | None = None

    def ranked_candidates(self, count: int | None = None) -> np.ndarray:
        """The candidate segmentations (B, count, n+1), best first by their loss against the
        predicted truth frequencies (the kept ``gamma`` is first): start points for a short
        refinement (:func:`prbdm.fit.refine_starts`). One candidate: ``gamma`` (B, 1, n+1)."""
        cand, loss = self.extra.get("gamma_candidates"), self.extra.get("candidate_loss")
        if cand is None or loss is None:
            return self.gamma[:, None, :]
        order = np.argsort(loss, axis=1, kind="stable")[:, :count]
        return np.take_along_axis(cand, order[..., None], axis=1)


class Surrogate:
    """A loaded checkpoint: NumPy weights, metadata, and :meth:`predict`."""

    def __init__(self, tensors: dict, metadata: dict, path: Path | None = None):
        """From checked weights and metadata (:func:`load_checkpoint` reads them from a file);
        :func:`prbdm.surrogate.checkpoint.check_checkpoint` is run again here, so that a
        Surrogate built in memory is checked too."""
        self.metadata = metadata
        self.path = path
        where = f"checkpoint {str(path)!r}" if path else "checkpoint"
        try:
            check_checkpoint(tensors, metadata)
        except BadInput as exc:
            raise BadInput(f"{where}: {exc}") from None
        try:
            self.joints = int(metadata["joints"])
            self.truth = str(metadata["truth"])
            self.law = str(metadata["law"])
            # checkpoints made before the frequency objective were trained on the paper's loss
            self.objective = str(metadata.get("objective", "eigenvalue"))
            self.poses = np.asarray(metadata["poses"], dtype=np.float64)
            #: what the network's chain matches away from rest (prbdm.pose_target): "shape" for a
            #: network trained at rest (its stiffness is held at every pose), "straight" for one
            #: trained on the paper's poses (one SCF per pose)
            self.pose_target = pose_target(metadata)
            self.modes = int(metadata["modes"])
            self.feature_spec = FeatureSpec(**metadata["features"]["spec"])
            self.norm = {k: np.asarray(v, dtype=np.float64)
                         for k, v in metadata["normalisation"].items()}
            self.f_mean, self.f_std = self.norm["feature_mean"], self.norm["feature_std"]
            self.k_mode = str(metadata["network"].get("k_mode", "direct"))
            net = metadata["network"]
            self.member_hypotheses = int(net.get("hypotheses", 1))
            self.n_members = int(net.get("members", 1))
            self.hypotheses = self.member_hypotheses * self.n_members   # candidates in all
            self.select_poses = [int(i) for i in net.get("select_poses", SELECT_POSES)]
            #: how a candidate is chosen: "plausible" (the least loss among the candidates with
            #: every mode within SELF_CHECK_IMPLAUSIBLE of the predicted truth; what answers) or
            #: "loss" (the least loss: the rule the shipped checkpoints' held-out tests were
            #: measured with, their ``network.candidate_rule`` when absent; training/retest.py
            #: measures with the checkpoint's own)
            self.candidate_rule = "plausible"
            self.f_min = np.asarray(metadata["features"]["min"], dtype=np.float64)
            self.f_max = np.asarray(metadata["features"]["max"], dtype=np.float64)
            self.names = list(metadata["features"]["names"])
            self.members = []
            for pre in member_prefixes(self.n_members):
                n_layers = len([k for k in tensors
                                if k.startswith(pre + "layers.") and k.endswith(".weight")])
                self.members.append(
                    [(np.ascontiguousarray(tensors[f"{pre}layers.{i}.weight"], np.float32),
                      np.ascontiguousarray(tensors[f"{pre}layers.{i}.bias"], np.float32))
                     for i in range(n_layers)])
            self.layers = self.members[0]
        except (KeyError, TypeError, ValueError) as exc:
            raise BadInput(f"{where}: incomplete surrogate metadata or weights "
                           f"({type(exc).__name__}: {exc})") from None
        if self.law != "beam":
            raise BadInput(f"{where}: law {self.law!r} is not supported by the NumPy PRBDM "
                           "(only 'beam')")
        #: the training panels' reference (normalised features, float64) and its record
        self.neighbours = metadata.get("neighbours")
        ref = tensors.get(NEIGHBOURS_TENSOR)
        self.reference = None if ref is None else np.asarray(ref, dtype=np.float64)
        self.reference_sq = None if ref is None else (self.reference ** 2).sum(1)
        span = self.f_max - self.f_min
        #: features that did not vary in training (see FIXED_FEATURE_TOL)
        self.fixed = span <= FIXED_FEATURE_TOL * np.maximum(1.0, np.abs(self.f_max))

    @property
    def name(self) -> str:
        return self.path.name if self.path else "<in memory>"

    def describe(self) -> dict:
        """A short summary for command output: path, name, truth, joints, data set size, and the
        accuracy its own held-out test measured (:meth:`held_out_accuracy`)."""
        ds = self.metadata.get("dataset", {})
        return {"path": str(self.path) if self.path else None, "name": self.name,
                "truth": self.truth, "joints": self.joints, "modes": self.modes, "law": self.law,
                "objective": self.objective,
                "dataset_size": ds.get("size"), "dataset_sha256": ds.get("sha256"),
                "training_mode": self.metadata.get("training", {}).get("selected_mode"),
                "held_out_accuracy": self.held_out_accuracy()}

    def held_out_accuracy(self, width_ratio: float | None = None) -> dict | None:
        """What the training script measured on the checkpoint's test split (beams it never saw):
        the PRBDM's paper loss median and p95 [%], and the median error of each predicted truth
        frequency [%] (the first ``modes``); None when the metadata has no test.

        ``width_ratio`` (a panel's full width over its length): the numbers of the test panels in
        that panel's width band (``test.by_width``, prbdm.constants.ACCURACY_WIDTH_EDGES) when the
        checkpoint recorded that band, ``full_width`` [lo, hi] (hi None: open); else the whole
        test's, ``full_width`` None."""
        test = self.metadata.get("test") or {}
        if test.get("loss_median") is None or not test.get("freq_err_median"):
            return None
        part, band = test, None
        if width_ratio is not None:
            bands = test.get("by_width") or []
            j = int(width_band_index(bands, width_ratio)[0])
            if j >= 0:
                part, band = bands[j], list(bands[j]["full_width"])
        measured = int(self.metadata.get("network", {}).get("members", 1))
        return {"beams": part.get("beams"), "loss_median_percent": float(part["loss_median"]),
                "loss_p95_percent": (None if part.get("loss_p95") is None
                                     else float(part["loss_p95"])),
                "truth_frequency_error_median_percent":
                    [100 * float(e) for e in part["freq_err_median"][:self.modes]],
                "full_width": band,
                # the test ran the whole ensemble; with_members(k) answers with fewer, less
                # accurately than these numbers, and says so
                "members_measured": measured, "members_used": self.n_members}

    def _band_representatives(self, width_ratios) -> list:
        """One full width (over length) of ``width_ratios`` per recorded width band they reach,
        and one for those in none: at most a few :meth:`accuracy_warning` calls for any batch."""
        r = np.asarray(width_ratios, dtype=np.float64)
        index = width_band_index((self.metadata.get("test") or {}).get("by_width") or [], r)
        _, first = np.unique(index, return_index=True)
        return [float(r[i]) for i in first]

    def _excess(self, width_ratio) -> float:
        """How far the held-out test at this width is past the accuracy limits, as a multiple of
        the limit it exceeds most: the roughest band of a batch is the one with the largest."""
        acc = self.held_out_accuracy(width_ratio)
        return max(acc["loss_median_percent"] / ACCURACY_WARN_LOSS_PERCENT,
                   max(acc["truth_frequency_error_median_percent"]) / ACCURACY_WARN_FREQ_PERCENT)

    def accuracy_warning(self, width_ratio: float | None = None) -> str | None:
        """A sentence for every answer of a checkpoint whose held-out test is worse than
        prbdm.constants.ACCURACY_WARN_LOSS_PERCENT / ACCURACY_WARN_FREQ_PERCENT, else None: a
        network that is known to be rough must not answer as if it were not. With
        ``width_ratio``, judged by the test panels of that width (:meth:`held_out_accuracy`)."""
        acc = self.held_out_accuracy(width_ratio)
        if acc is None:
            return None
        worst = max(acc["truth_frequency_error_median_percent"])
        if (acc["loss_median_percent"] <= ACCURACY_WARN_LOSS_PERCENT
                and worst <= ACCURACY_WARN_FREQ_PERCENT):
            return None
        modes = ", ".join(f"{e:.2g}" for e in acc["truth_frequency_error_median_percent"])
        where = ""
        if acc["full_width"] is not None:
            lo, hi = acc["full_width"]
            where = (f" {lo:g}-{hi:g} L wide" if hi is not None else f" wider than {lo:g} L")
        fewer = ""
        if acc["members_used"] < acc["members_measured"]:
            fewer = (f"; measured with all {acc['members_measured']} ensemble members, this "
                     f"answer used {acc['members_used']}, which is less accurate")
        return (f"checkpoint {self.name} is a rough estimate: on {acc['beams']} held-out "
                f"{self.truth} panels{where} its PRBDM loss was a median "
                f"{acc['loss_median_percent']:.3g} % "
                + (f"(p95 {acc['loss_p95_percent']:.3g} %) " if acc["loss_p95_percent"] is not None
                   else "")
                + "and its truth frequencies a median "
                f"[{modes}] % off (modes 1-{self.modes}{fewer}; limits "
                f"{ACCURACY_WARN_LOSS_PERCENT:g} % / {ACCURACY_WARN_FREQ_PERCENT:g} %); "
                f"for a faithful model use `prbdm fit BEAM --joints {self.joints}` (its "
                f"`--truth auto` takes the truth the panel needs; `--truth {self.truth}` is "
                "this network's)")

    # ---------------------------------------------------------------- the network in NumPy
    def features(self, beams) -> np.ndarray:
        batch = beams if isinstance(beams, BeamBatch) else BeamBatch.from_beams(beams)
        return features(batch, self.feature_spec)

    def with_members(self, count: int) -> "Surrogate":
        """The same checkpoint using only its first ``count`` ensemble members: fewer candidates
        to compare, faster, less accurate (docs/surrogate.md §5 measures both). Its
        :meth:`held_out_accuracy` is still the whole ensemble's test, with ``members_used`` below
        ``members_measured``, and its :meth:`accuracy_warning`, where the ensemble's test is past
        the limits, says so (where it is not, the fewer members give no warning)."""
        if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or \
                not 1 <= count <= self.n_members:
            raise BadInput(f"members: must be an integer in [1, {self.n_members}], got {count!r}")
        other = copy.copy(self)
        other.members = self.members[:count]
        other.n_members = int(count)
        other.hypotheses = self.member_hypotheses * other.n_members
        return other

    def forward(self, feats: np.ndarray, batch: "BeamBatch | None" = None) -> dict:
        """The decoded outputs (see :func:`.decode.decode_numpy`: gamma, logk, log_omega_hat,
        mu, ...) from raw features (B, F). In ``projection`` k mode, k needs the beams (``batch``);
        without them logk and mu are None (and, with several candidates, gamma is the first)."""
        # the MLP in float32 (its weights are float32): twice as fast as float64, and its
        # round-off (1e-7) is far below the network's own error
        if feats.shape[0] > CHUNK:  # see features(): bounded pieces
            parts = [self.forward(feats[i:i + CHUNK],
                                  None if batch is None else batch.take(slice(i, i + CHUNK)))
                     for i in range(0, feats.shape[0], CHUNK)]
            return concatenate_outputs(parts)
        f = ((feats - self.f_mean) / self.f_std).astype(np.float32)
        outs = []
        for layers in self.members:
            h = f
            for W, b in layers[:-1]:
                h = silu(h @ W.T + b)
            W, b = layers[-1]
            outs.append((h @ W.T + b).astype(np.float64))
        out = combine_members(outs, self.member_hypotheses, self.joints)
        rfe = feats[:, self.feature_spec.base_columns(len(self.norm["freq_mean"]))]
        x, w = (batch.x, batch.w) if batch is not None else (None, None)
        return decode_numpy(out, self.norm, self.joints, self.k_mode, rfe, x, w, self.poses,
                            self.modes, self.hypotheses, self.select_poses,
                            plausible=self.candidate_rule == "plausible")

    def check_range(self, feats: np.ndarray):
        """(B, F) bool out-of-range mask and the warning texts (at most ``20``)."""
        span = self.f_max - self.f_min
        # a feature fixed in training allows only round-off; the others a margin of their range
        slack = np.where(self.fixed, FIXED_FEATURE_TOL * np.maximum(1.0, np.abs(self.f_max)),
                         OOD_MARGIN * span)
        lo, hi = self.f_min - slack, self.f_max + slack
        bad = (feats < lo) | (feats > hi) | ~np.isfinite(feats)
        texts = []
        # a feature fixed in training first: extrapolating it is the larger leap
        pairs = sorted(zip(*np.nonzero(bad)), key=lambda ij: (not self.fixed[ij[1]], ij))
        for i, j in pairs:
            if len(texts) == 20:
                texts.append(f"... {int(bad.sum()) - 20} more out-of-range feature values")
                break
            prefix = f"beam {i}: " if feats.shape[0] > 1 else ""
            texts.append(f"{prefix}feature {self.names[j]} = {feats[i, j]:.4g} lies outside the "
                         f"training range [{self.f_min[j]:.4g}, {self.f_max[j]:.4g}] of checkpoint "
                         f"{self.name}; the prediction is an extrapolation")
        return bad, texts

    def check_neighbours(self, feats: np.ndarray, bad: np.ndarray):
        """(distance (B,), unlike (B,) bool, texts) of the inputs against the training panels'
        reference (:mod:`.neighbours`); (None, None, []) for a checkpoint without one. A text
        (at most 20) for each unlike input none of whose features is out of its range (those
        already say that they extrapolate)."""
        if self.reference is None:
            return None, None, []
        dist = nearest_distance((feats - self.f_mean) / self.f_std, self.reference,
                                self.reference_sq)
        limit = float(self.neighbours["limit"])
        with np.errstate(invalid="ignore"):
            unlike = ~(dist <= limit)
        texts = []
        only = np.flatnonzero(unlike & ~bad.any(1))
        for i in only[:20]:
            prefix = f"beam {i}: " if feats.shape[0] > 1 else ""
            texts.append(f"{prefix}no training panel of checkpoint {self.name} is like this one "
                         f"(nearest distance {dist[i]:.3g}, held-out p99 "
                         f"{float(self.neighbours['held_out']['p99']):.3g}, limit {limit:.3g}, "
                         "in normalised features): each feature lies in its training range but "
                         "not their combination; the prediction is an extrapolation")
        if len(only) > 20:
            texts.append(f"... {len(only) - 20} more inputs unlike every training panel")
        return dist, unlike, texts

    def refuse_extrapolation(self, feats: np.ndarray, bad: np.ndarray) -> None:
        """BadInput naming the first feature that was fixed in training (one value only) and
        has another value here: the network has never seen that feature vary, so its prediction
        there is a guess, not an extrapolation."""
        hit = bad & self.fixed[None, :]
        if not hit.any():
            return
        i, j = (int(v) for v in np.argwhere(hit)[0])
        prefix = f"beam {i}: " if feats.shape[0] > 1 else ""
        raise BadInput(f"{prefix}feature {self.names[j]} = {feats[i, j]:.6g} is outside the "
                       f"trained range [{self.f_min[j]:.6g}, {self.f_max[j]:.6g}] of checkpoint "
                       f"{self.name}, which saw a single value of it and cannot extrapolate; "
                       "--allow-extrapolation (allow_extrapolation=True) forces a prediction")

    def ood_summary(self, bad: np.ndarray, texts: list) -> str:
        """One line for a batch: the offending features by name, and the first case in full."""
        if len(texts) == 1:
            return texts[0]
        cols = np.flatnonzero(bad.any(0))
        names = ", ".join(self.names[j] for j in cols[:12]) + (", ..." if len(cols) > 12 else "")
        return (f"{int(bad.any(1).sum())} of {bad.shape[0]} input(s) outside the training range "
                f"of checkpoint {self.name} in feature(s) {names}; first: {texts[0]}")

    def _features_and_outputs(self, batch: BeamBatch, threads: int | None):
        """features and decoded outputs of a batch of beams, in pieces of at most ``PIECE``
        beams spread over ``threads`` threads (NumPy releases the GIL in its array loops and
        LAPACK calls, so the pieces run side by side on a multi-core machine)."""
        B = len(batch)
        threads = default_threads() if threads is None else max(1, int(threads))
        # the pieces do not depend on the thread count, so neither do the results (the float32
        # MLP's round-off depends on the shape of its matrix products)
        pieces = max(-(-B // PIECE), 1)
        if pieces == 1:
            feats = features(batch, self.feature_spec)
            return feats, self.forward(feats, batch)
        size = -(-B // pieces)
        slices = [slice(i, min(i + size, B)) for i in range(0, B, size)]

        def work(sl):
            part = batch.take(sl)
            f = features(part, self.feature_spec)
            return f, self.forward(f, part)

        if threads > 1:
            from concurrent.futures import ThreadPoolExecutor

            with ThreadPoolExecutor(min(threads, len(slices))) as pool:
                done = list(pool.map(work, slices))
        else:
            done = [work(sl) for sl in slices]
        return (np.concatenate([f for f, _ in done]),
                concatenate_outputs([d for _, d in done]))

    def predict(self, beams_or_features, frequencies: bool = True, warn: bool = True,
                threads: int | None = None, allow_extrapolation: bool = False) -> Prediction:
        """Predict for Beam(s), a :class:`BeamBatch`, or a (B, F) feature array.

        With beams: also the truth frequencies in rad/s and, if ``frequencies``, the PRBDM's
        frequencies per pose (B, m, n). Out-of-range features raise one
        :class:`OutOfDistributionWarning` (if ``warn``) and are flagged in ``ood``. Large
        batches run in pieces on ``threads`` threads (default: the usable cores, or
        ``$PRBDM_THREADS``); the result does not depend on the thread count.

        A feature that did not vary in training with another value here is refused (BadInput)
        unless ``allow_extrapolation``. Predictions that fail :func:`physical_problems` are
        flagged in ``implausible`` and ``problems`` and raise one
        :class:`ImplausiblePredictionWarning` (if ``warn``). A checkpoint whose own held-out test
        is poor (:meth:`accuracy_warning`) raises one :class:`LowAccuracyWarning` (if ``warn``)."""
        t0 = time.perf_counter()
        batch = None
        if isinstance(beams_or_features, np.ndarray):
            feats = np.asarray(beams_or_features, dtype=np.float64)
            if feats.ndim == 1:
                feats = feats[None]
            if feats.ndim != 2 or feats.shape[1] != len(self.names):
                raise BadInput(f"features: need shape (B, {len(self.names)}), got "
                               f"{feats.shape}")
        else:
            batch = (beams_or_features if isinstance(beams_or_features, BeamBatch)
                     else BeamBatch.from_beams(beams_or_features))
        # overflow in a broken prediction is reported by physical_problems, in words
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            if batch is None:
                bad, texts = self.check_range(feats)
                if not allow_extrapolation:
                    self.refuse_extrapolation(feats, bad)
                d = self.forward(feats, None)
            else:
                feats, d = self._features_and_outputs(batch, threads)
                bad, texts = self.check_range(feats)
                if not allow_extrapolation:
                    self.refuse_extrapolation(feats, bad)
            dist, unlike, far = self.check_neighbours(feats, bad)
            pred = self._assemble(d, feats, batch, bad, texts + far, frequencies)
            pred.neighbour_distance, pred.unlike = dist, unlike
        if warn and texts:
            warnings.warn(OutOfDistributionWarning(self.ood_summary(bad, texts)), stacklevel=2)
        if warn and far:
            more = f" (and {len(far) - 1} more)" if len(far) > 1 else ""
            warnings.warn(OutOfDistributionWarning(far[0] + more), stacklevel=2)
        if warn and pred.problems:
            more = f" (and {len(pred.problems) - 1} more)" if len(pred.problems) > 1 else ""
            warnings.warn(ImplausiblePredictionWarning(pred.problems[0] + more), stacklevel=2)
        rough = None
        if warn:
            # judged per width band where the checkpoint has bands: the roughest band any of
            # these panels lies in speaks for the batch
            widths = [None] if batch is None else self._band_representatives(2 * batch.w.max(1))
            found = [(self._excess(r), text) for r in widths if (text := self.accuracy_warning(r))]
            rough = max(found)[1] if found else None
        if rough:
            warnings.warn(LowAccuracyWarning(rough), stacklevel=2)
        pred.time_s = time.perf_counter() - t0
        return pred

    def _assemble(self, d, feats, batch, bad, texts, frequencies) -> Prediction:
        gamma, logk, low, mu = d["gamma"], d["logk"], d["log_omega_hat"], d["mu"]
        pred = Prediction(gamma=gamma, k=None if logk is None else np.exp(logk),
                          log_omega_hat=low, poses=self.poses, law=self.law, ood=bad,
                          warnings=texts)
        if self.hypotheses > 1:
            pred.extra["gamma_candidates"] = d["gamma_all"]
            if batch is None:       # choosing a candidate needs the PRBDM, i.e. the geometry
                pred.gamma = None
            else:
                pred.extra["selected"] = d["select"]
                pred.extra["candidate_loss"] = d["candidate_loss"]
        if batch is not None:
            sq = np.sqrt(batch.lambda0)[:, None]
            pred.omega_truth = np.exp(low) * sq
            if frequencies:
                if mu is None:
                    mu = prbdm_eigenvalues(batch.x, batch.w, gamma, self.poses)
                pred.omega = np.sqrt(mu * pred.k[:, :, None]) * sq[:, :, None]
        rfe = feats[:, self.feature_spec.base_columns(len(self.norm["freq_mean"]))]
        pred.implausible, pred.problems = physical_problems(pred, rfe, batch)
        return pred


def physical_problems(pred: Prediction, rfe: np.ndarray, batch: BeamBatch | None = None):
    """(B,) bool and one text per implausible prediction (at most 20): non-finite values, gamma
    outside (0, 1], k outside :data:`K_RANGE`, predicted truth frequencies not ascending, or any
    frequency (the truth's prediction, and the PRBDM's per pose for the modes the features
    estimate) more than :data:`FREQ_FACTOR` from the equal-link chain's estimate ``rfe``
    (B, R) = the base features (``FeatureSpec.base_columns``: log_omega_rfe or log_omega_spread;
    nondimensional). Vectorised: it runs on every batch."""
    B, R = pred.log_omega_hat.shape
    limit = math.log(FREQ_FACTOR)
    checks = []             # (B,) mask and the text for a beam it flags, in the order reported
    if pred.gamma is not None:
        g = pred.gamma
        checks.append((~np.all(np.isfinite(g) & (g > 0) & (g <= 1), axis=-1),
                       lambda i: f"gamma = {_vec(pred.gamma[i])} is not in (0, 1]"))
    if pred.k is not None:
        k = pred.k
        checks.append((~np.all(np.isfinite(k) & (k >= K_RANGE[0]) & (k <= K_RANGE[1]), axis=-1),
                       lambda i: f"k = {_vec(pred.k[i])} is not in [{K_RANGE[0]:g}, "
                                 f"{K_RANGE[1]:g}]"))
    dev = pred.log_omega_hat - rfe[:, :R]
    checks.append((~np.all(np.isfinite(dev) & (np.abs(dev) <= limit), axis=-1),
                   lambda i: f"truth frequencies {_vec(np.exp(dev[i]))} times the equal-link "
                             f"chain's estimate (allowed 1/{FREQ_FACTOR:g} to {FREQ_FACTOR:g})"))
    checks.append((np.any(np.diff(pred.log_omega_hat, axis=-1) < 0, axis=-1),
                   lambda i: "the predicted truth frequencies are not ascending"))
    if pred.omega is not None and batch is not None:
        nd = pred.omega / np.sqrt(batch.lambda0)[:, None, None]         # (B, m, n) nondim.
        r = min(nd.shape[-1], R)
        dp = np.log(nd[..., :r]) - rfe[:, None, :r]
        checks.append((~(np.all(np.isfinite(nd), axis=(1, 2))
                         & np.all(np.isfinite(dp) & (np.abs(dp) <= limit), axis=(1, 2))),
                       lambda i: _worst_pose_mode(dp[i])))
    if pred.omega is not None and pred.omega_truth is not None:
        # every answer checks itself: the PRBDM against the truth the same network predicted
        # (prbdm.constants.SELF_CHECK_IMPLAUSIBLE; predict warns from SELF_CHECK_TOLERANCE on)
        r = min(pred.omega.shape[-1], pred.omega_truth.shape[-1])
        rel = pred.omega[..., :r] / pred.omega_truth[:, None, :r] - 1.0    # (B, m, r)
        off = ~(np.abs(rel) <= SELF_CHECK_IMPLAUSIBLE)
        checks.append((np.any(off, axis=(1, 2)), lambda i: _self_check_text(rel[i])))
    bad = np.zeros(B, dtype=bool)
    for mask, _ in checks:
        bad |= mask
    texts = []
    for i in np.flatnonzero(bad)[:20]:
        why = next(text(i) for mask, text in checks if mask[i])
        texts.append((f"beam {i}: " if B > 1 else "") + "implausible prediction: " + why)
    return bad, texts


def _worst_pose_mode(dev) -> str:
    """Words for the worst of one beam's (m, r) log deviations of the PRBDM's frequencies."""
    dev = np.where(np.isfinite(dev), dev, np.inf)
    pose, mode = np.unravel_index(int(np.argmax(np.abs(dev))), dev.shape)
    v = dev[pose, mode]
    ratio = f"{np.exp(v):.3g} times" if np.isfinite(v) else "not a finite multiple of"
    return (f"the PRBDM's mode {mode + 1} frequency at pose {pose} is {ratio} the equal-link "
            f"chain's estimate (allowed 1/{FREQ_FACTOR:g} to {FREQ_FACTOR:g})")


def _self_check_text(rel) -> str:
    """Words for the worst of one beam's (m, r) relative errors of the PRBDM against its own
    predicted truth."""
    rel = np.where(np.isfinite(rel), rel, np.inf)
    pose, mode = np.unravel_index(int(np.argmax(np.abs(rel))), rel.shape)
    v = rel[pose, mode]
    size = (f"{100 * abs(v):.3g} % {'above' if v > 0 else 'below'}" if np.isfinite(v)
            else "not a finite multiple of")
    return (f"the PRBDM's mode {mode + 1} frequency at pose {pose} is {size} the truth the same "
            f"network predicted (allowed {100 * SELF_CHECK_IMPLAUSIBLE:g} %): the network's "
            "segmentation and stiffness do not make a model of this panel")


def _vec(v) -> str:
    return "[" + ", ".join(f"{x:.4g}" for x in np.ravel(v)) + "]"


def load_checkpoint(path) -> Surrogate:
    """Load a surrogate checkpoint (a ``.safetensors`` file written by
    :func:`prbdm.surrogate.save_checkpoint`), checked (:func:`.checkpoint.read_checkpoint`).

    Raises :class:`BadInput` naming the file and the problem for a missing, corrupt, foreign or
    inconsistent one."""
    tensors, metadata = read_checkpoint(path)
    return Surrogate(tensors, metadata, Path(path))


_CACHE: dict = {}


def predict(beams_or_features, joints: int | None = None, truth: str = "beam", checkpoint=None,
            frequencies: bool = True, warn: bool = True, threads: int | None = None,
            allow_extrapolation: bool = False) -> Prediction:
    """Batched prediction with a checkpoint: ``checkpoint`` (a path or a loaded
    :class:`Surrogate`), or the default one for (``joints``, ``truth``). See
    :meth:`Surrogate.predict`."""
    if isinstance(checkpoint, Surrogate):
        sur = checkpoint
    else:
        if checkpoint is None:
            if joints is None:
                raise BadInput("joints: give the number of joints or a checkpoint")
            checkpoint = default_checkpoint(joints, truth)
        key = str(Path(checkpoint).resolve())
        sur = _CACHE.get(key)
        if sur is None:
            sur = _CACHE[key] = load_checkpoint(checkpoint)
    if joints is not None and sur.joints != joints:
        raise BadInput(f"--joints {joints}: checkpoint {sur.name} was trained for "
                       f"{sur.joints} joints")
    return sur.predict(beams_or_features, frequencies=frequencies, warn=warn, threads=threads,
                       allow_extrapolation=allow_extrapolation)
