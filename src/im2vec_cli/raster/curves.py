"""Cubic Bezier geometry on NumPy arrays, without torch: what tracing, fitting and the SVG
bridge need, so that a picture traced and not polished never imports torch (``bezier.py`` holds
the tensor versions the renderer differentiates through).

Layout (shared/STYLE.md): ``points (..., 3S, 2)`` holds S cubic segments in diffvg's
wrap-around order ``anchor, control, control, anchor, ...`` (``bezier.py``).
"""

from __future__ import annotations

import functools

import numpy as np


def line_controls(a, b):
    """The two controls of a straight segment ``a -> b`` written as a cubic (at 1/3 and 2/3).

    Works on anything with arithmetic: NumPy arrays, tensors, ``(..., 2)`` batches.
    """
    return a + (b - a) / 3, a + 2 * (b - a) / 3


def cubic_at(ctrl, t):
    """Points of cubic segments at parameters ``t``: the one cubic evaluation of the project.

    Works on NumPy arrays and tensors alike.

    Args:
        ctrl: ``(..., 4, 2)`` control points ``[p0, p1, p2, p3]``.
        t: ``(N,)`` parameters in [0, 1].

    Returns:
        ``(..., N, 2)``.
    """
    t = t[:, None]  # (N, 1)
    u = 1 - t
    c = ctrl[..., None, :, :]  # (..., 1, 4, 2)
    return u**3 * c[..., 0, :] + 3 * u * u * t * c[..., 1, :] + 3 * u * t * t * c[..., 2, :] + t**3 * c[..., 3, :]


def cubics_at(ctrl: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``cubic_at`` of each of K cubics ``ctrl (K, 4, 2)`` at its own parameters ``t (K, N)``:
    ``(K, N, 2)``, each row bit for bit ``cubic_at(ctrl[k], t[k])``."""
    t, c = t[..., None], ctrl[:, None]  # (K, N, 1), (K, 1, 4, 2)
    u = 1 - t
    return u**3 * c[..., 0, :] + 3 * u * u * t * c[..., 1, :] + 3 * u * t * t * c[..., 2, :] + t**3 * c[..., 3, :]


def segments_of(points: np.ndarray) -> np.ndarray:
    """``points (..., 3S, 2)`` -> ``(..., S, 4, 2)``: ``[p0, p1, p2, p3]`` of each segment."""
    points = np.asarray(points)
    if points.shape[-1] != 2 or points.shape[-2] % 3 != 0 or points.shape[-2] == 0:
        raise ValueError(f"points must be (..., 3S, 2) with S >= 1, got {points.shape}")
    seg = points.reshape(*points.shape[:-2], points.shape[-2] // 3, 3, 2)
    nxt = np.roll(seg[..., 0, :], -1, axis=-2)  # (..., S, 2): the next anchor
    return np.concatenate([seg, nxt[..., None, :]], axis=-2)


@functools.lru_cache(maxsize=16)
def _weights(samples: int) -> np.ndarray:
    """Cubic Bernstein weights ``(samples, 4)`` at ``t = i / samples`` (shared: do not modify)."""
    w = cubic_at(np.eye(4)[..., None].repeat(2, -1), np.arange(samples, dtype=np.float64) / samples)[..., 0].T
    w.setflags(write=False)
    return w


def flatten_ring(points: np.ndarray, samples: int) -> np.ndarray:
    """A closed cubic path ``(..., 3S, 2)`` sampled ``samples`` times a segment: the vertices
    ``(..., S * samples, 2)`` of its closed polyline (``bezier.flatten_closed`` on arrays)."""
    return flatten_cubics(segments_of(np.asarray(points, dtype=np.float64)), samples)


def flatten_cubics(ctrl: np.ndarray, samples: int) -> np.ndarray:
    """Cubics ``(..., S, 4, 2)`` each sampled at ``t = i / samples``, ``i < samples``, one after
    the other: ``(..., S * samples, 2)`` (``flatten_ring`` of a closed path's segments)."""
    if samples < 1:
        raise ValueError(f"samples must be >= 1, got {samples}")
    verts = np.einsum("lk,...skc->...slc", _weights(samples), ctrl)  # (..., S, L, 2)
    return verts.reshape(*verts.shape[:-3], -1, 2)


def ring_area(verts: np.ndarray) -> np.ndarray:
    """Signed shoelace area of closed polylines ``(..., V, 2)`` -> ``(...)``."""
    x, y = verts[..., 0], verts[..., 1]
    x1, y1 = (np.concatenate([a[..., 1:], a[..., :1]], -1) for a in (x, y))  # np.roll(a, -1, -1), without its overhead
    return 0.5 * (x * y1 - x1 * y).sum(-1)


def _next_places(sizes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For items laid end to end in runs of ``sizes`` (each at least 1): each run's first place and, per
    item, the place of the next one along its run (closed: the last's next is the first)."""
    first = np.cumsum(sizes) - sizes
    nxt = np.arange(1, int(sizes.sum()) + 1)
    nxt[first + sizes - 1] = first
    return first, nxt


def ring_areas(rings: list[np.ndarray]) -> np.ndarray:
    """``ring_area`` of closed polylines of different lengths ``[(V_i, 2)]`` (each V_i >= 1) at once: ``(n,)``."""
    if not rings:
        return np.zeros(0)
    pts = np.concatenate(rings)
    first, nxt = _next_places(np.array([len(r) for r in rings]))
    return 0.5 * np.add.reduceat(pts[:, 0] * pts[nxt, 1] - pts[nxt, 0] * pts[:, 1], first)


def contour_areas(contours: list[np.ndarray], samples: int) -> np.ndarray:
    """Signed areas of closed cubic paths of different lengths ``[(3S_i, 2)]``, each flattened ``samples``
    times a segment (``flatten_ring``), at once: ``(n,)``."""
    if not contours:
        return np.zeros(0)
    seg = np.concatenate([c.reshape(-1, 3, 2) for c in contours])  # (S, 3, 2): anchor, control, control
    count = np.array([len(c) // 3 for c in contours])
    _, nxt = _next_places(count)
    verts = flatten_cubics(np.concatenate([seg, seg[nxt, :1]], 1), samples)  # (S * samples, 2)
    return ring_areas(np.split(verts, np.cumsum(samples * count)[:-1]))
