"""Clean outlines of a batch of pictures, read top to bottom as its stage list (like vtracer's
pipeline: segment -> fit -> composite -> optimise -> write):

1. ``starts``: each picture's own regions (``regions.trace``) and, for a two-tone picture when a
   model is at hand, the model's refined paths (``outline.redrawn``);
2. ``choose``: of two starts, the one nearer the picture, both fitted at ``CHOICE_TOLERANCE``;
3. fit: the chosen start's rings fitted with cubics within ``tolerance`` px, corners kept sharp
   (``Start.outline``);
4. ``polish``: points and colours through the differentiable renderer (the ``Polisher``:
   refinement's optimiser), smooth joins kept smooth; not an exact outline (a hard-edged
   picture's pixel edges) nor one of more than ``polish_segments`` segments;
5. ``split_and_polish``: segments along which the render is still wrong halved
   (``split_where_wrong``) and polished again, kept where nearer;
6. ``finish``: crossings ``untangle``-d, written nonzero.

Frame: the pixel frame of each picture; pictures are ``(H, W, 3)`` float64 arrays in [0, 1]. A
batch none of whose pictures is polished needs no renderer (``polisher`` None) and no torch.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from ..events import Stage
from ..options import Plan
from ..raster.curves import flatten_ring
from ..vector import VectorImage, VectorShape, fill_vector
from .fit import Corners, split_segments
from .outline import redrawn, traced
from .read import Reading
from .regions import background_color, two_tone
from .untangle import untangle

CHOICE_TOLERANCE = 0.25  # px: the clean-outline starts are compared fitted this closely


class Polisher(Protocol):
    """What the pipeline needs of the renderer (``refine.Refinement`` is one): a judge and a
    polish of vector images, each against the batch's picture ``index[i]``."""

    def loss(self, vecs: list[VectorImage], index: list[int]) -> list[float]: ...

    def polish_outline(self, vecs: list[VectorImage], flags: list[Corners], index: list[int]) -> list[VectorImage]: ...


ModelPaths = Callable[[list[int]], list[tuple[VectorImage, dict]]]  # picture indices -> (paths, summary) each


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

    def outline(self, tol: float) -> tuple[VectorImage, Corners, bool]:
        """Fitted within ``tol`` px, even-odd: the contours of a clean shape do not overlap, so
        even-odd renders them as nonzero does, without the renderer's boundary search
        (seconds on a picture of many regions). ``finish`` writes them nonzero. The flag:
        the outline is exact (``outline.traced``), not to be polished."""
        if self.paths is None:
            vec, flags, exact = traced(self.picture, tol, self.colors, self.max_paths, self.kind, self.tone)
        else:
            (vec, flags), exact = redrawn(self.paths, tol, self.picture), False
        return with_rule(vec, "evenodd"), flags, exact


def clean_outlines(pictures: list[np.ndarray], polisher: Polisher | None, s: Plan = Plan(), *,
                   model_paths: ModelPaths | None = None, readings: list[Reading] | None = None,
                   on_stage: Callable[[Stage], None] | None = None) -> list[tuple[VectorImage, dict]]:
    """Clean outlines of ``pictures`` (each ``(H, W, 3)`` in [0, 1]): non-overlapping outer
    contours and holes, nonzero, fitted within ``s.tolerance`` px and polished against the
    picture (``s``: the run's ``options.Plan``; ``s.colors`` and ``s.max_paths`` shape the palette).
    ``model_paths`` gives the model's paths of pictures (the second start).
    ``readings``: what each picture is (``read.read``: ``images`` are their clean pictures); its
    kind shapes the trace (pixel art along its pixel edges), the palette of a photo and
    whether the outline is polished (``polished``); ``polisher`` may be None where none is.
    ``on_stage`` hears each stage done (``events.STAGES``).

    Returns per picture the vector image and a summary: ``loss_end`` (the polisher's loss),
    ``start`` (which start was kept), ``segments``, and the model stage's figures where it ran.
    """
    readings = readings or [Reading("", pic) for pic in pictures]
    each = [r.colors if s.colors is None else s.colors for r in readings]
    polish_these = [polished(r, pic.shape, s) for r, pic in zip(readings, pictures)]
    if polisher is None and any(polish_these):
        raise ValueError("a picture to polish needs a polisher")
    starts, info = _starts(pictures, s, each, readings, polish_these, model_paths)
    chosen = choose(starts, polisher)
    made = [start.outline(s.tolerance * r.loose) for start, r in zip(chosen, readings)]
    tell = on_stage or (lambda _: None)
    tell(Stage("traced"))
    vecs, flags = [v for v, _, _ in made], [f for _, f, _ in made]
    todo = [i for i, (v, _, exact) in enumerate(made)  # an empty one has nothing to draw, an exact one nothing
            if v.shapes and not exact and v.num_segments <= s.polish_segments and polish_these[i]]  # to fix
    vecs, loss = polish(polisher, vecs, flags, todo) if todo else (vecs, {})
    if s.split_error > 0 and loss:
        vecs, loss = split_and_polish(polisher, pictures, vecs, flags, loss, s)
    tell(Stage("polished"))
    out = [finish(polisher, i, vecs[i], loss.get(i), info[i], chosen[i].name, judge=polish_these[i])
           for i in range(len(vecs))]
    tell(Stage("finished"))
    return out


def polished(reading: Reading, shape: tuple[int, ...], s: Plan) -> bool:
    """Whether the picture of ``shape (H, W, ...)`` read as ``reading`` is polished through the
    renderer (the only stage that needs torch): not at ``--effort draft``, nor pixel art or a
    photo (``Reading.polish``), nor a picture of a longer side than the polish's ``s.max_side``."""
    return s.polish and reading.polish and max(shape[:2]) <= s.max_side


def _starts(pictures: list[np.ndarray], s: Plan, colors: list[int | None], readings: list[Reading],
            polished: list[bool], model_paths: ModelPaths | None) -> tuple[list[list[Start]], list[dict]]:
    """Per picture its starts (the image's own first) and the model stage's summary (or ``{}``).

    Multi-colour pictures start from their own regions only: the shipped emoji model's paths
    lost to them on every OpenMoji face tried (bench/outlines.py) and cost seconds. So do
    pictures that are not polished (``polished``): the model's paths are drawn at the polish's
    size, coarser than the picture's own trace."""
    starts = [[Start("image", pic, colors=k, max_paths=s.max_paths, kind=r.kind, tone=r.tone)]
              for pic, k, r in zip(pictures, colors, readings)]
    info: list[dict] = [{} for _ in pictures]
    if model_paths is None or not s.model_start:
        return starts, info
    two = [i for i, pic in enumerate(pictures)
           if colors[i] in (None, 1) and polished[i] and readings[i].kind != "pixel"
           and (readings[i].tone is not None or two_tone(pic, background_color(pic)) is not None)]
    if two:
        for i, (paths, summary) in zip(two, model_paths(two)):
            info[i] = summary
            if paths.shapes:
                starts[i].append(Start("model", pictures[i], paths=paths))
    return starts, info


def choose(starts: list[list[Start]], polisher: Polisher) -> list[Start]:
    """Per picture the start nearer it, judged at ``CHOICE_TOLERANCE`` for all, so that a looser
    tolerance never changes the choice (the polish moves points by a fraction of a pixel: it
    does not reorder the starts)."""
    both = [i for i, st in enumerate(starts) if len(st) > 1]
    chosen = [st[0] for st in starts]
    if both:
        cands = [(i, start) for i in both for start in starts[i]]
        scores = polisher.loss([start.outline(CHOICE_TOLERANCE)[0] for _, start in cands], [i for i, _ in cands])
        for i in both:
            best = min((sc, start.name) for (j, start), sc in zip(cands, scores) if j == i)[1]
            chosen[i] = next(start for start in starts[i] if start.name == best)
    return chosen


def polish(polisher: Polisher, vecs: list[VectorImage], flags: list[Corners], todo: list[int]
           ) -> tuple[list[VectorImage], dict[int, float]]:
    """The pictures ``todo`` polished (the others as they are) and the loss of each polished one."""
    got = polisher.polish_outline([vecs[i] for i in todo], [flags[i] for i in todo], todo)
    out = list(vecs)
    for i, v in zip(todo, got):
        out[i] = v
    return out, dict(zip(todo, polisher.loss(got, todo)))


def split_and_polish(polisher: Polisher, pictures: list[np.ndarray], vecs: list[VectorImage], flags: list[Corners],
                     loss: dict[int, float], s: Plan) -> tuple[list[VectorImage], dict[int, float]]:
    """Each polished picture's segments that are still wrong halved and polished again; the
    new result kept where its loss is lower."""
    split = {}
    for i in loss:
        v, f, count = split_where_wrong(vecs[i], flags[i], pictures[i], s)
        if count:
            split[i] = (v, f)
    again = list(split)
    out, loss = list(vecs), dict(loss)
    if again:
        got = polisher.polish_outline([split[i][0] for i in again], [split[i][1] for i in again], again)
        for i, v, sc in zip(again, got, polisher.loss(got, again)):
            if sc < loss[i]:
                out[i], loss[i] = v, sc
    return out, loss


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


def finish(polisher: Polisher, i: int, vec: VectorImage, loss: float | None, info: dict, start: str,
           judge: bool = True) -> tuple[VectorImage, dict]:
    """Picture ``i``'s result written nonzero and untangled, with its summary (one never
    polished, empty or exact, is judged as it is; with ``judge`` False, not at all: a draft
    renders nothing)."""
    if loss is None and judge:
        loss = polisher.loss([vec], [i])[0]
    v = untangle(with_rule(vec, "nonzero"))
    return v, {**info, "loss_end": loss, "start": start, "segments": v.num_segments}


def with_rule(vec: VectorImage, rule: str) -> VectorImage:
    """``vec`` with every shape under ``rule``."""
    return VectorImage(vec.width, vec.height, [VectorShape(sh.contours, sh.color, rule) for sh in vec.shapes])


def _box3(a: np.ndarray) -> np.ndarray:
    """The mean of each pixel's 3 x 3 neighbourhood, edges mirrored (``scipy.ndimage.uniform_filter(a, 3)``,
    without importing SciPy's 0.3 s of modules for it)."""
    p = np.pad(a, 1, mode="symmetric")
    rows = (p[:-2] + p[1:-1] + p[2:]) / 3
    return (rows[:, :-2] + rows[:, 1:-1] + rows[:, 2:]) / 3
