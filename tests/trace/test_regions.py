"""The picture's regions (``trace/regions.py``): two-tone detection, the palette, hard-edged
pictures, specks and the region bound."""

from __future__ import annotations

import numpy as np
import pytest

from im2vec_cli.errors import TraceError
from im2vec_cli.trace.palette import _absorb_specks, hard_palette, quantize
from im2vec_cli.trace.regions import trace, two_tone
from tests.trace.outlines import picture


def test_two_tone_and_palette_detection():
    glyph = picture('<path d="M 10 50 L 30 8.5 L 52 50 Z"/>').permute(1, 2, 0).double().numpy()
    assert two_tone(glyph, np.ones(3)) is not None
    grey_fill = picture('<circle cx="32" cy="32" r="20" fill="#888" stroke="black" stroke-width="2"/>')
    assert two_tone(grey_fill.permute(1, 2, 0).double().numpy(), np.ones(3)) is None  # grey is a colour here
    face = picture('<circle cx="32" cy="32" r="26" fill="#fcea2b" stroke="#000" stroke-width="1.8"/>'
                   '<circle cx="24" cy="26" r="3"/><circle cx="40" cy="26" r="3"/>')
    palette, labels = quantize(face.permute(1, 2, 0).double().numpy(), None)
    assert len(palette) == 3  # white, yellow, and the thin black outline with the eyes
    assert any(np.abs(p).max() < 0.15 for p in palette)


def _blocks(size=64, block=8, colors=5, seed=1):
    rng = np.random.default_rng(seed)
    palette = rng.integers(0, 256, (colors, 3)) / 255
    grid = palette[rng.integers(0, colors, (size // block, size // block))]
    return np.kron(grid, np.ones((block, block, 1)))  # (H, W, 3), every pixel exactly one colour


def test_a_hard_edged_picture_is_traced_exactly_along_its_pixels():
    """Pixel art / a mosaic: the SVG renders back to the very pixels (cairosvg), every side a
    straight segment on the pixel grid; an anti-aliased picture of few colours is not taken
    for one."""
    from im2vec_cli.trace.outline import traced
    from im2vec_cli.vector import rasterize_svg

    img = _blocks()
    assert hard_palette(img) is not None
    vec, flags, exact = traced(img, 0.5)
    assert exact and all(f.all() for fl in flags for f in fl)  # every corner sharp
    back = rasterize_svg(vec.to_svg(), 64, 64)
    assert np.abs(back - img).max() < 2 / 255  # no seam, no crack, no rounded corner
    for sh in vec.shapes:
        for c in sh.contours:
            a = c[0::3]
            assert np.allclose(a, np.round(a)) and np.allclose(c[1::3], a + (np.roll(a, -1, 0) - a) / 3)
    aa = picture('<rect x="8.5" y="8.5" width="30" height="20" fill="#c03030"/>'
                 '<circle cx="40" cy="40" r="15" fill="#3050c0"/>').permute(1, 2, 0).double().numpy()
    assert hard_palette(aa) is None  # its edges blend two colours


@pytest.mark.parametrize("colours", [4, 40, 64, 65, 90])
def test_hard_palette_finds_the_colours_np_unique_finds(colours):
    """The palette read from a sample's colours first equals ``np.unique``'s, colours the sample
    misses (a few pixels each) included, and a colour over ``MAX_HARD_COLORS`` is refused."""
    from im2vec_cli.trace.palette import MAX_HARD_COLORS

    rng = np.random.default_rng(colours)
    pal = rng.permutation(256 ** 3)[:colours]
    labels = np.zeros((300, 300), dtype=np.int64)  # the first colour nearly everywhere...
    labels[rng.integers(0, 300, 400), rng.integers(0, 300, 400)] = rng.integers(0, colours, 400)  # ...the rest rare
    labels.ravel()[:colours] = np.arange(colours)  # (each present)
    img = np.stack([pal[labels] >> 16, (pal[labels] >> 8) & 255, pal[labels] & 255], -1) / 255
    got = hard_palette(img, pixel=True)
    if colours > MAX_HARD_COLORS:
        assert got is None
        return
    q = np.round(img * 255).astype(np.int64)
    values, inverse = np.unique(((q[..., 0] << 16) | (q[..., 1] << 8) | q[..., 2]).ravel(), return_inverse=True)
    assert np.array_equal(got[0] * 255, np.stack([values >> 16, (values >> 8) & 255, values & 255], 1))
    assert np.array_equal(got[1], inverse.reshape(300, 300))


def test_pictures_beyond_the_region_bound_are_one_trace_error(monkeypatch):
    """A one-pixel checkerboard (two-tone: its outlines) and noise (its pieces) are refused by
    count, before the work that would take minutes; --max-paths lifts the piece bound."""
    import im2vec_cli.trace.regions as regions

    monkeypatch.setattr(regions, "MAX_REGIONS", 50)
    checker = np.broadcast_to((np.indices((64, 64)).sum(0) % 2)[..., None], (64, 64, 3)).astype(float)
    with pytest.raises(TraceError, match="2,048 outlines"):
        regions.trace(checker)
    noise = np.random.default_rng(0).random((64, 64, 3))
    with pytest.raises(TraceError, match="--max-paths"):
        regions.trace(noise)
    assert len(regions.trace(noise, max_regions=10)) <= 10  # the ten largest


def test_a_checkerboard_of_corner_touches_is_refused_before_path_ops(monkeypatch):
    """A hard-edged picture whose pixels meet only at their corners (a 2 px checkerboard, read as
    pixel art) is refused by its count of corner touches, before Skia's union of its squares,
    whose time grows with their square (65,536 touches ran past a minute); a small one is traced."""
    import im2vec_cli.trace.pixels as pixels
    import im2vec_cli.trace.regions as regions

    def board(n):
        return np.broadcast_to(((np.indices((n, n)) // 2).sum(0) % 2)[..., None], (n, n, 3)).astype(float)

    m = board(8)[..., 0] > 0
    assert pixels.corner_touches(m) == 9  # the board's inner corners, 3 x 3
    assert pixels.corner_touches(np.eye(6, dtype=bool)) == 5  # a diagonal line: one a step
    assert pixels.corner_touches(np.ones((6, 6), dtype=bool)) == 0
    for max_regions in (None, 5):  # its layers, or with --max-paths its largest pieces
        calls = []
        monkeypatch.setattr(pixels, "pixel_polygons", lambda mask, calls=calls: calls.append(pixels.corner_touches(mask)) or [])
        with pytest.raises(TraceError, match="corners"):
            regions.trace(board(256), max_regions=max_regions, kind="pixel")  # 16,129 touches in its black squares
        assert max(calls, default=0) <= pixels.MAX_TOUCHES  # the mask that has them never reached path ops
        monkeypatch.undo()
    assert len(regions.trace(board(32), kind="pixel")) >= 1


def _absorb_one_at_a_time(labels, min_px):
    """The reference: each speck in turn takes the commonest label of its 4-neighbours."""
    from scipy.ndimage import binary_dilation, label

    labels = labels.copy()
    for k in np.unique(labels):
        pieces, _ = label(labels == k)
        sizes = np.bincount(pieces.ravel())
        for p in np.nonzero(sizes[1:] < min_px)[0] + 1:
            piece = pieces == p
            around = labels[binary_dilation(piece) & ~piece]
            around = around[around != k]
            if len(around):
                labels[piece] = np.bincount(around).argmax()
    return labels


def test_specks_absorbed_at_once_as_one_at_a_time():
    rng = np.random.default_rng(3)
    for size, k, min_px in ((40, 3, 4), (64, 6, 9), (33, 2, 30)):
        labels = rng.integers(0, k, (size // 4, size // 4)).repeat(4, 0).repeat(4, 1)[:size, :size]
        labels = np.where(rng.random(labels.shape) < 0.08, rng.integers(0, k, labels.shape), labels)
        assert np.array_equal(_absorb_specks(labels, min_px), _absorb_one_at_a_time(labels, min_px))


def test_a_piece_reaches_under_a_stroke_to_its_middle_never_to_its_far_side():
    """``_hidden_reach``: the pieces on either side of a 4 px stroke drawn over them claim two
    columns each (they meet under its middle, so a stroke polished thinner opens no gap); beside a
    2 px stroke over the background a piece claims one column; under a wide one at most
    ``HIDDEN_REACH`` columns."""
    from im2vec_cli.trace.regions import HIDDEN_REACH, _hidden_reach

    cols = np.arange(30)[None].repeat(12, 0)
    left, stroke, right = cols < 10, (cols >= 10) & (cols < 14), cols >= 14
    assert np.array_equal(np.unique(cols[_hidden_reach(left, stroke)]), [10, 11])
    assert np.array_equal(np.unique(cols[_hidden_reach(right, stroke)]), [12, 13])
    thin = (cols >= 10) & (cols < 12)  # the background from column 12 on
    assert np.array_equal(np.unique(cols[_hidden_reach(left, thin)]), [10])
    wide = cols >= 10
    assert np.array_equal(np.unique(cols[_hidden_reach(left, wide)]), np.arange(10, 10 + HIDDEN_REACH))
    assert not _hidden_reach(left, np.zeros_like(left)).any()


def test_a_white_panel_on_a_grey_canvas_is_drawn_white():
    """A screenshot whose border is grey (the canvas the SVG is drawn on) with a white panel along its
    top edge: the white around a picture is left to the canvas only where the canvas is white (issue
    69: the panel came out the canvas's grey). Rendered by cairosvg, the panel is white again."""
    from im2vec_cli.trace.ndops import gaussian
    from im2vec_cli.trace.outline import traced
    from im2vec_cli.vector import rasterize_svg

    pic = np.full((96, 160, 3), 0.9)
    pic[:40] = 1.0  # the panel, touching the top, left and right edges
    pic[60:80, 20:60] = (0.15, 0.35, 0.85)
    pic[12:22, 30:130] = 0.05  # a bar on the panel
    pic = gaussian(pic, 0.7)  # anti-aliased: quantised, not taken for a hard-edged picture
    vec, _, exact = traced(pic, 0.5)
    assert not exact
    out = rasterize_svg(vec.to_svg(), 160, 96)
    assert np.abs(out[2:10, 5:155] - 1.0).max() < 0.02 and np.abs(out[85:94, 5:155] - 0.9).max() < 0.02
    assert np.abs(out[64:76, 24:56] - (0.15, 0.35, 0.85)).max() < 0.02


def _logo_with_a_faint_line(peak: float) -> np.ndarray:
    """A 96 px picture, white, with a black disc (the ink) and apart from it a thin grey line 30 px long whose
    darkest pixels are ``peak`` of the ink (a logo's credit line): ``(H, W, 3)``."""
    y, x = np.mgrid[0:96, 0:96] + 0.5
    disc = np.clip(20.5 - np.hypot(x - 40, y - 40), 0, 1)
    line = peak * np.clip(1 - np.abs(y - 80.5), 0, 1) * ((x > 20) & (x < 50))  # 1 px thin, its centre on a row
    return np.repeat(1 - np.maximum(disc, line)[..., None], 3, -1)


def test_a_two_tone_logos_faint_marks_are_drawn_in_their_own_tone(monkeypatch):
    """Marks lighter than half the ink, which the ink's 0.5 level drops, are regions of their own tone drawn out to
    ``FAINT_LEVEL`` of their peak; asked for two tones (``--colors 1``), or where there are more than ``FAINT_MOST``
    of them (grain), only the ink."""
    from im2vec_cli.trace import regions as module
    from im2vec_cli.trace.outline import traced
    from im2vec_cli.vector import rasterize_svg

    pic = _logo_with_a_faint_line(0.4)
    greys = [r for r in trace(pic, kind="logo") if 0.5 < r.color[0] < 0.7]
    assert len(greys) == 1 and abs(greys[0].color[0] - 0.6) < 0.02
    vec, _, _ = traced(pic, 0.5, kind="logo")
    drawn = 1 - rasterize_svg(vec.to_svg(), 96, 96).mean(-1)
    assert drawn[80, 22:48].min() > 0.3 and drawn[78, 22:48].max() < 0.05  # the line, no wider than 1-2 px
    assert not [r for r in trace(pic, colors=1, kind="logo") if 0.05 < r.color[0] < 0.95]
    assert not [r for r in trace(_logo_with_a_faint_line(0.9), kind="logo") if 0.05 < r.color[0] < 0.95]
    monkeypatch.setattr(module, "FAINT_MOST", 0)
    assert not [r for r in trace(pic, kind="logo") if 0.05 < r.color[0] < 0.95]
