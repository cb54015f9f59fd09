"""Rings to cubics (``trace/fit.py``): within the tolerance, corners found, splits keep the outline."""

from __future__ import annotations

import numpy as np

from im2vec_cli.raster.curves import flatten_ring, ring_area
from im2vec_cli.trace.fit import KEEP_AREA, _fitted, corners, fit_ring, fit_rings, resample
from im2vec_cli.trace.simplify import split_segments
from im2vec_cli.vector import VectorImage, VectorShape, rasterize_svg


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


def test_a_thin_strip_keeps_its_area_at_every_tolerance():
    """A 1 px strip (a desktop icon's dark rim as ``regions.trace`` gives it: cut corners, 25 px long) fitted
    within 0.5 px fitted as one line there and back, enclosing nothing, and the rim vanished from the icon.
    Its fit keeps its area within ``KEEP_AREA`` at any tolerance; a large ring is fitted as before."""
    top, bottom = [[x + 0.5, 1.0] for x in range(4, 28)], [[x + 0.5, 2.0] for x in range(27, 3, -1)]
    strip = np.array([[3.9, 1.5], *top, [29.1, 1.5], *bottom], float)
    area = lambda c: ring_area(flatten_ring(c, 16))  # noqa: E731
    for tol in (0.25, 0.5, 1.0):
        c, _ = fit_ring(strip, tol)
        assert abs(area(c) - ring_area(strip)) <= KEEP_AREA * ring_area(strip), (tol, area(c))
    t = np.linspace(0, 2 * np.pi, 400, endpoint=False)
    disc = np.stack([32 + 20 * np.cos(t), 32 + 20 * np.sin(t)], 1)
    assert np.array_equal(fit_ring(disc, 0.5)[0], _fitted([disc], 0.5)[0][0])


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


def test_fitting_in_blocks_gives_what_fitting_at_once_gives(monkeypatch):
    """Many runs are fitted in batches of bounded memory (FIT_BLOCK padded points), shortest
    first; each run gets the cubics it gets in one batch."""
    import im2vec_cli.trace.fit as fit

    rng = np.random.default_rng(1)
    t = np.linspace(0, 2 * np.pi, 300, endpoint=False)
    rings = [np.stack([32 + r * np.cos(t) + rng.normal(0, 0.2, 300), 32 + 0.7 * r * np.sin(t)], 1)
             for r in rng.uniform(5, 25, 12)]
    at_once = fit.fit_rings(rings, 0.5)
    monkeypatch.setattr(fit, "FIT_BLOCK", 400)
    blocked = fit.fit_rings(rings, 0.5)
    for (a, fa), (b, fb) in zip(at_once, blocked):
        assert a.shape == b.shape and np.allclose(a, b, atol=1e-6) and np.array_equal(fa, fb)


def test_rings_fitted_together_are_fitted_as_each_alone():
    """``fit_rings`` plans every ring's runs at once (corners, sharpened corners, tangents: one
    pass over all of them), each run bit for bit as the ring's plan alone; and each ring comes
    out as ``fit_ring`` of it alone (to rounding: batches are padded to their longest run):
    round rings, polygons with corners, tiny rings, a ring whose corners are its only points."""
    import im2vec_cli.trace.fit as fit

    rng = np.random.default_rng(5)
    t = np.linspace(0, 2 * np.pi, 200, endpoint=False)
    rings = [np.stack([40 + r * np.cos(t) + rng.normal(0, 0.3, 200), 40 + 0.6 * r * np.sin(t)], 1)
             for r in rng.uniform(1, 30, 6)]
    for k in range(3, 9):
        ang = np.sort(rng.uniform(0, 2 * np.pi, k))
        rings.append(np.stack([40 + 20 * np.cos(ang), 40 + 20 * np.sin(ang)], 1))
    rings += [np.array([[0, 0], [1, 0], [1, 1]], float), np.array([[8, 8], [56, 8], [56, 20], [20, 20], [20, 56], [8, 56]],
                                                                  float)]
    for plan, ring in zip(fit._plans(rings), rings):
        alone = fit._plans([ring])[0]
        assert len(plan) == len(alone)
        for run, run_alone in zip(plan, alone):
            assert all(np.array_equal(a, b) for a, b in zip(run, run_alone))
    together = fit_rings(rings, 0.5)
    for ring, (c, sharp) in zip(rings, together):
        alone, sharp_alone = fit_ring(ring, 0.5)
        assert c.shape == alone.shape and np.allclose(c, alone, atol=1e-6) and np.array_equal(sharp, sharp_alone)
    assert sum(f.sum() for _, f in together) > 20  # corners were found and kept

