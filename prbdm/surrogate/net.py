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
    of H (n + 1) + m + R outputs (H candidate segmentations, ``hypotheses``). ``freq_width``
    > 0: the R frequency outputs come from a trunk of their own, ``depth`` layers of
    ``freq_width`` units (stored as one MLP, block-diagonal: inference does not know)."""

    def __init__(self, n_in: int, joints: int, poses: int, modes: int, width: int = 256,
                 depth: int = 3, k_mode: str = "projection", hypotheses: int = 1,
                 freq_width: int = 0):
        super().__init__()
        if k_mode not in K_MODES:
            raise BadInput(f"k_mode: must be one of {', '.join(K_MODES)}, got {k_mode!r}")
        if hypotheses > 1 and k_mode == "direct":
            raise BadInput("hypotheses > 1 needs k_mode 'projection'")
        if freq_width < 0 or (freq_width and modes < 1):
            raise BadInput(f"freq_width: 0, or > 0 with frequency outputs, got {freq_width}")
        self.joints, self.n_poses, self.modes, self.k_mode = joints, poses, modes, k_mode
        self.hypotheses, self.freq_width = hypotheses, int(freq_width)
        # freq_width > 0: the frequency outputs have a trunk of their own (no capacity shared
        # with the PRBDM's candidates and SCFs); both trunks together are still one MLP, of width
        # width + freq_width with block-diagonal hidden layers (:meth:`weights`)
        prbdm_out = hypotheses * (joints + 1) + poses + (0 if freq_width else modes)
        self.hidden, self.head = self._mlp(n_in, width, depth, prbdm_out)
        if freq_width:
            self.freq_hidden, self.freq_head = self._mlp(n_in, freq_width, depth, modes)

    @staticmethod
    def _mlp(n_in, width, depth, n_out):
        dims = [n_in] + [width] * depth
        return (nn.ModuleList(nn.Linear(a, b) for a, b in zip(dims[:-1], dims[1:])),
                nn.Linear(width, n_out))

    @staticmethod
    def _run(hidden, head, f):
        h = f
        for layer in hidden:
            h = torch.nn.functional.silu(layer(h))
        return head(h)

    def forward(self, f):
        out = self._run(self.hidden, self.head, f)
        if self.freq_width:
            out = torch.cat([out, self._run(self.freq_hidden, self.freq_head, f)], -1)
        return out

    def outputs(self, f, norm: dict, rfe, x=None, w=None, poses=None, r=None,
                select_poses=None, detach_frequencies=False) -> dict:
        """Decoded outputs for standardised features ``f`` (B, F), see
        :func:`decode_torch`: gamma (B, n+1), logk (B, m), log_omega_hat (B, R), mu
        (B, m, n) unit-k PRBDM eigenvalues (float64; None for ``k_mode = 'direct'``), ...
        ``norm``: torch tensors of the normalisation; ``rfe`` (B, R) the log_omega_rfe
        features; x, w (B, S) / L, poses (m, n) and the mapped mode count r are needed by
        ``k_mode = 'projection'``; candidates are compared on ``select_poses`` (all: None)."""
        return decode_torch(self(f), norm, self.joints, self.n_poses, self.k_mode, rfe, x, w,
                            poses, r, self.hypotheses, select_poses,
                            detach_frequencies)

    def _layers(self):
        """[(weight, bias)] of the one MLP the checkpoint stores: with a frequency trunk, its
        layers and the PRBDM trunk's side by side (hidden layers block-diagonal)."""
        pairs = [(a.weight, a.bias) for a in [*self.hidden, self.head]]
        if not self.freq_width:
            return pairs
        out = []
        for i, ((Wp, bp), f) in enumerate(zip(pairs, [*self.freq_hidden, self.freq_head])):
            # the first layer: both read the features; then each its own trunk's units
            W = torch.cat([Wp, f.weight], 0) if i == 0 else torch.block_diag(Wp, f.weight)
            out.append((W, torch.cat([bp, f.bias])))
        return out

    def weights(self) -> dict:
        """The weights as the checkpoint stores them: layers.{i}.weight/bias, NumPy float32."""
        out = {}
        for i, (W, b) in enumerate(self._layers()):
            out[f"layers.{i}.weight"] = W.detach().cpu().numpy().astype(np.float32)
            out[f"layers.{i}.bias"] = b.detach().cpu().numpy().astype(np.float32)
        return out

    def load_weights(self, weights: dict):
        """Copy weights in the checkpoint's layout (:meth:`weights`) into the layers (with a
        frequency trunk: read back from the blocks :meth:`weights` wrote)."""
        def w(i, key):
            return torch.as_tensor(weights[f"layers.{i}.{key}"])

        prbdm = [*self.hidden, self.head]
        for i, layer in enumerate(prbdm):             # the first rows and columns of each layer
            cols = slice(None) if i == 0 else slice(0, layer.in_features)
            layer.weight.data.copy_(w(i, "weight")[:layer.out_features, cols])
            layer.bias.data.copy_(w(i, "bias")[:layer.out_features])
        if self.freq_width:                            # the frequency trunk: the rest of them
            for i, (p, layer) in enumerate(zip(prbdm, [*self.freq_hidden, self.freq_head])):
                cols = slice(None) if i == 0 else slice(p.in_features, None)
                layer.weight.data.copy_(w(i, "weight")[p.out_features:, cols])
                layer.bias.data.copy_(w(i, "bias")[p.out_features:])
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
                select_poses=None, detach_frequencies=False) -> dict:
        return decode_torch(self(f), norm, self.joints, self.n_poses, self.k_mode, rfe, x, w,
                            poses, r, self.hypotheses, select_poses,
                            detach_frequencies)

    def weights(self) -> dict:
        """members.{j}.layers.{i}.weight/bias, NumPy float32."""
        return {f"members.{j}.{k}": v for j, net in enumerate(self.members)
                for k, v in net.weights().items()}
