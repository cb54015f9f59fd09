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


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_svg_text_is_svgwrites_byte_for_byte(seed):
    """The writer builds with ElementTree the tree svgwrite's Drawing builds (its import is a tenth of a
    one-picture call): svgwrite, the reference, writes the same text."""
    svgwrite = pytest.importorskip("svgwrite")
    from im2vec_cli.vector.svg import contour_d, hex_color, number_text

    img = random_image(seed)
    img.shapes.append(type(img.shapes[0])(contours=[], color=(1.0, 1.0, 1.0)))  # an empty shape: not written
    for decimals in (0, 2, 3):
        w, h = number_text(img.width, decimals), number_text(img.height, decimals)
        dwg = svgwrite.Drawing(size=(w, h), profile="full", debug=False)
        dwg["viewBox"] = f"0 0 {w} {h}"
        for shape in (s for s in img.shapes if s.contours):
            dwg.add(dwg.path(d=" ".join(contour_d(c, decimals) for c in shape.contours), fill=hex_color(shape.color),
                             fill_rule=shape.fill_rule, stroke="none"))
        assert to_svg(img, decimals) == dwg.tostring()


def test_to_tensors_pads_segments_without_changing_shape():
    img = random_image()
    img.shapes[0].contours[0] = img.shapes[0].contours[0][:6]  # 2 segments, others have 4
    pts, cols, sidx = to_tensors(img)
    assert pts.shape == (3, 12, 2) and sidx.tolist() == [0, 1, 1]
    a = rasterize_svg(to_svg(img, 4), 64, 48)
    b = rasterize_svg(to_svg(from_tensors(pts, cols, size=(48, 64), shape_index=sidx, fill_rule="evenodd"), 4), 64, 48)
    assert np.abs(a - b).max() < 0.02


@pytest.mark.parametrize("bad", ["<svg", "<svg xmlns='http://www.w3.org/2000/svg'><path d='M 0 0 L 1 1' fill='url(#g)'/></svg>"])
def test_bad_svg_is_a_one_line_error(bad):
    with pytest.raises(InputError):
        from_svg(bad)


NS = 'xmlns="http://www.w3.org/2000/svg" xmlns:xlink="http://www.w3.org/1999/xlink"'
FEATURES = {  # SVGs a user has, read by the reader and checked against cairosvg's render of the original
    "relative commands": f'<svg {NS} viewBox="0 0 20 20"><path d="m 2 2 l 12 0 l 0 12 z m 3 5 h 4 v 4 h -4 z" '
                         'fill-rule="evenodd"/></svg>',
    "H V S Q T": f'<svg {NS} viewBox="0 0 20 20"><path d="M2 2H16V6C14 8 12 8 10 6S6 4 4 8Q6 14 10 12T18 16V18H2Z"/></svg>',
    "arcs": f'<svg {NS} viewBox="0 0 20 20"><path d="M3 10 A7 5 20 1 1 17 10 a3 3 0 0 0 -14 0 Z" fill="#c30"/></svg>',
    "open subpaths are filled closed": f'<svg {NS} viewBox="0 0 20 20"><path d="M2 2 L18 2 L18 18 M4 10 L8 10 L8 16"/></svg>',
    "drawing after Z restarts at the subpath start": f'<svg {NS} viewBox="0 0 20 20">'
                                                     '<path d="M5 5 L15 5 L15 15 Z L5 15 L2 10 Z"/></svg>',
    "transforms and groups": f'<svg {NS} viewBox="0 0 40 20"><g transform="translate(20 0) rotate(15 10 10)" '
                             'fill="#0a4"><rect x="4" y="4" width="10" height="8" rx="2"/></g>'
                             '<g transform="matrix(1 0 0.3 1 0 0)"><circle cx="8" cy="10" r="5"/></g></svg>',
    "shapes": f'<svg {NS} viewBox="0 0 40 20"><ellipse cx="8" cy="10" rx="6" ry="3" fill="navy"/>'
              '<polygon points="20,2 30,18 14,14" fill="rgb(200,100,0)"/><polyline points="32,2 38,2 38,8"/></svg>',
    "use and defs": f'<svg {NS} viewBox="0 0 20 20"><defs><path id="t" d="M0 0 L6 0 L3 5 Z"/></defs>'
                    '<use xlink:href="#t" x="2" y="2"/><use xlink:href="#t" x="10" y="12" fill="#f0f"/></svg>',
    "viewBox offset and scale": f'<svg {NS} width="40" height="20" viewBox="-5 -5 20 10">'
                                '<path d="M-4 -4 L10 -4 L10 4 Z" style="fill:#123456"/></svg>',
    "fill none is skipped": f'<svg {NS} viewBox="0 0 20 20"><rect width="20" height="20" fill="none"/>'
                            '<circle cx="10" cy="10" r="4"/></svg>',
    "strokes: round caps and joins": f'<svg {NS} viewBox="0 0 24 24"><polyline points="3 12 9 18 21 6" fill="none" '
                                     'stroke="#000" stroke-width="2" stroke-linecap="round" stroke-linejoin="round"/></svg>',
    "strokes over fills": f'<svg {NS} viewBox="0 0 24 24"><rect x="4" y="4" width="16" height="12" rx="3" fill="#fc0" '
                          'stroke="#036" stroke-width="2"/></svg>',
    "strokes under a non-uniform scale": f'<svg {NS} width="48" height="48" viewBox="0 0 24 24"><g transform="scale(1 0.5)'
                                         ' translate(0 12)"><circle cx="12" cy="12" r="8" fill="none" stroke="red" '
                                         'stroke-width="3"/></g></svg>',
    "strokes: miter joins, butt caps, dashes": f'<svg {NS} viewBox="0 0 24 24"><path d="M4 20 L12 4 L20 20" fill="none" '
                                               'stroke="black" stroke-width="3" stroke-miterlimit="10"/><line x1="2" '
                                               'y1="22" x2="22" y2="22" stroke="#080" stroke-dasharray="3 2"/></svg>',
    "a stroked icon (Lucide's rotate-cw)": f'<svg {NS} width="24" height="24" viewBox="0 0 24 24" fill="none" '
                                           'stroke="currentColor" stroke-width="2" stroke-linecap="round" '
                                           'stroke-linejoin="round"><path d="M21 12a9 9 0 1 1-9-9c2.52 0 4.93 1 6.74 '
                                           '2.74L21 8"/><path d="M21 3v5h-5"/></svg>',
}


@pytest.mark.parametrize("name", list(FEATURES))
def test_reader_agrees_with_cairo(name):
    """Our reading of an SVG, written back and rendered by cairosvg, looks like cairosvg's
    render of the SVG itself (at 4x: only antialiasing of the cubic approximations differs)."""
    svg = FEATURES[name]
    img = from_svg(svg)
    w, h = int(img.width * 4), int(img.height * 4)
    ours = rasterize_svg(to_svg(img, 3), w, h)
    ref = rasterize_svg(svg, w, h)
    assert img.num_paths > 0
    assert np.abs(ours - ref).mean() < 4e-3, np.abs(ours - ref).mean()
    assert (np.abs(ours - ref).max(-1) > 0.5).mean() < 2e-3  # no region drawn differently


@pytest.mark.parametrize("svg, why", [
    (f'<svg {NS} viewBox="0 0 9 9"><path d="M1 1 L8 1 L8 8 Z" stroke="red" stroke-opacity="0.5"/></svg>',
     "semi-transparent strokes"),
    (f'<svg {NS} viewBox="0 0 9 9"><path d="M1 1 L8 1 L8 8 Z" stroke="url(#g)"/></svg>', "gradient and pattern strokes"),
    (f'<svg {NS} viewBox="0 0 9 9"><defs><radialGradient id="g"/></defs><circle r="3" cx="4" cy="4" fill="url(#g)"/>'
     '</svg>', "gradient"),
    (f'<svg {NS} viewBox="0 0 9 9"><circle r="3" cx="4" cy="4" fill-opacity="0.5"/></svg>', "semi-transparent"),
    (f'<svg {NS} viewBox="0 0 9 9"><circle r="3" cx="4" cy="4" opacity="0.5"/></svg>', "opacity"),
    (f'<svg {NS} viewBox="0 0 9 9"><text>a</text></svg>', "text"),
    (f'<svg {NS} viewBox="0 0 9 9"><path d="M1 1 L1e300 1 L8 8 Z"/></svg>', "not finite or beyond"),
    (f'<svg {NS} viewBox="0 0 0 9"><path d="M1 1 L8 1 L8 8 Z"/></svg>', "viewBox"),
])
def test_what_the_reader_refuses_it_names(svg, why):
    with pytest.raises(InputError, match=why):
        from_svg(svg)


def test_a_command_after_z_starts_a_subpath_at_the_start_point():
    # SVG: after closepath the current point is the subpath's start, where the next one begins
    cs = parse_d("M 5 5 C 6 5 7 5 8 5 C 8 6 8 7 8 8 Z C 7 8 6 8 5 8 Z L 9 9 L 5 9 Z")
    assert [c.shape for c in cs] == [(9, 2), (6, 2), (9, 2)]
    assert all(np.array_equal(c[0], [5, 5]) for c in cs)
    assert np.array_equal(cs[1][3], [5, 8])
    assert parse_d("M 1 1 Z M 5 5 L 8 5 L 8 8 Z")[0].shape == (9, 2) and len(parse_d("M 1 1 Z")) == 0


def test_an_open_subpath_is_closed_as_svg_fills_it():
    cs = parse_d("M 2 2 C 5 1 9 1 12 2 C 14 6 14 10 12 14 C 8 15 4 15 2 14 M 5 5 L 8 5 L 8 8 Z")
    assert [c.shape for c in cs] == [(12, 2), (9, 2)]  # the first gained its closing line 2 14 -> 2 2
    assert np.allclose(cs[0][9], [2, 14]) and np.allclose(cs[0][0], [2, 2])
