"""refine/projections.py: what the outline polish keeps after every step. A two-tone picture's
lines stay lines (their handles at the chord's thirds) and a smooth join beside a line turns along
it; without the hold the same polish bends them (so the check can fail)."""

import numpy as np
import torch

from im2vec_cli.options import Plan
from im2vec_cli.raster import set_compile
from im2vec_cli.raster.bezier import line_controls
from im2vec_cli.refine.core import _Fitter
from im2vec_cli.vector import VectorImage, VectorShape, rasterize_svg, to_svg


def _contour(segments):
    """``(3K, 2)`` from ``[(anchor, handle, handle)]``; ``None`` handles: a line to the next anchor."""
    out = []
    for k, (a, h1, h2) in enumerate(segments):
        b = np.asarray(segments[(k + 1) % len(segments)][0], dtype=np.float64)
        a = np.asarray(a, dtype=np.float64)
        out += [a, *(line_controls(a, b) if h1 is None else (np.asarray(h1, float), np.asarray(h2, float)))]
    return np.array(out)


def _polished(contour, corners, straight):
    """``contour`` polished for 40 steps against a disc of radius 15 at the centre of a 48 px picture."""
    set_compile(False)
    try:
        disc = VectorImage(48, 48, [VectorShape([_contour([((39, 24), (39, 32.3), (32.3, 39)), ((24, 39), (15.7, 39), (9, 32.3)),
                                                            ((9, 24), (9, 15.7), (15.7, 9)), ((24, 9), (32.3, 9), (39, 15.7))])],
                                                 (0, 0, 0), "nonzero")])
        img = torch.from_numpy(rasterize_svg(to_svg(disc), 48, 48)).permute(2, 0, 1).float()
        vec = VectorImage(48, 48, [VectorShape([contour], (0, 0, 0), "evenodd")])
        out = _Fitter(img[None], 8, Plan()).fit_points([vec], 40, 0.3, False, "outline", None, smooth=[[[corners]]],
                                                      straight=[straight])[0][0]
    finally:
        set_compile(None)
    return out.shapes[0].contours[0]


def _bend(c, k):
    """Px: how far segment ``k``'s handles of contour ``c (3K, 2)`` lie from its chord's thirds."""
    a, b = c[3 * k], c[(3 * k + 3) % len(c)]
    h1, h2 = line_controls(a, b)
    return max(np.hypot(*(c[3 * k + 1] - h1)), np.hypot(*(c[3 * k + 2] - h2)))


def test_a_two_tone_pictures_lines_stay_lines_in_the_polish():
    """A square (four lines, four corners) polished towards a disc: held, its sides stay lines while its
    corners move in; not held, the sides bow out towards the disc."""
    square = _contour([((12, 12), None, None), ((36, 12), None, None), ((36, 36), None, None), ((12, 36), None, None)])
    corners = np.ones(4, dtype=bool)
    held = _polished(square, corners, True)
    assert max(_bend(held, k) for k in range(4)) < 1e-4
    assert np.abs(held[0::3] - square[0::3]).max() > 0.3  # the corners moved
    free = _polished(square, corners, False)
    assert max(_bend(free, k) for k in range(4)) > 0.3


def test_a_smooth_join_beside_a_held_line_turns_along_the_line():
    """A line into a curve through a smooth join: held, the curve leaves the join along the line (the
    handles collinear with it, the line still a line); the join of two lines is left free to bend."""
    shape = _contour([((12, 12), None, None), ((30, 12), (36, 12), (36, 20)), ((36, 36), None, None),
                      ((12, 36), None, None)])
    corners = np.array([True, False, True, True])  # the join at (30, 12): smooth
    out = _polished(shape, corners, True)
    assert _bend(out, 0) < 1e-4  # the line stays a line
    along = (out[3] - out[0]) / np.hypot(*(out[3] - out[0]))
    leave = (out[4] - out[3]) / np.hypot(*(out[4] - out[3]))
    assert abs(along[0] * leave[1] - along[1] * leave[0]) < 1e-4 and along @ leave > 0


def test_a_join_of_two_held_lines_may_bend():
    """A side halved into two lines at a smooth join (as ``trace.split_where_wrong`` halves a segment):
    both halves stay lines, and their join leaves the line through its neighbours to meet the disc."""
    square = _contour([((12, 12), None, None), ((24, 12), None, None), ((36, 12), None, None), ((36, 36), None, None),
                       ((12, 36), None, None)])
    out = _polished(square, np.array([True, False, True, True, True]), True)
    assert _bend(out, 0) < 1e-4 and _bend(out, 1) < 1e-4
    a, m, b = out[0], out[3], out[6]
    off = abs((b - a)[0] * (m - a)[1] - (b - a)[1] * (m - a)[0]) / np.hypot(*(b - a))
    assert off > 0.3
