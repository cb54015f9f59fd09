"""Clean outlines: every shape as non-overlapping outer contours and holes.

Two ways in, one way out:

- ``traced``: the picture's own regions (``regions.py``), each ring fitted with few cubics
  (``fit.py``).
- ``redrawn``: any ``VectorImage`` (the model's overlapping parts), each shape rendered under
  its fill rule and traced again, so its parts are united and seams thinner than half a
  pixel close; for a two-tone picture, regions the shape misses or adds against the picture
  are added or cut out first (``correct``), so that a hole or a piece the model cannot draw
  is still there. (Uniting the curves exactly with path booleans keeps the model's hairline
  gaps between parts, the cracks this module is here to remove.)

``untangle`` (``untangle.py``) is the last step: a shape whose polished contours cross is
replaced by its exact outline (Skia path ops). Both give a ``VectorImage`` whose shapes are nonzero, with outer contours clockwise on screen
and holes counter-clockwise, and per contour the corner flags of ``fit.fit_rings`` (which
joins may stay sharp when the points are polished later). Frame: the pixel frame of the
picture (``image.py``).
"""

from __future__ import annotations

import numpy as np

from ..raster.bezier import line_controls
from ..vector import VectorImage, VectorShape, fill_vector
from .fit import Corners, fit_rings
from .regions import background_color, level_polygons, trace, two_tone
from .untangle import untangle


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


def traced(image: np.ndarray, tol: float, colors: int | None = None, max_paths: int | None = None,
           kind: str = "", tone: tuple[np.ndarray, np.ndarray] | None = None
           ) -> tuple[VectorImage, Corners, bool]:
    """The picture ``(H, W, 3)`` in [0, 1] traced and fitted (``regions.trace``, ``fit.fit_rings``),
    and whether the result is exact: a hard-edged picture's regions along its pixel edges,
    every side one straight segment, every corner sharp (nothing to fit or polish). ``kind``:
    what ``read.read`` read it as (``regions.trace``); ``tone``: its ink and coverage where it is
    two-tone and ``read.read`` found them."""
    h, w, _ = image.shape
    regions = trace(image, colors, max_paths, kind=kind, tone=tone)
    if regions and all(r.exact for r in regions):
        return straight([(r.color, r.polygons) for r in regions], w, h) + (True,)
    return fitted([(r.color, r.polygons) for r in regions], w, h, tol) + (False,)


def straight(rings_by_shape: list[tuple[tuple, list[np.ndarray]]], width: float, height: float
             ) -> tuple[VectorImage, Corners]:
    """``[(colour, rings)]`` back to front -> a nonzero ``VectorImage`` whose every side is one
    straight cubic, every corner sharp."""
    shapes, flags = [], []
    for color, rings in rings_by_shape:
        contours = [np.concatenate([np.stack([a, *line_controls(a, b)]) for a, b in zip(r, np.roll(r, -1, 0))])
                    for r in rings]
        shapes.append(VectorShape(contours, tuple(float(v) for v in color), "nonzero"))
        flags.append([np.ones(len(r), dtype=bool) for r in rings])
    return VectorImage(width, height, shapes), flags


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
