"""Grown pieces in a morph: the pieces ``refine.grow`` adds to each end of an interpolation (an eye, a
mouth, a dot), put in correspondence across the two ends and interpolated with the model's paths.

The paper gets part correspondence from its data (segments clustered across the set by position and
colour). At a morph's two ends we have each picture's grown pieces; a piece of one end is matched to
the piece of the other nearest it in position, colour and size (greedily, the nearest pair first,
within ``MATCH_COST``), their contours cut into as many segments (``raster.bezier.subdivide_to``: the
same curves), turned the same way and started at the anchors that lie nearest, and interpolated point
by point. A piece left unmatched shrinks to its centre toward the end that lacks it.

Frame: pieces are ``VectorShape`` s in the model square's normalised frame ([0, 1] on both axes).
"""

from __future__ import annotations

import numpy as np
import torch

from ..raster.bezier import subdivide_to
from .image import VectorShape
from .overlaps import reverse_contour

MATCH_COST = 0.35  # pieces this far apart (normalised distance of centres + RGB distance / sqrt 3 + a tenth of
# |log area ratio|) are not the same part


def _area(contour: np.ndarray) -> float:
    """Signed area of a contour's anchor polygon."""
    x, y = contour[0::3, 0], contour[0::3, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def _centre(piece: VectorShape) -> np.ndarray:
    return np.asarray(piece.contours[0], dtype=np.float64)[0::3].mean(0)


def _cost(a: VectorShape, b: VectorShape) -> float:
    size = abs(np.log((abs(_area(a.contours[0])) + 1e-6) / (abs(_area(b.contours[0])) + 1e-6)))
    return (float(np.linalg.norm(_centre(a) - _centre(b))) + float(np.linalg.norm(np.subtract(a.color, b.color))) / 3 ** 0.5
            + 0.1 * size)


def match(a: list[VectorShape], b: list[VectorShape]) -> list[tuple[int | None, int | None]]:
    """Pairs ``(i, j)`` of pieces of ``a`` and ``b`` that are one part (same number of contours, within
    ``MATCH_COST``), nearest first; then ``(i, None)`` and ``(None, j)`` for those left."""
    pairs = sorted((_cost(p, q), i, j) for i, p in enumerate(a) for j, q in enumerate(b)
                   if len(p.contours) == len(q.contours))
    used_a, used_b, out = set(), set(), []
    for cost, i, j in pairs:
        if cost < MATCH_COST and i not in used_a and j not in used_b:
            used_a.add(i)
            used_b.add(j)
            out.append((i, j))
    return (out + [(i, None) for i in range(len(a)) if i not in used_a]
            + [(None, j) for j in range(len(b)) if j not in used_b])


def paired(ca: np.ndarray, cb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two closed cubic contours ``(3S, 2)`` as contours of one segment count, turned the same way as ``ca``
    and started so that their anchors, each about its own centre, lie nearest."""
    ca, cb = np.asarray(ca, dtype=np.float64), np.asarray(cb, dtype=np.float64)
    if np.sign(_area(ca)) != np.sign(_area(cb)):
        cb = reverse_contour(cb)
    m = max(len(ca), len(cb)) // 3
    ca, cb = (subdivide_to(torch.from_numpy(c), m).numpy() for c in (ca, cb))
    ka, kb = ca[0::3] - ca[0::3].mean(0), cb[0::3] - cb[0::3].mean(0)
    shift = min(range(m), key=lambda s: float(((ka - np.roll(kb, -s, axis=0)) ** 2).sum()))
    return ca, np.roll(cb, -3 * shift, axis=0)


def _shrunk(piece: VectorShape) -> VectorShape:
    """The piece drawn as a point at its centre: what it grows from or shrinks to."""
    c = _centre(piece)
    return VectorShape([np.broadcast_to(c, np.shape(k)).copy() for k in piece.contours], piece.color, piece.fill_rule)


def frames(a: list[VectorShape], b: list[VectorShape], ts: list[float]) -> list[list[VectorShape]]:
    """The pieces of each frame at ``ts`` (0: ``a``, 1: ``b``), matched pieces interpolated."""
    ends = []
    for i, j in match(a, b):
        p = a[i] if i is not None else _shrunk(b[j])
        q = b[j] if j is not None else _shrunk(a[i])
        contours = [paired(x, y) for x, y in zip(p.contours, q.contours)]
        ends.append((contours, np.asarray(p.color), np.asarray(q.color)))
    return [[VectorShape([(1 - t) * x + t * y for x, y in cs], tuple(((1 - t) * ca + t * cb).tolist()), "nonzero")
             for cs, ca, cb in ends] for t in ts]
