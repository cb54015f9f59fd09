"""The differentiable renderer: closed cubic paths -> soft coverage -> composited image.

Input frame (shared/STYLE.md): ``points (B, P, 3S, 2)`` in normalised ``(x, y)`` in [0, 1],
y down; pixel ``(i, j)`` has its centre at ``((j + 0.5) / W, (i + 0.5) / H)``. Internally
the points are scaled to the pixel frame, where ``tau`` and ``radius`` are measured.

Shapes: ``shape_index (P,)`` maps each path to a shape ``0 .. G-1``. A shape's winding
number is the sum over its paths and its distance the minimum, so a glyph ``o`` made of
two contours under ``"evenodd"`` has a true hole. ``None`` makes every path its own shape.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import torch
from torch import nn

from ..config import PYRAMID_MODES
from .bezier import flatten_closed
from .composite import composite_over, composite_soft
from .coverage import boundary_edges, nearest_distance, signed_coverage, soft_coverage, winding_number
from .pyramid import gaussian_pyramid, pyramid_sizes


def _size(size: int | Sequence[int]) -> tuple[int, int]:
    if isinstance(size, int):
        return size, size
    h, w = (int(s) for s in size)
    return h, w


def shape_index_tensor(shape_index, num_paths: int, device: torch.device) -> torch.Tensor | None:
    """Validate a path->shape map; returns a ``(P,)`` long tensor or ``None``."""
    if shape_index is None:
        return None
    idx = torch.as_tensor(shape_index, dtype=torch.long, device=device)
    if idx.shape != (num_paths,):
        raise ValueError(f"shape_index must have one entry per path ({num_paths}), got {tuple(idx.shape)}")
    if idx.numel() and idx.min() < 0:
        raise ValueError("shape_index entries must be >= 0")
    return idx


def render_coverage(
    points: torch.Tensor,
    *,
    size: int | Sequence[int],
    tau: float = 0.5,
    fill_rule: str = "nonzero",
    shape_index=None,
    samples: int = 4,
    radius: float | None = None,
) -> torch.Tensor:
    """Soft coverage of each shape.

    Args:
        points: ``(B, P, 3S, 2)`` closed cubic paths, normalised frame.
        size: ``H`` (square) or ``(H, W)``.
        tau: edge softness in pixels (``sigmoid(signed_distance / tau)``).
        fill_rule: ``"nonzero"`` or ``"evenodd"``.
        shape_index: optional ``(P,)`` path -> shape map (see module doc).
        samples: line segments per cubic when flattening.
        radius: distance clamp and culling radius in pixels; ``None`` means ``8 * tau``
            (coverage there is within 3e-4 of 0 or 1), ``math.inf`` disables culling.

    Returns:
        ``(B, G, H, W)`` coverage in [0, 1]; ``G = P`` without ``shape_index``.
    """
    if points.dim() != 4 or points.shape[-1] != 2 or points.shape[-2] % 3 != 0 or points.shape[-2] == 0:
        raise ValueError(f"points must be (B, P, 3S, 2), got {tuple(points.shape)}")
    if tau <= 0:
        raise ValueError(f"tau must be > 0 pixels, got {tau}")
    if fill_rule not in ("nonzero", "evenodd"):
        raise ValueError(f"fill_rule must be 'nonzero' or 'evenodd', got {fill_rule!r}")
    h, w = _size(size)
    p = points.shape[1]
    radius = 8.0 * tau if radius is None else float(radius)
    scale = torch.tensor([w, h], dtype=points.dtype, device=points.device)
    verts = flatten_closed(points * scale, samples)  # (B, P, E, 2) pixel frame
    sidx = shape_index_tensor(shape_index, p, points.device)
    active = boundary_edges(verts, sidx) if fill_rule == "nonzero" else None  # (B, P, E)
    ends = torch.roll(verts, shifts=-1, dims=2)  # each path closes on itself
    counts = torch.bincount(sidx) if sidx is not None else None
    if sidx is None or bool((counts == counts[0]).all()):
        return _coverage_equal_shapes(verts, ends, active, sidx, counts, (h, w), radius, tau, fill_rule)
    return _coverage_by_path(verts, ends, active, sidx, counts.numel(), (h, w), radius, tau, fill_rule)


def _coverage_equal_shapes(verts, ends, active, sidx, counts, size, radius, tau, fill_rule) -> torch.Tensor:
    """Shapes of equal size (one path each, or one shape of all paths): each shape is a single
    edge set, so winding and nearest edge are computed per shape directly. -> ``(B, G, H, W)``."""
    (b, p), (h, w) = verts.shape[:2], size
    g = p if sidx is None else counts.numel()
    order = torch.arange(p, device=verts.device) if sidx is None else torch.argsort(sidx, stable=True)
    a = verts[:, order].reshape(b * g, -1, 2)  # (B*G, (P/G)*E, 2)
    bb = ends[:, order].reshape(b * g, -1, 2)
    act = active[:, order].reshape(b * g, -1) if active is not None else None
    wind = winding_number(a, bb, h, w)
    cov = soft_coverage(a, bb, wind, h, w, radius=radius, tau=tau, fill_rule=fill_rule, active=act)
    return cov.view(b, g, h, w)


def _coverage_by_path(verts, ends, active, sidx, g, size, radius, tau, fill_rule) -> torch.Tensor:
    """Shapes of different sizes: winding and distance per path, then summed (winding) and
    minimised (distance) over each shape's paths. -> ``(B, G, H, W)``."""
    (b, p, e), (h, w) = verts.shape[:3], size
    a, bb = verts.reshape(b * p, e, 2), ends.reshape(b * p, e, 2)
    act = active.reshape(b * p, e) if active is not None else None
    wind = winding_number(a, bb, h, w).view(b, p, h, w)
    dist = nearest_distance(a, bb, h, w, radius=radius, active=act)[0].view(b, p, h, w)  # (B, P, H, W)
    wind = torch.zeros(b, g, h, w, dtype=wind.dtype, device=wind.device).index_add_(1, sidx, wind)
    member = torch.arange(g, device=verts.device).view(g, 1) == sidx.view(1, p)  # (G, P)
    inf = torch.tensor(math.inf, dtype=dist.dtype, device=dist.device)
    dist = torch.where(member.view(1, g, p, 1, 1), dist.unsqueeze(1), inf).min(dim=2).values  # (B, G, H, W)
    return signed_coverage(dist, wind, radius, tau, fill_rule)


def render_paths(
    points: torch.Tensor,
    colors: torch.Tensor,
    depth: torch.Tensor | None = None,
    *,
    size: int | Sequence[int],
    tau: float = 0.5,
    fill_rule: str = "nonzero",
    shape_index=None,
    samples: int = 4,
    radius: float | None = None,
    composite: str = "over",
    temperature: float = 0.1,
    background: float = 1.0,
) -> torch.Tensor:
    """Render closed cubic paths to an RGB image.

    Args:
        points: ``(B, P, 3S, 2)``, normalised frame.
        colors: ``(B, G, 3)`` fill per shape (``G = P`` without ``shape_index``).
        depth: ``(B, G)``, larger in front; ``None`` draws in index order.
        composite: ``"over"`` (exact, for final renders) or ``"soft"`` (differentiable in depth).
        temperature: softness of ``"soft"`` compositing.
        Other arguments as in ``render_coverage``.

    Returns:
        ``(B, 3, H, W)`` image in [0, 1] over a ``background`` grey.
    """
    cov = render_coverage(
        points, size=size, tau=tau, fill_rule=fill_rule, shape_index=shape_index, samples=samples, radius=radius
    )
    if depth is None:
        depth = torch.arange(cov.shape[1], dtype=cov.dtype, device=cov.device).expand(cov.shape[0], -1)
    if composite == "over":
        return composite_over(cov, colors, depth, background)
    if composite == "soft":
        return composite_soft(cov, colors, depth, temperature, background)
    raise ValueError(f"composite must be 'over' or 'soft', got {composite!r}")


def render_supersampled(
    points: torch.Tensor,
    colors: torch.Tensor,
    depth: torch.Tensor | None = None,
    *,
    size: int | Sequence[int],
    factor: int,
    **kwargs,
) -> torch.Tensor:
    """``render_paths`` at ``factor`` times ``size``, box-filtered down to ``(B, 3, H, W)``:
    each pixel is the mean of ``factor**2`` sub-pixels, like the antialiased render of the
    SVG (cairo). ``tau`` is in sub-pixels. Other arguments as in ``render_paths``."""
    if factor < 1:
        raise ValueError(f"factor must be >= 1, got {factor}")
    h, w = _size(size)
    img = render_paths(points, colors, depth, size=(h * factor, w * factor), **kwargs)
    return torch.nn.functional.avg_pool2d(img, factor) if factor > 1 else img


PYRAMID_COARSE = PYRAMID_MODES  # the values of render_pyramid's ``coarse`` (TrainConfig.pyramid)


def render_pyramid(
    points: torch.Tensor,
    colors: torch.Tensor,
    depth: torch.Tensor | None = None,
    *,
    size: int | Sequence[int],
    levels: int = 3,
    supersample: int = 1,
    coarse: str = "blur",
    **kwargs,
) -> list[torch.Tensor]:
    """The render's pyramid (finest first), to compare with ``gaussian_pyramid`` of a target.

    The finest level is ``render_supersampled`` (``tau`` in its sub-pixels when
    ``supersample > 1``). ``coarse`` picks the coarser levels:

    - ``"blur"``: ``gaussian_pyramid`` of the finest render, built exactly as the target's
      pyramid is, so a render equal to the target scores zero at every level;
    - ``"render"``: the paths rendered again at each level's size (``tau`` in that level's
      pixels). These sharp renders never match the blurred target levels (on MNIST digits
      they add about 3x the finest level's error), which biases the fit; kept to reproduce
      models trained before the ``pyramid`` option of ``TrainConfig``.

    Keyword arguments as in ``render_paths``.
    """
    sizes = pyramid_sizes(_size(size), levels)
    finest = render_supersampled(points, colors, depth, size=sizes[0], factor=supersample, **kwargs)
    if coarse == "blur":
        return gaussian_pyramid(finest, levels)
    if coarse == "render":
        return [finest] + [render_paths(points, colors, depth, size=s, **kwargs) for s in sizes[1:]]
    raise ValueError(f"coarse must be one of {PYRAMID_COARSE}, got {coarse!r}")


@dataclass(frozen=True)
class RasterSettings:
    """Hyper-parameters of the renderer (see ``render_paths``)."""

    tau: float = 0.5
    fill_rule: str = "nonzero"
    samples: int = 4
    radius: float | None = None
    composite: str = "soft"
    temperature: float = 0.1
    background: float = 1.0


class Rasterizer(nn.Module):
    """Module wrapper of ``render_paths``; stores the settings, holds no state."""

    def __init__(self, size: int | Sequence[int], settings: RasterSettings = RasterSettings()):
        super().__init__()
        self.size = _size(size)
        self.settings = settings

    def forward(self, points, colors, depth=None, shape_index=None, tau: float | None = None):
        s = self.settings
        return render_paths(
            points, colors, depth, size=self.size, tau=s.tau if tau is None else tau, fill_rule=s.fill_rule,
            shape_index=shape_index, samples=s.samples, radius=s.radius, composite=s.composite,
            temperature=s.temperature, background=s.background,
        )
