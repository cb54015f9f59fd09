"""Paths grown where the model's fitted paths miss a part of the picture (``--parts model``).

The model draws a class with a fixed number of paths (eight layers for emoji), too few for a face's
two eyes and mouth as well as its head and hair. After its paths are fitted, the picture's own
regions (``trace``: pixels only, no vector source) are cut into pieces, one outer contour with its
holes each, and a piece is added on top as a path of its own where drawing it in its colour lowers
the error of the render by at least ``GROW_GAIN`` pixels' worth: greedily, the most paying first,
each judged against the render with those before it, at most ``Plan.grow`` of them. The polish then
fits the grown paths with the model's, and the colours are solved (``clean.solved_colors``).

Frame: the picture's pixel frame; pictures ``(H, W, 3)`` float64 in [0, 1] on white.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..options import Plan
from ..trace import Reading, background_color, image_starts
from ..trace.outline import shape_coverage
from ..vector import VectorImage, VectorShape, fill_vector

GROW_GAIN = 1.0  # px: a piece is grown where it lowers the render's squared error (summed over RGB) by this many
# fully wrong pixels' worth (an eye of 6 px on skin gains about 8). Set with ``options.GROW`` on bench/parts.py's
# test-split runs (2 and 16 paths -> 1 and 32: emoji small parts kept 89% -> 91%); its held-out sets not tuned on
CANDIDATES = 4  # pieces weighed per path that may grow: bounds the work on a picture of thousands of pieces (a photo)
BACKGROUND_NEAR = 0.1  # RGB distance: a hole whose pixels are this near the background's colour shows the background


def pieces(shape: VectorShape) -> list[VectorShape]:
    """``shape``'s pieces: each outer contour with the holes directly inside it, one shape each, its holes wound
    against its outer contour, so that either fill rule draws it (contours nested by their anchors: a contour
    inside an odd number of others is a hole)."""
    import cv2

    from ..vector.overlaps import reverse_contour

    polys = [np.asarray(c[0::3], dtype=np.float32) for c in shape.contours]
    inside = [[j for j, q in enumerate(polys) if j != i and len(q) > 2
               and cv2.pointPolygonTest(q, tuple(float(v) for v in p[0]), False) > 0] for i, p in enumerate(polys)]
    depth = [len(js) for js in inside]
    out = []
    for i, d in enumerate(depth):
        if d % 2:
            continue
        holes = [k for k, js in enumerate(inside) if depth[k] == d + 1 and i in js]
        sign = np.sign(cv2.contourArea(polys[i], oriented=True))
        cs = [shape.contours[i]] + [shape.contours[k] if np.sign(cv2.contourArea(polys[k], oriented=True)) != sign
                                    else reverse_contour(shape.contours[k]) for k in holes]
        out.append(VectorShape(cs, shape.color, "nonzero"))
    return out


def _candidates(piece: VectorShape, picture: np.ndarray, background: np.ndarray) -> list:
    """The piece and each of its holes through which the picture's ``background`` shows (a shape of the
    background's colour: drawn on top, it opens a hole that fitted paths filled), each with the box of the
    pixels it covers and its coverage there (``_boxed``)."""
    h, w = picture.shape[:2]
    out = [_boxed(piece, shape_coverage(piece, w, h))]
    for c in piece.contours[1:]:
        hole = VectorShape([c], tuple(float(v) for v in background), "nonzero")
        cov = shape_coverage(hole, w, h)
        inside = cov > 0.5
        if inside.any() and np.linalg.norm(np.median(picture[inside], 0) - background) < BACKGROUND_NEAR:
            out.append(_boxed(hole, cov))
    return [c for c in out if c is not None]


def _over(render: np.ndarray, piece: VectorShape, coverage: np.ndarray) -> np.ndarray:
    """``render (h, w, 3)`` with ``piece`` of ``coverage (h, w)`` drawn over it in its colour."""
    return render + coverage[..., None] * (np.asarray(piece.color) - render)


def _boxed(piece: VectorShape, cov: np.ndarray) -> tuple[VectorShape, tuple[slice, slice], np.ndarray] | None:
    """A piece with the box of the pixels its coverage ``cov (h, w)`` touches and its coverage there
    (``None``: it covers none)."""
    ys, xs = np.nonzero(cov)
    if not len(ys):
        return None
    box = (slice(ys.min(), ys.max() + 1), slice(xs.min(), xs.max() + 1))
    return piece, box, cov[box]


def _gain(render: np.ndarray, picture: np.ndarray, cand) -> float:
    """How much drawing the candidate over ``render`` lowers its squared error against ``picture``."""
    piece, box, cov = cand
    now, want = render[box], picture[box]
    return float(((now - want) ** 2).sum() - ((_over(now, piece, cov) - want) ** 2).sum())


def grown(vec: VectorImage, picture: np.ndarray, reading: Reading, s: Plan) -> tuple[VectorImage, int]:
    """``vec`` (any frame) with at most ``s.grow`` pieces of the picture's own trace added on top where they
    pay (``GROW_GAIN``), judged on ``picture`` (its size: the work's), and no more than ``s.max_paths`` shapes
    in all; and how many were added. ``reading``: what the picture is (``trace.read``), which shapes its trace.
    Each round weighs only the ``CANDIDATES * s.grow`` pieces that paid most at the start, each over its box."""
    h, w = picture.shape[:2]
    most = s.grow if s.max_paths is None else min(s.grow, s.max_paths - len(vec.shapes))
    if most <= 0 or not vec.shapes:
        return vec, 0
    render = fill_vector(vec.rescaled(w, h), w, h)
    traced = image_starts([picture], s, [reading])[0].outline(s.tolerance)[0].rescaled(w, h)
    bg = background_color(picture)
    cands = [c for sh in traced.shapes for p in pieces(sh) for c in _candidates(p, picture, bg)]
    start = [_gain(render, picture, c) for c in cands]
    cands = [cands[i] for i in np.argsort(start, kind="stable")[::-1][: CANDIDATES * most]]
    added: list[VectorShape] = []
    while cands and len(added) < most:
        gains = [_gain(render, picture, c) for c in cands]
        best = int(np.argmax(gains))
        if gains[best] < GROW_GAIN:
            break
        piece, box, cov = cands.pop(best)
        render[box] = _over(render[box], piece, cov)
        added.append(piece)
    if not added:
        return vec, 0
    shapes = VectorImage(w, h, added).rescaled(vec.width, vec.height).shapes
    return dataclasses.replace(vec, shapes=list(vec.shapes) + shapes), len(added)
