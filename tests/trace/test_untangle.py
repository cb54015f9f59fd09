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
