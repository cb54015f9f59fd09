"""raster/pyramid.py: the loss of sec. 3.4, eq. 1 (a Gaussian pyramid and the L2 summed over its
levels), against a direct computation and against torch's own convolution."""

from __future__ import annotations

import pytest
import torch
import torch.nn.functional as F

from im2vec_cli.raster.pyramid import detail_weights, gaussian_pyramid, pyr_down, pyramid_l2, pyramid_sizes


def test_sizes_halve_rounding_up():
    assert pyramid_sizes((64, 48), 4) == [(64, 48), (32, 24), (16, 12), (8, 6)]
    assert pyramid_sizes((5, 3), 4) == [(5, 3), (3, 2), (2, 1), (1, 1)]
    with pytest.raises(ValueError, match="levels"):
        pyramid_sizes((8, 8), 0)


def test_pyr_down_is_a_normalised_binomial_blur_then_halving():
    img = torch.rand(2, 3, 9, 8, dtype=torch.float64, generator=torch.Generator().manual_seed(0))
    out = pyr_down(img)
    assert out.shape == (2, 3, 5, 4) and [t.shape[-1] for t in gaussian_pyramid(img, 3)] == [8, 4, 2]
    k1 = torch.tensor([1.0, 4.0, 6.0, 4.0, 1.0], dtype=torch.float64) / 16
    k = (k1[:, None] * k1[None, :]).expand(3, 1, 5, 5)  # the separable 5x5 binomial, one per channel
    ref = F.conv2d(F.pad(img, (2, 2, 2, 2), mode="replicate"), k, groups=3)[..., ::2, ::2]
    torch.testing.assert_close(out, ref)
    torch.testing.assert_close(pyr_down(torch.full((1, 1, 6, 6), 0.3)), torch.full((1, 1, 3, 3), 0.3))  # flat stays flat
    with pytest.raises(ValueError, match="B, C, H, W"):
        pyr_down(torch.zeros(3, 8, 8))


def test_pyramid_l2_sums_each_levels_mse_and_has_a_gradient():
    a = torch.rand(2, 3, 16, 16, dtype=torch.float64, requires_grad=True)
    b = torch.rand(2, 3, 16, 16, dtype=torch.float64)
    ra, rb = gaussian_pyramid(a, 3), gaussian_pyramid(b, 3)
    per = pyramid_l2(ra, rb, reduction="none")
    assert per.shape == (2,)
    ref = sum(((x - y) ** 2).mean(dim=(1, 2, 3)) for x, y in zip(ra, rb))
    torch.testing.assert_close(per, ref)
    torch.testing.assert_close(pyramid_l2(ra, rb), ref.mean())
    assert float(pyramid_l2(rb, rb)) == 0.0
    assert torch.autograd.gradcheck(lambda x: pyramid_l2(gaussian_pyramid(x, 2), rb[:2]), (a,))
    with pytest.raises(ValueError):
        pyramid_l2(ra, rb[:2])


def test_detail_weights_average_one_and_find_the_small_part():
    img = torch.ones(1, 3, 32, 32)
    img[:, :, 10:13, 20:23] = 0.0  # a 3 px dot on white
    w = detail_weights(img, 4.0)
    assert w.shape == (1, 1, 32, 32)
    torch.testing.assert_close(w.mean(), torch.tensor(1.0))
    assert w[0, 0, 11, 21] > 4 * w[0, 0, 0, 0]  # the dot weighs far more than the flat paper
    torch.testing.assert_close(detail_weights(torch.full((1, 3, 8, 8), 0.5), 4.0), torch.ones(1, 1, 8, 8))
    torch.testing.assert_close(detail_weights(img, 0.0), torch.ones(1, 1, 32, 32))
