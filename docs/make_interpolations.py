"""docs/interpolations.png and docs/morph-<model>.svg: `im2vec interpolate` for every shipped model.

Two test-split images per set (from tests/assets/<set>_test, never trained on), interpolated by
the tool itself (`im2vec interpolate A B --steps 6 --animate --model M`); one row per model:
input A | the 8 frames (A's reconstruction ... B's, cairosvg renders of the SVGs it wrote) |
input B. The morphs are the tool's SMIL animations of the model's own paths.

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
PAIRS = {  # model: (A, B), files of tests/assets/<set>_test
    "fonts": ("fonts_test/Campania_Regular_0061.png", "fonts_test/Fira_Code_Regular_006d.png"),
    "mnist": ("mnist_test/0_00372.png", "mnist_test/2_00326.png"),
    "emoji": ("emoji_test/1f61e.png", "emoji_test/1f970.png"),
    "icons": ("icons_test/emoticon-frown.png", "icons_test/seal.png"),
}


def tile(img: Image.Image) -> Image.Image:
    flat = Image.new("RGBA", img.size, "white")
    flat.alpha_composite(img.convert("RGBA"))
    return flat.convert("RGB").resize((CELL, CELL), Image.NEAREST)


def main():
    rows = [m for m in PAIRS if (ROOT / "models" / m / "config.json").is_file()]
    label = 56
    sheet = Image.new("RGB", (label + (STEPS + 4) * CELL, len(rows) * CELL), "white")
    draw = ImageDraw.Draw(sheet)
    with tempfile.TemporaryDirectory() as tmp:
        for r, model in enumerate(rows):
            a, b = (ROOT / "tests" / "assets" / p for p in PAIRS[model])
            out = Path(tmp) / model
            subprocess.run(EXE + ["interpolate", str(a), str(b), "--steps", str(STEPS), "--animate", "--model", model,
                                  "-o", str(out)], check=True)
            frames = sorted(out.glob("frame_*.svg"))
            if len(frames) != STEPS + 2:
                raise SystemExit(f"{model}: expected {STEPS + 2} frames, got {len(frames)}")
            y = r * CELL
            draw.text((4, y + CELL // 2 - 6), model, fill="black")
            sheet.paste(tile(Image.open(a)), (label, y))
            for i, f in enumerate(frames, 1):
                arr = rasterize_svg(f.read_text(), CELL, CELL)
                sheet.paste(Image.fromarray(np.round(arr * 255).astype(np.uint8)), (label + i * CELL, y))
            sheet.paste(tile(Image.open(b)), (label + (STEPS + 3) * CELL, y))
            (ROOT / "docs" / f"morph-{model}.svg").write_text((out / "morph.svg").read_text())
    sheet.save(ROOT / "docs" / "interpolations.png")
    print(f"docs/interpolations.png: {', '.join(rows)}; docs/morph-<model>.svg")


if __name__ == "__main__":
    main()
