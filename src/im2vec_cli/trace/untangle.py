"""The last guarantee of a clean outline: no loops, no crossings.

A polished corner can fold a loop a fraction of a pixel wide; ``untangle`` replaces each shape
whose contours cross by the exact outline of what it fills (Skia path ops, through
``vector/skia.py``). Frame: the pixel frame of the picture.
"""

from __future__ import annotations

import numpy as np

from ..raster.curves import flatten_ring
from ..vector import VectorImage, VectorShape, skia
from .simplify import simplify_contour


def untangle(vec: VectorImage, merge_tol: float = 0.25) -> VectorImage:
    """Each shape whose contours cross themselves or each other (a polished corner can fold a
    loop a fraction of a pixel wide) replaced by the exact outline of what it fills under its
    rule (Skia's path ops: ``skia-pathops``), so no pin hole or sliver is left at any zoom;
    the segments path ops split are merged again within ``merge_tol`` px where that crosses
    nothing. Shapes without crossings are kept as they are, and so is a shape that Skia's path
    ops fail on (rare: nearly coincident curves), with its coordinates snapped and without."""
    shapes = []
    for sh in vec.shapes:
        if not crosses(sh.contours):  # keep our cubics and start points
            shapes.append(sh)
            continue
        clean = _outline(sh)
        if clean is None:  # Skia could not resolve it: keep the shape (its loop is a fraction of a pixel)
            shapes.append(sh)
            continue
        merged = [simplify_contour(c, merge_tol) if len(c) >= 9 else c for c in clean]  # path ops split curves
        shapes.append(VectorShape(clean if crosses(merged) else merged, sh.color, "nonzero"))
    return VectorImage(vec.width, vec.height, shapes)


def _outline(sh: VectorShape, snap: float = 1 / 256) -> list[np.ndarray] | None:
    """The exact outline of what ``sh`` fills, as contours; ``None`` when path ops fail on it
    as it is and with its points snapped to a ``snap`` px grid."""
    import pathops

    for grid in (None, snap):
        cs = sh.contours if grid is None else [np.round(np.asarray(c) / grid) * grid for c in sh.contours]
        path = skia.to_path([skia.contour_chain(c) for c in cs], sh.fill_rule)
        try:
            return skia.contours(pathops.simplify(path, fix_winding=True, keep_starting_points=True))
        except pathops.PathOpsError:
            continue
    return None


CROSS_BLOCK = 64  # edges tested at once by ``crosses``, against the edges in their box: a few cubics' box, which
# few other edges enter (512: a glyph's box, and 2 s for a 2048 px page of text instead of 0.3 s)


def crosses(contours: list[np.ndarray], samples: int = 16) -> bool:
    """Whether closed cubic contours ``(3S, 2)`` cross themselves or each other (their
    polylines at ``samples`` lines per cubic; touching end to end is not crossing)."""
    polys = [flatten_ring(c, samples) for c in contours if len(c)]
    if not polys:  # a shape without contours crosses nothing (it crashed two real 512 px icons: issue 69)
        return False
    a = np.concatenate(polys)
    b = np.concatenate([np.roll(p, -1, 0) for p in polys])
    owner = np.concatenate([np.full(len(p), i) for i, p in enumerate(polys)])
    index = np.concatenate([np.arange(len(p)) for p in polys])
    size = np.concatenate([np.full(len(p), len(p)) for p in polys])
    d = b - a  # (E, 2)

    def cross(u, v):
        return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]

    lo_xy, hi_xy = np.minimum(a, b), np.maximum(a, b)  # (E, 2) edge boxes
    by_x = np.argsort(lo_xy[:, 0], kind="stable")  # edges by their left side: those that can reach a box
    left, widest = lo_xy[by_x, 0], float((hi_xy[:, 0] - lo_xy[:, 0]).max())
    for lo in range(0, len(a), CROSS_BLOCK):  # blocks of edges i (neighbours along a contour: a small box)
        i = slice(lo, lo + CROSS_BLOCK)
        box_lo, box_hi = lo_xy[i].min(0), hi_xy[i].max(0)
        maybe = by_x[np.searchsorted(left, box_lo[0] - widest, "left") : np.searchsorted(left, box_hi[0], "right")]
        near = maybe[((lo_xy[maybe] <= box_hi) & (hi_xy[maybe] >= box_lo)).all(1)]  # edges j in that box
        r = a[near][None] - a[i, None]  # (B, J, 2): from edge i's start to edge j's start
        den = cross(d[i, None], d[near][None])
        ok = np.abs(den) > 1e-12
        t = np.where(ok, cross(r, d[near][None]) / np.where(ok, den, 1), -1)  # along edge i
        u = np.where(ok, cross(r, d[i, None]) / np.where(ok, den, 1), -1)  # along edge j
        hit = ok & (t > 1e-9) & (t < 1 - 1e-9) & (u > 1e-9) & (u < 1 - 1e-9)
        same = owner[i, None] == owner[near][None]
        gap = np.abs(index[i, None] - index[near][None])
        neighbours = same & ((gap <= 1) | (gap >= size[i, None] - 1))
        if (hit & ~neighbours).any():
            return True
    return False
