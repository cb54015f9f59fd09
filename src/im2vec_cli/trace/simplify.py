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
    cheapest merge (or stops, none within ``tol``); each comes out as it does alone."""
    t = np.linspace(0, 1, SAMPLES, endpoint=False)
    # per contour: [(uid, control points (4, 2), samples of the original outline it stands for (M, 2), end excluded)]
    every = [[(i, c, _bezier(c, t)) for i, c in enumerate(_segments(np.asarray(p, dtype=np.float64)))]
             for p in contours]
    uid = [len(segs) for segs in every]
    costs: list[dict[tuple[int, int], tuple[np.ndarray, float]]] = [{} for _ in every]  # merges of neighbours by uid
    active = [k for k, segs in enumerate(every) if len(segs) > min_segments]
    while active:
        todo = []  # (contour, key, first, second, the original outline from first's start to second's end)
        for k in active:
            segs = every[k]
            for (ua, a, sa), (ub, b, sb) in zip(segs, segs[1:] + segs[:1]):
                if (ua, ub) not in costs[k]:
                    todo.append((k, (ua, ub), a, b, np.concatenate([sa, sb, b[3:4]])))
        for (k, key, *_), got in zip(todo, fit_merges([w[2:] for w in todo])):
            costs[k][key] = got
        still = []
        for k in active:
            segs, n = every[k], len(every[k])
            best_i, best = -1, (None, np.inf)
            for i in range(n):
                cost = costs[k][(segs[i][0], segs[(i + 1) % n][0])]
                if cost[1] < best[1]:
                    best_i, best = i, cost
            if best[1] > tol:
                continue
            j = (best_i + 1) % n
            segs[best_i] = (uid[k], best[0], np.concatenate([segs[best_i][2], segs[j][2]]))
            uid[k] += 1
            del segs[j]
            if len(segs) > min_segments:
                still.append(k)
        active = still
    return [np.concatenate([c[:3] for _, c, _ in segs]) for segs in every]


def simplify(image: VectorImage, tol: float) -> VectorImage:
    """``simplify_contour`` on every contour of ``image`` (``tol`` in its pixel frame)."""
    if tol <= 0:
        return image
    done = iter(simplify_contours([c for s in image.shapes for c in s.contours], tol))
    shapes = [dataclasses.replace(s, contours=[next(done) for _ in s.contours]) for s in image.shapes]
    return dataclasses.replace(image, shapes=shapes)
