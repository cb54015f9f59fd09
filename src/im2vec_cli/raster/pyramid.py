"""Gaussian pyramid and the multi-resolution L2 of Im2Vec (sec. 3.4, eq. 1)."""

from __future__ import annotations

from collections.abc import Sequence

import torch
import torch.nn.functional as F

_BINOMIAL = (1.0, 4.0, 6.0, 4.0, 1.0)


def pyramid_sizes(size: tuple[int, int], levels: int) -> list[tuple[int, int]]:
    """``(H, W)`` of each level; level 0 is ``size`` and each level halves (rounding up)."""
    if levels < 1:
        raise ValueError(f"levels must be >= 1, got {levels}")
    h, w = size
    out = []
    for _ in range(levels):
        out.append((h, w))
        h, w = max(1, -(-h // 2)), max(1, -(-w // 2))
    return out


def pyr_down(img: torch.Tensor) -> torch.Tensor:
    """Blur with a 5-tap binomial kernel (replicate border) and halve H and W.

    Args:
        img: ``(B, C, H, W)``.

    Returns:
        ``(B, C, ceil(H/2), ceil(W/2))``.
    """
    if img.dim() != 4:
        raise ValueError(f"img must be (B, C, H, W), got {tuple(img.shape)}")
    k = torch.tensor(_BINOMIAL, dtype=img.dtype, device=img.device)
    k = k / k.sum()
    c = img.shape[1]
    x = F.pad(img, (2, 2, 2, 2), mode="replicate")
    x = F.conv2d(x, k.view(1, 1, 1, 5).expand(c, 1, 1, 5), groups=c)
    x = F.conv2d(x, k.view(1, 1, 5, 1).expand(c, 1, 5, 1), groups=c)
    return x[:, :, ::2, ::2]


def gaussian_pyramid(img: torch.Tensor, levels: int) -> list[torch.Tensor]:
    """``levels`` images, finest first: ``[img, down(img), down(down(img)), ...]``."""
    out = [img]
    for _ in range(levels - 1):
        out.append(pyr_down(out[-1]))
    return out


def detail_weights(img: torch.Tensor, strength: float) -> torch.Tensor:
    """Per-pixel weights of the finest loss level that favour a picture's fine detail.

    A pixel's contrast is its colour's distance (L1 over channels) from the mean of its 3x3
    neighbourhood (replicate border); its detail is the largest contrast in its 3x3
    neighbourhood, so a small part (an eye, a mouth) is covered whole, an edge by a band 3 px
    wide, and flat regions are zero. The weight is ``(1 + strength * detail / mean detail) / (1 + strength)``,
    so the weights of each picture average 1; a flat picture (no detail) weighs 1 everywhere.

    Args:
        img: ``(B, C, H, W)``, the target.
        strength: ``>= 0``; 0 weighs every pixel 1.

    Returns:
        ``(B, 1, H, W)``.
    """
    if img.dim() != 4:
        raise ValueError(f"img must be (B, C, H, W), got {tuple(img.shape)}")
    if not strength >= 0:
        raise ValueError(f"strength must be >= 0, got {strength}")
    local = F.avg_pool2d(F.pad(img, (1, 1, 1, 1), mode="replicate"), 3, stride=1)  # (B, C, H, W)
    contrast = (img - local).abs().sum(1, keepdim=True)  # (B, 1, H, W)
    detail = F.max_pool2d(contrast, 3, stride=1, padding=1)  # (B, 1, H, W)
    mean = detail.mean((1, 2, 3), keepdim=True)  # (B, 1, 1, 1)
    w = (1 + strength * detail / mean.clamp_min(1e-6)) / (1 + strength)
    return torch.where(mean <= 1e-6, torch.ones_like(w), w)  # a flat picture weighs 1


def pyramid_l2(
    renders: Sequence[torch.Tensor], targets: Sequence[torch.Tensor], reduction: str = "mean",
    weight: torch.Tensor | None = None,
) -> torch.Tensor:
    """Sum over levels of the per-level mean squared error (eq. 1).

    Args:
        renders, targets: same-length sequences of ``(B, C, H_l, W_l)``.
        reduction: ``"mean"`` over the batch, or ``"none"`` for ``(B,)``.
        weight: ``(B, 1, H_0, W_0)`` per-pixel weights of the finest level (``detail_weights``);
            the coarser levels weigh every pixel alike.
    """
    if len(renders) != len(targets):
        raise ValueError(f"got {len(renders)} render levels and {len(targets)} target levels")
    if weight is not None and (weight.dim() != 4 or weight.shape[1] != 1 or weight.shape[2:] != targets[0].shape[2:]):
        raise ValueError(f"weight must be (B, 1, H_0, W_0) of the finest level, got {tuple(weight.shape)}")
    total = 0
    for i, (r, t) in enumerate(zip(renders, targets)):
        if r.shape != t.shape:
            raise ValueError(f"render level {tuple(r.shape)} != target level {tuple(t.shape)}")
        err = (r - t) ** 2
        total = total + (err if i or weight is None else err * weight).flatten(1).mean(1)
    return total.mean() if reduction == "mean" else total
