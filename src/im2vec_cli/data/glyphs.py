"""Exact glyph outlines with fontTools, as closed cubic contours.

Frame: ``glyph_outline`` returns font units (y up); ``fit_outline`` maps them into a
``size x size`` pixel canvas (y down), scaled so that the glyph's bounding box fits inside
``size - 2 * margin`` pixels and centred. The same convention is used for every glyph,
so a PNG and its SVG ground truth overlay exactly.
"""

from __future__ import annotations

import numpy as np
import torch
from fontTools.pens.basePen import BasePen

from ..errors import DataError
from ..raster import cubic_at, line_controls, segment_controls
from ..vector import VectorImage, VectorShape


class _CubicPen(BasePen):
    """Collects closed contours as cubic control points; lines and quadratics are elevated."""

    def __init__(self, glyphset):
        super().__init__(glyphset)
        self.contours: list[np.ndarray] = []
        self._cur: list[tuple[float, float]] = []
        self._start: tuple[float, float] | None = None

    def _moveTo(self, pt):
        self._cur = [pt]
        self._start = pt

    def _lineTo(self, pt):
        a = np.asarray(self._getCurrentPoint())
        b = np.asarray(pt)
        self._cur += [*map(tuple, line_controls(a, b)), pt]

    def _curveToOne(self, p1, p2, p3):
        self._cur += [p1, p2, p3]

    def _qCurveToOne(self, p1, p2):
        a, q, b = np.asarray(self._getCurrentPoint()), np.asarray(p1), np.asarray(p2)
        self._cur += [tuple(a + 2 * (q - a) / 3), tuple(b + 2 * (q - b) / 3), p2]

    def _closePath(self):
        if self._start is not None and len(self._cur) > 1:
            if not np.allclose(self._cur[-1], self._start):
                self._lineTo(self._start)
            pts = np.asarray(self._cur[:-1], dtype=np.float64)  # last anchor == start
            if len(pts) >= 3:
                self.contours.append(pts)
        self._cur, self._start = [], None

    _endPath = _closePath


def glyph_outline(font, char: str) -> list[np.ndarray]:
    """Closed cubic contours ``(3S_i, 2)`` of ``char`` in font units (y up).

    Args:
        font: a ``fontTools.ttLib.TTFont``.
    """
    cmap = font.getBestCmap() or {}
    name = cmap.get(ord(char))
    if name is None:
        raise DataError(f"font has no glyph for {char!r}")
    glyphset = font.getGlyphSet()
    pen = _CubicPen(glyphset)
    glyphset[name].draw(pen)
    return pen.contours


def _curve_samples(points: np.ndarray, n: int = 32) -> np.ndarray:
    """Points along a closed cubic contour ``(3S, 2)``: ``(S * n, 2)``."""
    ctrl = segment_controls(torch.from_numpy(np.asarray(points, dtype=np.float64))).numpy()  # (S, 4, 2)
    return cubic_at(ctrl, np.linspace(0, 1, n, endpoint=False)).reshape(-1, 2)  # (S * n, 2)


def fit_outline(contours: list[np.ndarray], size: int, margin: float) -> list[np.ndarray]:
    """Map font-unit contours into a ``size``-pixel canvas (y down), bbox-fitted and centred."""
    if not contours:
        raise DataError("glyph has no outline")
    allp = np.concatenate([_curve_samples(c) for c in contours], 0)  # the curve's box, not the controls'
    lo, hi = allp.min(0), allp.max(0)
    extent = float(max(hi[0] - lo[0], hi[1] - lo[1]))
    if extent <= 0:
        raise DataError("glyph outline is degenerate")
    scale = (size - 2 * margin) / extent
    centre = (lo + hi) / 2
    out = []
    for c in contours:
        x = (c[:, 0] - centre[0]) * scale + size / 2
        y = size / 2 - (c[:, 1] - centre[1]) * scale
        out.append(np.stack([x, y], -1))
    return out


def glyph_image(font, char: str, size: int = 64, margin: float = 4.0) -> VectorImage:
    """The exact outline of ``char`` as a black nonzero-filled shape on a ``size`` canvas."""
    contours = fit_outline(glyph_outline(font, char), size, margin)
    return VectorImage(float(size), float(size), [VectorShape(contours, (0.0, 0.0, 0.0), "nonzero")])
