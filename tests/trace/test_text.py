"""Text as people bring it (issue 69). Scanned text keeps its stroke weight: a line of text
rendered clean, degraded as a scan or a phone photo degrades it (tinted paper, light falling off
to one side, blur, noise, JPEG), vectorized, and the ink of the vector render measured against
the clean line's. Screenshot text drawn with sub-pixel anti-aliasing is read as the grey text it
is, not as a picture of many colours."""

from __future__ import annotations

import io

import numpy as np
import pytest
from PIL import Image, ImageDraw, ImageFilter, ImageFont

from im2vec_cli import api
from im2vec_cli.trace.read import read, subpixel_grey
from im2vec_cli.vector import rasterize_svg

LINE = "Vectorize the pages people bring: 1984 scans"


def clean_line(size: int, wide: int = 1) -> np.ndarray:
    """The text in black on white, Pillow's own scalable face at ``size`` px (``wide`` times as
    wide): ``(H, W)`` in [0, 1]."""
    font = ImageFont.load_default(size=size)
    left, top, right, bottom = font.getbbox(LINE)
    img = Image.new("L", (right - left + 2 * size, bottom - top + 2 * size), 255)
    ImageDraw.Draw(img).text((size - left, size - top), LINE, font=font, fill=0)
    if wide > 1:
        img = img.resize((img.width * wide, img.height), Image.LANCZOS)
    return np.clip(np.asarray(img, np.float64) / 255, 0, 1)


def subpixel_line(size: int) -> np.ndarray:
    """The text drawn as an LCD's sub-pixel anti-aliasing draws it: rendered three times as wide,
    each three columns one pixel's red, green and blue: ``(H, W, 3)`` with colour fringes."""
    wide = clean_line(size, 3)
    w = wide.shape[1] // 3
    return wide[:, : 3 * w].reshape(wide.shape[0], w, 3)


def scanned(clean: np.ndarray, seed: int, quality: int = 60) -> bytes:
    """``clean`` as a scan: paper at 0.85-0.6 grey from left to right, ink at 0.12, blurred
    (sigma 0.8 px), noise of 0.03, saved as a JPEG of ``quality``."""
    h, w = clean.shape
    rng = np.random.default_rng(seed)
    paper = np.linspace(0.85, 0.6, w)[None, :] * np.ones((h, 1))
    img = paper * clean + 0.12 * (1 - clean)
    img = Image.fromarray(np.round(img * 255).astype(np.uint8)).filter(ImageFilter.GaussianBlur(0.8))
    noisy = np.asarray(img, np.float64) / 255 + rng.normal(0, 0.03, (h, w))
    buf = io.BytesIO()
    Image.fromarray(np.round(np.clip(noisy, 0, 1) * 255).astype(np.uint8)).save(buf, "JPEG", quality=quality)
    return buf.getvalue()


def ink(grey: np.ndarray) -> float:
    """The ink's area: pixels darker than half-way."""
    return float((grey < 0.5).sum())


@pytest.mark.parametrize("size,seed", [(18, 0), (28, 1), (40, 2)])
def test_scanned_text_keeps_its_stroke_weight(size, seed, tmp_path):
    clean = clean_line(size)
    data = scanned(clean, seed)
    path = tmp_path / "scan.jpg"
    path.write_bytes(data)
    svg = api.vectorize(path).to_svg()
    h, w = clean.shape
    render = rasterize_svg(svg, w, h).mean(axis=2)
    got, want = ink(render), ink(clean)
    assert abs(got - want) <= 0.10 * want, f"ink {got:.0f} px against the clean line's {want:.0f} px"


def test_subpixel_text_is_read_as_grey_text(tmp_path):
    """Sub-pixel anti-aliased text has red and blue fringes on every stroke (a screenshot's): it
    is read as two-tone text, drawn in one neutral ink, its ink area within 10% of the same text's
    grey; a colour picture of flat areas stays colour."""
    rgb = subpixel_line(20)
    assert (np.ptp(rgb, axis=-1) > 0.1).mean() > 0.02  # the fringes are there
    assert subpixel_grey(rgb) is not None and read(rgb).tone is not None
    path = tmp_path / "screen.png"
    Image.fromarray(np.round(rgb * 255).astype(np.uint8)).save(path)
    vec = api.vectorize(path)
    assert all(np.ptp(np.asarray(sh.color, float)) < 0.05 for sh in vec.shapes)  # one grey ink, no fringe colours
    h, w, _ = rgb.shape
    got, want = ink(rasterize_svg(vec.to_svg(), w, h).mean(axis=2)), ink(rgb.mean(axis=2))
    assert abs(got - want) <= 0.10 * want, f"ink {got:.0f} px against the text's {want:.0f} px"
    flat = np.ones((120, 160, 3))
    flat[20:70, 20:80] = (0.9, 0.1, 0.1)
    flat[60:110, 90:150] = (0.1, 0.2, 0.9)
    assert subpixel_grey(flat) is None
