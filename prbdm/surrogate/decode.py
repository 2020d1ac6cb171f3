"""From the network's raw head to valid outputs: gamma on the bounded simplex, k > 0 per pose and
the truth frequencies, for one network or an ensemble, in NumPy (:func:`decode_numpy`, inference)
and torch (:func:`decode_torch`, training; torch is imported inside it only).

The head of a network with H candidate segmentations is H (n + 1) gamma logits, m k outputs (one
per pose) and R frequency corrections. Every decoded output is valid by construction:
``gamma = g_min + (1 - (n+1) g_min) softmax(.)`` (sum 1, each in [0.025, 0.975]), ``k = exp(.)``
or a least-squares projection of positive eigenvalues (> 0), and
``log omega_hat = base + correction``, the base being ``log_omega_rfe`` (``log_omega_spread`` for
a ``spread`` network, ``FeatureSpec.base_columns``).
"""
from __future__ import annotations

import math

import numpy as np

from ..chain import prbdm_eigenvalues
from ..constants import GAMMA_MAX, GAMMA_MIN  # noqa: E402,F401  (GAMMA_MAX re-exported)


def silu(v):
    """``v sigmoid(v)``; below v = -709 ``exp(-v)`` overflows to inf and the quotient is -0, the
    exact limit, so that overflow is not reported."""
    with np.errstate(over="ignore"):
        return v / (1.0 + np.exp(-v))


def gamma_from_logits_np(logits, g_min: float = GAMMA_MIN):
    z = logits - logits.max(-1, keepdims=True)
    e = np.exp(z)
    n1 = logits.shape[-1]
    return g_min + (1.0 - n1 * g_min) * e / e.sum(-1, keepdims=True)


K_MODES = ("projection", "direct")
#: the poses on which a checkpoint without ``network.select_poses`` (format 1) compares its
#: candidate segmentations: the first and last of the set
SELECT_POSES = [0, -1]


def gauss_select_poses(m: int) -> list:
    """Indices of the poses on which candidates are compared, for a set of m poses: the two
    nearest the 2-point Gauss-Legendre nodes of the pose index range (m = 6: poses 1 and 4). The
    choice estimates the mean loss over the poses, which two Gauss nodes integrate far better
    than the end points (docs/surrogate.md §2)."""
    if m <= 2:
        return list(range(m))
    c = (m - 1) / 2
    return sorted({int(round(c - c / math.sqrt(3))), int(round(c + c / math.sqrt(3)))})


#: scale of the k head in ``projection`` mode: an output of 1 changes k by a factor e^0.01
K_DELTA_SCALE = 0.01


def project_k(mu, lam_pred):
    """Least-squares SCF per pose, <mu_i, lam> / <mu_i, mu_i> (> 0 for positive vectors)."""
    return (mu * lam_pred[..., None, :]).sum(-1) / (mu * mu).sum(-1)


def candidate_losses(mu, lam):
    """Loss [%] (docs/conventions.md §3) of each candidate's PRBDM with its least-squares SCFs against ``lam``:
    mu (B, H, m, r), lam (B, r) -> k (B, H, m), loss (B, H). Works for NumPy and torch."""
    lam_c = lam[:, None, :]
    k = project_k(mu, lam_c)
    res = k[..., None] * mu - lam_c[..., None, :]
    if isinstance(mu, np.ndarray):
        rel = np.linalg.norm(res, axis=-1) / np.linalg.norm(lam_c, axis=-1)[..., None]
    else:
        rel = res.norm(dim=-1) / lam_c.norm(dim=-1)[..., None]
    return k, 100.0 * rel.mean(-1)


def _plausible_first(loss, k, mu, lam):
    """The candidates' losses (B, H) with those whose PRBDM has a mode further than
    SELF_CHECK_IMPLAUSIBLE from the predicted truth on the choice poses put last (inf), where the
    beam has a plausible one. The loss weighs the highest mode most: on 39 of 300 held-out beams
    (beam-n4, seed 1) the candidate of least loss had mode 1 76 % off its own predicted truth
    (a rigid root link over a flexible neck), while another of its candidates had every mode
    within 50 % (median worst 20 %) at a loss a median 1.6 times higher."""
    from ..constants import SELF_CHECK_IMPLAUSIBLE

    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):   # a broken head
        err = np.sqrt(k[..., None] * mu / lam[:, None, None, :]) - 1.0      # (B, H, m, r)
    bad = ~(np.abs(err) <= SELF_CHECK_IMPLAUSIBLE).all(axis=(-2, -1))       # (B, H)
    some = ~bad.all(axis=1, keepdims=True)
    return np.where(bad & some, np.inf, loss)


def decode_numpy(out, norm: dict, joints: int, k_mode: str, rfe, x=None, w=None, poses=None,
                 r=None, hypotheses: int = 1, select_poses=SELECT_POSES,
                 plausible: bool = True) -> dict:
    """The network's raw head ``out`` (B, H (n+1) + m + R) -> a dict of gamma (B, n+1), logk
    (B, m), log_omega_hat (B, R), mu (B, m, n) unit-k PRBDM eigenvalues, and with H > 1 the
    candidates ``gamma_all`` (B, H, n+1) and the chosen one ``select`` (B,).

    - ``gamma = g_min + (1 - (n+1) g_min) softmax(logits)``: on the bounded simplex, for each of
      the H candidate segmentations (``hypotheses``);
    - ``log omega_hat = base + out[:, -R:] * freq_std + freq_mean`` (base: ``FeatureSpec.base_columns``): the truth
      frequencies / sqrt(E t^2 / (rho L^4)), as a correction of the rigid-finite-element estimate;
    - ``k``, per pose, in one of two ways (``k_mode``):
      ``direct``: ``log k = out * logk_std + logk_mean`` (H = 1 only);
      ``projection``: the least-squares SCF that matches the PRBDM's unit-k eigenvalues
      ``mu_i(gamma)`` to the network's own predicted truth eigenvalues ``omega_hat^2`` (the same
      variable projection as the fit, docs/conventions.md §3, with the prediction in place of the truth), times
      ``exp(K_DELTA_SCALE * out)``. It needs the geometry (x, w / L), the poses and r.
    - with H > 1 candidates, the one kept is the one whose PRBDM best matches the predicted truth
      frequencies (the docs/conventions.md §3 loss against ``omega_hat``, on the poses ``select_poses`` of the
      set), among those with every mode within SELF_CHECK_IMPLAUSIBLE of it where the beam has
      such a candidate (``plausible``; False: the least loss alone): the network proposes, the
      physics chooses. Without geometry, candidate 0 is returned and logk is None.
    Every output is valid by construction: k > 0 because mu > 0 and omega_hat > 0.
    """
    n1 = joints + 1
    H = hypotheses
    m = len(norm["logk_mean"])
    B = out.shape[0]
    gamma_all = gamma_from_logits_np(out[:, :H * n1].reshape(B, H, n1))
    kh = out[:, H * n1:H * n1 + m]
    log_omega_hat = rfe + out[:, H * n1 + m:] * norm["freq_std"] + norm["freq_mean"]
    res = {"gamma": gamma_all[:, 0], "logk": None, "log_omega_hat": log_omega_hat, "mu": None,
           "gamma_all": gamma_all, "select": np.zeros(B, dtype=np.int64), "candidate_loss": None}
    if k_mode == "direct":
        res["logk"] = kh * norm["logk_std"] + norm["logk_mean"]
    elif x is not None:
        lam_p = np.exp(2 * log_omega_hat[:, :r])
        rows = np.arange(B)
        sel = np.zeros(B, dtype=np.int64)
        if H > 1:       # choose on a few poses (cheap), then solve the kept one on the others
            select_poses = [int(i) % len(poses) for i in select_poses]
            mu_all = prbdm_eigenvalues(np.repeat(x, H, 0), np.repeat(w, H, 0),
                                       gamma_all.reshape(B * H, n1), poses[select_poses])
            mu_all = mu_all.reshape(B, H, *mu_all.shape[1:])
            k_all, res["candidate_loss"] = candidate_losses(mu_all[..., :r], lam_p)
            sel = np.argmin(_plausible_first(res["candidate_loss"], k_all, mu_all[..., :r], lam_p)
                            if plausible else res["candidate_loss"], axis=1)
            gamma = gamma_all[rows, sel]
            rest = [i for i in range(len(poses)) if i not in select_poses]
            mu = np.empty((B, len(poses), joints))
            mu[:, select_poses] = mu_all[rows, sel]
            if rest:
                mu[:, rest] = prbdm_eigenvalues(x, w, gamma, poses[rest])
        else:
            gamma = gamma_all[rows, sel]
            mu = prbdm_eigenvalues(x, w, gamma, poses)
        kp = project_k(mu[..., :r], lam_p)
        res.update(gamma=gamma, mu=mu, select=sel, logk=np.log(kp) + K_DELTA_SCALE * kh)
    return res


def combine_members(outs: list, hypotheses: int, joints: int):
    """One head output from the heads of an ensemble's members (each (B, H (n+1) + m + R)):
    every member's H candidate segmentations side by side (M H candidates; the physics chooses
    among all of them), the mean k correction and the mean frequency correction (averaging
    independent networks' frequency predictions lowers their error). NumPy or torch."""
    if len(outs) == 1:
        return outs[0]
    c = hypotheses * (joints + 1)
    if isinstance(outs[0], np.ndarray):
        return np.concatenate([o[:, :c] for o in outs]
                              + [np.mean([o[:, c:] for o in outs], axis=0)], axis=1)
    import torch
    return torch.cat([o[:, :c] for o in outs] + [torch.stack([o[:, c:] for o in outs]).mean(0)],
                     dim=1)


def decode_torch(out, norm: dict, joints: int, m: int, k_mode: str, rfe, x=None, w=None,
                 poses=None, r=None, hypotheses: int = 1, select_poses=None,
                 detach_frequencies: bool = False) -> dict:
    """Torch twin of :func:`decode_numpy` (differentiable; eigenvalues in float64). Also returns
    ``mu_all`` (B, H, m, n) for the training losses. By default (``select_poses=None``) the
    candidates are compared on every pose (all are solved for the training losses anyway): the
    rule that the Gauss poses of :func:`decode_numpy` approximate at a third of the cost.
    ``detach_frequencies``: the candidates' choice and the SCF projection read the predicted
    frequencies without their gradient, so that a loss on the PRBDM does not move them."""
    import torch

    from .. import model

    n1 = joints + 1
    H = hypotheses
    B = out.shape[0]
    gamma_all = GAMMA_MIN + (1 - n1 * GAMMA_MIN) * torch.softmax(
        out[:, :H * n1].reshape(B, H, n1), -1)
    kh = out[:, H * n1:H * n1 + m]
    log_omega_hat = rfe + out[:, H * n1 + m:] * norm["freq_std"] + norm["freq_mean"]
    res = {"gamma": gamma_all[:, 0], "logk": None, "log_omega_hat": log_omega_hat, "mu": None,
           "mu_all": None, "gamma_all": gamma_all,
           "select": torch.zeros(B, dtype=torch.long)}
    if k_mode == "direct":
        res["logk"] = kh * norm["logk_std"] + norm["logk_mean"]
    elif x is not None:
        ones = torch.ones(B, 1, dtype=torch.float64)
        bt = model.BeamTensors(x[:, None], w[:, None], ones, ones, ones, ones)
        mu_all = model.eigenvalues_unit_k(bt, gamma_all.double(), poses, "beam")
        lam_p = torch.exp(2 * (log_omega_hat.detach() if detach_frequencies
                               else log_omega_hat)[:, :r].double())
        rows = torch.arange(B)
        # the choice on every pose, as the loss itself (the first and last poses alone chose a
        # worse candidate for many beams: docs/surrogate.md §5)
        on = mu_all if select_poses is None else mu_all[:, :, select_poses]
        sel = candidate_losses(on[..., :r], lam_p)[1].detach().argmin(1)
        mu = mu_all[rows, sel]
        kp = project_k(mu[..., :r], lam_p)
        res.update(gamma=gamma_all[rows, sel], mu=mu, mu_all=mu_all, select=sel,
                   logk=torch.log(kp) + K_DELTA_SCALE * kh.double())
    return res



def concatenate_outputs(parts: list) -> dict:
    """Decoded outputs of consecutive pieces of a batch, joined along the beams (None stays
    None: those outputs need the geometry, which none of the pieces had)."""
    return {key: (None if parts[0][key] is None
                  else np.concatenate([part[key] for part in parts])) for key in parts[0]}
