"""Rasterisation of any SVG with cairosvg (no autograd): the independent reference and
what a user's viewer shows."""

from __future__ import annotations

import io
import math

import numpy as np

from .image import VectorImage


def rasterize_svg(text: str | bytes, width: int, height: int) -> np.ndarray:
    """Render SVG text with cairosvg at ``width x height`` over white.

    Returns:
        ``(H, W, 3)`` float64 array in [0, 1].
    """
    import cairosvg
    from PIL import Image

    data = text.encode() if isinstance(text, str) else text
    png = cairosvg.svg2png(bytestring=data, output_width=width, output_height=height)
    img = Image.open(io.BytesIO(png)).convert("RGBA")
    arr = np.asarray(img, dtype=np.float64) / 255.0
    rgb, a = arr[..., :3], arr[..., 3:]
    return rgb * a + (1 - a)


def contact_sheet(images: list[VectorImage], cell: int = 96, columns: int = 8) -> bytes:
    """PNG grid of cairosvg renders of the vector images."""
    from PIL import Image

    from ..files import encode_png

    cols = min(columns, len(images))
    rows = math.ceil(len(images) / cols)
    sheet = Image.new("RGB", (cols * cell, rows * cell), "white")
    for i, im in enumerate(images):
        arr = rasterize_svg(im.to_svg(3), cell, cell)
        tile = Image.fromarray(np.round(arr * 255).astype(np.uint8))
        sheet.paste(tile, ((i % cols) * cell, (i // cols) * cell))
    return encode_png(sheet)
