"""vector/morph.py: grown pieces matched across a morph's two ends and interpolated."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from im2vec_cli.vector import VectorImage, VectorShape, rasterize_svg
from im2vec_cli.vector.morph import frames, match, paired
from tests.refine.test_grow import circle

ASSETS = Path(__file__).resolve().parents[1] / "assets"


def _render(shapes: list[VectorShape], size: int = 64) -> np.ndarray:
    scaled = [VectorShape([c * size for c in sh.contours], sh.color, sh.fill_rule) for sh in shapes]
    return rasterize_svg(VectorImage(size, size, scaled).to_svg(), size, size)


def test_paired_contours_keep_their_curves_and_line_up():
    """Cut into one segment count (the same curves: cairosvg draws them alike), turned one way, started near."""
    a = circle(0.3, 0.3, 0.2)  # 4 segments
    b = np.roll(circle(0.6, 0.6, 0.1, ccw=True), -6, axis=0)  # the other way round, started two segments on
    pa, pb = paired(a, b)
    assert pa.shape == pb.shape == (12, 2)
    for before, after in ((a, pa), (b, pb)):
        assert np.abs(_render([VectorShape([before], (0, 0, 0), "nonzero")])
                      - _render([VectorShape([after], (0, 0, 0), "nonzero")])).max() < 1e-6
    ka, kb = pa[0::3] - pa[0::3].mean(0), pb[0::3] - pb[0::3].mean(0)
    assert np.allclose(ka / 0.2, kb / 0.1, atol=1e-6)  # same turn, same start: anchor for anchor
    fine = paired(circle(0.5, 0.5, 0.1), subdivided(circle(0.5, 0.5, 0.2), 7))
    assert fine[0].shape == fine[1].shape == (21, 2)  # the coarser one cut to the finer one's count


def subdivided(contour: np.ndarray, segments: int) -> np.ndarray:
    import torch

    from im2vec_cli.raster.bezier import subdivide_to

    return subdivide_to(torch.from_numpy(contour), segments).numpy()


def test_eyes_match_eyes_and_what_has_no_match_shrinks_away():
    dark, red = (0.2, 0.1, 0.1), (0.9, 0.1, 0.2)
    a = [VectorShape([circle(0.3, 0.4, 0.06)], dark, "nonzero"), VectorShape([circle(0.7, 0.4, 0.06)], dark, "nonzero"),
         VectorShape([circle(0.5, 0.7, 0.1)], red, "nonzero")]
    b = [VectorShape([circle(0.72, 0.45, 0.05)], dark, "nonzero"), VectorShape([circle(0.28, 0.45, 0.05)], dark,
                                                                                 "nonzero")]
    assert sorted(match(a, b)) == sorted([(0, 1), (1, 0), (2, None)])
    got = frames(a, b, [0.0, 0.5, 1.0])
    assert np.abs(_render(got[0]) - _render(a)).max() < 1e-6
    assert np.abs(_render(got[2]) - _render(b)).max() < 0.02  # the mouth shrunk to a point: nothing drawn
    mid = _render(got[1])
    assert mid[int(0.425 * 64), int(0.29 * 64)].max() < 0.4 and mid[int(0.425 * 64), int(0.71 * 64)].max() < 0.4
    assert mid[int(0.7 * 64), int(0.5 * 64)][0] > 0.8  # the mouth half way to its centre, still red there


def _eyes(rgb: np.ndarray) -> int:
    """Small dark parts of a face: pieces of 3-80 px much darker than the skin around them."""
    import cv2

    lum = rgb.mean(-1)
    n, lab, stats, _ = cv2.connectedComponentsWithStats((lum < 0.4).astype(np.uint8), connectivity=4)
    count = 0
    for k in range(1, n):
        part = lab == k
        ring = cv2.dilate(part.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool) & ~part
        count += 3 <= stats[k, cv2.CC_STAT_AREA] <= 80 and lum[ring].mean() > 0.55
    return count


@pytest.mark.parametrize("a,b", [("1f467-1f3fb.png", "1f471-1f3fc.png")])
def test_every_frame_of_a_face_to_face_morph_keeps_its_eyes(a, b):
    """The emoji model's fitted paths alone lose both faces' eyes in every frame; with parts grown and matched
    each frame has two (tests/assets/emoji_test: never trained on)."""
    from im2vec_cli import api
    from im2vec_cli.files import load_picture

    model = api.load_model("emoji")
    ends = [load_picture(ASSETS / "emoji_test" / n) for n in (a, b)]
    counts = {g: [_eyes(rasterize_svg(f.to_svg(), 64, 64)) for f in api.interpolate(*ends, model, steps=2, grow=g)]
              for g in (0, 32)}
    assert max(counts[0]) < 2 and min(counts[32]) >= 2
