"""The stages of refinement of the model's paths, as the methods of ``Refinement``."""

from __future__ import annotations

from collections.abc import Callable

import torch
import torch.nn.functional as F

from ..events import RefineStep
from ..frame import Placement
from ..infer import model_input, segment_counts, to_vector
from ..model.vae import Im2Vec
from ..optim import Adam
from ..options import Plan
from ..trace import Corners, simplify
from ..vector import VectorImage, picture_array, resolve_overlaps
from .core import _Fitter, _Progress

HELD_COLORS_SIDE = 48  # px: an icon this small keeps the trace's colours while the polish moves its points. Most of
# its pixels are edges, and colours fitted through the soft edges went to extremes (a 22 px icon's 1 px mid-blue
# outline navy, its light fill near white); held, 110 Tango 22-32 px icons outside bench/wild.py went 77 -> 86 at or
# above both peers. At 64 px held colours opened cracks in 3 of 80 OpenMoji faces where learned ones left 1.


class Refinement:
    """The refinement of a batch of images of one size, stage by stage (``refine_batch``
    runs them in order). Every stage takes and returns one item per image (or per ``index``,
    the images it is given), so that one render per step serves the whole batch.

    Holds the model (frozen while it runs), the fit targets ``(B, 3, h, w)`` at the fit size,
    and two objectives: ``fitter`` with the model's lines per cubic for the latent and point
    stages, ``fine`` with ``polish_samples`` that judges results and fits the polish.
    """

    def __init__(self, model: Im2Vec, images: list[torch.Tensor], settings: Plan,
                 on_step: Callable[[RefineStep], None] | None = None):
        s = self.s = settings
        self.model, self.images, self.on_step = model, images, on_step
        self.device = next(model.parameters()).device
        _, h, w = images[0].shape
        if any(tuple(im.shape) != (3, h, w) for im in images):
            raise ValueError("a refinement batch needs images of one size")
        target = torch.stack(images).to(self.device)
        if max(h, w) > s.max_side:
            f = s.max_side / max(h, w)
            target = F.interpolate(target, size=(max(4, round(h * f)), max(4, round(w * f))), mode="area")
        self.fitter = _Fitter(target, model.config.samples, s)
        self.fine = _Fitter(target, max(s.polish_samples, model.config.samples), s)
        self._inputs: list | None = None  # each image in the model's frame (``model_input``), at first need

    def model_inputs(self, index: list[int]) -> tuple[torch.Tensor, list[Placement]]:
        """The images ``index`` as the model takes them, ``(A, 3, S, S)`` on its device, and their
        placements; each image is put in the model's frame once, for the encoder and the passes alike."""
        if self._inputs is None:
            self._inputs = [model_input(self.model, im) for im in self.images]
        xs, places = zip(*(self._inputs[i] for i in index))
        return torch.stack(xs).to(self.device), list(places)

    def encode(self, index: list[int], segments, quality) -> tuple[torch.Tensor, Placement, int | torch.Tensor | None]:
        """The amortised guess of the images ``index``: ``mu (A, D)``, the placement (one for
        the batch: its images share a size), and the segments to decode with."""
        x, places = self.model_inputs(index)
        with torch.no_grad():
            mu, _ = self.model.encode(x)
            return mu, places[0], segment_counts(self.model, self.model.path_state(mu)[0], segments, quality)

    def fit_latent(self, mu: torch.Tensor, k, place: Placement, index: list[int]) -> tuple[torch.Tensor, list[int]]:
        """Stage 1: Adam on the latents (the shapes stay on the model's manifold), at ``tau_start``.

        Each latent stops when its own loss converges. Returns the best latents (``mu`` itself
        where no step improves on it) and the steps taken by each."""
        s = self.s
        z = mu.clone().requires_grad_(True)
        opt = Adam([{"params": [z], "lr": s.latent_lr}])
        progress = _Progress(len(index), s)
        best_z = z.detach().clone()
        rows_all = torch.tensor(index, device=z.device)
        for i in range(s.latent_steps):
            sel = torch.tensor(progress.live, device=z.device)
            kk = k[sel] if isinstance(k, torch.Tensor) else k
            dec = self.model.decode(z[sel], kk)
            sidx = None if dec.shape_index is None else dec.shape_index.expand(len(sel), -1)
            loss = self.fitter.loss(place.model_to_input(dec.points), dec.colors, dec.depth, rows_all[sel], s.tau_start,
                                    fill_rule=dec.fill_rule, shape_index=sidx, counts=dec.counts)  # (A,)
            opt.zero_grad()
            loss.sum().backward()
            opt.step()
            for _, j in progress.record(loss.tolist())[0]:
                best_z[j] = z[j].detach()
            if self.on_step:
                self.on_step(RefineStep("latent", i, float(loss.detach().mean()), len(sel)))
            if not progress.live:
                break
        return best_z, [len(h) for h in progress.hist]

    def decode(self, z: torch.Tensor, k, place: Placement, max_paths: int | None, index: list[int]) -> list[VectorImage]:
        """The paths of each latent in the input's frame, overlaps resolved against its input (once):
        through the model's picture door (its passes, given the pictures ``index``) or its latent
        door, as ``Plan.passes`` says."""
        with torch.no_grad():
            door = self.s.passes if self.s.passes is not None else self.model.config.grouping != "layers"
            dec = self.model.decode(z, k, self.model_inputs(index)[0] if door else None)
            return [resolve_overlaps(to_vector(dec, a, place, max_paths=max_paths), self.images[i])
                    for a, i in enumerate(index)]

    def fit_points(self, vecs: list[VectorImage], index: list[int]) -> tuple[list[VectorImage], list[int]]:
        """Stage 2: control points and colours (learned-colour models only), tau annealed."""
        learn_colors = not self.model.palette.numel()
        return self.fitter.fit_points(vecs, self.s.point_steps, self.s.tau_start, learn_colors, "points", self.on_step,
                                      index=index)

    def prune(self, vecs: list[VectorImage], index: list[int]) -> list[VectorImage]:
        """Drop paths that do not change the result (``_Fitter.prune``)."""
        return [self.fitter.prune(v, self.s.prune_tol, i) for v, i in zip(vecs, index)]

    def simplify_and_polish(self, vecs: list[VectorImage], index: list[int]) -> tuple[list[VectorImage], list[int]]:
        """Stage 3: merge segments within ``simplify_tol`` px, then a short points-only polish."""
        if self.s.simplify_tol <= 0:
            return vecs, [0] * len(vecs)
        return self.fine.fit_points([simplify(v, self.s.simplify_tol) for v in vecs], self.s.polish_steps,
                                    self.s.tau_end, False, "polish", self.on_step, index=index)

    def polish_outline(self, vecs: list[VectorImage], flags: list[Corners], index: list[int],
                       straight: list[bool] | None = None) -> list[VectorImage]:
        """Clean outlines: points and colours polished for ``outline_steps``, smooth joins kept smooth and, where
        ``straight`` says (a two-tone picture's), lines straight (the colours are solved again after:
        ``clean.solved_colors``); a picture of at most ``HELD_COLORS_SIDE`` px keeps the trace's colours while its
        points move."""
        learn_colors = max(self.images[0].shape[1:]) > HELD_COLORS_SIDE
        return self.fine.fit_points(vecs, self.s.outline_steps, self.s.outline_tau, learn_colors, "outline",
                                    self.on_step, smooth=flags, index=index, straight=straight)[0]

    def targets(self, index: list[int]) -> list:
        """The pictures ``index`` at the fit size, as the loss sees them: ``(h, w, 3)`` float64 arrays."""
        return [picture_array(self.fitter.target[0][i]) for i in index]

    def grow(self, vecs: list[VectorImage], index: list[int]) -> tuple[list[VectorImage], list[int]]:
        """Paths of the pictures' own pieces added where the fitted paths miss them (``grow.grown``), and how many."""
        from ..trace import read_pictures
        from .grow import grown

        pics = self.targets(index)
        got = [grown(v, p, r, self.s) for v, p, r in zip(vecs, pics, read_pictures(pics, self.s))]
        return [v for v, _ in got], [n for _, n in got]

    def solved(self, vecs: list[VectorImage], loss: list[float], index: list[int]) -> tuple[list[VectorImage], list[float]]:
        """Each image's colours solved against its picture (``clean.solved_colors``), kept where the loss is lower."""
        from .clean import solved_colors

        got = [solved_colors(v, p) if v.shapes else v for v, p in zip(vecs, self.targets(index))]
        now = self.loss(got, index)
        pairs = [(g, b) if b < a else (v, a) for v, g, a, b in zip(vecs, got, loss, now)]
        return [v for v, _ in pairs], [e for _, e in pairs]

    def loss(self, vecs: list[VectorImage], index: list[int]) -> list[float]:
        """The judge: pyramid L2 at ``tau_end`` with ``polish_samples`` lines per cubic."""
        return self.fine.vector_loss(vecs, self.s.tau_end, index)


def model_paths(run: Refinement, index: list[int], plan: Plan, outline: bool = False
                 ) -> list[tuple[VectorImage, dict]]:
    """The model's paths of the images ``index`` refined (``parts="model"``; ``plan.segments``,
    ``plan.quality`` and ``plan.max_paths`` shape them); never worse than the model's guess.

    ``outline``: stop after the point stage (the paths are then united and refitted)."""
    mu, place, k = run.encode(index, plan.segments, plan.quality)
    z, latent_steps = run.fit_latent(mu, k, place, index)
    guess = run.decode(z, k, place, plan.max_paths, index)
    start = run.loss(guess, index)
    vecs, point_steps = run.fit_points(guess, index)
    info = [{"loss_start": a, "latent_steps": b, "point_steps": c} for a, b, c in zip(start, latent_steps, point_steps)]
    if outline:
        return list(zip(vecs, info))
    vecs = run.prune(vecs, index)
    vecs, grew = run.grow(vecs, index) if plan.grow else (vecs, [0] * len(vecs))
    fitted = [v.num_segments for v in vecs]
    vecs, polish_steps = run.simplify_and_polish(vecs, index)
    end = run.loss(vecs, index)
    if not run.model.palette.numel():  # learned colours: solved against the picture, kept where nearer
        vecs, end = run.solved(vecs, end, index)
    out = []
    for j, v in enumerate(vecs):
        e = end[j]
        if e > start[j]:  # refinement never makes the result worse than the model's guess
            v, e = simplify(guess[j], run.s.simplify_tol), start[j]
        out.append((v, {**info[j], "loss_end": e, "polish_steps": polish_steps[j], "segments_fitted": fitted[j], "grown": grew[j],
                        "segments": v.num_segments}))
    return out
