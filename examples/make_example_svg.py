"""Write a small example SVG (a glyph outline from DejaVu Sans, or circles without it)."""

import sys
from pathlib import Path

from im2vec_cli.io import atomic_write
from im2vec_cli.svg import VectorImage, VectorShape, to_svg

out = Path(sys.argv[1] if len(sys.argv) > 1 else "example.svg")
out.parent.mkdir(parents=True, exist_ok=True)
font = Path("/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf")
if font.exists():
    from fontTools.ttLib import TTFont

    from im2vec_cli.data.glyphs import glyph_image

    image = glyph_image(TTFont(font), "g", size=64, margin=4)
else:
    import numpy as np

    t = np.linspace(0, 2 * np.pi, 25)[:-1]
    ring = lambda r: np.stack([32 + r * np.cos(t), 32 + r * np.sin(t)], -1)  # noqa: E731
    image = VectorImage(64, 64, [VectorShape([ring(24), ring(12)], (0.1, 0.1, 0.1), "evenodd")])
atomic_write(out, to_svg(image))
print(out)
