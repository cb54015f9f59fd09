from xml.etree import ElementTree

import numpy as np
import pytest
import torch

from im2vec_cli.errors import InputError
from im2vec_cli.vector import from_svg, from_tensors, parse_d, rasterize_svg, to_svg, to_tensors


def random_image(seed=0):
    g = torch.Generator().manual_seed(seed)
    pts = torch.rand(3, 12, 2, generator=g, dtype=torch.float64)
    cols = torch.rand(2, 3, generator=g, dtype=torch.float64)
    return from_tensors(pts, cols, size=(48, 64), shape_index=[0, 1, 1], fill_rule="evenodd")


def test_round_trip_is_exact_to_printed_precision():
    img = random_image()
    text = to_svg(img, decimals=3)
    back = from_svg(text)
    assert to_svg(back, decimals=3) == text
    for s0, s1 in zip(img.shapes, back.shapes):
        for c0, c1 in zip(s0.contours, s1.contours):
            assert np.array_equal(np.round(c0, 3), c1)
        assert s1.fill_rule == "evenodd"


def test_svg_structure_and_cairo_render():
    text = to_svg(random_image(), decimals=2)
    root = ElementTree.fromstring(text)
    assert root.get("viewBox") == "0 0 64 48"
    paths = [e for e in root.iter() if e.tag.endswith("path")]
    assert len(paths) == 2
    for p in paths:
        d = p.get("d")
        assert d.startswith("M ") and d.endswith("Z") and set(d.split()) & {"C"}
        assert p.get("fill").startswith("#") and p.get("fill-rule") == "evenodd"
    assert paths[1].get("d").count("M") == 2  # two contours, one shape
    arr = rasterize_svg(text, 64, 48)
    assert arr.shape == (48, 64, 3) and arr.min() < 0.9


def test_to_tensors_pads_segments_without_changing_shape():
    img = random_image()
    img.shapes[0].contours[0] = img.shapes[0].contours[0][:6]  # 2 segments, others have 4
    pts, cols, sidx = to_tensors(img)
    assert pts.shape == (3, 12, 2) and sidx.tolist() == [0, 1, 1]
    a = rasterize_svg(to_svg(img, 4), 64, 48)
    b = rasterize_svg(to_svg(from_tensors(pts, cols, size=(48, 64), shape_index=sidx, fill_rule="evenodd"), 4), 64, 48)
    assert np.abs(a - b).max() < 0.02


@pytest.mark.parametrize("bad", ["<svg", "<svg xmlns='http://www.w3.org/2000/svg'><path d='M 0 0 L 1 1'/></svg>"])
def test_bad_svg_is_a_one_line_error(bad):
    with pytest.raises(InputError):
        from_svg(bad)


def test_a_command_after_z_starts_a_subpath_at_the_start_point():
    # SVG: after closepath the current point is the subpath's start, where the next one begins
    # (a case the fuzz test found: the reader used to return a contour of 5 points)
    cs = parse_d("M 5 5 C 6 5 7 5 8 5 C 8 6 8 7 8 8 Z C 7 8 6 8 5 8 Z L 9 9 L 5 9 Z")
    assert [c.shape for c in cs] == [(9, 2), (6, 2), (9, 2)]
    assert all(np.array_equal(c[0], [5, 5]) for c in cs)
    assert np.array_equal(cs[1][3], [5, 8])
    assert parse_d("M 1 1 Z M 5 5 L 8 5 L 8 8 Z")[0].shape == (9, 2) and len(parse_d("M 1 1 Z")) == 0


@pytest.mark.parametrize("d", ["C 1 1 2 2 3 3 Z", "L 1 1 Z"])
def test_path_data_without_a_first_moveto_is_an_input_error(d):
    with pytest.raises(InputError, match="must start with M"):
        parse_d(d)


def test_an_open_subpath_before_the_next_moveto_is_an_input_error():
    # another fuzz find: the open subpath was kept, ending on its last anchor (10 points)
    with pytest.raises(InputError, match="open subpath"):
        parse_d("M 2 2 C 5 1 9 1 12 2 C 14 6 14 10 12 14 C 8 15 4 15 2 14 M 5 5 L 8 5 L 8 8 Z")
