"""Training-batch augmentation (``TrainConfig.augment``, ``data.augment``)."""

import pytest
import torch

from im2vec_cli.config import TrainConfig
from im2vec_cli.data.augment import augment_batch
from im2vec_cli.errors import ConfigError


def _batch() -> torch.Tensor:
    x = torch.ones(64, 3, 64, 64)
    x[:, :, 20:40, 10:30] = 0.0  # a black square left of centre in every picture
    return x


def test_flip_mirrors_about_half_the_pictures_and_nothing_else():
    x = _batch()
    y = augment_batch(x, "flip", torch.Generator().manual_seed(0))
    mirrored = [bool(torch.equal(b, a.flip(-1))) for a, b in zip(x, y, strict=True)]
    kept = [bool(torch.equal(b, a)) for a, b in zip(x, y, strict=True)]
    assert all(m != k for m, k in zip(mirrored, kept, strict=True))  # each one or the other
    assert 20 <= sum(mirrored) <= 44


def test_shift_moves_each_picture_by_at_most_two_pixels_and_keeps_its_ink():
    x = _batch()
    y = augment_batch(x, "shift", torch.Generator().manual_seed(1))
    assert y.shape == x.shape
    offsets = set()
    for a in y:
        ink = (a[0] < 0.5).nonzero()
        (top, left), (bottom, right) = ink.min(0).values.tolist(), ink.max(0).values.tolist()
        assert (bottom - top, right - left) == (19, 19)  # the whole square, unclipped
        dy, dx = top - 20, left - 10
        assert abs(dy) <= 2 and abs(dx) <= 2
        offsets.add((dy, dx))
    assert len(offsets) > 5  # drawn per picture
    assert float(y.min()) == 0.0 and float(y.max()) == 1.0  # the border repeated: white stays white


def test_the_same_generator_state_draws_the_same_batch_and_no_augment_is_the_batch():
    x = torch.rand(8, 3, 64, 64)
    a = augment_batch(x, "flip,scale,shift", torch.Generator().manual_seed(5))
    b = augment_batch(x, "flip,scale,shift", torch.Generator().manual_seed(5))
    assert torch.equal(a, b) and not torch.equal(a, x)
    assert augment_batch(x, "", torch.Generator()) is x


def test_bad_augment_is_refused_in_the_config():
    with pytest.raises(ConfigError, match="augment"):
        TrainConfig(augment="rotate")
    with pytest.raises(ConfigError, match="outline"):
        TrainConfig(augment="flip", outline=0.005)


def test_scale_magnifies_each_picture_about_its_centre_by_at_most_an_eighth():
    x = torch.ones(64, 3, 64, 64)
    x[:, :, 22:42, 22:42] = 0.0  # a centred 20 px black square
    y = augment_batch(x, "scale", torch.Generator().manual_seed(2))
    assert y.shape == x.shape
    sides = []
    for a in y:
        ink = (1 - a[0]).sum(0)  # (W,) the square's darkness per column: its width in px, antialiased
        width, centre = float(ink.max()), float((ink * torch.arange(64)).sum() / ink.sum())
        assert 20 * (1 - 1 / 8) - 0.6 <= width <= 20 * (1 + 1 / 8) + 0.6  # the square's side, scaled
        assert abs(centre - 31.5) < 0.05  # about the centre
        sides.append(width)
    assert max(sides) - min(sides) > 3  # a factor drawn per picture
    assert float(y.max()) <= 1.0 and float(y.min()) >= 0.0 and float(y[:, :, 0, 0].min()) == 1.0  # white stays white
