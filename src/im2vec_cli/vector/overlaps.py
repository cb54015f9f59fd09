"""Overlapping contours of an even-odd shape: keep them as holes, or fill them (nonzero).

The fonts, MNIST and icons models draw each image as *one* shape whose paths combine under
the even-odd rule, so a counter (the hole of an "o") is simply a path inside another. Where
two paths that should add up overlap a little instead of meeting edge to edge, even-odd
punches that overlap out: a thin white seam across the glyph. The same shape written under
the nonzero rule, with each hole path reversed, keeps every true hole and fills the seams.

Which paths are holes is read off the image being vectorised: every orientation of the
paths (the first one fixed) is rasterised under nonzero, and the variant nearest the image
in L2 replaces the even-odd shape when it is nearer than the even-odd original. ``vectorize``
and refinement use it; ``sample`` and ``interpolate`` have no image to read it from, and
draw their frames clean instead (``trace.cleaned``).

Frame: ``VectorImage`` pixel frame (``image.py``); the image is the input ``(3, H, W)`` in
[0, 1] on the same canvas. Contours keep the wrap-around cubic layout when reversed.
"""

from __future__ import annotations

import itertools

import numpy as np
import torch
import torch.nn.functional as F

from ..raster import composite_over, flatten_closed, inside_from_winding, winding_number
from .image import VectorImage, VectorShape


def reverse_contour(points: np.ndarray) -> np.ndarray:
    """The same closed cubic contour ``(3S, 2)`` traversed the other way, first anchor kept.

    ``[a0, c0, d0, a1, c1, d1, ...]`` (segment ``i``: ``a_i, c_i, d_i, a_{i+1}``) becomes
    ``[a0, d_{S-1}, c_{S-1}, a_{S-1}, ...]``.
    """
    return np.roll(np.asarray(points)[::-1], 1, axis=0).copy()


def _windings(contours: list[np.ndarray], scale: tuple[float, float], size: tuple[int, int], samples: int) -> torch.Tensor:
    """Winding number of each contour at the pixel centres of a ``size = (H, W)`` grid.

    Contours are in the canvas's pixel frame, multiplied by ``scale = (sx, sy)`` into the grid's.

    Returns:
        ``(N, H, W)`` float.
    """
    polys = [flatten_closed(torch.as_tensor(c, dtype=torch.float64), samples) * torch.tensor(scale, dtype=torch.float64)
             for c in contours]  # N x (E_i, 2)
    e = max(len(p) for p in polys)
    # pad with copies of the last vertex: zero-length edges cross no row
    verts = torch.stack([torch.cat([p, p[-1:].expand(e - len(p), 2)]) for p in polys])  # (N, E, 2)
    return winding_number(verts, torch.roll(verts, -1, 1), *size, eager=True)


def resolve_overlaps(
    vec: VectorImage, image: torch.Tensor, *, max_contours: int = 6, max_side: int = 128, samples: int = 8
) -> VectorImage:
    """Rewrite each even-odd shape of ``vec`` under nonzero where that is nearer ``image``.

    Shapes are visited back to front; each even-odd shape of 2 to ``max_contours`` contours
    tries the ``2^(n-1)`` orientations of its contours under nonzero, scored by the L2 of a
    2x2-supersampled hard render of the whole image (at most ``max_side`` pixels a side)
    against ``image``. Other shapes are copied unchanged.

    Args:
        vec: the vector image, in the pixel frame of ``image``.
        image: ``(3, H, W)`` in [0, 1], the picture ``vec`` was made from.

    Returns:
        A new ``VectorImage``; a shape that changed has ``fill_rule="nonzero"``.
    """
    if image.dim() != 3 or image.shape[0] != 3:
        raise ValueError(f"image must be (3, H, W), got {tuple(image.shape)}")
    todo = [g for g, s in enumerate(vec.shapes) if s.fill_rule == "evenodd" and 2 <= len(s.contours) <= max_contours]
    if not todo:
        return vec
    image = image.detach().cpu()
    _, h, w = image.shape
    f = min(1.0, max_side / max(h, w))
    hs, ws = max(1, round(h * f)), max(1, round(w * f))
    target = F.interpolate(image[None].double(), size=(hs, ws), mode="area")[0] if f < 1 else image.double()  # (3, h, w)
    scale = (2 * ws / vec.width, 2 * hs / vec.height)

    def coverage(wind: torch.Tensor, signs: torch.Tensor, rule: str) -> torch.Tensor:
        """``wind (N, 2h, 2w)`` of each contour, ``signs (C, N)`` -> ``(C, h, w)`` box-filtered coverage."""
        total = torch.einsum("cn,nyx->cyx", signs, wind).round()  # (C, 2h, 2w)
        return F.avg_pool2d(inside_from_winding(total, rule).double()[:, None], 2)[:, 0]

    shapes = list(vec.shapes)
    winds = [_windings(s.contours, scale, (2 * hs, 2 * ws), samples) for s in shapes]  # G x (N_g, 2h, 2w)
    covs = torch.stack([coverage(wd, torch.ones(1, len(wd), dtype=torch.float64), s.fill_rule)[0]
                        for s, wd in zip(shapes, winds)])  # (G, h, w)
    colors = torch.tensor([s.color for s in shapes], dtype=torch.float64)  # (G, 3)
    depth = torch.arange(len(shapes), dtype=torch.float64)  # (G,): listed back to front
    for g in todo:
        n = len(shapes[g].contours)
        signs = torch.tensor([(1,) + t for t in itertools.product((1, -1), repeat=n - 1)], dtype=torch.float64)  # (C, n)
        options = torch.cat([covs[g][None], coverage(winds[g], signs, "nonzero")])  # (1 + C, h, w); option 0: even-odd
        stack = covs[None].repeat(len(options), 1, 1, 1)  # (1 + C, G, h, w)
        stack[:, g] = options
        out = composite_over(stack, colors.expand(len(options), -1, -1), depth.expand(len(options), -1))  # (1 + C, 3, h, w)
        err = ((out - target[None]) ** 2).mean(dim=(1, 2, 3))  # (1 + C,)
        best = int(torch.argmin(err))
        if best == 0 or err[best] >= err[0] - 1e-9:
            continue
        sg = signs[best - 1].tolist()
        cs = [c if s > 0 else reverse_contour(c) for c, s in zip(shapes[g].contours, sg)]
        shapes[g] = VectorShape(cs, shapes[g].color, "nonzero")
        covs[g] = options[best]
    return VectorImage(vec.width, vec.height, shapes)
