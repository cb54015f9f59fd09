"""refine/clean.py: the clean-outline stage list, with a refinement and without one (NumPy only)."""

from __future__ import annotations

import subprocess
import sys

import pytest

from im2vec_cli.options import Plan
from im2vec_cli.refine.clean import clean_outlines, trace_alone
from im2vec_cli.trace import read
from im2vec_cli.vector import rasterize_svg
from tests.trace.test_read import drawing, iou


class NoRenderer:
    def loss(self, vecs, index):
        raise AssertionError("a draft renders nothing")

    def polish_outline(self, vecs, flags, index):
        raise AssertionError("a draft polishes nothing")


def test_a_draft_traces_and_fits_without_rendering():
    clean = drawing(64)
    (vec, info), = clean_outlines([clean], NoRenderer(), Plan(outline_steps=0))
    back = rasterize_svg(vec.to_svg(), 64, 64)
    assert iou(back.mean(-1) < 0.5, clean.mean(-1) < 0.5) > 0.95 and info["loss_end"] is None


def test_a_picture_to_polish_needs_a_refinement():
    with pytest.raises(ValueError, match="needs a refinement"):
        clean_outlines([drawing(64)], None, Plan())  # 64 px, polished by default
    (vec, info), = trace_alone([read(drawing(200))], [(400, 400)], Plan())  # 200 px: not polished
    assert (vec.width, vec.height) == (400.0, 400.0) and vec.shapes and info["kind"] and info["loss_end"] is None


class Recording:
    """A renderer that polishes nothing and hears, per picture, whether its lines were held straight."""

    def __init__(self):
        self.held = []

    def loss(self, vecs, index):
        return [1.0] * len(vecs)

    def polish_outline(self, vecs, flags, index, straight):
        self.held += straight
        return vecs


@pytest.mark.parametrize("tolerance, held", [(0.5, True), (1.0, False)])
def test_a_two_tone_pictures_lines_are_held_only_when_fitted_close(tolerance, held):
    """Lines fitted within 0.5 px stay lines in the polish; fitted 1 px off, one may stand off a junction the
    ink curves into, and held straight it cracked 2 of 620 glyphs (bench/outlines.py)."""
    run = Recording()
    picture = drawing(64)
    clean_outlines([picture], run, Plan(tolerance=tolerance, split_error=0, model_start=False), readings=[read(picture)])
    assert run.held and set(run.held) == {held}


def test_the_stage_list_without_a_renderer_imports_no_torch():
    code = ("import sys, numpy as np; from im2vec_cli.refine.clean import trace_alone; from im2vec_cli.trace import read;"
            "from im2vec_cli.options import Plan; p = np.ones((300, 300, 3)); p[100:200, 80:220] = 0;"
            "v, _ = trace_alone([read(p)], [(300, 300)], Plan())[0]; assert v.shapes; print('torch' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_solved_colours_are_those_a_viewer_shows():
    """Colours are solved against the pixels cairosvg draws (an independent renderer) from wrong starting colours; a
    shape hidden under another keeps its own."""
    import numpy as np

    from im2vec_cli.refine.clean import solved_colors
    from im2vec_cli.vector import VectorImage, VectorShape

    def box(x0, y0, x1, y1):  # a closed cubic path of 4 straight segments
        corners = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=float)
        return np.concatenate([np.stack([a, a + (b - a) / 3, a + 2 * (b - a) / 3]) for a, b in
                               zip(corners, np.roll(corners, -1, 0))])

    ring = [box(4, 4, 28, 28), box(10, 10, 22.5, 22.5)[::-1]]  # a square with a hole, edges off the pixel grid
    truth = VectorImage(32, 32, [VectorShape([box(0, 0, 32, 32)], (0.9, 0.95, 1.0)),
                                 VectorShape([box(11, 11, 21, 21)], (0.1, 0.8, 0.2)),  # in the ring's hole
                                 VectorShape(ring, (0.2, 0.4, 0.64), "evenodd"),
                                 VectorShape([box(13, 13, 19, 19)], (0.3, 0.3, 0.3))])  # (a few px: pulled to its own)
    picture = rasterize_svg(truth.to_svg(decimals=3), 32, 32)
    wrong = VectorImage(32, 32, [VectorShape(s.contours, (0.5, 0.5, 0.5), s.fill_rule) for s in truth.shapes])
    got = solved_colors(wrong, picture)
    for s, t in zip(got.shapes, truth.shapes):  # within 3 levels of 255: 8-bit pixels, the ridge's pull
        assert np.abs(np.array(s.color) - t.color).max() < 3 / 255, (s.color, t.color)
    hidden = VectorImage(32, 32, [*truth.shapes, VectorShape([box(0, 0, 32, 32)], (0.0, 0.0, 0.0)),
                                  VectorShape([box(2, 2, 6, 6)], (0.7, 0.1, 0.1))])
    hidden.shapes[0] = VectorShape(hidden.shapes[0].contours, (0.25, 0.5, 0.75))  # under the black page: unseen
    got = solved_colors(hidden, rasterize_svg(hidden.to_svg(decimals=3), 32, 32))
    assert np.abs(np.array(got.shapes[0].color) - (0.25, 0.5, 0.75)).max() < 0.02
    assert np.abs(np.array(got.shapes[-1].color) - (0.7, 0.1, 0.1)).max() < 3 / 255
