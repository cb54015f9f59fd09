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
CROSS_CELL = 32  # px: the grid that finds the edges in a block's box; an edge in more than WIDE_CELLS cells is
WIDE_CELLS = 64  # tested against every block (a page's frame, a long rule: few)
CROSS_ALL = 256  # a shape of at most this many edges tests every pair at once (a photo's piece: 0.9 -> 0.2 ms)


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

    def hits(i, near: np.ndarray) -> bool:  # whether an edge of ``i`` crosses one of ``near`` (not its neighbour)
        r = a[near][None] - a[i, None]  # (B, J, 2): from edge i's start to edge j's start
        den = cross(d[i, None], d[near][None])
        ok = np.abs(den) > 1e-12
        t = np.where(ok, cross(r, d[near][None]) / np.where(ok, den, 1), -1)  # along edge i
        u = np.where(ok, cross(r, d[i, None]) / np.where(ok, den, 1), -1)  # along edge j
        hit = ok & (t > 1e-9) & (t < 1 - 1e-9) & (u > 1e-9) & (u < 1 - 1e-9)
        same = owner[i, None] == owner[near][None]
        gap = np.abs(index[i, None] - index[near][None])
        neighbours = same & ((gap <= 1) | (gap >= size[i, None] - 1))
        return bool((hit & ~neighbours).any())

    if len(a) <= CROSS_ALL:  # a small shape: every pair at once
        return hits(slice(None), np.arange(len(a)))
    lo_xy, hi_xy = np.minimum(a, b), np.maximum(a, b)  # (E, 2) edge boxes
    grid = _EdgeGrid(lo_xy, hi_xy)
    for i in _blocks([len(p) for p in polys], lo_xy, hi_xy):  # neighbours along a contour: a small box
        box_lo, box_hi = lo_xy[i].min(0), hi_xy[i].max(0)
        maybe = grid.within(box_lo, box_hi)
        if hits(i, maybe[((lo_xy[maybe] <= box_hi) & (hi_xy[maybe] >= box_lo)).all(1)]):  # edges j in that box
            return True
    return False


def _blocks(sizes: list[int], lo_xy: np.ndarray, hi_xy: np.ndarray) -> list[slice]:
    """Runs of at most ``CROSS_BLOCK`` edges along one contour, consecutive small contours put
    together while their box stays within a ``CROSS_CELL`` px square (a block across two far
    apart contours would have a page-sized box)."""
    out, start = [], 0
    for n in sizes:
        for lo in range(start, start + n, CROSS_BLOCK):
            hi = min(lo + CROSS_BLOCK, start + n)
            if out and out[-1].stop == lo and hi - out[-1].start <= CROSS_BLOCK:
                j = slice(out[-1].start, hi)
                if (hi_xy[j].max(0) - lo_xy[j].min(0)).max() <= CROSS_CELL:
                    out[-1] = j
                    continue
            out.append(slice(lo, hi))
        start += n
    return out


class _EdgeGrid:
    """Edge boxes ``(E, 2)`` filed by the ``CROSS_CELL`` px grid cells they enter, to find every
    edge whose box may meet a given box (a superset: the caller tests the boxes)."""

    def __init__(self, lo_xy: np.ndarray, hi_xy: np.ndarray):
        self.origin = lo_xy.min(0)
        c0, c1 = self._cell(lo_xy), self._cell(hi_xy)
        self.columns = int(c1[:, 0].max()) + 1
        span = c1 - c0 + 1
        count = span[:, 0] * span[:, 1]
        wide = count > WIDE_CELLS
        self.wide = np.flatnonzero(wide)
        edge = np.repeat(np.flatnonzero(~wide), count[~wide])  # one row per (edge, cell)
        first = np.repeat(np.cumsum(count[~wide]) - count[~wide], count[~wide])
        k = np.arange(len(edge)) - first  # the k-th cell of its edge's box, row by row
        w = span[edge, 0]
        cell = (c0[edge, 1] + k // w) * self.columns + c0[edge, 0] + k % w
        order = np.argsort(cell, kind="stable")
        self.cell, self.edge = cell[order], edge[order]

    def _cell(self, xy: np.ndarray) -> np.ndarray:
        return np.floor((xy - self.origin) / CROSS_CELL).astype(np.int64)

    def within(self, box_lo: np.ndarray, box_hi: np.ndarray) -> np.ndarray:
        (x0, y0), (x1, y1) = self._cell(box_lo[None])[0], self._cell(box_hi[None])[0]
        x1 = min(x1, self.columns - 1)
        rows = np.arange(max(y0, 0), y1 + 1) * self.columns
        starts = np.searchsorted(self.cell, rows + max(x0, 0), "left")
        ends = np.searchsorted(self.cell, rows + x1, "right")
        parts = [self.edge[s:e] for s, e in zip(starts, ends)] + [self.wide]
        return np.unique(np.concatenate(parts))
