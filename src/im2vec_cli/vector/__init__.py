"""Vector images: the ``VectorImage`` types, the tensor bridge (and our rasterizer on a
``VectorImage``), SVG read/write (static and animated), cairo rasterisation, the Skia
path-ops bridge and overlap resolution. Tracing, curve fitting and outline clean-up live in
``trace/``.

Its names load on first use (``lazy.py``): only ``overlaps`` and ``tensors`` need torch.
"""

from ..lazy import lazy_names

_WHERE = {
    "VectorImage": "image",
    "VectorShape": "image",
    "contact_sheet": "cairo",
    "contour_d": "svg",
    "fill_vector": "cairo",
    "flipbook_svg": "svg",
    "from_svg": "read",
    "from_tensors": "tensors",
    "parse_d": "read",
    "picture_array": "tensors",
    "rasterize_svg": "cairo",
    "render_vector": "tensors",
    "resolve_overlaps": "overlaps",
    "reverse_contour": "overlaps",
    "to_svg": "svg",
    "to_tensors": "tensors",
}
__all__ = sorted(_WHERE)
__getattr__, __dir__ = lazy_names(__name__, _WHERE)
