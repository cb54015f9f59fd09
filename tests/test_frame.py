"""How inputs are fitted to the model square (``ModelConfig.fit``) and mapped back: "pad"
centres a smaller image unscaled (MNIST's 28 x 28 in a 32 x 32 model), "resize" upscales it."""

import dataclasses

import pytest
import torch

from im2vec_cli.data.folder import load_folder
from im2vec_cli.files import tensor_to_png
from im2vec_cli.frame import Placement, fit_square
from im2vec_cli.infer import model_input, to_vector, vectorize
from im2vec_cli.model import build_model
from im2vec_cli.model.pretrained import from_pretrained, save_pretrained
from im2vec_cli.model.vae import Decoded
from im2vec_cli.vector import rasterize_svg, to_svg
from tests.helpers import TINY, check_svg, make_tiny_model


def test_pad_keeps_small_images_unscaled():
    g = torch.Generator().manual_seed(0)
    img = torch.rand(3, 28, 20, generator=g)
    out = fit_square(img, 32, "pad")
    assert out.shape == (3, 32, 32)
    assert torch.equal(out[:, 2:30, 6:26], img)  # no resampling: the very pixels, centred
    border = torch.ones(3, 32, 32, dtype=torch.bool)
    border[:, 2:30, 6:26] = False
    assert (out[border] == 1).all()  # white around
    # larger inputs are resized either way
    big = torch.rand(3, 40, 48, generator=g)
    assert torch.equal(fit_square(big, 32, "pad"), fit_square(big, 32, "resize"))
    assert not torch.equal(fit_square(img, 32, "resize")[:, 2:30, 6:26], img)
    with pytest.raises(ValueError, match="fit"):
        fit_square(img, 32, "stretch")


def test_placement_maps_the_model_square_back_to_the_input():
    """A square path at known model-frame corners lands on the input pixels it covers."""
    place = Placement(20, 28, 32, "pad")
    assert place.side == 32 and place.offset == (6, 2)
    assert Placement(20, 28).side == 28 and Placement(20, 28).offset == (4, 0)
    # corners (6, 2) and (26, 30) of the 32 x 32 square = the input's (0, 0) and (20, 28)
    corners = torch.tensor([[6, 2], [26, 2], [26, 30], [6, 30]], dtype=torch.float64) / 32
    pts = []
    for a, b in zip(corners, corners.roll(-1, 0)):
        pts += [a, a + (b - a) / 3, a + 2 * (b - a) / 3]
    dec = Decoded(torch.stack(pts)[None, None].float(), torch.zeros(1, 1, 3), torch.zeros(1, 1),
                  torch.zeros(1, dtype=torch.long), "evenodd")
    svg = to_svg(to_vector(dec, 0, place))
    check_svg(svg, 20, 28)
    ink = 1 - rasterize_svg(svg, 20, 28)[..., 0].astype(float) / 255
    assert ink.min() > 0.99  # the square fills the whole 20 x 28 input, edge to edge


def test_pad_model_vectorizes_in_the_input_frame(tmp_path):
    """A "pad" model: training loads and inference fits alike, and a 24 x 16 input comes
    back as an SVG in its own frame."""
    d = make_tiny_model(tmp_path / "tiny")
    model = from_pretrained(d)
    cfg = dataclasses.replace(model.config, fit="pad")
    padded = build_model(cfg)
    padded.load_state_dict(model.state_dict())
    save_pretrained(padded, tmp_path / "pad")
    model = from_pretrained(tmp_path / "pad")
    assert model.config.fit == "pad"
    img = torch.ones(3, 16, 24)
    img[:, 4:12, 6:18] = 0.0
    x, place = model_input(model, img)
    assert torch.equal(x[:, 8:24, 4:28], img)
    check_svg(to_svg(vectorize(model, [img])[0]), 24, 16)
    folder = tmp_path / "imgs"
    folder.mkdir()
    (folder / "a.png").write_bytes(tensor_to_png(img))
    loaded, _ = load_folder(folder, 32, fit="pad")
    assert torch.equal(loaded[0].float() / 255, x)


def test_unknown_fit_is_rejected():
    with pytest.raises(ValueError, match="fit"):
        build_model(dataclasses.replace(TINY, fit="stretch"))
