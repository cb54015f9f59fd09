"""Regenerate docs/vectorize.png and docs/interpolate.png with the shipped default model.

Run from the repository root: ``python docs/make_figures.py`` (uses the CLI, as a user would).
"""

import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image

from im2vec_cli.svg import rasterize_svg

ROOT = Path(__file__).resolve().parents[1]
EXE = [sys.executable, "-m", "im2vec_cli"]
CELL = 128


def main():
    examples = sorted((ROOT / "examples").glob("*.png"))
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run(EXE + ["vectorize", *map(str, examples), "-o", tmp], check=True)
        sheet = Image.new("RGB", (len(examples) * CELL, 2 * CELL), "white")
        for i, ex in enumerate(examples):
            sheet.paste(Image.open(ex).convert("RGB").resize((CELL, CELL), Image.NEAREST), (i * CELL, 0))
            svg = (Path(tmp) / (ex.stem + ".svg")).read_text()
            arr = rasterize_svg(svg, CELL, CELL)
            sheet.paste(Image.fromarray(np.round(arr * 255).astype(np.uint8)), (i * CELL, CELL))
        sheet.save(ROOT / "docs" / "vectorize.png")
        out = Path(tmp) / "interp"
        subprocess.run(EXE + ["interpolate", str(ROOT / "examples/glyph_a.png"), str(ROOT / "examples/glyph_R.png"),
                              "--steps", "6", "-o", str(out), "--animate"], check=True)
        (ROOT / "docs" / "interpolate.png").write_bytes((out / "contact.png").read_bytes())
        (ROOT / "docs" / "morph.svg").write_text((out / "morph.svg").read_text())


if __name__ == "__main__":
    main()
