"""What the polish of a clean outline keeps after every Adam step (projected gradient descent,
``core._Fitter.fit_points``): each smooth join's handles collinear (``align``) and, in a two-tone
picture's outline, each line a line (``straighten``). The corner flags are ``trace.fit_rings``'; the
indices are in ``core._Paths`` order (every contour one path), the points ``(B, P, 3K, 2)``
input-normalised."""

from __future__ import annotations

import numpy as np
import torch

from ..raster import line_controls
from ..trace import Corners
from ..vector import VectorImage

LINE_EPS = 1e-6  # px: a segment whose handles lie this near its chord's thirds is a line (``trace.fit`` makes them so)


def joins_and_lines(vecs: list[VectorImage], flags: list[Corners], straight: list[bool], device
                    ) -> tuple[torch.Tensor, torch.Tensor]:
    """``(7, J)`` indices (image, path, anchor, handle before, handle after, whether the segment
    before and the one after are held straight) of the smooth joins of every contour of ``vecs``,
    and ``(3, S)`` (image, path, first anchor) of the lines held straight: those of the images
    ``straight`` says. A two-tone picture's trace fits its lines to the ink's sub-pixel coverage, where
    a straight run is straight; a colour picture's regions are pixel staircases, whose lines the
    polish may bend (bench/outlines.py: held, glyphs and icons nearer, emoji further)."""
    rows, lines = [], []
    for b, (vec, fl_img) in enumerate(zip(vecs, flags)):
        p = 0
        for sh, fl in zip(vec.shapes, fl_img):
            for c, f in zip(sh.contours, fl):
                c, corner = np.asarray(c, dtype=np.float64), np.asarray(f, dtype=bool)
                h1, h2 = line_controls(c[0::3], np.roll(c[0::3], -1, 0))
                line = (np.abs(c[1::3] - h1).max(1) < LINE_EPS) & (np.abs(c[2::3] - h2).max(1) < LINE_EPS)
                line &= straight[b]
                lines += [(b, p, 3 * k) for k in np.flatnonzero(line)]
                rows += [(b, p, 3 * k, (3 * k - 1) % len(c), 3 * k + 1, int(line[k - 1]), int(line[k]))
                         for k in np.flatnonzero(~corner)]
                p += 1
    as_t = lambda r, k: torch.tensor(r, dtype=torch.long, device=device).reshape(-1, k).T  # noqa: E731
    return as_t(rows, 7), as_t(lines, 3)


def straighten(pts: torch.Tensor, lines: torch.Tensor, counts: torch.Tensor) -> None:
    """In place on ``pts (B, P, 3K, 2)``: each of ``lines`` (``joins_and_lines``) a line again, its
    handles at its chord's thirds: the polish moves a line's ends, never bends it. ``counts (B, P)``:
    segments per path."""
    if not lines.shape[1]:
        return
    with torch.no_grad():
        i, p, a = lines
        h1, h2 = line_controls(pts[i, p, a], pts[i, p, (a + 3) % (3 * counts[i, p])])
        pts[i, p, a + 1], pts[i, p, a + 2] = h1, h2


def align(pts: torch.Tensor, joins: torch.Tensor, size: tuple[int, int]) -> None:
    """In place on ``pts (B, P, 3K, 2)``: each smooth join's handles made collinear through its
    anchor (in pixels, ``size (H, W)``), their lengths kept; where one side is a line held straight
    (``straighten``-ed first), along the line. A join of two such lines is left free: a line halved
    where the render was wrong (``trace.split_where_wrong``) may bend there."""
    if not joins.shape[1]:
        return
    with torch.no_grad():
        scale = torch.tensor([size[1], size[0]], dtype=pts.dtype, device=pts.device)
        i, p, a, b, c, line_b, line_a = joins
        line_b, line_a = line_b.bool()[:, None], line_a.bool()[:, None]
        anchor, before, after = pts[i, p, a] * scale, pts[i, p, b] * scale, pts[i, p, c] * scale
        la, lb = (after - anchor).norm(dim=-1, keepdim=True), (anchor - before).norm(dim=-1, keepdim=True)
        ta, tb = (after - anchor) / la.clamp_min(1e-9), (anchor - before) / lb.clamp_min(1e-9)
        t = torch.where(line_a, ta, torch.where(line_b, tb, ta + tb))
        t = t / t.norm(dim=-1, keepdim=True).clamp_min(1e-9)
        ok = ((la > 1e-6) & (lb > 1e-6) & ~(line_a & line_b)).expand_as(t)
        pts[i, p, c] = torch.where(ok, anchor + la * t, after) / scale
        pts[i, p, b] = torch.where(ok, anchor - lb * t, before) / scale
