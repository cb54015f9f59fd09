"""Vector images <-> SVG text, and rasterisation of any SVG with cairosvg (no autograd).

Frame: a ``VectorImage`` stores contours in *pixel* coordinates of its ``width x height``
canvas, which is also the SVG ``viewBox``. Tensors use the normalised frame of
shared/STYLE.md; ``from_tensors`` / ``to_tensors`` convert.
"""

from __future__ import annotations

import io
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from xml.etree import ElementTree

import numpy as np
import svgwrite
import torch

from .errors import InputError
from .raster.bezier import flatten_closed, line_controls, polygon_area, subdivide_to


@dataclass
class VectorShape:
    """One filled shape: closed contours ``(3S_i, 2)`` (pixel frame), one colour, a fill rule."""

    contours: list[np.ndarray]
    color: tuple[float, float, float] = (0.0, 0.0, 0.0)
    fill_rule: str = "nonzero"


@dataclass
class VectorImage:
    """Shapes listed back to front on a ``width x height`` canvas."""

    width: float
    height: float
    shapes: list[VectorShape] = field(default_factory=list)

    @property
    def num_segments(self) -> int:
        return sum(len(c) // 3 for s in self.shapes for c in s.contours)

    @property
    def num_paths(self) -> int:
        return sum(len(s.contours) for s in self.shapes)


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
    start = None
    pos = None
    cmd = None
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
                if cur and pos is not None and start is not None and not np.allclose(pos, start):
                    a, b = np.asarray(pos), np.asarray(start)
                    cur += [*map(list, line_controls(a, b)), list(b)]
                if len(cur) > 1:  # the last anchor is the start point again ("M x y Z" draws nothing)
                    contours.append(np.asarray(cur[:-1], dtype=np.float64))
                cur = []
                pos = start
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


def from_tensors(
    points: torch.Tensor | Sequence[torch.Tensor],
    colors: torch.Tensor,
    *,
    size: tuple[float, float],
    shape_index: Sequence[int] | torch.Tensor | None = None,
    depth: torch.Tensor | None = None,
    fill_rule: str = "nonzero",
    min_area: float = 0.0,
) -> VectorImage:
    """One image's tensors -> ``VectorImage`` in a ``(height, width)`` pixel frame.

    Args:
        points: ``(P, 3S, 2)`` normalised frame, or a list of ``(3S_i, 2)`` (paths of different lengths).
        colors: ``(G, 3)``.
        size: ``(height, width)`` of the output canvas (the viewBox).
        shape_index: ``(P,)`` path -> shape; ``None``: each path its own shape.
        depth: ``(G,)``, larger in front; shapes are written back to front.
        min_area: contours whose flattened area is below this (pixels^2) are dropped.
    """
    h, w = size
    scale = torch.tensor([w, h], dtype=torch.float64)
    pts = [c.detach().double().cpu() * scale for c in points]  # P x (3S_i, 2) px
    p = len(pts)
    sidx = list(range(p)) if shape_index is None else [int(v) for v in torch.as_tensor(shape_index).tolist()]
    g = colors.shape[0]
    order = list(range(g)) if depth is None else torch.argsort(depth.detach().cpu()).tolist()
    if len({len(c) for c in pts}) == 1:  # one batched call when all paths have the same length
        areas = polygon_area(flatten_closed(torch.stack(pts), 8)).abs().tolist()
    else:
        areas = [float(polygon_area(flatten_closed(c[None], 8)).abs()) for c in pts]
    shapes = []
    for gi in order:
        cs = [pts[i].numpy() for i in range(p) if sidx[i] == gi and areas[i] >= min_area]
        if cs:
            shapes.append(VectorShape(cs, tuple(float(c) for c in colors[gi].tolist()), fill_rule))
    return VectorImage(float(w), float(h), shapes)


def to_tensors(image: VectorImage, segments: int | None = None) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """``VectorImage`` -> ``points (P, 3S, 2)`` normalised, ``colors (G, 3)``, ``shape_index (P,)``.

    Contours with fewer segments are subdivided (shape unchanged) to the common ``S``:
    ``segments``, or the largest count present.
    """
    contours, sidx, colors = [], [], []
    for gi, shape in enumerate(image.shapes):
        colors.append(shape.color)
        for c in shape.contours:
            contours.append(torch.as_tensor(c, dtype=torch.float64))
            sidx.append(gi)
    if not contours:
        raise InputError("the SVG has no closed path")
    s = segments or max(len(c) // 3 for c in contours)
    pts = torch.stack([subdivide_to(c, s) for c in contours])  # (P, 3S, 2) px
    pts = pts / torch.tensor([image.width, image.height], dtype=torch.float64)
    return pts, torch.tensor(colors, dtype=torch.float64), torch.tensor(sidx, dtype=torch.long)


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
