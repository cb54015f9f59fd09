"""Convolutional encoder: image -> VAE posterior ``(mu, logvar)`` (paper sec. 3)."""

from __future__ import annotations

import torch
from torch import nn


class Encoder(nn.Module):
    """Stride-2 convolutions down to 4x4, then a linear layer to ``2 * latent``.

    Input ``(B, C, S, S)`` in [0, 1] with S a power of two >= 8 (other shapes: ``ValueError``);
    output ``mu, logvar`` of ``(B, D)``.
    """

    def __init__(self, image_size: int, channels: int, latent: int, width: int):
        super().__init__()
        if image_size < 8 or image_size & (image_size - 1):
            raise ValueError(f"image_size must be a power of two >= 8, got {image_size}")
        self.shape = (channels, image_size, image_size)
        self.net, features = conv_stack(image_size, channels, width)
        self.head = nn.Linear(features, 2 * latent)

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        if x.dim() != 4 or x.shape[1:] != self.shape:
            c, s, _ = self.shape
            raise ValueError(f"images must be (B, {c}, {s}, {s}), got {tuple(x.shape)}")
        h = self.net(2 * x - 1).flatten(1)  # (B, C' * 16)
        mu, logvar = self.head(h).chunk(2, dim=-1)  # (B, D) each
        return mu, logvar.clamp(-10, 10)


class Feedback(nn.Module):
    """One render-and-compare pass: the picture, the render of the current latent and their
    difference ``(B, 3C, S, S)``, and with ``paths = P`` each path's own coverage ``(B, P, S, S)``
    (``ModelConfig.feedback_paths``: which path drew what), through a conv stack like the
    encoder's, then a linear step from those features and the latent to a correction added to
    the latent ``(B, D)``.

    The step's layer starts at zero, so a model given a feedback pass (``ModelConfig.feedback``,
    grown by ``train --init``) encodes what it encoded before and learns the correction from there.
    """

    def __init__(self, image_size: int, channels: int, latent: int, width: int, paths: int = 0):
        super().__init__()
        self.net, features = conv_stack(image_size, 3 * channels + paths, width)
        self.step = nn.Linear(features + latent, latent)
        nn.init.zeros_(self.step.weight)
        nn.init.zeros_(self.step.bias)

    def forward(self, x: torch.Tensor, seen: torch.Tensor, z: torch.Tensor,
                parts: torch.Tensor | None = None) -> torch.Tensor:
        """``x, seen (B, C, S, S)`` in [0, 1], ``z (B, D)``, ``parts (B, P, S, S)`` in [0, 1] when
        built with ``paths`` -> the corrected latent ``(B, D)``."""
        inputs = [2 * x - 1, 2 * seen - 1, x - seen] + ([2 * parts - 1] if parts is not None else [])
        h = self.net(torch.cat(inputs, 1)).flatten(1)  # (B, C' * 16)
        return z + self.step(torch.cat([h, z], -1))


class PathPass(nn.Module):
    """One render-and-compare pass on each path: the picture, the render of the current paths,
    their difference and this path's own coverage ``(B*P, 3C+1, S, S)``, through a conv stack
    like the encoder's (shared by the paths), then a small MLP from those features, the path's
    code and its colour to a correction of both ``(B, P, code + 3)`` (the colour's in logit space).

    The latent passes (``Feedback``) correct one ``z`` through the LSTM; this one corrects each
    path's code directly, the space that per-picture fits reach furthest in from the same start
    (docs/results/fonts-ablation.md). The MLP's last layer starts at zero, so a model given a
    path pass (``ModelConfig.path_passes``, grown by ``train --init``) draws what it drew before.
    """

    def __init__(self, image_size: int, channels: int, code: int, width: int, hidden: int = 256):
        super().__init__()
        self.net, features = conv_stack(image_size, 3 * channels + 1, width)
        self.step = nn.Sequential(nn.Linear(features + code + 3, hidden), nn.SiLU(), nn.Linear(hidden, code + 3))
        nn.init.zeros_(self.step[-1].weight)
        nn.init.zeros_(self.step[-1].bias)

    def forward(self, x: torch.Tensor, seen: torch.Tensor, parts: torch.Tensor, code: torch.Tensor,
                color: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``x, seen (B, C, S, S)`` and ``parts (B, P, S, S)`` in [0, 1], ``code (B, P, K)``,
        ``color (B, P, 3)`` -> the corrected code ``(B, P, K)`` and colour ``(B, P, 3)`` in [0, 1]."""
        b, p, k = code.shape
        pic = torch.cat([2 * x - 1, 2 * seen - 1, x - seen], 1)  # (B, 3C, S, S)
        inputs = torch.cat([pic[:, None].expand(-1, p, -1, -1, -1), 2 * parts[:, :, None] - 1], 2)  # (B, P, 3C+1, S, S)
        h = self.net(inputs.flatten(0, 1)).flatten(1)  # (B*P, F)
        d = self.step(torch.cat([h, code.flatten(0, 1), color.flatten(0, 1)], -1)).view(b, p, k + 3)
        logit = torch.logit(color.clamp(1e-4, 1 - 1e-4))  # a step in logit space: no colour is pinned at 0 or 1
        return code + d[..., :k], torch.sigmoid(logit + d[..., k:])


def conv_stack(image_size: int, channels: int, width: int) -> tuple[nn.Sequential, int]:
    """Stride-2 convolutions from ``(B, channels, S, S)`` down to 4x4; returns the stack and the
    number of features it leaves per picture (flattened)."""
    layers, c_in, c, s = [], channels, width, image_size
    while s > 4:
        layers += [nn.Conv2d(c_in, c, 4, 2, 1), nn.GroupNorm(8, c), nn.SiLU()]
        c_in, c, s = c, min(c * 2, width * 8), s // 2
    return nn.Sequential(*layers), c_in * 16


def sample_latent(mu: torch.Tensor, logvar: torch.Tensor, sample: bool = True) -> torch.Tensor:
    """A draw ``z (B, D)`` from the posterior (reparameterised), or its mean ``mu``."""
    return mu + torch.randn_like(mu) * (0.5 * logvar).exp() if sample else mu
