"""Flattening closed cubic Bezier paths into closed polylines.

Layout (shared/STYLE.md): ``points (..., 3S, 2)`` holds S cubic segments in diffvg's
wrap-around order ``anchor, control, control, anchor, ...``; segment ``s`` uses points
``3s, 3s+1, 3s+2`` and ``(3s+3) mod 3S``, so the last segment ends at point 0.
"""

from __future__ import annotations

import functools

import torch

from .curves import cubic_at, line_controls

__all__ = ["bernstein_weights", "cubic_at", "flatten_closed", "line_controls", "polygon_area", "restrict",
           "segment_controls", "split_segment", "subdivide_to"]


def bernstein_weights(samples: int, *, dtype: torch.dtype, device: torch.device) -> torch.Tensor:
    """Cubic Bernstein weights at ``t = i / samples`` for ``i = 0 .. samples-1``.

    Returns:
        ``(samples, 4)`` weights (shared: do not modify); the end point ``t = 1`` is the next
        segment's start.
    """
    return _bernstein(samples, dtype, torch.device(device))


@functools.lru_cache(maxsize=64)
def _bernstein(samples: int, dtype: torch.dtype, device: torch.device) -> torch.Tensor:
    t = torch.arange(samples, dtype=dtype, device=device) / samples
    basis = torch.eye(4, dtype=dtype, device=device)[..., None].expand(4, 4, 2)  # weight k: control k alone
    return cubic_at(basis, t)[..., 0].T  # (samples, 4)


def segment_controls(points: torch.Tensor) -> torch.Tensor:
    """Group a closed path's points into per-segment control quadruples.

    Args:
        points: ``(..., 3S, 2)``.

    Returns:
        ``(..., S, 4, 2)``: ``[p0, p1, p2, p3]`` of each segment.
    """
    if points.shape[-1] != 2 or points.shape[-2] % 3 != 0 or points.shape[-2] == 0:
        raise ValueError(f"points must be (..., 3S, 2) with S >= 1, got {tuple(points.shape)}")
    s = points.shape[-2] // 3
    seg = points.unflatten(-2, (s, 3))  # (..., S, 3, 2)
    nxt = torch.roll(seg[..., 0, :], shifts=-1, dims=-2)  # (..., S, 2): next anchor
    return torch.cat([seg, nxt.unsqueeze(-2)], dim=-2)  # (..., S, 4, 2)


def flatten_closed(points: torch.Tensor, samples: int) -> torch.Tensor:
    """Sample each cubic segment ``samples`` times, giving the vertices of a closed polyline.

    The map is linear in the control points, so gradients pass through it exactly.

    Args:
        points: ``(..., 3S, 2)`` closed cubic path.
        samples: line segments per cubic segment (>= 1).

    Returns:
        ``(..., S * samples, 2)`` polyline vertices; edge ``i`` joins vertex ``i`` to ``i+1``
        and the last vertex joins vertex 0.
    """
    if samples < 1:
        raise ValueError(f"samples must be >= 1, got {samples}")
    ctrl = segment_controls(points)  # (..., S, 4, 2)
    w = bernstein_weights(samples, dtype=points.dtype, device=points.device)  # (L, 4)
    verts = torch.einsum("lk,...skc->...slc", w, ctrl)  # (..., S, L, 2)
    return verts.flatten(-3, -2)  # (..., S*L, 2)


def split_segment(ctrl: torch.Tensor, t: float = 0.5) -> tuple[torch.Tensor, torch.Tensor]:
    """de Casteljau split of cubic segments at ``t``.

    Args:
        ctrl: ``(..., 4, 2)``.

    Returns:
        two ``(..., 4, 2)`` halves that trace the same curve.
    """
    p0, p1, p2, p3 = ctrl.unbind(-2)
    p01, p12, p23 = torch.lerp(p0, p1, t), torch.lerp(p1, p2, t), torch.lerp(p2, p3, t)
    p012, p123 = torch.lerp(p01, p12, t), torch.lerp(p12, p23, t)
    mid = torch.lerp(p012, p123, t)
    return torch.stack([p0, p01, p012, mid], -2), torch.stack([mid, p123, p23, p3], -2)


def subdivide_to(points: torch.Tensor, segments: int) -> torch.Tensor:
    """Resample one closed path to exactly ``segments`` segments without changing its shape.

    Splits the longest segment (by control polygon length) until the count is reached.

    Args:
        points: ``(3S, 2)`` with ``S <= segments``.

    Returns:
        ``(3 * segments, 2)``.
    """
    if points.dim() != 2:
        raise ValueError(f"points must be (3S, 2), got {tuple(points.shape)}")
    segs = list(segment_controls(points).unbind(0))  # S x (4, 2)
    if len(segs) > segments:
        raise ValueError(f"path has {len(segs)} segments, more than the {segments} asked for")
    while len(segs) < segments:
        lengths = [float((s[1:] - s[:-1]).norm(dim=-1).sum()) for s in segs]
        i = max(range(len(segs)), key=lengths.__getitem__)
        left, right = split_segment(segs[i])
        segs[i : i + 1] = [left, right]
    return torch.cat([s[:3] for s in segs], 0)


def restrict(ctrl: torch.Tensor, t0: torch.Tensor, t1: torch.Tensor) -> torch.Tensor:
    """The pieces of cubic segments over ``[t0, t1]``, exactly (blossoming: the piece's control
    points are the blossom values ``f(t0,t0,t0), f(t0,t0,t1), f(t0,t1,t1), f(t1,t1,t1)``).

    Args:
        ctrl: ``(N, 4, 2)``; t0, t1: ``(N,)``.

    Returns:
        ``(N, 4, 2)``.
    """
    def blossom(u1, u2, u3):  # de Casteljau with one parameter per level (symmetric in them)
        q = ctrl
        for u in (u1, u2, u3):
            q = torch.lerp(q[:, :-1], q[:, 1:], u.view(-1, 1, 1).to(q.dtype))
        return q[:, 0]  # (N, 2)

    return torch.stack([blossom(t0, t0, t0), blossom(t0, t0, t1), blossom(t0, t1, t1), blossom(t1, t1, t1)], 1)


def polygon_area(verts: torch.Tensor) -> torch.Tensor:
    """Signed shoelace area of closed polylines. ``verts (..., V, 2)`` -> ``(...)``."""
    x, y = verts[..., 0], verts[..., 1]
    return 0.5 * (x * torch.roll(y, -1, -1) - torch.roll(x, -1, -1) * y).sum(-1)
