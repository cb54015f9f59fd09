"""`make demo`'s contact sheet: each example next to its SVG, both at 4x (the SVG by cairosvg).

Usage: python examples/demo_sheet.py EXAMPLES_DIR SVG_DIR OUT.png
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from PIL import Image

from im2vec_cli.vector import rasterize_svg

UP = 4


def main(examples: Path, svgs: Path, out: Path) -> None:
    rows = []
    for svg in sorted(svgs.glob("*.svg")):
        src = Image.open(examples / f"{svg.stem}.png").convert("RGB")
        w, h = src.size
        left = np.asarray(src.resize((w * UP, h * UP), Image.NEAREST))
        right = np.round(rasterize_svg(svg.read_text(), w * UP, h * UP) * 255).astype(np.uint8)
        gap = np.full((h * UP, 8, 3), 255, np.uint8)
        rows.append(np.concatenate([left, gap, right], 1))
    width = max(r.shape[1] for r in rows)
    rows = [np.pad(r, ((0, 8), (0, width - r.shape[1]), (0, 0)), constant_values=255) for r in rows]
    Image.fromarray(np.concatenate(rows, 0)).save(out)


if __name__ == "__main__":
    main(Path(sys.argv[1]), Path(sys.argv[2]), Path(sys.argv[3]))
