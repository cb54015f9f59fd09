"""``raster.solve_colors``: the layer colours closest to a picture under ``composite_over``."""

import numpy as np
import pytest
import torch

from im2vec_cli.config import ConfigError, ModelConfig
from im2vec_cli.raster import composite_over, solve_colors


def _layers(seed: int, b: int = 2, g: int = 4, size: int = 12):
    gen = torch.Generator().manual_seed(seed)
    cov = torch.rand(b, g, size, size, generator=gen, dtype=torch.float64) * 0.9  # no layer hides the others
    depth = torch.rand(b, g, generator=gen, dtype=torch.float64)
    colors = torch.rand(b, g, 3, generator=gen, dtype=torch.float64)
    return cov, depth, colors


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
    with pytest.raises(ConfigError, match="solve_colors"):
        ModelConfig(grouping="evenodd", solve_colors=True)
    with pytest.raises(ConfigError, match="solve_colors"):
        ModelConfig(grouping="layers", palette="#000000", solve_colors=True)
