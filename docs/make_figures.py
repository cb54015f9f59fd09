"""Regenerate docs/vectorize.png and docs/interpolate.png with the shipped models.

vectorize.png: inputs (top row), `vectorize --no-refine` (the model alone), `vectorize --parts
model` (the model's paths refined) and `vectorize` (bottom row, clean outlines: the default for
one image), each example with its matching shipped model (digit: mnist, emoji: emoji, icon:
icons), else fonts.

Run from the repository root: ``python docs/make_figures.py`` (uses the CLI, as a user would).
"""

import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image

from im2vec_cli.vector import rasterize_svg

ROOT = Path(__file__).resolve().parents[1]
EXE = [sys.executable, "-m", "im2vec_cli"]
CELL = 128


MATCH = {"digit": "mnist", "emoji": "emoji", "icon": "icons"}


def model_for(example: Path) -> str:
    name = MATCH.get(example.stem.split("_")[0], "fonts")
    return name if (ROOT / "models" / name / "config.json").is_file() else "fonts"


def main():
    examples = sorted((ROOT / "examples").glob("*.png"))
    with tempfile.TemporaryDirectory() as tmp:
        rows = [["--no-refine"], ["--parts", "model"], []]
        sheet = Image.new("RGB", (len(examples) * CELL, (1 + len(rows)) * CELL), "white")
        for i, ex in enumerate(examples):
            sheet.paste(Image.open(ex).convert("RGB").resize((CELL, CELL), Image.NEAREST), (i * CELL, 0))
            for row, extra in enumerate(rows, 1):
                out = Path(tmp) / f"{ex.stem}_{row}.svg"
                subprocess.run(EXE + ["vectorize", str(ex), "-o", str(out), "--model", model_for(ex), *extra],
                               check=True)
                arr = rasterize_svg(out.read_text(), CELL, CELL)
                sheet.paste(Image.fromarray(np.round(arr * 255).astype(np.uint8)), (i * CELL, row * CELL))
        sheet.save(ROOT / "docs" / "vectorize.png")
        out = Path(tmp) / "interp"
        subprocess.run(EXE + ["interpolate", str(ROOT / "examples/glyph_a.png"), str(ROOT / "examples/glyph_R.png"),
                              "--steps", "6", "-o", str(out), "--animate"], check=True)
        (ROOT / "docs" / "interpolate.png").write_bytes((out / "contact.png").read_bytes())
        (ROOT / "docs" / "morph.svg").write_text((out / "morph.svg").read_text())


if __name__ == "__main__":
    main()
