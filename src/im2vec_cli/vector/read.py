"""SVG text -> ``VectorImage``: any SVG a user has, with svgelements.

The whole path grammar (M L H V C S Q T A Z, absolute and relative), transforms, ``<use>``,
CSS styles and the basic shapes (rect, circle, ellipse, line, polyline, polygon) become
closed cubic contours: lines and quadratics are elevated, arcs are approximated by cubics
(svgelements), and an open subpath is closed as SVG fills it. The canvas is the SVG's
viewport (``width x height``, or the viewBox's size), in the pixel frame of ``image.py``.

Refused with one ``InputError`` line, never drawn wrong: strokes, gradient or pattern fills,
semi-transparent fills, text and embedded images, and, before any geometry is built, SVGs
over ``MAX_SEGMENTS`` segments or with coordinates beyond ``MAX_COORD`` px. Shapes with
``fill="none"`` and no stroke draw nothing and are skipped.
"""

from __future__ import annotations

import io
import math
import re
from xml.etree import ElementTree

import numpy as np

from ..errors import InputError
from ..raster.bezier import line_controls
from .image import VectorImage, VectorShape

MAX_SEGMENTS = 200_000  # path segments in one SVG (an SVG of 1,000,000 took minutes to read)
MAX_COORD = 1e6  # |coordinate| and canvas side, in px
_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def _check_xml(data: bytes) -> None:
    """Well-formed XML with an ``<svg>`` root, a valid viewBox if any, and at most
    ``MAX_SEGMENTS`` worth of numbers in its geometry, checked with the C parser before
    svgelements (pure Python, lenient) sees it."""
    try:
        root = ElementTree.fromstring(data)
    except (ElementTree.ParseError, ValueError) as exc:  # ValueError: e.g. NUL bytes, bad encodings
        raise InputError(f"not valid SVG/XML ({exc})") from None
    if root.tag.rsplit("}", 1)[-1] != "svg":
        raise InputError(f"the root element is <{root.tag.rsplit('}', 1)[-1]}>, not <svg>")
    vb = root.get("viewBox")
    if vb is not None:
        try:
            box = [float(v) for v in vb.replace(",", " ").split()]
        except ValueError:
            box = []
        if len(box) != 4 or not all(math.isfinite(v) for v in box) or box[2] <= 0 or box[3] <= 0:
            raise InputError(f"the viewBox must be four finite numbers with a positive size, got {vb[:40]!r}")
    numbers = sum(len(_NUMBER.findall(el.get(a, ""))) for el in root.iter() for a in ("d", "points"))
    if numbers > 6 * MAX_SEGMENTS:
        raise InputError(f"too much path data ({numbers} numbers; at most {MAX_SEGMENTS} segments)")


def _refuse_paint(el) -> None:
    """One line for what a ``VectorShape`` (one opaque flat fill) cannot hold."""
    kind = type(el).__name__.lower()
    fill = str(el.values.get("fill", ""))
    if fill.startswith("url("):
        raise InputError(f"<{kind}>: gradient and pattern fills are not supported ({fill})")
    if el.stroke is not None and el.stroke.value is not None and (el.stroke_width or 0) > 0:
        raise InputError(f"<{kind}>: strokes are not supported (convert strokes to filled paths)")
    if el.fill is not None and el.fill.value is not None and el.fill.alpha < 255:
        raise InputError(f"<{kind}>: semi-transparent fills are not supported")
    opacity = el.values.get("opacity")
    if opacity is not None and float(opacity) < 1:
        raise InputError(f"<{kind}>: opacity below 1 is not supported")


def _point(p, m=None) -> list[float]:
    """A point, mapped by the affine matrix ``m`` (svgelements ``Matrix``) when given, and checked."""
    x, y = float(p.x), float(p.y)
    if m is not None:
        x, y = m.a * x + m.c * y + m.e, m.b * x + m.d * y + m.f
    if not (math.isfinite(x) and math.isfinite(y) and abs(x) <= MAX_COORD and abs(y) <= MAX_COORD):
        raise InputError(f"path coordinate ({x:g}, {y:g}) is not finite or beyond {MAX_COORD:g} px")
    return [x, y]


def _contours(make_path, matrix=None) -> list[np.ndarray]:
    """``make_path()``, svgelements path segments in their element's own coordinates -> closed cubic
    contours ``(3S, 2)`` (every subpath closed), mapped by ``matrix``: the element's transforms
    and the viewBox, applied to the cubics' control points (exact for an affine map; arcs are
    made cubic first, so a skewed circle stays an ellipse). Any failure of svgelements on odd
    data is one ``InputError`` line."""
    try:
        return _walk(make_path(), matrix)
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 - svgelements raises many types (e.g. on degenerate arcs)
        raise InputError(f"unreadable path data ({' '.join(str(exc).split())[:120] or type(exc).__name__})") from None


def _walk(segments, m) -> list[np.ndarray]:
    import svgelements as se

    contours: list[np.ndarray] = []
    cur: list[list[float]] = []

    def close():
        if len(cur) > 1 and not np.allclose(cur[-1], cur[0]):
            a, b = np.asarray(cur[-1]), np.asarray(cur[0])
            cur.extend([*map(list, line_controls(a, b)), list(b)])
        if len(cur) > 3:  # the last anchor is the start again; a lone point draws nothing
            contours.append(np.asarray(cur[:-1], dtype=np.float64))
        cur.clear()

    for seg in segments:
        if isinstance(seg, se.Move):
            close()
            cur.append(_point(seg.end, m))
            continue
        if isinstance(seg, se.Close):
            close()
            continue
        if not cur:  # drawing without a moveto starts where the last subpath started (0, 0 at first)
            cur.append(_point(seg.start, m) if seg.start is not None else _point(se.Point(0, 0), m))
        for c in seg.as_cubic_curves() if isinstance(seg, se.Arc) else [seg]:
            if isinstance(c, se.Line):
                a, b = np.asarray(cur[-1]), np.asarray(_point(c.end, m))
                cur.extend([*map(list, line_controls(a, b)), list(b)])
            elif isinstance(c, se.QuadraticBezier):
                a, q, b = np.asarray(cur[-1]), np.asarray(_point(c.control, m)), np.asarray(_point(c.end, m))
                cur.extend([list(a + 2 * (q - a) / 3), list(b + 2 * (q - b) / 3), list(b)])
            elif isinstance(c, se.CubicBezier):
                cur.extend([_point(c.control1, m), _point(c.control2, m), _point(c.end, m)])
    close()
    return contours


def from_svg(text: str | bytes) -> VectorImage:
    """Read any SVG into a ``VectorImage`` of closed cubic contours (see the module doc).

    Raises ``InputError`` (one line) on bad XML, a canvas that is not a positive finite size
    within ``MAX_COORD``, and everything the module doc lists as refused.
    """
    import svgelements as se

    data = text.encode("utf-8") if isinstance(text, str) else bytes(text)
    _check_xml(data)
    try:
        doc = se.SVG.parse(io.BytesIO(data), reify=False)  # transforms are applied to our cubics (_walk)
    except Exception as exc:  # noqa: BLE001 - svgelements raises many types on odd documents
        raise InputError(f"unreadable SVG ({' '.join(str(exc).split())[:120] or type(exc).__name__})") from None
    if not isinstance(doc, se.SVG):
        raise InputError("not an SVG document (its root is not <svg> in the SVG namespace)")
    w, h = float(doc.width), float(doc.height)
    if not (math.isfinite(w) and math.isfinite(h) and 0 < w <= MAX_COORD and 0 < h <= MAX_COORD):
        raise InputError(f"the canvas must have a positive finite size up to {MAX_COORD:g} px, got {w:g} x {h:g}")
    shapes, segments = [], 0
    for el in doc.elements():
        if isinstance(el, (se.Text, se.Image)):
            raise InputError(f"<{type(el).__name__.lower()}> is not supported (convert text to paths first)")
        if not isinstance(el, se.Shape):
            continue
        _refuse_paint(el)
        if el.fill is None or el.fill.value is None:  # fill="none" without a stroke: nothing to draw
            continue
        contours = _contours(lambda el=el: el.segments(transformed=False), el.transform)
        segments += sum(len(c) // 3 for c in contours)
        if segments > MAX_SEGMENTS:
            raise InputError(f"too many path segments (more than {MAX_SEGMENTS})")
        rule = str(el.values.get("fill-rule", "nonzero")).strip()
        if rule not in ("nonzero", "evenodd"):
            raise InputError(f"unsupported fill-rule {rule!r} (nonzero or evenodd)")
        if contours:
            shapes.append(VectorShape(contours, (el.fill.red / 255, el.fill.green / 255, el.fill.blue / 255), rule))
    return VectorImage(w, h, shapes)


def parse_d(d: str) -> list[np.ndarray]:
    """Closed cubic contours ``(3S, 2)`` of SVG path data (any commands; see ``from_svg``)."""
    import svgelements as se

    if len(_NUMBER.findall(d)) > 6 * MAX_SEGMENTS:
        raise InputError(f"too much path data (at most {MAX_SEGMENTS} segments)")
    return _contours(lambda: se.Path(d).segments())
