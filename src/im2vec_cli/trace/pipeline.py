"""The stages of clean outlines (``refine.clean`` runs them in order, with the renderer where a
picture is polished and without it where none is):

1. ``image_starts``: each picture's own regions (``regions.trace``), and ``model_start_wanted``:
   which pictures also start from the model's refined paths (``Start`` with ``paths``,
   ``outline.redrawn``);
2. fit: a start's rings fitted with cubics within ``tolerance`` px, corners kept sharp
   (``Start.outline``), the two starts compared fitted at ``CHOICE_TOLERANCE``;
3. ``polished``: whether a picture is polished through the renderer at all;
4. ``split_where_wrong``: segments along which the render is still wrong halved, for another polish;
5. ``finished``: crossings ``untangle``-d, written nonzero.

Frame: the pixel frame of each picture; pictures are ``(H, W, 3)`` float64 arrays in [0, 1].
NumPy only: nothing here renders through torch.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..options import Plan
from ..raster.curves import flatten_ring
from ..vector import VectorImage, VectorShape, fill_vector
from .fit import Corners
from .outline import redrawn, traced
from .read import Reading
from .regions import background_color, two_tone
from .simplify import split_segments
from .untangle import untangle

CHOICE_TOLERANCE = 0.25  # px: the clean-outline starts are compared fitted this closely


@dataclass(frozen=True)
class Start:
    """One way to a clean outline of ``picture (H, W, 3)``: its own regions (``paths`` None;
    ``colors`` and ``max_paths`` shape the palette) or the model's ``paths`` redrawn."""

    name: str
    picture: np.ndarray
    paths: VectorImage | None = None
    colors: int | None = None
    max_paths: int | None = None
    kind: str = ""  # what the picture was read as (``read.Reading.kind``): pixel art and photos are traced their way
    tone: tuple[np.ndarray, np.ndarray] | None = None  # a two-tone picture's ink and coverage (``read.Reading``)
    speck: int = 0  # px: a photo's smallest piece (``read.Reading``)
    marks: float = 0.0  # and how much a smaller mark stands out
    palette: bool = False  # traced by its palette though it looks two-tone (``read.Reading``)

    def outline(self, tol: float) -> tuple[VectorImage, Corners, bool]:
        """Fitted within ``tol`` px, even-odd: the contours of a clean shape do not overlap, so
        even-odd renders them as nonzero does, without the renderer's boundary search
        (seconds on a picture of many regions). ``finish`` writes them nonzero. The flag:
        the outline is exact (``outline.traced``), not to be polished."""
        if self.paths is None:
            vec, flags, exact = traced(self.picture, tol, self.colors, self.max_paths, self.kind, self.tone,
                                       self.speck, self.marks, self.palette)
        else:
            (vec, flags), exact = redrawn(self.paths, tol, self.picture), False
        return with_rule(vec, "evenodd"), flags, exact


def image_starts(pictures: list[np.ndarray], s: Plan, readings: list[Reading]) -> list[Start]:
    """Each picture's own start: its regions traced as its reading says (``s.colors``,
    ``s.max_paths``)."""
    return [Start("image", pic, colors=s.colors, max_paths=s.max_paths,
                  kind=r.kind, tone=r.tone, speck=r.speck, marks=r.marks, palette=r.palette)
            for pic, r in zip(pictures, readings)]


def model_start_wanted(pictures: list[np.ndarray], s: Plan, readings: list[Reading], polish: list[bool]) -> list[int]:
    """The pictures that also start from the model's paths (``s.model_start``): two-tone ones that are
    polished. Multi-colour pictures start from their own regions only: the shipped emoji model's
    paths lost to them on every OpenMoji face tried (bench/outlines.py) and cost seconds. So do
    pictures that are not polished (``polished``): the model's paths are drawn at the polish's
    size, coarser than the picture's own trace; and pixel art."""
    if not s.model_start:
        return []
    return [i for i, pic in enumerate(pictures)
            if s.colors in (None, 1) and polish[i] and readings[i].kind != "pixel" and not readings[i].palette
            and (readings[i].tone is not None or two_tone(pic, background_color(pic)) is not None)]


def polished(reading: Reading, shape: tuple[int, ...], s: Plan) -> bool:
    """Whether the picture of ``shape (H, W, ...)`` read as ``reading`` is polished through the
    renderer (the only stage that needs torch): not at ``--effort draft``, nor pixel art or a
    photo (``Reading.polish``), nor a picture of a longer side than the polish's ``s.max_side``."""
    return s.polish and reading.polish and max(shape[:2]) <= s.max_side


def split_where_wrong(vec: VectorImage, flags: Corners, picture: np.ndarray, s: Plan
                      ) -> tuple[VectorImage, Corners, int]:
    """Halve every segment along which the render still differs from ``picture (H, W, 3)`` by
    more than ``s.split_error`` (mean squared, over the pixels the segment passes and their
    neighbours, cairo at the input's size; scaled by ``(tolerance / 0.5)^2``): the polish
    then has the points it lacked there.

    Returns the new image, its corner flags and the segments split."""
    h, w, _ = picture.shape
    got = fill_vector(vec, w, h)  # (H, W, 3): cairo, as rasterize_svg(vec.to_svg(3)) draws it
    err = _box3(((got - picture) ** 2).sum(-1))
    limit = s.split_error * (s.tolerance / 0.5) ** 2  # a looser tolerance splits less
    shapes, out_flags, count = [], [], 0
    for sh, fl in zip(vec.shapes, flags):
        cs, fs = [], []
        for c, f in zip(sh.contours, fl):
            pts = flatten_ring(c, 8).reshape(-1, 8, 2)
            ix = np.clip(pts[..., 0].astype(int), 0, w - 1)
            iy = np.clip(pts[..., 1].astype(int), 0, h - 1)
            bad = np.nonzero(err[iy, ix].mean(1) > limit)[0]
            if len(bad) and len(c) // 3 + len(bad) <= s.max_segments:
                c, f = split_segments(c, f, bad)
                count += len(bad)
            cs.append(c)
            fs.append(f)
        shapes.append(VectorShape(cs, sh.color, sh.fill_rule))
        out_flags.append(fs)
    return VectorImage(vec.width, vec.height, shapes), out_flags, count


def finished(vec: VectorImage) -> VectorImage:
    """A clean outline as written: every shape nonzero, its crossings untangled (``untangle``)."""
    return untangle(with_rule(vec, "nonzero"))


def with_rule(vec: VectorImage, rule: str) -> VectorImage:
    """``vec`` with every shape under ``rule``."""
    return VectorImage(vec.width, vec.height, [VectorShape(sh.contours, sh.color, rule) for sh in vec.shapes])


def _box3(a: np.ndarray) -> np.ndarray:
    """The mean of each pixel's 3 x 3 neighbourhood, edges mirrored (``scipy.ndimage.uniform_filter(a, 3)``,
    without importing SciPy's 0.3 s of modules for it)."""
    p = np.pad(a, 1, mode="symmetric")
    rows = (p[:-2] + p[1:-1] + p[2:]) / 3
    return (rows[:, :-2] + rows[:, 1:-1] + rows[:, 2:]) / 3
