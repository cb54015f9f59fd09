"""The batch driver of refinement: ``refine`` and ``refine_batch``: pictures read, flat ones set
aside, the others grouped by size and refined a batch at a time, each batch one ``Refinement``
(the model's paths, ``stages.model_paths``, or clean outlines polished by it, ``clean.clean_outlines``),
and each result scaled back to its picture's frame."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import torch

from ..events import Event, Stage
from ..model.vae import Im2Vec
from ..options import PARTS, Plan
from ..trace import Reading, read_pictures
from ..trace.batch import workable
from ..vector import VectorImage, picture_array
from .clean import clean_outlines, flat_apart, on_canvas
from .stages import Refinement, model_paths

REFINE_BATCH = 32  # images refined together (one render per step); bounds the memory of a batch


def refine(model: Im2Vec, image: torch.Tensor, plan: Plan = Plan(), *,
           on_step: Callable[[Event], None] | None = None) -> tuple[VectorImage, dict]:
    """Vectorise one image ``(3, H, W)`` in [0, 1] and refine the result against it, as the run's
    ``plan`` says (``options.Plan``: ``VectorizeOptions.resolve()`` makes one; ``Plan()`` refines most).

    ``plan.parts="model"`` keeps the model's own paths (the same P paths in the same order for
    every image of a class): the latent stage, the point stage, pruning, simplifying and a
    polish. ``"clean"`` (the default) writes clean outlines instead: two starts, each
    polished through the renderer, the one nearer the image kept:

    - the model's refined paths, each shape redrawn as clean rings (``trace.redrawn``),
      with the pieces and holes of a two-tone image that the model missed added or cut out;
    - the image's own regions traced (``trace.traced``; ``plan.colors`` sets the palette).

    (The stage list of clean outlines is ``clean.clean_outlines``; ``Refinement`` polishes them.)

    Both are shapes of non-overlapping outer contours and holes, fitted with cubics within
    ``plan.tolerance`` input pixels, corners kept sharp. ``plan.segments`` / ``plan.quality`` as in
    ``infer.vectorize`` (``"auto"``: per-path counts) shape the model's paths.

    Returns:
        The vector image (input pixel frame) and a summary: the pyramid L2 of the model's
        guess (after the latent stage) and of the result (at ``tau_end``), the steps taken,
        the segments, and with ``parts="clean"`` which start was kept (``"start"``).
    """
    if image.dim() != 3 or image.shape[0] != 3:
        raise ValueError(f"image must be (3, H, W), got {tuple(image.shape)}")
    return refine_batch(model, [image], plan, on_step=on_step)[0]


def refine_batch(model: Im2Vec, images: list[torch.Tensor], plan: Plan = Plan(), *,
                 on_step: Callable[[Event], None] | None = None, batch: int = REFINE_BATCH,
                 readings: list[Reading] | None = None) -> list[tuple[VectorImage, dict]]:
    """``refine`` of many images ``(3, H_i, W_i)``: images of one size are refined together, ``batch`` at a
    time, each step one render of them all; an image that has converged stops costing. Each image gets what
    ``refine`` alone gives it, up to float rounding (the batch sums per-image losses; Adam's state is per
    coordinate). Returns ``(vector image, summary)`` per image, in order. A picture of more than
    ``plan.work_pixels`` is vectorized at an area-averaged copy that large, its result scaled back to its frame.

    With ``plan.parts="clean"`` each picture is first read (``trace.read``: ``plan.preset``,
    ``plan.speckle``) and its clean picture traced; the summary's ``kind`` and ``reading`` say what it
    was read as. ``readings``: theirs where the caller has them (``trace.read_pictures`` of this plan):
    not read again."""
    sizes = _sizes(images, plan.parts)
    images, readings = _read(images, plan, on_step, readings)
    out, todo = flat_apart([picture_array(im) for im in images])  # a flat one: the same answer as amortised vectorisation
    by_size: dict[tuple[int, int], list[int]] = {}
    for i in todo:
        by_size.setdefault(tuple(images[i].shape[1:]), []).append(i)
    req = [p.requires_grad for p in model.parameters()]
    for p in model.parameters():
        p.requires_grad_(False)
    try:
        with torch.enable_grad():
            for group in by_size.values():
                for start in range(0, len(group), batch):
                    ids = group[start : start + batch]
                    for i, r in zip(ids, _refined(model, [images[i] for i in ids], plan, on_step,
                                                  readings and [readings[i] for i in ids])):
                        out[i] = r
    finally:
        for p, r in zip(model.parameters(), req):
            p.requires_grad_(r)
    return on_canvas(out, sizes, readings)


def _refined(model: Im2Vec, images: list[torch.Tensor], plan: Plan, on_step, readings: list[Reading] | None
             ) -> list[tuple[VectorImage, dict]]:
    """One batch of images of one size refined: the model's paths, or clean outlines polished by it."""
    run = Refinement(model, images, plan, on_step)
    if plan.parts == "model":
        return model_paths(run, list(range(len(images))), plan)
    return clean_outlines([picture_array(im) for im in run.images], run, plan, readings=readings, on_stage=on_step)


def _sizes(images: list[torch.Tensor], parts: str) -> list[tuple[int, int]]:
    """Each image's ``(H, W)``; ``ValueError`` for a bad ``parts`` or an image not ``(3, H, W)``."""
    if parts not in PARTS:
        raise ValueError(f"parts must be one of {PARTS}, got {parts!r}")
    for im in images:
        if im.dim() != 3 or im.shape[0] != 3:
            raise ValueError(f"image must be (3, H, W), got {tuple(im.shape)}")
    return [tuple(im.shape[1:]) for im in images]


def _read(images: list[torch.Tensor], plan: Plan, on_step=None, readings: list[Reading] | None = None
          ) -> tuple[list[torch.Tensor], list[Reading] | None]:
    """With ``plan.parts="clean"`` each picture read (``trace.read_pictures``: at most ``plan.work_pixels``
    pixels; ``readings`` where given) and its clean picture, ``(3, H', W')`` on its device; ``on_step``
    hears ``Stage("read")``. Else each picture at most ``plan.work_pixels`` pixels, and no readings."""
    most = plan.work_pixels
    if plan.parts != "clean":
        return [_tensor(workable(picture_array(im), most), im) if im.shape[1] * im.shape[2] > most else im
                for im in images], None
    if readings is None:
        readings = read_pictures([picture_array(im) for im in images], plan)
    if on_step:
        on_step(Stage("read"))
    return [_tensor(r.picture, im) for r, im in zip(readings, images)], readings


def _tensor(picture: np.ndarray, like: torch.Tensor) -> torch.Tensor:
    """``picture (H, W, 3)`` -> ``(3, H, W)`` of ``like``'s dtype and device."""
    return torch.from_numpy(np.ascontiguousarray(picture.transpose(2, 0, 1))).to(like)
