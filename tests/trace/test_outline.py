"""Outlines redrawn clean (``trace/outline.py``), checked on cairosvg renders against the true shape."""

from __future__ import annotations

import numpy as np
import torch

from im2vec_cli.raster import flatten_closed, polygon_area
from im2vec_cli.trace.outline import redrawn
from im2vec_cli.vector import VectorImage, VectorShape
from tests.trace.outlines import check_clean_svg, ink, no_background_inside, svg_of, topology


def test_redrawn_unites_overlapping_parts_into_outer_contour_and_hole():
    """A ring drawn as two overlapping halves with a hairline gap where they should meet (the
    model's way of drawing): redrawn, it is one shape of one outer contour and one hole, the
    hairline closed, nothing of the ring's inside left uncovered."""
    def half(a0, a1, r0=24.0, r1=14.0, n=24):
        t = np.linspace(a0, a1, n)
        outer = np.stack([32 + r0 * np.cos(t), 32 + r0 * np.sin(t)], 1)
        inner = np.stack([32 + r1 * np.cos(t[::-1]), 32 + r1 * np.sin(t[::-1])], 1)
        ring = np.vstack([outer, inner])
        return np.repeat(ring, 3, axis=0)  # straight cubics: anchor, control, control at one point

    parts = [half(-0.05, np.pi + 0.05), half(np.pi + 0.06, 2 * np.pi - 0.02)]  # overlap on one side, 0.24 px gap on the other
    model_like = VectorImage(64, 64, [VectorShape(parts, (0, 0, 0), "nonzero")])  # as resolve_overlaps leaves it
    clean, flags = redrawn(model_like, 0.5)
    assert len(clean.shapes) == 1 and len(clean.shapes[0].contours) == 2
    areas = sorted(float(polygon_area(flatten_closed(torch.from_numpy(c), 8))) for c in clean.shapes[0].contours)
    assert areas[0] < 0 < areas[1]  # one hole (counter-clockwise), one outer contour (clockwise on screen)
    svg = clean.to_svg()
    check_clean_svg(svg)
    truth = svg_of('<circle cx="32" cy="32" r="24"/><circle cx="32" cy="32" r="14" fill="white"/>')
    assert topology(ink(svg, 4)) == topology(ink(truth, 4)) == (1, 1)
    assert no_background_inside(svg, truth, depth=1.0)
