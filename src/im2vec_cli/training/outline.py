"""An auxiliary loss against the traced outlines of the training images (issue 37, item 2).

The renderer's gradient reaches a path only through the pixels its edge crosses: a part of
the picture (a hole, a separate piece) that no path comes near pulls no path towards it, and
the encoder's guess keeps missing it. A phase with ``TrainConfig.outline > 0`` adds a
long-range pull:

1. ``trace_targets``: before the first step, every training image is traced (``trace.regions.trace``,
   the regions ``vectorize`` starts from: level sets of the picture itself) and its rings are
   resampled to ``OUTLINE_POINTS`` points by arc length, each ring at least ``MIN_PER_RING``
   (the canvas border is not an outline);
2. each step adds ``outline`` times ``outline_loss``: the mean squared distance of each of
   those points to the nearest point sampled on the decoded paths, in square pixels of the
   model square. One-sided on purpose: the paths' own boundaries may run inside the picture's
   ink, where they overlap (the overlap is what keeps a union of parts free of cracks), so
   they are not pulled onto the outline; only every stretch of outline wants a path near it.

The targets are derived from the rasters alone: still no vector supervision.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch

from ..errors import TraceError
from ..raster.bezier import flatten_closed
from ..trace.fit import resample
from ..trace.regions import trace

OUTLINE_POINTS = 256  # points per picture's outline (M)
MIN_PER_RING = 6  # points each ring gets at least (a small hole still pulls)
CURVE_SAMPLES = 4  # points sampled on each decoded cubic segment

__all__ = ["OUTLINE_POINTS", "Outlines", "outline_distances", "outline_loss", "outline_points", "trace_targets"]


@dataclass
class Outlines:
    """Outline points ``points (N, M, 2)`` (model frame, [0, 1]) of the training images and
    ``valid (N,)``: whether the picture has an outline (a blank one has none)."""

    points: torch.Tensor
    valid: torch.Tensor

    def loss(self, paths: torch.Tensor, index: torch.Tensor, size: int) -> torch.Tensor:
        """``outline_loss`` of decoded ``paths (B, P, 3S, 2)`` against the outlines of training rows ``index (B,)``."""
        i = index.to(self.points.device)
        return outline_loss(paths, self.points[i], self.valid[i], size)


def _ring_lengths(rings: list[np.ndarray]) -> np.ndarray:
    return np.array([np.linalg.norm(r - np.roll(r, -1, axis=0), axis=1).sum() for r in rings])


def _shares(lengths: np.ndarray, total: int) -> np.ndarray:
    """Points per ring: ``MIN_PER_RING`` each, the rest by length; exactly ``total`` in all."""
    n = np.full(len(lengths), MIN_PER_RING)
    n += np.floor((total - n.sum()) * lengths / lengths.sum()).astype(int)
    n[np.argmax(lengths)] += total - n.sum()
    return n


def outline_points(image: np.ndarray, total: int = OUTLINE_POINTS) -> np.ndarray | None:
    """``total`` points ``(M, 2)`` on the traced outlines of ``image (S, S, 3)`` in [0, 1],
    in the model frame ([0, 1], y down); ``None`` when the picture has no outline."""
    if image.ndim != 3 or image.shape[2] != 3:
        raise ValueError(f"image must be (H, W, 3), got {image.shape}")
    h, w = image.shape[:2]
    try:
        regions = trace(image)
    except TraceError:  # too many pieces to trace: no target, the pyramid loss alone
        return None
    border = np.array([w, h], dtype=np.float64)
    rings = [r for reg in regions for r in reg.polygons  # not the rings that run along the canvas border
             if not np.any((r <= 1e-6) | (r >= border - 1e-6), axis=1).all()]
    lengths = _ring_lengths(rings) if rings else np.zeros(0)
    keep = np.argsort(-lengths, kind="stable")[: total // MIN_PER_RING]
    keep = keep[lengths[keep] > 0]
    if len(keep) == 0:
        return None
    n = _shares(lengths[keep], total)
    pts = np.concatenate([resample(rings[i], count=k) for i, k in zip(keep, n)])  # (M, 2) pixel frame
    return pts / border


def trace_targets(train_x: torch.Tensor, on_progress: Callable[[int, int], None] | None = None) -> Outlines:
    """``Outlines`` of every training image (uint8 ``(N, 3, S, S)``)."""
    n = len(train_x)
    points, valid = torch.zeros(n, OUTLINE_POINTS, 2), torch.zeros(n, dtype=torch.bool)
    for i in range(n):
        pts = outline_points(train_x[i].permute(1, 2, 0).numpy() / 255.0)  # (S, S, 3)
        if pts is not None:
            points[i], valid[i] = torch.from_numpy(pts).float(), True
        if on_progress is not None and ((i + 1) % 1024 == 0 or i + 1 == n):
            on_progress(i + 1, n)
    return Outlines(points, valid)


def _take(points: torch.Tensor, index: torch.Tensor) -> torch.Tensor:
    """``points (B, N, 2)`` at ``index (B, K)`` -> ``(B, K, 2)``."""
    return points.gather(1, index.unsqueeze(-1).expand(-1, -1, 2))


def outline_distances(points: torch.Tensor, target: torch.Tensor, size: int) -> torch.Tensor:
    """Squared distance of each outline point to the nearest point sampled on the paths.

    Args:
        points: ``(B, P, 3S, 2)`` decoded paths, model frame.
        target: ``(B, M, 2)`` outline points, model frame.
        size: the model square's side in pixels (``S``), the unit of the result.

    Returns:
        ``(B, M)`` square pixels, differentiable in ``points``.
    """
    if points.ndim != 4 or target.ndim != 3 or target.shape[0] != points.shape[0]:
        raise ValueError(f"points must be (B, P, 3S, 2) and target (B, M, 2), got {tuple(points.shape)}, "
                         f"{tuple(target.shape)}")
    curve = flatten_closed(points, CURVE_SAMPLES).flatten(1, 2) * size  # (B, Q, 2) pixels
    goal = target.to(curve) * size  # (B, M, 2)
    with torch.no_grad():  # which point is nearest; the distances to it are taken exactly below
        near = torch.cdist(goal, curve).argmin(dim=2)  # (B, M): each outline point's nearest path point
    return (goal - _take(curve, near)).square().sum(-1)


def outline_loss(points: torch.Tensor, target: torch.Tensor, valid: torch.Tensor, size: int) -> torch.Tensor:
    """How far the traced outlines are from the decoded paths (one-sided Chamfer), square pixels.

    Args:
        points, target, size: as ``outline_distances``.
        valid: ``(B,)`` pictures that have an outline (the others count for nothing).

    Returns:
        A scalar: the mean over valid pictures of the mean squared distance of each outline
        point to the nearest point sampled on the paths.
    """
    per = outline_distances(points, target, size).mean(1)  # (B,)
    w = valid.to(per)
    return (per * w).sum() / w.sum().clamp(min=1)
