"""``VectorImage`` <-> renderer tensors, and our differentiable rasterizer on a ``VectorImage``.

Tensors use the normalised frame of shared/STYLE.md (``(x / W, y / H)`` of the canvas);
``VectorImage`` uses the canvas's pixel frame.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch

from ..errors import InputError
from ..raster import composite_over, render_coverage
from ..raster.bezier import flatten_closed, polygon_area, subdivide_to
from .image import VectorImage, VectorShape

MAX_RENDER_PIXELS = 16_000_000  # the render of one SVG; its tensors take a few hundred bytes a pixel


def from_tensors(
    points: torch.Tensor | Sequence[torch.Tensor],
    colors: torch.Tensor,
    *,
    size: tuple[float, float],
    shape_index: Sequence[int] | torch.Tensor | None = None,
    depth: torch.Tensor | None = None,
    fill_rule: str = "nonzero",
    min_area: float = 0.0,
) -> VectorImage:
    """One image's tensors -> ``VectorImage`` in a ``(height, width)`` pixel frame.

    Args:
        points: ``(P, 3S, 2)`` normalised frame, or a list of ``(3S_i, 2)`` (paths of different lengths).
        colors: ``(G, 3)``.
        size: ``(height, width)`` of the output canvas (the viewBox).
        shape_index: ``(P,)`` path -> shape; ``None``: each path its own shape.
        depth: ``(G,)``, larger in front; shapes are written back to front.
        min_area: contours whose flattened area is below this (pixels^2) are dropped.
    """
    h, w = size
    scale = torch.tensor([w, h], dtype=torch.float64)
    pts = [c.detach().double().cpu() * scale for c in points]  # P x (3S_i, 2) px
    p = len(pts)
    sidx = list(range(p)) if shape_index is None else [int(v) for v in torch.as_tensor(shape_index).tolist()]
    g = colors.shape[0]
    order = list(range(g)) if depth is None else torch.argsort(depth.detach().cpu()).tolist()
    if len({len(c) for c in pts}) == 1:  # one batched call when all paths have the same length
        areas = polygon_area(flatten_closed(torch.stack(pts), 8)).abs().tolist()
    else:
        areas = [float(polygon_area(flatten_closed(c[None], 8)).abs()) for c in pts]
    shapes = []
    for gi in order:
        cs = [pts[i].numpy() for i in range(p) if sidx[i] == gi and areas[i] >= min_area]
        if cs:
            shapes.append(VectorShape(cs, tuple(float(c) for c in colors[gi].tolist()), fill_rule))
    return VectorImage(float(w), float(h), shapes)


def to_tensors(image: VectorImage, segments: int | None = None) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """``VectorImage`` -> ``points (P, 3S, 2)`` normalised, ``colors (G, 3)``, ``shape_index (P,)``.

    Contours with fewer segments are subdivided (shape unchanged) to the common ``S``:
    ``segments``, or the largest count present.
    """
    contours, sidx, colors = [], [], []
    for gi, shape in enumerate(image.shapes):
        colors.append(shape.color)
        for c in shape.contours:
            contours.append(torch.as_tensor(c, dtype=torch.float64))
            sidx.append(gi)
    if not contours:
        raise InputError("the SVG has no closed path")
    s = segments or max(len(c) // 3 for c in contours)
    pts = torch.stack([subdivide_to(c, s) for c in contours])  # (P, 3S, 2) px
    pts = pts / torch.tensor([image.width, image.height], dtype=torch.float64)
    return pts, torch.tensor(colors, dtype=torch.float64), torch.tensor(sidx, dtype=torch.long)


def render_vector(image: VectorImage, *, scale: float = 1.0, tau: float = 0.15, samples: int = 16) -> torch.Tensor:
    """Render a ``VectorImage`` with im2vec's rasterizer (shapes back to front, each with its own fill rule).

    Outputs over ``MAX_RENDER_PIXELS`` are refused (``InputError``) before anything is allocated.

    Returns:
        ``(3, H, W)`` with ``H, W = round(height * scale), round(width * scale)``.
    """
    if not (math.isfinite(scale) and scale > 0 and math.isfinite(tau) and tau > 0):
        raise ValueError(f"scale and tau must be finite and > 0, got {scale}, {tau}")
    h, w = max(1, round(image.height * scale)), max(1, round(image.width * scale))
    if h * w > MAX_RENDER_PIXELS:
        raise InputError(f"render of {w}x{h} pixels refused (at most {MAX_RENDER_PIXELS // 1_000_000} megapixels; "
                         "lower --scale)")
    if not image.shapes:
        return torch.ones(3, h, w)
    pts, cols, sidx = to_tensors(image)
    pts, cols = pts.float(), cols.float()
    layers = []
    for g, shape in enumerate(image.shapes):
        sel = sidx == g
        cov = render_coverage(
            pts[sel][None], size=(h, w), tau=tau, fill_rule=shape.fill_rule,
            shape_index=torch.zeros(int(sel.sum()), dtype=torch.long), samples=samples,
        )
        layers.append(cov)
    cov = torch.cat(layers, 1)  # (1, G, H, W)
    depth = torch.arange(cov.shape[1], dtype=cov.dtype)[None]
    return composite_over(cov, cols[None], depth)[0]
