"""The public Python API (``import im2vec_cli``): pictures in, ``VectorImage`` out, and the
CLI writes what the API returns."""

from __future__ import annotations

import subprocess
import sys
from xml.etree import ElementTree

import numpy as np
import pytest
import torch
from PIL import Image

import im2vec_cli as iv
from im2vec_cli.errors import InputError, ModelError
from im2vec_cli.vector import VectorImage, rasterize_svg
from tests.helpers import check_svg, make_tiny_model, png, run


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    folder = make_tiny_model(tmp_path_factory.mktemp("m") / "tiny")
    return iv.load_model(folder, "cpu"), folder


def _disc(w=40, h=24) -> np.ndarray:
    yy, xx = np.mgrid[0:h, 0:w]
    return np.where((xx - w / 2) ** 2 + (yy - h / 2) ** 2 < (min(w, h) / 3) ** 2, 0, 255).astype(np.uint8)


def test_readme_example_runs_and_the_cli_writes_the_same_svg(model, tmp_path):
    m, folder = model
    src = png(tmp_path / "a.png", 40, 24)
    svg = iv.vectorize(src, m, refine=False).to_svg()  # the README's five lines, without refinement
    check_svg(svg, 40, 24)
    res = run(["vectorize", src, "-o", "-", "--no-refine", "--model", folder])
    assert res.exit_code == 0 and res.stdout == svg


def test_every_picture_form_gives_the_same_result(model, tmp_path):
    m, _ = model
    arr = _disc()
    pil = Image.fromarray(arr, "L")
    pil.save(tmp_path / "d.png")
    forms = [arr, arr.astype(np.float32) / 255, np.stack([arr] * 3, -1), pil, pil.convert("RGBA"),
             torch.from_numpy(arr).float().div(255).expand(3, -1, -1), str(tmp_path / "d.png"), tmp_path / "d.png"]
    svgs = {iv.vectorize(f, m, refine=False).to_svg() for f in forms}
    assert len(svgs) == 1
    vec = iv.vectorize(arr, m, refine=False)
    assert isinstance(vec, VectorImage) and (vec.width, vec.height) == (40, 24)


def test_an_options_object_and_keyword_fields_are_one_thing(model):
    m, _ = model
    opts = iv.VectorizeOptions(parts="model", effort="fast", simplify_px=0.5)
    by_object = iv.vectorize(_disc(), m, opts).to_svg()
    assert by_object == iv.vectorize(_disc(), m, parts="model", simplify_px=0.5).to_svg()
    assert by_object != iv.vectorize(_disc(), m, opts, simplify_px=0.0).to_svg()  # a field overrides the object
    assert opts.parts == "model"  # and the object itself is left as it was (frozen)


def test_lists_in_lists_out_and_refinement_never_worse(model):
    m, _ = model
    imgs = [_disc(), _disc(32, 32)]
    guesses = iv.vectorize(imgs, m, refine=False)
    fitted = iv.vectorize(imgs, m, refine=True)
    assert isinstance(fitted, list) and len(fitted) == 2
    def err(v, img):
        target = np.stack([img / 255.0] * 3, -1)  # (H, W, 3)
        return float(((rasterize_svg(v.to_svg(), img.shape[1], img.shape[0]) - target) ** 2).mean())

    for img, g, f in zip(imgs, guesses, fitted):
        assert err(f, img) <= err(g, img) * 1.05  # the judge is our renderer; cairo agrees within a few percent


def test_encode_decode_sample_interpolate(model):
    m, _ = model
    z = iv.encode([_disc(), _disc(32, 32)], m)
    assert z.shape == (2, m.config.latent) and z.dtype == np.float32
    one = iv.encode(_disc(), m)
    assert np.allclose(one[0], z[0], atol=1e-5)
    s = m.config.image_size
    assert all(v.width == s for v in iv.decode(z, m))
    a, b = iv.sample(3, m, seed=5), iv.sample(3, m, seed=5)
    assert [v.to_svg() for v in a] == [v.to_svg() for v in b]
    frames = iv.interpolate(_disc(), z[1], m, steps=3)
    assert len(frames) == 5
    assert frames[-1].to_svg() == iv.decode(z[1], m)[0].to_svg()  # a latent endpoint is decoded as given


def test_errors_are_raised_not_printed(model, capsys):
    m, _ = model
    with pytest.raises(InputError, match="too small"):
        iv.vectorize(np.zeros((2, 2), np.uint8), m)
    with pytest.raises(ValueError, match="image array"):
        iv.vectorize(np.zeros((4, 4, 2), np.uint8), m)
    with pytest.raises(ValueError, match="latents must be"):
        iv.decode(np.zeros(3), m)
    with pytest.raises(ModelError, match="segment predictor"):
        iv.vectorize(_disc(), m, segments="auto")
    with pytest.raises(ValueError, match="effort"):
        iv.vectorize(_disc(), m, effort="slow")
    assert capsys.readouterr() == ("", "")


def test_help_does_not_import_torch():
    code = "import sys; from im2vec_cli.cli import main; sys.argv=['im2vec','--help']\n" \
           "try:\n    main()\nexcept SystemExit:\n    pass\nprint('torch' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip().splitlines()[-1] == "False"


def test_empty_path_arguments_are_usage_errors_naming_the_argument(tmp_path, model):
    _, folder = model
    src = png(tmp_path / "a.png")
    cases = [(["interpolate", src, "", "--steps", "4"], "'B'"), (["interpolate", "", src], "'A'"),
             (["vectorize", "", "-o", str(tmp_path / "x.svg")], "'IMG...'"),
             (["vectorize", src, "-o", ""], "'-o' / '--output'"), (["render", ""], "'SVG'")]
    for args, name in cases:
        res = run([*args, "--model", folder] if args[0] != "render" else args)
        assert res.exit_code == 2, (args, res.output)
        assert name in res.output and "is empty" in res.output, res.output
        assert "Traceback" not in res.output
    assert not (tmp_path / "x.svg").exists()


def test_svg_of_the_api_is_valid_xml_of_closed_paths(model):
    m, _ = model
    root = ElementTree.fromstring(iv.vectorize(_disc(), m).to_svg())
    for el in root.iter():
        if el.tag.endswith("path"):
            assert el.get("d").strip().endswith("Z")


def test_the_api_trains_fine_tunes_fits_a_prior_and_exports(tmp_path):
    """What `train`, `train --init`, `fit-prior` and `export` do, from Python: models from
    images without the CLI (issue 33, item 4)."""
    from im2vec_cli import api
    from im2vec_cli.errors import ModelError
    from tests.helpers import TINY

    data = tmp_path / "data"
    data.mkdir()
    for i in range(6):
        png(data / f"{i}.png", 32, 32 - i)
    base = make_tiny_model(tmp_path / "base")
    fast = {"steps": 2, "batch": 2, "workers": 1, "val_every": 1000, "ckpt_every": 1000, "preview_every": 1000}
    out = api.train(data, tmp_path / "run", init=base, model_config={"paths": TINY.paths + 1}, train_config=fast,
                   device="cpu")
    grown = iv.load_model(str(out), "cpu")
    assert grown.config.paths == TINY.paths + 1 and grown.config.latent == TINY.latent
    with pytest.raises(ValueError, match="drop latent"):
        api.train(data, tmp_path / "run2", init=base, model_config={"latent": 8}, train_config=fast, device="cpu")
    prior = iv.fit_prior(data, iv.load_model(base, "cpu"), tmp_path / "with", components=1)
    assert prior.config.images == 6 and iv.load_model(str(tmp_path / "with"), "cpu").latent_prior is not None
    assert iv.load_model(base, "cpu").latent_prior is None  # the model's own folder is left alone
    with pytest.raises(ModelError, match="own folder"):
        iv.fit_prior(data, iv.load_model(base, "cpu"), base, components=1)
    folder, step = iv.export(tmp_path / "run", tmp_path / "exported")
    assert step == 2 and (folder / "model.safetensors").is_file()


def test_the_module_example_runs(monkeypatch):
    """The API's own example (its module docstring) is a doctest: it runs and prints what it says."""
    import doctest
    from pathlib import Path

    from im2vec_cli import api

    monkeypatch.chdir(Path(__file__).resolve().parents[1])  # the example's paths are the repository's
    result = doctest.testmod(api, verbose=False)
    assert result.attempted >= 8 and result.failed == 0


def test_the_memory_budget_sets_the_work_size():
    """``max_memory`` (bytes) sets how large a copy is worked on and how large a picture may be
    read; the default (2 GiB) keeps the 2048² work size, and traces a two-colour picture whole up to
    12.6 MP (a 300 dpi page); a budget under 768 MiB is refused."""
    from im2vec_cli.options import MAX_BILEVEL_PIXELS, MAX_WORK_PIXELS, VectorizeOptions

    default = VectorizeOptions()
    assert default.work_pixels() == MAX_WORK_PIXELS and default.max_input_pixels() > 64_000_000
    assert default.bilevel_pixels() == (2**31 - 2**29) // 128 > 2550 * 3300
    small = VectorizeOptions(max_memory=2**30)
    assert small.work_pixels() == 2**29 // 256 and small.max_input_pixels() == 2**29 // 16
    assert small.bilevel_pixels() == 2**29 // 128
    assert VectorizeOptions(max_memory=2**35).bilevel_pixels() == MAX_BILEVEL_PIXELS
    with pytest.raises(ValueError, match="max_memory"):
        VectorizeOptions(max_memory=100 * 2**20)


@pytest.mark.parametrize("field, value", [("parts", "bogus"), ("effort", "sketch"), ("colors", 0), ("tolerance", -1)])
def test_bad_options_raise_the_documented_error(field, value):
    """README: a bad input raises Im2VecError; VectorizeOptions raised a plain ValueError."""
    from im2vec_cli.errors import ConfigError, Im2VecError
    from im2vec_cli.options import VectorizeOptions

    with pytest.raises(Im2VecError, match=field) as info:
        VectorizeOptions(**{field: value})
    assert isinstance(info.value, ConfigError) and isinstance(info.value, ValueError)  # still a ValueError too


def test_no_refine_runs_eager_unless_compile_is_asked(monkeypatch, model):
    """`vectorize --no-refine` ran the model's passes through torch.compile (8-18 s a process for
    0.15 s of work once the model is loaded): like refinement, it compiles only with ``compile=True``."""
    import im2vec_cli.infer as infer
    from im2vec_cli.raster import compile_enabled

    seen, real = [], infer.vectorize
    monkeypatch.delenv("IM2VEC_COMPILE", raising=False)
    monkeypatch.setattr(infer, "vectorize", lambda *a, **k: seen.append(compile_enabled()) or real(*a, **k))
    img = torch.ones(3, 32, 32)
    img[:, 8:24, 8:24] = 0
    iv.vectorize(img, model[0], refine=False, parts="model")
    assert seen == [False]
