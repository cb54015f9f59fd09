"""``vectorize --no-refine``: the model's guess drawn clean (``infer.clean_guess``) on the fonts
model's 64 test-split glyphs (never trained on), against the model's own paths and the pictures."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.ndimage import binary_closing

import im2vec_cli as iv
from im2vec_cli.files import load_image
from im2vec_cli.trace import crosses
from tests.helpers import make_tiny_model, png, run
from tests.trace.outlines import check_clean_svg, ink, needs_fonts, topology

ASSETS = Path(__file__).resolve().parents[1] / "assets" / "fonts_test"
UP = 4


def hairlines(out: np.ndarray, truth: np.ndarray) -> int:
    """Pixels at 4x where the render's ink ``out`` shows background inside the picture's ink
    ``truth`` within a gap of its own ink narrower than about 2 input px (what a closing of the
    render fills): the seams and cracks between parts, not a part drawn a pixel off or missed."""
    return int((binary_closing(out, np.ones((2 * UP - 1,) * 2, dtype=bool)) & ~out & truth).sum())


@needs_fonts
def test_no_refine_draws_the_models_guess_without_its_seams():
    model = iv.load_model("fonts", "cpu")
    files = sorted(ASSETS.glob("*.png"))
    pictures = [load_image(f.name, f.read_bytes()) for f in files]
    clean = iv.vectorize(pictures, model, refine=False)
    paths = iv.vectorize(pictures, model, refine=False, parts="model")
    hair = {"clean": 0, "model": 0}
    same_topology = {"clean": 0, "model": 0}
    ious = []
    for pic, c, m in zip(pictures, clean, paths):
        truth = np.kron(pic.mean(0).numpy() < 0.5, np.ones((UP, UP), dtype=bool))  # the picture's ink at 4x
        inks = {"clean": ink(c.to_svg(), UP), "model": ink(m.to_svg(), UP)}
        for name, out in inks.items():
            hair[name] += hairlines(out, truth)
            same_topology[name] += topology(out) == topology(truth)
        check_clean_svg(c.to_svg())
        assert all(s.fill_rule == "nonzero" and not crosses(s.contours) for s in c.shapes)
        a, b = inks["clean"], inks["model"]
        ious.append((a & b).sum() / max((a | b).sum(), 1))
    assert hair["clean"] <= 0.2 * hair["model"], hair
    assert same_topology["clean"] >= len(files) // 2 and same_topology["clean"] > same_topology["model"], same_topology
    assert np.mean(ious) >= 0.95, np.mean(ious)  # the same shape: the guess mended, not redrawn from the picture
    assert sum(v.num_segments for v in clean) < sum(v.num_segments for v in paths)


@needs_fonts
def test_no_refine_clean_work_is_in_model_pixels_whatever_the_picture_size():
    """A glyph 16 times the model's size: its guess is cleaned at the model's scale (bounded work,
    seams measured in model pixels) and comes back in the picture's frame, the same shape as at 64 px."""
    model = iv.load_model("fonts", "cpu")
    f = sorted(ASSETS.glob("*.png"))[0]
    small = load_image(f.name, f.read_bytes())
    big = small.repeat_interleave(16, 1).repeat_interleave(16, 2)  # (3, 1024, 1024), nearest
    a, b = iv.vectorize([small, big], model, refine=False)
    assert (b.width, b.height) == (1024, 1024)
    ink_a, ink_b = ink(a.to_svg(), UP), ink(b.to_svg(), UP)  # both at 256 px
    assert (ink_a & ink_b).sum() / (ink_a | ink_b).sum() >= 0.9
    assert b.num_segments <= 2 * a.num_segments


@pytest.mark.parametrize("parts", ["clean", "model"])
def test_parts_is_not_warned_about_with_no_refine(tmp_path, parts):
    model = make_tiny_model(tmp_path)
    res = run(["vectorize", png(tmp_path / "a.png"), "-o", str(tmp_path / "a.svg"), "--model", model,
               "--no-refine", "--parts", parts])
    assert res.exit_code == 0, res.output
    assert "--parts" not in res.output
    check_clean_svg((tmp_path / "a.svg").read_text())
