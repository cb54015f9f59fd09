"""Convolutional encoder: image -> VAE posterior ``(mu, logvar)`` (paper sec. 3)."""

from __future__ import annotations

import torch
from torch import nn


class Encoder(nn.Module):
    """Stride-2 convolutions down to 4x4, then a linear layer to ``2 * latent``.

    Input ``(B, C, S, S)`` with S a power of two >= 8; output ``mu, logvar`` of ``(B, D)``.
    """

    def __init__(self, image_size: int, channels: int, latent: int, width: int):
        super().__init__()
        if image_size < 8 or image_size & (image_size - 1):
            raise ValueError(f"image_size must be a power of two >= 8, got {image_size}")
        layers, c_in, c, s = [], channels, width, image_size
        while s > 4:
            layers += [nn.Conv2d(c_in, c, 4, 2, 1), nn.GroupNorm(8, c), nn.SiLU()]
            c_in, c, s = c, min(c * 2, width * 8), s // 2
        self.net = nn.Sequential(*layers)
        self.head = nn.Linear(c_in * 16, 2 * latent)

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        h = self.net(2 * x - 1).flatten(1)  # (B, C' * 16)
        mu, logvar = self.head(h).chunk(2, dim=-1)  # (B, D) each
        return mu, logvar.clamp(-10, 10)
