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
        layers, c_in, c, s = [], channels, width, image_size
        while s > 4:
            layers += [nn.Conv2d(c_in, c, 4, 2, 1), nn.GroupNorm(8, c), nn.SiLU()]
            c_in, c, s = c, min(c * 2, width * 8), s // 2
        self.net = nn.Sequential(*layers)
        self.head = nn.Linear(c_in * 16, 2 * latent)

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        if x.dim() != 4 or x.shape[1:] != self.shape:
            c, s, _ = self.shape
            raise ValueError(f"images must be (B, {c}, {s}, {s}), got {tuple(x.shape)}")
        h = self.net(2 * x - 1).flatten(1)  # (B, C' * 16)
        mu, logvar = self.head(h).chunk(2, dim=-1)  # (B, D) each
        return mu, logvar.clamp(-10, 10)


def sample_latent(mu: torch.Tensor, logvar: torch.Tensor, sample: bool = True) -> torch.Tensor:
    """A draw ``z (B, D)`` from the posterior (reparameterised), or its mean ``mu``."""
    return mu + torch.randn_like(mu) * (0.5 * logvar).exp() if sample else mu
