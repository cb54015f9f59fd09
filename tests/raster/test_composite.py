"""raster/composite.py: ``composite_over`` against the "over" operator applied layer by layer here;
``solve_colors``: the layer colours closest to a picture under ``composite_over``; ``solve_order``:
their order, scored with its colours solved. (``composite_soft``'s convexity, its limit and its
gradient: tests/raster/test_render.py.)"""

import itertools

import numpy as np
import pytest
import torch

from im2vec_cli.config import ConfigError, ModelConfig
from im2vec_cli.raster import composite_over, solve_colors, solve_order


def _layers(seed: int, b: int = 2, g: int = 4, size: int = 12):
    gen = torch.Generator().manual_seed(seed)
    cov = torch.rand(b, g, size, size, generator=gen, dtype=torch.float64) * 0.9  # no layer hides the others
    depth = torch.rand(b, g, generator=gen, dtype=torch.float64)
    colors = torch.rand(b, g, 3, generator=gen, dtype=torch.float64)
    return cov, depth, colors


def test_over_is_the_over_operator_back_to_front():
    cov, depth, colors = _layers(3)
    out = composite_over(cov, colors, depth, background=0.8)
    assert out.shape == (2, 3, 12, 12)
    for i in range(2):
        ref = torch.full((3, 12, 12), 0.8, dtype=torch.float64)
        for g in torch.argsort(depth[i]).tolist():  # the farthest first
            ref = ref * (1 - cov[i, g]) + cov[i, g] * colors[i, g][:, None, None]
        torch.testing.assert_close(out[i], ref)
    with pytest.raises(ValueError):
        composite_over(cov, colors[:, :3], depth)


def test_recovers_the_colours_a_picture_was_composited_with():
    cov, depth, truth = _layers(0)
    target = composite_over(cov, truth, depth)
    got = solve_colors(cov, depth, target, prior=torch.full_like(truth, 0.5), ridge=1e-12)
    assert torch.allclose(got, truth, atol=1e-6)


def test_matches_a_least_squares_solve_of_the_rendered_basis():
    # independent reference: composite_over is affine in the colours, so render it with each unit
    # colour to get the design matrix and solve the ridge problem with numpy
    cov, depth, prior = _layers(1)
    gen = torch.Generator().manual_seed(2)
    target = torch.rand(2, 3, 12, 12, generator=gen, dtype=torch.float64) * 0.2 + 0.4
    ridge = 1e-2
    got = solve_colors(cov, depth, target, prior, ridge=ridge)
    for i in range(2):
        base = composite_over(cov[i : i + 1], torch.zeros(1, 4, 3, dtype=torch.float64), depth[i : i + 1])[0, 0]
        cols = []
        for j in range(4):
            unit = torch.zeros(1, 4, 3, dtype=torch.float64)
            unit[0, j] = 1.0
            cols.append((composite_over(cov[i : i + 1], unit, depth[i : i + 1])[0, 0] - base).flatten().numpy())
        a = np.stack(cols, 1)  # (N, G)
        lam = ridge * a.shape[0]
        for c in range(3):
            rhs = a.T @ (target[i, c].flatten().numpy() - base.flatten().numpy()) + lam * prior[i, :, c].numpy()
            want = np.clip(np.linalg.solve(a.T @ a + lam * np.eye(4), rhs), 0, 1)
            np.testing.assert_allclose(got[i, :, c].numpy(), want, atol=1e-9)


def test_a_hidden_layer_keeps_its_prior_and_the_error_never_grows():
    cov, depth, truth = _layers(3, b=1)
    cov[0, 0] = 0.5
    cov[0, 1] = 1.0  # layer 1 opaque everywhere, in front of layer 0
    depth[0, 0], depth[0, 1] = 0.0, 0.5
    depth[0, 2:] = torch.tensor([0.7, 0.9], dtype=torch.float64)
    target = composite_over(cov, truth, depth)
    prior = torch.rand(1, 4, 3, generator=torch.Generator().manual_seed(4), dtype=torch.float64)
    got = solve_colors(cov, depth, target, prior, ridge=1e-3)
    assert torch.allclose(got[0, 0], prior[0, 0], atol=1e-9)
    err = lambda c: float((composite_over(cov, c, depth) - target).pow(2).mean())  # noqa: E731
    assert err(got) < 0.01 * err(prior)


def test_bad_shapes_and_configs_are_refused():
    cov, depth, prior = _layers(5)
    with pytest.raises(ValueError, match="target"):
        solve_colors(cov, depth, torch.rand(2, 3, 5, 5, dtype=torch.float64), prior)
    with pytest.raises(ValueError, match="ridge"):
        solve_colors(cov, depth, torch.rand(2, 3, 12, 12, dtype=torch.float64), prior, ridge=0.0)
    with pytest.raises(ValueError, match="target"):
        solve_order(cov, depth, torch.rand(2, 3, 5, 5, dtype=torch.float64), prior)
    with pytest.raises(ValueError, match="ridge"):
        solve_order(cov, depth, torch.rand(2, 3, 12, 12, dtype=torch.float64), prior, ridge=0.0)
    with pytest.raises(ConfigError, match="solve_colors"):
        ModelConfig(grouping="evenodd", solve_colors=True)
    with pytest.raises(ConfigError, match="solve_colors"):
        ModelConfig(grouping="layers", palette="#000000", solve_colors=True)
    with pytest.raises(ConfigError, match="solve_order needs solve_colors"):
        ModelConfig(grouping="layers", solve_order=True)


def test_gradients_through_the_solve_match_finite_differences():
    # TrainConfig.solved trains the shapes through the solve: its derivative in the coverages
    cov, depth, truth = _layers(3, b=1, g=3, size=5)
    truth = 0.2 + 0.6 * truth  # the solution inside (0, 1): the clamp is inactive
    target = composite_over(cov, truth, depth) + 0.01 * torch.randn(1, 3, 5, 5, dtype=torch.float64,
                                                                    generator=torch.Generator().manual_seed(4))
    cov.requires_grad_(True)
    assert torch.autograd.gradcheck(lambda c: solve_colors(c, depth, target, truth, ridge=1e-3), (cov,))


def _error(cov, depth, target):
    colors = solve_colors(cov, depth, target, torch.full(depth.shape + (3,), 0.5, dtype=cov.dtype), ridge=1e-9)
    return (composite_over(cov, colors, depth) - target).pow(2).flatten(1).mean(1)  # (B,)


def test_the_order_a_picture_was_composited_in_is_found_again():
    # the front layer sent to the back, then two layers swapped: one move, then two, away from the truth
    cov, depth, truth = _layers(6, b=2, g=4)
    target = composite_over(cov, truth, depth)
    order = torch.argsort(depth, 1)  # back to front
    wrong = depth.clone()
    wrong[0, order[0, -1]] = depth[0].min() - 1  # picture 0: its front layer at the back
    wrong[1, order[1, 1]], wrong[1, order[1, 2]] = depth[1, order[1, 2]], depth[1, order[1, 1]]  # picture 1: a swap
    got = solve_order(cov, wrong, target, torch.full_like(truth, 0.5), ridge=1e-9)
    assert torch.equal(torch.argsort(got, 1), order)
    assert torch.equal(got.sort(1).values, wrong.sort(1).values)  # the depths' own values, reassigned
    assert float(_error(cov, got, target).max()) < 1e-12 < float(_error(cov, wrong, target).min())


def test_tied_depths_come_back_in_the_order_found():
    cov, depth, truth = _layers(10, b=2, g=4)
    target = composite_over(cov, truth, depth)
    got = solve_order(cov, torch.zeros_like(depth), target, torch.full_like(truth, 0.5), ridge=1e-9)
    assert torch.equal(torch.argsort(got, 1), torch.argsort(depth, 1))
    assert bool((got.sort(1).values.diff(dim=1) > 0).all()) and float(got.abs().max()) < 1e-5  # ulps apart


def test_the_order_found_is_never_worse_and_often_the_best_of_all():
    # against every one of the 4! orders, on pictures no order draws exactly (noise added)
    cov, depth, truth = _layers(7, b=6, g=4)
    target = (composite_over(cov, truth, torch.rand(depth.shape, dtype=torch.float64,
                                                    generator=torch.Generator().manual_seed(8)))
              + 0.05 * torch.randn(6, 3, 12, 12, dtype=torch.float64, generator=torch.Generator().manual_seed(9)))
    got = solve_order(cov, depth, target, torch.full_like(truth, 0.5), ridge=1e-9)
    every = torch.stack([_error(cov, torch.tensor(p, dtype=torch.float64).expand(6, 4), target)
                         for p in itertools.permutations(range(4))])  # (24, B)
    found = _error(cov, got, target)
    assert bool((found <= _error(cov, depth, target) + 1e-12).all())
    assert bool((found <= 1.02 * every.min(0).values).all())
