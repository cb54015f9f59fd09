"""A pixel-art picture's exact outlines: the union of a mask's pixel squares (Skia's path ops),
bounded by the corner touches that make that union slow.

Frame: ``regions``'s (pixel coordinates of the input; outer boundaries clockwise on screen).
"""

from __future__ import annotations

import numpy as np

from ..errors import TraceError
from ..raster.curves import ring_area


def pixel_polygons(mask: np.ndarray) -> list[np.ndarray]:
    """Closed rings ``(N, 2)`` along the pixel edges around ``mask (H, W)``: its exact outline
    (the union of its pixels' squares, Skia's path ops), corners only where the outline turns,
    outer boundaries clockwise on screen and holes counter-clockwise."""
    import pathops

    from ..vector import skia

    pad = np.zeros((mask.shape[0], mask.shape[1] + 2), dtype=np.int8)
    pad[:, 1:-1] = mask
    ys, xs = np.nonzero(np.diff(pad, axis=1))  # each row's runs: starts, then ends, in order
    path = pathops.Path()
    for y, x0, x1 in zip(ys[0::2].tolist(), xs[0::2].tolist(), xs[1::2].tolist()):
        path.moveTo(x0, y)
        path.lineTo(x1, y)
        path.lineTo(x1, y + 1)
        path.lineTo(x0, y + 1)
        path.close()
    rings = []
    for c in skia.contours(pathops.simplify(path, fix_winding=True)):
        ring = c[0::3]  # (N, 2): the anchors of straight sides
        d0, d1 = ring - np.roll(ring, 1, 0), np.roll(ring, -1, 0) - ring
        turn = d0[:, 0] * d1[:, 1] - d0[:, 1] * d1[:, 0]
        ring = ring[turn != 0]  # points along a straight side are not corners
        if len(ring) >= 3:
            rings.append(ring)
    if rings and float(ring_area(max(rings, key=lambda r: np.ptp(r, 0).prod()))) < 0:
        rings = [r[::-1].copy() for r in rings]  # outer boundaries clockwise on screen
    return rings


MAX_TOUCHES = 10_000  # pixels meeting only at a corner, over a hard-edged picture's exact layers: Skia's union of their
# squares grows with their square (a 2 px checkerboard: 2,209 in 0.2 s, 9,025 in 3.2 s; 65,536 ran past 60 s)


def corner_touches(mask: np.ndarray) -> int:
    """The 2 x 2 windows of ``mask (H, W)`` whose two set pixels meet only at their corner (a
    diagonal step of a dither or a checkerboard; a pixel-art diagonal line has one a pixel)."""
    a, b, c, d = mask[:-1, :-1], mask[:-1, 1:], mask[1:, :-1], mask[1:, 1:]
    return int(np.count_nonzero((a & d & ~b & ~c) | (b & c & ~a & ~d)))


class ExactOutlines:
    """``pixel_polygons`` of one picture's masks, one after another (its layers, or its pieces),
    their corner touches counted together: a ``TraceError`` when they pass ``MAX_TOUCHES``, before
    the mask that passes them reaches path ops."""

    def __init__(self):
        self.touches = 0

    def __call__(self, mask: np.ndarray) -> list[np.ndarray]:
        self.touches += corner_touches(mask)
        if self.touches > MAX_TOUCHES:
            raise TraceError(f"the picture's pixels meet only at their corners {self.touches:,} times or more (a "
                             f"dither or a checkerboard?), more than the {MAX_TOUCHES:,} im2vec outlines exactly")
        return pixel_polygons(mask)
