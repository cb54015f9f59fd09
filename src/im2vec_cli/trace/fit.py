"""Closed polygons to closed cubic contours: few segments, sharp corners, within a tolerance.

A ring from ``regions.py`` (or a flattened outline) is resampled at even arc length, its
*corners* are found (a turn that happens within a short arc: a serif or a stem end, not the
round end of a stroke), and each run between corners is fitted with as few cubics as keep
every sample within ``tol`` pixels (least squares on the two tangent lengths with fixed end
tangents, Newton re-parametrisation, split at the worst sample: Schneider, "An algorithm for
automatically fitting digitized curves", Graphics Gems 1990). Joins inside a run share their
tangent (smooth); joins at corners do not. Straight runs become one straight cubic.

Frame: pixel coordinates; contours use the wrap-around cubic layout ``(3S, 2)`` of
``raster/bezier.py`` (anchor, control, control per segment; the last segment ends at point 0).
"""

from __future__ import annotations

import numpy as np

from ..raster.curves import cubics_at, line_controls

Corners = list[list[np.ndarray]]  # per shape, per contour: (S,) bool, true where anchor i is sharp

STEP = 0.5  # resampling step along the ring (px)
NEAR, FAR = 1.5, 3.0  # arc lengths (px) over which a turn is measured
CORNER_DEG = 50.0  # a turn of at least this within NEAR...
CONCENTRATION = 1.5  # ...that grows less than this much over FAR is a corner


def resample(ring: np.ndarray, step: float = STEP, count: int | None = None) -> np.ndarray:
    """Points every ``step`` px along a closed ring ``(N, 2)`` (at least 8), or ``count`` points
    evenly spaced by arc length: ``(M, 2)``."""
    closed = np.vstack([ring, ring[:1]])
    seg = np.hypot(*np.diff(closed, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    m = count if count is not None else max(8, int(np.ceil(s[-1] / step)))
    t = np.linspace(0, s[-1], m, endpoint=False)
    return np.stack([np.interp(t, s, closed[:, 0]), np.interp(t, s, closed[:, 1])], 1)


def _turn(pts: np.ndarray, k: int) -> np.ndarray:
    """Turning angle (degrees) at each point of a closed ring between the chords to +-k points."""
    a = pts - np.roll(pts, k, 0)
    b = np.roll(pts, -k, 0) - pts
    cos = (a * b).sum(1) / np.maximum(np.hypot(*a.T) * np.hypot(*b.T), 1e-12)
    return np.degrees(np.arccos(np.clip(cos, -1, 1)))


def corners(pts: np.ndarray, step: float = STEP, degrees: float = CORNER_DEG) -> np.ndarray:
    """Indices of the corners of an evenly resampled closed ring ``(M, 2)``, ascending."""
    n = len(pts)
    near, far = max(1, round(NEAR / step)), max(2, round(FAR / step))
    if n < 2 * far + 2:
        return np.zeros(0, dtype=np.int64)
    a_near, a_far = _turn(pts, near), _turn(pts, far)
    cand = (a_near >= degrees) & (a_far <= CONCENTRATION * a_near)
    out = []
    for i in np.nonzero(cand)[0]:  # local maxima of the near turn
        window = [(i + d) % n for d in range(-near, near + 1)]
        if a_near[i] >= a_near[window].max() and not any((i - j) % n <= near for j in out[-1:]):
            out.append(i)
    if len(out) > 1 and (out[0] - out[-1]) % n <= near:
        out.pop()
    return np.array(sorted(out), dtype=np.int64)


def sharpen(pts: np.ndarray, idx: np.ndarray, near: float = 1.0, far: float = 3.0, reach: float = 0.75,
            step: float = STEP) -> np.ndarray:
    """Move each corner ``idx`` of a resampled ring to where its two sides meet.

    A traced corner is cut off (the 0.5 level of an anti-aliased corner runs diagonally
    across its pixel); the sides' lines, fitted between ``near`` and ``far`` px from the corner,
    meet at the true corner. A move of more than ``reach`` px (nearly parallel sides, or a
    feature too small for its sides to be lines) is not made.
    """
    out = pts.copy()
    n, k1, k2 = len(pts), max(1, round(near / step)), max(2, round(far / step))
    for i in idx:
        p_in, q_in = pts[(i - k2) % n], pts[(i - k1) % n]
        p_out, q_out = pts[(i + k1) % n], pts[(i + k2) % n]
        d_in, d_out = q_in - p_in, q_out - p_out
        den = d_in[0] * d_out[1] - d_in[1] * d_out[0]
        if abs(den) < 1e-9 * np.hypot(*d_in) * np.hypot(*d_out) + 1e-12:
            continue
        r = p_out - p_in
        s = (r[0] * d_out[1] - r[1] * d_out[0]) / den
        corner = p_in + s * d_in
        if np.hypot(*(corner - pts[i])) <= reach:
            out[i] = corner
    return out


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.hypot(*v)
    return v / n if n > 1e-12 else v


def _end_tangent(pts: np.ndarray, at_start: bool, reach: int) -> np.ndarray:
    """Unit tangent leaving the first point (or entering the last, pointing back) of a run."""
    seq = pts if at_start else pts[::-1]
    k = min(reach, len(seq) - 1)
    return _unit(seq[1 : k + 1].mean(0) - seq[0])


def fit_cubics(pts: np.ndarray, mask: np.ndarray, u: np.ndarray, t0: np.ndarray, t1: np.ndarray, iterations: int
               ) -> tuple[np.ndarray, np.ndarray]:
    """For each of K runs, the cubic from its first to its last point with end tangents
    ``t0``/``t1`` that fits its points: ``iterations`` rounds of least squares on the two
    handle lengths at the parameters ``u`` (a third of the chord each when that fails or gives
    a loop), then one Newton step per point towards its nearest point on the cubic (Schneider's
    reparametrisation).

    Args:
        pts: ``(K, N, 2)`` the runs, padded after their last point; mask ``(K, N)`` true on real
            points (at least two per run); u ``(K, N)`` their parameters; t0, t1 ``(K, 2)``.

    Returns:
        ``(K, 4, 2)`` cubics and ``(K, N)`` the last parameters. One vectorised pass serves every
    run of a picture, where a call per run would spend its time in NumPy's per-call overhead."""
    k = len(pts)
    last = mask.sum(1) - 1
    p0, p3 = pts[:, 0], pts[np.arange(k), last]  # (K, 2)
    x, y = pts[..., 0], pts[..., 1]
    chord = np.hypot(*(p3 - p0).T)  # (K,)
    lo, hi = 1e-3 * chord, 2 * chord + 1
    t00, t01, t11 = (t0 * t0).sum(1), (t0 * t1).sum(1), (t1 * t1).sum(1)
    col = (lambda a: a[:, None])  # (K,) -> (K, 1)
    ctrl = np.empty((k, 4, 2))
    for _ in range(iterations):
        v = 1 - u
        vv, uu, vu = v * v, u * u, v * u
        b0, b1, b2, b3 = vv * v, 3 * vv * u, 3 * v * uu, uu * u
        m1, m2 = b1 * mask, b2 * mask  # the normal equations sum over real points only
        near, far = b0 + b1, b2 + b3
        rx, ry = x - near * col(p0[:, 0]) - far * col(p3[:, 0]), y - near * col(p0[:, 1]) - far * col(p3[:, 1])
        d00, d01, d11 = (m1 * m1).sum(1) * t00, (m1 * m2).sum(1) * t01, (m2 * m2).sum(1) * t11
        r0 = (m1 * (rx * col(t0[:, 0]) + ry * col(t0[:, 1]))).sum(1)
        r1 = (m2 * (rx * col(t1[:, 0]) + ry * col(t1[:, 1]))).sum(1)
        det = d00 * d11 - d01 * d01
        solvable = np.abs(det) > 1e-12 * np.maximum(d00 * d11, 1e-300)
        safe = np.where(solvable, det, 1.0)
        x0, x1 = (r0 * d11 - d01 * r1) / safe, (d00 * r1 - d01 * r0) / safe
        good = solvable & (lo < x0) & (x0 < hi) & (lo < x1) & (x1 < hi)
        a0, a1 = np.where(good, x0, chord / 3), np.where(good, x1, chord / 3)
        ctrl = np.stack([p0, p0 + col(a0) * t0, p3 + col(a1) * t1, p3], 1)  # (K, 4, 2)
        (ax, bx, cx, dx), (ay, by, cy, dy) = (col(c) for c in ctrl[..., 0].T), (col(c) for c in ctrl[..., 1].T)
        qx = b0 * ax + b1 * bx + b2 * cx + b3 * dx - x  # the cubic at u, minus the points
        qy = b0 * ay + b1 * by + b2 * cy + b3 * dy - y
        e0x, e1x, e2x = 3 * (bx - ax), 3 * (cx - bx), 3 * (dx - cx)
        e0y, e1y, e2y = 3 * (by - ay), 3 * (cy - by), 3 * (dy - cy)
        q1x, q1y = vv * e0x + 2 * vu * e1x + uu * e2x, vv * e0y + 2 * vu * e1y + uu * e2y  # first derivative
        q2x, q2y = 2 * (v * (e1x - e0x) + u * (e2x - e1x)), 2 * (v * (e1y - e0y) + u * (e2y - e1y))  # second
        num = qx * q1x + qy * q1y
        den = q1x * q1x + q1y * q1y + qx * q2x + qy * q2y
        ok = np.abs(den) > 1e-12
        u = np.clip(u - np.where(ok, num / np.where(ok, den, 1), 0), 0, 1)
    return ctrl, u


def fit_cubic(pts: np.ndarray, u: np.ndarray, t0: np.ndarray, t1: np.ndarray, iterations: int
              ) -> tuple[np.ndarray, np.ndarray]:
    """``fit_cubics`` of one run ``pts (N, 2)`` at ``u (N,)``: the cubic ``(4, 2)`` and ``u``."""
    ctrl, u = fit_cubics(pts[None], np.ones((1, len(pts)), dtype=bool), u[None], t0[None], t1[None], iterations)
    return ctrl[0], u[0]


def _cross(a: np.ndarray, b: np.ndarray) -> float:
    return float(a[0] * b[1] - a[1] * b[0])


def _line_error(pts: np.ndarray) -> float:
    p0, d = pts[0], pts[-1] - pts[0]
    n = np.hypot(*d)
    if n < 1e-12:
        return float(np.hypot(*(pts - p0).T).max())
    return float(np.abs((pts[:, 0] - p0[0]) * d[1] - (pts[:, 1] - p0[1]) * d[0]).max() / n)


MAX_DEPTH = 24  # splits of one run, at most


def fit_runs(runs: list[tuple[np.ndarray, np.ndarray, np.ndarray]], tol: float) -> list[list[np.ndarray]]:
    """Cubics ``(4, 2)`` for each run ``(pts (N, 2), t0, t1)``: from ``pts[0]`` to ``pts[-1]``,
    leaving along ``t0`` and arriving against ``t1``, every point within ``tol`` px of them.

    A run that no cubic fits is split at its worst point (a smooth join) and its halves are
    fitted in the next round, breadth first: every piece of every run pending in a round is
    fitted by one ``fit_cubics``. Returns each run's cubics in order along it."""
    done: list[list[tuple[tuple, np.ndarray]]] = [[] for _ in runs]
    pending = [(r, (), pts, t0, t1, 0) for r, (pts, t0, t1) in enumerate(runs)]
    while pending:
        fit = []
        for r, key, pts, t0, t1, depth in pending:
            chord = pts[-1] - pts[0]
            straight = _line_error(pts) <= tol  # a straight run (a split piece only if its tangents allow it)
            if straight and (depth == 0 or min(abs(_cross(t0, chord)), abs(_cross(t1, chord))) <= 0.02 * np.hypot(*chord)):
                done[r].append((key, np.stack([pts[0], *line_controls(pts[0], pts[-1]), pts[-1]])))
            elif len(pts) <= 3:
                n = np.hypot(*chord) / 3
                done[r].append((key, np.stack([pts[0], pts[0] + n * t0, pts[-1] + n * t1, pts[-1]])))
            else:
                fit.append((r, key, pts, t0, t1, depth))
        pending = []
        for block in _blocks(fit):
            ctrls, worst, where = _fit_block(block)
            for (r, key, p, t0, t1, depth), ctrl, err, at in zip(block, ctrls, worst.tolist(), where.tolist()):
                if err <= tol or depth > MAX_DEPTH:
                    done[r].append((key, ctrl))
                    continue
                i = int(np.clip(at, 2, len(p) - 3))
                tc = _unit(p[i + 2] - p[i - 2])  # the split is a smooth join
                pending += [(r, key + (0,), p[: i + 1], t0, -tc, depth + 1), (r, key + (1,), p[i:], tc, t1, depth + 1)]
    return [[c for _, c in sorted(d, key=lambda kc: kc[0])] for d in done]


FIT_BLOCK = 1 << 21  # points in one ``fit_cubics`` batch (pieces x the longest piece): bounded memory
FIT_SPREAD = 2  # pieces fitted in one batch are at most this many times longer than its shortest: padded to
# the longest, a batch of all of a picture's pieces held 21-37 times its points (Adwaita icons, scikit-image's logo)


def _blocks(fit: list[tuple]) -> list[list[tuple]]:
    """The pieces to fit (``(run, key, pts, t0, t1, depth)``) in batches by length: each of pieces
    within ``FIT_SPREAD`` times of each other's length and at most ``FIT_BLOCK`` padded points."""
    out, cur = [], []
    for f in sorted(fit, key=lambda f: len(f[2])):
        if cur and (len(f[2]) > FIT_SPREAD * len(cur[0][2]) or (len(cur) + 1) * len(f[2]) > FIT_BLOCK):
            out.append(cur)
            cur = []
        cur.append(f)
    return out + [cur] if cur else out


def _fit_block(fit: list[tuple]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``fit_cubics`` of pieces ``(run, key, pts, t0, t1, depth)`` padded to the longest:
    control points ``(R, 4, 2)``, each piece's largest distance from its points to its cubic
    at their parameters ``(R,)`` and the index of the (first) farthest point ``(R,)``."""
    size = max(len(f[2]) for f in fit)
    pts = np.zeros((len(fit), size, 2))
    mask = np.zeros((len(fit), size), dtype=bool)
    u = np.zeros((len(fit), size))
    for j, (_, _, p, _, _, _) in enumerate(fit):
        seg = np.hypot(*np.diff(p, axis=0).T)
        pts[j, : len(p)], mask[j, : len(p)] = p, True
        u[j, 1 : len(p)] = np.cumsum(seg) / max(seg.sum(), 1e-12)  # chord-length parameters
    ctrl, u = fit_cubics(pts, mask, u, np.stack([f[3] for f in fit]), np.stack([f[4] for f in fit]), 4)
    err = np.where(mask, np.hypot(*np.moveaxis(cubics_at(ctrl, u) - pts, -1, 0)), -np.inf)  # (R, L)
    return ctrl, err.max(1), err.argmax(1)


def fit_run(pts: np.ndarray, t0: np.ndarray, t1: np.ndarray, tol: float) -> list[np.ndarray]:
    """``fit_runs`` of one run."""
    return fit_runs([(pts, t0, t1)], tol)[0]


def _runs(ring: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, bool]]:
    """A closed ring cut at its corners: ``(points, start tangent, end tangent, starts at a
    corner)`` per run; a ring without corners is one run from where it turns most, round."""
    pts = resample(np.asarray(ring, dtype=np.float64))
    cs = corners(pts)
    n, reach = len(pts), max(2, round(1.5 / STEP))
    if len(cs) == 0:
        start = int(np.argmax(_turn(pts, 2)))
        loop = np.roll(pts, -start, 0)
        t = _unit(loop[2] - loop[-2])
        return [(np.vstack([loop, loop[:1]]), t, -t, False)]
    pts = sharpen(pts, cs)
    out = []
    for a, b in zip(cs, np.roll(cs, -1)):
        run = pts[np.arange(a, a + ((b - a) % n or n) + 1) % n]
        out.append((run, _end_tangent(run, True, reach), _end_tangent(run, False, reach), True))
    return out


def fit_rings(rings: list[np.ndarray], tol: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """Closed rings ``(N, 2)`` as closed cubic contours within ``tol`` px, the runs of all of
    them fitted together (``fit_runs``).

    Returns:
        Per ring, ``(3S, 2)`` control points (same orientation as the ring) and ``(S,)`` bool,
        true where anchor ``i`` is a corner (a join whose tangents may differ).
    """
    plans = [_runs(r) for r in rings]
    pieces = iter(fit_runs([(p, t0, t1) for plan in plans for p, t0, t1, _ in plan], tol))
    out = []
    for plan in plans:
        segs, sharp = [], []
        for *_, corner in plan:
            part = next(pieces)
            segs += part
            sharp += [corner] + [False] * (len(part) - 1)
        out.append((np.concatenate([c[:3] for c in segs]), np.array(sharp)))
    return out


def fit_ring(ring: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """``fit_rings`` of one ring: ``(3S, 2)`` control points and ``(S,)`` corner flags."""
    return fit_rings([ring], tol)[0]


def split_segments(contour: np.ndarray, sharp: np.ndarray, which: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Split segments ``which`` (indices) of a closed contour ``(3S, 2)`` in half (de Casteljau:
    the outline does not move; the new anchors are smooth joins).

    Returns:
        The new contour and its corner flags, as ``fit_ring`` gives them.
    """
    n = len(contour)
    segs, flags, todo = [], [], set(int(i) for i in which)
    for s in range(n // 3):
        ctrl = np.stack([contour[3 * s], contour[3 * s + 1], contour[3 * s + 2], contour[(3 * s + 3) % n]])
        if s in todo:
            p01, p12, p23 = (ctrl[0] + ctrl[1]) / 2, (ctrl[1] + ctrl[2]) / 2, (ctrl[2] + ctrl[3]) / 2
            q0, q1 = (p01 + p12) / 2, (p12 + p23) / 2
            mid = (q0 + q1) / 2
            segs += [np.stack([ctrl[0], p01, q0]), np.stack([mid, q1, p23])]
            flags += [bool(sharp[s]), False]
        else:
            segs.append(ctrl[:3])
            flags.append(bool(sharp[s]))
    return np.concatenate(segs), np.array(flags)
