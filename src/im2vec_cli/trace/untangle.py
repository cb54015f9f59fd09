"""The last guarantee of a clean outline: no loops, no crossings.

A polished corner can fold a loop a fraction of a pixel wide; ``untangle`` replaces each shape
whose contours cross by the exact outline of what it fills (Skia path ops, through
``vector/skia.py``). Frame: the pixel frame of the picture.
"""

from __future__ import annotations

import numpy as np

from ..raster.curves import flatten_cubics
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
    for sh, tangled in zip(vec.shapes, crosses_each([sh.contours for sh in vec.shapes])):
        if not tangled:  # keep our cubics and start points
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
CROSS_SWEEP = 2048  # a shape of at most this many edges is tested by a sweep along x (``crosses_each``): the pairs
# whose x spans meet, a few per edge (every pair of a photo's 160-edge piece: 0.35 ms a piece; a page of text,
# thousands of edges in one x span, goes by the grid)
SWEEP_PAIRS = 1 << 22  # pairs tested at once by the sweep: bounded memory


def crosses(contours: list[np.ndarray], samples: int = 16) -> bool:
    """Whether closed cubic contours ``(3S, 2)`` cross themselves or each other (their
    polylines at ``samples`` lines per cubic; touching end to end is not crossing)."""
    return bool(crosses_each([contours], samples)[0])


def crosses_each(shapes: list[list[np.ndarray]], samples: int = 16) -> np.ndarray:
    """``crosses`` of each shape's contours: ``(N,)`` bool. Shapes of at most ``CROSS_SWEEP``
    edges are tested together by one sweep (``_swept``), larger ones each by its grid (``_gridded``)."""
    edges = _Edges(shapes, samples)
    out = np.zeros(len(shapes), dtype=bool)
    per_shape = np.bincount(edges.shape, minlength=len(shapes))
    small = per_shape <= CROSS_SWEEP
    out[small] = _swept(edges, small)[small]
    for k in np.flatnonzero(~small):
        out[k] = _gridded(edges, k)
    return out


class _Edges:
    """The polylines of closed cubic contours at ``samples`` lines a cubic, as edges: starts
    ``a (E, 2)``, directions ``d``, boxes ``lo``/``hi``, and per edge its ``shape``, its
    contour (``owner``, numbered over all shapes), its ``index`` along it and that contour's ``size``."""

    def __init__(self, shapes: list[list[np.ndarray]], samples: int):
        cs = [(k, np.asarray(c, dtype=np.float64)) for k, cont in enumerate(shapes) for c in cont if len(c)]
        if not cs:  # no contour crosses anything (an empty shape crashed two real 512 px icons: issue 69)
            self.a = self.d = self.lo = self.hi = np.zeros((0, 2))
            self.shape = self.owner = self.index = self.size = np.zeros(0, dtype=np.int64)
            return
        n3 = np.array([len(c) for _, c in cs])
        segs = n3 // 3  # cubics a contour
        first = np.repeat(np.cumsum(n3) - n3, segs)  # each cubic's contour's first point
        s = np.arange(segs.sum()) - np.repeat(np.cumsum(segs) - segs, segs)  # each cubic's number along it
        pts = np.concatenate([c for _, c in cs])
        ctrl = pts[first[:, None] + (3 * s[:, None] + np.arange(4)) % np.repeat(n3, segs)[:, None]]  # (C, 4, 2)
        self.a = flatten_cubics(ctrl, samples)  # each contour's flatten_ring, one after another
        size = segs * samples
        self.owner = np.repeat(np.arange(len(cs)), size)
        self.size = size[self.owner]
        self.index = np.arange(len(self.a)) - np.repeat(np.cumsum(size) - size, size)
        nxt = np.arange(len(self.a)) + 1
        nxt[self.index == self.size - 1] -= self.size[self.index == self.size - 1]  # a contour's last edge closes it
        b = self.a[nxt]
        self.d = b - self.a
        self.lo, self.hi = np.minimum(self.a, b), np.maximum(self.a, b)
        self.shape = np.array([k for k, _ in cs])[self.owner]

    def hit(self, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        """For edge pairs ``(i, j)`` of one shape (index arrays that broadcast), whether they
        cross (not neighbours along a contour, not end to end): bool, of their broadcast shape."""
        a, d = self.a, self.d
        same = self.owner[i] == self.owner[j]
        gap = np.abs(self.index[i] - self.index[j])
        neighbours = same & ((gap <= 1) | (gap >= self.size[i] - 1))
        r = a[j] - a[i]  # from edge i's start to edge j's start
        den = _cross(d[i], d[j])
        ok = np.abs(den) > 1e-12
        t = np.where(ok, _cross(r, d[j]) / np.where(ok, den, 1), -1)  # along edge i
        u = np.where(ok, _cross(r, d[i]) / np.where(ok, den, 1), -1)  # along edge j
        return ok & ~neighbours & (t > 1e-9) & (t < 1 - 1e-9) & (u > 1e-9) & (u < 1 - 1e-9)


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]


def _swept(edges: _Edges, which: np.ndarray) -> np.ndarray:
    """Whether each shape ``which`` (``(N,)`` bool) crosses itself, all at once: the edges sorted
    by shape, then by the left of their box; each pairs with those after it whose left lies
    within its box's x span (any two edges whose boxes meet pair so, the leftmost with the
    other); the pairs whose boxes meet in y too are tested. ``(N,)`` bool."""
    out = np.zeros(len(which), dtype=bool)
    keep = np.flatnonzero(which[edges.shape])
    if not len(keep):
        return out
    lo, hi, shape = edges.lo[keep], edges.hi[keep], edges.shape[keep]
    x0 = lo[:, 0].min()
    span = float(hi[:, 0].max() - x0) + 2  # shapes' keys apart by more than any x
    key = shape * span + (lo[:, 0] - x0)
    order = np.argsort(key, kind="stable")
    stop = np.searchsorted(key[order], (shape * span + (hi[:, 0] - x0))[order] + 1e-6, "right")
    count = stop - np.arange(len(order)) - 1  # edges after each (in order) whose left is within its span
    ends = np.cumsum(count)
    start = 0
    while start < len(order):  # blocks of at most SWEEP_PAIRS pairs
        stop_at = max(int(np.searchsorted(ends, ends[start] - count[start] + SWEEP_PAIRS, "right")), start + 1)
        c = count[start:stop_at]
        first = np.repeat(np.arange(start, stop_at), c)
        second = first + 1 + np.arange(c.sum()) - np.repeat(np.cumsum(c) - c, c)
        i, j = keep[order[first]], keep[order[second]]
        meet = (edges.lo[j] <= edges.hi[i]).all(1) & (edges.lo[i] <= edges.hi[j]).all(1)
        i, j = i[meet], j[meet]
        out[edges.shape[i[edges.hit(i, j)]]] = True
        start = stop_at
    return out


def _gridded(edges: _Edges, k: int) -> bool:
    """Whether shape ``k`` crosses itself: runs of its edges (``_blocks``) each tested against the
    edges in their box, found by a grid (``_EdgeGrid``)."""
    mine = np.flatnonzero(edges.shape == k)
    lo_xy, hi_xy = edges.lo[mine], edges.hi[mine]
    grid = _EdgeGrid(lo_xy, hi_xy)
    sizes = np.bincount(edges.owner[mine] - edges.owner[mine].min())
    for blk in _blocks([int(n) for n in sizes if n], lo_xy, hi_xy):  # neighbours along a contour: a small box
        box_lo, box_hi = lo_xy[blk].min(0), hi_xy[blk].max(0)
        maybe = grid.within(box_lo, box_hi)
        maybe = maybe[((lo_xy[maybe] <= box_hi) & (hi_xy[maybe] >= box_lo)).all(1)]  # edges j in that box
        if edges.hit(mine[blk][:, None], mine[maybe][None]).any():  # (B, J) pairs
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
