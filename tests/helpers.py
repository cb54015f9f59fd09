"""Shapes and CLI helpers used by several tests."""

import math
from xml.etree import ElementTree

import numpy as np
import torch
from click.testing import CliRunner
from PIL import Image

from im2vec_cli.cli import cli
from im2vec_cli.config import ModelConfig
from im2vec_cli.raster.bezier import line_controls
from im2vec_cli.vector import rasterize_svg


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
        pts += [a, *line_controls(a, b)]
    return torch.stack(pts).to(dtype)


def synthetic_shapes(n: int, size: int, seed: int = 0):
    """``n`` black shapes on white (circles, stars, DejaVu letters when installed), uint8
    ``(n, 3, size, size)``, rendered by cairosvg."""
    import os

    from im2vec_cli.vector import VectorImage, VectorShape, rasterize_svg, to_svg

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


TINY = ModelConfig(image_size=32, latent=16, enc_width=8, lstm_hidden=16, code=8, dec_width=16, dec_layers=3,
                   deform_width=8, segments=6)


def make_tiny_model(folder) -> str:
    """Save a small random model (decoder head perturbed so paths are not degenerate)."""
    from im2vec_cli.model.pretrained import save_pretrained
    from im2vec_cli.model.vae import Im2Vec

    torch.manual_seed(0)
    m = Im2Vec(TINY)
    for p in m.decoder.net[-1].parameters():
        p.data.normal_(0, 0.05)
    save_pretrained(m, folder)
    return str(folder)


def png(path, w=40, h=24, mode="RGB"):
    """A white image with a centred dark rectangle."""
    arr = np.full((h, w, 3), 255, np.uint8)
    arr[h // 4 : 3 * h // 4, w // 4 : 3 * w // 4] = 0
    Image.fromarray(arr).convert(mode).save(path)
    return str(path)


def run(args, **kw):
    return CliRunner().invoke(cli, args, catch_exceptions=False, **kw)


def check_svg(text, w, h):
    """Parses as XML, viewBox is the input's pixel frame, closed M..C..Z paths, renders."""
    root = ElementTree.fromstring(text)
    assert root.get("viewBox") == f"0 0 {w} {h}"
    paths = list(root.iter("{http://www.w3.org/2000/svg}path"))
    for p in paths:
        d = p.get("d")
        assert d.startswith("M") and d.rstrip().endswith("Z")
    assert rasterize_svg(text, w, h).shape == (h, w, 3)
    return paths


def descend(error, params, steps: int = 40, lr: float = 1e-2) -> tuple[float, float]:
    """``steps`` of Adam on ``params`` down ``error()`` (a scalar tensor); its value before and after."""
    opt = torch.optim.Adam(list(params), lr=lr)
    with torch.no_grad():
        before = float(error())
    for _ in range(steps):
        opt.zero_grad()
        error().backward()
        opt.step()
    with torch.no_grad():
        return before, float(error())
