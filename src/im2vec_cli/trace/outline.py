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

from ..raster.curves import line_controls
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
           kind: str = "", tone: tuple[np.ndarray, np.ndarray] | None = None, speck: int = 0, marks: float = 0.0,
           palette: bool = False) -> tuple[VectorImage, Corners, bool]:
    """The picture ``(H, W, 3)`` in [0, 1] traced and fitted (``regions.trace``, ``fit.fit_rings``),
    and whether the result is exact: a hard-edged picture's regions along its pixel edges,
    every side one straight segment, every corner sharp (nothing to fit or polish). ``kind``:
    what ``read.read`` read it as (``regions.trace``); ``tone``: its ink and coverage where it is
    two-tone and ``read.read`` found them; ``speck``, ``marks``: a photo's smallest piece, and how much a
    smaller mark stands out; ``palette``: traced by its palette though it looks two-tone."""
    h, w, _ = image.shape
    regions = trace(image, colors, max_paths, kind=kind, tone=tone, speck=speck, marks=marks, palette=palette)
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
    from .ndops import dilate, opening

    ink, drawn = alpha >= 0.5, coverage >= 0.5
    k = np.ones((2 * min_width + 1,) * 2, dtype=bool)
    wrong = opening(ink & ~drawn, k) | opening(drawn & ~ink, k)
    if not wrong.any():
        return coverage
    near = dilate(wrong, iterations=2 * min_width)
    return np.where(near, alpha, coverage)


SEAM = 1.5  # input px: what the paths of a decoded image (with no picture behind it) cover but its fill rule
# cuts out is filled where narrower than this (seams), and pieces of ink no wider are dropped (slivers)
CRACK = 1.5  # input px: background that no path covers is filled where narrower than this (cracks between paths)
SPECK = 4.0  # input px^2: pieces and holes of such an image smaller than this are dropped
# (SEAM, CRACK, SPECK) = (1.5, 1.0, 2.0) kept 95.8% of the frames of bench/morphs.py's 12 pairs with the
# character's pieces and holes, (1.5, 1.5, 4.0) 100% (96.9% against 95.8% on 12 other pairs, "bhnpqyADP692"),
# at the same end-frame IoU; SEAM 2.0 lost frames (96.9%) that it gained in samples' pieces


def mended(shape: VectorShape, width: int, height: int, scale: float = 1.0) -> np.ndarray:
    """``shape_coverage`` of a decoded shape with its seams, cracks and slivers mended.

    Where two of the model's paths overlap under even-odd, the overlap is cut out; where two
    meet, a hairline of background may show between them. The parts of such cut-outs
    narrower than ``SEAM`` input px and of the background narrower than ``CRACK`` are
    filled (a grey closing there), and pieces of ink no wider than ``SEAM`` anywhere are
    dropped. Wider parts (counters, strokes with their thin serifs) stay as they are.
    """
    from .ndops import dilate, grey_closing, label, opening

    cov = shape_coverage(shape, width, height, scale)
    union = np.max([shape_coverage(VectorShape([c], (0.0, 0.0, 0.0), "nonzero"), width, height, scale)
                    for c in shape.contours], axis=0) if shape.fill_rule == "evenodd" else cov  # (H, W)
    seam, crack = (np.ones((max(2, int(np.ceil(w * scale))),) * 2, dtype=bool) for w in (SEAM, CRACK))
    bg, cut = cov < 0.5, (union >= 0.5) & (cov < 0.5)
    thin = (cut & ~opening(cut, seam)) | (bg & ~opening(bg, crack, border=1))
    out = np.where(dilate(thin), np.maximum(cov, grey_closing(np.maximum(cov, union * cut), seam)), cov)
    ink, n = label(out >= 0.5)
    if n:
        wide = np.zeros(n + 1, dtype=bool)
        wide[np.unique(ink[opening(ink > 0, seam)])] = True
        out = np.where(dilate(~wide[ink] & (ink > 0)), 0.0, out)
    return out


def redrawn(vec: VectorImage, tol: float, image: np.ndarray | None = None) -> tuple[VectorImage, Corners]:
    """Each shape of ``vec`` as the clean rings around where it covers at least half a pixel
    (rendered at ``SUPERSAMPLE`` x, so overlaps, seams narrower than that and self-
    intersections are gone), refitted within ``tol`` px.

    With ``image (H, W, 3)`` of a two-tone picture and a one-shape ``vec`` (the fonts, MNIST
    and icons models), the shape is first ``correct``-ed against the picture's ink: a hole
    or a piece the model cannot draw is still there. Without one (a sample, a morph's frame),
    each shape's seams are ``mended`` and pieces and holes under ``SPECK`` px^2 are dropped.
    """
    w, h, up = int(round(vec.width)), int(round(vec.height)), SUPERSAMPLE
    tone = None
    if image is not None and len(vec.shapes) == 1:
        tone = two_tone(image, background_color(image))
    out = []
    for shape in vec.shapes:
        if not shape.contours:
            continue
        cov = (shape_coverage if image is not None else mended)(shape, w * up, h * up, up)
        if tone is not None:
            cov = correct(cov, np.kron(tone[1], np.ones((up, up))), min_width=up)
        rings = [r / up for r in level_polygons(cov, min_area=(0.5 if image is not None else SPECK) * up * up)]
        if rings:
            out.append((shape.color, rings))
    return fitted(out, vec.width, vec.height, tol)


def cleaned(vec: VectorImage, tol: float = 0.25) -> VectorImage:
    """A decoded image with no picture behind it (a sample, an interpolation frame) drawn
    clean: each shape ``redrawn`` as the outer contours and holes of what it fills under its
    own rule, ``mended``, and ``untangle``-d. ``tol`` (px): on the 24 fitted end frames of
    bench/morphs.py, 0.5 gives IoU@4x 0.967 with 16.4 segments, 0.25 0.977 with 25.9 (the
    model's own paths: 0.985 with 47.5)."""
    return untangle(redrawn(vec, tol)[0])
