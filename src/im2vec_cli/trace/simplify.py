"""Fewer segments for the same outline: drop collapsed segments, merge neighbours.

Works on one contour ``(3S, 2)`` of closed cubic control points in the pixel frame (the
layout of ``svg.VectorShape``: anchor, control, control per segment; the path closes on
point 0). Two neighbouring segments are replaced by one cubic when a single cubic with the
same end points and end tangents (so the joins keep their smoothness) stays within ``tol``
pixels of the *original* outline they replace (measured at samples of the original segments,
so errors do not accumulate over successive merges); the cheapest merge is done first, until
none fits.
"""

from __future__ import annotations

import dataclasses
import heapq

import numpy as np

from ..raster.curves import cubic_at, cubics_at, segments_of
from ..vector import VectorImage
from .fit import fit_cubic, fit_cubics

SAMPLES = 12  # points per original segment when measuring a merge


def _bezier(ctrl: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``ctrl (4, 2)``, ``t (N,)`` -> ``(N, 2)``."""
    return cubic_at(ctrl, t)


def _segments(points: np.ndarray) -> np.ndarray:
    """``(3S, 2)`` -> ``(S, 4, 2)``."""
    return segments_of(points)


def _tangent(ctrl: np.ndarray, at_start: bool) -> np.ndarray | None:
    """Unit tangent leaving the start (or entering the end, pointing back) of a segment."""
    seq = ctrl if at_start else ctrl[::-1]
    for q in seq[1:]:
        d = q - seq[0]
        n = np.hypot(*d)
        if n > 1e-9:
            return d / n
    return None


def fit_merge(first: np.ndarray, second: np.ndarray, pts: np.ndarray) -> tuple[np.ndarray, float]:
    """One cubic for two consecutive segments ``(4, 2)`` each, fitted to ``pts (N, 2)``, the
    original outline from ``first[0]`` to ``second[3]``: control points and the largest
    distance (px) from ``pts`` to it."""
    p0, p3 = first[0], second[3]
    t0, t1 = _tangent(first, True), _tangent(second, False)
    chord = np.hypot(*(p3 - p0))
    if t0 is None or t1 is None or chord < 1e-9:
        return np.stack([p0, p0, p3, p3]), np.inf
    seg = np.hypot(*np.diff(pts, axis=0).T)
    u = np.concatenate([[0.0], np.cumsum(seg)]) / max(seg.sum(), 1e-12)  # chord-length parameters
    ctrl, u = fit_cubic(pts, u, t0, t1, 3)  # least squares on the two tangent lengths, then re-parametrise
    err = float(np.hypot(*(_bezier(ctrl, u) - pts).T).max())
    return ctrl, err


def fit_merges(pairs: list[tuple[np.ndarray, np.ndarray, np.ndarray]]) -> list[tuple[np.ndarray, float]]:
    """``fit_merge`` of each ``(first, second, pts)``, those of one length of ``pts`` in one
    ``fit_cubics`` batch (every step is row by row, so each result is ``fit_merge``'s to the bit)."""
    out: list = [None] * len(pairs)
    todo: dict[int, list] = {}
    for i, (first, second, pts) in enumerate(pairs):
        t0, t1 = _tangent(first, True), _tangent(second, False)
        if t0 is None or t1 is None or np.hypot(*(second[3] - first[0])) < 1e-9:
            out[i] = fit_merge(first, second, pts)
        else:
            todo.setdefault(len(pts), []).append((i, pts, t0, t1))
    for rows in todo.values():
        pts = np.stack([r[1] for r in rows])  # (K, N, 2)
        seg = np.hypot(*np.moveaxis(np.diff(pts, axis=1), -1, 0))  # (K, N - 1)
        u = np.concatenate([np.zeros((len(rows), 1)), np.cumsum(seg, 1)], 1) / np.maximum(seg.sum(1), 1e-12)[:, None]
        ctrl, u = fit_cubics(pts, np.ones(u.shape, dtype=bool), u, np.stack([r[2] for r in rows]),
                             np.stack([r[3] for r in rows]), 3)
        err = np.hypot(*np.moveaxis(cubics_at(ctrl, u) - pts, -1, 0)).max(1)  # (K,)
        for (i, *_), cc, e in zip(rows, ctrl, err.tolist()):
            out[i] = (cc, e)
    return out


def simplify_contour(points: np.ndarray, tol: float, min_segments: int = 2) -> np.ndarray:
    """Merge segments of a closed contour ``(3S, 2)`` (px) while each merge stays within ``tol`` px.

    Returns:
        ``(3S', 2)`` with ``min_segments <= S' <= S``, starting at one of the original anchors.
    """
    return simplify_contours([points], tol, min_segments)[0]


def simplify_contours(contours: list[np.ndarray], tol: float, min_segments: int = 2) -> list[np.ndarray]:
    """``simplify_contour`` of each contour, all of them in step: every round, each contour's
    merges not yet fitted are fitted together (``fit_merges``), then each contour makes its
    cheapest merge (or stops, none within ``tol``); each comes out as it does alone.

    A contour is a ring of segments linked both ways with a heap of its fitted merges (stale
    ones skipped when they come up), so a round costs a contour the two merges its last one
    made, not a pass over its segments: O(S log S) in all, not O(S^2) (a 1-bit dither's
    contours run to tens of thousands of segments). Ties go to the merge first along the
    contour, as a scan in order would take them: a merge keeps its first segment's place,
    so the ring in order of first places is always the contour from its first anchor."""
    t = np.linspace(0, 1, SAMPLES, endpoint=False)
    rings = [_Ring(_segments(np.asarray(p, dtype=np.float64)), t) for p in contours]
    todo = [(k, pair) for k, ring in enumerate(rings) if ring.size > min_segments for pair in ring.pairs()]
    while todo:
        got = fit_merges([rings[k].merge_input(*pair) for k, pair in todo])
        for (k, pair), (ctrl, err) in zip(todo, got):
            rings[k].offer(pair, ctrl, err)
        todo = [(k, pair) for k in sorted({k for k, _ in todo}) for pair in rings[k].merge_best(tol, min_segments)]
    return [ring.points() for ring in rings]


class _Ring:
    """One contour being simplified: its segments by id (control points ``(4, 2)``, samples of the
    original outline each stands for ``(M, 2)``, end excluded, and the place of its first original
    segment), linked both ways, and a heap of fitted merges ``(error, place, first id, second id, controls)``."""

    def __init__(self, segs: np.ndarray, t: np.ndarray):
        n = len(segs)
        self.ctrl = dict(enumerate(segs))
        self.samples = {i: _bezier(c, t) for i, c in enumerate(segs)}
        self.place = {i: i for i in range(n)}
        self.next = {i: (i + 1) % n for i in range(n)}
        self.prev = {i: (i - 1) % n for i in range(n)}
        self.heap, self.size, self._uid = [], n, n

    def pairs(self) -> list[tuple[int, int]]:
        """Every pair of neighbours, in order."""
        return [(i, self.next[i]) for i in sorted(self.ctrl, key=self.place.get)]

    def merge_input(self, a: int, b: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``fit_merges``' input for the neighbours ``a, b``: both segments and the original outline they stand for."""
        return self.ctrl[a], self.ctrl[b], np.concatenate([self.samples[a], self.samples[b], self.ctrl[b][3:4]])

    def offer(self, pair: tuple[int, int], ctrl: np.ndarray, err: float) -> None:
        err = err if err == err else np.inf  # NaN never merges (a scan's ``<`` never takes it)
        heapq.heappush(self.heap, (err, self.place[pair[0]], *pair, ctrl))

    def merge_best(self, tol: float, min_segments: int) -> list[tuple[int, int]]:
        """Make the cheapest merge within ``tol`` px, if any; the new pairs it makes, to fit (none once
        ``min_segments`` are left, or when nothing merged)."""
        while self.heap:
            err, _, a, b, ctrl = self.heap[0]
            if a in self.ctrl and self.next[a] == b:
                break
            heapq.heappop(self.heap)
        else:
            return []
        if err > tol:
            return []
        heapq.heappop(self.heap)
        u, self._uid = self._uid, self._uid + 1
        before, after = self.prev[a], self.next[b]
        self.ctrl[u], self.samples[u], self.place[u] = ctrl, np.concatenate([self.samples[a], self.samples[b]]), self.place[a]
        for d in (self.ctrl, self.samples, self.place, self.next, self.prev):
            del d[a], d[b]
        self.size -= 1
        before, after = (u, u) if before == b else (before, after)  # two segments became one
        self.next[before], self.prev[u], self.next[u], self.prev[after] = u, before, after, u
        return [(before, u), (u, after)] if self.size > min_segments else []

    def points(self) -> np.ndarray:
        """``(3S', 2)``: the contour from its first anchor."""
        return np.concatenate([self.ctrl[i][:3] for i in sorted(self.ctrl, key=self.place.get)])


def simplify(image: VectorImage, tol: float) -> VectorImage:
    """``simplify_contour`` on every contour of ``image`` (``tol`` in its pixel frame)."""
    if tol <= 0:
        return image
    done = iter(simplify_contours([c for s in image.shapes for c in s.contours], tol))
    shapes = [dataclasses.replace(s, contours=[next(done) for _ in s.contours]) for s in image.shapes]
    return dataclasses.replace(image, shapes=shapes)


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
