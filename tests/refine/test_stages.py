"""refine/stages.py: ``Refinement``, the stages of one batch of pictures of one size, on a tiny model
(shapes, bounds, bad input) and on the shipped fonts model (each stage never worse than its start)."""

from __future__ import annotations

import pytest
import torch

from im2vec_cli.config import REPO_MODELS
from im2vec_cli.files import load_image
from im2vec_cli.model.pretrained import from_pretrained
from im2vec_cli.options import Plan
from im2vec_cli.refine import Refinement
from tests.helpers import make_tiny_model

ASSETS = REPO_MODELS.parent / "tests" / "assets" / "fonts_test"


def test_a_batch_is_one_size_and_a_large_one_is_fitted_smaller(tmp_path):
    model = from_pretrained(make_tiny_model(tmp_path / "tiny"))
    with pytest.raises(ValueError, match="one size"):
        Refinement(model, [torch.ones(3, 20, 20), torch.ones(3, 20, 24)], Plan())
    run = Refinement(model, [torch.ones(3, 300, 200)] * 2, Plan(max_side=60))
    assert run.fitter.size == (60, 40)  # fitted at max_side, the aspect kept


def test_encode_and_decode_give_one_guess_per_picture_in_its_frame(tmp_path):
    model = from_pretrained(make_tiny_model(tmp_path / "tiny"))
    images = [torch.rand(3, 30, 40, generator=torch.Generator().manual_seed(i)) for i in range(3)]
    run = Refinement(model, images, Plan())
    mu, place, k = run.encode([0, 2], None, None)
    assert mu.shape == (2, model.config.latent)
    vecs = run.decode(mu, k, place, None, [0, 2])
    assert len(vecs) == 2 and all((v.width, v.height) == (40, 30) for v in vecs)


@pytest.mark.skipif(not (REPO_MODELS / "fonts" / "config.json").exists(), reason="no shipped fonts model")
def test_each_stage_ends_no_worse_than_it_started():
    """The latent stage keeps each picture's best latent (its start where no step helps), and the
    point stage lowers the loss of the guess it is given, on three test-split glyphs together."""
    model = from_pretrained("fonts")
    images = [load_image(f) for f in sorted(ASSETS.glob("*.png"))[:3]]
    run = Refinement(model, images, Plan(latent_steps=6, point_steps=15))
    index = [0, 1, 2]
    mu, place, k = run.encode(index, None, None)
    start = run.loss(run.decode(mu, k, place, None, index), index)
    z, steps = run.fit_latent(mu, k, place, index)
    assert len(steps) == 3 and all(1 <= n <= 6 for n in steps)
    guess = run.decode(z, k, place, None, index)
    fitted, _ = run.fit_points(guess, index)
    after = run.loss(fitted, index)
    before = run.loss(guess, index)
    assert all(a <= b for a, b in zip(after, before)) and sum(after) < sum(start)
