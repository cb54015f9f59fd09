"""Test-time refinement (issue "Vectorize fidelity"): it lowers the loss against the input,
handles inputs of other sizes than the model's, and keeps the SVG valid."""

from pathlib import Path

import numpy as np
import pytest
import torch

from im2vec_cli.checkpoint import REPO_MODELS, from_pretrained
from im2vec_cli.infer import vectorize
from im2vec_cli.io import load_image
from im2vec_cli.raster._compile import set_compile
from im2vec_cli.refine import RefineSettings, refine
from im2vec_cli.svg import rasterize_svg, to_svg
from tests.helpers import check_svg, make_tiny_model

ASSETS = Path(__file__).parent / "assets" / "fonts_test"
QUICK = RefineSettings(latent_steps=10, point_steps=30)


@pytest.fixture(autouse=True)
def eager():
    set_compile(False)
    yield
    set_compile(None)


def _cairo_mse(vec, img):
    h, w = img.shape[1:]
    return float(((rasterize_svg(to_svg(vec), w, h) - img.permute(1, 2, 0).numpy()) ** 2).mean())


@pytest.mark.skipif(not (REPO_MODELS / "fonts" / "config.json").exists(), reason="no shipped fonts model")
def test_refinement_lowers_the_error_on_real_glyphs():
    """On test-split glyphs (families never trained on), judged by cairosvg, not by our renderer."""
    model = from_pretrained("fonts")
    files = sorted(ASSETS.glob("*.png"))[:4]
    before, after = [], []
    for f in files:
        img = load_image(f)
        vec, info = refine(model, img, settings=QUICK)
        assert info["loss_end"] <= info["loss_start"]
        check_svg(to_svg(vec), 64, 64)
        before.append(_cairo_mse(vectorize(model, [img])[0], img))
        after.append(_cairo_mse(vec, img))
    assert np.mean(after) < 0.7 * np.mean(before), (before, after)


def test_refinement_handles_other_sizes(tmp_path):
    """A 30 x 50 input (the tiny model works at 32 x 32): the SVG is in the input's frame
    and the fit improves against the input itself."""
    model = from_pretrained(make_tiny_model(tmp_path / "tiny"))
    img = torch.ones(3, 30, 50)
    img[:, 8:22, 10:40] = 0.0
    vec, info = refine(model, img, settings=QUICK)
    assert info["loss_end"] < info["loss_start"]
    check_svg(to_svg(vec), 50, 30)
    assert _cairo_mse(vec, img) < _cairo_mse(vectorize(model, [img])[0], img)


def test_refinement_of_flat_images_matches_amortised(tmp_path):
    """Blank input gives an empty SVG and a flat colour one square, as without --refine."""
    model = from_pretrained(make_tiny_model(tmp_path / "tiny"))
    for img in (torch.ones(3, 20, 30), torch.full((3, 20, 30), 0.25)):
        vec, _ = refine(model, img, settings=QUICK)
        assert to_svg(vec) == to_svg(vectorize(model, [img])[0])
    assert refine(model, torch.ones(3, 20, 30), settings=QUICK)[0].shapes == []
