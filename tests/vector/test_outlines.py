"""Clean outlines (``vectorize --parts clean``, the default): checked on cairosvg renders of
what we write, against shapes whose true outline is known (drawn here as exact SVG)."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import torch
from click.testing import CliRunner
from scipy.ndimage import distance_transform_edt, label

from im2vec_cli import api
from im2vec_cli.cli import cli
from im2vec_cli.files import load_image
from im2vec_cli.model.pretrained import REPO_MODELS
from im2vec_cli.raster import flatten_closed, polygon_area
from im2vec_cli.vector import VectorImage, VectorShape, rasterize_svg
from im2vec_cli.vector.fit import corners, fit_ring, resample, split_segments
from im2vec_cli.vector.outline import redrawn
from im2vec_cli.vector.trace import quantize, two_tone

needs_fonts = pytest.mark.skipif(not (REPO_MODELS / "fonts" / "config.json").exists(), reason="no shipped fonts model")
needs_emoji = pytest.mark.skipif(not (REPO_MODELS / "emoji" / "config.json").exists(), reason="no shipped emoji model")


def svg_of(body: str, size: int = 64) -> str:
    return f'<svg xmlns="http://www.w3.org/2000/svg" width="{size}" height="{size}" viewBox="0 0 {size} {size}">{body}</svg>'


def picture(body: str, size: int = 64):
    """``(3, H, W)`` tensor of an exact SVG rendered by cairo (anti-aliased, over white)."""
    import torch

    return torch.from_numpy(rasterize_svg(svg_of(body, size), size, size)).permute(2, 0, 1).float()


def ink(svg: str, scale: int) -> np.ndarray:
    return rasterize_svg(svg, 64 * scale, 64 * scale).mean(-1) < 0.5


def topology(mask: np.ndarray) -> tuple[int, int]:
    """Pieces (8-connected) and holes (4-connected background not touching the border)."""
    _, pieces = label(mask, structure=np.ones((3, 3)))
    bg, n = label(~mask)
    border = set(np.unique(np.concatenate([bg[0], bg[-1], bg[:, 0], bg[:, -1]]))) - {0}
    return pieces, n - len(border)


def check_clean_svg(svg: str) -> list[str]:
    """Valid XML whose every <path> is closed cubics only (M, C, Z); returns the d strings."""
    root = ET.fromstring(svg)
    ds = [el.get("d") for el in root.iter() if el.tag.endswith("path")]
    for d in ds:
        assert re.fullmatch(r"(M [-\d. ]+( C [-\d. ]+)+ Z ?)+", d.strip() + " "), d[:80]
    return ds


def no_background_inside(svg: str, truth_svg: str, scale: int = 4, depth: float = 1.0) -> bool:
    """No near-white pixel of the render lies ``depth`` input px or more inside the true ink."""
    truth = ink(truth_svg, scale)
    inner = distance_transform_edt(np.pad(truth, 1))[1:-1, 1:-1] > depth * scale
    return not (inner & (rasterize_svg(svg, 64 * scale, 64 * scale).min(-1) > 0.9)).any()


# --- the pieces -------------------------------------------------------------------------------------


def test_redrawn_unites_overlapping_parts_into_outer_contour_and_hole():
    """A ring drawn as two overlapping halves with a hairline gap where they should meet (the
    model's way of drawing): redrawn, it is one shape of one outer contour and one hole, the
    hairline closed, nothing of the ring's inside left uncovered."""
    def half(a0, a1, r0=24.0, r1=14.0, n=24):
        t = np.linspace(a0, a1, n)
        outer = np.stack([32 + r0 * np.cos(t), 32 + r0 * np.sin(t)], 1)
        inner = np.stack([32 + r1 * np.cos(t[::-1]), 32 + r1 * np.sin(t[::-1])], 1)
        ring = np.vstack([outer, inner])
        return np.repeat(ring, 3, axis=0)  # straight cubics: anchor, control, control at one point

    parts = [half(-0.05, np.pi + 0.05), half(np.pi + 0.06, 2 * np.pi - 0.02)]  # overlap on one side, 0.24 px gap on the other
    model_like = VectorImage(64, 64, [VectorShape(parts, (0, 0, 0), "nonzero")])  # as resolve_overlaps leaves it
    clean, flags = redrawn(model_like, 0.5)
    assert len(clean.shapes) == 1 and len(clean.shapes[0].contours) == 2
    areas = sorted(float(polygon_area(flatten_closed(torch.from_numpy(c), 8))) for c in clean.shapes[0].contours)
    assert areas[0] < 0 < areas[1]  # one hole (counter-clockwise), one outer contour (clockwise on screen)
    svg = clean.to_svg()
    check_clean_svg(svg)
    truth = svg_of('<circle cx="32" cy="32" r="24"/><circle cx="32" cy="32" r="14" fill="white"/>')
    assert topology(ink(svg, 4)) == topology(ink(truth, 4)) == (1, 1)
    assert no_background_inside(svg, truth, depth=1.0)


def test_fit_ring_stays_within_tolerance_and_looser_means_fewer_segments():
    """Every point of the traced ring (but within a pixel of a corner, which is moved to where
    its sides meet) lies within ``tol`` of the cubics fitted to it, and a larger tolerance never
    gives more segments (six rings of glyph-like shapes)."""
    rng = np.random.default_rng(0)
    t = np.linspace(0, 2 * np.pi, 400, endpoint=False)
    rings = [np.stack([32 + (20 + 3 * np.sin(k * t + rng.uniform(0, 6))) * np.cos(t),
                       32 + (14 + 2 * np.cos((k + 1) * t)) * np.sin(t)], 1) for k in range(2, 6)]
    rings += [np.array([[10, 10], [50, 10], [50, 50], [10, 50]], float), np.array([[8, 8], [56, 8], [56, 20], [20, 20],
                                                                              [20, 56], [8, 56]], float)]
    for ring in rings:
        counts = []
        for tol in (0.1, 0.25, 0.5, 1.0, 2.0):
            c, sharp = fit_ring(ring, tol)
            counts.append(len(c) // 3)
            segs = [np.stack([c[3 * s], c[3 * s + 1], c[3 * s + 2], c[(3 * s + 3) % len(c)]]) for s in range(len(c) // 3)]
            u = np.linspace(0, 1, 200)[:, None]
            curve = np.concatenate([(1 - u) ** 3 * q[0] + 3 * (1 - u) ** 2 * u * q[1] + 3 * (1 - u) * u**2 * q[2]
                                    + u**3 * q[3] for q in segs])
            dense = resample(ring, 0.25)
            at = resample(ring)[corners(resample(ring))]  # corners move to where the sides meet (fit.sharpen)
            if len(at):
                dense = dense[np.hypot(*(dense[:, None] - at[None]).transpose(2, 0, 1)).min(1) > 1.0]
            dist = np.sqrt(((dense[:, None] - curve[None]) ** 2).sum(-1)).min(1)
            assert dist.max() <= tol + 0.05, (tol, dist.max())
        assert all(a >= b for a, b in zip(counts, counts[1:])), counts


def test_corners_are_found_and_round_ends_are_not():
    square = resample(np.array([[10, 10], [50, 10], [50, 50], [10, 50]], float))
    assert len(corners(square)) == 4
    t = np.linspace(0, 2 * np.pi, 300, endpoint=False)
    stadium = resample(np.stack([32 + 20 * np.clip(1.4 * np.cos(t), -1, 1), 32 + 3 * np.sin(t)], 1))  # round ends, r=3
    circle = resample(np.stack([32 + 3 * np.cos(t), 32 + 3 * np.sin(t)], 1))
    assert len(corners(circle)) == 0 and len(corners(stadium)) <= 4


def test_split_segments_keeps_the_outline():
    c, sharp = fit_ring(np.array([[10, 10], [50, 12], [48, 50], [12, 46]], float), 0.5)
    more, flags = split_segments(c, sharp, np.array([0, 2]))
    assert len(more) == len(c) + 6 and flags.sum() == sharp.sum()
    a = rasterize_svg(VectorImage(64, 64, [VectorShape([c])]).to_svg(4), 128, 128)
    b = rasterize_svg(VectorImage(64, 64, [VectorShape([more])]).to_svg(4), 128, 128)
    assert np.abs(a - b).max() < 0.05


def test_two_tone_and_palette_detection():
    glyph = picture('<path d="M 10 50 L 30 8.5 L 52 50 Z"/>').permute(1, 2, 0).double().numpy()
    assert two_tone(glyph, np.ones(3)) is not None
    grey_fill = picture('<circle cx="32" cy="32" r="20" fill="#888" stroke="black" stroke-width="2"/>')
    assert two_tone(grey_fill.permute(1, 2, 0).double().numpy(), np.ones(3)) is None  # grey is a colour here
    face = picture('<circle cx="32" cy="32" r="26" fill="#fcea2b" stroke="#000" stroke-width="1.8"/>'
                   '<circle cx="24" cy="26" r="3"/><circle cx="40" cy="26" r="3"/>')
    palette, labels = quantize(face.permute(1, 2, 0).double().numpy(), None)
    assert len(palette) == 3  # white, yellow, and the thin black outline with the eyes
    assert any(np.abs(p).max() < 0.15 for p in palette)


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


def test_untangle_removes_crossings_and_keeps_the_fill():
    """A contour folded into a small loop at a corner (what a polished corner can do) is found
    crossing and replaced by its exact outline: nothing crosses, the render stays the same
    but for the loop's pin hole."""
    from im2vec_cli.vector.outline import crosses, untangle

    def lines(pts):
        pts = np.asarray(pts, float)
        nxt = np.roll(pts, -1, 0)
        return np.concatenate([np.stack([p, p + (q - p) / 3, p + 2 * (q - p) / 3]) for p, q in zip(pts, nxt)])

    square = lines([[10, 10], [50, 10], [50, 50], [10, 50]])
    looped = lines([[10, 10], [50, 10], [51.5, 11.5], [49, 12.5], [50, 9], [50, 50], [10, 50]])  # a loop at a corner
    assert not crosses([square]) and crosses([looped])
    vec = VectorImage(64, 64, [VectorShape([looped], (0, 0, 0), "nonzero")])
    out = untangle(vec)
    assert not any(crosses(s.contours) for s in out.shapes)
    check_clean_svg(out.to_svg())
    a, b = ink(vec.to_svg(), 4), ink(out.to_svg(), 4)
    assert (a != b).sum() <= 16  # at most the loop's pin hole, a pixel at 4x
    kept = untangle(VectorImage(64, 64, [VectorShape([square])]))  # nothing to untangle: left as it was
    assert len(kept.shapes) == 1 and len(kept.shapes[0].contours) == 1
    assert (ink(kept.to_svg(), 4) != ink(VectorImage(64, 64, [VectorShape([square])]).to_svg(), 4)).sum() == 0
