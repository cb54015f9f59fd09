"""Rasterisation with cairo (no autograd): the independent reference and what a user's
viewer shows.

``rasterize_svg`` draws any SVG through cairosvg. ``fill_vector`` draws one of our own
``VectorImage`` (closed cubic paths, flat fills) straight through libcairo, with the calls
cairosvg makes for it, so the pixels are the same (tests/cli/test_startup.py) without cairocffi,
whose import parses cairo's C headers at every start (0.3-0.5 s, a fifth of a one-picture
`vectorize`). Where libcairo cannot be loaded that way, it goes through cairosvg.
"""

from __future__ import annotations

import ctypes
import functools
import math
import sys

import numpy as np

from .image import VectorImage
from .svg import hex_color, number_text

LIBCAIRO = ("libcairo.so.2", "libcairo.2.dylib", "libcairo-2.dll")  # the names cairocffi loads


@functools.cache
def _cairo():
    """libcairo through ctypes with the signatures used here (once per process), or ``None``."""
    for name in LIBCAIRO:
        try:
            lib = ctypes.CDLL(name)
            break
        except OSError:
            continue
    else:
        return None
    vp, dbl, i32 = ctypes.c_void_p, ctypes.c_double, ctypes.c_int
    for name, res, args in (
        ("cairo_image_surface_create", vp, [i32, i32, i32]), ("cairo_create", vp, [vp]),
        ("cairo_scale", None, [vp, dbl, dbl]), ("cairo_move_to", None, [vp, dbl, dbl]),
        ("cairo_curve_to", None, [vp] + [dbl] * 6), ("cairo_close_path", None, [vp]),
        ("cairo_set_fill_rule", None, [vp, i32]), ("cairo_set_source_rgba", None, [vp] + [dbl] * 4),
        ("cairo_fill", None, [vp]), ("cairo_surface_flush", None, [vp]),
        ("cairo_image_surface_get_data", ctypes.POINTER(ctypes.c_ubyte), [vp]),
        ("cairo_image_surface_get_stride", i32, [vp]), ("cairo_status", i32, [vp]),
        ("cairo_destroy", None, [vp]), ("cairo_surface_destroy", None, [vp]),
    ):
        fn = getattr(lib, name)
        fn.restype, fn.argtypes = res, args
    return lib


def fill_vector(image: VectorImage, width: int, height: int, decimals: int = 3) -> np.ndarray:
    """``rasterize_svg(image.to_svg(decimals), width, height)``, pixel for pixel, without
    cairosvg: each shape's contours filled under its rule, back to front, over white, its
    coordinates rounded as the SVG text writes them. ``(H, W, 3)`` float64 in [0, 1]."""
    lib = _cairo()
    vw, vh = float(number_text(image.width, decimals)), float(number_text(image.height, decimals))
    sx, sy = (width / vw, height / vh) if vw > 0 and vh > 0 else (0.0, 1.0)
    if lib is None or sx != sy or width < 1 or height < 1:  # (a letterboxed viewBox: cairosvg's business)
        return rasterize_svg(image.to_svg(decimals), width, height)
    surface = lib.cairo_image_surface_create(0, width, height)  # CAIRO_FORMAT_ARGB32, cleared
    cr = lib.cairo_create(surface)
    try:
        if lib.cairo_status(cr) != 0:
            raise MemoryError(f"cairo could not make a {width} x {height} surface")
        if sx != 1:
            lib.cairo_scale(cr, sx, sy)
        for shape in image.shapes:
            if not shape.contours:
                continue
            for c in shape.contours:  # as svg.contour_d writes it: M p0 C p1 p2 p3 ... Z
                q = [(float(number_text(x, decimals)), float(number_text(y, decimals)))
                     for x, y in np.asarray(c, dtype=np.float64).tolist()]
                n = len(q)
                lib.cairo_move_to(cr, *q[0])
                for k in range(n // 3):
                    lib.cairo_curve_to(cr, *q[3 * k + 1], *q[3 * k + 2], *q[(3 * k + 3) % n])
                lib.cairo_close_path(cr)
            lib.cairo_set_fill_rule(cr, 1 if shape.fill_rule == "evenodd" else 0)  # EVEN_ODD or WINDING
            rgb = bytes.fromhex(hex_color(shape.color)[1:])
            lib.cairo_set_source_rgba(cr, rgb[0] / 255, rgb[1] / 255, rgb[2] / 255, 1.0)
            lib.cairo_fill(cr)
        lib.cairo_surface_flush(surface)
        stride = lib.cairo_image_surface_get_stride(surface)
        data = np.ctypeslib.as_array(lib.cairo_image_surface_get_data(surface), shape=(height * stride,)).copy()
    finally:
        lib.cairo_destroy(cr)
        lib.cairo_surface_destroy(surface)
    return _over_white(data.reshape(height, stride // 4, 4)[:, :width])


def _over_white(px: np.ndarray) -> np.ndarray:
    """Cairo's premultiplied native-endian ARGB32 pixels ``(H, W, 4)`` uint8 over white: ``(H, W, 3)``."""
    bgra = px if sys.byteorder == "little" else px[..., ::-1]  # a native-endian 32-bit ARGB word
    return bgra[..., 2::-1] / 255.0 + (1 - bgra[..., 3:] / 255.0)  # premultiplied colour over white


def rasterize_svg(text: str | bytes, width: int, height: int) -> np.ndarray:
    """Render SVG text with cairosvg at ``width x height`` over white, once its size and
    nesting are checked (``document.check_bounds``: else one ``InputError`` line).

    Read from cairo's own pixel buffer (premultiplied ARGB32), not through a PNG: half the
    time at 64 px, and no unpremultiply rounding.

    Returns:
        ``(H, W, 3)`` float64 array in [0, 1].
    """
    from cairosvg.parser import Tree
    from cairosvg.surface import PNGSurface

    from .document import check_bounds

    data = text.encode() if isinstance(text, str) else text
    check_bounds(data)  # no entity expansion, no <use> fan-out: cairosvg bounds neither
    surface = PNGSurface(Tree(bytestring=data), None, 96, output_width=width, output_height=height).cairo
    surface.flush()
    h, w = surface.get_height(), surface.get_width()
    return _over_white(np.frombuffer(surface.get_data(), np.uint8).reshape(h, surface.get_stride() // 4, 4)[:, :w])


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
