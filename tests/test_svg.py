from xml.etree import ElementTree

import numpy as np
import pytest
import torch

from im2vec_cli.errors import InputError
from im2vec_cli.svg import from_svg, from_tensors, rasterize_svg, to_svg, to_tensors


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
