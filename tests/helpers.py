"""Shapes used by several tests."""

import math

import torch


def circle(cx, cy, r, segments=8, dtype=torch.float64):
    """A closed cubic circle ``(3S, 2)`` with the standard 4/3 tan(theta/4) handles."""
    k = 4 / 3 * math.tan(math.pi / (2 * segments))
    pts = []
    for s in range(segments):
        a0, a1 = 2 * math.pi * s / segments, 2 * math.pi * (s + 1) / segments
        p0 = (cx + r * math.cos(a0), cy + r * math.sin(a0))
        p3 = (cx + r * math.cos(a1), cy + r * math.sin(a1))
        c1 = (p0[0] - k * r * math.sin(a0), p0[1] + k * r * math.cos(a0))
        c2 = (p3[0] + k * r * math.sin(a1), p3[1] - k * r * math.cos(a1))
        pts += [p0, c1, c2]
    return torch.tensor(pts, dtype=dtype)


def star(cx, cy, r_out, r_in, spikes, dtype=torch.float64, generator=None):
    """A star-like closed path with straight edges (as degenerate cubics), ``(3 * 2k, 2)``."""
    verts = []
    for i in range(2 * spikes):
        r = r_out if i % 2 == 0 else r_in
        if generator is not None:
            r = r * (0.8 + 0.4 * float(torch.rand((), generator=generator)))
        a = math.pi * i / spikes
        verts.append((cx + r * math.cos(a), cy + r * math.sin(a)))
    return polyline_as_cubic(verts, dtype)


def polyline_as_cubic(verts, dtype=torch.float64):
    pts = []
    n = len(verts)
    for i in range(n):
        a, b = torch.tensor(verts[i]), torch.tensor(verts[(i + 1) % n])
        pts += [a, a + (b - a) / 3, a + 2 * (b - a) / 3]
    return torch.stack(pts).to(dtype)
