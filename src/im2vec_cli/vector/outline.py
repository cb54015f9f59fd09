"""Clean outlines: every shape as non-overlapping outer contours and holes.

Two ways in, one way out:

- ``traced``: the picture's own regions (``trace.py``), each ring fitted with few cubics
  (``fit.py``).
- ``redrawn``: any ``VectorImage`` (the model's overlapping parts), each shape rendered under
  its fill rule and traced again, so its parts are united and seams thinner than half a
  pixel close; for a two-tone picture, regions the shape misses or adds against the picture
  are added or cut out first (``correct``), so that a hole or a piece the model cannot draw
  is still there. (Uniting the curves exactly with path booleans keeps the model's hairline
  gaps between parts, the cracks this module is here to remove.)

``untangle`` is the last step: a shape whose polished contours cross is replaced by its
exact outline (Skia path ops). Both give a ``VectorImage`` whose shapes are nonzero, with outer contours clockwise on screen
and holes counter-clockwise, and per contour the corner flags of ``fit.fit_rings`` (which
joins may stay sharp when the points are polished later). Frame: the pixel frame of the
picture (``image.py``).
"""

from __future__ import annotations

import numpy as np

from . import skia
from .cairo import fill_vector
from .fit import fit_rings
from .image import VectorImage, VectorShape
from .simplify import simplify_contour
from .trace import background_color, level_polygons, trace, two_tone

Corners = list[list[np.ndarray]]  # per shape, per contour: (S,) bool, true where anchor i is sharp


def fitted(rings_by_shape: list[tuple[tuple, list[np.ndarray]]], width: float, height: float,
           tol: float) -> tuple[VectorImage, Corners]:
    """``[(colour, rings)]`` back to front -> a nonzero ``VectorImage`` of cubics within ``tol`` px."""
    shapes, flags = [], []
    every = iter(fit_rings([r for _, rings in rings_by_shape for r in rings], tol))  # all runs fitted together
    for color, rings in rings_by_shape:
        fits = [next(every) for _ in rings]
        if fits:
            shapes.append(VectorShape([c for c, _ in fits], tuple(float(v) for v in color), "nonzero"))
            flags.append([s for _, s in fits])
    return VectorImage(width, height, shapes), flags


def traced(image: np.ndarray, tol: float, colors: int | None = None, max_paths: int | None = None
           ) -> tuple[VectorImage, Corners]:
    """The picture ``(H, W, 3)`` in [0, 1] traced and fitted (``trace.trace``, ``fit.fit_ring``)."""
    h, w, _ = image.shape
    regions = trace(image, colors, max_paths)
    return fitted([(r.color, r.polygons) for r in regions], w, h, tol)


# --- the model's paths, redrawn clean ------------------------------------------------------------

SUPERSAMPLE = 2  # the model's shapes are rendered at this multiple of the input's size before tracing


def shape_coverage(shape: VectorShape, width: int, height: int, scale: float = 1.0) -> np.ndarray:
    """``(H, W)`` in [0, 1]: how much of each pixel of a ``width x height`` grid the shape covers
    (cairo, under the shape's fill rule), its pixel frame multiplied by ``scale``."""
    ink = VectorImage(width / scale, height / scale, [VectorShape(shape.contours, (0.0, 0.0, 0.0), shape.fill_rule)])
    return 1 - fill_vector(ink, width, height).mean(-1)


def correct(coverage: np.ndarray, alpha: np.ndarray, min_width: int = 1) -> np.ndarray:
    """``coverage`` with the picture's ink ``alpha`` put back where they disagree by more than
    an edge: pieces the shape misses or adds, wider than ``2 * min_width`` pixels, and the
    pixels around them. Both ``(H, W)`` in [0, 1] on one grid."""
    from scipy.ndimage import binary_dilation, binary_opening

    ink, drawn = alpha >= 0.5, coverage >= 0.5
    k = np.ones((2 * min_width + 1,) * 2, dtype=bool)
    wrong = binary_opening(ink & ~drawn, k) | binary_opening(drawn & ~ink, k)
    if not wrong.any():
        return coverage
    near = binary_dilation(wrong, iterations=2 * min_width)
    return np.where(near, alpha, coverage)


def redrawn(vec: VectorImage, tol: float, image: np.ndarray | None = None) -> tuple[VectorImage, Corners]:
    """Each shape of ``vec`` as the clean rings around where it covers at least half a pixel
    (rendered at ``SUPERSAMPLE`` x, so overlaps, seams narrower than that and self-
    intersections are gone), refitted within ``tol`` px.

    With ``image (H, W, 3)`` of a two-tone picture and a one-shape ``vec`` (the fonts, MNIST
    and icons models), the shape is first ``correct``-ed against the picture's ink: a hole
    or a piece the model cannot draw is still there.
    """
    w, h, up = int(round(vec.width)), int(round(vec.height)), SUPERSAMPLE
    tone = None
    if image is not None and len(vec.shapes) == 1:
        tone = two_tone(image, background_color(image))
    out = []
    for shape in vec.shapes:
        if not shape.contours:
            continue
        cov = shape_coverage(shape, w * up, h * up, up)
        if tone is not None:
            cov = correct(cov, np.kron(tone[1], np.ones((up, up))), min_width=up)
        rings = [r / up for r in level_polygons(cov, min_area=0.5 * up * up)]
        if rings:
            out.append((shape.color, rings))
    return fitted(out, vec.width, vec.height, tol)


def cleaned(vec: VectorImage, tol: float = 0.5) -> VectorImage:
    """A decoded image with no picture behind it (a sample, an interpolation frame) drawn
    clean: each shape ``redrawn`` as the outer contours and holes of what it fills under its
    own rule (so even-odd overlaps become real holes, not checkerboards) and ``untangle``-d."""
    return untangle(redrawn(vec, tol)[0])


# --- the last guarantee: no loops ----------------------------------------------------------------


def untangle(vec: VectorImage, merge_tol: float = 0.25) -> VectorImage:
    """Each shape whose contours cross themselves or each other (a polished corner can fold a
    loop a fraction of a pixel wide) replaced by the exact outline of what it fills under its
    rule (Skia's path ops: ``skia-pathops``), so no pin hole or sliver is left at any zoom;
    the segments path ops split are merged again within ``merge_tol`` px where that crosses
    nothing. Shapes without crossings are kept as they are."""
    import pathops

    shapes = []
    for sh in vec.shapes:
        if not crosses(sh.contours):  # keep our cubics and start points
            shapes.append(sh)
            continue
        path = skia.to_path([skia.contour_chain(c) for c in sh.contours], sh.fill_rule)
        clean = skia.contours(pathops.simplify(path, fix_winding=True, keep_starting_points=True))
        merged = [simplify_contour(c, merge_tol) if len(c) >= 9 else c for c in clean]  # path ops split curves
        shapes.append(VectorShape(clean if crosses(merged) else merged, sh.color, "nonzero"))
    return VectorImage(vec.width, vec.height, shapes)


CROSS_BLOCK = 512  # edges tested at once by ``crosses`` (a few MB of pair arrays)


def crosses(contours: list[np.ndarray], samples: int = 16) -> bool:
    """Whether closed cubic contours ``(3S, 2)`` cross themselves or each other (their
    polylines at ``samples`` lines per cubic; touching end to end is not crossing)."""
    import torch

    from ..raster import flatten_closed

    polys = [flatten_closed(torch.as_tensor(np.asarray(c, dtype=np.float64)), samples).numpy() for c in contours]
    a = np.concatenate(polys)
    b = np.concatenate([np.roll(p, -1, 0) for p in polys])
    owner = np.concatenate([np.full(len(p), i) for i, p in enumerate(polys)])
    index = np.concatenate([np.arange(len(p)) for p in polys])
    size = np.concatenate([np.full(len(p), len(p)) for p in polys])
    d = b - a  # (E, 2)

    def cross(u, v):
        return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]

    for lo in range(0, len(a), CROSS_BLOCK):  # blocks of edges i against all edges j: memory stays bounded
        i = slice(lo, lo + CROSS_BLOCK)
        r = a[None] - a[i, None]  # (B, E, 2): from edge i's start to edge j's start
        den = cross(d[i, None], d[None])
        ok = np.abs(den) > 1e-12
        t = np.where(ok, cross(r, d[None]) / np.where(ok, den, 1), -1)  # along edge i
        u = np.where(ok, cross(r, d[i, None]) / np.where(ok, den, 1), -1)  # along edge j
        hit = ok & (t > 1e-9) & (t < 1 - 1e-9) & (u > 1e-9) & (u < 1 - 1e-9)
        same = owner[i, None] == owner[None]
        gap = np.abs(index[i, None] - index[None])
        neighbours = same & ((gap <= 1) | (gap >= size[i, None] - 1))
        if (hit & ~neighbours).any():
            return True
    return False
