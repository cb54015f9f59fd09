"""Closed cubic contours <-> Skia paths (``skia-pathops``): the one conversion both the SVG
reader (strokes to fills) and the clean outlines (``outline.untangle``) use.

Frame: whatever frame the contours are in; Skia keeps it. Chains are ``(1 + 3S, 2)``
(anchor, control, control, anchor, ...) with a flag for whether they are closed; contours use
the wrap-around layout ``(3S, 2)`` of ``raster/bezier.py``.
"""

from __future__ import annotations

import numpy as np

from ..raster.curves import line_controls


def to_path(chains: list[tuple[np.ndarray, bool]], fill_rule: str = "nonzero"):
    """A ``pathops.Path`` of cubic chains under ``fill_rule``."""
    import pathops

    path = pathops.Path(fillType=pathops.FillType.EVEN_ODD if fill_rule == "evenodd" else pathops.FillType.WINDING)
    for ch, closed in chains:
        path.moveTo(*ch[0])
        for i in range(1, len(ch), 3):
            path.cubicTo(*ch[i], *ch[i + 1], *ch[i + 2])
        if closed:
            path.close()
    return path


def contour_chain(contour: np.ndarray) -> tuple[np.ndarray, bool]:
    """A closed contour ``(3S, 2)`` as a closed chain (its first anchor repeated at the end)."""
    c = np.asarray(contour, dtype=np.float64)
    return np.vstack([c, c[:1]]), True


def close_chain(chain: np.ndarray) -> np.ndarray | None:
    """A chain closed as a fill closes it (a straight line back to its start where needed):
    ``(3S, 2)`` in the wrap-around layout, or ``None`` when it encloses nothing."""
    if not np.allclose(chain[-1], chain[0]):
        a, b = chain[-1], chain[0]
        chain = np.concatenate([chain, np.stack([*line_controls(a, b), b])])
    return chain[:-1] if len(chain) > 3 else None  # the last anchor is the start again


def contours(path) -> list[np.ndarray]:
    """A Skia path's contours as closed cubic contours ``(3S, 2)``: lines and quadratics
    (conics converted first) raised to cubics, every contour closed."""
    from fontTools.pens.basePen import decomposeQuadraticSegment

    out, cur = [], []
    for verb, pts in path.segments:
        if verb == "moveTo":
            cur = [list(pts[0])]
        elif verb == "lineTo":
            a, b = np.asarray(cur[-1]), np.asarray(pts[0])
            cur.extend([*map(list, line_controls(a, b)), list(b)])
        elif verb == "curveTo":
            cur.extend([list(p) for p in pts])
        elif verb == "qCurveTo":
            if pts[-1] is None:  # a closed contour of off-curve points only: it starts between the last and first
                start = tuple((np.asarray(pts[-2]) + np.asarray(pts[0])) / 2)
                cur, pts = [list(start)], (*pts[:-1], start)
            for q, b in decomposeQuadraticSegment(pts):
                a, q, b = np.asarray(cur[-1]), np.asarray(q), np.asarray(b)
                cur.extend([list(a + 2 * (q - a) / 3), list(b + 2 * (q - b) / 3), list(b)])
        elif verb in ("closePath", "endPath") and len(cur) > 1:
            c = close_chain(np.asarray(cur, dtype=np.float64))
            if c is not None:
                out.append(c)
            cur = []
    return out
