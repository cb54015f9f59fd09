"""Every model in models/ loads; the fonts model keeps the quality its card states."""

import json
from pathlib import Path

import pytest

from im2vec_cli.checkpoint import REPO_MODELS, from_pretrained
from im2vec_cli.evaluate import reconstruction_l2

MODELS = sorted(p.parent.name for p in REPO_MODELS.glob("*/config.json"))
ASSETS = Path(__file__).parent / "assets" / "fonts_test"


@pytest.mark.parametrize("name", MODELS)
def test_shipped_model_loads(name):
    m = from_pretrained(name)
    assert (REPO_MODELS / name / "README.md").is_file(), "every shipped model needs a model card"
    assert m.config.image_size > 0


@pytest.mark.skipif("fonts" not in MODELS, reason="no shipped fonts model")
def test_fonts_quality_on_test_split_subset():
    # 64 glyphs of test-split families (never trained on), copied from the dataset build;
    # the card's metrics.json records the figure measured on exactly these files.
    card = json.loads((REPO_MODELS / "fonts" / "metrics.json").read_text())
    res = reconstruction_l2(from_pretrained("fonts"), sorted(ASSETS.glob("*.png")))
    assert res["images"] == 64
    assert res["recon_l2"] <= card["assets_subset_recon_l2"] * 1.05 + 1e-3, res
