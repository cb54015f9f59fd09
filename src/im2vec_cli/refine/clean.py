"""Clean outlines of a batch of pictures, read top to bottom as its stage list (like vtracer's
pipeline: segment -> fit -> composite -> optimise -> write), over ``trace``'s stages:

1. starts: each picture's own regions (``trace.image_starts``) and, for a two-tone picture when a
   refinement is at hand, the model's refined paths (``stages.model_paths``, redrawn clean);
2. ``choose``: of two starts, the one nearer the picture, both fitted at ``trace.CHOICE_TOLERANCE``;
3. fit: the chosen start's rings fitted with cubics within ``tolerance`` px (``trace.Start.outline``);
4. ``polish``: points and colours through the renderer (``Refinement.polish_outline``), smooth
   joins kept smooth and a two-tone picture's lines straight (up to ``HOLD_TOLERANCE``); not an
   exact outline (a hard-edged picture's pixel edges) nor one of more than ``polish_segments`` segments;
5. ``split_and_polish``: segments along which the render is still wrong halved
   (``trace.split_where_wrong``) and polished again, kept where nearer;
6. ``colors_solved``: each polished picture's colours solved against it (``solved_colors``);
7. ``finish``: crossings untangled, written nonzero (``trace.finished``).

``trace_alone`` runs it without a renderer, for pictures none of which is polished: NumPy only,
so this module imports no torch (a ``Refinement`` comes in from ``refine_batch``, which has it).
Frame: the pixel frame of each picture; pictures are ``(H, W, 3)`` float64 arrays in [0, 1].
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from ..events import Stage
from ..options import Plan
from ..trace import (
    CHOICE_TOLERANCE,
    FLAT_SUMMARY,
    Corners,
    Reading,
    Start,
    finished,
    flat_result,
    image_starts,
    model_start_wanted,
    polished,
    split_where_wrong,
)
from ..vector import VectorImage

if TYPE_CHECKING:
    from .stages import Refinement

HOLD_TOLERANCE = 0.5  # px: a two-tone picture's lines are held straight in the polish where fitted this close.
# A looser line may stand off a junction the ink curves into: held straight at --tolerance 1, 2 of 620 glyphs
# cracked there (bench/outlines.py), none of them held at 0.5 (the default) or not held at 1


def clean_outlines(pictures: list[np.ndarray], run: Refinement | None, s: Plan = Plan(), *,
                   readings: list[Reading] | None = None, on_stage: Callable[[Stage], None] | None = None
                   ) -> list[tuple[VectorImage, dict]]:
    """Clean outlines of ``pictures`` (each ``(H, W, 3)`` in [0, 1]): non-overlapping outer
    contours and holes, nonzero, fitted within ``s.tolerance`` px and polished against the picture
    by ``run`` (the ``Refinement`` of these pictures, or ``None`` where none is polished).
    ``s``: the run's ``options.Plan``. ``readings``: what each picture is (``trace.read``); its
    kind shapes the trace, the palette of a photo and whether the outline is polished
    (``trace.polished``). ``on_stage`` hears each stage done (``events.STAGES``).

    Returns per picture the vector image and a summary: ``loss_end`` (the render's loss),
    ``start`` (which start was kept), ``segments``, and the model stage's figures where it ran.
    """
    readings = readings or [Reading("", pic) for pic in pictures]
    polish_these = [polished(r, pic.shape, s) for r, pic in zip(readings, pictures)]
    if run is None and any(polish_these):
        raise ValueError("a picture to polish needs a refinement")
    starts, info = _starts(pictures, run, s, readings, polish_these)
    chosen = choose(starts, run)
    made = [start.outline(s.tolerance) for start in chosen]
    tell = on_stage or (lambda _: None)
    tell(Stage("traced"))
    vecs, flags = [v for v, _, _ in made], [f for _, f, _ in made]
    todo = [i for i, (v, _, exact) in enumerate(made)  # an empty one has nothing to draw, an exact one nothing
            if v.shapes and not exact and v.num_segments <= s.polish_segments and polish_these[i]]  # to fix
    straight = [r.tone is not None and s.tolerance <= HOLD_TOLERANCE for r in readings]  # ``projections``
    vecs, loss = polish(run, vecs, flags, todo, straight) if todo else (vecs, {})
    if s.split_error > 0 and loss:
        vecs, loss = split_and_polish(run, pictures, vecs, flags, loss, s, straight)
    if loss:
        vecs, loss = colors_solved(run, pictures, vecs, list(loss))
    tell(Stage("polished"))
    out = [finish(run, i, vecs[i], loss.get(i), info[i], chosen[i].name, judge=polish_these[i])
           for i in range(len(vecs))]
    tell(Stage("finished"))
    return out


def trace_alone(readings: list[Reading], sizes: list[tuple[int, int]], s: Plan, *,
                on_stage: Callable[[Stage], None] | None = None) -> list[tuple[VectorImage, dict]]:
    """The clean outlines (``s``: the run's ``options.Plan``) of pictures read as ``readings`` none
    of which is polished (``trace.needs_renderer`` false for each), each on its ``sizes (H, W)``
    canvas, with its summary (as ``refine_batch`` gives it: the kind it was read as, and how)."""
    out, todo = flat_apart([r.picture for r in readings])
    if todo:
        got = clean_outlines([readings[i].picture for i in todo], None, s, readings=[readings[i] for i in todo],
                             on_stage=on_stage)
        for i, r in zip(todo, got):
            out[i] = r
    return on_canvas(out, sizes, readings)


def flat_apart(pictures: list[np.ndarray]) -> tuple[list, list[int]]:
    """Per picture ``(H, W, 3)`` its result where it is flat (one colour: nothing to fit,
    ``trace.flat_result`` with ``FLAT_SUMMARY``), else ``None``; and the indices of the others."""
    out: list = [None] * len(pictures)
    todo = []
    for i, pic in enumerate(pictures):
        flat = flat_result(pic)
        if flat is not None:
            out[i] = (flat, dict(FLAT_SUMMARY))
        else:
            todo.append(i)
    return out, todo


def on_canvas(results: list[tuple[VectorImage, dict]], sizes: list[tuple[int, int]],
              readings: list[Reading] | None) -> list[tuple[VectorImage, dict]]:
    """Each ``(vector image, summary)`` scaled to its picture's ``sizes (H, W)`` canvas, its summary
    with the kind the picture was read as, and how (``readings``; ``None``: nothing added)."""
    notes = [{"kind": r.kind, "reading": r.figures or {}} for r in readings] if readings else [{}] * len(results)
    return [(v.rescaled(w, h), {**info, **n}) for (v, info), (h, w), n in zip(results, sizes, notes)]


def _starts(pictures: list[np.ndarray], run: Refinement | None, s: Plan, readings: list[Reading],
            polish: list[bool]) -> tuple[list[list[Start]], list[dict]]:
    """Per picture its starts (the image's own first) and the model stage's summary (or ``{}``)."""
    starts = [[start] for start in image_starts(pictures, s, readings)]
    info: list[dict] = [{} for _ in pictures]
    two = model_start_wanted(pictures, s, readings, polish) if run is not None else []
    if two:
        from .stages import model_paths  # (torch: a refinement is at hand)

        for i, (paths, summary) in zip(two, model_paths(run, two, s, outline=True)):
            info[i] = summary
            if paths.shapes:
                starts[i].append(Start("model", pictures[i], paths=paths))
    return starts, info
def choose(starts: list[list[Start]], run: Refinement) -> list[Start]:
    """Per picture the start nearer it, judged at ``CHOICE_TOLERANCE`` for all, so that a looser
    tolerance never changes the choice (the polish moves points by a fraction of a pixel: it
    does not reorder the starts)."""
    both = [i for i, st in enumerate(starts) if len(st) > 1]
    chosen = [st[0] for st in starts]
    if both:
        cands = [(i, start) for i in both for start in starts[i]]
        scores = run.loss([start.outline(CHOICE_TOLERANCE)[0] for _, start in cands], [i for i, _ in cands])
        for i in both:
            best = min((sc, start.name) for (j, start), sc in zip(cands, scores) if j == i)[1]
            chosen[i] = next(start for start in starts[i] if start.name == best)
    return chosen


def polish(run: Refinement, vecs: list[VectorImage], flags: list[Corners], todo: list[int], straight: list[bool]
           ) -> tuple[list[VectorImage], dict[int, float]]:
    """The pictures ``todo`` polished (the others as they are; ``straight``: per picture, whether its lines
    stay lines) and the loss of each polished one."""
    got = run.polish_outline([vecs[i] for i in todo], [flags[i] for i in todo], todo, [straight[i] for i in todo])
    out = list(vecs)
    for i, v in zip(todo, got):
        out[i] = v
    return out, dict(zip(todo, run.loss(got, todo)))


def split_and_polish(run: Refinement, pictures: list[np.ndarray], vecs: list[VectorImage], flags: list[Corners],
                     loss: dict[int, float], s: Plan, straight: list[bool]) -> tuple[list[VectorImage], dict[int, float]]:
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
        got = run.polish_outline([split[i][0] for i in again], [split[i][1] for i in again], again,
                                 [straight[i] for i in again])
        for i, v, sc in zip(again, got, run.loss(got, again)):
            if sc < loss[i]:
                out[i], loss[i] = v, sc
    return out, loss


def colors_solved(run: Refinement, pictures: list[np.ndarray], vecs: list[VectorImage], todo: list[int]
                  ) -> tuple[list[VectorImage], dict[int, float]]:
    """The polished pictures ``todo`` with their shapes' colours solved (``solved_colors``) and the loss of each."""
    out = list(vecs)
    for i in todo:
        out[i] = solved_colors(vecs[i], pictures[i])
    return out, dict(zip(todo, run.loss([out[i] for i in todo], todo)))


def solved_colors(vec: VectorImage, picture: np.ndarray, ridge: float = 1e-3) -> VectorImage:
    """``vec`` with the colours whose cairo render over white is nearest ``picture (H, W, 3)`` (least
    squares, ``raster.composite.solve_colors``; ``ridge`` pulls a hidden shape to its own colour): each shape's
    exact coverage (``shape_coverage``) at 1x, the pixels a viewer shows. The polish fits colours through the
    renderer's soft edges (but a small icon's: ``stages.HELD_COLORS_SIDE``), which are not those pixels."""
    import torch

    from ..raster.composite import solve_colors
    from ..trace.outline import shape_coverage

    if not vec.shapes:
        return vec
    h, w = picture.shape[:2]
    cov = torch.from_numpy(np.stack([shape_coverage(sh, w, h, w / vec.width) for sh in vec.shapes]))[None]
    prior = torch.tensor([[sh.color for sh in vec.shapes]], dtype=torch.float64)
    target = torch.from_numpy(np.ascontiguousarray(picture.transpose(2, 0, 1), dtype=np.float64))[None]
    depth = torch.arange(len(vec.shapes), dtype=torch.float64)[None]  # listed back to front
    colors = solve_colors(cov, depth, target, prior, ridge)[0].tolist()
    shapes = [dataclasses.replace(sh, color=tuple(c)) for sh, c in zip(vec.shapes, colors)]
    return dataclasses.replace(vec, shapes=shapes)


def finish(run: Refinement | None, i: int, vec: VectorImage, loss: float | None, info: dict, start: str,
           judge: bool = True) -> tuple[VectorImage, dict]:
    """Picture ``i``'s result written nonzero and untangled, with its summary (one never
    polished, empty or exact, is judged as it is; with ``judge`` False, not at all: a draft
    renders nothing)."""
    if loss is None and judge:
        loss = run.loss([vec], [i])[0]
    v = finished(vec)
    return v, {**info, "loss_end": loss, "start": start, "segments": v.num_segments}
