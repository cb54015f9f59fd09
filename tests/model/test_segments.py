"""Segment-count control (issue "Vectorize fidelity", paper sec. 3.3): the auxiliary fit,
`--segments auto`, per-path (ragged) decoding and segment merging."""

from pathlib import Path

import numpy as np
import pytest
import torch

from im2vec_cli.config import REPO_MODELS
from im2vec_cli.files import load_image
from im2vec_cli.frame import Placement
from im2vec_cli.infer import model_input, to_vector, vectorize
from im2vec_cli.model.pretrained import from_pretrained
from im2vec_cli.model.segments import K_MIN, SegmentPredictor, choose_segments, curve, fit_loss
from im2vec_cli.raster import render_paths
from im2vec_cli.training.aux import AuxSettings, train_segment_predictor
from tests.helpers import TINY, check_svg, make_tiny_model, png, run, synthetic_shapes

ROOT = Path(__file__).resolve().parents[2]


def test_predicted_curves_are_monotone_and_fit_exact_curves():
    """Any parameters give a non-increasing curve; the fit recovers known exponential curves."""
    torch.manual_seed(0)
    ks = torch.arange(1, 60, dtype=torch.float32)
    pred = SegmentPredictor(8, 32)
    codes = torch.randn(256, 8) * 3
    assert (curve(pred(codes), ks).diff(dim=1) <= 0).all()
    # exact curves a*exp(-b*k)+c, parameters a smooth function of the code
    a = 0.05 * torch.sigmoid(codes[:, 0]) + 0.01
    b = 0.2 + 0.3 * torch.sigmoid(codes[:, 1])
    c = torch.full_like(a, 1e-4)
    truth = torch.stack([a, b, c], 1)
    sweep = torch.tensor([3, 4, 6, 8, 12, 16, 25], dtype=torch.float32)
    losses = curve(truth, sweep)
    opt = torch.optim.Adam(pred.parameters(), lr=3e-3)
    first = fit_loss(pred(codes), sweep, losses).item()
    for _ in range(1500):
        loss = fit_loss(pred(codes), sweep, losses)
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert loss.item() < 0.01 * first
    with torch.no_grad():
        err = (curve(pred(codes), sweep) - losses).abs() / losses
    assert err.median() < 0.1
    assert (curve(pred(codes), ks).diff(dim=1) <= 0).all()


def test_choose_segments_follows_the_slope():
    """Steeper curves need more segments; a looser quality never asks for more."""
    params = torch.tensor([[0.1, 0.3, 0.0], [0.01, 0.3, 0.0], [1e-9, 0.3, 0.0]])
    k = choose_segments(params, 1e-3, 25)
    assert k[0] > k[1] > k[2] and k[2] == K_MIN
    # the chosen k is the first whose slope a*b*exp(-b*k) is below the threshold
    a, b = 0.1, 0.3
    kk = int(k[0])
    assert a * b * np.exp(-b * kk) <= 1e-3 < a * b * np.exp(-b * (kk - 1))
    qs = [1e-5, 1e-4, 1e-3, 1e-2]
    ks = [choose_segments(params, q, 25) for q in qs]
    for lo, hi in zip(ks, ks[1:]):
        assert (hi <= lo).all()
    assert int(choose_segments(torch.tensor([[10.0, 0.05, 0.0]]), 1e-6, 25)) == 25  # clamped to k_max
    with pytest.raises(ValueError):
        choose_segments(params, 0.0, 25)


def test_ragged_decode_renders_like_each_path_alone(tmp_path):
    """Per-path counts pad with zero-length segments; the render equals the unpadded paths'."""
    model = from_pretrained(make_tiny_model(tmp_path / "tiny"))
    z = torch.randn(2, TINY.latent)
    counts = torch.tensor([[3, 5, 4, 7], [6, 6, 3, 4]])
    dec = model.decode(z, counts)
    assert dec.points.shape == (2, 4, 3 * 7, 2)
    for i in range(2):
        for p in range(4):
            k = int(counts[i, p])
            alone = model.decode(z[i : i + 1], k).points[0, p]  # (3k, 2)
            assert torch.allclose(dec.points[i, p, : 3 * k], alone, atol=1e-6)
            assert (dec.points[i, p, 3 * k :] == dec.points[i, p, 0]).all()  # padding at anchor 0
        vec = to_vector(dec, i, Placement(32, 32), keep_all=True)
        assert [len(c) // 3 for s in vec.shapes for c in s.contours] == counts[i].tolist()
        trimmed = [dec.points[i, p, : 3 * int(counts[i, p])] for p in range(4)]
        for p in range(4):  # each path rendered alone, padded vs trimmed
            a = render_paths(dec.points[i : i + 1, p : p + 1], torch.zeros(1, 1, 3), size=32)
            b = render_paths(trimmed[p][None, None], torch.zeros(1, 1, 3), size=32)
            assert torch.allclose(a, b, atol=1e-6)


def test_train_aux_then_auto_segments(tmp_path):
    """`train-aux` on a tiny model and folder, then `--segments auto`: valid SVGs whose paths
    have the counts the predictor chose, within [K_MIN, max_segments]."""
    data = tmp_path / "data"
    data.mkdir()
    from PIL import Image

    for i, img in enumerate(synthetic_shapes(24, 32)):
        Image.fromarray(img.permute(1, 2, 0).numpy()).save(data / f"{i:02d}.png")
    tiny = make_tiny_model(tmp_path / "tiny")
    res = run(["train-aux", str(data), "--model", tiny, "-o", str(tmp_path / "aux"), "--images", "16", "--steps", "200"])
    assert res.exit_code == 0, res.output
    assert "measuring 16 images" in res.stderr and "step 199: fit" in res.stderr  # its events, said
    model = from_pretrained(tmp_path / "aux")
    assert model.segment_predictor is not None
    base = from_pretrained(tiny)
    for (k, v), (k2, v2) in zip(base.state_dict().items(), model.state_dict().items()):
        assert k == k2 and torch.equal(v, v2)  # the VAE itself is untouched
    img = png(tmp_path / "in.png", 32, 32)
    out = tmp_path / "auto.svg"
    res = run(["vectorize", img, "-o", str(out), "--model", str(tmp_path / "aux"), "--segments", "auto",
               "--quality", "1e-4", "--no-refine"])
    assert res.exit_code == 0, res.output
    for p in check_svg(out.read_text(), 32, 32):
        n = p.get("d").count("C")
        assert K_MIN <= n <= TINY.max_segments
    # without a predictor: one clear error line
    res = run(["vectorize", img, "-o", str(tmp_path / "x.svg"), "--model", tiny, "--segments", "auto", "--no-refine"])
    assert res.exit_code == 1 and "train-aux" in res.output and not (tmp_path / "x.svg").exists()
    # in place, over a model with both priors: they are kept as they were (the latents did not change)
    res = run(["fit-prior", str(data), "--model", tiny, "-o", tiny, "--overwrite", "--components", "2",
               "--neighbours", "2"])
    assert res.exit_code == 0, res.output
    priors = {p.name: p.read_bytes() for p in Path(tiny).glob("latent_*")}
    assert {"latent_prior.json", "latent_neighbours.json"} <= set(priors)
    res = run(["train-aux", str(data), "--model", tiny, "-o", tiny, "--overwrite", "--images", "16", "--steps", "50"])
    assert res.exit_code == 0, res.output
    assert {p.name: p.read_bytes() for p in Path(tiny).glob("latent_*")} == priors


def test_segment_fit_report(tmp_path):
    model = from_pretrained(make_tiny_model(tmp_path / "tiny"))
    out, report = train_segment_predictor(model, synthetic_shapes(8, 32).float() / 255, AuxSettings(steps=100, hidden=16))
    assert report["paths"] == 8 * TINY.paths and len(report["measured_mean"]) == len(report["ks"])
    assert report["measured_mean"][-1] == 0.0  # the reference is the largest k itself
    assert out.config.segment_predictor == 16


@pytest.mark.skipif(not (REPO_MODELS / "fonts" / "segments.json").exists(), reason="fonts model without predictor")
def test_auto_segments_fewer_for_simple_shapes():
    """The shipped fonts model: a plain bar gets fewer segments than the glyph 'g'."""
    model = from_pretrained("fonts")
    bar = torch.ones(3, 64, 64)
    bar[:, 6:58, 26:38] = 0.0
    g = load_image(ROOT / "examples" / "glyph_g.png")
    simple, complex_ = vectorize(model, [bar, g], segments="auto")
    assert 0 < simple.num_segments < complex_.num_segments
    x = torch.stack([model_input(model, im)[0] for im in (bar, g)])
    counts = model.choose_segments(model.encode(x)[0], 2e-4)
    assert counts.min() >= K_MIN and counts.max() <= model.config.max_segments


# --- merging --------------------------------------------------------------------------------


