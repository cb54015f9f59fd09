"""``VectorImage`` -> SVG text: the writer (static and animated); the reader is ``read.py``.

Frame: the ``VectorImage`` pixel frame is the SVG ``viewBox``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import svgwrite

from .image import VectorImage


def number_text(v: float, decimals: int) -> str:
    """A coordinate as the SVG text writes it: ``decimals`` places, trailing zeros dropped."""
    s = f"{v:.{decimals}f}"
    if "." in s:
        s = s.rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


def hex_color(color: Sequence[float]) -> str:
    """``#rrggbb`` of an RGB colour in [0, 1] (clamped)."""
    r, g, b = (int(round(min(1.0, max(0.0, float(c))) * 255)) for c in color)
    return f"#{r:02x}{g:02x}{b:02x}"


def contour_d(points: np.ndarray, decimals: int = 2) -> str:
    """Path data ``M x y C ... Z`` of one closed cubic contour ``(3S, 2)``."""
    n = len(points)
    xy = [f"{number_text(x, decimals)} {number_text(y, decimals)}" for x, y in np.asarray(points, dtype=np.float64).tolist()]
    parts = [f"M {xy[0]}"]
    for s in range(n // 3):
        parts.append(f"C {xy[3 * s + 1]} {xy[3 * s + 2]} {xy[(3 * s + 3) % n]}")
    parts.append("Z")
    return " ".join(parts)


def to_svg(image: VectorImage, decimals: int = 2) -> str:
    """SVG text: one ``<path>`` per shape, back to front, each contour a subpath."""
    w, h = image.width, image.height
    # debug=False: no per-attribute validation (the values are ours and well-formed; 5x faster)
    dwg = svgwrite.Drawing(size=(number_text(w, decimals), number_text(h, decimals)), profile="full", debug=False)
    dwg["viewBox"] = f"0 0 {number_text(w, decimals)} {number_text(h, decimals)}"
    for shape in image.shapes:
        if not shape.contours:
            continue
        d = " ".join(contour_d(c, decimals) for c in shape.contours)
        dwg.add(dwg.path(d=d, fill=hex_color(shape.color), fill_rule=shape.fill_rule, stroke="none"))
    return dwg.tostring()


def animated_svg(frames: list[VectorImage], seconds: float = 3.0, decimals: int = 2) -> str:
    """One SVG whose paths morph through ``frames`` with SMIL ``<animate>`` (there and back).

    All frames must have the same shapes, contours and segment counts (decode with
    ``keep_all=True`` and a fixed number of segments), so the path data interpolates.
    """
    first = frames[0]
    sig = [[len(c) for c in s.contours] for s in first.shapes]
    for f in frames:
        if [[len(c) for c in s.contours] for s in f.shapes] != sig:
            raise ValueError("frames differ in structure; decode them with keep_all=True and fixed segments")
    seq = frames + frames[-2:0:-1]  # ping-pong
    base = to_svg(first, decimals)
    out = base[: base.rfind("</svg>")]
    out = out[: out.find("<path")] if "<path" in out else out
    parts = [out]
    for si, shape in enumerate(first.shapes):
        values = ";".join(" ".join(contour_d(c, decimals) for c in f.shapes[si].contours) for f in seq + [seq[0]])
        r, g, b = (int(round(v * 255)) for v in shape.color)
        parts.append(
            f'<path d="{values.split(";")[0]}" fill="#{r:02x}{g:02x}{b:02x}" fill-rule="{shape.fill_rule}" stroke="none">'
            f'<animate attributeName="d" dur="{seconds * 2:g}s" repeatCount="indefinite" values="{values}"/></path>'
        )
    parts.append("</svg>")
    return "".join(parts)
