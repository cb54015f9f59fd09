"""Vector images: the ``VectorImage`` types, the tensor bridge (and our rasterizer on a
``VectorImage``), SVG read/write (static and animated), cairo rasterisation, the Skia
path-ops bridge and overlap resolution. Tracing, curve fitting and outline clean-up live in
``trace/``."""

from .cairo import contact_sheet, fill_vector, rasterize_svg
from .image import VectorImage, VectorShape
from .overlaps import resolve_overlaps, reverse_contour
from .read import from_svg, parse_d
from .svg import contour_d, flipbook_svg, to_svg
from .tensors import from_tensors, render_vector, to_tensors

__all__ = [
    "VectorImage", "VectorShape", "contact_sheet", "contour_d", "fill_vector", "flipbook_svg", "from_svg",
    "from_tensors", "parse_d", "rasterize_svg", "render_vector", "resolve_overlaps", "reverse_contour", "to_svg",
    "to_tensors",
]
