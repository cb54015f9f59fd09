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
import torch

from ..raster.bezier import cubic_at, segment_controls
from .image import VectorImage

SAMPLES = 12  # points per original segment when measuring a merge


def _bezier(ctrl: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``ctrl (4, 2)``, ``t (N,)`` -> ``(N, 2)``."""
    return cubic_at(ctrl, t)


def _segments(points: np.ndarray) -> np.ndarray:
    """``(3S, 2)`` -> ``(S, 4, 2)``."""
    return segment_controls(torch.from_numpy(points)).numpy()


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
    for _ in range(3):  # least squares on the two tangent lengths, then re-parametrise
        b = np.stack([(1 - u) ** 3, 3 * (1 - u) ** 2 * u, 3 * (1 - u) * u**2, u**3], 1)  # (N, 4)
        a1, a2 = b[:, 1:2] * t0, b[:, 2:3] * t1  # (N, 2) each
        rest = pts - (b[:, 0:1] + b[:, 1:2]) * p0 - (b[:, 2:3] + b[:, 3:4]) * p3
        m = np.array([[np.sum(a1 * a1), np.sum(a1 * a2)], [np.sum(a1 * a2), np.sum(a2 * a2)]])
        r = np.array([np.sum(a1 * rest), np.sum(a2 * rest)])
        try:
            alpha = np.linalg.solve(m, r)
        except np.linalg.LinAlgError:
            alpha = np.array([chord / 3, chord / 3])
        if not (alpha > 1e-3 * chord).all():
            alpha = np.array([chord / 3, chord / 3])
        ctrl = np.stack([p0, p0 + alpha[0] * t0, p3 + alpha[1] * t1, p3])
        u = _reparametrise(ctrl, pts, u)
    err = float(np.hypot(*(_bezier(ctrl, u) - pts).T).max())
    return ctrl, err


def _reparametrise(ctrl: np.ndarray, pts: np.ndarray, u: np.ndarray) -> np.ndarray:
    """One Newton step per sample towards its closest point on the curve."""
    d1 = 3 * np.diff(ctrl, axis=0)  # (3, 2)
    d2 = 2 * np.diff(d1, axis=0)  # (2, 2)
    t = u[:, None]
    q = _bezier(ctrl, u) - pts
    q1 = (1 - t) ** 2 * d1[0] + 2 * (1 - t) * t * d1[1] + t**2 * d1[2]
    q2 = (1 - t) * d2[0] + t * d2[1]
    num = (q * q1).sum(1)
    den = (q1 * q1).sum(1) + (q * q2).sum(1)
    step = np.where(np.abs(den) > 1e-12, num / np.where(np.abs(den) > 1e-12, den, 1), 0)
    return np.clip(u - step, 0, 1)


def simplify_contour(points: np.ndarray, tol: float, min_segments: int = 2) -> np.ndarray:
    """Merge segments of a closed contour ``(3S, 2)`` (px) while each merge stays within ``tol`` px.

    Returns:
        ``(3S', 2)`` with ``min_segments <= S' <= S``, starting at one of the original anchors.
    """
    t = np.linspace(0, 1, SAMPLES, endpoint=False)
    # (uid, control points (4, 2), samples of the original outline it stands for (M, 2), end excluded)
    segs = [(i, c, _bezier(c, t)) for i, c in enumerate(_segments(np.asarray(points, dtype=np.float64)))]
    uid = len(segs)
    costs: dict[tuple[int, int], tuple[np.ndarray, float]] = {}  # merge of two neighbours by uid
    while len(segs) > min_segments:
        n = len(segs)
        best_i, best = -1, (None, np.inf)
        for i in range(n):
            (ua, a, sa), (ub, b, sb) = segs[i], segs[(i + 1) % n]
            if (ua, ub) not in costs:
                costs[(ua, ub)] = fit_merge(a, b, np.concatenate([sa, sb, b[3:4]]))
            if costs[(ua, ub)][1] < best[1]:
                best_i, best = i, costs[(ua, ub)]
        if best[1] > tol:
            break
        j = (best_i + 1) % n
        segs[best_i] = (uid, best[0], np.concatenate([segs[best_i][2], segs[j][2]]))
        uid += 1
        del segs[j]
    return np.concatenate([c[:3] for _, c, _ in segs])


def simplify(image: VectorImage, tol: float) -> VectorImage:
    """``simplify_contour`` on every contour of ``image`` (``tol`` in its pixel frame)."""
    if tol <= 0:
        return image
    shapes = [dataclasses.replace(s, contours=[simplify_contour(c, tol) for c in s.contours]) for s in image.shapes]
    return dataclasses.replace(image, shapes=shapes)
