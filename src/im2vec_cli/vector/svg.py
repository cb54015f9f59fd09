"""SVG text <-> ``VectorImage``: the writer (static and animated) and a reader of closed
cubic paths.

Frame: the ``VectorImage`` pixel frame is the SVG ``viewBox``.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from xml.etree import ElementTree

import numpy as np
import svgwrite

from ..errors import InputError
from ..raster.bezier import line_controls
from .image import VectorImage, VectorShape


def _fmt(v: float, decimals: int) -> str:
    s = f"{v:.{decimals}f}"
    if "." in s:
        s = s.rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


def _hex(color: Sequence[float]) -> str:
    r, g, b = (int(round(min(1.0, max(0.0, float(c))) * 255)) for c in color)
    return f"#{r:02x}{g:02x}{b:02x}"


def contour_d(points: np.ndarray, decimals: int = 2) -> str:
    """Path data ``M x y C ... Z`` of one closed cubic contour ``(3S, 2)``."""
    n = len(points)
    xy = [f"{_fmt(x, decimals)} {_fmt(y, decimals)}" for x, y in np.asarray(points, dtype=np.float64).tolist()]
    parts = [f"M {xy[0]}"]
    for s in range(n // 3):
        parts.append(f"C {xy[3 * s + 1]} {xy[3 * s + 2]} {xy[(3 * s + 3) % n]}")
    parts.append("Z")
    return " ".join(parts)


def to_svg(image: VectorImage, decimals: int = 2) -> str:
    """SVG text: one ``<path>`` per shape, back to front, each contour a subpath."""
    w, h = image.width, image.height
    # debug=False: no per-attribute validation (the values are ours and well-formed; 5x faster)
    dwg = svgwrite.Drawing(size=(_fmt(w, decimals), _fmt(h, decimals)), profile="full", debug=False)
    dwg["viewBox"] = f"0 0 {_fmt(w, decimals)} {_fmt(h, decimals)}"
    for shape in image.shapes:
        if not shape.contours:
            continue
        d = " ".join(contour_d(c, decimals) for c in shape.contours)
        dwg.add(dwg.path(d=d, fill=_hex(shape.color), fill_rule=shape.fill_rule, stroke="none"))
    return dwg.tostring()


_TOKEN = re.compile(r"[A-Za-z]|[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


OPEN_SUBPATH = "open subpath (no Z): im2vec reads closed paths only"


def _close(cur: list[list[float]], pos, start, contours: list[np.ndarray]) -> None:
    """``Z``: a straight closing segment back to ``start`` where needed, then the contour."""
    if cur and pos is not None and start is not None and not np.allclose(pos, start):
        a, b = np.asarray(pos), np.asarray(start)
        cur += [*map(list, line_controls(a, b)), list(b)]
    if len(cur) > 1:  # the last anchor is the start point again ("M x y Z" draws nothing)
        contours.append(np.asarray(cur[:-1], dtype=np.float64))


def parse_d(d: str) -> list[np.ndarray]:
    """Closed contours of a path made of absolute ``M``, ``C``, ``L`` and ``Z`` commands.

    Lines become cubics with controls at 1/3 and 2/3. Returns ``(3S, 2)`` arrays.
    """
    junk = _TOKEN.sub(" ", d).replace(",", " ").strip()
    if junk:
        raise InputError(f"unexpected characters in path data: {junk[:20]!r}")
    toks = _TOKEN.findall(d)
    contours: list[np.ndarray] = []
    cur: list[list[float]] = []
    start = pos = cmd = None  # the subpath's start, the current point, the current command
    i = 0

    def nums(k):
        nonlocal i
        vals = [float(t) for t in toks[i : i + k] if not t.isalpha()]
        if len(vals) != k:
            raise InputError(f"path data: command {cmd!r} needs {k} more numbers")
        i += k
        return vals

    while i < len(toks):
        t = toks[i]
        if t.isalpha():
            cmd = t
            i += 1
            if cmd in "Zz":
                _close(cur, pos, start, contours)
                cur, pos = [], start
                continue
        if cmd is None:
            raise InputError("path data must start with a command")
        if cmd in "mlc" and cmd.islower():
            raise InputError(f"relative path command {cmd!r} is not supported")
        if cmd in "LC" and not cur:  # a drawing command after Z starts a new subpath at the last start
            if pos is None:
                raise InputError("path data must start with M")
            cur = [list(pos)]
        if cmd == "M":
            if cur:  # a new subpath before the last one was closed
                raise InputError(OPEN_SUBPATH)
            start = pos = nums(2)
            cur = [list(pos)]
            cmd = "L"
        elif cmd == "L":
            p = nums(2)
            a, b = np.asarray(pos), np.asarray(p)
            cur += [*map(list, line_controls(a, b)), list(b)]
            pos = p
        elif cmd == "C":
            c1, c2, p = nums(2), nums(2), nums(2)
            cur += [c1, c2, p]
            pos = p
        else:
            raise InputError(f"unsupported path command {cmd!r}")
    if cur:
        raise InputError(OPEN_SUBPATH)
    return contours


def _parse_color(value: str | None) -> tuple[float, float, float]:
    if not value or value == "none":
        return (0.0, 0.0, 0.0)
    v = value.strip()
    if re.fullmatch(r"#[0-9a-fA-F]{6}", v):
        return tuple(int(v[k : k + 2], 16) / 255 for k in (1, 3, 5))  # type: ignore[return-value]
    if re.fullmatch(r"#[0-9a-fA-F]{3}", v):
        return tuple(int(c * 2, 16) / 255 for c in v[1:])  # type: ignore[return-value]
    named = {"black": (0.0, 0.0, 0.0), "white": (1.0, 1.0, 1.0)}
    if v in named:
        return named[v]
    raise InputError(f"unsupported fill colour {value!r}")


def from_svg(text: str | bytes) -> VectorImage:
    """Read an SVG of closed cubic paths (as written by ``to_svg``) into a ``VectorImage``.

    Raises ``InputError`` (one line) on anything else: bad XML, a bad viewBox, relative or
    unsupported path commands, open subpaths, unknown fill rules or colours.
    """
    try:
        root = ElementTree.fromstring(text)
    except (ElementTree.ParseError, ValueError) as exc:  # ValueError: e.g. NUL bytes, bad encodings
        raise InputError(f"not valid SVG/XML ({exc})") from None
    if root.tag.rsplit("}", 1)[-1] != "svg":
        raise InputError(f"the root element is <{root.tag.rsplit('}', 1)[-1]}>, not <svg>")
    vb = root.get("viewBox")
    try:
        if vb:
            x0, y0, w, h = (float(v) for v in vb.replace(",", " ").split())
        else:
            x0 = y0 = 0.0
            w, h = float(root.get("width", "")), float(root.get("height", ""))
    except ValueError:
        raise InputError("the SVG needs a viewBox of four numbers, or numeric width and height") from None
    if x0 != 0 or y0 != 0:
        raise InputError("viewBox must start at 0 0")
    if not (math.isfinite(w) and math.isfinite(h) and w > 0 and h > 0):
        raise InputError(f"the canvas must have a positive finite size, got {w:g} x {h:g}")
    shapes = []
    for el in root.iter():
        if el.tag.rsplit("}", 1)[-1] != "path":
            continue
        contours = parse_d(el.get("d", ""))
        if any(not np.isfinite(c).all() for c in contours):
            raise InputError("path data contains a non-finite number")
        rule = el.get("fill-rule", "nonzero")
        if rule not in ("nonzero", "evenodd"):
            raise InputError(f"unsupported fill-rule {rule!r} (nonzero or evenodd)")
        shapes.append(VectorShape(contours, _parse_color(el.get("fill")), rule))
    return VectorImage(w, h, shapes)


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
