"""refine/grow.py: paths grown where the model's fitted paths miss a part of the picture."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from im2vec_cli.files import load_picture
from im2vec_cli.options import Plan, VectorizeOptions
from im2vec_cli.refine.grow import grown, pieces
from im2vec_cli.trace import read
from im2vec_cli.vector import VectorImage, VectorShape, rasterize_svg

ASSETS = Path(__file__).resolve().parents[1] / "assets"


def circle(cx: float, cy: float, r: float, ccw: bool = False) -> np.ndarray:
    """A closed cubic contour ``(12, 2)``: four quarter arcs."""
    k = 0.5523 * r
    a = [(cx + r, cy), (cx, cy + r), (cx - r, cy), (cx, cy - r)]
    t = [(0, k), (-k, 0), (0, -k), (k, 0)]
    pts = []
    for i in range(4):
        (x0, y0), (x1, y1) = a[i], a[(i + 1) % 4]
        (u0, v0), (u1, v1) = t[i], t[(i + 1) % 4]
        pts += [(x0, y0), (x0 + u0, y0 + v0), (x1 - u1, y1 - v1)]
    pts = np.array(pts, dtype=np.float64)
    return np.roll(pts[::-1], 1, axis=0) if ccw else pts


def face(eyes: bool) -> VectorImage:
    """A 64 px yellow face, with two dark eyes and a ring-shaped mouth (a hole the face shows through) or without."""
    shapes = [VectorShape([circle(32, 32, 26)], (1.0, 0.8, 0.2), "nonzero")]
    if eyes:
        shapes.append(VectorShape([circle(22, 26, 4), circle(42, 26, 4)], (0.2, 0.1, 0.1), "nonzero"))
        shapes.append(VectorShape([circle(32, 44, 7), circle(32, 44, 4)], (0.8, 0.1, 0.2), "evenodd"))
    return VectorImage(64, 64, shapes)


def test_a_shapes_pieces_draw_what_it_draws():
    """Each outer contour with the holes inside it: a ring and a dot are two pieces, and the pieces drawn one by one
    (nonzero, holes wound against their outer contour) cover what the even-odd shape covers, by cairosvg."""
    ring_and_dot = VectorShape([circle(20, 32, 14), circle(20, 32, 7), circle(50, 32, 6)], (0, 0, 0), "evenodd")
    got = pieces(ring_and_dot)
    assert sorted(len(p.contours) for p in got) == [1, 2] and all(p.fill_rule == "nonzero" for p in got)
    whole = rasterize_svg(VectorImage(64, 64, [ring_and_dot]).to_svg(), 64, 64)
    apart = rasterize_svg(VectorImage(64, 64, got).to_svg(), 64, 64)
    assert np.abs(whole - apart).max() < 1e-6 and whole.min() < 0.1


def test_the_missing_eyes_and_mouth_are_grown_on_top():
    picture = rasterize_svg(face(True).to_svg(), 64, 64)
    guess = face(False)  # what a model of one layer draws: the head alone
    vec, n = grown(guess, picture, read(picture), Plan())
    assert n == 4  # two eyes, the mouth and the face inside it (the trace stacks it on the mouth's disc)
    assert vec.shapes[0] == guess.shapes[0]  # the model's paths first, as they were
    before = ((rasterize_svg(guess.to_svg(), 64, 64) - picture) ** 2).mean()
    after = ((rasterize_svg(vec.to_svg(), 64, 64) - picture) ** 2).mean()
    assert after < before / 10


def test_a_hole_the_paths_filled_is_opened():
    ring = VectorImage(64, 64, [VectorShape([circle(32, 32, 24), circle(32, 32, 12, ccw=True)], (0, 0, 0), "nonzero")])
    picture = rasterize_svg(ring.to_svg(), 64, 64)
    disc = VectorImage(64, 64, [VectorShape([circle(32, 32, 24)], (0, 0, 0), "nonzero")])
    vec, n = grown(disc, picture, read(picture), Plan())
    assert n == 1 and np.allclose(vec.shapes[1].color, 1.0, atol=0.02)  # the background's colour, on top
    assert rasterize_svg(vec.to_svg(), 64, 64)[32, 32].min() > 0.9


def test_growth_keeps_to_its_bounds():
    picture = rasterize_svg(face(True).to_svg(), 64, 64)
    assert grown(face(False), picture, read(picture), Plan(grow=0))[1] == 0
    assert grown(face(False), picture, read(picture), Plan(max_paths=2))[1] == 1  # one shape + one grown
    assert grown(face(True), picture, read(picture), Plan())[1] == 0  # nothing missed: nothing pays


def test_grow_is_checked_and_idle_without_model_parts():
    with pytest.raises(ValueError, match="grow must be"):
        VectorizeOptions(grow=-1)
    assert VectorizeOptions(grow=3, parts="model").resolve().grow == 3
    assert any(n.startswith("grow does nothing") for n in VectorizeOptions(grow=3).idle({"grow"}))


def _dark_parts_kept(picture: np.ndarray, out: np.ndarray) -> float:
    """The share of a face's small dark parts (eyes: pieces of 4-80 px much darker than the skin around them)
    drawn dark."""
    import cv2

    lum = picture.mean(-1)
    n, lab, stats, _ = cv2.connectedComponentsWithStats((lum < 0.35).astype(np.uint8), connectivity=4)
    small = np.zeros(lum.shape, bool)
    for k in range(1, n):
        part = lab == k
        ring = cv2.dilate(part.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool) & ~part
        if 4 <= stats[k, cv2.CC_STAT_AREA] <= 80 and lum[ring].mean() > 0.6:
            small |= part
    assert small.sum() >= 8
    return float((out.mean(-1)[small] < 0.5).mean())


@pytest.mark.parametrize("name", ["1f467-1f3fb.png"])
def test_the_models_fitted_paths_keep_a_faces_eyes(name):
    """The emoji model's eight layers draw the girl's head and hair; fitted alone they lose her eyes, grown they
    keep them (tests/assets/emoji_test: never trained on)."""
    from im2vec_cli.vectorizing import load_model, vectorize

    picture = load_picture(ASSETS / "emoji_test" / name)
    model = load_model("emoji")
    alone, with_grown = (vectorize(picture, model, parts="model", grow=g) for g in (0, 32))
    h, w = picture.shape[:2]
    kept = [_dark_parts_kept(picture, rasterize_svg(v.to_svg(), w, h)) for v in (alone, with_grown)]
    assert kept[0] < 0.5 < 0.9 < kept[1]
    assert len(with_grown.shapes) > len(alone.shapes)
