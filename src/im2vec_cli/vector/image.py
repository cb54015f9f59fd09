"""Vector images: filled shapes of closed cubic contours, in a canvas's pixel frame.

Frame: a ``VectorImage`` stores contours ``(3S, 2)`` in *pixel* coordinates of its
``width x height`` canvas (y down), which is also the SVG ``viewBox``. Contours use the
wrap-around cubic layout of ``raster/bezier.py`` (anchor, control, control, ...; the last
segment ends at point 0). Tensors use the normalised frame; ``tensors.py`` converts.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


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
    notes: dict = field(default_factory=dict, compare=False, repr=False)  # how it was made (``api.vectorize``)

    def rescaled(self, width: float, height: float) -> VectorImage:
        """This image on a ``width x height`` canvas: every point scaled by ``width / self.width``
        across and ``height / self.height`` down (itself when the canvas is already that)."""
        if (self.width, self.height) == (width, height):
            return self
        f = np.array([width / self.width, height / self.height])
        return VectorImage(width, height, [VectorShape([c * f for c in sh.contours], sh.color, sh.fill_rule)
                                           for sh in self.shapes], self.notes)

    @property
    def num_segments(self) -> int:
        return sum(len(c) // 3 for s in self.shapes for c in s.contours)

    @property
    def num_paths(self) -> int:
        return sum(len(s.contours) for s in self.shapes)

    def to_svg(self, decimals: int = 2) -> str:
        """SVG text of this image (``svg.to_svg``)."""
        from .svg import to_svg

        return to_svg(self, decimals)
