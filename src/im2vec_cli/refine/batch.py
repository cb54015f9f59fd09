"""The batch driver of refinement: ``refine`` and ``refine_batch``, the model-path run and
the clean-outline run."""

from __future__ import annotations

from collections.abc import Callable

import torch

from ..infer import flat_result
from ..model.vae import Im2Vec
from ..options import PARTS
from ..vector import VectorImage, VectorShape, simplify
from ..vector.outline import Corners, redrawn, traced, untangle
from ..vector.trace import background_color, two_tone
from .settings import CHOICE_TOLERANCE, RefineSettings
from .stages import Refinement

REFINE_BATCH = 32  # images refined together (one render per step); bounds the memory of a batch


def refine(
    model: Im2Vec,
    image: torch.Tensor,
    *,
    parts: str = "clean",
    colors: int | None = None,
    segments: int | str | torch.Tensor | None = None,
    quality: float | None = None,
    max_paths: int | None = None,
    settings: RefineSettings = RefineSettings(),
    on_step: Callable[[dict], None] | None = None,
) -> tuple[VectorImage, dict]:
    """Vectorise one image ``(3, H, W)`` in [0, 1] and refine the result against it.

    ``parts="model"`` keeps the model's own paths (the same P paths in the same order for
    every image of a class): the latent stage, the point stage, pruning, simplifying and a
    polish. ``parts="clean"`` (the default) writes clean outlines instead: two starts, each
    polished through the renderer, the one nearer the image kept:

    - the model's refined paths, each shape redrawn as clean rings (``vector.outline.redrawn``),
      with the pieces and holes of a two-tone image that the model missed added or cut out;
    - the image's own regions traced (``vector.outline.traced``; ``colors`` sets the palette).

    Both are shapes of non-overlapping outer contours and holes, fitted with cubics within
    ``settings.tolerance`` input pixels, corners kept sharp. ``segments`` / ``quality`` as in
    ``infer.vectorize`` (``"auto"``: per-path counts) shape the model's paths.

    Returns:
        The vector image (input pixel frame) and a summary: the pyramid L2 of the model's
        guess (after the latent stage) and of the result (at ``tau_end``), the steps taken,
        the segments, and with ``parts="clean"`` which start was kept (``"start"``).
    """
    if image.dim() != 3 or image.shape[0] != 3:
        raise ValueError(f"image must be (3, H, W), got {tuple(image.shape)}")
    return refine_batch(model, [image], parts=parts, colors=colors, segments=segments, quality=quality,
                        max_paths=max_paths, settings=settings, on_step=on_step)[0]


def refine_batch(
    model: Im2Vec,
    images: list[torch.Tensor],
    *,
    parts: str = "clean",
    colors: int | None = None,
    segments: int | str | None = None,
    quality: float | None = None,
    max_paths: int | None = None,
    settings: RefineSettings = RefineSettings(),
    on_step: Callable[[dict], None] | None = None,
    batch: int = REFINE_BATCH,
) -> list[tuple[VectorImage, dict]]:
    """``refine`` of many images ``(3, H_i, W_i)``: images of one size are refined together,
    ``batch`` at a time, each step one render of them all; an image that has converged stops
    costing. Each image gets what ``refine`` alone gives it, up to float rounding (the
    batch sums per-image losses; Adam's state is per coordinate). Returns ``(vector image,
    summary)`` per image, in order."""
    if parts not in PARTS:
        raise ValueError(f"parts must be one of {PARTS}, got {parts!r}")
    for im in images:
        if im.dim() != 3 or im.shape[0] != 3:
            raise ValueError(f"image must be (3, H, W), got {tuple(im.shape)}")
    out: list = [None] * len(images)
    by_size: dict[tuple[int, int], list[int]] = {}
    for i, im in enumerate(images):
        flat = flat_result(im)
        if flat is not None:  # nothing to fit: the same answer as amortised vectorisation
            out[i] = (flat, {"loss_start": 0.0, "loss_end": 0.0, "latent_steps": 0, "point_steps": 0})
        else:
            by_size.setdefault(tuple(im.shape[1:]), []).append(i)
    req = [p.requires_grad for p in model.parameters()]
    for p in model.parameters():
        p.requires_grad_(False)
    try:
        with torch.enable_grad():
            for group in by_size.values():
                for start in range(0, len(group), batch):
                    ids = group[start : start + batch]
                    run = Refinement(model, [images[i] for i in ids], settings, on_step)
                    idx = list(range(len(ids)))
                    if parts == "model":
                        got = _model_paths(run, idx, segments, quality, max_paths)
                    else:
                        got = _clean(run, segments, quality, colors, max_paths)
                    for i, r in zip(ids, got):
                        out[i] = r
    finally:
        for p, r in zip(model.parameters(), req):
            p.requires_grad_(r)
    return out


def _model_paths(run: Refinement, index: list[int], segments, quality, max_paths, outline: bool = False
                 ) -> list[tuple[VectorImage, dict]]:
    """The model's paths of the images ``index`` refined (``parts="model"``); never worse than
    the model's guess.

    ``outline``: stop after the point stage (the paths are then united and refitted)."""
    mu, place, k = run.encode(index, segments, quality)
    z, latent_steps = run.fit_latent(mu, k, place, index)
    guess = run.decode(z, k, place, max_paths, index)
    start = run.loss(guess, index)
    vecs, point_steps = run.fit_points(guess, index)
    info = [{"loss_start": a, "latent_steps": b, "point_steps": c} for a, b, c in zip(start, latent_steps, point_steps)]
    if outline:
        return list(zip(vecs, info))
    vecs = run.prune(vecs, index)
    fitted = [v.num_segments for v in vecs]
    vecs, polish_steps = run.simplify_and_polish(vecs, index)
    end = run.loss(vecs, index)
    out = []
    for j, v in enumerate(vecs):
        e = end[j]
        if e > start[j]:  # refinement never makes the result worse than the model's guess
            v, e = simplify(guess[j], run.s.simplify_tol), start[j]
        out.append((v, {**info[j], "loss_end": e, "polish_steps": polish_steps[j], "segments_fitted": fitted[j],
                        "segments": v.num_segments}))
    return out


def _clean(run: Refinement, segments, quality, colors: int | None, max_paths: int | None
           ) -> list[tuple[VectorImage, dict]]:
    """Clean outlines from each image's regions and, for a two-tone image, from the model's
    refined paths; the start nearer the image is polished (and split where still wrong)."""
    n = len(run.images)
    pictures = [im.permute(1, 2, 0).double().cpu().numpy() for im in run.images]  # (H, W, 3)
    # The contours of a clean shape do not overlap, so even-odd renders them as nonzero does,
    # without the renderer's boundary search (seconds on a picture of many regions); written nonzero.
    starts: list[dict] = [{"image": lambda tol, pic=pic: _evenodd(*traced(pic, tol, colors, max_paths))}
                          for pic in pictures]
    info: list[dict] = [{} for _ in range(n)]
    if run.s.model_start and colors in (None, 1):
        # Multi-colour pictures: the shipped emoji model's paths lost to the image's own regions on
        # every OpenMoji face tried (bench/outlines.py) and cost seconds, so only the image is traced.
        two = [i for i, pic in enumerate(pictures) if two_tone(pic, background_color(pic)) is not None]
        if two:
            for i, (mv, inf) in zip(two, _model_paths(run, two, segments, quality, max_paths, outline=True)):
                info[i] = inf
                if mv.shapes:
                    starts[i]["model"] = lambda tol, mv=mv, pic=pictures[i]: _evenodd(*redrawn(mv, tol, pic))
    names = ["image"] * n
    both = [i for i in range(n) if len(starts[i]) > 1]
    if both:  # chosen at one tolerance for all, so that a looser one never changes the choice
        cands = [(i, name, make(CHOICE_TOLERANCE)[0]) for i in both for name, make in starts[i].items()]
        scores = run.loss([v for _, _, v in cands], [i for i, _, _ in cands])
        for i in both:  # the polish moves points by a fraction of a pixel: it does not reorder the starts
            names[i] = min((sc, name) for (j, name, _), sc in zip(cands, scores) if j == i)[1]
    made = [starts[i][names[i]](run.s.tolerance) for i in range(n)]
    vecs, flags = [v for v, _ in made], [f for _, f in made]
    todo = [i for i in range(n) if vecs[i].shapes]  # an empty one has nothing to draw
    got = run.polish_outline([vecs[i] for i in todo], [flags[i] for i in todo], todo)
    loss = dict(zip(todo, run.loss(got, todo)))
    for i, v in zip(todo, got):
        vecs[i] = v
    if run.s.split_error > 0:
        more = {}
        for i in todo:
            v, f, count = run.split_where_wrong(vecs[i], flags[i], i)
            if count:
                more[i] = (v, f)
        again = list(more)
        if again:
            got = run.polish_outline([more[i][0] for i in again], [more[i][1] for i in again], again)
            for i, v, sc in zip(again, got, run.loss(got, again)):
                if sc < loss[i]:
                    vecs[i], loss[i] = v, sc
    out = []
    for i in range(n):
        if i not in loss:
            out.append((vecs[i], {**info[i], "loss_end": run.loss([vecs[i]], [i])[0], "start": names[i],
                                  "segments": 0}))
            continue
        v = untangle(_with_rule(vecs[i], "nonzero"))
        out.append((v, {**info[i], "loss_end": loss[i], "start": names[i], "segments": v.num_segments}))
    return out


def _with_rule(vec: VectorImage, rule: str) -> VectorImage:
    return VectorImage(vec.width, vec.height, [VectorShape(sh.contours, sh.color, rule) for sh in vec.shapes])


def _evenodd(vec: VectorImage, flags: Corners) -> tuple[VectorImage, Corners]:
    return _with_rule(vec, "evenodd"), flags
