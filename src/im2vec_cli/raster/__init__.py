"""Differentiable soft rasterizer for closed cubic Bezier paths (see ``render.py``).

This package imports nothing of im2vec's above it.
"""

from ._compile import compile_enabled, compiling, set_compile
from .bezier import cubic_at, flatten_closed, line_controls, polygon_area, segment_controls, subdivide_to
from .composite import composite_over, composite_soft, solve_colors, solve_order
from .coverage import inside_from_winding
from .pyramid import detail_weights, gaussian_pyramid, pyramid_l2, pyramid_sizes
from .render import (
    PYRAMID_COARSE,
    Rasterizer,
    RasterSettings,
    render_coverage,
    render_paths,
    render_pyramid,
    render_supersampled,
)
from .winding import winding_number

__all__ = [
    "PYRAMID_COARSE", "RasterSettings", "Rasterizer", "compile_enabled", "compiling", "composite_over", "composite_soft",
    "cubic_at", "detail_weights", "flatten_closed", "gaussian_pyramid", "inside_from_winding", "line_controls",
    "polygon_area", "pyramid_l2", "pyramid_sizes", "render_coverage", "render_paths", "render_pyramid", "render_supersampled",
    "segment_controls", "set_compile", "solve_colors", "solve_order", "subdivide_to", "winding_number",
]
