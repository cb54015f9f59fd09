"""The last guarantee of a clean outline: no loops, no crossings.

A polished corner can fold a loop a fraction of a pixel wide; ``untangle`` replaces each shape
whose contours cross by the exact outline of what it fills (Skia path ops, through
``vector/skia.py``). Frame: the pixel frame of the picture.
"""

from __future__ import annotations

import numpy as np

from ..vector import VectorImage, VectorShape, skia
from .simplify import simplify_contour


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
