"""Every model in models/ (and the baselines and ablation models under it) loads; models
keep the quality their cards state."""

import json
from pathlib import Path

import pytest

from im2vec_cli.config import REPO_MODELS
from im2vec_cli.evaluate import reconstruction_l2
from im2vec_cli.model.pretrained import from_pretrained

MODELS = sorted(str(p.parent.relative_to(REPO_MODELS)) for p in REPO_MODELS.glob("**/config.json")
                if json.loads(p.read_text()).get("class_name") == "ModelConfig")  # not the feature nets (features/)
FEATURE_NETS = sorted(str(p.parent.relative_to(REPO_MODELS)) for p in REPO_MODELS.glob("features/*/config.json"))
ASSETS = Path(__file__).parents[1] / "assets" / "fonts_test"


@pytest.mark.parametrize("name", MODELS)
def test_shipped_model_loads(name):
    m = from_pretrained(name)
    assert (REPO_MODELS / name / "README.md").is_file(), "every shipped model needs a model card"
    assert m.config.image_size > 0


@pytest.mark.parametrize("name", FEATURE_NETS)
def test_shipped_feature_net_loads_with_its_card(name):
    from im2vec_cli.model.features import FeatureNet

    net = FeatureNet.load(REPO_MODELS / name)
    assert (REPO_MODELS / name / "README.md").is_file()
    assert net.config.test_accuracy > 0 or net.config.test_mse > 0  # its own quality was measured


def _with_assets():
    out = []
    for name in MODELS:
        card = json.loads((REPO_MODELS / name / "metrics.json").read_text()) if (
            REPO_MODELS / name / "metrics.json").is_file() else {}
        if "assets_subset_recon_l2" in card:
            out.append(name)
    return out


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if n in ("emoji", "icons") else n
                                  for n in _with_assets()])  # the 8-path models' 64 pictures: 10-15 s each
def test_quality_on_test_split_subset(name):
    # 64 test-split images (never trained on) copied into tests/assets/<name>_test (or the
    # card's "assets_dir"); the card's metrics.json records the figure measured on exactly these files.
    card = json.loads((REPO_MODELS / name / "metrics.json").read_text())
    files = sorted((ASSETS.parent / card.get("assets_dir", f"{name}_test")).glob("*.png"))
    res = reconstruction_l2(from_pretrained(name), files)
    assert res["images"] == card["assets_subset_images"] == len(files)
    assert res["recon_l2"] <= card["assets_subset_recon_l2"] * 1.05 + 1e-3, res


def test_default_model_has_a_quality_check():
    assert "fonts" in _with_assets()


@pytest.mark.slow  # about 45 s: every model's paths fitted to its 64 test images
@pytest.mark.parametrize("name", [n for n in _with_assets() if "assets_subset_fitted_recon_l2" in json.loads(
    (REPO_MODELS / n / "metrics.json").read_text())])
def test_fitted_quality_on_test_split_subset(name):
    # the paths fitted to each image (`eval --fit`, what `interpolate` draws) keep the figure of
    # docs/results/ratios.md, and stay below the encoder's guess (by a tenth at least: the phases
    # of issue 37 close that gap from the encoder's side: with the point pass, mnist's fitted paths
    # are 0.82x of its guess, which is below what a smooth filled outline draws: docs/results/fill-bound.md)
    card = json.loads((REPO_MODELS / name / "metrics.json").read_text())
    files = sorted((ASSETS.parent / card.get("assets_dir", f"{name}_test")).glob("*.png"))
    res = reconstruction_l2(from_pretrained(name), files, outlines=False, fit=True)
    assert res["recon_l2"] <= card["assets_subset_fitted_recon_l2"] * 1.1 + 1e-4, res
    assert res["recon_l2"] < 0.9 * card["assets_subset_recon_l2"], res

