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
