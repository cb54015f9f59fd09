"""Decoder: latent -> per-path codes (bi-LSTM) -> closed cubic paths (circular 1-D convs).

Paper sec. 3.1: a path decoder deforms 3k points sampled on the unit circle into the
control points of a closed cubic path of k segments. Each point carries the fused vector
``[cos t, sin t, onehot(anchor | control), path code]``. A sample-deformation subnetwork
(sec. 3.1.2) first moves the points along the circle by a bounded angle.
Convolutions use circular padding 1 with kernel 3, so the length stays 3k (the authors'
``padding=2`` grows it on torch >= 1.5).
"""

from __future__ import annotations

import contextlib
import math

import torch
from torch import nn


def circle_samples(k: int, batch: int, device, dtype) -> torch.Tensor:
    """Angles of 3k points evenly spaced on the circle, ``(B, 3k)``; point 3s is an anchor."""
    t = torch.arange(3 * k, device=device, dtype=dtype) * (2 * math.pi / (3 * k))
    return t.expand(batch, -1)


def point_types(k: int, device, dtype) -> torch.Tensor:
    """One-hot ``(2, 3k)``: row 0 anchors, row 1 controls."""
    anchor = (torch.arange(3 * k, device=device) % 3 == 0).to(dtype)
    return torch.stack([anchor, 1 - anchor])


def _circular_stack(c_in: int, width: int, layers: int, c_out: int) -> nn.Sequential:
    mods: list[nn.Module] = []
    c = c_in
    for _ in range(layers - 1):
        mods += [nn.Conv1d(c, width, 3, padding=1, padding_mode="circular"), nn.ReLU()]
        c = width
    mods.append(nn.Conv1d(c, c_out, 3, padding=1, padding_mode="circular"))
    return nn.Sequential(*mods)


class PathDecoder(nn.Module):
    """Path code ``(N, C)`` and k -> control points ``(N, 3k, 2)`` in [0, 1] (normalised frame)."""

    def __init__(self, code: int, width: int, layers: int, deform: bool, deform_width: int):
        super().__init__()
        fused = 2 + 2 + code
        self.deform = _circular_stack(fused, deform_width, 3, 1) if deform else None
        self.net = _circular_stack(fused, width, layers, 2)
        nn.init.zeros_(self.net[-1].weight)
        nn.init.zeros_(self.net[-1].bias)
        if self.deform is not None:
            nn.init.zeros_(self.deform[-1].weight)
            nn.init.zeros_(self.deform[-1].bias)

    @staticmethod
    def _stack(stack: nn.Sequential, theta: torch.Tensor, types: torch.Tensor, code: torch.Tensor) -> torch.Tensor:
        """Run a circular stack on the fused ``[cos t, sin t, types, code]`` ``(N, 4 + C, 3k)``.

        The code is constant along the circle, so the first conv's share of it is one
        matrix product per path (its taps summed) added as a bias: the same output as the
        conv over all 4 + C channels, at a fraction of the cost (``theta (N, 3k)``,
        ``types (1, 2, 3k)``, ``code (N, C)``).
        """
        first = stack[0]
        geom = torch.cat([torch.stack([theta.cos(), theta.sin()], 1), types.expand(theta.shape[0], -1, -1)], 1)
        w = first.weight  # (W, 4 + C, 3)
        h = nn.functional.conv1d(nn.functional.pad(geom, (1, 1), mode="circular"), w[:, :4])  # (N, W, 3k)
        h = h + nn.functional.linear(code, w[:, 4:].sum(-1), first.bias).unsqueeze(-1)
        return stack[1:](h)

    def forward(self, code: torch.Tensor, k: int, centre: torch.Tensor | None = None) -> torch.Tensor:
        """``code (N, C)``, ``centre (N, 2)`` start position of each path in [0, 1] (default 0.5)."""
        n = code.shape[0]
        theta = circle_samples(k, n, code.device, code.dtype)  # (N, 3k)
        types = point_types(k, code.device, code.dtype).unsqueeze(0)  # (1, 2, 3k)
        if self.deform is not None:
            # bounded shift: at most half the spacing, so points keep their circular order
            shift = torch.tanh(self._stack(self.deform, theta, types, code)[:, 0]) * (math.pi / (3 * k))
            theta = theta + shift  # (N, 3k)
        out = self._stack(self.net, theta, types, code)  # (N, 2, 3k)
        base = torch.stack([theta.cos(), theta.sin()], 1) * 0.2  # (N, 2, 3k)
        offset = torch.zeros(n, 2, 1, device=code.device, dtype=code.dtype)
        if centre is not None:
            offset = torch.logit(centre.clamp(0.05, 0.95)).unsqueeze(-1)
        # ReLU features -> canvas through a sigmoid, so points stay in [0, 1]; with the zero
        # initialised last layer each path starts as a circle of radius ~0.1 around its centre.
        pts = torch.sigmoid(offset + 2 * (out + base))
        return pts.transpose(1, 2)  # (N, 3k, 2)


class PathCodes(nn.Module):
    """Bidirectional LSTM over P steps of ``z``: per-path codes, depths and colours."""

    def __init__(self, latent: int, hidden: int, code: int, paths: int):
        super().__init__()
        self.paths = paths
        self.step = nn.Parameter(torch.randn(paths, latent) * 0.02)  # tells the steps apart
        self.lstm = nn.LSTM(latent, hidden, batch_first=True, bidirectional=True)
        self.code = nn.Linear(2 * hidden, code)  # combines the two directions
        self.depth = nn.Linear(2 * hidden, 1)
        self.color = nn.Linear(2 * hidden, 3)

    def forward(self, z: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """``z (B, D)`` -> code ``(B, P, C)``, depth ``(B, P)``, colour ``(B, P, 3)``, LSTM output ``(B, P, 2H)``."""
        seq = z.unsqueeze(1) + self.step  # (B, P, D)
        # fitting latents (encode --fit, interpolate, refinement) backpropagates through the LSTM of
        # a model in eval mode, which cuDNN's RNN refuses ("backward can only be called in training
        # mode"); PyTorch's own kernels compute the same LSTM (no dropout)
        no_cudnn = seq.is_cuda and torch.is_grad_enabled() and not self.training
        with torch.backends.cudnn.flags(enabled=False) if no_cudnn else contextlib.nullcontext():
            h, _ = self.lstm(seq)  # (B, P, 2H)
        return self.code(h), self.depth(h).squeeze(-1), torch.sigmoid(self.color(h)), h
