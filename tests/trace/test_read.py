"""Reading a picture before tracing it (``trace.read``): its kind, and the clean picture it shows,
checked against the exact SVG each test picture is rendered from (cairosvg)."""

from __future__ import annotations

import io

import numpy as np
import pytest
import torch
from PIL import Image
from scipy.ndimage import distance_transform_edt, gaussian_filter

from im2vec_cli import api
from im2vec_cli.trace import background_color, read, two_tone
from im2vec_cli.trace.read import despeckled, noise_sigma, pixel_block, stroke_width
from im2vec_cli.vector import rasterize_svg
from tests.trace.outlines import needs_fonts, svg_of, topology

RING = '<circle cx="{c}" cy="{c}" r="{r}" fill="none" stroke="black" stroke-width="{w}"/>'


def drawing(size: int) -> np.ndarray:
    """``(H, W, 3)``: a thick ring and a bar, black on white, rendered exactly."""
    s = size / 64
    body = (RING.format(c=24 * s, r=14 * s, w=8 * s)
            + f'<rect x="{44 * s}" y="{8 * s}" width="{10 * s}" height="{48 * s}"/>')
    return rasterize_svg(svg_of(body, size), size, size)


def scanned(clean: np.ndarray, seed: int = 0) -> np.ndarray:
    """``clean`` as a phone photo makes it: warm paper, light falling off, blur, noise, JPEG 40."""
    rng = np.random.default_rng(seed)
    h, w, _ = clean.shape
    yy, xx = np.mgrid[0:h, 0:w] / max(h, w)
    light = 0.97 - 0.35 * ((xx + yy) / 2) ** 1.5
    a = 1 - clean.mean(-1, keepdims=True)
    img = (np.array([0.97, 0.93, 0.85]) * (1 - a) + np.array([0.12, 0.11, 0.15]) * a) * light[..., None]
    img = gaussian_filter(img, (1.2, 1.2, 0)) + rng.normal(0, 0.04, img.shape)
    buf = io.BytesIO()
    Image.fromarray(np.round(np.clip(img, 0, 1) * 255).astype(np.uint8)).save(buf, "JPEG", quality=40)
    return np.asarray(Image.open(buf).convert("RGB"), np.float64) / 255


def iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / max((a | b).sum(), 1))


def test_a_scan_reads_as_black_ink_on_white_paper():
    clean = drawing(256)
    r = read(scanned(clean))
    assert r.kind == "scan"
    truth, got = clean.mean(-1) < 0.5, r.picture.mean(-1) < 0.5
    assert iou(truth, got) > 0.97
    assert topology(got) == topology(truth)
    assert r.picture[gaussian_filter(got.astype(float), 2) < 0.01].min() > 0.9  # the paper is white, shaded or not
    assert r.picture[gaussian_filter(got.astype(float), 2) > 0.99].max() < 0.05  # the grey ink is black


def test_the_clean_picture_of_a_clean_render_is_itself():
    clean = drawing(128)
    r = read(clean)
    assert r.kind == "logo" and r.picture is clean and r.polish


def test_forced_scan_reads_a_clean_render_too():
    clean = drawing(128)
    r = read(clean, "scan")
    assert r.kind == "scan"
    assert iou(clean.mean(-1) < 0.5, r.picture.mean(-1) < 0.5) > 0.98


def test_noise_estimate_follows_the_noise():
    rng = np.random.default_rng(0)
    flat = np.full((128, 128, 3), 0.5)
    for sigma in (0.01, 0.03, 0.06):
        got = noise_sigma(flat + rng.normal(0, sigma, flat.shape))
        assert sigma * 0.7 < got < sigma * 1.3, (sigma, got)
    assert noise_sigma(drawing(128)) < 0.005  # edges are not noise


def test_pixel_block_finds_nearest_neighbour_upscaling():
    rng = np.random.default_rng(0)
    sprite = rng.integers(0, 5, (12, 10))
    colors = rng.uniform(0, 1, (5, 3)).round(2)
    assert pixel_block(np.kron(colors[sprite], np.ones((8, 8, 1)))) == 8
    assert pixel_block(np.kron(colors[sprite], np.ones((3, 3, 1)))) == 3
    assert pixel_block(colors[sprite]) == 1
    assert pixel_block(drawing(64)) == 1  # anti-aliased: no blocks
    cut = np.kron(colors[sprite], np.ones((8, 8, 1)))[:-3]  # the blocks do not divide the picture
    assert pixel_block(cut) == 1


@needs_fonts
def test_pixel_art_is_exact_with_one_path_a_colour():
    rng = np.random.default_rng(1)
    sprite = rng.integers(0, 6, (16, 16))
    colors = np.vstack([[1, 1, 1], rng.integers(0, 256, (5, 3)) / 255])
    big = np.kron(colors[sprite], np.ones((8, 8, 1)))
    vec = api.vectorize(torch.from_numpy(big).permute(2, 0, 1).float(), "fonts")
    assert vec.notes["kind"] == "pixel" and vec.notes["reading"]["block"] == 8
    back = rasterize_svg(vec.to_svg(), 128, 128)
    assert ((back - big) ** 2).mean() <= 1e-4
    assert len(vec.shapes) <= 6  # one path a colour


def test_thin_strokes_are_line_art():
    size = 256
    body = "".join(RING.format(c=c, r=r, w=1.5) for c, r in ((90, 60), (150, 70), (128, 30)))
    pic = rasterize_svg(svg_of(body, size), size, size)
    r = read(pic)
    assert r.kind == "line"
    assert stroke_width(pic.mean(-1) < 0.5) < 3
    assert stroke_width(drawing(256).mean(-1) < 0.5) > 10


@needs_fonts
def test_line_art_stays_lines_without_gaps():
    size = 256
    body = "".join(RING.format(c=c, r=r, w=1.5) for c, r in ((90, 60), (150, 70), (128, 30)))
    pic = rasterize_svg(svg_of(body, size), size, size)
    vec = api.vectorize(torch.from_numpy(pic).permute(2, 0, 1).float(), "fonts")
    back = rasterize_svg(vec.to_svg(), size, size)
    level = 0.75  # a 1.5 px stroke's anti-aliased pixels: any darkening counts as ink
    assert topology(back.mean(-1) < level) == topology(pic.mean(-1) < level)
    far = distance_transform_edt(pic.mean(-1) > 0.99) > 1.5  # 1.5 px off the lines: what they enclose
    assert back[far].min() > 0.9  # stays background


def test_despeckle_drops_small_pieces_and_holes_only():
    alpha = np.zeros((40, 40))
    alpha[5:7, 5:7] = 1  # a 2x2 speck
    alpha[10:30, 10:30] = 1  # a square...
    alpha[19:21, 19:21] = 0  # ...with a 2x2 pin hole
    alpha[32:38, 32:38] = 1  # a 6x6 dot
    out = despeckled(alpha, 4)
    assert out[5:7, 5:7].max() == 0 and out[19:21, 19:21].min() == 1 and out[32:38, 32:38].min() == 1
    assert (despeckled(alpha, 0) == alpha).all()


def test_a_photo_is_read_as_one_cut_into_pieces():
    import skimage.data

    photo = np.asarray(Image.fromarray(skimage.data.astronaut()).resize((128, 128), Image.LANCZOS)) / 255.0
    r = read(photo)
    assert r.kind == "photo" and r.speck == 4 * 4 and not r.polish  # PHOTO_SPECK px a side
    assert read(photo, speckle=5).speck == 25


def test_a_grey_photo_is_a_photo():
    """A grey photo's 16 grey levels at 4 bits a channel covered it whole: it read as a drawing."""
    import skimage.data

    grey = np.asarray(Image.fromarray(skimage.data.astronaut()).convert("L").resize((160, 160), Image.LANCZOS))
    assert read(np.repeat(grey[..., None] / 255.0, 3, -1)).kind == "photo"


@pytest.mark.parametrize("preset", ["scan", "logo", "line", "pixel", "photo"])
def test_every_preset_gives_a_picture_of_the_input_size(preset):
    clean = drawing(64)
    r = read(clean, preset)
    assert r.kind == preset and r.picture.shape == clean.shape


@needs_fonts
def test_vectorize_tells_its_stages_in_order():
    """``on_event`` hears each stage once, in order (the CLI's progress bar of one picture)."""
    from im2vec_cli.events import STAGES, Stage

    heard = []
    api.vectorize(torch.from_numpy(scanned(drawing(160))).permute(2, 0, 1).float(), "fonts", on_event=heard.append)
    assert [e.stage for e in heard if isinstance(e, Stage)] == list(STAGES)


def scribbles(seed: int, w: int, h: int) -> np.ndarray:
    """A phone photo of strokes and circles on paper: bench/hardening.py's scan (warm paper,
    light falling off as cosines, noise) saved as JPEG 70."""
    from bench.hardening import scan

    buf = io.BytesIO()
    scan(seed, w, h).save(buf, "JPEG", quality=70)
    return np.asarray(Image.open(buf).convert("RGB"), np.float64) / 255


def test_shaded_paper_along_the_ink_line_is_a_scan():
    """Strokes photographed on paper whose light falls off towards the ink's grey: every pixel
    lies on the paper-ink line, so the picture passes as clean two-tone, but its background is
    no one colour: it is read as a scan, and the paper comes out white."""
    pic = scribbles(2, 240, 200)
    assert two_tone(pic, background_color(pic)) is not None  # what made it look clean
    r = read(pic)
    assert r.kind in ("scan", "line")
    ink = r.picture.mean(-1) < 0.5
    assert np.median(r.picture[gaussian_filter(ink.astype(float), 2) < 0.01]) > 0.97  # white paper (faint strokes
    assert np.median(r.picture[gaussian_filter(ink.astype(float), 1) > 0.99]) < 0.05  # stay grey), black ink


def test_a_dim_grey_photo_of_dark_lines_keeps_its_grey():
    """scikit-image's retina crop (dark vessels on mid-grey, 102 px): ink on paper by its colours,
    but its "paper" is 0.4 grey. Read as a page, it came out white (MSE 0.34); it stays grey."""
    import skimage.data

    pic = np.repeat(skimage.data.microaneurysms()[..., None] / 255.0, 3, -1)
    r = read(pic)
    assert r.kind not in ("scan", "line")
    assert abs(np.median(r.picture) - np.median(pic)) < 0.05


def test_light_on_dark_is_no_ink_on_paper():
    """scikit-image's Hubble deep field as a 640 px JPEG (galaxies on a black sky) was read as a
    scan whose ink is the sky: a black page with a pale blot. Its dark ground is no ink."""
    import skimage.data

    im = Image.fromarray(skimage.data.hubble_deep_field())
    im.thumbnail((640, 640))
    buf = io.BytesIO()
    im.save(buf, "JPEG")
    r = read(np.asarray(Image.open(buf), np.float64) / 255)
    assert r.kind == "photo"


def test_a_grainy_gradient_is_no_page():
    """A black-to-white ramp with a little grain (OpenCV's sample gradient.png is one): its light fits a
    smooth surface exactly, so as a page it flattened to blank white paper (MSE 0.29). Paper is never black."""
    rng = np.random.default_rng(0)
    ramp = np.tile(np.linspace(0, 1, 300), (300, 1)) + rng.normal(0, 0.004, (300, 300))
    pic = np.repeat(np.round(np.clip(ramp, 0, 1) * 255)[..., None] / 255, 3, -1)
    r = read(pic)
    assert r.kind not in ("scan", "line")
    assert ((r.picture - pic) ** 2).mean() < 1e-3


def test_a_clean_colour_picture_is_not_read_as_a_scan():
    """A rendered colour picture (no grain) stays a logo, whatever its colours' layout."""
    body = ('<rect width="64" height="64" fill="#f4d03f"/><circle cx="32" cy="32" r="20" fill="#8e5a2b"/>'
            '<circle cx="32" cy="32" r="20" fill="none" stroke="black" stroke-width="3"/>')
    pic = rasterize_svg(svg_of(body, 128), 128, 128)
    assert read(pic).kind == "logo"


def _aliased_circles(size: int, seed: int = 1) -> np.ndarray:
    """``(size, size, 3)``: 120 flat circles of 10 colours drawn without anti-aliasing (PIL)."""
    from PIL import ImageDraw

    rng = np.random.default_rng(seed)
    img = Image.new("RGB", (size, size), "white")
    draw = ImageDraw.Draw(img)
    colors = [tuple(int(c) for c in rng.integers(0, 256, 3)) for _ in range(10)]
    for i in range(120):
        x, y, r = *rng.uniform(0, size, 2), rng.uniform(3, size / 8)
        draw.ellipse((x - r, y - r, x + r, y + r), fill=colors[i % 10])
    return np.asarray(img, np.float64) / 255


def test_a_hard_edged_drawing_of_curves_is_no_pixel_art():
    """Flat circles without anti-aliasing at 384 px were read as pixel art and traced along their
    staircases (75,196 segments, 80 s on the probe's picture): now a logo of its exact colours,
    each a curve. A sprite at its own size (16 px, or 96 px of pixel-sized features) stays pixel art."""
    from im2vec_cli.trace.outline import traced

    pic = _aliased_circles(384)
    r = read(pic)
    assert r.kind == "logo" and r.figures == {"aliased": True}
    vec, _, exact = traced(r.picture, 0.5, None, None, r.kind, r.tone)
    assert not exact and len(vec.shapes) <= 11  # one path a colour
    assert vec.num_segments < 3000
    back = rasterize_svg(vec.to_svg(), 384, 384)
    assert ((back - pic) ** 2).mean() < 0.002
    assert (np.abs(back - pic).max(-1) > 0.5).mean() < 0.01  # no colour lost, no sliver: edges only
    rng = np.random.default_rng(1)
    colors = np.vstack([[1, 1, 1], rng.integers(0, 256, (5, 3)) / 255])
    assert read(colors[rng.integers(0, 6, (16, 16))]).kind == "pixel"
    assert read(colors[rng.integers(0, 6, (96, 96))]).kind == "pixel"


def test_a_hard_edged_diagram_of_thin_lines_stays_exact():
    """Boxes, a connector and a diagonal drawn 1 px wide without anti-aliasing (320 px, few colour
    edges): drawn as curves, the diagonal vanished and the outlines thinned to hairlines, so a
    picture with a colour in lines a pixel or two wide is traced along its pixels, exactly."""
    from PIL import ImageDraw

    from im2vec_cli.trace.outline import traced

    img = Image.new("RGB", (320, 240), "white")
    draw = ImageDraw.Draw(img)
    draw.rectangle((20, 20, 140, 100), fill=(230, 230, 250), outline=(0, 0, 0))
    draw.rectangle((180, 20, 300, 100), fill=(250, 230, 200), outline=(0, 0, 0))
    draw.line((140, 60, 180, 60), fill=(0, 0, 0), width=1)
    draw.ellipse((120, 140, 200, 220), outline=(200, 0, 0), width=2)
    draw.line((20, 200, 100, 130), fill=(0, 0, 200), width=1)
    pic = np.asarray(img, np.float64) / 255
    r = read(pic)
    assert r.kind == "pixel"
    vec, _, exact = traced(r.picture, 0.5, None, None, r.kind, r.tone)
    assert exact and np.abs(rasterize_svg(vec.to_svg(), 320, 240) - pic).max() < 2 / 255


def shaded_icon(size: int = 256, seed: int = 0) -> np.ndarray:
    """``(H, W, 3)``: a desktop icon as Oxygen draws them: a grey body shaded top to bottom, a
    darker panel and a few black marks, on white (as a transparent icon looks), with a trace of
    rendering noise."""
    rng = np.random.default_rng(seed)
    img = np.ones((size, size, 3))
    y = np.linspace(0, 1, size)[:, None, None]
    body = np.s_[size // 10 : 9 * size // 10, size // 10 : 9 * size // 10]
    img[body] = (0.9 - 0.5 * y[body[0]]) * np.ones(3)
    img[size // 3 : size // 2, size // 4 : 3 * size // 4] = 0.35
    for k in range(4):
        img[2 * size // 3 : 2 * size // 3 + 6, size // 4 + 12 * k : size // 4 + 12 * k + 4] = 0.05
    return np.clip(img + rng.normal(0, 0.004, img.shape), 0, 1)


def test_a_shaded_icon_is_no_scan():
    """A grey icon shaded from light to dark is no ink on uneven paper: read as a scan (issue 69),
    Oxygen's printer icon came out as a few black marks (MSE 0.032, vtracer 0.004). In-between
    shades in steady areas tell it from a scan, whose in-between pixels are its strokes' edges."""
    from im2vec_cli.trace.read import shaded_share

    icon = shaded_icon()
    r = read(icon)
    assert r.kind != "scan", r.figures
    vec = api.vectorize(icon)
    got = rasterize_svg(vec.to_svg(), 256, 256)
    assert ((got - icon) ** 2).mean() < 0.004  # the body's shades are drawn, not dropped as paper
    assert shaded_share(np.clip((0.9 - icon.mean(-1)) / 0.85, 0, 1)) > 0.02


def test_a_small_icons_detail_is_not_smoothed_as_noise():
    """A 32 px icon's pixel-sized detail measures as noise; smoothing it away blurred Tango's
    calculator into a grey blob (issue 69): pictures of at most 64 px are read as drawn."""
    rng = np.random.default_rng(3)
    yy, xx = np.mgrid[0:32, 0:32]
    icon = np.ones((32, 32, 3))
    body = (yy >= 2) & (yy < 30) & (xx >= 2) & (xx < 30)
    icon[body] = (0.35 + 0.3 * yy / 32 + rng.uniform(0, 0.12, (32, 32)))[body][:, None] * np.array([1, 0.95, 0.9])
    assert noise_sigma(icon) > 0.012  # what the noise estimate makes of its texture
    r = read(icon)
    assert r.kind == "logo" and np.array_equal(r.picture, icon)


def test_a_scanned_bold_silhouette_is_a_scan():
    """A bold icon scanned or photographed can be mostly ink (Font Awesome's camera and house in
    bench/realworld.py's scans: 62-68%): it is still ink on light paper, read as a scan, and comes out one black
    shape. (Ink over half the picture read it as a photo of 600 paths from 4cdd3a6 to here.)"""
    size = 200
    clean = rasterize_svg(svg_of(f'<rect x="12" y="12" width="{size - 24}" height="{size - 24}" rx="30"/>'
                                 '<circle cx="100" cy="100" r="25" fill="white"/>', size), size, size)
    picture = scanned(clean)
    assert (clean.mean(-1) < 0.5).mean() > 0.65
    r = read(picture)
    assert r.kind == "scan"
    vec = api.vectorize(picture)
    assert len(vec.shapes) == 1 and iou(rasterize_svg(vec.to_svg(), size, size).mean(-1) < 0.5,
                                        clean.mean(-1) < 0.5) > 0.95


def test_a_two_colour_picture_is_traced_whole_and_a_dither_at_the_copy():
    """A picture of exactly two colours (a 1-bit scan) beyond ``Plan.work_pixels`` is read whole,
    up to ``Plan.bilevel_pixels`` (an averaged copy blurs its pixel edges: issue 69's typewritten
    page); one of three colours, or a two-colour dither (its grain is the grey it stands for), is
    read at the copy."""
    import dataclasses

    from im2vec_cli.options import Plan
    from im2vec_cli.trace.batch import bilevel, read_pictures

    page = np.ones((120, 160, 3))
    page[20:100:10, 20:140] = 0.0  # lines of "text"
    page[20:100, 30:34] = 0.0
    dither = np.ones((120, 160, 3)) * (np.indices((120, 160)).sum(0) % 2 == 0)[..., None]
    grey = page.copy()
    grey[50:60, 50:60] = 0.5
    assert bilevel(page) and not bilevel(dither) and not bilevel(grey) and bilevel(np.ones((8, 8, 3)))
    assert bilevel(page * 0.3 + 0.2)  # any two colours
    plan = dataclasses.replace(Plan(), work_pixels=60 * 80, bilevel_pixels=120 * 160)
    shapes = [r.picture.shape[:2] for r in read_pictures([page, dither, grey], plan)]
    assert shapes[0] == (120, 160) and shapes[1][0] * shapes[1][1] <= 60 * 80 and shapes[2][0] < 120
    small = dataclasses.replace(plan, bilevel_pixels=100 * 100)  # beyond its own bound too: the copy
    h, w, _ = read_pictures([page], small)[0].picture.shape
    assert h * w <= 100 * 100
