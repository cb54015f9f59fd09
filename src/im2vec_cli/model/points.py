"""The point pass: a render-and-compare correction of each path's outline where it lies.

The latent and path passes (``encoder.Feedback``, ``encoder.PathPass``) see the picture through
convolutions down to 4x4 and correct a code: they place a path, but not its edge to the pixel.
This pass looks along the outline itself, as Deep Snake (Peng et al., CVPR 2020) does for
polygons: at three points of each cubic segment (t = 0, 1/3, 2/3) it samples the picture, the
render of the current paths and their difference on a short line across the curve, a circular
1-D convolution over the outline (like the path decoder's) turns those profiles into a move of
each point across and along the curve, and the segment's control points are solved to pass
through the moved points. With ``smooth = n`` the moves are first low-passed along the outline
(n circular [1, 2, 1] / 4 filters): on blurred grey pictures (MNIST's scans) a pass free to move
each point alone learns sub-pixel wiggles that draw the grey edge, which no designer keeps. The
moves are bounded (``MAX_MOVE`` px a pass) and the last layer
starts at zero, so a model given the pass (``ModelConfig.point_passes``, grown by ``train --init``)
draws what it drew before.

Frames: points ``(N, 3k, 2)`` in the normalised frame (``raster``: x right, y down, [0, 1]
the canvas), row ``3s + j`` of a path being segment ``s``'s anchor (j = 0) or its two controls.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from .decoder import _circular_stack

OFFSETS = (-3.0, -2.0, -1.0, 0.0, 1.0, 2.0, 3.0)  # px across the curve where the profiles are read
MAX_MOVE = 3.0  # px: the furthest one pass moves a point across or along the curve


def curve_samples(points: torch.Tensor) -> torch.Tensor:
    """Control points ``(N, 3k, 2)`` of closed cubic paths -> the points at t = 0, 1/3, 2/3 of
    each segment ``(N, 3k, 2)``, in the same rows (``from_samples`` inverts it)."""
    p0, c1, c2 = points[:, 0::3], points[:, 1::3], points[:, 2::3]  # (N, k, 2) each
    p3 = p0.roll(-1, 1)
    q1 = (8 * p0 + 12 * c1 + 6 * c2 + p3) / 27
    q2 = (p0 + 6 * c1 + 12 * c2 + 8 * p3) / 27
    return torch.stack([p0, q1, q2], 2).flatten(1, 2)


def from_samples(samples: torch.Tensor) -> torch.Tensor:
    """The inverse of ``curve_samples``: the control points of the closed cubic paths through
    the points ``(N, 3k, 2)`` at t = 0, 1/3, 2/3 of each segment. Both are linear maps."""
    p0, q1, q2 = samples[:, 0::3], samples[:, 1::3], samples[:, 2::3]
    p3 = p0.roll(-1, 1)
    r1 = 27 * q1 - 8 * p0 - p3  # = 12 c1 + 6 c2
    r2 = 27 * q2 - p0 - 8 * p3  # = 6 c1 + 12 c2
    return torch.stack([p0, (2 * r1 - r2) / 18, (2 * r2 - r1) / 18], 2).flatten(1, 2)


class PointPass(nn.Module):
    """One pass on paths ``(N, 3k, 2)`` of pictures ``x`` and their renders ``seen (B, C, S, S)``,
    path ``n`` being of picture ``rows[n]``; any k (the convolution is circular, like the
    path decoder's)."""

    def __init__(self, channels: int, width: int = 64, layers: int = 4, smooth: int = 0):
        super().__init__()
        self.smooth = smooth
        self.net = _circular_stack(3 * channels * len(OFFSETS) + 3, width, layers, 2)
        nn.init.zeros_(self.net[-1].weight)
        nn.init.zeros_(self.net[-1].bias)

    def forward(self, x: torch.Tensor, seen: torch.Tensor, points: torch.Tensor, rows: torch.Tensor) -> torch.Tensor:
        n, m, _ = points.shape
        size = x.shape[-1]
        pic = torch.cat([2 * x - 1, 2 * seen - 1, x - seen], 1)[rows]  # (N, 3C, S, S)
        q = curve_samples(points)  # (N, 3k, 2)
        tangent = q.roll(-1, 1) - q.roll(1, 1)
        tangent = tangent / tangent.norm(dim=-1, keepdim=True).clamp_min(1e-6)
        normal = torch.stack([-tangent[..., 1], tangent[..., 0]], -1)  # (N, 3k, 2)
        across = q.new_tensor(OFFSETS) / size  # (D,)
        where = q[:, :, None] + across[:, None] * normal[:, :, None]  # (N, 3k, D, 2)
        profile = F.grid_sample(pic, 2 * where - 1, align_corners=False, padding_mode="border")  # (N, 3C, 3k, D)
        kind = torch.eye(3, dtype=q.dtype, device=q.device).repeat(1, m // 3)  # (3, 3k): t = 0, 1/3, 2/3
        feats = torch.cat([profile.permute(0, 1, 3, 2).flatten(1, 2), kind.expand(n, -1, -1)], 1)  # (N, 3C*D + 3, 3k)
        move = MAX_MOVE * torch.tanh(self.net(feats)) / size  # (N, 2, 3k): across, along
        for _ in range(self.smooth):
            move = (move.roll(1, -1) + 2 * move + move.roll(-1, -1)) / 4
        move = move.transpose(1, 2)  # (N, 3k, 2)
        shift = move[..., :1] * normal + move[..., 1:] * tangent
        return points + from_samples(shift)  # the control points move linearly with their samples
