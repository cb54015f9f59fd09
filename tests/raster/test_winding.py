"""raster/winding.py: winding numbers of closed polylines, against a ray-crossing count written here
(NumPy, one point and one edge at a time)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from im2vec_cli.raster.winding import edge_boundary, point_winding, point_winding_banded, winding_number


def reference(px: float, py: float, verts: np.ndarray) -> int:
    """Signed crossings of the ray from (px, py) to +x by the closed polyline ``verts (V, 2)``."""
    w = 0
    for (x0, y0), (x1, y1) in zip(verts, np.roll(verts, -1, 0)):
        if (y0 <= py) != (y1 <= py):
            x = x0 + (py - y0) * (x1 - x0) / (y1 - y0)
            if x > px:
                w += 1 if y1 > y0 else -1
    return w


def star(n: int = 5, r: float = 9.0, cx: float = 12.3, cy: float = 11.7) -> np.ndarray:
    """A self-intersecting {n/2} star: winding 2 at its centre, 1 in its points."""
    k = np.arange(n) * 2 * (2 * math.pi / n)
    return np.stack([cx + r * np.cos(k), cy + r * np.sin(k)], -1)


def edges(verts: np.ndarray) -> tuple[torch.Tensor, torch.Tensor]:
    a = torch.tensor(verts, dtype=torch.float64)[None]
    return a, torch.roll(a, -1, 1)


@pytest.mark.parametrize("verts", [star(), star()[::-1].copy(), np.array([[3.2, 2.1], [20.5, 4.0], [9.7, 19.9]])],
                         ids=["star", "star reversed", "triangle"])
def test_every_pixel_centre_and_any_point_get_the_reference_count(verts):
    a, b = edges(verts)
    grid = winding_number(a.float(), b.float(), 24, 24, eager=True)[0]  # (24, 24) at pixel centres
    ref = np.array([[reference(x + 0.5, y + 0.5, verts) for x in range(24)] for y in range(24)])
    assert grid.shape == (24, 24) and (grid.numpy() == ref).all()
    assert ref.min() < 0 or ref.max() >= 1  # the case draws something
    pts = torch.rand(1, 200, 2, generator=torch.Generator().manual_seed(1), dtype=torch.float64) * 24
    want = [reference(x, y, verts) for x, y in pts[0].tolist()]
    assert point_winding(pts, a, b)[0].tolist() == want
    assert point_winding_banded(pts, a, b)[0].tolist() == want


def area(verts: np.ndarray) -> float:
    return 0.5 * float((verts[:, 0] * np.roll(verts[:, 1], -1) - np.roll(verts[:, 0], -1) * verts[:, 1]).sum())


@pytest.mark.parametrize("same_way", [True, False])
def test_an_edge_between_two_filled_windings_is_not_a_boundary(same_way):
    """Under nonzero, a bar inside a square wound the same way lies between winding 1 and 2: its
    edges bound nothing; wound the other way it is a hole (winding 0), and its edges are boundary."""
    square = np.array([[2.0, 2.0], [22.0, 2.0], [22.0, 22.0], [2.0, 22.0]])
    bar = np.array([[12.0, 5.0], [12.0, 18.0], [13.0, 18.0], [13.0, 5.0]])
    if ((area(bar) > 0) == (area(square) > 0)) != same_way:
        bar = bar[::-1].copy()
    (a1, b1), (a2, b2) = edges(square), edges(bar)
    keep = edge_boundary(torch.cat([a1, a2], 1), torch.cat([b1, b2], 1))[0]
    assert keep[:4].all() and bool(keep[4:].any()) != same_way and bool(keep[4:].all()) != same_way
