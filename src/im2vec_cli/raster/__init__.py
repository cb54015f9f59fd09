"""Differentiable soft rasterizer for closed cubic Bezier paths (see ``render.py``)."""

from .bezier import flatten_closed
from .composite import composite_over, composite_soft
from .pyramid import gaussian_pyramid, pyramid_l2, pyramid_sizes
from .render import Rasterizer, RasterSettings, render_coverage, render_paths, render_pyramid, render_supersampled

__all__ = [
    "RasterSettings", "Rasterizer", "composite_over", "composite_soft", "flatten_closed",
    "gaussian_pyramid", "pyramid_l2", "pyramid_sizes", "render_coverage", "render_paths", "render_pyramid",
    "render_supersampled",
]
