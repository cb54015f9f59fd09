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


def synthetic_shapes(n: int, size: int, seed: int = 0):
    """``n`` black shapes on white (circles, stars, DejaVu letters when installed), uint8
    ``(n, 3, size, size)``, rendered by cairosvg."""
    import os

    import numpy as np

    from im2vec_cli.svg import VectorImage, VectorShape, rasterize_svg, to_svg

    g = torch.Generator().manual_seed(seed)
    font = None
    path = "/usr/share/fonts/truetype/dejavu/DejaVuSans-Bold.ttf"
    if os.path.exists(path):
        from fontTools.ttLib import TTFont

        font = TTFont(path)
    out = []
    for i in range(n):
        kind = i % 3
        u = lambda lo, hi: lo + (hi - lo) * float(torch.rand((), generator=g))  # noqa: E731
        if kind == 2 and font is not None:
            from im2vec_cli.data.glyphs import glyph_image

            img = glyph_image(font, "LTVIJZN"[i % 7], size=size, margin=size / 8)
        else:
            cx, cy = u(0.35, 0.65) * size, u(0.35, 0.65) * size
            c = circle(cx, cy, u(0.15, 0.3) * size) if kind == 0 else star(cx, cy, u(0.25, 0.35) * size, u(0.1, 0.15) * size, 5, generator=g)
            img = VectorImage(size, size, [VectorShape([c.numpy()], (0, 0, 0), "nonzero")])
        arr = rasterize_svg(to_svg(img, 3), size, size)
        out.append(torch.from_numpy(np.round(arr * 255).astype(np.uint8)).permute(2, 0, 1))
    return torch.stack(out)
