"""The differentiable renderer: closed cubic paths -> soft coverage -> composited image.

Input frame (shared/STYLE.md): ``points (B, P, 3S, 2)`` in normalised ``(x, y)`` in [0, 1],
y down; pixel ``(i, j)`` has its centre at ``((j + 0.5) / W, (i + 0.5) / H)``. Internally
the points are scaled to the pixel frame, where ``tau`` and ``radius`` are measured.

Shapes: ``shape_index (P,)`` maps each path to a shape ``0 .. G-1``. A shape's winding
number is the sum over its paths and its distance the minimum, so a glyph ``o`` made of
two contours under ``"evenodd"`` has a true hole. ``None`` makes every path its own shape.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import torch
from torch import nn

from ..config import PYRAMID_MODES
from .bezier import flatten_closed
from .composite import composite_over, composite_soft
from .coverage import soft_coverage
from .pyramid import gaussian_pyramid, pyramid_sizes
from .winding import _FAR, boundary_edges, edge_boundary, winding_number


def _size(size: int | Sequence[int]) -> tuple[int, int]:
    if isinstance(size, int):
        return size, size
    h, w = (int(s) for s in size)
    return h, w


def shape_index_tensor(shape_index, num_paths: int, device: torch.device) -> torch.Tensor | None:
    """Validate a path->shape map, ``(P,)`` or per image ``(B, P)`` (-1: a padding path that
    belongs to no shape); returns a long tensor or ``None``."""
    if shape_index is None:
        return None
    idx = torch.as_tensor(shape_index, dtype=torch.long, device=device)
    if idx.dim() not in (1, 2) or idx.shape[-1] != num_paths:
        raise ValueError(f"shape_index must have one entry per path ({num_paths}), got {tuple(idx.shape)}")
    if idx.numel() and idx.min() < (-1 if idx.dim() == 2 else 0):
        raise ValueError("shape_index entries must be >= 0 (-1 for padding paths in a (B, P) map)")
    return idx


def render_coverage(
    points: torch.Tensor,
    *,
    size: int | Sequence[int],
    tau: float = 0.5,
    fill_rule: str = "nonzero",
    shape_index=None,
    counts: torch.Tensor | None = None,
    num_shapes: int | None = None,
    samples: int = 4,
    radius: float | None = None,
) -> torch.Tensor:
    """Soft coverage of each shape.

    Args:
        points: ``(B, P, 3S, 2)`` closed cubic paths, normalised frame.
        size: ``H`` (square) or ``(H, W)``.
        tau: edge softness in pixels (``sigmoid(signed_distance / tau)``).
        fill_rule: ``"nonzero"`` or ``"evenodd"``.
        shape_index: optional path -> shape map (see module doc): ``(P,)`` for every image, or
            ``(B, P)`` per image, where -1 marks a padding path (drawn by no shape) and a shape
            with no path renders to exactly nothing (ragged batches of different images).
        counts: optional ``(B, P)`` segments of each path; the segments after them are padding,
            drawn by nothing (the last real segment ends at the first padding point, which must
            be the path's first anchor, as the decoder and refinement pad).
        num_shapes: ``G`` for a ``(B, P)`` map (default: its largest entry + 1).
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
    b, p = points.shape[:2]
    radius = 8.0 * tau if radius is None else float(radius)
    scale = torch.tensor([w, h], dtype=points.dtype, device=points.device)
    verts = flatten_closed(points * scale, samples)  # (B, P, E, 2) pixel frame
    sidx = shape_index_tensor(shape_index, p, points.device)
    each = torch.arange(p, device=points.device) if sidx is None else sidx  # no map: every path its own shape
    if counts is None and each.dim() == 1:
        sizes = torch.bincount(each)
        if bool((sizes == sizes[:1]).all()):  # one edge set per shape as it stands: no gather
            active = boundary_edges(verts, sidx) if fill_rule == "nonzero" else None  # (B, P, E)
            return _coverage_equal_shapes(verts, active, each, sizes.numel(), (h, w), radius, tau, fill_rule)
    sidx = each.expand(b, p)
    g = int(sidx.max()) + 1 if num_shapes is None else num_shapes
    e = verts.shape[2]  # real edges per path:
    n = torch.full((b, p), e, device=points.device) if counts is None else counts.to(points.device).expand(b, p) * samples
    return _coverage_rows(verts, sidx, n, g, (h, w), radius, tau, fill_rule)


def _coverage_equal_shapes(verts, active, sidx, g, size, radius, tau, fill_rule) -> torch.Tensor:
    """Shapes of equal size (one path each, or one shape of all paths): each shape is a single
    edge set, so winding and nearest edge are computed per shape directly. -> ``(B, G, H, W)``."""
    b, (h, w) = verts.shape[0], size
    ends = torch.roll(verts, shifts=-1, dims=2)  # each path closes on itself
    order = torch.argsort(sidx, stable=True)
    a = verts[:, order].reshape(b * g, -1, 2)  # (B*G, (P/G)*E, 2)
    bb = ends[:, order].reshape(b * g, -1, 2)
    act = active[:, order].reshape(b * g, -1) if active is not None else None
    wind = winding_number(a, bb, h, w)
    cov = soft_coverage(a, bb, wind, h, w, radius=radius, tau=tau, fill_rule=fill_rule, active=act)
    return cov.view(b, g, h, w)


def _coverage_rows(verts, sidx, n, g, size, radius, tau, fill_rule) -> torch.Tensor:
    """Shapes of any size: the edges of each (image, shape) gathered into one row, padded with
    an edge parked far away (never near a pixel, crossing no scanline). -> ``(B, G, H, W)``.

    Args:
        verts: ``(B, P, E, 2)`` pixel frame; sidx ``(B, P)`` (-1: padding path); n ``(B, P)``
            real edges of each path (its first ``n``; the ``n``-th vertex closes on vertex 0).
    """
    (b, p, e), (h, w) = verts.shape[:3], size
    dev = verts.device
    with torch.no_grad():
        k = torch.arange(e, device=dev)
        real = (k < n.unsqueeze(-1)) & (sidx >= 0).unsqueeze(-1)  # (B, P, E)
        first = (torch.arange(b * p, device=dev) * e).view(b, p, 1)
        start = (first + k).masked_select(real)  # flat vertex ids of the real edges, in path order
        end = torch.where(k + 1 < n.unsqueeze(-1), first + k + 1, first).masked_select(real)
        row = (torch.arange(b, device=dev).view(b, 1, 1) * g + sidx.unsqueeze(-1)).expand(b, p, e).masked_select(real)
        row, order = torch.sort(row, stable=True)
        length = torch.bincount(row, minlength=b * g)  # (B*G,)
        offset = torch.cumsum(length, 0) - length
        slot = torch.arange(row.numel(), device=dev) - offset[row]
        pad = b * p * e  # the parked vertex
        width_ = max(1, int(length.max()) if length.numel() else 1)
        ia = torch.full((b * g, width_), pad, dtype=torch.long, device=dev)
        ib = ia.clone()
        ia[row, slot], ib[row, slot] = start[order], end[order]
    far = torch.full((1, 2), _FAR, dtype=verts.dtype, device=dev)
    table = torch.cat([verts.reshape(-1, 2), far])
    a = table.index_select(0, ia.view(-1)).view(*ia.shape, 2)  # (B*G, L, 2); index_select's backward is an
    bb = table.index_select(0, ib.view(-1)).view(*ib.shape, 2)  # index_add, where a[ia]'s sorts the indices
    act = edge_boundary(a, bb) if fill_rule == "nonzero" else None
    wind = winding_number(a, bb, h, w)
    cov = soft_coverage(a, bb, wind, h, w, radius=radius, tau=tau, fill_rule=fill_rule, active=act)
    drawn = (length > 0).to(cov.dtype).view(b, g, 1, 1)  # a shape without paths renders to nothing
    return cov.view(b, g, h, w) * drawn


def render_paths(
    points: torch.Tensor,
    colors: torch.Tensor,
    depth: torch.Tensor | None = None,
    *,
    size: int | Sequence[int],
    tau: float = 0.5,
    fill_rule: str = "nonzero",
    shape_index=None,
    counts: torch.Tensor | None = None,
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
    cov = render_coverage(points, size=size, tau=tau, fill_rule=fill_rule, shape_index=shape_index, counts=counts,
                          num_shapes=colors.shape[1], samples=samples, radius=radius)
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
