"""raster/coverage.py: the nearest edge, the soft coverage and its closed-form gradient, against a
dense NumPy distance computed here and against finite differences (``gradcheck``)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from im2vec_cli.raster.coverage import inside_from_winding, nearest_edge_search, signed_coverage, soft_coverage
from im2vec_cli.raster.winding import winding_number


def polygon(n: int = 7, r: float = 6.0, c: float = 8.1) -> tuple[torch.Tensor, torch.Tensor]:
    k = torch.arange(n, dtype=torch.float64) * 2 * math.pi / n
    a = torch.stack([c + r * torch.cos(k), c + 0.8 * r * torch.sin(k)], -1)[None]  # (1, n, 2)
    return a, torch.roll(a, -1, 1)


def dense_distance(a: np.ndarray, b: np.ndarray, h: int, w: int) -> np.ndarray:
    """Distance from every pixel centre to the nearest segment a_i b_i, all pairs: ``(H, W)``."""
    y, x = np.mgrid[0:h, 0:w] + 0.5
    p = np.stack([x, y], -1)[..., None, :]  # (H, W, 1, 2)
    d = b - a
    t = np.clip(((p - a) * d).sum(-1) / (d * d).sum(-1), 0, 1)
    return np.linalg.norm(p - a - t[..., None] * d, axis=-1).min(-1)


def test_nearest_edge_is_the_dense_minimum_with_culling_or_not():
    a, b = polygon()
    ref = dense_distance(a[0].numpy(), b[0].numpy(), 16, 16)
    for radius in (math.inf, 3.0):
        idx, dist = nearest_edge_search(a, b, 16, 16, radius=radius)
        assert idx.shape == dist.shape == (1, 16, 16)
        near = ref <= radius  # beyond the culling radius only "farther than radius" is promised
        np.testing.assert_allclose(dist[0].numpy()[near], ref[near], atol=1e-6)
        assert (dist[0].numpy()[~near] >= radius - 1e-6).all()


def test_coverage_is_a_sigmoid_of_the_signed_distance_in_range_and_shape():
    a, b = polygon()
    wind = winding_number(a.float(), b.float(), 16, 16, eager=True).to(torch.float64)
    cov = soft_coverage(a, b, wind, 16, 16, radius=4.0, tau=0.5)
    assert cov.shape == (1, 16, 16) and float(cov.min()) >= 0 and float(cov.max()) <= 1
    d = torch.from_numpy(dense_distance(a[0].numpy(), b[0].numpy(), 16, 16)).clamp(max=4.0)
    sign = torch.where(wind[0] != 0, 1.0, -1.0).to(torch.float64)
    torch.testing.assert_close(cov[0], torch.sigmoid(sign * d / 0.5), atol=1e-6, rtol=0)
    torch.testing.assert_close(signed_coverage(d[None], wind, 4.0, 0.5, "nonzero"), cov, atol=1e-6, rtol=0)


def test_the_closed_form_gradient_is_the_true_one():
    a, b = polygon(5)
    pts = a[0].clone().requires_grad_(True)

    def cover(p):
        aa = p[None]
        bb = torch.roll(aa, -1, 1)
        wind = winding_number(aa.detach().float(), bb.detach().float(), 16, 16, eager=True).to(torch.float64)
        return soft_coverage(aa, bb, wind, 16, 16, radius=3.0, tau=0.7)

    assert torch.autograd.gradcheck(cover, (pts,), atol=1e-5)


def test_the_fill_rules_and_a_bad_one():
    wind = torch.tensor([[-2.0, -1.0, 0.0, 1.0, 2.0, 3.0]])
    assert inside_from_winding(wind, "nonzero").tolist() == [[True, True, False, True, True, True]]
    assert inside_from_winding(wind, "evenodd").tolist() == [[False, True, False, True, False, True]]
    a, b = polygon()
    with pytest.raises(ValueError, match="fill_rule"):
        soft_coverage(a, b, torch.zeros(1, 16, 16), 16, 16, radius=3.0, tau=0.5, fill_rule="winding")
