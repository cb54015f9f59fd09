"""The ImageVAE baseline (paper sec. 4) and the segments ablation (paper Fig. 5)."""

import dataclasses
import json

import numpy as np
import pytest
import torch
from PIL import Image

from im2vec_cli.config import ModelConfig
from im2vec_cli.evaluate import deformation_off, generation_l2, interpolation_l2, reconstruction_l2, segments_sweep
from im2vec_cli.model import ImageVAE, build_model
from im2vec_cli.model.pretrained import from_pretrained, save_pretrained
from im2vec_cli.training.train import evaluate_l2, train
from tests.helpers import TINY, make_tiny_model, run, synthetic_shapes

IVAE = ModelConfig(arch="imagevae", image_size=32, latent=16, enc_width=8)


def _white_model(folder) -> str:
    """An ImageVAE whose output is white everywhere (last bias +40: sigmoid is 1 to 1e-17)."""
    torch.manual_seed(0)
    m = ImageVAE(IVAE)
    last = m.decoder.net[-1]
    torch.nn.init.zeros_(last.weight)
    torch.nn.init.constant_(last.bias, 40.0)
    save_pretrained(m, folder)
    return str(folder)


def test_shapes_and_builder():
    m = build_model(IVAE)
    out, mu, logvar = m(torch.rand(5, 3, 32, 32))
    assert out.shape == (5, 3, 32, 32) and mu.shape == logvar.shape == (5, 16)
    assert 0 <= float(out.detach().min()) and float(out.detach().max()) <= 1
    assert type(build_model(TINY)).__name__ == "Im2Vec"
    with pytest.raises(ValueError, match="arch"):
        build_model(dataclasses.replace(IVAE, arch="gan"))


def test_known_answers_for_raster_metrics(tmp_path):
    """A model that draws white: reconstruction L2 of a white image is 0; of an image with a
    black block it is the block's share of the pixels, in the input's own (non-square) frame;
    generation and interpolation L2 are 0 against a white training set and 1 against a black one."""
    model = from_pretrained(_white_model(tmp_path / "m"))
    Image.new("RGB", (40, 24), "white").save(tmp_path / "white.png")
    arr = np.full((24, 40, 3), 255, np.uint8)
    arr[4:10, 8:20] = 0  # 6 x 12 = 72 of 960 pixels
    Image.fromarray(arr).save(tmp_path / "block.png")
    assert reconstruction_l2(model, [tmp_path / "white.png"])["recon_l2"] < 1e-9
    res = reconstruction_l2(model, [tmp_path / "block.png"])
    assert abs(res["recon_l2"] - 72 / 960) < 1e-6 and "paths" not in res
    white = torch.full((10, 3, 32, 32), 255, dtype=torch.uint8)
    assert generation_l2(model, white, samples=16)["generation_l2"] < 1e-9
    assert abs(generation_l2(model, torch.zeros_like(white), samples=16)["generation_l2"] - 1) < 1e-6
    # interpolants between training pairs are white too: 0 against white, 1 against black
    assert interpolation_l2(model, white, pairs=5)["interpolation_l2"] < 1e-9
    res = interpolation_l2(model, torch.zeros_like(white), pairs=5)
    assert abs(res["interpolation_l2"] - 1) < 1e-6 and res["interpolants"] == 20


def test_train_export_and_eval(tmp_path):
    """`train` fits the baseline (val loss falls), exports it, and `eval` scores it without
    vector metrics; the vector commands refuse it with one error line."""
    from im2vec_cli.config import TrainConfig

    shapes = synthetic_shapes(48, 32)
    cfg = TrainConfig(steps=200, batch=16, lr=5e-3, beta=0.0, val_every=1000, ckpt_every=1000, preview_every=1000,
                      log_every=50, val_fraction=0.2)
    torch.manual_seed(0)
    before = evaluate_l2(ImageVAE(IVAE), shapes[-9:], 8, 0.5)["val_mse"]
    out = train(None, tmp_path / "run", IVAE, cfg, images=shapes)
    after = [json.loads(x) for x in (tmp_path / "run" / "metrics.jsonl").read_text().splitlines()][-1]
    assert after["event"] == "val" and after["val_mse"] < before / 2, (before, after)
    assert list((tmp_path / "run").glob("preview_*.png"))
    test = tmp_path / "d" / "test"
    test.mkdir(parents=True)
    for i, img in enumerate(shapes[:4]):
        Image.fromarray(img.permute(1, 2, 0).numpy()).save(test / f"{i}.png")
    res = run(["eval", "--model", str(out), "--data", str(tmp_path / "d"), "-o", str(tmp_path / "r.json"),
               "--markdown", str(tmp_path / "r.md")])
    assert res.exit_code == 0, res.output
    r = json.loads((tmp_path / "r.json").read_text())
    assert r["arch"] == "imagevae" and r["images"] == 4 and 0 < r["recon_l2"] < 1 and "segments" not in r
    assert "paths / segments" not in (tmp_path / "r.md").read_text()
    bad = run(["vectorize", str(test / "0.png"), "--model", str(out), "-o", str(tmp_path / "x.svg")])
    assert bad.exit_code != 0 and "ImageVAE" in bad.stderr and len(bad.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "x.svg").exists()


def test_sweep_deformation_off_is_identity_when_the_shift_is_zero(tmp_path):
    """Switching the deformation off changes nothing when its shift is zero (zero last layer),
    and changes the reconstruction when it is not."""
    model = from_pretrained(make_tiny_model(tmp_path / "m"))
    folder = tmp_path / "imgs"
    folder.mkdir()
    files = []
    for i, img in enumerate(synthetic_shapes(3, 32, seed=1)):
        files.append(folder / f"{i}.png")
        Image.fromarray(img.permute(1, 2, 0).numpy()).save(files[-1])
    last = model.decoder.deform[-1]
    torch.nn.init.zeros_(last.weight)
    torch.nn.init.zeros_(last.bias)
    on, off = segments_sweep(model, files, [6, 9]), segments_sweep(model, files, [6, 9], deform=False)
    assert [r["k"] for r in on] == [6, 9]
    assert all(a["recon_l2"] == b["recon_l2"] for a, b in zip(on, off))
    torch.nn.init.constant_(last.bias, 3.0)  # a large shift along the circle
    moved = segments_sweep(model, files, [6, 9])
    assert any(abs(a["recon_l2"] - b["recon_l2"]) > 1e-6 for a, b in zip(on, moved))
    with deformation_off(model):
        assert model.decoder.deform is None
    assert model.decoder.deform is not None and model.decoder.deform[-1] is last  # restored


def test_eval_sweep_and_plot(tmp_path):
    model = make_tiny_model(tmp_path / "m")
    (tmp_path / "t").mkdir()
    for i, img in enumerate(synthetic_shapes(2, 32, seed=2)):
        Image.fromarray(img.permute(1, 2, 0).numpy()).save(tmp_path / "t" / f"{i}.png")
    res = run(["eval", "--model", model, "--data", str(tmp_path / "t"), "--sweep", "6-8", "--plot",
               str(tmp_path / "s.png"), "-o", str(tmp_path / "r.json")])
    assert res.exit_code == 0, res.output
    r = json.loads((tmp_path / "r.json").read_text())
    assert [x["k"] for x in r["segments_sweep"]] == [6, 7, 8] and len(r["segments_sweep_deform_off"]) == 3
    with Image.open(tmp_path / "s.png") as im:
        assert im.size[0] > 300
    bad = run(["eval", "--model", model, "--data", str(tmp_path / "t"), "--sweep", "9-6"])
    assert bad.exit_code == 2 and "K1-K2" in bad.stderr
