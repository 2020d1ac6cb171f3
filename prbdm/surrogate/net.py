"""The torch network, for training: :class:`SurrogateNet` (an MLP on standardised features with one
linear head) and :class:`SurrogateEnsemble` (several of them as one network).

This module imports torch; nothing on the inference path (``prbdm predict``, :mod:`.prediction`)
imports it. Inference runs the same MLP in NumPy from the weights that :meth:`SurrogateNet.weights`
returns and :func:`prbdm.surrogate.save_checkpoint` stores.
"""
from __future__ import annotations

import numpy as np
import torch
from torch import nn

from ..errors import BadInput
from .decode import K_MODES, combine_members, decode_torch


class SurrogateNet(nn.Module):
    """MLP on standardised features -> (gamma logits, k head, standardised frequency
    correction). :meth:`outputs` maps them to valid gamma, k > 0 and log omega_hat (see
    :func:`prbdm.surrogate.decode.decode_numpy`).

    layers: ``depth`` hidden Linear + SiLU layers of ``width`` units, then one linear head
    of H (n + 1) + m + R outputs (H candidate segmentations, ``hypotheses``)."""

    def __init__(self, n_in: int, joints: int, poses: int, modes: int, width: int = 256,
                 depth: int = 3, k_mode: str = "projection", hypotheses: int = 1):
        super().__init__()
        if k_mode not in K_MODES:
            raise BadInput(f"k_mode: must be one of {', '.join(K_MODES)}, got {k_mode!r}")
        if hypotheses > 1 and k_mode == "direct":
            raise BadInput("hypotheses > 1 needs k_mode 'projection'")
        self.joints, self.n_poses, self.modes, self.k_mode = joints, poses, modes, k_mode
        self.hypotheses = hypotheses
        dims = [n_in] + [width] * depth
        self.hidden = nn.ModuleList(nn.Linear(a, b) for a, b in zip(dims[:-1], dims[1:]))
        self.head = nn.Linear(width, hypotheses * (joints + 1) + poses + modes)

    def forward(self, f):
        h = f
        for layer in self.hidden:
            h = torch.nn.functional.silu(layer(h))
        return self.head(h)

    def outputs(self, f, norm: dict, rfe, x=None, w=None, poses=None, r=None,
                select_poses=None) -> dict:
        """Decoded outputs for standardised features ``f`` (B, F), see
        :func:`decode_torch`: gamma (B, n+1), logk (B, m), log_omega_hat (B, R), mu
        (B, m, n) unit-k PRBDM eigenvalues (float64; None for ``k_mode = 'direct'``), ...
        ``norm``: torch tensors of the normalisation; ``rfe`` (B, R) the log_omega_rfe
        features; x, w (B, S) / L, poses (m, n) and the mapped mode count r are needed by
        ``k_mode = 'projection'``; candidates are compared on ``select_poses`` (all: None)."""
        return decode_torch(self(f), norm, self.joints, self.n_poses, self.k_mode, rfe, x, w,
                            poses, r, self.hypotheses, select_poses)

    def weights(self) -> dict:
        """The weights as the checkpoint stores them: layers.{i}.weight/bias, NumPy float32."""
        out = {}
        for i, layer in enumerate([*self.hidden, self.head]):
            out[f"layers.{i}.weight"] = layer.weight.detach().cpu().numpy().astype(np.float32)
            out[f"layers.{i}.bias"] = layer.bias.detach().cpu().numpy().astype(np.float32)
        return out

    def load_weights(self, weights: dict):
        """Copy weights in the checkpoint's layout (:meth:`weights`) into the layers."""
        for i, layer in enumerate([*self.hidden, self.head]):
            layer.weight.data.copy_(torch.as_tensor(weights[f"layers.{i}.weight"]))
            layer.bias.data.copy_(torch.as_tensor(weights[f"layers.{i}.bias"]))
        return self


class SurrogateEnsemble(nn.Module):
    """Several :class:`SurrogateNet` members as one network: their candidates side by side
    and their k and frequency corrections averaged (:func:`combine_members`)."""

    def __init__(self, members):
        super().__init__()
        self.members = nn.ModuleList(members)
        first = members[0]
        self.joints, self.n_poses, self.modes = first.joints, first.n_poses, first.modes
        self.k_mode, self.member_hypotheses = first.k_mode, first.hypotheses
        self.hypotheses = first.hypotheses * len(members)

    def forward(self, f):
        return combine_members([net(f) for net in self.members], self.member_hypotheses,
                               self.joints)

    def outputs(self, f, norm: dict, rfe, x=None, w=None, poses=None, r=None,
                select_poses=None) -> dict:
        return decode_torch(self(f), norm, self.joints, self.n_poses, self.k_mode, rfe, x, w,
                            poses, r, self.hypotheses, select_poses)

    def weights(self) -> dict:
        """members.{j}.layers.{i}.weight/bias, NumPy float32."""
        return {f"members.{j}.{k}": v for j, net in enumerate(self.members)
                for k, v in net.weights().items()}
