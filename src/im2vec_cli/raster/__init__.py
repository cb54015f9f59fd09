"""Differentiable soft rasterizer for closed cubic Bezier paths (see ``render.py``).

This package imports nothing of im2vec's above it.

Its names load on first use (``lazy.py``): ``curves`` needs NumPy alone, the rest torch.
"""

from ..lazy import lazy_names

_WHERE = {
    "PYRAMID_COARSE": "render",
    "RasterSettings": "render",
    "Rasterizer": "render",
    "compile_enabled": "_compile",
    "compiling": "_compile",
    "composite_over": "composite",
    "composite_soft": "composite",
    "cubic_at": "curves",
    "detail_weights": "pyramid",
    "flatten_closed": "bezier",
    "gaussian_pyramid": "pyramid",
    "inside_from_winding": "coverage",
    "line_controls": "curves",
    "polygon_area": "bezier",
    "pyramid_l2": "pyramid",
    "pyramid_sizes": "pyramid",
    "render_coverage": "render",
    "render_paths": "render",
    "render_pyramid": "render",
    "render_supersampled": "render",
    "segment_controls": "bezier",
    "set_compile": "_compile",
    "solve_colors": "composite",
    "solve_order": "composite",
    "subdivide_to": "bezier",
    "winding_number": "winding",
}
__all__ = sorted(_WHERE)
__getattr__, __dir__ = lazy_names(__name__, _WHERE)
