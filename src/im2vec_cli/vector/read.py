"""SVG text -> ``VectorImage``: any SVG a user has, with svgelements.

The whole path grammar (M L H V C S Q T A Z, absolute and relative), transforms, ``<use>``,
CSS styles and the basic shapes (rect, circle, ellipse, line, polyline, polygon) become
closed cubic contours: lines and quadratics are elevated, arcs are approximated by cubics
(svgelements), and an open subpath is closed as SVG fills it. The canvas is the SVG's
viewport (``width x height``, or the viewBox's size), in the pixel frame of ``image.py``.

Strokes become filled outlines (skia-pathops: width, caps, joins, miter limit, dashes),
stroked in the element's own coordinates and then transformed, written as a second shape
over the element's fill. Refused with one ``InputError`` line, never drawn wrong: gradient
or pattern paint, semi-transparent paint, text and embedded images, and, before any
geometry is built, clip paths, masks, markers and filters, SVGs over ``MAX_SEGMENTS`` segments
(strokes and dashes counted before they are made), over ``MAX_ELEMENTS`` elements with
every ``<use>`` expanded (or with a ``<use>`` cycle), or with coordinates beyond ``MAX_COORD`` px.
Shapes with ``fill="none"`` and no stroke, or ``visibility="hidden"``, draw nothing and are skipped.
"""

from __future__ import annotations

import io
import math
import re

import numpy as np

from ..errors import InputError
from ..raster.curves import line_controls
from . import skia
from .document import MAX_SEGMENTS, check_document
from .image import VectorImage, VectorShape

MAX_COORD = 1e6  # |coordinate| and canvas side, in px
SEGMENTS_PER_DASH = 6  # a butt dash strokes to 4 lines and a close; round caps add curves
_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def _stroked(el) -> bool:
    return el.stroke is not None and el.stroke.value is not None and float(el.stroke_width or 0) > 0


def _tag(el) -> str:
    """The SVG element name of an svgelements shape."""
    kind = type(el).__name__.lower()
    return {"simpleline": "line"}.get(kind, kind)


def _refuse_paint(el) -> None:
    """One line for what a ``VectorShape`` (one opaque flat fill) cannot hold."""
    kind = _tag(el)
    fill = str(el.values.get("fill", ""))
    if fill.startswith("url("):
        raise InputError(f"<{kind}>: gradient and pattern fills are not supported ({fill})")
    stroke = str(el.values.get("stroke", ""))
    if stroke.startswith("url("):
        raise InputError(f"<{kind}>: gradient and pattern strokes are not supported ({stroke})")
    if _stroked(el) and el.stroke.alpha < 255:
        raise InputError(f"<{kind}>: semi-transparent strokes are not supported")
    if el.fill is not None and el.fill.value is not None and el.fill.alpha < 255:
        raise InputError(f"<{kind}>: semi-transparent fills are not supported")
    opacity = el.values.get("opacity")
    if opacity is not None and _fraction(str(opacity), "opacity") < 1:
        raise InputError(f"<{kind}>: opacity below 1 is not supported")
    for paint, drawn in (("fill", el.fill is not None and el.fill.value is not None), ("stroke", _stroked(el))):
        alpha = el.values.get(f"{paint}-opacity")  # a percentage svgelements does not read: checked here
        if drawn and alpha is not None and _fraction(str(alpha), f"{paint}-opacity") < 1:
            raise InputError(f"<{kind}>: semi-transparent {paint}s are not supported")


def _fraction(text: str, name: str) -> float:
    """An SVG alpha value: a number or a percentage (SVG 2: ``50%`` is 0.5), clamped to [0, 1]."""
    text = text.strip()
    try:
        value = float(text[:-1]) / 100 if text.endswith("%") else float(text)
    except ValueError:
        raise InputError(f"{name} {text[:40]!r} is not a number or a percentage") from None
    if not math.isfinite(value):
        raise InputError(f"{name} {text[:40]!r} is not finite")
    return min(max(value, 0.0), 1.0)


def _point(p) -> list[float]:
    """An svgelements point, checked finite and within ``MAX_COORD``."""
    x, y = float(p.x), float(p.y)
    _check_coords(np.array([x, y]))
    return [x, y]


def _check_coords(points: np.ndarray) -> None:
    bad = ~(np.isfinite(points) & (np.abs(points) <= MAX_COORD))
    if bad.any():
        x, y = points.reshape(-1, 2)[bad.reshape(-1, 2).any(-1)][0]
        raise InputError(f"path coordinate ({x:g}, {y:g}) is not finite or beyond {MAX_COORD:g} px")


def _transform(points: np.ndarray, m) -> np.ndarray:
    """``(N, 2)`` mapped by the affine svgelements ``Matrix`` ``m`` (exact on cubic control
    points), checked like every coordinate."""
    if m is not None:
        points = points @ np.array([[m.a, m.b], [m.c, m.d]]) + np.array([m.e, m.f])
    _check_coords(points)
    return points


def _guard(fn, *args):
    """``fn(*args)``; any failure of svgelements or pathops on odd data is one ``InputError`` line."""
    try:
        return fn(*args)
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 - they raise many types (e.g. on degenerate arcs)
        raise InputError(f"unreadable path data ({' '.join(str(exc).split())[:120] or type(exc).__name__})") from None


def _subpaths(segments) -> list[tuple[np.ndarray, bool]]:
    """svgelements path segments (their element's own coordinates) -> cubic chains
    ``(1 + 3S, 2)`` (anchor, control, control, anchor, ...) and whether each was closed by Z.
    Lines and quadratics are elevated; arcs are made cubic here, before any transform, so a
    skewed circle stays exact."""
    import svgelements as se

    out: list[tuple[np.ndarray, bool]] = []
    cur: list[list[float]] = []

    def end(closed: bool):
        if len(cur) > 1:
            out.append((np.asarray(cur, dtype=np.float64), closed))
        cur.clear()

    for seg in segments:
        if isinstance(seg, se.Move):
            end(False)
            cur.append(_point(seg.end))
            continue
        if isinstance(seg, se.Close):
            end(True)
            continue
        if not cur:  # drawing without a moveto starts where the last subpath started (0, 0 at first)
            cur.append(_point(seg.start) if seg.start is not None else [0.0, 0.0])
        for c in seg.as_cubic_curves() if isinstance(seg, se.Arc) else [seg]:
            if isinstance(c, se.Line):
                a, b = np.asarray(cur[-1]), np.asarray(_point(c.end))
                cur.extend([*map(list, line_controls(a, b)), list(b)])
            elif isinstance(c, se.QuadraticBezier):
                a, q, b = np.asarray(cur[-1]), np.asarray(_point(c.control)), np.asarray(_point(c.end))
                cur.extend([list(a + 2 * (q - a) / 3), list(b + 2 * (q - b) / 3), list(b)])
            elif isinstance(c, se.CubicBezier):
                cur.extend([_point(c.control1), _point(c.control2), _point(c.end)])
    end(False)
    return out


def _fill_contours(chains: list[tuple[np.ndarray, bool]], m) -> list[np.ndarray]:
    """Every subpath closed (as SVG fills an open one), mapped by ``m``; subpaths on one
    straight line (a ``<line>``'s fill) enclose nothing and are dropped."""
    out = []
    for c in (skia.close_chain(ch) for ch, _ in chains):
        if c is not None and np.linalg.matrix_rank(c - c.mean(0), tol=1e-9 * (1 + np.abs(c).max())) == 2:
            out.append(_transform(c, m))
    return out


CAPS = {"butt": "BUTT_CAP", "round": "ROUND_CAP", "square": "SQUARE_CAP"}
JOINS = {"miter": "MITER_JOIN", "miter-clip": "MITER_JOIN", "arcs": "MITER_JOIN", "round": "ROUND_JOIN",
         "bevel": "BEVEL_JOIN"}


def _stroke_contours(chains: list[tuple[np.ndarray, bool]], el, m) -> list[np.ndarray]:
    """The outline of an element's stroke as closed filled contours (skia-pathops: width,
    caps, joins, miter limit and dashes as SVG says), stroked in the element's own
    coordinates and then mapped by ``m``, so a scaled or skewed stroke is scaled or skewed too."""
    import pathops

    v = el.values
    path = skia.to_path(chains)
    dashes = _dashes(str(v.get("stroke-dasharray", "none")))
    if dashes:  # bound the dashes before skia makes them: path length / period
        length = sum(float(np.linalg.norm(np.diff(ch, axis=0), axis=1).sum()) for ch, _ in chains)  # >= arc length
        count = length / sum(dashes) * (len(dashes) // 2)
        if count * SEGMENTS_PER_DASH > MAX_SEGMENTS:
            raise InputError(f"<{_tag(el)}>: stroke-dasharray makes about {count:,.0f} dashes "
                             f"(at most {MAX_SEGMENTS // SEGMENTS_PER_DASH:,})")
    path.stroke(float(el.stroke_width), getattr(pathops.LineCap, CAPS.get(str(v.get("stroke-linecap", "butt")), "BUTT_CAP")),
                getattr(pathops.LineJoin, JOINS.get(str(v.get("stroke-linejoin", "miter")), "MITER_JOIN")),
                float(v.get("stroke-miterlimit", 4)), dash_array=dashes or None,
                dash_offset=float(v.get("stroke-dashoffset", 0) or 0))
    path.convertConicsToQuads()
    if sum(1 for _ in path.segments) > MAX_SEGMENTS:
        raise InputError(f"<{_tag(el)}>: its stroke outline has more than {MAX_SEGMENTS} segments")
    # Filled under nonzero as it stands (the outline's pieces overlap at joins, as Skia draws
    # strokes): no pathops.simplify, whose cost grows with the crossings beyond any bound.
    return [_transform(c, m) for c in skia.contours(path)]


def _dashes(text: str) -> list[float]:
    """``stroke-dasharray`` as an even list of lengths; ``[]`` (solid) for ``none``, and, as
    SVG says, for a list that sums to zero or has a negative value."""
    text = text.strip()
    try:
        dashes = [] if text in ("none", "") else [float(x) for x in re.split(r"[\s,]+", text) if x]
    except ValueError:
        raise InputError(f"stroke-dasharray {text[:40]!r} is not a list of numbers") from None
    if not all(math.isfinite(d) and d >= 0 for d in dashes) or sum(dashes) <= 0:
        return []
    return dashes * 2 if len(dashes) % 2 else dashes  # SVG repeats an odd list


def from_svg(text: str | bytes) -> VectorImage:
    """Read any SVG into a ``VectorImage`` of closed cubic contours (see the module doc).

    Raises ``InputError`` (one line) on bad XML, a canvas that is not a positive finite size
    within ``MAX_COORD``, and everything the module doc lists as refused.
    """
    import svgelements as se

    data = check_document(text.encode("utf-8") if isinstance(text, str) else bytes(text))
    try:
        doc = se.SVG.parse(io.BytesIO(data), reify=False)  # transforms are applied to our cubics (_transform)
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
        if not isinstance(el, se.Shape) or str(el.values.get("visibility", "visible")).strip() in ("hidden", "collapse"):
            continue  # visibility is inherited (svgelements carries it down) and a child may undo it
        _refuse_paint(el)
        filled, stroked = el.fill is not None and el.fill.value is not None, _stroked(el)
        if not (filled or stroked):  # fill="none" and no stroke: nothing to draw
            continue
        chains = _guard(lambda el=el: _subpaths(el.segments(transformed=False)))
        rule = str(el.values.get("fill-rule", "nonzero")).strip()
        if rule not in ("nonzero", "evenodd"):
            raise InputError(f"unsupported fill-rule {rule!r} (nonzero or evenodd)")
        for paint, contours, fill_rule in (
            (el.fill, _fill_contours(chains, el.transform) if filled else [], rule),  # the fill, then the stroke over it
            (el.stroke, _guard(_stroke_contours, chains, el, el.transform) if stroked else [], "nonzero"),
        ):
            segments += sum(len(c) // 3 for c in contours)
            if segments > MAX_SEGMENTS:
                raise InputError(f"too many path segments (more than {MAX_SEGMENTS})")
            if contours:
                shapes.append(VectorShape(contours, (paint.red / 255, paint.green / 255, paint.blue / 255), fill_rule))
    return VectorImage(w, h, shapes)


def parse_d(d: str) -> list[np.ndarray]:
    """Closed cubic contours ``(3S, 2)`` of SVG path data (any commands; see ``from_svg``)."""
    import svgelements as se

    if len(_NUMBER.findall(d)) > 6 * MAX_SEGMENTS:
        raise InputError(f"too much path data (at most {MAX_SEGMENTS} segments)")
    return _fill_contours(_guard(lambda: _subpaths(se.Path(d).segments())), None)
