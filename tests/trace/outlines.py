"""What the clean-outline tests share: exact SVG pictures, their ink and topology, and the
checks of a clean SVG."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import torch
from scipy.ndimage import distance_transform_edt, label

from im2vec_cli.model.pretrained import REPO_MODELS
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


def no_background_inside(svg: str, truth_svg: str, scale: int = 4, depth: float = 1.0) -> bool:
    """No near-white pixel of the render lies ``depth`` input px or more inside the true ink."""
    truth = ink(truth_svg, scale)
    inner = distance_transform_edt(np.pad(truth, 1))[1:-1, 1:-1] > depth * scale
    return not (inner & (rasterize_svg(svg, 64 * scale, 64 * scale).min(-1) > 0.9)).any()
