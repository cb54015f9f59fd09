"""docs/outlines.png: input | potrace | vtracer | im2vec, rendered at 4x by cairosvg, for a
glyph, an icon and an emoji that no shipped model trained on (the sets of bench/outlines.py).

Run: ``make bench-outlines`` first (it fetches the sets), then ``python docs/make_outlines_figure.py``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))
sys.path.insert(0, str(ROOT / "src"))

import outlines as ol  # noqa: E402
from im2vec_cli import api  # noqa: E402
from im2vec_cli.files import load_image  # noqa: E402
from im2vec_cli.vector import rasterize_svg  # noqa: E402

PICKS = [("glyphs", "FreeSerif-Bold Italic-0067"), ("glyphs", "Lato-Black-0052"), ("icons", "dragon"),
         ("emoji", "grinning-face-with-sweat")]
SIDE = 256


def main():
    src = ROOT / "bench" / ".sets"
    sets = {"glyphs": lambda: ol.glyphs(None), "icons": lambda: ol.icons(src, 10**6), "emoji": lambda: ol.emoji(src, 10**6)}
    rows = []
    for name, key in PICKS:
        r = ol._with_png([g for g in sets[name]() if g["name"] == key], gray=name == "glyphs")[0]
        model = api.load_model(ol.MODELS[name], "cpu")
        ours = api.vectorize(load_image(key + ".png", r["png"]), model).to_svg()
        theirs = ol.potrace(r["png"]) if name in ol.TWO_TONE else None
        vt = ol.vtracer(r["png"], "binary" if name in ol.TWO_TONE else "color")
        img = Image.open(__import__("io").BytesIO(r["png"])).convert("RGB").resize((SIDE, SIDE), Image.NEAREST)
        tiles = [np.asarray(img, dtype=np.float64) / 255]
        for svg in (theirs, vt, ours):
            tiles.append(np.ones((SIDE, SIDE, 3)) if svg is None else rasterize_svg(svg, SIDE, SIDE))
        rows.append(np.concatenate(tiles, 1))
    sheet = Image.fromarray((np.concatenate(rows, 0) * 255).round().astype(np.uint8))
    head = Image.new("RGB", (sheet.width, 28), "white")
    draw = ImageDraw.Draw(head)
    for i, label in enumerate(["input (64 px)", "potrace", "vtracer", "im2vec vectorize"]):
        draw.text((i * SIDE + 8, 8), label, fill="black")
    out = Image.new("RGB", (sheet.width, sheet.height + head.height), "white")
    out.paste(head, (0, 0))
    out.paste(sheet, (0, head.height))
    out.save(ROOT / "docs" / "outlines.png")


if __name__ == "__main__":
    main()
