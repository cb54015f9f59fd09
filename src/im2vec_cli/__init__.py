"""im2vec: raster images to closed cubic Bezier vector graphics with a learned model."""

__version__ = "0.1.0"
