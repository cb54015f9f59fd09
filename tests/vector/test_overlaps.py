"""resolve_overlaps: even-odd seams filled, true holes kept; references are cairosvg renders."""

import numpy as np
import pytest
import torch

from im2vec_cli.raster.bezier import flatten_closed, polygon_area
from im2vec_cli.vector import VectorImage, VectorShape, rasterize_svg, resolve_overlaps, reverse_contour, to_svg
from tests.helpers import circle, polyline_as_cubic

W, H = 48, 40


def rect(x0, y0, x1, y1):
    return polyline_as_cubic([(x0, y0), (x1, y0), (x1, y1), (x0, y1)]).numpy()


def render(vec):
    """``(3, H, W)`` cairosvg render of the SVG a user gets."""
    return torch.from_numpy(rasterize_svg(to_svg(vec, 3), W, H)).permute(2, 0, 1)


def one_shape(contours, rule="evenodd", color=(0.0, 0.0, 0.0)):
    return VectorImage(W, H, [VectorShape([np.asarray(c) for c in contours], color, rule)])


def test_reverse_contour_flips_orientation_keeps_shape():
    c = circle(20, 18, 11, segments=5).numpy()
    r = reverse_contour(c)
    assert np.array_equal(r[0], c[0]) and np.array_equal(reverse_contour(r), c)
    area = lambda p: float(polygon_area(flatten_closed(torch.as_tensor(p), 16)))  # noqa: E731
    assert area(r) == pytest.approx(-area(c), rel=1e-9)
    assert float((render(one_shape([r], "nonzero")) - render(one_shape([c], "nonzero"))).abs().max()) < 1e-6


def test_overlap_seam_is_filled():
    # two bars meant to add up, overlapping by 1.5 px: even-odd cuts a white seam through them
    a, b = rect(6, 10, 26.75, 30), rect(25.25, 10, 42, 30)
    union = one_shape([rect(6, 10, 42, 30)], "nonzero")
    target = render(union)
    seamed = one_shape([a, b])
    assert float(((render(seamed) - target) ** 2).mean()) > 5e-3
    fixed = resolve_overlaps(seamed, target)
    assert fixed.shapes[0].fill_rule == "nonzero"
    assert float(((render(fixed) - target) ** 2).mean()) < 1e-5


@pytest.mark.parametrize("flip_inner", [False, True])
def test_true_hole_is_kept(flip_inner):
    # a ring drawn as two contours, the inner one either way round: the hole must survive
    outer, inner = circle(24, 20, 16).numpy(), circle(24, 20, 8).numpy()
    inner = reverse_contour(inner) if flip_inner else inner
    ring = one_shape([outer, inner])
    target = render(ring)  # cairo, even-odd: the intended ring
    out = resolve_overlaps(ring, target)
    assert float(((render(out) - target) ** 2).mean()) < 1e-5
    assert float(render(out)[:, 20, 24].min()) > 0.99  # the centre stays white


def test_hole_plus_seam_in_one_shape():
    # an "o" (ring) with a bar overlapping its right side: fill the overlap, keep the counter
    outer, inner = circle(18, 20, 14).numpy(), circle(18, 20, 6).numpy()
    bar = rect(30, 14, 44, 26)
    want = VectorImage(W, H, [VectorShape([outer, reverse_contour(inner), bar], (0.1, 0.2, 0.6), "nonzero")])
    target = render(want)
    got = resolve_overlaps(one_shape([outer, inner, bar], color=(0.1, 0.2, 0.6)), target)
    assert got.shapes[0].fill_rule == "nonzero"
    assert float(((render(got) - target) ** 2).mean()) < 1e-5


def test_untouched_cases():
    c = circle(24, 20, 10).numpy()
    target = render(one_shape([c]))
    single = one_shape([c])
    assert resolve_overlaps(single, target) is single  # one contour: nothing to choose
    nz = one_shape([c, rect(2, 2, 10, 10)], "nonzero")
    assert resolve_overlaps(nz, target) is nz  # already nonzero
    # the image shows the even-odd overlap as a hole (a lens cut out of two discs): kept
    lens = one_shape([circle(18, 20, 12).numpy(), circle(30, 20, 12).numpy()])
    assert resolve_overlaps(lens, render(lens)).shapes[0].fill_rule == "evenodd"
    with pytest.raises(ValueError, match="image must be"):
        resolve_overlaps(lens, target[0])


def test_large_input_is_scored_at_reduced_size():
    # a 4x larger canvas: scored at max_side, the answer is the same
    big = VectorImage(4 * W, 4 * H, [VectorShape([rect(24, 40, 107, 120), rect(101, 40, 168, 120)], (0, 0, 0), "evenodd")])
    target = torch.from_numpy(rasterize_svg(
        to_svg(VectorImage(4 * W, 4 * H, [VectorShape([rect(24, 40, 168, 120)], (0, 0, 0), "nonzero")]), 3),
        4 * W, 4 * H)).permute(2, 0, 1)
    assert resolve_overlaps(big, target, max_side=64).shapes[0].fill_rule == "nonzero"
