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

from ..raster.curves import contour_areas, cubics_at, line_controls, ring_areas
from .ndops import run_places

Corners = list[list[np.ndarray]]  # per shape, per contour: (S,) bool, true where anchor i is sharp

STEP = 0.5  # resampling step along the ring (px)
NEAR, FAR = 1.5, 3.0  # arc lengths (px) over which a turn is measured
CORNER_DEG = 50.0  # a turn of at least this within NEAR...
CONCENTRATION = 1.5  # ...that grows less than this much over FAR is a corner
KEEP_AREA = 0.25  # a fitted ring's area is within this share of the ring's


def resample(ring: np.ndarray, step: float = STEP, count: int | None = None) -> np.ndarray:
    """Points every ``step`` px along a closed ring ``(N, 2)`` (at least 8), or ``count`` points
    evenly spaced by arc length: ``(M, 2)``."""
    closed = np.vstack([ring, ring[:1]])
    seg = np.hypot(*np.diff(closed, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    m = count if count is not None else max(8, int(np.ceil(s[-1] / step)))
    t = np.linspace(0, s[-1], m, endpoint=False)
    return np.stack([np.interp(t, s, closed[:, 0]), np.interp(t, s, closed[:, 1])], 1)


def corners(pts: np.ndarray, step: float = STEP, degrees: float = CORNER_DEG) -> np.ndarray:
    """Indices of the corners of an evenly resampled closed ring ``(M, 2)``, ascending: a near
    turn (over ``NEAR`` px) of at least ``degrees`` that is a local maximum and grows less than
    ``CONCENTRATION`` times over ``FAR`` px; none on a ring shorter than ``2 FAR + 1 px``."""
    return np.array(_Rings([pts]).corners(step, degrees)[0], dtype=np.int64)


def sharpen(pts: np.ndarray, idx: np.ndarray, near: float = 1.0, far: float = 3.0, reach: float = 0.75,
            step: float = STEP) -> np.ndarray:
    """Move each corner ``idx`` of a resampled ring to where its two sides meet.

    A traced corner is cut off (the 0.5 level of an anti-aliased corner runs diagonally
    across its pixel); the sides' lines, fitted between ``near`` and ``far`` px from the corner,
    meet at the true corner. A move of more than ``reach`` px (nearly parallel sides, or a
    feature too small for its sides to be lines) is not made.
    """
    return _Rings([pts]).sharpened(np.asarray(idx, dtype=np.int64), near, far, reach, step)


def _units(v: np.ndarray) -> np.ndarray:
    """Each row of ``v (N, 2)`` scaled to length 1 (a row shorter than 1e-12 as it is)."""
    norm = np.hypot(*v.T)[:, None]
    return np.where(norm > 1e-12, v / np.where(norm > 1e-12, norm, 1), v)


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


def _line_errors(pts: np.ndarray, first: np.ndarray, n: np.ndarray) -> np.ndarray:
    """For each run ``pts[first : first + n]`` (of ``pts (P, 2)``), the largest distance of its
    points from the line through its ends (from its first point where the ends meet): ``(R,)``."""
    idx = np.repeat(first, n) + run_places(n)
    at = np.cumsum(n) - n  # each run's first place in ``idx``
    p0 = pts[first]
    d = pts[first + n - 1] - p0
    length = np.hypot(*d.T)
    of = np.repeat(np.arange(len(n)), n)
    q = pts[idx] - p0[of]
    off = np.abs(q[:, 0] * d[of, 1] - q[:, 1] * d[of, 0])
    far = np.maximum.reduceat(off, at) / np.where(length < 1e-12, 1, length)
    closed = length < 1e-12
    if closed.any():
        far[closed] = np.maximum.reduceat(np.hypot(*q.T), at)[closed]
    return far


MAX_DEPTH = 24  # splits of one run, at most


def fit_runs(runs: list[tuple[np.ndarray, np.ndarray, np.ndarray]], tol: float) -> list[list[np.ndarray]]:
    """Cubics ``(4, 2)`` for each run ``(pts (N, 2), t0, t1)``: from ``pts[0]`` to ``pts[-1]``,
    leaving along ``t0`` and arriving against ``t1``, every point within ``tol`` px of them.

    A run that no cubic fits is split at its worst point (a smooth join) and its halves are
    fitted in the next round, breadth first: every piece of every run pending in a round is
    fitted by one ``fit_cubics``. The pieces are spans of the runs' points laid end to end,
    each round's arrays of them (its run, first point, size, tangents, depth), in the order
    the halves were made. Returns each run's cubics in order along it."""
    if not runs:
        return []
    size = np.array([len(p) for p, _, _ in runs], dtype=np.int64)
    pts = np.concatenate([p for p, _, _ in runs])
    run, first, n = np.arange(len(runs)), np.cumsum(size) - size, size
    t0, t1 = np.stack([t for _, t, _ in runs]), np.stack([t for _, _, t in runs])
    depth = np.zeros(len(runs), dtype=np.int64)
    done: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []  # (runs, first points, cubics) of finished pieces
    while len(run):
        p0, p3 = pts[first], pts[first + n - 1]
        chord = p3 - p0
        turned = np.minimum(np.abs(t0[:, 0] * chord[:, 1] - t0[:, 1] * chord[:, 0]),
                            np.abs(t1[:, 0] * chord[:, 1] - t1[:, 1] * chord[:, 0]))
        allowed = (depth == 0) | (turned <= 0.02 * np.hypot(*chord.T))  # (a split piece straight only if its
        straight = (_line_errors(pts, first, n) <= tol) & allowed  # tangents allow it)
        short = ~straight & (n <= 3)
        third = np.hypot(*(p3 - p0)[short].T)[:, None] / 3
        done += [(run[straight], first[straight], np.stack([p0, *line_controls(p0, p3), p3], 1)[straight]),
                 (run[short], first[short], np.stack([p0[short], p0[short] + third * t0[short],
                                                      p3[short] + third * t1[short], p3[short]], 1))]
        fit = np.flatnonzero(~straight & ~short)
        halves = []
        for block in _blocks(fit[np.argsort(n[fit], kind="stable")], n):
            ctrl, worst, where = _fit_block(pts, first[block], n[block], t0[block], t1[block])
            ok = (worst <= tol) | (depth[block] > MAX_DEPTH)
            done.append((run[block][ok], first[block][ok], ctrl[ok]))
            if not ok.all():
                halves.append(_halves(pts, block[~ok], where[~ok], run, first, n, t0, t1, depth))
        run, first, n, t0, t1, depth = (np.concatenate(a) for a in zip(*halves)) if halves else ([],) * 6
    runs_, firsts, ctrls = (np.concatenate(a) for a in zip(*done))
    order = np.lexsort((firsts, runs_))  # along each run: a piece's halves split it at a later point
    ctrls = list(ctrls[order])
    ends = np.cumsum(np.bincount(runs_, minlength=len(runs))).tolist()
    return [ctrls[a:b] for a, b in zip([0, *ends[:-1]], ends)]


def _halves(pts: np.ndarray, which: np.ndarray, at: np.ndarray, run, first, n, t0, t1, depth) -> tuple:
    """The pieces ``which`` split at their points ``at`` (kept 2 points from either end) into two
    halves that share the split point, where they join smoothly (the tangent of the points 2
    before and after it): the halves' ``(run, first, n, t0, t1, depth)``, each piece's first
    half then its second, in the pieces' order."""
    i = np.minimum(np.maximum(at, 2), n[which] - 3)  # (a piece of 4 points: 1)
    tc = _units(pts[first[which] + i + 2] - pts[first[which] + (i - 2) % n[which]])  # (from its last point then)
    pair = (lambda a, b: np.stack([a, b], 1).reshape(-1, *np.shape(a)[1:]))  # a0 b0 a1 b1 ...
    return (pair(run[which], run[which]), pair(first[which], first[which] + i), pair(i + 1, n[which] - i),
            pair(t0[which], tc), pair(-tc, t1[which]), pair(depth[which] + 1, depth[which] + 1))


FIT_BLOCK = 1 << 21  # points in one ``fit_cubics`` batch (pieces x the longest piece): bounded memory
FIT_SPREAD = 2  # pieces fitted in one batch are at most this many times longer than its shortest: padded to
# the longest, a batch of all of a picture's pieces held 21-37 times its points (Adwaita icons, scikit-image's logo)


def _blocks(order: np.ndarray, n: np.ndarray) -> list[np.ndarray]:
    """The pieces ``order`` (shortest first; ``n``: every piece's points) in batches: each of
    pieces within ``FIT_SPREAD`` times of each other's length and at most ``FIT_BLOCK`` padded points."""
    out, begin = [], 0
    sizes = n[order].tolist()
    for j, m in enumerate(sizes):
        if j > begin and (m > FIT_SPREAD * sizes[begin] or (j - begin + 1) * m > FIT_BLOCK):
            out.append(order[begin:j])
            begin = j
    return out + [order[begin:]] if len(sizes) > begin else out


def _fit_block(pts: np.ndarray, first: np.ndarray, n: np.ndarray, t0: np.ndarray, t1: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``fit_cubics`` of the pieces ``pts[first : first + n]`` padded to the longest: control
    points ``(R, 4, 2)``, each piece's largest distance from its points to its cubic at their
    parameters ``(R,)`` and the index of the (first) farthest point ``(R,)``."""
    size = int(n.max())
    mask = np.arange(size) < n[:, None]
    padded = np.zeros((len(n), size, 2))
    padded[mask] = pts[(first[:, None] + np.arange(size))[mask]]
    seg = np.where(mask[:, 1:], np.hypot(*np.moveaxis(np.diff(padded, axis=1), -1, 0)), 0)  # (R, L - 1)
    total = np.empty(len(n))
    for m in np.unique(n).tolist():  # as a run alone sums its m - 1 lengths (pairwise): pieces of one size at once
        rows = n == m
        total[rows] = seg[rows, : m - 1].sum(1)
    u = np.zeros((len(n), size))
    u[:, 1:] = np.cumsum(seg, 1) / np.maximum(total, 1e-12)[:, None] * mask[:, 1:]  # chord-length parameters
    ctrl, u = fit_cubics(padded, mask, u, t0, t1, 4)
    err = np.where(mask, np.hypot(*np.moveaxis(cubics_at(ctrl, u) - padded, -1, 0)), -np.inf)  # (R, L)
    return ctrl, err.max(1), err.argmax(1)


class _Rings:
    """Closed rings, resampled (``resample``), laid end to end: ``pts (N, 2)``, and per point
    its ring (``of``), its place along it (``at``) and its ring's size (``n``) and first point
    (``first``); ``shift(k)`` is, for every point, the index of the point ``k`` after it round its ring."""

    def __init__(self, pts: list[np.ndarray]):
        size = np.array([len(p) for p in pts], dtype=np.int64)
        self.starts = np.cumsum(size) - size
        self.pts = np.concatenate(pts) if pts else np.zeros((0, 2))
        self.of = np.repeat(np.arange(len(pts)), size)
        self.size, self.n, self.first = size, size[self.of], self.starts[self.of]
        self.at = run_places(size)

    def shift(self, k: int) -> np.ndarray:
        return self.first + (self.at + k) % self.n

    def turn(self, k: int) -> np.ndarray:
        """The turning angle (degrees) at every point between its chords to the points ``k`` before and after it."""
        a = self.pts - self.pts[self.shift(-k)]
        b = self.pts[self.shift(k)] - self.pts
        cos = (a * b).sum(1) / np.maximum(np.hypot(*a.T) * np.hypot(*b.T), 1e-12)
        return np.degrees(np.arccos(np.clip(cos, -1, 1)))

    def corners(self, step: float = STEP, degrees: float = CORNER_DEG) -> list[list[int]]:
        """``corners`` of each ring: per ring, its corners' places along it, ascending."""
        near, far = max(1, round(NEAR / step)), max(2, round(FAR / step))
        a_near, a_far = self.turn(near), self.turn(far)
        peak = np.max([a_near[self.shift(d)] for d in range(-near, near + 1)], 0)  # the near turn's local maxima
        cand = (self.n >= 2 * far + 2) & (a_near >= degrees) & (a_far <= CONCENTRATION * a_near) & (a_near >= peak)
        out: list[list[int]] = [[] for _ in self.size]
        idx = np.flatnonzero(cand)
        for r, i in zip(self.of[idx].tolist(), self.at[idx].tolist()):
            mine = out[r]
            if not mine or i - mine[-1] > near:
                mine.append(i)
        for r, mine in enumerate(out):
            if len(mine) > 1 and (mine[0] - mine[-1]) % int(self.size[r]) <= near:
                mine.pop()
        return out

    def sharpened(self, at: np.ndarray, near: float = 1.0, far: float = 3.0, reach: float = 0.75,
                  step: float = STEP) -> np.ndarray:
        """``sharpen`` of every ring at the points ``at`` (indices into ``pts``): the points, moved."""
        out, pts = self.pts.copy(), self.pts
        k1, k2 = max(1, round(near / step)), max(2, round(far / step))
        p_in, q_in = pts[self.shift(-k2)[at]], pts[self.shift(-k1)[at]]
        p_out, q_out = pts[self.shift(k1)[at]], pts[self.shift(k2)[at]]
        d_in, d_out = q_in - p_in, q_out - p_out
        den = d_in[:, 0] * d_out[:, 1] - d_in[:, 1] * d_out[:, 0]
        ok = ~(np.abs(den) < 1e-9 * np.hypot(*d_in.T) * np.hypot(*d_out.T) + 1e-12)
        r = p_out - p_in
        s = (r[:, 0] * d_out[:, 1] - r[:, 1] * d_out[:, 0]) / np.where(ok, den, 1)
        corner = p_in + s[:, None] * d_in
        ok &= np.hypot(*(corner - pts[at]).T) <= reach
        out[at[ok]] = corner[ok]
        return out


def _plans(rings: list[np.ndarray]) -> list[list[tuple[np.ndarray, np.ndarray, np.ndarray, bool]]]:
    """Each closed ring cut at its corners: per ring, ``(points, start tangent, end tangent,
    starts at a corner)`` per run; a ring without corners is one run from where it turns most,
    round. All rings at once (``_Rings``), each as a ring alone would be."""
    rs = _Rings([resample(np.asarray(r, dtype=np.float64)) for r in rings])
    found = rs.corners()
    at = np.array([int(rs.starts[r]) + i for r, cs in enumerate(found) for i in cs], dtype=np.int64)
    runs = iter(_cut(rs, found, rs.sharpened(at)))
    turn2 = rs.turn(2) if any(not cs for cs in found) else None
    plans = []
    for r, cs in enumerate(found):
        if cs:
            plans.append([next(runs) for _ in cs])
            continue
        first, n = int(rs.starts[r]), int(rs.size[r])
        start = int(np.argmax(turn2[first : first + n]))
        loop = rs.pts[first + (start + np.arange(n + 1)) % n]
        t = _units((loop[2] - loop[-3])[None])[0]
        plans.append([(loop, t, -t, False)])
    return plans


def _cut(rs: _Rings, found: list[list[int]], pts: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, bool]]:
    """The runs between consecutive corners ``found`` of the rings of ``rs`` (their points
    ``pts``, sharpened), ring after ring: ``(points, start tangent, end tangent, True)``, each
    tangent the direction from the end to the mean of the (at most) 1.5 px of points beside it."""
    ring = np.array([r for r, cs in enumerate(found) for _ in cs], dtype=np.int64)
    a = np.array([i for cs in found for i in cs], dtype=np.int64)
    b = np.array([i for cs in found for i in cs[1:] + cs[:1]], dtype=np.int64)
    if not len(a):
        return []
    n, first = rs.size[ring], rs.starts[ring]
    length = (b - a) % n
    length = np.where(length == 0, n, length) + 1  # points a run, both corners included
    where = np.cumsum(length) - length
    idx = np.repeat(first, length) + (np.repeat(a, length) + run_places(length)) % np.repeat(n, length)
    reach = np.minimum(max(2, round(1.5 / STEP)), length - 1)
    tangents = []
    for end, sign in ((where, 1), (where + length - 1, -1)):  # the start's points after it, the end's before it
        total = pts[idx[end + sign]]
        for k in range(2, int(reach.max()) + 1):
            total = np.where((reach >= k)[:, None], total + pts[idx[np.where(reach >= k, end + sign * k, end)]], total)
        tangents.append(_units(total / reach[:, None] - pts[idx[end]]))
    parts = np.split(pts[idx], np.cumsum(length)[:-1])
    return [(p, t0, t1, True) for p, t0, t1 in zip(parts, *tangents)]


def fit_rings(rings: list[np.ndarray], tol: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """Closed rings ``(N, 2)`` as closed cubic contours within ``tol`` px, the runs of all of
    them fitted together (``fit_runs``); a ring whose fit loses or gains more than ``KEEP_AREA`` of
    its area is fitted again within half the tolerance, down to ``tol / 8``: within 0.5 px, a 1 px
    strip (a desktop icon's dark rim) fitted as a line there and back, enclosing nothing.

    Returns:
        Per ring, ``(3S, 2)`` control points (same orientation as the ring) and ``(S,)`` bool,
        true where anchor ``i`` is a corner (a join whose tangents may differ).
    """
    out, want = _fitted(rings, tol), ring_areas(rings)
    todo = np.arange(len(rings))
    for _ in range(3):
        got = contour_areas([out[i][0] for i in todo], 8)
        todo = todo[np.abs(got - want[todo]) > KEEP_AREA * np.abs(want[todo])]
        if not len(todo):
            break
        tol /= 2
        for i, again in zip(todo, _fitted([rings[i] for i in todo], tol)):
            out[i] = again
    return out


def _fitted(rings: list[np.ndarray], tol: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """``fit_rings`` at ``tol`` without the area check."""
    if not rings:
        return []
    plans = _plans(rings)
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
