"""``VectorImage`` -> SVG text: the writer (static and animated); the reader is ``read.py``.

Frame: the ``VectorImage`` pixel frame is the SVG ``viewBox``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

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


SVG_ROOT = {"baseProfile": "full", "version": "1.1", "xmlns": "http://www.w3.org/2000/svg",
            "xmlns:ev": "http://www.w3.org/2001/xml-events", "xmlns:xlink": "http://www.w3.org/1999/xlink"}


def to_svg(image: VectorImage, decimals: int = 2) -> str:
    """SVG text: one ``<path>`` per shape, back to front, each contour a subpath.

    The element tree svgwrite's ``Drawing`` (``profile="full"``) builds and writes, built here
    with the standard library's ElementTree that svgwrite writes through, without svgwrite's
    import (46 ms, its validators; a tenth of a one-picture call): the same text byte for byte.
    """
    from xml.etree import ElementTree

    w, h = number_text(image.width, decimals), number_text(image.height, decimals)
    root = ElementTree.Element("svg", dict(sorted({**SVG_ROOT, "height": h, "width": w,
                                                   "viewBox": f"0 0 {w} {h}"}.items())))
    ElementTree.SubElement(root, "defs")
    for shape in image.shapes:
        if shape.contours:  # attributes in svgwrite's (sorted) order
            ElementTree.SubElement(root, "path", {"d": " ".join(contour_d(c, decimals) for c in shape.contours),
                                                  "fill": hex_color(shape.color), "fill-rule": shape.fill_rule,
                                                  "stroke": "none"})
    return ElementTree.tostring(root, encoding="utf-8").decode("utf-8")


def flipbook_svg(frames: list[VectorImage], seconds: float = 3.0, decimals: int = 2) -> str:
    """One SVG that shows ``frames`` in turn, there and back, over ``2 * seconds`` (SMIL).

    Each frame is a group of its own paths shown for its share of the time (``display``
    animated with ``calcMode="discrete"``), so every picture on screen is one of ``frames``
    exactly: frames of different paths (clean outlines) play as well as the model's own. A
    viewer without SMIL shows the first frame.
    """
    if not frames:
        raise ValueError("a flipbook needs at least one frame")
    first = frames[0]
    if any((f.width, f.height) != (first.width, first.height) for f in frames):
        raise ValueError("the frames of a flipbook share one canvas size")
    seq = list(range(len(frames))) + list(range(len(frames) - 2, 0, -1))  # ping-pong
    times = ";".join(number_text(j / len(seq), 4) for j in range(len(seq)))
    base = to_svg(first, decimals)
    head = base[: base.find("<path")] if "<path" in base else base[: base.rfind("</svg>")]
    parts = [head]
    for i, frame in enumerate(frames):
        shown = ";".join("inline" if j == i else "none" for j in seq)
        paths = "".join(f'<path d="{" ".join(contour_d(c, decimals) for c in sh.contours)}" fill="{hex_color(sh.color)}" '
                        f'fill-rule="{sh.fill_rule}" stroke="none"/>' for sh in frame.shapes if sh.contours)
        parts.append(f'<g display="{"inline" if i == 0 else "none"}">{paths}<animate attributeName="display" '
                     f'calcMode="discrete" dur="{seconds * 2:g}s" repeatCount="indefinite" keyTimes="{times}" '
                     f'values="{shown}"/></g>')
    parts.append("</svg>")
    return "".join(parts)
