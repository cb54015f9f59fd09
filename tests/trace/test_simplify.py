"""Fewer segments for the same outline (``trace/simplify.py``), checked on cairosvg renders and dense samples."""

from __future__ import annotations

import numpy as np

from im2vec_cli.evaluate import outline_iou, svg_mask
from im2vec_cli.raster.bezier import line_controls
from im2vec_cli.trace import simplify, simplify_contour
from im2vec_cli.vector import VectorImage, VectorShape, to_svg
from tests.helpers import circle


def _as_image(contours, w=64, h=64):
    return VectorImage(float(w), float(h), [VectorShape([np.asarray(c) for c in contours], (0, 0, 0), "evenodd")])


def test_simplify_merges_a_finely_split_circle():
    """16 segments on a circle of radius 20 px -> at most 5, outline within 0.5% IoU (cairosvg at 4x)."""
    c = circle(32, 32, 20, segments=16).numpy()
    before = _as_image([c])
    after = simplify(before, 0.05)
    n = after.num_segments
    assert 4 <= n <= 5
    iou = outline_iou(svg_mask(to_svg(before, 4), 256), svg_mask(to_svg(after, 4), 256))
    assert iou > 0.995


def test_simplify_joins_collinear_lines_and_keeps_corners():
    """A square drawn with 3 straight segments per side becomes 4 segments, same corners."""
    corners = np.array([[0, 0], [30, 0], [30, 30], [0, 30]], float) + 10
    pts = []
    for i in range(4):
        a, b = corners[i], corners[(i + 1) % 4]
        for j in range(3):
            p, q = a + (b - a) * j / 3, a + (b - a) * (j + 1) / 3
            pts += [p, *line_controls(p, q)]
    out = simplify_contour(np.array(pts), 0.05)
    assert len(out) == 12
    anchors = {tuple(np.round(p, 6)) for p in out[0::3]}
    assert anchors == {tuple(c) for c in corners}


def _dense(contour, n=200):
    seg = contour[(np.arange(len(contour) // 3)[:, None] * 3 + np.arange(4)) % len(contour)]  # (S, 4, 2)
    t = np.linspace(0, 1, n)[None, :, None]
    u = 1 - t
    return (u**3 * seg[:, None, 0] + 3 * u * u * t * seg[:, None, 1] + 3 * u * t * t * seg[:, None, 2]
            + t**3 * seg[:, None, 3]).reshape(-1, 2)


def test_simplify_stays_within_tolerance_of_the_original():
    """Random smooth-ish contours: every point of the original lies within ~tol of the result
    (checked on dense samples, independent of the merge's own error measure)."""
    rng = np.random.default_rng(0)
    tol = 0.3
    for _ in range(20):
        n = int(rng.integers(3, 12))
        ang = np.sort(rng.uniform(0, 2 * np.pi, 3 * n))
        r = rng.uniform(8, 25, 3 * n)
        c = np.stack([32 + r * np.cos(ang), 32 + r * np.sin(ang)], 1)
        out = simplify_contour(c, tol)
        assert 2 <= len(out) // 3 <= n and len(out) % 3 == 0
        a, b = _dense(c), _dense(out)
        dist = np.sqrt(((a[:, None] - b[None]) ** 2).sum(-1)).min(1)
        assert dist.max() < tol * 1.5, dist.max()  # samples between the measured ones may stray a little
    assert simplify(_as_image([c]), 0.0).num_segments == n  # tolerance 0: unchanged


def test_fit_merges_is_fit_merge_row_by_row_to_the_bit():
    """The batched first merges of ``simplify_contour`` give each pair ``fit_merge``'s cubic and error exactly."""
    from im2vec_cli.raster.curves import cubic_at
    from im2vec_cli.trace.simplify import SAMPLES, fit_merge, fit_merges

    rng = np.random.default_rng(0)
    t = np.linspace(0, 1, SAMPLES, endpoint=False)
    pairs = []
    for i in range(200):
        a, b = rng.normal(size=(4, 2)) * 10, rng.normal(size=(4, 2)) * 10
        b[0] = a[3]
        if i % 10 == 0:
            a[:] = a[0]  # a collapsed segment: no tangent
        n = SAMPLES if i % 3 else SAMPLES * 2  # two lengths: two batches
        pairs.append((a, b, np.concatenate([cubic_at(a, t), cubic_at(b, np.linspace(0, 1, n, endpoint=False)), b[3:4]])))
    for (ctrl, err), pair in zip(fit_merges(pairs), pairs):
        want_ctrl, want_err = fit_merge(*pair)
        assert np.array_equal(ctrl, want_ctrl) and (err == want_err or np.isinf(err) and np.isinf(want_err))


def test_contours_simplified_together_come_out_as_each_alone():
    """``simplify_contours`` merges every contour's segments in step, fitting each round's
    merges of all of them together; each contour comes out bit for bit as it does alone
    (``simplify_contour``): circles finely split, a square of collinear thirds, a wavy ring
    that keeps some of its segments, a contour already at ``min_segments``."""
    from im2vec_cli.trace.simplify import simplify_contours

    rng = np.random.default_rng(3)
    contours = [circle(32, 32, r, segments=n).numpy() for r, n in ((20, 16), (6, 9), (30, 24))]
    side = [np.array(p, float) for p in ((8, 8), (20, 8), (32, 8), (44, 8), (44, 20), (44, 32), (44, 44), (32, 44),
                                         (20, 44), (8, 44), (8, 32), (8, 20))]
    contours.append(np.concatenate([np.stack([a, *line_controls(a, b)]) for a, b in zip(side, side[1:] + side[:1])]))
    wavy = circle(32, 32, 18, segments=20).numpy()
    contours.append(wavy + rng.normal(0, 0.4, wavy.shape))
    contours.append(circle(10, 10, 5, segments=2).numpy())
    together = simplify_contours(contours, 0.1)
    assert [len(c) for c in together] != [len(c) for c in contours]  # merges were made
    for c, t in zip(contours, together):
        assert np.array_equal(t, simplify_contour(c, 0.1))


def _scan_simplify(points: np.ndarray, tol: float, min_segments: int = 2) -> np.ndarray:
    """The reference: every round, every pair of neighbours scanned in order, the first of the
    cheapest merged (the O(S^2) way ``simplify_contours`` did it before its heap)."""
    from im2vec_cli.raster.curves import cubic_at, segments_of
    from im2vec_cli.trace.simplify import SAMPLES, fit_merge

    t = np.linspace(0, 1, SAMPLES, endpoint=False)
    segs = [(c, cubic_at(c, t)) for c in segments_of(np.asarray(points, dtype=np.float64))]
    while len(segs) > min_segments:
        fits = [fit_merge(a, b, np.concatenate([sa, sb, b[3:4]])) for (a, sa), (b, sb) in zip(segs, segs[1:] + segs[:1])]
        i = min(range(len(fits)), key=lambda k: (fits[k][1] if fits[k][1] == fits[k][1] else np.inf, k))
        if not fits[i][1] <= tol:
            break
        j = (i + 1) % len(segs)
        segs[i] = (fits[i][0], np.concatenate([segs[i][1], segs[j][1]]))
        del segs[j]
    return np.concatenate([c[:3] for c, _ in segs])


def test_the_heap_makes_the_merges_a_scan_in_order_makes():
    """``simplify_contours`` keeps its merges in a heap per contour; it comes out bit for bit as the
    scan of every pair every round (``_scan_simplify``) on contours full of ties (centred on the
    origin and symmetric through it or under a quarter turn, so that merges cost exactly the same:
    IEEE rounding is symmetric; the scan takes the first), a polygon of collinear thirds and a noisy ring, at two
    tolerances."""
    from im2vec_cli.trace.simplify import simplify_contours

    rng = np.random.default_rng(11)
    a = np.linspace(0, 2 * np.pi, 90, endpoint=False)
    stairs = np.round(np.stack([20 * np.cos(a), 14 * np.sin(a)], 1) * 2) / 2 + 30
    stairs = stairs[np.any(np.diff(stairs, axis=0, append=stairs[:1]) != 0, axis=1)]  # no repeated anchors
    half = np.concatenate([rng.normal(0, 0.2, (20, 2)) + np.stack([15 * np.cos(a[:45:2]), 9 * np.sin(a[:45:2])], 1)[:20]])
    twin = np.concatenate([half, -half])  # symmetric through the origin: ties
    quarter = np.stack([10 * np.cos(a[:22:4]), 10 * np.sin(a[:22:4])], 1) + rng.normal(0, 0.3, (6, 2))
    turns = [quarter]
    for _ in range(3):  # a quarter turn, (x, y) -> (-y, x), is exact: merges that overlap tie
        turns.append(np.stack([-turns[-1][:, 1], turns[-1][:, 0]], 1))
    square = np.array([(10.0, 0.0), (0.0, 10.0), (-10.0, 0.0), (0.0, -10.0)])  # 4 merges, all tied
    side = [np.array(p, float) for p in ((8, 8), (20, 8), (32, 8), (44, 8), (44, 20), (44, 44), (20, 44), (8, 44))]
    rings = [twin, np.concatenate(turns), square, stairs, np.array(side), 30 + np.stack([12 * np.cos(a[::3]), 12 * np.sin(a[::3])], 1) + rng.normal(0, 0.3, (30, 2))]
    contours = [np.concatenate([np.stack([p, *line_controls(p, q)]) for p, q in zip(r, np.roll(r, -1, 0))]) for r in rings]
    for tol in (0.1, 0.5):
        got = simplify_contours(contours, tol)
        assert [len(g) for g in got] != [len(c) for c in contours]  # merges were made
        for c, g in zip(contours, got):
            assert np.array_equal(g, _scan_simplify(c, tol))
