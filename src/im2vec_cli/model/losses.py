"""The training objective (paper sec. 3.4): L2 over a Gaussian pyramid (eq. 1) plus the KL term."""

from __future__ import annotations

import torch

from ..raster import detail_weights, gaussian_pyramid, pyramid_l2, render_pyramid
from .pretrained import unwrap_model


def kl_divergence(mu: torch.Tensor, logvar: torch.Tensor) -> torch.Tensor:
    """KL(q(z|x) || N(0, I)) summed over latent dims, averaged over the batch."""
    return (-0.5 * (1 + logvar - mu.square() - logvar.exp()).sum(-1)).mean()


def reconstruction_loss(model, images: torch.Tensor, segments: int, tau: float, sample: bool,
                        supersample: int = 1, pyramid: str = "blur", solved: bool = False, detail: float = 0.0):
    """Pyramid L2 (eq. 1) of the reconstruction, and the KL term. ``images (B, 3, S, S)``.

    ``model`` may be wrapped (DDP, ``torch.compile``); ``supersample > 1`` renders the finest
    level from that many sub-pixels per side (``tau`` in sub-pixels there), so the loss sees
    the edges a user's antialiased render shows. ``pyramid`` picks the coarser levels
    (``render_pyramid``'s ``coarse``). ``solved`` (``TrainConfig.solved``, a vector model with
    ``solve_colors``): the colours solved in training too, and the layers composited "over" as
    the SVG draws them instead of the depth-differentiable "soft" blend. ``detail > 0``
    (``TrainConfig.detail``): the finest level weighs each pixel by ``raster.detail_weights``.

    Returns ``(pyramid L2, KL, decoded, mu)``: ``Decoded`` paths, or for the ImageVAE baseline
    its ``(B, 3, S, S)`` raster, scored by the same pyramid loss; ``mu (B, D)`` the encoder's mean.
    """
    m = unwrap_model(model)
    cfg = m.config
    dec, mu, logvar = model(images, segments, sample=sample, **({"solve": True} if solved else {}))
    target = gaussian_pyramid(images, cfg.levels)
    weight = detail_weights(images, detail) if detail else None  # (B, 1, S, S)
    if m.raster_output:
        return pyramid_l2(gaussian_pyramid(dec, cfg.levels), target, weight=weight), kl_divergence(mu, logvar), dec, mu
    renders = render_pyramid(
        dec.points, dec.colors, dec.depth, size=cfg.image_size, levels=cfg.levels, tau=tau,
        fill_rule=dec.fill_rule, shape_index=dec.shape_index, samples=cfg.samples, composite="over" if solved else "soft",
        supersample=supersample, coarse=pyramid,
    )
    return pyramid_l2(renders, target, weight=weight), kl_divergence(mu, logvar), dec, mu
