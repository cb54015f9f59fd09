"""The made sets of bench/realworld.py: pictures built here from packages no shipped model trained
on, degraded as a phone photo or a scan makes them (the sets are listed in realworld.py's docstring).

``make_sets`` draws every random choice from one generator in a fixed order (scans, line, large),
so the sets are the same in every run.
"""

from __future__ import annotations

import io
import re
import sys
from pathlib import Path

import numpy as np
from PIL import Image, ImageFilter

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT / "bench"))

from im2vec_cli.vector import rasterize_svg  # noqa: E402
from outlines import held_out_fonts  # noqa: E402

LOGOS = ["linkedin", "openfoodfact", "recycling-symbol", "no-entry", "radioactive", "peace-symbol", "yin-yang",
         "stop-sign"]
LARGE_LOGOS = ["rainbow", "1st-place-medal"]
SPRITES = ["black-cat", "duck", "moai", "latte-macchiato", "red-heart", "rocket", "cherries", "strawberry"]
WORDS = ["Hamburg", "vector 42", "fox jumps"]
FACES = {("FreeSans", "Bold"), ("FreeSerif", "Regular"), ("Lato", "Black"), ("Lato", "Regular"), ("FreeSerif", "Bold")}


def _png(arr: np.ndarray) -> bytes:
    buf = io.BytesIO()
    Image.fromarray(np.round(np.clip(arr, 0, 1) * 255).astype(np.uint8)).save(buf, "PNG")
    return buf.getvalue()


def _jpeg(arr: np.ndarray, quality: int) -> bytes:
    buf = io.BytesIO()
    Image.fromarray(np.round(np.clip(arr, 0, 1) * 255).astype(np.uint8)).save(buf, "JPEG", quality=quality)
    return buf.getvalue()


def text_svg(font, text: str, height: int, margin: float = 0.12) -> tuple[str, int]:
    """``(svg, width)``: ``text`` in ``font`` (fontTools) on a canvas ``height`` px high, black."""
    from fontTools.pens.svgPathPen import SVGPathPen
    from fontTools.pens.transformPen import TransformPen

    gs, cmap, hmtx = font.getGlyphSet(), font.getBestCmap(), font["hmtx"]
    upm = font["head"].unitsPerEm
    asc, desc = font["hhea"].ascent, font["hhea"].descent
    scale = height * (1 - 2 * margin) / (asc - desc)
    pen, x = SVGPathPen(gs), margin * height / scale
    for ch in text:
        name = cmap.get(ord(ch))
        if name is None:
            continue
        gs[name].draw(TransformPen(pen, (1, 0, 0, 1, x, 0)))
        x += hmtx[name][0]
    width = int(round(x * scale + margin * height))
    del upm
    tf = f"matrix({scale} 0 0 {-scale} 0 {margin * height + asc * scale})"
    return (f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" viewBox="0 0 {width} {height}">'
            f'<path transform="{tf}" d="{pen.getCommands()}"/></svg>'), width


def degrade(clean: np.ndarray, rng: np.random.Generator) -> bytes:
    """A scan or phone photo of the black-on-white ``clean (H, W, 3)``: tinted paper and ink,
    light falling off across the page, blur, noise, JPEG quality 40."""
    h, w, _ = clean.shape
    yy, xx = np.mgrid[0:h, 0:w] / max(h, w)
    ang = rng.uniform(0, 2 * np.pi)
    ramp = np.cos(ang) * xx + np.sin(ang) * yy
    ramp = (ramp - ramp.min()) / max(np.ptp(ramp), 1e-9)
    light = 0.97 - rng.uniform(0.25, 0.4) * ramp ** 1.5
    paper = np.array([0.98, 0.95, 0.87]) - rng.uniform(0, 0.05)
    ink = np.array([0.1, 0.1, 0.14]) + rng.uniform(0, 0.06)
    a = 1 - clean.mean(-1, keepdims=True)
    img = (paper * (1 - a) + ink * a) * light[..., None]
    blurred = Image.fromarray(np.round(np.clip(img, 0, 1) * 255).astype(np.uint8))
    blurred = blurred.filter(ImageFilter.GaussianBlur(rng.uniform(0.8, 1.5)))
    noisy = np.asarray(blurred, np.float64) / 255 + rng.normal(0, rng.uniform(0.03, 0.05), img.shape)
    return _jpeg(noisy, 40)


def _om_svg(src: Path, name: str) -> str:
    import json

    data = json.loads((src / "om" / "package" / "icons.json").read_text())
    w, h = data.get("width", 72), data.get("height", 72)
    return f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {w} {h}">{data["icons"][name]["body"]}</svg>'


def _fa(src: Path, names: list[str]) -> list[tuple[str, str]]:
    d = src / "fa" / "package" / "svgs" / "solid"
    return [(n, (d / f"{n}.svg").read_text()) for n in names]


def _stroked(svg: str, width_px: float, size: int) -> str:
    """``svg`` (a Font Awesome icon) drawn as ``width_px`` px black strokes at ``size`` px, unfilled."""
    vb = [float(v) for v in re.search(r'viewBox="([^"]+)"', svg).group(1).split()]
    sw = width_px * max(vb[2], vb[3]) / size
    svg = re.sub(r'\s(fill|stroke|stroke-width)="[^"]*"', "", re.sub(r"<!--.*?-->", "", svg))
    return re.sub(r"<path ", f'<path fill="none" stroke="black" stroke-width="{sw:.3f}" ', svg)


def curves_svg(rng: np.random.Generator, size: int) -> str:
    """Overlapping stroked circles, lines and curves, 1-2 px wide, at ``size`` px."""
    parts = []
    for _ in range(int(rng.integers(3, 6))):
        (x, y), r = rng.uniform(0.25, 0.75, 2) * size, rng.uniform(0.1, 0.25) * size
        parts.append(f'<circle cx="{x:.1f}" cy="{y:.1f}" r="{r:.1f}" fill="none" stroke="black" '
                     f'stroke-width="{rng.uniform(1, 2):.2f}"/>')
    for _ in range(int(rng.integers(2, 4))):
        p = rng.uniform(0.08, 0.92, (4, 2)) * size
        parts.append(f'<path d="M {p[0, 0]:.1f} {p[0, 1]:.1f} C {p[1, 0]:.1f} {p[1, 1]:.1f} {p[2, 0]:.1f} '
                     f'{p[2, 1]:.1f} {p[3, 0]:.1f} {p[3, 1]:.1f}" fill="none" stroke="black" '
                     f'stroke-width="{rng.uniform(1, 2):.2f}" stroke-linecap="round"/>')
    return f'<svg xmlns="http://www.w3.org/2000/svg" width="{size}" height="{size}">{"".join(parts)}</svg>'


def _sprite(svg: str, side: int, colors: int) -> np.ndarray:
    """``svg`` as a ``side`` px sprite of at most ``colors`` colours (no dithering), upscaled 8x."""
    small = Image.fromarray(np.round(rasterize_svg(svg, side, side) * 255).astype(np.uint8))
    small = small.quantize(colors, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE).convert("RGB")
    return np.asarray(small.resize((side * 8, side * 8), Image.NEAREST), np.float64) / 255


def make_sets(src: Path, names: list[str], limit: int | None) -> dict[str, list[dict]]:
    """Per set, its pictures: ``name``, ``input`` (file bytes, PNG or JPEG) and ``clean`` (the
    picture it was made from, ``(H, W, 3)`` in [0, 1])."""
    rng = np.random.default_rng(0)
    fonts = dict(held_out_fonts(lambda f: f in FACES))
    made = {"scans": lambda: _scans(src, fonts, rng), "logos": lambda: _logos(src), "pixel": lambda: _pixel(src),
            "line": lambda: _line(src, rng), "photos": _photos, "large": lambda: _large(fonts, rng)}
    sets = {name: make() for name, make in made.items() if name in names}  # in this order: one rng
    return {name: rows[:limit] if limit else rows for name, rows in sets.items()}


def _scans(src: Path, fonts: dict, rng: np.random.Generator) -> list[dict]:
    rows = []
    for i, (face, ch) in enumerate([(("FreeSans", "Bold"), "g"), (("FreeSerif", "Regular"), "R"),
                                    (("Lato", "Black"), "&"), (("Lato", "Regular"), "B")]):
        size = int(rng.integers(400, 601))
        svg, w = text_svg(fonts[face], ch, size)
        svg = svg.replace(f'width="{w}"', f'width="{size}"').replace(f"0 0 {w} ", f"0 0 {size} ")
        rows.append({"name": f"glyph{i}", "svg": svg, "size": (size, size)})
    for i, word in enumerate(WORDS):
        svg, w = text_svg(fonts[[("Lato", "Regular"), ("FreeSerif", "Bold"), ("FreeSans", "Bold")][i]], word, 160)
        rows.append({"name": f"word{i}", "svg": svg, "size": (w, 160)})
    for name, svg in _fa(src, ["house", "camera", "bicycle"]):
        rows.append({"name": name, "svg": svg, "size": (500, 500)})
    for name, svg in _fa(src, ["gear", "tree"]):  # large scans
        rows.append({"name": f"{name} (1024 px)", "svg": svg, "size": (1024, 1024)})
    for r in rows:
        r["clean"] = rasterize_svg(r["svg"], *r["size"])
        r["input"] = degrade(r["clean"], rng)
    return rows


def _logos(src: Path) -> list[dict]:
    rows = []
    for i, n in enumerate(LOGOS + LARGE_LOGOS):
        side = 512 if n in LOGOS else 1024
        clean = rasterize_svg(_om_svg(src, n), side, side)
        rows.append({"name": n + (" (jpeg)" if i % 2 else "") + (f" ({side} px)" if side > 512 else ""),
                     "clean": clean, "input": _jpeg(clean, 70) if i % 2 else _png(clean)})
    return rows


def _pixel(src: Path) -> list[dict]:
    rows = []
    for i, n in enumerate(SPRITES):
        clean = _sprite(_om_svg(src, n), [16, 24, 32][i % 3], 12)
        rows.append({"name": n, "clean": clean, "input": _png(clean)})
    return rows


def _line(src: Path, rng: np.random.Generator) -> list[dict]:
    rows = []
    for n, svg in _fa(src, ["bicycle", "camera", "star", "gear"]):
        clean = rasterize_svg(_stroked(svg, 1.5, 512), 512, 512)
        rows.append({"name": n, "clean": clean, "input": _png(clean)})
    for i in range(4):
        clean = rasterize_svg(curves_svg(rng, 512), 512, 512)
        rows.append({"name": f"curves{i}", "clean": clean, "input": _png(clean)})
    return rows


def _photos() -> list[dict]:
    import skimage.data

    rows = []
    for n in ("astronaut", "coffee", "chelsea"):
        clean = getattr(skimage.data, n)() / 255.0
        rows.append({"name": n, "clean": clean, "input": _png(clean)})
    return rows


def _large(fonts: dict, rng: np.random.Generator) -> list[dict]:
    font = fonts[("FreeSerif", "Regular")]
    lines = ["The quick brown fox", "jumps over the lazy", "dog; 0123456789", "Pack my box with", "five dozen jugs."]
    page = np.ones((2048, 2048, 3))
    for k, line in enumerate(lines):
        svg, w = text_svg(font, line, 300)
        img = rasterize_svg(svg, w, 300)[:, :1900]
        page[100 + 370 * k : 400 + 370 * k, 74 : 74 + img.shape[1]] = img
    return [{"name": "page2048", "clean": page, "input": degrade(page, rng)}]
