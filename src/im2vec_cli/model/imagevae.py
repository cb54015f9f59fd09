"""The ImageVAE baseline of the paper (sec. 4): Im2Vec's encoder with a transposed-conv raster
decoder. It draws pixels, not paths, so it has no vector output and no vector metrics; it is
trained by ``im2vec train --arch imagevae`` with the same loss (Gaussian-pyramid L2 + KL) and
scored by ``im2vec eval`` beside the vector model.
"""

from __future__ import annotations

import torch
from torch import nn

from ..config import ModelConfig
from .encoder import Encoder, sample_latent


class RasterDecoder(nn.Module):
    """Mirror of ``Encoder``: ``z (B, D)`` -> linear to ``(C, 4, 4)`` -> stride-2 transposed
    convolutions (4x4 kernels, GroupNorm, SiLU) up to ``(B, channels, S, S)`` in [0, 1]."""

    def __init__(self, image_size: int, channels: int, latent: int, width: int):
        super().__init__()
        widths, c, s = [], width, image_size
        while s > 4:  # the encoder's stage widths, finest first
            widths.append(c)
            c, s = min(c * 2, width * 8), s // 2
        self.top = widths[-1]
        self.head = nn.Linear(latent, self.top * 16)
        layers, c_in = [], self.top
        for c in reversed(widths[:-1]):
            layers += [nn.ConvTranspose2d(c_in, c, 4, 2, 1), nn.GroupNorm(8, c), nn.SiLU()]
            c_in = c
        # the last stage draws the image itself (as in DCGAN): a full-resolution conv stack
        # would triple the cost of a training step on CPU
        self.net = nn.Sequential(*layers, nn.ConvTranspose2d(c_in, channels, 4, 2, 1))
        # start near white (sigmoid(3) = 0.95), as Im2Vec starts from small circles on white:
        # every dataset here is drawn on white, and a grey start costs hundreds of steps
        nn.init.constant_(self.net[-1].bias, 3.0)

    def forward(self, z: torch.Tensor) -> torch.Tensor:
        h = self.head(z).view(len(z), self.top, 4, 4)
        return torch.sigmoid(self.net(h))  # (B, C, S, S)


class ImageVAE(nn.Module):
    """Encoder + ``RasterDecoder``, configured by ``ModelConfig`` (``arch="imagevae"``; the
    path settings are ignored). ``forward`` returns ``(raster (B, C, S, S), mu, logvar)``."""

    raster_output = True

    def __init__(self, config: ModelConfig):
        super().__init__()
        self.config = config
        self.encoder = Encoder(config.image_size, config.channels, config.latent, config.enc_width)
        self.decoder = RasterDecoder(config.image_size, config.channels, config.latent, config.enc_width)

    def encode(self, images: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``(B, C, S, S)`` in [0, 1] -> ``mu, logvar (B, D)``."""
        return self.encoder(images)

    def decode(self, z: torch.Tensor) -> torch.Tensor:
        """``z (B, D)`` -> ``(B, C, S, S)`` in [0, 1]."""
        return self.decoder(z)

    def forward(self, images: torch.Tensor, segments: int | None = None, sample: bool = True):
        """Reconstruct a batch (``segments`` is ignored: there are no paths)."""
        mu, logvar = self.encode(images)
        return self.decode(sample_latent(mu, logvar, sample)), mu, logvar
