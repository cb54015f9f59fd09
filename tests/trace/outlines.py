"""What the clean-outline tests share: exact SVG pictures, their ink and topology, and the
checks of a clean SVG."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import torch
from scipy.ndimage import distance_transform_edt, label

from im2vec_cli.config import REPO_MODELS
from im2vec_cli.vector import rasterize_svg

needs_fonts = pytest.mark.skipif(not (REPO_MODELS / "fonts" / "config.json").exists(), reason="no shipped fonts model")
needs_emoji = pytest.mark.skipif(not (REPO_MODELS / "emoji" / "config.json").exists(), reason="no shipped emoji model")


def svg_of(body: str, size: int = 64) -> str:
    return f'<svg xmlns="http://www.w3.org/2000/svg" width="{size}" height="{size}" viewBox="0 0 {size} {size}">{body}</svg>'


def picture(body: str, size: int = 64):
    """``(3, H, W)`` tensor of an exact SVG rendered by cairo (anti-aliased, over white)."""
    return torch.from_numpy(rasterize_svg(svg_of(body, size), size, size)).permute(2, 0, 1).float()


def ink(svg: str, scale: int) -> np.ndarray:
    return rasterize_svg(svg, 64 * scale, 64 * scale).mean(-1) < 0.5


def topology(mask: np.ndarray) -> tuple[int, int]:
    """Pieces (8-connected) and holes (4-connected background not touching the border)."""
    _, pieces = label(mask, structure=np.ones((3, 3)))
    bg, n = label(~mask)
    border = set(np.unique(np.concatenate([bg[0], bg[-1], bg[:, 0], bg[:, -1]]))) - {0}
    return pieces, n - len(border)


def check_clean_svg(svg: str) -> list[str]:
    """Valid XML whose every <path> is closed cubics only (M, C, Z); returns the d strings."""
    root = ET.fromstring(svg)
    ds = [el.get("d") for el in root.iter() if el.tag.endswith("path")]
    for d in ds:
        assert re.fullmatch(r"(M [-\d. ]+( C [-\d. ]+)+ Z ?)+", d.strip() + " "), d[:80]
    return ds


def no_background_inside(svg: str, truth_svg: str, scale: int = 4, depth: float = 1.0, colour: bool = False) -> bool:
    """No near-white pixel of the render lies ``depth`` input px or more inside the true ink
    (``colour``: any colour 0.1 off white in a channel, a light grey too, as bench/outlines.py)."""
    truth = ink(truth_svg, scale) if not colour else (1 - rasterize_svg(truth_svg, 64 * scale, 64 * scale)).max(-1) > 0.1
    inner = distance_transform_edt(np.pad(truth, 1))[1:-1, 1:-1] > depth * scale
    return not (inner & (rasterize_svg(svg, 64 * scale, 64 * scale).min(-1) > 0.9)).any()


OPENMOJI_COLOURS = ["#d0cfce", "#92d3f5", "#fcea2b", "#fadcbc", "#b1cc33", "#ea5a47"]  # OpenMoji's palette


def openmoji_like(seed: int) -> str:
    """An SVG drawn as OpenMoji draws (its colours, black lines 2 units wide over the fills, a
    72-unit frame at 64 px): one or two ellipses, each with an arc of line along its edge, and one
    to three curves of line across them."""
    rng = np.random.default_rng(seed)
    line = 'fill="none" stroke="#000" stroke-width="2" stroke-linecap="round" stroke-linejoin="round"'
    out = []
    for _ in range(rng.integers(1, 3)):
        cx, cy, rx, ry = rng.uniform(24, 48), rng.uniform(24, 48), rng.uniform(12, 24), rng.uniform(12, 24)
        out.append(f'<ellipse cx="{cx:.1f}" cy="{cy:.1f}" rx="{rx:.1f}" ry="{ry:.1f}" '
                   f'fill="{OPENMOJI_COLOURS[rng.integers(len(OPENMOJI_COLOURS))]}"/>')
        a0 = rng.uniform(0, 6.28)
        a1 = a0 + rng.uniform(1.5, 6.2)
        x0, y0, x1, y1 = cx + rx * np.cos(a0), cy + ry * np.sin(a0), cx + rx * np.cos(a1), cy + ry * np.sin(a1)
        out.append(f'<path {line} d="M{x0:.1f} {y0:.1f} A{rx:.1f} {ry:.1f} 0 {int(a1 - a0 > 3.14)} 1 {x1:.1f} {y1:.1f}"/>')
    for _ in range(rng.integers(1, 4)):
        p = rng.uniform(10, 62, 8)
        out.append(f'<path {line} d="M{p[0]:.1f} {p[1]:.1f} C{p[2]:.1f} {p[3]:.1f} {p[4]:.1f} {p[5]:.1f} {p[6]:.1f} {p[7]:.1f}"/>')
    return f'<svg xmlns="http://www.w3.org/2000/svg" width="64" height="64" viewBox="0 0 72 72">{"".join(out)}</svg>'
