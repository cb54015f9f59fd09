"""The last guarantee of a clean outline: no loops, no crossings.

A polished corner can fold a loop a fraction of a pixel wide; ``untangle`` replaces each shape
whose contours cross by the exact outline of what it fills (Skia path ops, through
``vector/skia.py``). Frame: the pixel frame of the picture.
"""

from __future__ import annotations

import numpy as np

from ..raster.curves import flatten_cubics, flatten_ring, ring_area
from ..vector import VectorImage, VectorShape, skia
from .ndops import label, run_places
from .simplify import simplify_contours


def untangle(vec: VectorImage, merge_tol: float = 0.25) -> VectorImage:
    """Each shape whose contours cross themselves or each other (a polished corner can fold a
    loop a fraction of a pixel wide) replaced by the exact outline of what it fills under its
    rule (Skia's path ops: ``skia-pathops``), so no pin hole or sliver is left at any zoom;
    the segments path ops split are merged again within ``merge_tol`` px where that crosses
    nothing. A shape of many contours is untangled by its groups (``_groups``: contours whose
    boxes meet), only those that cross: a page of text is one shape of thousands of letters, a
    few of them tangled. Shapes without crossings are kept as they are, and so is a group that
    Skia's path ops fail on (rare: nearly coincident curves), with its coordinates snapped and without."""
    tangled = crosses_each([sh.contours for sh in vec.shapes])
    parts = {k: _untangled(vec.shapes[k]) for k in np.flatnonzero(tangled).tolist()}
    parts = {k: p for k, p in parts.items() if p[1]}  # (kept, outlined); none outlined: Skia could not
    clean = {k: new for k, (_, new) in parts.items()}  # resolve it (its loop is a fraction of a pixel): kept
    long = [(k, i) for k, cs in clean.items() for i, c in enumerate(cs) if len(c) >= 9]  # path ops split curves:
    merged = {k: list(cs) for k, cs in clean.items()}  # merged again, all shapes' contours at once
    for (k, i), c in zip(long, simplify_contours([clean[k][i] for k, i in long], merge_tol)):
        merged[k][i] = c
    again = dict(zip(merged, crosses_each(list(merged.values()))))
    shapes = [VectorShape(parts[k][0] + (clean[k] if again[k] else merged[k]), sh.color,
                          sh.fill_rule if parts[k][0] else "nonzero") if k in clean else sh
              for k, sh in enumerate(vec.shapes)]  # untangled shapes nonzero; the others keep our cubics and starts
    return VectorImage(vec.width, vec.height, shapes)


GROUP_MIN = 8  # contours a shape has before it is untangled by its groups...
GROUP_PIXELS = 1 << 26  # ...and the most pixels of the grid its groups are found on (else one group)


def _untangled(sh: VectorShape) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """``sh``'s contours as ``(kept, outlined)``: those of its groups that cross nothing, and the
    ``_outline`` of each group that crosses (a group Skia's path ops fail on kept). The groups'
    fills are apart, so each is outlined alone; the outlines' winding is 0 or 1, the same under
    either rule, and the kept contours keep ``sh``'s rule."""
    if len(sh.contours) < GROUP_MIN:
        out = _outline(sh)
        return (list(sh.contours), []) if out is None else ([], out)
    groups = _groups(sh.contours)
    members = [[sh.contours[i] for i in g] for g in groups]
    kept, outlined = [], []
    for cs, crossed in zip(members, crosses_each(members)):
        out = _outline(VectorShape(cs, sh.color, sh.fill_rule)) if crossed else None
        if out is None:
            kept.extend(cs)
        else:
            outlined.extend(out)
    return kept, outlined


def _groups(contours: list[np.ndarray]) -> list[list[int]]:
    """The contours whose boxes (of their control points, which hold their curves) meet, directly
    or through others: indices, in order. Found on a pixel grid, each box a pixel or two larger,
    so boxes that meet always share a group (and boxes a pixel apart may)."""
    lo = np.array([np.asarray(c).min(0) for c in contours])
    hi = np.array([np.asarray(c).max(0) for c in contours])
    a = np.floor(lo - lo.min(0)).astype(np.int64)
    b = np.floor(hi - lo.min(0)).astype(np.int64) + 2
    w, h = b.max(0)
    if w * h > GROUP_PIXELS:
        return [list(range(len(contours)))]
    grid = np.zeros((h, w), dtype=bool)
    for (x0, y0), (x1, y1) in zip(a, b):
        grid[y0:y1, x0:x1] = True
    key = label(grid)[0][a[:, 1], a[:, 0]]
    order = np.argsort(key, kind="stable")
    cuts = np.flatnonzero(np.diff(key[order])) + 1
    return [g.tolist() for g in sorted(np.split(order, cuts), key=lambda g: g[0])]


def _outline(sh: VectorShape, snap: float = 1 / 256) -> list[np.ndarray] | None:
    """The exact outline of what ``sh`` fills, as contours; ``None`` when path ops fail on it
    as it is and with its points snapped to a ``snap`` px grid. Path ops can fail without a word on
    nearly coincident curves (a polished 1 px ring whose hole came back filled: issue 69), so an
    outline that fills other points than ``sh`` does (``fills_alike``) counts as a failure."""
    import pathops

    for grid in (None, snap):
        cs = sh.contours if grid is None else [np.round(np.asarray(c) / grid) * grid for c in sh.contours]
        path = skia.to_path([skia.contour_chain(c) for c in cs], sh.fill_rule)
        try:
            out = skia.contours(pathops.simplify(path, fix_winding=True, keep_starting_points=True))
        except pathops.PathOpsError:
            continue
        if fills_alike(sh.contours, sh.fill_rule, out):
            return out
    return None


CHECK_SIDE = 48  # points a side of the grid over a shape's box at which an outline is checked against the shape...
CHECK_SHARE = 0.01  # ...which may disagree at this share of them (points on a boundary, read from polylines)
CHECK_EDGES = 1 << 21  # point-edge pairs at once


def fills_alike(contours: list[np.ndarray], rule: str, outline: list[np.ndarray]) -> bool:
    """Whether ``outline`` (nonzero) fills what closed cubic ``contours`` fill under ``rule`` at a
    ``CHECK_SIDE`` grid of points over their box, but for ``CHECK_SHARE`` of them; at once where their
    signed areas add up alike (within ``CHECK_SHARE``: the contours turn as their nesting says)."""
    cs = [np.asarray(c, dtype=np.float64) for c in contours if len(c)]
    if not cs:
        return not outline
    shape, out = ([flatten_ring(np.asarray(c, dtype=np.float64), 8) for c in g if len(c)] for g in (cs, outline))
    areas = [abs(sum(float(ring_area(r)) for r in rings)) for rings in (shape, out)]
    if abs(areas[0] - areas[1]) <= CHECK_SHARE * max(areas) + 0.5:
        return True
    pts = np.concatenate(cs)
    lo, hi = pts.min(0), pts.max(0)
    t = (np.arange(CHECK_SIDE) + 0.5) / CHECK_SIDE
    grid = np.stack(np.meshgrid(lo[0] + t * (hi[0] - lo[0]), lo[1] + t * (hi[1] - lo[1])), -1).reshape(-1, 2)
    wind = _winding(grid, shape)
    inside = (wind % 2 == 1) if rule == "evenodd" else (wind != 0)
    return bool((inside != (_winding(grid, out) != 0)).mean() <= CHECK_SHARE)


def _winding(points: np.ndarray, rings: list[np.ndarray]) -> np.ndarray:
    """The winding number ``(M,)`` of each point of ``points (M, 2)`` about closed polylines ``rings`` (each
    ``(V, 2)``, its last vertex joined to its first)."""
    if not rings:
        return np.zeros(len(points), dtype=np.int64)
    a = np.concatenate(rings)
    b = np.concatenate([np.roll(r, -1, 0) for r in rings])
    wind = np.zeros(len(points), dtype=np.int64)
    step = max(1, CHECK_EDGES // max(len(points), 1))
    px, py = points[:, :1], points[:, 1:]
    for i in range(0, len(a), step):
        (x0, y0), (x1, y1) = a[i : i + step].T, b[i : i + step].T
        left = (x1 - x0) * (py - y0) - (px - x0) * (y1 - y0)  # (M, E): > 0 where the point is left of the edge
        up, down = (y0 <= py) & (y1 > py), (y1 <= py) & (y0 > py)
        wind += (up & (left > 0)).sum(1) - (down & (left < 0)).sum(1)
    return wind


SWEEP_BAND = 8  # px: edges are swept along x within bands of this height (an edge in each band it enters), so that
# a page of text, thousands of edges in one x span, pairs each edge with the few beside it in its line
SWEEP_PAIRS = 1 << 18  # pairs tested at once by the sweep, and the cubics of the shapes swept at once (16 edges each):
SWEEP_CUBICS = 1 << 12  # bounded memory (a 512 px photo's 3,000 shapes at once held 80 MB in the sweep; so, 19)


def crosses(contours: list[np.ndarray], samples: int = 16) -> bool:
    """Whether closed cubic contours ``(3S, 2)`` cross themselves or each other (their
    polylines at ``samples`` lines per cubic; touching end to end is not crossing)."""
    return bool(crosses_each([contours], samples)[0])


def crosses_each(shapes: list[list[np.ndarray]], samples: int = 16) -> np.ndarray:
    """``crosses`` of each shape's contours: ``(N,)`` bool, as many shapes at once (``_swept``) as
    hold ``SWEEP_CUBICS`` cubics (a shape of more alone)."""
    out, start = np.zeros(len(shapes), dtype=bool), 0
    cubics = np.cumsum([sum(len(c) // 3 for c in contours) for contours in shapes])
    while start < len(shapes):
        stop = max(int(np.searchsorted(cubics, (cubics[start - 1] if start else 0) + SWEEP_CUBICS, "right")), start + 1)
        out[start:stop] = _swept(_Edges(shapes[start:stop], samples), stop - start)
        start = stop
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
        s = run_places(segs)  # each cubic's number along its contour
        pts = np.concatenate([c for _, c in cs])
        ctrl = pts[first[:, None] + (3 * s[:, None] + np.arange(4)) % np.repeat(n3, segs)[:, None]]  # (C, 4, 2)
        self.a = flatten_cubics(ctrl, samples)  # each contour's flatten_ring, one after another
        size = segs * samples
        self.owner = np.repeat(np.arange(len(cs)), size)
        self.size = size[self.owner]
        self.index = run_places(size)
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


def _swept(edges: _Edges, count: int) -> np.ndarray:
    """Whether each of ``count`` shapes crosses itself: each edge filed in the ``SWEEP_BAND`` px
    bands its box enters; within a band of a shape, the edges sorted by the left of their box,
    each paired with those after it whose left lies within its x span (any two edges whose
    boxes meet share a band and pair so, the leftmost with the other); the pairs whose boxes
    meet in y too are tested (``_Edges.hit``). ``(count,)`` bool."""
    out = np.zeros(count, dtype=bool)
    if not len(edges.a):
        return out
    y0 = edges.lo[:, 1].min()
    b0 = np.floor((edges.lo[:, 1] - y0) / SWEEP_BAND).astype(np.int64)
    n = np.floor((edges.hi[:, 1] - y0) / SWEEP_BAND).astype(np.int64) - b0 + 1
    edge = np.repeat(np.arange(len(edges.a)), n)  # one row per (edge, band)
    band = np.repeat(b0, n) + run_places(n)
    group = np.unique(edges.shape[edge] * (int(band.max()) + 1) + band, return_inverse=True)[1]
    x0 = edges.lo[:, 0].min()
    span = float(edges.hi[:, 0].max() - x0) + 2  # groups' keys apart by more than any x
    key = group * span + (edges.lo[edge, 0] - x0)
    order = np.argsort(key, kind="stable")
    edge = edge[order]
    stop = np.searchsorted(key[order], group[order] * span + (edges.hi[edge, 0] - x0) + 1e-3, "right")
    after = stop - np.arange(len(order)) - 1  # rows after each (in order) whose left is within its x span
    ends = np.cumsum(after)
    start = 0
    while start < len(order):  # blocks of at most SWEEP_PAIRS pairs
        stop_at = max(int(np.searchsorted(ends, ends[start] - after[start] + SWEEP_PAIRS, "right")), start + 1)
        c = after[start:stop_at]
        first = np.repeat(np.arange(start, stop_at), c)
        i, j = edge[first], edge[first + 1 + run_places(c)]
        meet = (edges.lo[j] <= edges.hi[i]).all(1) & (edges.lo[i] <= edges.hi[j]).all(1)
        i, j = i[meet], j[meet]
        out[edges.shape[i[edges.hit(i, j)]]] = True
        start = stop_at
    return out
