"""docs/interpolations.png and docs/morph-<row>.svg: `im2vec interpolate` for every shipped model.

Two test-split images per set (from tests/assets/<set>_test, never trained on), interpolated by
the tool itself with its defaults (`im2vec interpolate A B --steps 6 --animate --model M`: the
model's paths fitted to each image, then interpolated); one row per pair: input A | the 8
frames (A's projection ... B's, cairosvg renders of the SVGs it wrote) | input B. Fonts has two
rows: one letter in two faces, and two different letters. The morphs are the tool's
flipbooks of 24 clean frames.

    python docs/make_interpolations.py
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from im2vec_cli.vector import rasterize_svg

ROOT = Path(__file__).resolve().parents[1]
EXE = [sys.executable, "-m", "im2vec_cli"]
CELL = 96
STEPS = 6
PAIRS = {  # row: (A, B), files of tests/assets/<set>_test; the row's model is its name up to "-"
    "fonts": ("fonts_test/National_Park_Heavy_006f.png", "fonts_test/Roadgeek_2014_Series_D_Regular_006f.png"),
    "fonts-letters": ("fonts_test/Campania_Regular_0061.png", "fonts_test/Fira_Code_Regular_006d.png"),
    "mnist": ("mnist_test/0_00372.png", "mnist_test/2_00326.png"),
    "emoji": ("emoji_test/1f61e.png", "emoji_test/1f970.png"),
    "icons": ("icons_test/emoticon-frown.png", "icons_test/seal.png"),
}


def tile(img: Image.Image) -> Image.Image:
    flat = Image.new("RGBA", img.size, "white")
    flat.alpha_composite(img.convert("RGBA"))
    return flat.convert("RGB").resize((CELL, CELL), Image.NEAREST)


def main():
    rows = [r for r in PAIRS if (ROOT / "models" / r.split("-")[0] / "config.json").is_file()]
    label = 56
    sheet = Image.new("RGB", (label + (STEPS + 4) * CELL, len(rows) * CELL), "white")
    draw = ImageDraw.Draw(sheet)
    with tempfile.TemporaryDirectory() as tmp:
        for r, row in enumerate(rows):
            a, b = (ROOT / "tests" / "assets" / p for p in PAIRS[row])
            out = Path(tmp) / row
            subprocess.run(EXE + ["interpolate", str(a), str(b), "--steps", str(STEPS), "--animate", "--model",
                                  row.split("-")[0], "-o", str(out)], check=True)
            frames = sorted(out.glob("frame_*.svg"))
            if len(frames) != STEPS + 2:
                raise SystemExit(f"{row}: expected {STEPS + 2} frames, got {len(frames)}")
            y = r * CELL
            draw.text((4, y + CELL // 2 - 6), row.replace("-", "\n"), fill="black")
            sheet.paste(tile(Image.open(a)), (label, y))
            for i, f in enumerate(frames, 1):
                arr = rasterize_svg(f.read_text(), CELL, CELL)
                sheet.paste(Image.fromarray(np.round(arr * 255).astype(np.uint8)), (label + i * CELL, y))
            sheet.paste(tile(Image.open(b)), (label + (STEPS + 3) * CELL, y))
            (ROOT / "docs" / f"morph-{row}.svg").write_text((out / "morph.svg").read_text())
    sheet.save(ROOT / "docs" / "interpolations.png")
    print(f"docs/interpolations.png: {', '.join(rows)}; docs/morph-<model>.svg")


if __name__ == "__main__":
    main()
