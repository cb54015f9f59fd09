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


def pyramid_l2(
    renders: Sequence[torch.Tensor], targets: Sequence[torch.Tensor], reduction: str = "mean"
) -> torch.Tensor:
    """Sum over levels of the per-level mean squared error (eq. 1).

    Args:
        renders, targets: same-length sequences of ``(B, C, H_l, W_l)``.
        reduction: ``"mean"`` over the batch, or ``"none"`` for ``(B,)``.
    """
    if len(renders) != len(targets):
        raise ValueError(f"got {len(renders)} render levels and {len(targets)} target levels")
    total = 0
    for r, t in zip(renders, targets):
        if r.shape != t.shape:
            raise ValueError(f"render level {tuple(r.shape)} != target level {tuple(t.shape)}")
        total = total + ((r - t) ** 2).flatten(1).mean(1)
    return total.mean() if reduction == "mean" else total
