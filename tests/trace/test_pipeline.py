"""The clean-outline pipeline (``trace/pipeline.py``; ``vectorize --parts clean``, the default):
checked on cairosvg renders of what we write, against shapes whose true outline is known (drawn
here as exact SVG)."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from click.testing import CliRunner
from scipy.ndimage import label

from im2vec_cli import api
from im2vec_cli.cli import cli
from im2vec_cli.config import REPO_MODELS
from im2vec_cli.files import load_image
from im2vec_cli.options import Plan
from im2vec_cli.trace import split_where_wrong
from im2vec_cli.trace.pipeline import _box3
from im2vec_cli.vector import VectorImage, VectorShape, rasterize_svg, to_svg
from tests.helpers import circle
from tests.trace.outlines import (
    check_clean_svg,
    ink,
    needs_emoji,
    needs_fonts,
    no_background_inside,
    openmoji_like,
    picture,
    svg_of,
    topology,
)


def _ring(cx, cy, r):
    return circle(cx, cy, r, segments=8).numpy()



# --- vectorize, end to end (the acceptance list) -------------------------------------------------


@needs_fonts
@pytest.mark.parametrize("body, holes", [
    ('<rect x="10.3" y="12.6" width="30" height="22"/><rect x="26.5" y="24.2" width="26" height="28"/>', 0),
    ('<path d="M 32 8 A 24 24 0 1 1 31.99 8 Z M 32 18.5 A 13.5 13.5 0 1 0 32.01 18.5 Z" fill-rule="evenodd"/>', 1),
])
def test_overlapping_parts_become_one_clean_path(body, holes):
    """Two overlapping rectangles, and a ring: one <path>, no background inside the true shape
    at 4x, and the true number of pieces and holes."""
    vec = api.vectorize(picture(body), "fonts")
    svg = vec.to_svg()
    assert len(check_clean_svg(svg)) == 1
    truth = svg_of(body)
    assert no_background_inside(svg, truth)
    assert topology(ink(svg, 4)) == topology(ink(truth, 4)) == (1, holes)


@needs_fonts
def test_features_the_model_cannot_draw_are_kept():
    """A disc with two small holes on the fonts model: the SVG has both holes."""
    body = ('<circle cx="32" cy="32" r="22"/><circle cx="24" cy="28" r="3.5" fill="white"/>'
            '<circle cx="41" cy="36" r="3" fill="white"/>')
    svg = api.vectorize(picture(body), "fonts").to_svg()
    check_clean_svg(svg)
    assert topology(ink(svg, 4)) == (1, 2)
    assert no_background_inside(svg, svg_of(body))


@needs_emoji
def test_smiley_keeps_its_eyes_on_the_emoji_model():
    """examples/emoji_grin.png with the emoji model: two dark eyes in the upper half of the face
    (the model alone draws a disc and a mouth), on the cairosvg render."""
    img = load_image("examples/emoji_grin.png")
    svg = api.vectorize(img, "emoji").to_svg()
    check_clean_svg(svg)
    out = rasterize_svg(svg, img.shape[2] * 4, img.shape[1] * 4)
    top = out[: out.shape[0] // 2]
    dark = top.max(-1) < 0.5
    _, eyes = label(dark)
    assert eyes == 2
    ref = np.asarray(img.permute(1, 2, 0))
    assert ((rasterize_svg(svg, img.shape[2], img.shape[1]) - ref) ** 2).mean() < 0.003


@needs_fonts
@pytest.mark.parametrize("body, pts", [
    ('<rect x="14.3" y="12.6" width="35" height="37.5"/>', [(14.3, 12.6), (49.3, 12.6), (49.3, 50.1), (14.3, 50.1)]),
    ('<path d="M 12.4 10.2 H 24.6 V 41.3 H 52.2 V 53.5 H 12.4 Z"/>',
     [(12.4, 10.2), (24.6, 10.2), (24.6, 41.3), (52.2, 41.3), (52.2, 53.5), (12.4, 53.5)]),
])
def test_corners_stay_sharp(body, pts):
    """A square and an "L" (convex and concave corners): the render at 8x matches the true
    shape within a pixel of each corner (at most 15% of the 8x pixels there differ), and the
    outline has a sharp join on each corner (an anchor within 0.35 px whose handles turn 60-120 degrees)."""
    vec = api.vectorize(picture(body), "fonts")
    got, truth = ink(vec.to_svg(), 8), ink(svg_of(body), 8)
    contours = [c for sh in vec.shapes for c in sh.contours]
    for x, y in pts:
        cx, cy = int(round(x * 8)), int(round(y * 8))
        win = (slice(cy - 8, cy + 8), slice(cx - 8, cx + 8))  # one input pixel around the corner
        assert (got[win] != truth[win]).mean() <= 0.15, (x, y, (got[win] != truth[win]).mean())
        dist, c, i = min((np.hypot(*(c[3 * i] - [x, y])), ci, i) for ci, c in enumerate(contours)
                         for i in range(len(c) // 3))
        assert dist <= 0.35, (x, y, dist)
        c = contours[c]
        into, out = c[3 * i] - c[(3 * i - 1) % len(c)], c[3 * i + 1] - c[3 * i]
        turn = np.degrees(np.arccos(np.dot(into, out) / (np.linalg.norm(into) * np.linalg.norm(out) + 1e-12)))
        assert 60 <= turn <= 120, (x, y, turn)  # a sharp join: the outline turns there, it does not round it off


@needs_emoji
def test_touching_colours_show_no_background_between_them():
    """Red and blue rectangles sharing an edge (at x = 31.4): at 4x no pixel along the shared
    edge is lighter than either colour (the white canvas never shows between them)."""
    # the blue lies under the red in the input, so that the input itself has no conflation seam
    body = '<rect x="28" y="10" width="28.4" height="44" fill="#3040c0"/><rect x="8" y="10" width="23.4" height="44" fill="#d03030"/>'
    svg = api.vectorize(picture(body), "emoji").to_svg()
    check_clean_svg(svg)
    out = rasterize_svg(svg, 256, 256)
    edge = out[48:208, int(31.4 * 4) - 3 : int(31.4 * 4) + 4]  # rows inside both rectangles
    assert edge.min(-1).max() < 0.35, edge.min(-1).max()  # the lightest channel stays dark: no white seam


@needs_emoji
@pytest.mark.parametrize("seed", [32, 34])
def test_light_colours_under_black_lines_show_no_background(seed):
    """OpenMoji-like pictures (light fills, black lines over them) on which the polish used to
    open slivers of background beside the lines (108 and 97 px at 4x, before
    ``regions._hidden_reach``, the held hidden points of the polish and the edge field that
    ignores pixels under pieces above): none now, the background counted as bench/outlines.py
    counts it (white where the true picture is any colour, 1.5 input px inside)."""
    truth = openmoji_like(seed)
    pic = torch.from_numpy(rasterize_svg(truth, 64, 64)).permute(2, 0, 1).float()
    svg = api.vectorize(pic, "emoji").to_svg()
    check_clean_svg(svg)
    assert no_background_inside(svg, truth, depth=1.5, colour=True)


@pytest.mark.slow  # 16 full vectorize runs
@needs_fonts
def test_larger_tolerance_gives_fewer_segments_on_glyphs():
    """``--tolerance``: on four glyph-like shapes, segments never grow with the tolerance."""
    bodies = ['<path d="M 12 52 C 12 20 30 8 52 10 L 52 22 C 36 22 26 30 26 52 Z"/>',
              '<circle cx="32" cy="32" r="20"/><circle cx="32" cy="32" r="10" fill="white"/>',
              '<path d="M 10 50 L 30 8.5 L 52 50 L 42 50 L 30 24 L 20 50 Z"/>',
              '<rect x="14.3" y="12.6" width="35" height="37.5"/>']
    for body in bodies:
        img = picture(body)
        counts = [api.vectorize(img, "fonts", tolerance=t).num_segments for t in (0.25, 0.5, 1.0, 2.0)]
        assert all(a >= b for a, b in zip(counts, counts[1:])), (body, counts)


@needs_fonts
def test_parts_model_keeps_the_models_paths(tmp_path):
    """`--parts model` is the model's own structure: several paths, each of at most the model's
    segment count (merging only removes segments), where clean parts give one path."""
    img = picture('<rect x="14.3" y="12.6" width="35" height="37.5"/>')
    clean = api.vectorize(img, "fonts")
    model = api.vectorize(img, "fonts", parts="model")
    segments = api.load_model("fonts").config.segments
    counts = [len(c) // 3 for s in model.shapes for c in s.contours]
    assert clean.num_paths == 1 and model.num_paths >= 2
    assert all(1 <= k <= segments for k in counts) and len(set(counts)) > 1  # merged per path, not padded
    assert model.to_svg() != clean.to_svg()


def test_cli_writes_clean_svgs_with_the_new_options(tmp_path):
    """The options reach the pipeline: --colors 1 makes a colour picture two-tone (one path)."""
    from PIL import Image

    img = picture('<circle cx="32" cy="32" r="20" fill="#d03030"/><rect x="8" y="8" width="12" height="12" fill="#3040c0"/>')
    Image.fromarray((img.permute(1, 2, 0).numpy() * 255).astype(np.uint8)).save(tmp_path / "a.png")
    model = "fonts" if (REPO_MODELS / "fonts" / "config.json").exists() else None
    if model is None:
        pytest.skip("no shipped fonts model")
    res = CliRunner().invoke(cli, ["vectorize", str(tmp_path / "a.png"), "-o", str(tmp_path / "two.svg"),
                                   "--colors", "1", "--tolerance", "1"])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "two.svg").read_text().count("<path") == 1
    res = CliRunner().invoke(cli, ["vectorize", str(tmp_path / "a.png"), "-o", str(tmp_path / "many.svg")])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "many.svg").read_text().count("<path") == 2


def test_split_where_wrong_splits_only_where_the_render_is_wrong():
    """A circle traced with 8 segments, the input a circle with a bump on its right: only the
    two segments that meet at the bump are halved."""
    h = w = 48
    bumped = _ring(24, 24, 14)
    bumped[0:2, 0] += 6  # the first anchor (at 0 degrees, the right) and its handle pushed out
    bumped[-1, 0] += 6
    truth = VectorImage(w, h, [VectorShape([bumped], (0.0, 0.0, 0.0), "nonzero")])
    # (H, W, 3): float32 pixels in float64, as clean_outlines holds its pictures
    target = rasterize_svg(to_svg(truth, 4), w, h).astype(np.float32).astype(np.float64)
    plain = VectorImage(w, h, [VectorShape([_ring(24, 24, 14)], (0.0, 0.0, 0.0), "nonzero")])
    flags = [[np.zeros(8, dtype=bool)]]
    vec, new_flags, count = split_where_wrong(plain, flags, target, Plan())
    assert count == 2
    assert len(vec.shapes[0].contours[0]) == 3 * (8 + count) and len(new_flags[0][0]) == 8 + count
    old = {tuple(a) for a in np.round(plain.shapes[0].contours[0][0::3], 6)}
    new = [a for a in np.round(vec.shapes[0].contours[0][0::3], 6) if tuple(a) not in old]
    assert len(new) == 2 and all(a[0] > 34 for a in new)  # the new anchors halve those two, on the right
    assert split_where_wrong(truth, flags, target, Plan())[2] == 0  # nothing is wrong with the truth


def test_box3_is_scipys_uniform_filter():
    from scipy.ndimage import uniform_filter

    a = np.random.default_rng(0).random((37, 53)) ** 3
    assert np.abs(_box3(a) - uniform_filter(a, 3)).max() < 1e-12
