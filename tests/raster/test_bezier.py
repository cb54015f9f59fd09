"""raster/bezier.py: the cubic geometry of the renderer, against the Bernstein form written out here."""

from __future__ import annotations

import math

import pytest
import torch

from im2vec_cli.raster.bezier import (
    bernstein_weights,
    flatten_closed,
    polygon_area,
    restrict,
    segment_controls,
    split_segment,
    subdivide_to,
)


def bernstein(ctrl: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
    """The reference: ``ctrl (..., 4, 2)`` at ``t (T,)`` -> ``(..., T, 2)``, the polynomial written out."""
    t = t[:, None]
    p0, p1, p2, p3 = (ctrl[..., i, None, :] for i in range(4))
    return (1 - t) ** 3 * p0 + 3 * (1 - t) ** 2 * t * p1 + 3 * (1 - t) * t**2 * p2 + t**3 * p3


def ring(segments: int = 4, seed: int = 0) -> torch.Tensor:
    """A random closed path ``(3S, 2)`` in float64."""
    return torch.rand(3 * segments, 2, generator=torch.Generator().manual_seed(seed), dtype=torch.float64)


def test_bernstein_weights_are_the_polynomial_at_each_sample():
    w = bernstein_weights(8, dtype=torch.float64, device=torch.device("cpu"))
    assert w.shape == (8, 4)
    torch.testing.assert_close(w.sum(1), torch.ones(8, dtype=torch.float64))
    basis = torch.eye(4, dtype=torch.float64)[..., None].expand(4, 4, 2)  # control k alone
    ref = bernstein(basis, torch.arange(8, dtype=torch.float64) / 8)[..., 0].T  # (8, 4)
    torch.testing.assert_close(w, ref)


def test_segment_controls_close_the_path_and_refuse_a_ragged_one():
    pts = ring(3)
    ctrl = segment_controls(pts)
    assert ctrl.shape == (3, 4, 2)
    torch.testing.assert_close(ctrl[-1, 3], pts[0])  # the last segment ends where the path starts
    torch.testing.assert_close(ctrl[1, 0], pts[3])
    for bad in (torch.zeros(7, 2), torch.zeros(6, 3), torch.zeros(0, 2)):
        with pytest.raises(ValueError, match="3S, 2"):
            segment_controls(bad)


def test_flatten_closed_samples_every_segment_and_passes_gradients_exactly():
    pts = ring(4).requires_grad_(True)
    verts = flatten_closed(pts, 5)
    assert verts.shape == (20, 2)
    ref = bernstein(segment_controls(pts), torch.arange(5, dtype=torch.float64) / 5).reshape(20, 2)
    torch.testing.assert_close(verts, ref)
    assert torch.autograd.gradcheck(lambda p: flatten_closed(p, 3), (pts,))


def test_split_and_restrict_reproduce_the_curve():
    ctrl = segment_controls(ring(2, seed=1))  # (2, 4, 2)
    u = torch.linspace(0, 1, 7, dtype=torch.float64)
    left, right = split_segment(ctrl, 0.3)
    torch.testing.assert_close(bernstein(left, u), bernstein(ctrl, 0.3 * u))
    torch.testing.assert_close(bernstein(right, u), bernstein(ctrl, 0.3 + 0.7 * u))
    t0, t1 = torch.tensor([0.2, 0.5], dtype=torch.float64), torch.tensor([0.6, 0.9], dtype=torch.float64)
    piece = restrict(ctrl, t0, t1)
    for i in range(2):
        torch.testing.assert_close(bernstein(piece[i], u), bernstein(ctrl[i], t0[i] + (t1[i] - t0[i]) * u))


def test_subdivide_to_adds_segments_without_moving_the_outline():
    pts = ring(3, seed=2)
    finer = subdivide_to(pts, 7)
    assert finer.shape == (21, 2)
    dense = bernstein(segment_controls(pts), torch.linspace(0, 1, 2001, dtype=torch.float64)).reshape(-1, 2)
    anchors = finer[0::3]
    assert torch.cdist(anchors, dense).min(1).values.max() < 1e-3  # every new anchor lies on the old curve


def test_polygon_area_is_signed_and_exact():
    square = torch.tensor([[0.0, 0.0], [2.0, 0.0], [2.0, 3.0], [0.0, 3.0]], dtype=torch.float64)
    assert float(polygon_area(square)) == 6.0 and float(polygon_area(square.flip(0))) == -6.0
    theta = torch.arange(2000, dtype=torch.float64) * 2 * math.pi / 2000
    circle = torch.stack([torch.cos(theta), torch.sin(theta)], -1)
    assert abs(float(polygon_area(circle)) - math.pi) < 1e-4
    assert polygon_area(torch.stack([square, 2 * square])).tolist() == [6.0, 24.0]  # batched
