"""raster/curves.py: the cubic geometry in NumPy (the trace's, which imports no torch), against the
Bernstein form written out here and against the renderer's own torch geometry."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from im2vec_cli.raster.bezier import flatten_closed
from im2vec_cli.raster.curves import (
    contour_areas,
    cubic_at,
    flatten_ring,
    line_controls,
    ring_area,
    ring_areas,
    segments_of,
)


def test_cubic_at_is_the_bernstein_polynomial_on_arrays_and_tensors():
    rng = np.random.default_rng(0)
    ctrl = rng.random((3, 4, 2))
    t = np.linspace(0, 1, 9)
    p0, p1, p2, p3 = (ctrl[:, i, None, :] for i in range(4))
    tt = t[:, None]
    ref = (1 - tt) ** 3 * p0 + 3 * (1 - tt) ** 2 * tt * p1 + 3 * (1 - tt) * tt**2 * p2 + tt**3 * p3
    np.testing.assert_allclose(cubic_at(ctrl, t), ref, atol=1e-12)
    np.testing.assert_allclose(cubic_at(torch.from_numpy(ctrl), torch.from_numpy(t)).numpy(), ref, atol=1e-12)


def test_a_line_as_a_cubic_stays_on_the_line():
    a, b = np.array([1.0, 2.0]), np.array([7.0, -4.0])
    c1, c2 = line_controls(a, b)
    pts = cubic_at(np.stack([a, c1, c2, b])[None], np.linspace(0, 1, 11))[0]
    np.testing.assert_allclose(pts, a + np.linspace(0, 1, 11)[:, None] * (b - a), atol=1e-12)  # evenly spaced


def test_the_numpy_ring_is_the_renderers_ring():
    pts = np.random.default_rng(1).random((2, 12, 2))  # two paths of 4 segments
    verts = flatten_ring(pts, 6)
    assert verts.shape == (2, 24, 2)
    np.testing.assert_allclose(verts, flatten_closed(torch.from_numpy(pts), 6).numpy(), atol=1e-12)
    assert segments_of(pts).shape == (2, 4, 4, 2)
    with pytest.raises(ValueError, match="3S, 2"):
        segments_of(np.zeros((5, 2)))
    with pytest.raises(ValueError, match="samples"):
        flatten_ring(pts, 0)


def test_ring_area_of_a_square_and_a_circle():
    square = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [0.0, 4.0]])
    assert ring_area(square) == 16.0 and ring_area(square[::-1]) == -16.0
    k = 0.5522847498  # the cubic circle: four quarter arcs of radius 1
    quarter = [[1, 0], [1, k], [k, 1], [0, 1], [-k, 1], [-1, k], [-1, 0], [-1, -k], [-k, -1], [0, -1], [k, -1], [1, -k]]
    area = ring_area(flatten_ring(np.array(quarter, dtype=float), 64))
    assert abs(area - np.pi) < 2e-3


def test_cubics_at_is_cubic_at_row_by_row_to_the_bit():
    from im2vec_cli.raster.curves import cubic_at, cubics_at

    rng = np.random.default_rng(2)
    ctrl, t = rng.normal(size=(9, 4, 2)), rng.random((9, 13))
    got = cubics_at(ctrl, t)
    assert got.shape == (9, 13, 2)
    assert all(np.array_equal(got[k], cubic_at(ctrl[k], t[k])) for k in range(9))


def test_areas_of_rings_of_different_lengths_are_each_ones_area():
    """``ring_areas`` and ``contour_areas`` (one pass over rings laid end to end) give, ring by ring, what
    ``ring_area`` and ``ring_area(flatten_ring(...))`` give one at a time."""
    rng = np.random.default_rng(0)
    rings = [rng.normal(size=(n, 2)) * 10 for n in (3, 1, 7, 40, 4)]
    contours = [rng.normal(size=(3 * s, 2)) * 10 for s in (1, 2, 5, 13)]
    assert np.allclose(ring_areas(rings), [ring_area(r) for r in rings], rtol=0, atol=1e-9)
    assert np.allclose(contour_areas(contours, 8), [ring_area(flatten_ring(c, 8)) for c in contours], rtol=0, atol=1e-9)
    assert ring_areas([]).shape == contour_areas([], 8).shape == (0,)
