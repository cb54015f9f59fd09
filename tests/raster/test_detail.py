"""The detail-weighted loss (``TrainConfig.detail``, ``raster.detail_weights``): weights that
average 1 per picture and favour small parts, applied to the finest pyramid level only."""

import pytest
import torch

from im2vec_cli.config import ModelConfig, TrainConfig
from im2vec_cli.errors import ConfigError
from im2vec_cli.model.losses import reconstruction_loss
from im2vec_cli.model.vae import Im2Vec
from im2vec_cli.raster import detail_weights, gaussian_pyramid, pyramid_l2, render_pyramid

TINY = dict(image_size=32, latent=16, enc_width=8, lstm_hidden=16, code=8, dec_width=16, dec_layers=3, deform_width=8)


def _face() -> torch.Tensor:
    """A skin-coloured disc with two 3x3 dark eyes, on white: ``(1, 3, 32, 32)``."""
    yy, xx = torch.meshgrid(torch.arange(32.0), torch.arange(32.0), indexing="ij")
    x = torch.ones(1, 3, 32, 32)
    disc = (yy - 16) ** 2 + (xx - 16) ** 2 < 12**2
    x[0, :, disc] = torch.tensor([0.9, 0.7, 0.5])[:, None]
    x[0, :, 12:15, 11:14] = 0.1  # left eye
    x[0, :, 12:15, 19:22] = 0.1  # right eye
    return x


def test_weights_average_one_peak_on_small_parts_and_leave_flat_pictures_alone():
    x = torch.cat([_face(), torch.full((1, 3, 32, 32), 0.4)])  # a face, then a flat grey picture
    w = detail_weights(x, 3.0)
    assert w.shape == (2, 1, 32, 32)
    assert torch.allclose(w.mean((1, 2, 3)), torch.ones(2), atol=1e-5)
    assert torch.equal(w[1], torch.ones(1, 32, 32))
    eye, cheek, background = w[0, 0, 13, 12], w[0, 0, 20, 16], w[0, 0, 1, 1]
    assert eye > 5 * cheek and eye > 1  # the eye weighs more than any flat pixel...
    assert torch.isclose(cheek, torch.tensor(0.25)) and torch.isclose(background, torch.tensor(0.25))  # ...1/(1+3)
    assert torch.equal(detail_weights(x, 0.0), torch.ones(2, 1, 32, 32))
    with pytest.raises(ValueError, match="strength"):
        detail_weights(x, -1.0)


def test_a_lost_eye_costs_more_than_an_equal_error_in_a_flat_region():
    """Plain L2 prices both errors alike; the weighted finest level prices the eye higher, and
    the coarser levels are unweighted (a weight of ones gives the plain loss)."""
    x = _face()
    no_eye = x.clone()
    no_eye[0, :, 12:15, 11:14] = torch.tensor([0.9, 0.7, 0.5])[:, None]  # the left eye painted over with skin
    smudge = x.clone()
    smudge[0, :, 22:25, 11:14] = 0.1  # a dark spot on the flat cheek: the same squared error
    assert torch.allclose((no_eye - x).square().sum(), (smudge - x).square().sum())
    levels = 3
    target = gaussian_pyramid(x, levels)

    def loss(img, w=None):
        return float(pyramid_l2(gaussian_pyramid(img, levels), target, weight=w))

    w = detail_weights(x, 2.0)
    assert loss(no_eye, w) > 2 * loss(smudge, w)
    assert loss(no_eye) == pytest.approx(loss(no_eye, torch.ones_like(w)), rel=1e-6)
    coarse = sum(float((a - b).square().mean()) for a, b in zip(gaussian_pyramid(no_eye, levels)[1:], target[1:]))
    assert loss(no_eye, w) == pytest.approx(float(((no_eye - x).square() * w).mean()) + coarse, rel=1e-5)
    with pytest.raises(ValueError, match="finest level"):
        pyramid_l2(gaussian_pyramid(no_eye, levels), target, weight=w[..., :16, :16])


def test_the_training_loss_takes_the_weights_and_the_config_checks_them():
    torch.manual_seed(0)
    model = Im2Vec(ModelConfig(grouping="layers", paths=3, **TINY)).eval()
    x = _face()
    plain = reconstruction_loss(model, x, 8, 0.5, sample=False)[0]
    weighted = reconstruction_loss(model, x, 8, 0.5, sample=False, detail=2.0)[0]
    dec = model(x, 8, sample=False)[0]
    renders = render_pyramid(dec.points, dec.colors, dec.depth, size=32, levels=model.config.levels, tau=0.5,
                             fill_rule=dec.fill_rule, shape_index=dec.shape_index, samples=model.config.samples)
    by_hand = pyramid_l2(renders, gaussian_pyramid(x, model.config.levels), weight=detail_weights(x, 2.0))
    assert torch.allclose(weighted, by_hand, atol=1e-6) and not torch.allclose(weighted, plain, atol=1e-4)
    assert TrainConfig(detail=2.0).detail == 2.0
    with pytest.raises(ConfigError, match="detail"):
        TrainConfig(detail=-1.0)
