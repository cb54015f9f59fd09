"""No crossings (``trace/untangle.py``)."""

from __future__ import annotations

import numpy as np

from im2vec_cli.trace.untangle import crosses, untangle
from im2vec_cli.vector import VectorImage, VectorShape
from tests.trace.outlines import check_clean_svg, ink


def _lines(pts):
    """A closed contour of straight cubics through ``pts``."""
    pts = np.asarray(pts, float)
    nxt = np.roll(pts, -1, 0)
    return np.concatenate([np.stack([p, p + (q - p) / 3, p + 2 * (q - p) / 3]) for p, q in zip(pts, nxt)])


def test_untangle_removes_crossings_and_keeps_the_fill():
    """A contour folded into a small loop at a corner (what a polished corner can do) is found
    crossing and replaced by its exact outline: nothing crosses, the render stays the same
    but for the loop's pin hole."""

    square = _lines([[10, 10], [50, 10], [50, 50], [10, 50]])
    looped = _lines([[10, 10], [50, 10], [51.5, 11.5], [49, 12.5], [50, 9], [50, 50], [10, 50]])  # a loop at a corner
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


def test_a_shape_path_ops_fail_on_is_kept_not_a_crash(monkeypatch):
    """Skia's path ops can fail (PathOpsError: nearly coincident curves in a scanned page): the
    crossing shape is then kept as it is, and the picture still gets its SVG."""
    import pathops

    looped = VectorShape([_lines([[10, 10], [50, 10], [51.5, 11.5], [49, 12.5], [50, 9], [50, 50], [10, 50]])],
                         (0, 0, 0), "nonzero")

    def fail(*a, **k):
        raise pathops.PathOpsError("operation did not succeed")

    monkeypatch.setattr(pathops, "simplify", fail)
    out = untangle(VectorImage(64, 64, [looped]))
    assert len(out.shapes) == 1 and np.array_equal(out.shapes[0].contours[0], looped.contours[0])


# A 32 px key's 1 px frame as polished (Tango's accessories-character-map at 32 px, issue 69): the outer contour
# and the hole's, nearly coincident and crossing. Skia's simplify under nonzero returned the frame's box filled.
FRAME = [[4.78, 28.32], [4.38, 28.2], [4.71, 27.18], [4.18, 26.98], [3.68, 26.79], [3.35, 26.37], [3.72, 25.13],
         [3.94, 24.41], [3.95, 19.28], [3.86, 14.18], [3.77, 9.53], [3.69, 4.55], [4.33, 4.08], [4.7, 3.81],
         [4.74, 3.17], [5.26, 3.16], [5.94, 3.14], [5.98, 2.96], [5.96, 2.54], [5.94, 2.19], [11.52, 2.59],
         [16.66, 2.45], [22.57, 2.3], [26.86, 2.34], [26.93, 2.92], [26.96, 3.2], [27.71, 3.59], [28.09, 4.03],
         [28.37, 4.34], [28.17, 4.69], [28.15, 5.12], [28.12, 5.75], [28.43, 11.24], [28.41, 17.29], [28.39, 22.9],
         [28.6, 28.13], [28.33, 28.2], [26.98, 28.54], [22.36, 29.24], [17.17, 29.15], [10.67, 29.04], [5.92, 28.65]]
HOLE = [[28.39, 4.39], [27.67, 3.99], [27.05, 3.9], [26.89, 3.46], [26.74, 3.07], [26.42, 2.84], [26.08, 2.84],
        [23.92, 2.86], [18.76, 3.0], [13.77, 2.9], [8.8, 2.81], [4.64, 2.37], [5.16, 2.7], [5.34, 2.82], [4.81, 3.35],
        [4.46, 3.63], [4.1, 3.92], [3.76, 4.17], [3.59, 4.23], [3.11, 4.41], [3.45, 9.95], [3.46, 15.0],
        [3.47, 21.19], [3.35, 26.97], [3.69, 27.19], [4.36, 27.61], [5.93, 28.51], [8.54, 28.39], [10.57, 28.3],
        [13.13, 28.42], [14.36, 28.46], [16.81, 28.55], [18.83, 28.34], [20.72, 28.45], [22.93, 28.57],
        [25.02, 28.29], [26.61, 28.1], [26.89, 28.07], [27.37, 27.89], [27.55, 27.47], [27.8, 26.93], [27.86, 26.59],
        [27.87, 26.54], [28.78, 22.52], [28.52, 19.4], [28.44, 15.71], [28.35, 11.92], [28.93, 7.54]]


def test_a_thin_frame_path_ops_fill_in_keeps_its_hole():
    """Path ops fail without a word on the polished 1 px frame (its box comes back filled): that outline is
    refused (``fills_alike``) and the shape kept as it is, its hole open, as cairo draws it."""
    import pathops

    from im2vec_cli.trace.untangle import fills_alike
    from im2vec_cli.vector import skia

    frame = [np.asarray(FRAME, float), np.asarray(HOLE, float)]
    assert crosses(frame)
    filled = skia.contours(pathops.simplify(skia.to_path([skia.contour_chain(c) for c in frame]), fix_winding=True))
    assert not fills_alike(frame, "nonzero", filled)  # what path ops give: the box filled
    vec = VectorImage(32, 32, [VectorShape(frame, (0, 0, 0), "nonzero")])
    out = untangle(vec)
    before, after = ink(vec.to_svg(), 4), ink(out.to_svg(), 4)
    assert not before[40:88, 40:88].any()  # cairo draws a frame: the middle is empty
    assert (before != after).sum() == 0


def test_fills_alike_agrees_with_matplotlib_on_points_inside():
    """``_winding``'s inside points against matplotlib's ``Path.contains_points`` (an independent
    point-in-polygon test) on a square with a square hole, under both rules, and ``fills_alike``
    tells the holed square from the plain one."""
    from matplotlib.path import Path as MplPath

    from im2vec_cli.raster.curves import flatten_ring
    from im2vec_cli.trace.untangle import _winding, fills_alike

    outer, hole = _lines([[0, 0], [40, 0], [40, 40], [0, 40]]), _lines([[10, 10], [10, 30], [30, 30], [30, 10]])
    same_way = _lines([[10, 10], [30, 10], [30, 30], [10, 30]])
    pts = np.random.default_rng(0).uniform(-5, 45, (500, 2))
    in_outer, in_inner = (MplPath(flatten_ring(c, 8)).contains_points(pts) for c in (outer, hole))
    for inner in (hole, same_way):
        wind = _winding(pts, [flatten_ring(c, 8) for c in (outer, inner)])
        for rule, inside in (("evenodd", wind % 2 == 1), ("nonzero", wind != 0)):
            holed = rule == "evenodd" or inner is hole  # nonzero with the inner contour turning the outer's way: filled
            assert np.array_equal(inside, in_outer & ~in_inner if holed else in_outer), (rule, inner is hole)
    assert fills_alike([outer, hole], "nonzero", [outer, hole])
    assert not fills_alike([outer, hole], "nonzero", [outer])
    assert fills_alike([outer, same_way], "evenodd", [outer, hole]) and not fills_alike([outer, same_way], "nonzero",
                                                                                      [outer, hole])


def _crosses_everywhere(contours, samples=16) -> bool:
    """The reference: every pair of polyline edges tested at once (not neighbours along one contour)."""
    from im2vec_cli.raster.curves import flatten_ring

    polys = [flatten_ring(c, samples) for c in contours]
    a = np.concatenate(polys)
    d = np.concatenate([np.roll(p, -1, 0) for p in polys]) - a
    who = np.concatenate([np.full(len(p), i) for i, p in enumerate(polys)])
    k = np.concatenate([np.arange(len(p)) for p in polys])
    n = np.concatenate([np.full(len(p), len(p)) for p in polys])

    def cross(u, v):
        return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]

    r = a[None] - a[:, None]
    den = cross(d[:, None], d[None])
    with np.errstate(divide="ignore", invalid="ignore"):
        t, u = cross(r, d[None]) / den, cross(r, d[:, None]) / den
    hit = (np.abs(den) > 1e-12) & (t > 1e-9) & (t < 1 - 1e-9) & (u > 1e-9) & (u < 1 - 1e-9)
    gap = np.abs(k[:, None] - k[None])
    neighbours = (who[:, None] == who[None]) & ((gap <= 1) | (gap >= n[:, None] - 1))
    return bool((hit & ~neighbours).any())


def _random_shapes(rng, count: int, spread: float = 0) -> list[list[np.ndarray]]:
    """``count`` random sets of 1-3 contours: long wavy rings that fold back on themselves far
    along, short ones, rings inside rings, touching rings (set ``k`` moved ``spread`` x (k mod 5)
    px right and down)."""
    shapes = []
    for trial in range(count):
        contours = []
        for _ in range(rng.integers(1, 4)):
            n = int(rng.choice([3, 5, 12, 30]))
            ang = np.sort(rng.uniform(0, 2 * np.pi, n))
            r = rng.uniform(5, 30) * (1 + rng.uniform(-0.6, 0.6, n) * (trial % 3 > 0))
            c = rng.uniform(20, 60, 2) + spread * (trial % 5)
            contours.append(_lines(np.stack([c[0] + r * np.cos(ang), c[1] + r * np.sin(ang)], 1)))
        shapes.append(contours)
    return shapes


def test_crosses_agrees_with_testing_every_pair():
    """``crosses`` (near edges at once, far blocks by their boxes) against every pair of edges, on
    300 random contour sets: long wavy rings that fold back on themselves far along, short ones,
    rings inside rings, touching rings; about half of them cross."""
    found = []
    for trial, contours in enumerate(_random_shapes(np.random.default_rng(7), 300)):
        got, want = crosses(contours), _crosses_everywhere(contours)
        assert got == want, trial
        found.append(want)
    assert 0.2 < np.mean(found) < 0.8


def test_crosses_each_agrees_with_every_pair_in_any_bands_and_blocks(monkeypatch):
    """``crosses_each`` of many shapes at once (one sweep along x within bands of every shape)
    gives, for each, what testing every pair of its edges gives, whatever the bands' height
    (``SWEEP_BAND`` 1 px, 8, 1000: one band), in blocks of a few pairs (``SWEEP_PAIRS`` 64) and a
    few shapes at a time (``SWEEP_CUBICS`` 10)."""
    import sys

    untangle_module = sys.modules["im2vec_cli.trace.untangle"]
    shapes = _random_shapes(np.random.default_rng(11), 120, spread=200)  # side by side and on top of each other
    shapes.insert(7, [])  # an empty shape among them
    want = np.array([bool(s) and _crosses_everywhere(s) for s in shapes])
    assert 0.2 < want.mean() < 0.8
    for band, pairs, cubics in ((8, 1 << 22, 1 << 12), (1, 1 << 22, 1 << 12), (1000, 1 << 22, 1 << 12), (8, 64, 1 << 12),
                                (8, 1 << 22, 10)):
        monkeypatch.setattr(untangle_module, "SWEEP_BAND", band)
        monkeypatch.setattr(untangle_module, "SWEEP_PAIRS", pairs)
        monkeypatch.setattr(untangle_module, "SWEEP_CUBICS", cubics)
        assert np.array_equal(untangle_module.crosses_each(shapes), want), (band, pairs, cubics)


def test_a_shape_without_contours_crosses_nothing():
    """An empty shape (or an empty contour) is untangled as it is, not a ``ValueError`` (issue 69:
    two real 512 px icons failed with "need at least one array to concatenate")."""
    assert not crosses([]) and not crosses([np.zeros((0, 2))])
    vec = VectorImage(8, 8, [VectorShape([], (0, 0, 0), "nonzero")])
    assert untangle(vec).shapes[0].contours == []


def _crosses_brute(contours, samples=16):
    """Every pair of polyline edges tested: the reference ``crosses`` must agree with."""
    from im2vec_cli.raster.curves import flatten_ring

    edges = []
    for k, c in enumerate(contours):
        p = flatten_ring(c, samples)
        edges += [(k, j, len(p), p[j], p[(j + 1) % len(p)]) for j in range(len(p))]
    for k1, j1, n1, a1, b1 in edges:
        for k2, j2, _, a2, b2 in edges:
            gap = abs(j1 - j2)
            if k1 == k2 and (gap <= 1 or gap >= n1 - 1):
                continue
            d1, d2, r = b1 - a1, b2 - a2, a2 - a1
            den = d1[0] * d2[1] - d1[1] * d2[0]
            if abs(den) <= 1e-12:
                continue
            t = (r[0] * d2[1] - r[1] * d2[0]) / den
            u = (r[0] * d1[1] - r[1] * d1[0]) / den
            if 1e-9 < t < 1 - 1e-9 and 1e-9 < u < 1 - 1e-9:
                return True
    return False


def test_crosses_agrees_with_every_pair_tested():
    rng = np.random.default_rng(7)
    seen = set()
    for _ in range(40):
        contours = [np.cumsum(rng.normal(size=(3 * int(rng.integers(1, 4)), 2)), 0) * 3 + rng.uniform(0, 40, 2)
                    for _ in range(int(rng.integers(1, 4)))]
        want = _crosses_brute(contours)
        assert crosses(contours) == want
        seen.add(want)
    assert seen == {True, False}


def test_a_shape_of_many_contours_is_untangled_by_its_groups(monkeypatch):
    """A page is one shape of thousands of letters, a few of them tangled: only the groups of
    contours whose boxes meet and cross are outlined by path ops (a page of text 21 s -> 7 s);
    the other contours are kept as they were, point for point, and the fill is the same."""
    import pathops

    letters = [_lines([[x, 4], [x + 5, 4], [x + 5, 12], [x, 12]]) for x in range(2, 60, 7)]  # 9 squares apart
    hole = _lines([[3, 6], [3, 10], [6, 10], [6, 6]])[::-1]  # a hole in the first, wound the other way
    looped = _lines([[10, 30], [50, 30], [51.5, 31.5], [49, 32.5], [50, 29], [50, 50], [10, 50]])
    vec = VectorImage(64, 64, [VectorShape([*letters, hole, looped], (0, 0, 0), "nonzero")])
    sizes = []
    real = pathops.simplify
    monkeypatch.setattr(pathops, "simplify", lambda path, **k: sizes.append(len(list(path.segments))) or real(path, **k))
    (out,) = untangle(vec).shapes
    assert len(sizes) == 1 and sizes[0] <= 10  # the looped contour alone went through path ops
    assert all(any(np.array_equal(c, k) for k in out.contours) for c in [*letters, hole])
    assert not crosses(out.contours)
    check_clean_svg(VectorImage(64, 64, [out]).to_svg())
    assert (ink(vec.to_svg(), 4) != ink(VectorImage(64, 64, [out]).to_svg(), 4)).sum() <= 16  # the loop's pin hole


def test_groups_join_the_contours_whose_boxes_meet():
    """``_groups``: contours whose boxes overlap, even through a third, share a group; a contour
    inside another's box (a hole, a letter's counter) is in its group; contours far apart are not."""
    from im2vec_cli.trace.untangle import _groups

    a = _lines([[0, 0], [10, 0], [10, 10], [0, 10]])
    inner = _lines([[3, 3], [6, 3], [6, 6], [3, 6]])
    b = _lines([[9.5, 20], [20, 20], [20, 30], [9.5, 30]])  # overlaps c only
    c = _lines([[18, 25], [40, 25], [40, 40], [18, 40]])
    far = _lines([[60, 60], [70, 60], [70, 70], [60, 70]])
    assert _groups([a, b, inner, far, c]) == [[0, 2], [1, 4], [3]]
