"""``VectorImage`` <-> renderer tensors, and our differentiable rasterizer on a ``VectorImage``.

Tensors use the normalised frame of shared/STYLE.md (``(x / W, y / H)`` of the canvas);
``VectorImage`` uses the canvas's pixel frame.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence

import numpy as np
import torch

from ..errors import InputError
from ..raster import compiling, render_coverage
from ..raster.bezier import flatten_closed, polygon_area, restrict, segment_controls, subdivide_to
from .image import VectorImage, VectorShape

MAX_RENDER_PIXELS = 16_000_000  # the render of one SVG; its tensors take a few hundred bytes a pixel
RENDER_PIECE_PX = 32.0  # longest cubic piece (control polygon, output px) the renderer flattens
MAX_RENDER_EDGES = 4_000_000  # flattened edges of one render (about a second each 100,000 on 2 cores)
RENDER_CHUNK = 4_000_000  # coverage pixels (shapes x H x W), and padded segments and edges, drawn at once
SNAP = 1e-3  # coverage this near 0 or 1 is drawn as 0 or 1 (the radius clamp leaves 3e-4)
RENDER_SAMPLES = 16  # render_vector's default lines per cubic piece


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


def picture_array(image: torch.Tensor) -> np.ndarray:
    """A picture ``(3, H, W)`` tensor as the trace reads it: ``(H, W, 3)`` float64 NumPy on the CPU."""
    return image.detach().permute(1, 2, 0).double().cpu().numpy()


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


def render_vector(image: VectorImage, *, scale: float = 1.0, tau: float = 0.15, samples: int = RENDER_SAMPLES
                  ) -> torch.Tensor:
    """Render a ``VectorImage`` with im2vec's rasterizer (shapes back to front, each with its own fill rule).

    Contours stay ragged (each padded only within its chunk of shapes, with ``counts``), and
    every cubic is cut into pieces of at most ``RENDER_PIECE_PX`` before it is flattened, so
    that a long edge is never a candidate for far-away pixels. Chunks of shapes are drawn
    and composited in turn, within ``RENDER_CHUNK``. Outputs over ``MAX_RENDER_PIXELS`` and
    drawings over ``MAX_RENDER_EDGES`` flattened edges are refused (``InputError``) before
    anything is drawn.

    Returns:
        ``(3, H, W)`` with ``H, W = round(height * scale), round(width * scale)``.
    """
    if not (math.isfinite(scale) and scale > 0 and math.isfinite(tau) and tau > 0):
        raise ValueError(f"scale and tau must be finite and > 0, got {scale}, {tau}")
    h, w = max(1, round(image.height * scale)), max(1, round(image.width * scale))
    if h * w > MAX_RENDER_PIXELS:
        raise InputError(f"render of {w}x{h} pixels refused (at most {MAX_RENDER_PIXELS // 1_000_000} megapixels; "
                         "lower --scale)")
    out = torch.ones(3, h, w)
    contours, sidx = _pieces(image, (w / max(image.width, 1e-9), h / max(image.height, 1e-9)), samples)
    margin = 8 * tau + 1  # coverage beyond it is within 3e-4 of 0 (render_coverage's radius)
    with torch.no_grad(), compiling(False):  # one picture: a compile costs more than it saves
        for first, last, (x0, y0, x1, y1) in _chunks(image, contours, sidx, (h, w), margin, samples):
            sel = range(bisect.bisect_left(sidx, first), bisect.bisect_left(sidx, last))  # sidx is sorted
            smax = max(len(contours[i]) // 3 for i in sel)
            pts = torch.stack([torch.cat([contours[i], contours[i][:1].expand(3 * smax - len(contours[i]), 2)])
                               for i in sel])  # (P, 3Smax, 2) px, padded with each path's first anchor
            pts = (pts - torch.tensor([x0, y0], dtype=pts.dtype)) / torch.tensor([x1 - x0, y1 - y0], dtype=pts.dtype)
            cov = render_coverage(pts[None].float(), size=(y1 - y0, x1 - x0), tau=tau,  # the chunk's box only
                                  fill_rule=image.shapes[first].fill_rule,
                                  shape_index=torch.tensor([sidx[i] - first for i in sel])[None],
                                  counts=torch.tensor([len(contours[i]) // 3 for i in sel])[None],
                                  num_shapes=last - first, samples=samples)[0]  # (G, h, w)
            # beyond the culling radius coverage is clamped at sigmoid(-8) = 3e-4, not 0: over
            # a thousand shapes that would tint the whole picture, so it is snapped to 0 and 1
            cov = torch.where(cov < SNAP, 0.0, torch.where(cov > 1 - SNAP, 1.0, cov))
            box = out[:, y0:y1, x0:x1]
            for g in range(last - first):
                color = torch.tensor(image.shapes[first + g].color, dtype=cov.dtype).view(3, 1, 1)
                box = box * (1 - cov[g]) + color * cov[g]
            out[:, y0:y1, x0:x1] = box
    return out


def _pieces(image: VectorImage, scale: tuple[float, float], samples: int) -> tuple[list[torch.Tensor], list[int]]:
    """Every contour in output pixels, each cubic cut into equal-parameter pieces of at most
    ``RENDER_PIECE_PX`` (exactly, ``bezier.restrict``); the count is checked before the cut.

    Returns the contours ``(3S_i, 2)`` and the shape of each."""
    conts = [(torch.as_tensor(c, dtype=torch.float64) * torch.tensor(scale, dtype=torch.float64), g)
             for g, shape in enumerate(image.shapes) for c in shape.contours]
    if not conts:
        return [], []
    segs = [segment_controls(c) for c, _ in conts]  # P x (S_i, 4, 2)
    ctrl = torch.cat(segs)  # (N, 4, 2)
    length = (ctrl[:, 1:] - ctrl[:, :-1]).norm(dim=-1).sum(-1)  # (N,) control polygon: >= the arc length
    n = torch.ceil(length / RENDER_PIECE_PX).clamp(min=1).long()  # pieces of each segment
    edges = int(n.sum()) * samples
    if edges > MAX_RENDER_EDGES:
        raise InputError(f"too complex to render: {edges:,} edges once flattened (at most {MAX_RENDER_EDGES:,}; "
                         "lower --scale or simplify the SVG)")
    seg = torch.repeat_interleave(torch.arange(len(ctrl)), n)  # (M,) the segment of each piece
    j = torch.arange(len(seg)) - torch.repeat_interleave(torch.cumsum(n, 0) - n, n)  # index within its segment
    t0, t1 = j / n[seg], (j + 1) / n[seg]
    pieces = restrict(ctrl[seg], t0.double(), t1.double())[:, :3].reshape(-1, 2)  # (3M, 2): each piece's first 3
    owner = torch.repeat_interleave(torch.arange(len(segs)), torch.tensor([len(s) for s in segs]))  # (N,) contour
    per = torch.zeros(len(segs), dtype=torch.long).index_add_(0, owner, n)  # (P,) pieces of each contour
    return list(torch.split(pieces, (3 * per).tolist())), [g for _, g in conts]


def _chunks(image: VectorImage, contours: list[torch.Tensor], sidx: list[int], size: tuple[int, int],
            margin: float, samples: int) -> list[tuple[int, int, tuple[int, int, int, int]]]:
    """Runs ``[first, last)`` of consecutive drawn shapes of one fill rule with the pixel box
    ``(x0, y0, x1, y1)`` they cover (grown by ``margin``), each run within ``RENDER_CHUNK``
    coverage pixels (shapes x box) and padded segments; a shape too big alone is a run of its own."""
    h, w = size
    box = [None] * len(image.shapes)  # (x0, y0, x1, y1, paths, longest path, all segments) of each shape
    for c, g in zip(contours, sidx):
        lo, hi = c.min(0).values.tolist(), c.max(0).values.tolist()
        b = box[g] or (math.inf, math.inf, -math.inf, -math.inf, 0, 0, 0)
        box[g] = (min(b[0], lo[0]), min(b[1], lo[1]), max(b[2], hi[0]), max(b[3], hi[1]), b[4] + 1,
                  max(b[5], len(c) // 3), b[6] + len(c) // 3)

    def pixels(b):  # the box in whole pixels, clipped to the canvas
        x0, y0 = max(0, math.floor(b[0] - margin)), max(0, math.floor(b[1] - margin))
        x1, y1 = min(w, math.ceil(b[2] + margin)), min(h, math.ceil(b[3] + margin))
        return x0, y0, max(x0, x1), max(y0, y1)

    runs, cur = [], None  # cur: [first, last, union box, paths, longest path, largest shape]
    for g, b in enumerate(box):
        if b is None:
            continue  # no contour: draws nothing
        x0, y0, x1, y1 = pixels(b)
        if x1 <= x0 or y1 <= y0:
            continue  # wholly off the canvas: draws nothing
        if cur is not None:
            u = (min(cur[2][0], b[0]), min(cur[2][1], b[1]), max(cur[2][2], b[2]), max(cur[2][3], b[3]))
            x0, y0, x1, y1 = pixels(u)
            shapes = g + 1 - cur[0]  # the renderer pads paths to the longest, and shapes to the largest
            fits = shapes * (x1 - x0) * (y1 - y0) <= RENDER_CHUNK and (cur[3] + b[4]) * max(cur[4], b[5]) \
                <= RENDER_CHUNK and shapes * max(cur[5], b[6]) * samples <= RENDER_CHUNK
            if fits and image.shapes[g].fill_rule == image.shapes[cur[0]].fill_rule:
                cur = [cur[0], g + 1, u, cur[3] + b[4], max(cur[4], b[5]), max(cur[5], b[6])]
                continue
            runs.append((cur[0], cur[1], pixels(cur[2])))
        cur = [g, g + 1, b[:4], b[4], b[5], b[6]]
    if cur is not None:
        runs.append((cur[0], cur[1], pixels(cur[2])))
    return runs
