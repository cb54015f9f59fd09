"""A photo cut into pieces of one fine colour step (trace/photo.py), and vectorized from them."""

import numpy as np
import pytest
import scipy.ndimage as ndi
from PIL import Image

from im2vec_cli import api
from im2vec_cli.trace.ndops import boxes, equal_pieces
from im2vec_cli.trace.photo import edge_agreement, pieces
from im2vec_cli.vector import rasterize_svg


def shaded(size: int = 96, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A grey ramp (0.2 to 0.8, left to right) with grain, and a sharp red disc on it; the disc's mask."""
    yy, xx = np.mgrid[:size, :size] + 0.5
    image = np.repeat((0.2 + 0.6 * xx / size)[..., None], 3, -1)
    disc = (yy - size / 2) ** 2 + (xx - size / 3) ** 2 < (size / 5) ** 2
    image[disc] = (0.85, 0.1, 0.1)
    image += np.random.default_rng(seed).normal(0, 0.01, image.shape)
    return np.clip(image, 0, 1), disc


@pytest.mark.parametrize("seed", range(3))
def test_pieces_are_connected_of_their_mean_colour_and_none_is_a_speck(seed):
    image, _ = shaded(seed=seed)
    colours, ids = pieces(image, 16)
    n = len(colours)
    assert ids.min() == 0 and ids.max() == n - 1
    assert equal_pieces(ids)[1] == n  # each piece one 4-connected piece
    assert np.bincount(ids.ravel()).min() >= 16
    means = np.stack([ndi.mean(image[..., c], ids, range(n)) for c in range(3)], -1)
    assert np.allclose(colours, means)


def test_a_sharp_edge_is_kept_and_shading_comes_in_fine_steps():
    image, disc = shaded()
    colours, ids = pieces(image, 16)
    inside, outside = ndi.binary_erosion(disc, iterations=2), ~ndi.binary_dilation(disc, iterations=2)
    assert not set(np.unique(ids[inside])) & set(np.unique(ids[outside]))  # no piece crosses the disc's edge
    ramp = colours[ids][~ndi.binary_dilation(disc, iterations=3)].mean(-1)  # the ramp's grey, piece by piece
    steps = np.abs(np.diff(np.sort(np.unique(np.round(ramp, 4)))))
    assert steps.max() < 0.08  # a grey step of 20 levels is no edge; a posterised ramp steps by 0.6 / colours
    assert np.abs(colours[ids] - image).mean() < 0.03


def test_boxes_match_scipy():
    labels = np.random.default_rng(0).integers(0, 9, (23, 31))
    assert boxes(labels, 9) == ndi.find_objects(labels + 1)


def test_a_photo_keeps_its_edges():
    """scikit-image's astronaut at 192 px: the vector photo's edges are the photo's."""
    import skimage.data

    photo = np.asarray(Image.fromarray(skimage.data.astronaut()).resize((192, 192), Image.LANCZOS)) / 255.0
    vec = api.vectorize(photo)
    render = rasterize_svg(vec.to_svg(), 192, 192)
    assert edge_agreement(photo, render) >= 0.87 and ((render - photo) ** 2).mean() <= 0.0045  # measured: 0.89, 0.0034
    # posterised to 12 colours (--colors 12, the way photos were traced before): 0.85, 0.0055


def test_noise_is_merged_down_to_the_bound(monkeypatch):
    """RGB noise has no piece of a few px: its smallest are merged until at most MAX_PIECES are left."""
    import im2vec_cli.trace.photo as photo

    monkeypatch.setattr(photo, "MAX_PIECES", 50)
    noise = np.random.default_rng(0).random((64, 64, 3))
    colours, ids = pieces(noise, 4)
    assert 1 < len(colours) <= 50 and equal_pieces(ids)[1] == len(colours)


def test_a_photo_never_has_more_pieces_than_are_traced():
    """The photo's bound on pieces is within the trace's bound on regions: at 12,000 pieces a painting
    (OpenCV's starry_night.jpg, 11,511 pieces) failed with "more than the 10,000 im2vec traces"."""
    from im2vec_cli.trace.photo import MAX_PIECES
    from im2vec_cli.trace.regions import MAX_REGIONS

    assert MAX_PIECES <= MAX_REGIONS


def drawing(size: int = 160, shaded: bool = False) -> np.ndarray:
    """Three overlapping discs on white, anti-aliased (4x supersampled); ``shaded``: each lit from
    its top left, a smooth radial gradient from its colour to white."""
    s = 4 * size
    yy, xx = (np.mgrid[:s, :s] + 0.5) / 4
    image = np.ones((s, s, 3))
    for (cy, cx, r), colour in zip([(60, 60, 40), (90, 100, 45), (110, 50, 30)],
                                   [(0.9, 0.2, 0.1), (0.1, 0.4, 0.8), (0.2, 0.7, 0.2)]):
        d = np.hypot(yy - cy, xx - cx)
        inside = d < r
        light = np.clip(np.hypot(yy - cy + r / 2, xx - cx + r / 2) / (1.5 * r), 0, 1)[..., None] if shaded else 1.0
        image[inside] = (1 - (1 - np.array(colour)) * light)[inside] if shaded else colour
    return image.reshape(size, 4, size, 4, 3).mean((1, 3))


def test_shading_is_drawn_by_pieces_and_flat_colours_by_a_palette():
    from im2vec_cli.trace.photo import agrees_better
    from im2vec_cli.trace.read import read

    flat, shaded = drawing(), drawing(shaded=True)
    assert not agrees_better(flat, 16)[0] and read(flat).kind == "logo"
    better, agreement = agrees_better(shaded, 16)
    assert better and agreement["photo_edges"] >= agreement["logo_edges"] + 0.03
    assert read(shaded).kind == "photo" and read(shaded, "logo").kind == "logo"  # a preset is obeyed
    assert read(shaded, colors=6).kind == "logo"  # and so is --colors: a palette of 6, not judged


def test_a_large_drawing_is_judged_on_its_busiest_window(monkeypatch):
    """A drawing of more than ``AGREE_PIXELS`` pixels was never judged (always a logo): a
    1512 px screenshot's anti-aliased text came out as 48 flat paths. It is now judged on its
    window with the most edges, which holds the detail wherever it lies: the shaded discs, set in
    the corner of a large white page, are read as a photo as they are alone."""
    import im2vec_cli.trace.photo as photo
    from im2vec_cli.trace.read import read

    monkeypatch.setattr(photo, "AGREE_PIXELS", 200 * 200)  # a small bound, so that the test stays quick
    page = np.ones((300, 500, 3))
    page[130:290, 330:490] = drawing(shaded=True)  # the detail in the bottom right corner
    window = photo.busiest_window(page)
    assert window.shape[0] * window.shape[1] <= 200 * 200
    assert window.shape[:2] == (200, 200) and (window < 0.9).sum() == (page < 0.9).sum()  # all the discs in it
    band = photo.busiest_window(np.ones((100, 900, 3)))  # a narrow picture: a band as tall as it is
    assert band.shape[:2] == (100, 400)
    assert photo.busiest_window(page[:150, :200]) is not None and photo.busiest_window(page[:150, :200]).shape == (
        150, 200, 3)  # small enough: the whole picture
    reading = read(page)
    assert reading.kind == "photo" and "photo_edges" in reading.figures


def test_edge_agreement():
    pic = drawing()
    assert edge_agreement(pic, pic) == 1.0
    assert edge_agreement(pic, np.ones_like(pic)) == 0.0 and edge_agreement(np.ones_like(pic), np.ones_like(pic)) == 1.0
    bars = np.ones((64, 64, 3))
    bars[:, 10:20] = bars[:, 40:50] = 0.2  # vertical edges 10 px apart or more
    shifted = np.roll(bars, 3, axis=1)  # every edge 3 px off: none within 1.5 px
    assert edge_agreement(bars, shifted) < 0.05 and edge_agreement(bars, np.roll(bars, 1, axis=1)) > 0.95


def test_small_marks_are_kept_and_grain_is_not():
    """A photo's pieces under 4x4 px are merged (grain), but marks of a few px (a screenshot's anti-aliased text,
    dots on a shaded panel), darker or lighter than all around them, are kept (``photo.marks``): by half a colour
    step in a rendered picture, which has no grain, by two steps in a grainy one, where grain adds few pieces
    (measured: 4% more than merging every small piece). Before, the 3x3 px dots vanished (rendered 0.55-1.0)."""
    from im2vec_cli.trace.photo import MARK_GRAINY, MARK_RENDERED
    from im2vec_cli.trace.read import read

    image = drawing(shaded=True)
    centres = [(20 + 10 * i, 8) for i in range(13)] + [(60, 40 + 8 * i) for i in range(6)]  # on white, on the discs
    for y, x in centres:
        image[y - 1 : y + 2, x - 1 : x + 2] = 0.05
    for grain, by in [(0.0, MARK_RENDERED), (0.01, MARK_GRAINY), (0.02, MARK_GRAINY)]:
        picture = np.clip(image + np.random.default_rng(0).normal(0, grain, image.shape), 0, 1)
        reading = read(picture)
        assert reading.kind == "photo" and (reading.speck, reading.marks) == (16, by)
        vec = api.vectorize(picture)
        render = rasterize_svg(vec.to_svg(), 160, 160)
        assert max(render[y, x].mean() for y, x in centres) < 0.3  # measured: 0.14-0.19
        if grain:
            assert len(vec.shapes) <= 1.1 * len(api.vectorize(picture, speckle=4).shapes)  # measured: 1.04


def test_a_picture_read_as_a_photo_is_cut_into_pieces_though_its_blur_looks_two_tone():
    """A small grey icon (a sheet: dark frame, near-white page, grey lines of text), blurred as a photo is, lies on
    one line from white to grey: traced as two-tone it came out one dark grey block. Read as a photo, it is its
    pieces: the page stays light and its lines keep their grey."""
    from im2vec_cli.trace.photo import PHOTO_SIGMA
    from im2vec_cli.trace.regions import background_color, trace, two_tone

    icon = np.ones((22, 22, 3))
    icon[3:19, 4:18] = 0.55
    icon[4:18, 5:17] = 0.95
    icon[7:15:2, 7:15] = 0.75
    picture = ndi.gaussian_filter(icon, (PHOTO_SIGMA, PHOTO_SIGMA, 0), mode="nearest")
    assert two_tone(picture, background_color(picture)) is not None
    greys = [r.color[0] for r in trace(picture, kind="photo", speck=4)]
    assert any(g >= 0.9 for g in greys) and any(abs(g - 0.8) < 0.05 for g in greys)  # measured: 0.95, 0.80


def test_a_mark_is_darker_or_lighter_than_all_it_touches_and_an_edges_mix_is_not():
    from im2vec_cli.trace.photo import marks

    lum = np.array([90.0, 50.0, 10.0, 12.0, 4.0])  # paper, the mix along an edge, ink, a dot, the ink's shadow
    touching = [(0, 1), (1, 2), (2, 4), (0, 3)]  # paper | mix | ink | shadow, and the dot on the paper
    a = np.array([p for p, q in touching] + [q for p, q in touching])
    b = np.array([q for p, q in touching] + [p for p, q in touching])
    assert marks(lum, a, b, 3.0).tolist() == [True, False, False, True, True]  # paper too (large: never merged)


def tinted_plus(size: int = 22) -> np.ndarray:
    """``(size, size, 3)``: a plus drawn as Tango draws a 22 px icon: a 1 px mid-blue outline, anti-aliased outside,
    around a 2 px light fill that is a tint of the outline's blue (on the white-blue line: it looks two-tone)."""
    ink, white = np.array([52, 101, 164]) / 255, np.ones(3)
    mask = np.zeros((size, size), dtype=bool)
    c = size // 2
    mask[c - 2 : c + 2, 3 : size - 3] = True  # the arms with their outline: 4 px wide
    mask[3 : size - 3, c - 2 : c + 2] = True
    fill = ndi.binary_erosion(mask, np.ones((3, 3)))  # 2 px wide inside a 1 px outline
    image = np.ones((size, size, 3))
    image[ndi.binary_dilation(mask) & ~mask] = white + 0.2 * (ink - white)  # its outer edge anti-aliased
    image[mask] = ink
    image[fill] = white + 0.35 * (ink - white)
    return image


def test_a_small_icons_tint_is_a_fill_of_its_own_not_an_edge():
    from im2vec_cli.trace import background_color, read, two_tone
    from im2vec_cli.trace.photo import tints_agree_better

    plus = tinted_plus()
    tone = two_tone(plus, background_color(plus))
    assert tone is not None  # it looks two-tone: every pixel on the white-blue line
    assert tints_agree_better(plus, background_color(plus), *tone)
    reading = read(plus)
    assert reading.palette and reading.tone is None
    svg = api.vectorize(plus).to_svg()
    back = rasterize_svg(svg, 22, 22)
    c = 11
    fill = back[c - 1 : c + 1, c - 1 : c + 1]  # where the arms cross: drawn nearer its tint than the white around
    assert (np.linalg.norm(fill - plus[c, c], axis=-1) < np.linalg.norm(fill - 1, axis=-1)).all(), fill
    assert np.abs(back[c, 3] - plus[c, 3]).max() < 0.05  # the outline's blue at the left arm's end (was 0.15 off)


@pytest.mark.parametrize("size", [24, 48, 64])
def test_an_anti_aliased_glyph_stays_two_tone(size):
    from im2vec_cli.trace import background_color, read, two_tone
    from im2vec_cli.trace.photo import tints_agree_better
    from tests.trace.test_read import drawing

    glyph = drawing(size)
    tone = two_tone(glyph, background_color(glyph))
    assert tone is not None and not tints_agree_better(glyph, background_color(glyph), *tone)
    assert read(glyph).tone is not None and not read(glyph).palette


def test_a_drawing_the_logo_reading_polishes_needs_a_wider_margin(monkeypatch):
    """Where the logo reading polishes (at most ``Plan.max_side`` px a side), its palette's raster draws hard the edges
    the polish fits: the pieces must agree by ``POLISHED_MARGIN`` more, not ``AGREE_MARGIN`` (a 64 px FaceTime logo
    whose pieces agreed 0.043 better was read as a photo, MSE 0.0069 against 0.0005 as a logo). Agreements are set."""
    import im2vec_cli.trace.photo as photo

    agreements = iter([0.90, 0.94] * 2)  # logo's, then the pieces': 0.04 better
    monkeypatch.setattr(photo, "edge_agreement", lambda picture, drawn: next(agreements))
    small = drawing(shaded=True)  # 160 px ...
    assert photo.agrees_better(small, 16)[0]
    assert not photo.agrees_better(small[::2, ::2], 16)[0]  # ... and 80 px, polished as a logo
