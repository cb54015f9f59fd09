"""The palette of a picture (``trace.palette``): distinct colours keep a colour of their own."""

from __future__ import annotations

import collections

import numpy as np

from im2vec_cli.trace.palette import posterize, quantize


def _nearest(palette: np.ndarray, color) -> float:
    return float(np.linalg.norm(palette - np.asarray(color), axis=1).min())


def test_a_small_area_of_a_distinct_colour_keeps_its_own():
    """A pale blue field in a black frame with a thin grey ring (2% of the picture, 0.21 from the
    blue): the mean error of one colour for both is small, and grey is a mix of black and white
    (an edge colour, not a colour of its own, by that test), but the ring is another colour."""
    yy, xx = np.mgrid[0:128, 0:128]
    pic = np.ones((128, 128, 3))
    pic[14:116, 4:124] = 0.0
    pic[20:110, 10:118] = (0.6, 0.8, 0.95)
    r = np.hypot(yy - 64, xx - 64)
    grey = (0.75, 0.78, 0.8)
    pic[(r > 12) & (r < 16)] = grey
    palette, labels = quantize(pic, None)
    assert _nearest(palette, grey) < 0.05 and _nearest(palette, (0.6, 0.8, 0.95)) < 0.05
    ring = (r > 13) & (r < 15)
    assert np.linalg.norm(palette[labels[ring]] - grey, axis=-1).max() < 0.05


def test_posterize_keeps_a_small_patch_of_a_distinct_hue():
    """A noisy orange photo with a purple patch of 2% of it: k-means in CIELAB on all pixels
    gives the patch a colour of its own, and labels cover the picture with few specks."""
    rng = np.random.default_rng(0)
    yy, xx = np.mgrid[0:160, 0:160]
    pic = np.stack([0.85 + 0 * xx, 0.35 + 0.3 * xx / 160, 0.15 + 0.1 * yy / 160], -1)
    disc = np.hypot(yy - 50, xx - 110) < 13
    pic[disc] = (0.45, 0.3, 0.75)
    pic = np.clip(pic + rng.normal(0, 0.02, pic.shape), 0, 1)
    palette, labels = posterize(pic, 8)
    assert _nearest(palette, (0.45, 0.3, 0.75)) < 0.08
    purple = np.argmin(np.linalg.norm(palette - (0.45, 0.3, 0.75), axis=1))
    assert (labels[disc] == purple).mean() > 0.95 and (labels[~disc] == purple).mean() < 0.01
    assert labels.shape == (160, 160) and len(palette) <= 8


def test_a_small_grey_area_between_black_lines_keeps_its_own_colour():
    """A grey chin (4 x 9 px, 14 flat pixels: under the share of flat pixels that would add a
    colour) in a black frame below an orange face. Grey lies on the mix of black and white, so
    the thin-colour test takes it for an edge; the far flat pixels of one colour are an area
    (``_far_area``) and get a colour of their own, and the chin is labelled grey, not white."""
    yy, xx = np.mgrid[0:64, 0:64]
    pic = np.ones((64, 64, 3))
    r = np.hypot(yy - 28, xx - 32)
    pic[r < 20] = (0.89, 0.44, 0.13)
    pic[(r >= 20) & (r < 22)] = 0.0
    pic[50:59, 25:40] = 0.0  # a black frame 2 px wide...
    grey = (0.82, 0.81, 0.81)
    pic[52:56, 27:36] = grey  # ...around the chin
    palette, labels = quantize(pic, None)
    assert _nearest(palette, grey) < 0.02 and len(palette) == 4
    assert np.linalg.norm(palette[labels[52:56, 27:36]] - grey, axis=-1).max() < 0.02


def test_a_clean_renders_small_pieces_are_kept_and_a_jpegs_specks_absorbed():
    """Small text in a screenshot (pieces of 6-20 px: letters, dots) is part of the picture, not
    specks: in a clean render (flat colours exact) pieces of 4 px or more are kept (issue 69: the
    pieces under 24 px were absorbed and a UI's labels vanished); the same picture saved as a
    JPEG has its specks absorbed as before."""
    import io

    from PIL import Image

    pic = np.ones((240, 320, 3))
    pic[20:80, 20:300] = (0.2, 0.4, 0.8)  # a banner
    pic[120:200, 40:120] = (0.85, 0.2, 0.2)  # a red panel
    marks = [(150 + 8 * (k // 10), 150 + 12 * (k % 10)) for k in range(30)]
    for y, x in marks:  # 30 'letters' of 3 x 4 px
        pic[y : y + 4, x : x + 3] = 0.1
    palette, labels = quantize(pic, None)
    dark = int(np.argmin(palette.sum(1)))
    assert palette[dark].max() < 0.2
    assert all((labels[y : y + 4, x : x + 3] == dark).all() for y, x in marks)
    buf = io.BytesIO()
    Image.fromarray(np.round(pic * 255).astype(np.uint8)).save(buf, "JPEG", quality=60)
    jpeg = np.asarray(Image.open(buf), np.float64) / 255
    _, jl = quantize(jpeg, None)
    from im2vec_cli.trace.ndops import label

    pieces = [np.bincount(label(jl == k)[0].ravel())[1:] for k in np.unique(jl)]
    assert min(int(p.min()) for p in pieces if len(p)) >= 24  # a JPEG's speck size: its specks absorbed


def test_quantize_keeps_its_last_results(monkeypatch):
    """read.read judges a drawing by its palette and the trace quantises the same picture again:
    the second call is the first's result (a copy: changing it changes nothing kept)."""
    import im2vec_cli.trace.palette as palette

    calls = []
    real = palette._quantize
    monkeypatch.setattr(palette, "_quantize", lambda *a, **k: calls.append(1) or real(*a, **k))
    monkeypatch.setattr(palette, "_kept", collections.deque(maxlen=palette.KEPT))
    pic = np.random.default_rng(3).random((24, 24, 3))
    p1, l1 = quantize(pic, None)
    l1[:] = -1
    p2, l2 = quantize(pic.copy(), None)
    assert len(calls) == 1 and (l2 >= 0).all() and np.array_equal(p1, p2)
    quantize(pic, 3)
    quantize(pic + 0.001, None)
    quantize(pic, None)  # kept are the last two: this one was pushed out
    assert len(calls) == 4
    pic[5, 5, 1] += 0.5  # the picture changed where it was kept from: quantised anew
    quantize(pic, None)
    assert len(calls) == 5


def test_two_fills_of_near_colours_keep_a_colour_each():
    """A card (248, 245, 245) covering a third of a white picture, with red pips: one colour
    between the two meets the flat pixels' mean squared error, but both are exact fills of large
    areas, farther apart than ``FILL_TIE``: each keeps its own colour, and the card is labelled apart
    from the background (issue 69: the cards of a diagram vanished into the white)."""
    pic = np.ones((120, 160, 3))
    card = (248 / 255, 245 / 255, 245 / 255)
    pic[20:100, 40:100] = card
    pic[40:50, 60:70] = (0.88, 0.07, 0.07)
    palette, labels = quantize(pic, None)
    assert _nearest(palette, card) < 0.005 and _nearest(palette, (1, 1, 1)) < 0.005
    assert np.linalg.norm(palette[labels[25:95, 45:55]] - card, axis=-1).max() < 0.005
    assert np.linalg.norm(palette[labels[:15]] - 1, axis=-1).max() < 0.005


def test_a_shaded_ramp_of_exact_colours_stays_one_colour():
    """A grey ramp of exact 8-bit levels one apart (each a fill by its share) is one chain of fills
    within ``FILL_TIE`` of each other: not cut into a colour a level."""
    pic = np.ones((64, 160, 3))
    pic[:, 40:120] = (np.round(np.linspace(132, 141, 80)) / 255)[None, :, None]
    palette, _ = quantize(pic, None)
    assert sum(float(np.abs(c - 136.5 / 255).max()) < 0.03 for c in palette) == 1


def _hairline_picture(width: float, ink: float) -> tuple[np.ndarray, np.ndarray]:
    """A white picture of 160 px (larger than the polish's, where the crest rule runs), a square of
    grey ``ink`` (a palette colour) and a line of it ``width`` px wide from (4, 10) to (110, 40) (x, y),
    its coverage of each pixel exact to 1/64 (8 x 8 samples); and the pixels it covers by 0.3 or more."""
    s = (np.arange(160 * 8) + 0.5) / 8
    yy, xx = np.meshgrid(s, s, indexing="ij")
    (x0, y0), (x1, y1) = (4, 10), (110, 40)
    dx, dy = x1 - x0, y1 - y0
    t = np.clip(((xx - x0) * dx + (yy - y0) * dy) / (dx * dx + dy * dy), 0, 1)
    inside = np.hypot(xx - x0 - t * dx, yy - y0 - t * dy) <= width / 2
    cover = inside.reshape(160, 8, 160, 8).mean((1, 3))
    pic = np.repeat((1 - cover * (1 - ink))[..., None], 3, -1)
    pic[120:150, 120:150] = ink
    return pic, cover >= 0.3


def test_a_line_thinner_than_a_pixel_is_kept_whole():
    """A grey line 0.9 px wide (a card's outline drawn at an angle) holds less grey than white wherever
    it falls across two pixels, so the larger share breaks it into dashes: each such pixel is the crest
    of a grey line across it (``RIDGE_T``) and is labelled grey, and the line is one piece end to end."""
    from im2vec_cli.trace.ndops import label

    pic, line = _hairline_picture(0.9, 0.5)
    palette, labels = quantize(pic, None)
    grey = labels == int(np.argmin(np.linalg.norm(palette - 0.5, axis=1)))
    assert grey[line].mean() > 0.9
    pieces, _ = label(grey, eight=True)
    assert len(np.unique(pieces[line])) == 1


def test_an_anti_aliased_edge_keeps_its_weight():
    """A black square whose edge column is 40% black: that column's pixels have black on one side, so
    they are no crest of a line, and take white as before (the shape is not made heavier)."""
    pic = np.ones((160, 160, 3))
    pic[40:120, 40:100] = 0.0
    pic[40:120, 100] = 0.6
    palette, labels = quantize(pic, None)
    black = int(np.argmin(np.linalg.norm(palette, axis=1)))
    assert (labels[44:116, 100] != black).all() and (labels[44:116, 44:100] == black).all()


def test_a_stroke_whose_pixels_meet_at_corners_is_not_specks():
    """A clean render's stroke a pixel wide drawn at 45 degrees (small text) is a chain of pixels that
    meet at their corners: 4-connected, each is a speck of one pixel and was absorbed into the page.
    In a clean render over 128 px specks are counted 8-connected, as regions are: the stroke stays."""
    pic = np.ones((160, 160, 3))
    pic[120:150, 120:150] = 0.0  # black is a palette colour
    idx = np.arange(10, 100)
    pic[idx, idx] = 0.0
    palette, labels = quantize(pic, None)
    black = int(np.argmin(np.linalg.norm(palette, axis=1)))
    assert (labels[idx, idx] == black).all()


def test_a_small_icons_two_pixel_fill_keeps_its_own_colour():
    """A 22 px toolbar icon (Tango's list-add): a 1 px outline round a fill two pixels wide, of a
    tint of the outline's colour shaded along the arm. No pixel of the fill has a flat 3x3, so
    before the 2x2 blocks (``palette.SMALL_FLAT``) the fill took white or the outline's colour.
    Now it keeps a colour of its own, within 0.06 of its true mean, and every fill pixel has it."""
    from im2vec_cli.trace.palette import SMALL_FLAT

    outline, tint = np.array([52, 101, 164]) / 255, np.array([160, 190, 224]) / 255
    img = np.ones((22, 22, 3))
    arm = np.zeros((22, 22), dtype=bool)
    arm[4:18, 9:13] = arm[9:13, 4:18] = True  # the cross, 4 px wide
    fill = np.zeros_like(arm)
    fill[5:17, 10:12] = fill[10:12, 5:17] = True  # its inside, 2 px wide
    img[arm] = outline
    shade = np.linspace(-0.03, 0.03, 22)[None, :, None]  # a shading along x, as Tango's gradients
    img[fill] = np.broadcast_to(tint + shade, img.shape)[fill]
    assert img.shape[0] * img.shape[1] <= SMALL_FLAT
    palette, labels = quantize(img, None)
    own = np.linalg.norm(palette - tint, axis=1).argmin()
    assert np.linalg.norm(palette[own] - tint) < 0.06
    assert (labels[fill] == own).all()
    assert (labels[arm & ~fill] != own).all()  # and the outline keeps its own
