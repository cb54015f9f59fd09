"""The paper's metrics, on tiny cases where the right answer is known."""

import json

import numpy as np
import torch
from click.testing import CliRunner
from PIL import Image

from im2vec_cli.cli import cli
from im2vec_cli.evaluate import decoded_images, generation_l2, held_out_l2, nearest_mse, reconstruction_l2
from im2vec_cli.model.pretrained import from_pretrained
from im2vec_cli.vector import VectorImage, VectorShape, rasterize_svg, to_svg
from tests.helpers import make_tiny_model, polyline_as_cubic


def test_nearest_mse_is_zero_for_copies_and_exact_otherwise():
    g = torch.Generator().manual_seed(0)
    ref = (torch.rand(50, 3, 8, 8, generator=g) * 255).round().to(torch.uint8)
    copies = ref[[3, 17, 42]].float() / 255
    assert torch.allclose(nearest_mse(copies, ref), torch.zeros(3), atol=1e-6)
    q = torch.rand(4, 3, 8, 8, generator=g)
    brute = ((q[:, None] - ref[None].float() / 255) ** 2).flatten(2).mean(-1).min(1).values
    assert torch.allclose(nearest_mse(q, ref, chunk=7), brute, atol=1e-6)


def test_generation_l2_is_zero_when_training_set_holds_the_samples(tmp_path):
    """If the training set is exactly the decoded prior samples, every sample has a copy."""
    model = from_pretrained(make_tiny_model(tmp_path / "m"))
    g = torch.Generator().manual_seed(0)
    z = torch.randn(20, model.config.latent, generator=g)
    train = (decoded_images(model, z) * 255).round().to(torch.uint8)
    res = generation_l2(model, train, samples=20, seed=0)
    assert res["generation_l2"] < 1e-5 and res["generated"] == 20
    other = torch.full_like(train, 255)  # an all-white "training set": a clearly positive score
    assert generation_l2(model, other, samples=20, seed=0)["generation_l2"] > 1e-3


def test_held_out_l2_measures_test_pictures_at_the_model_size_against_the_training_set(tmp_path):
    """A test picture that is a training picture (at another size: brought to the model's) scores 0;
    a white one against black training pictures scores 1."""
    g = torch.Generator().manual_seed(1)
    train = (torch.rand(6, 3, 16, 16, generator=g) > 0.5).to(torch.uint8) * 255
    big = train[2].repeat_interleave(4, 1).repeat_interleave(4, 2)  # the same picture at 64 px, nearest-upsampled
    Image.fromarray(big.permute(1, 2, 0).numpy()).save(tmp_path / "copy.png")
    Image.new("RGB", (20, 20), (255, 255, 255)).save(tmp_path / "white.png")
    res = held_out_l2([tmp_path / "copy.png"], train, 16, "resize")
    assert res["held_out_l2"] < 1e-3 and res["held_out"] == 1
    assert held_out_l2([tmp_path / "white.png"], torch.zeros_like(train), 16, "resize")["held_out_l2"] == 1.0


def test_reconstruction_l2_is_zero_for_a_flat_image_and_positive_otherwise(tmp_path):
    """A flat image is reconstructed exactly (one canvas square); a shape is not, with a tiny model."""
    model = from_pretrained(make_tiny_model(tmp_path / "m"))
    Image.new("RGB", (20, 30), (40, 80, 120)).save(tmp_path / "flat.png")
    res = reconstruction_l2(model, [tmp_path / "flat.png"])
    assert res["recon_l2"] < 1e-5
    square = VectorImage(32, 32, [VectorShape([polyline_as_cubic([(8, 8), (24, 8), (24, 24), (8, 24)]).numpy()])])
    Image.fromarray((rasterize_svg(to_svg(square), 32, 32) * 255).astype(np.uint8)).save(tmp_path / "sq.png")
    assert reconstruction_l2(model, [tmp_path / "sq.png"])["recon_l2"] > 1e-3


def test_eval_command_with_train_data(tmp_path):
    model = make_tiny_model(tmp_path / "m")
    for split, n in (("train", 12), ("test", 3)):
        (tmp_path / "d" / split).mkdir(parents=True)
        for i in range(n):
            arr = np.full((32, 32, 3), 255, np.uint8)
            arr[4 + i % 8 : 20 + i % 8, 6:26] = 0
            Image.fromarray(arr).save(tmp_path / "d" / split / f"{i}.png")
    res = CliRunner().invoke(cli, ["eval", "--model", model, "--data", str(tmp_path / "d"), "--train-data",
                                   str(tmp_path / "d"), "--samples", "8", "--pairs", "3", "-o",
                                   str(tmp_path / "r.json"), "--markdown", str(tmp_path / "r.md")])
    assert res.exit_code == 0, res.output
    r = json.loads((tmp_path / "r.json").read_text())
    assert r["images"] == 3 and r["generated"] == 8 and r["interpolants"] == 12 and r["train_images"] == 12
    for key in ("recon_l2", "generation_l2", "interpolation_l2"):
        assert 0 <= r[key] <= 1
    assert r["held_out"] == 3 and r["held_out_l2"] < 1e-6  # the three test pictures are training pictures too
    md = (tmp_path / "r.md").read_text()
    assert "generation L2 (Table 2)" in md and md.count("\n") == 7 and "paths / segments per image" in md


def test_eval_missing_train_data_is_one_error_line(tmp_path):
    model = make_tiny_model(tmp_path / "m")
    (tmp_path / "t" / "test").mkdir(parents=True)
    Image.new("RGB", (32, 32), "white").save(tmp_path / "t" / "test" / "a.png")
    res = CliRunner().invoke(cli, ["eval", "--model", model, "--data", str(tmp_path / "t"), "--train-data",
                                   str(tmp_path / "nope")])
    assert res.exit_code == 1 and res.stderr.startswith("Error:")


def test_outline_metrics_on_known_shapes():
    """Concentric circles r and r + 1 are 1 px apart; a shape against itself is IoU 1 and
    Chamfer 0; two unit-offset squares have a known IoU."""
    from im2vec_cli.evaluate import chamfer_px, outline_iou, svg_mask
    from tests.helpers import circle

    def img(*contours):
        return VectorImage(64.0, 64.0, [VectorShape([np.asarray(c) for c in contours], (0, 0, 0), "nonzero")])

    a, b = img(circle(32, 32, 15, 16).numpy()), img(circle(32, 32, 16, 16).numpy())
    assert chamfer_px(a, a) < 1e-9
    assert abs(chamfer_px(a, b) - 1.0) < 0.01
    sq = lambda x0: img(polyline_as_cubic([[x0, 10.0], [x0 + 20, 10], [x0 + 20, 30], [x0, 30]]).numpy())  # noqa: E731
    m1, m2 = svg_mask(to_svg(sq(10.0)), 256), svg_mask(to_svg(sq(14.0)), 256)
    assert outline_iou(m1, m1) == 1.0
    assert abs(outline_iou(m1, m2) - 16 / 24) < 0.01  # overlap 16x20 of union 24x20
    assert outline_iou(np.zeros((4, 4), bool), np.zeros((4, 4), bool)) == 1.0


def test_reconstruction_reports_outline_metrics_where_truth_exists(tmp_path):
    """Test images with their true outline beside them get IoU and Chamfer; all get compactness."""
    model = from_pretrained(make_tiny_model(tmp_path / "m"))
    shape = VectorImage(32.0, 32.0, [VectorShape([polyline_as_cubic([[8.0, 8], [24, 8], [24, 24], [8, 24]]).numpy()],
                                                 (0, 0, 0), "nonzero")])
    text = to_svg(shape)
    (tmp_path / "a.svg").write_text(text)
    Image.fromarray((rasterize_svg(text, 32, 32) * 255).round().astype(np.uint8)).save(tmp_path / "a.png")
    res = reconstruction_l2(model, [tmp_path / "a.png"])
    assert res["outlines"] == 1 and 0 <= res["outline_iou"] <= 1 and res["chamfer_px"] > 0
    assert res["paths"] >= 1 and res["segments"] == 6 * res["paths"]  # the tiny model decodes k = 6 per path
    (tmp_path / "a.svg").unlink()
    assert "outline_iou" not in reconstruction_l2(model, [tmp_path / "a.png"])


def test_unreadable_outline_is_counted_not_fatal(tmp_path):
    """A true outline the reader refuses (a gradient fill) is counted in outlines_unread; the image
    still gets its reconstruction L2. Relative commands (as Twemoji's) are read."""
    model = from_pretrained(make_tiny_model(tmp_path / "m"))
    arr = np.full((32, 32, 3), 255, np.uint8)
    arr[8:24, 8:24] = 0
    Image.fromarray(arr).save(tmp_path / "e.png")
    (tmp_path / "e.svg").write_text('<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 32 32">'
                                    '<path d="M8 8l16 0l0 16l-16 0z" fill="url(#g)"/></svg>')
    res = reconstruction_l2(model, [tmp_path / "e.png"])
    assert res["outlines_unread"] == 1 and "outline_iou" not in res and res["images"] == 1
    (tmp_path / "e.svg").write_text('<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 32 32">'
                                    '<path d="M8 8l16 0l0 16l-16 0z"/></svg>')
    res = reconstruction_l2(model, [tmp_path / "e.png"])
    assert "outlines_unread" not in res and res["outlines"] == 1


def test_eval_fit_lowers_the_error_and_refuses_what_it_cannot_fit(tmp_path):
    from pathlib import Path

    files = sorted((Path(__file__).parent / "assets" / "fonts_test").glob("*.png"))[:4]  # test split
    fonts = from_pretrained("fonts")
    guess = reconstruction_l2(fonts, files, outlines=False)["recon_l2"]
    fitted = reconstruction_l2(fonts, files, outlines=False, fit=True)["recon_l2"]
    assert fitted < 0.5 * guess, (guess, fitted)
    data = str(files[0].parent)
    for args, why in ((["--model", "baselines/mnist-imagevae"], "draws pixels"), (["--segments", "auto"], "--fit")):
        res = CliRunner().invoke(cli, ["eval", "--data", data, "--fit", "--limit", "1", *args])
        assert res.exit_code == 2 and why in res.output, res.output
