"""A batch of pictures read and, where none needs the renderer, vectorized without it: what
``vectorize`` does with every picture that is not polished (larger than the polish's size, pixel
art, photos, ``--effort draft``), in NumPy alone, so that such a picture never imports torch.

Stages: ``workable`` (a picture over the pixel budget at an area-averaged copy) -> ``read`` ->
``flat_result`` (one colour: nothing to trace); ``needs_renderer`` says which pictures are
polished. ``refine.clean`` runs the clean outlines of the others without the renderer
(``trace_alone``) and of these with it (``refine_batch``). Frame: each picture's pixel frame; pictures are
``(H, W, 3)`` arrays in [0, 1].
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..options import Plan
from ..raster.curves import line_controls
from ..vector import VectorImage, VectorShape
from .pipeline import polished
from .read import Reading, read

UNIFORM_TOL = 2 / 255  # a picture whose pixels all lie within this of each other is one flat colour


def uniform_color(picture: np.ndarray) -> tuple[float, float, float] | None:
    """The colour of a flat ``picture (H, W, 3)``, or ``None`` when it has any detail."""
    flat = picture.reshape(-1, picture.shape[-1])
    sample = flat[:: max(1, len(flat) // 1024)]  # a picture with any detail mostly shows it in a sample: at once
    if not ((sample.max(0) - sample.min(0)) <= UNIFORM_TOL).all():
        return None
    if bool(((flat.max(0) - flat.min(0)) <= UNIFORM_TOL).all()):
        return tuple(float(v) for v in flat.mean(0, dtype=np.float64))
    return None


def flat_vector(w: int, h: int, color: tuple[float, float, float]) -> VectorImage:
    """A flat ``w x h`` image as vectors: nothing on white, else one canvas-sized square in ``color``."""
    if min(color) >= 1 - UNIFORM_TOL:
        return VectorImage(float(w), float(h), [])
    corners = np.array([[0, 0], [w, 0], [w, h], [0, h]], dtype=np.float64)
    pts = []
    for i in range(4):  # straight sides as cubics
        a, b = corners[i], corners[(i + 1) % 4]
        pts += [a, *line_controls(a, b)]
    return VectorImage(float(w), float(h), [VectorShape([np.stack(pts)], color, "nonzero")])


def flat_result(picture: np.ndarray) -> VectorImage | None:
    """The vector image of a flat ``picture (H, W, 3)`` (one colour: nothing to fit), else ``None``."""
    color = uniform_color(picture)
    return None if color is None else flat_vector(picture.shape[1], picture.shape[0], color)


FLAT_SUMMARY = {"loss_start": 0.0, "loss_end": 0.0, "latent_steps": 0, "point_steps": 0}


def workable(picture: np.ndarray, most: int) -> np.ndarray:
    """``picture (H, W, 3)``, or its area-averaged copy of at most ``most`` pixels: tracing costs
    memory and time by the pixel (a 64 MP picture: 7.5 GB). (The copy is torch's area resize, as
    refinement's: a picture this large pays torch's import once, on a second's work.)"""
    h, w, _ = picture.shape
    if h * w <= most:
        return picture
    import torch

    f = (most / (h * w)) ** 0.5
    size = (max(4, int(h * f)), max(4, int(w * f)))
    x = torch.from_numpy(np.ascontiguousarray(picture, dtype=np.float32)).permute(2, 0, 1)[None]
    return torch.nn.functional.interpolate(x, size=size, mode="area")[0].permute(1, 2, 0).numpy()


BILEVEL_GRAIN = 0.15  # changes of colour a pixel (to its right and lower neighbours) past which a two-colour
# picture is a dither, a halftone or noise (a 300 dpi page of text: 0.02-0.06; an ordered dither: 1.2)


def bilevel(picture: np.ndarray) -> bool:
    """Whether ``picture (H, W, 3)`` holds at most two colours, exactly (a 1-bit scan, a fax), and
    is not grain (``BILEVEL_GRAIN``: at an averaged copy a dither's grain is the grey it stands for)."""
    flat = picture.reshape(-1, picture.shape[-1])
    other = (flat != flat[0]).any(1)
    if not other.any():
        return True
    b = flat[int(np.argmax(other))]
    if not (~other | (flat == b).all(1)).all():
        return False
    ink = other.reshape(picture.shape[:2])
    changes = np.count_nonzero(ink[:, 1:] != ink[:, :-1]) + np.count_nonzero(ink[1:] != ink[:-1])
    return changes <= BILEVEL_GRAIN * ink.size


def read_pictures(pictures: list[np.ndarray], s: Plan) -> list[Reading]:
    """Each picture (at most ``s.work_pixels`` pixels, or ``s.bilevel_pixels`` if ``bilevel``:
    ``workable``) read (``read.read``, as ``s.preset``, ``s.speckle`` and ``s.colors`` say); its clean
    picture as refinement sees it, in float32."""
    out = []
    for pic in pictures:
        h, w, _ = pic.shape
        most = s.bilevel_pixels if h * w > s.work_pixels and bilevel(pic) else s.work_pixels
        r = read(workable(pic, most).astype(np.float64), s.preset, s.speckle, s.colors)
        out.append(dataclasses.replace(r, picture=r.picture.astype(np.float32).astype(np.float64)))
    return out


def needs_renderer(readings: list[Reading], s: Plan) -> list[bool]:
    """Per reading, whether its picture is polished through the renderer (not flat, ``polished``)."""
    return [polished(r, r.picture.shape, s) and uniform_color(r.picture) is None for r in readings]
