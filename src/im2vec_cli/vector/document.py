"""An SVG document's checks, made with the C XML parser before svgelements (pure Python,
lenient) or cairosvg sees it: its size and nesting bounded (``check_bounds``: for any SVG we
render), and what we cannot draw as SVG draws it refused by name or left out
(``check_document``: for the SVGs read into shapes, ``read.from_svg``).
"""

from __future__ import annotations

import locale
import math
import re
from xml.etree import ElementTree

from ..errors import InputError

MAX_SEGMENTS = 200_000  # path segments in one SVG (an SVG of 1,000,000 took minutes to read)
MAX_ELEMENTS = 100_000  # elements once every <use> is expanded (nested <use> grows exponentially)
MAX_SVG_BYTES = 32 * 2**20  # an SVG (or its gzip-compressed form once inflated) larger than this is refused
_XLINK_HREF = "{http://www.w3.org/1999/xlink}href"
_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def check_bounds(data: bytes):
    """The parsed root of an SVG document that is well-formed XML within the bounds any
    renderer needs: no entity declarations (a 30 MB SVG of quadratic entity expansion took
    5.8 GB), at most ``MAX_ELEMENTS`` elements once every ``<use>`` is expanded and no
    ``<use>`` cycle, nesting Python can follow. Else one ``InputError`` line."""
    if b"<!ENTITY" in data:
        raise InputError("the SVG declares XML entities (<!ENTITY>), which are not supported")
    try:
        root = ElementTree.fromstring(data)
    except (ElementTree.ParseError, ValueError) as exc:  # ValueError: e.g. NUL bytes, bad encodings
        raise InputError(f"not valid SVG/XML ({exc})") from None
    try:
        _expanded_size(root)
    except RecursionError:
        raise InputError("the SVG nests elements too deeply") from None
    return root


def read_svg_bytes(raw: bytes, name: str) -> bytes:
    """An SVG file's text: as it is, or, gzip-compressed (``.svgz``), inflated to at most
    ``MAX_SVG_BYTES`` (a 1.4 MB bomb inflated to 4.6 GB) ."""
    import zlib

    if raw[:2] != b"\x1f\x8b":
        return raw
    inflate = zlib.decompressobj(wbits=31)
    try:
        out = inflate.decompress(raw, MAX_SVG_BYTES + 1)
    except zlib.error as exc:
        raise InputError(f"{name}: corrupt gzip data ({exc})") from None
    if len(out) > MAX_SVG_BYTES:
        raise InputError(f"{name}: inflates to more than {MAX_SVG_BYTES // 2**20} MiB")
    return out


def check_document(data: bytes) -> bytes:
    """Well-formed XML with an ``<svg>`` root, a valid viewBox if any, and at most
    ``MAX_SEGMENTS`` worth of numbers in its geometry, checked with the C parser before
    svgelements (pure Python, lenient) sees it. Returns the document svgelements is to read:
    ``data``, or, where some of it is never drawn (``_undrawn``), the document without it."""
    root = check_bounds(data)
    if _name(root) != "svg":
        raise InputError(f"the root element is <{_name(root)}>, not <svg>")
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
    _refuse_effects(root)
    return ElementTree.tostring(root) if _undrawn(root) else data


SVG_NS = "http://www.w3.org/2000/svg"
ElementTree.register_namespace("", SVG_NS)  # a pruned document is written back with SVG as its default namespace
ElementTree.register_namespace("xlink", "http://www.w3.org/1999/xlink")
NEVER_DRAWN = ("clipPath", "mask", "pattern", "marker", "symbol")  # drawn only where referenced, which is refused
FEATURES = frozenset(f"http://www.w3.org/TR/SVG11/feature#{f}" for f in (
    "SVG", "SVG-static", "CoreAttribute", "Structure", "BasicStructure", "ConditionalProcessing", "Image", "Style",
    "ViewportAttribute", "Shape", "BasicText", "BasicPaintAttribute", "OpacityAttribute", "BasicGraphicsAttribute",
    "Marker", "Gradient", "Pattern", "Clip", "BasicClip", "Mask"))  # what requiredFeatures may ask, as cairosvg reads it


def _name(el) -> str:
    return el.tag.rsplit("}", 1)[-1] if isinstance(el.tag, str) else ""


def _passes(el, here: str) -> bool:
    """SVG's conditional processing, as cairosvg does it: no ``requiredExtensions``, features
    among ``FEATURES`` and a ``systemLanguage`` (if any) that the user's locale ``here`` starts with."""
    if el.get("requiredExtensions") is not None:
        return False
    features = el.get("requiredFeatures")
    if features is not None and not set(features.split()) <= FEATURES:
        return False
    languages = el.get("systemLanguage")
    return languages is None or any(lang.strip() and here.startswith(lang.strip()) for lang in languages.split(","))


def _undrawn(root) -> bool:
    """Remove from ``root`` what an SVG renderer never draws and svgelements would: the contents
    of ``NEVER_DRAWN`` elements, children that fail conditional processing, and every child of a
    ``<switch>`` but its first that passes. What we cannot draw as SVG does is refused by name
    (``InputError``): a nested ``<svg>`` viewport, a ``<use>`` of a ``<symbol>`` or an ``<svg>``
    (their viewports clip and scale), a ``<use>`` of something inside a never-drawn element.
    Returns whether anything was removed."""
    here = locale.getlocale()[0] or ""
    ids = {el.get("id"): el for el in root.iter() if el.get("id")}
    hidden: set[int] = set()
    for el in root.iter():
        if el is not root and _name(el) == "svg":
            raise InputError("a nested <svg> viewport is not supported (draw its content in the outer <svg>)")
        if _name(el) in NEVER_DRAWN:
            hidden.update(id(e) for e in el.iter())
    for el in root.iter():
        ref = el.get("href") or el.get(_XLINK_HREF) or ""
        target = ids.get(ref[1:]) if _name(el) == "use" and ref.startswith("#") else None
        if target is not None and _name(target) in ("symbol", "svg"):
            raise InputError(f"<use> of a <{_name(target)}> is not supported (its viewport scales and clips)")
        if target is not None and id(target) in hidden:
            raise InputError(f"<use> of {ref[:40]}, which is inside a <clipPath>, <mask>, <pattern> or <marker>, "
                             "is not supported")
    removed = False
    for parent in list(root.iter()):
        kept_one = False
        for child in list(parent):
            drop = _name(child) in NEVER_DRAWN or not _passes(child, here) or (_name(parent) == "switch" and kept_one)
            if drop:
                parent.remove(child)
                removed = True
            elif _name(parent) == "switch" and isinstance(child.tag, str):
                kept_one = True
    return removed


EFFECTS = ("clip-path", "mask", "marker-start", "marker-mid", "marker-end", "marker", "filter")
_EFFECT_CSS = re.compile(r"(?<![\w-])(" + "|".join(EFFECTS) + r")\s*:\s*([^;}]+)")


def _refuse_effects(root) -> None:
    """Clip paths, masks, markers and filters change what is drawn in ways a ``VectorShape``
    does not hold: refused by name (an attribute, a ``style`` or a ``<style>`` sheet), never
    drawn wrong. ``none`` is no effect."""
    for el in root.iter():
        tag = _name(el)
        found = [(k, el.get(k)) for k in EFFECTS if el.get(k) is not None]
        found += _EFFECT_CSS.findall(el.get("style", "") + (el.text or "" if tag == "style" else ""))
        for name, value in found:
            if value.strip() != "none":
                raise InputError(f"<{tag}>: {name} is not supported ({name}: {value.strip()[:40]})")


def _expanded_size(root) -> int:
    """Elements in the document once every ``<use>`` is expanded, refused (``InputError``)
    past ``MAX_ELEMENTS`` or on a ``<use>`` cycle, before svgelements expands anything."""
    ids = {el.get("id"): el for el in root.iter() if el.get("id")}
    memo: dict[int, int] = {}
    visiting: set[int] = set()

    def size(el) -> int:
        if id(el) in memo:
            return memo[id(el)]
        if id(el) in visiting:
            raise InputError("a <use> refers to an element that contains it (a cycle)")
        visiting.add(id(el))
        n = 1 + sum(size(child) for child in el)
        ref = el.get("href") or el.get(_XLINK_HREF) or ""
        if _name(el) == "use" and ref.startswith("#") and ref[1:] in ids:
            n += size(ids[ref[1:]])
        visiting.discard(id(el))
        if n > MAX_ELEMENTS:
            raise InputError(f"too many elements once <use> is expanded (more than {MAX_ELEMENTS})")
        memo[id(el)] = n
        return n

    return size(root)
