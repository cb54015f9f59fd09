"""Test-time refinement: fit the decoded paths of one image to that image.

The amortised encoder gives a first guess; refinement then minimises the pyramid L2
(sec. 3.4, eq. 1) against the input itself, first over the latent ``z`` (the shapes stay
on the model's manifold), then over the control points and colours directly. Paths whose
removal barely changes the loss are then dropped, neighbouring segments are merged while the
outline moves less than ``simplify_tol`` pixels (``vector/simplify.py``), and a short points-only
polish follows. The default uses one pyramid level: see ``RefineSettings.levels``. The stages
are the methods of ``Refinement``; overlapping even-odd paths are resolved once, on the
latent stage's result (``vector.resolve_overlaps``), and the later stages fit under the rule it chose.

Frames: the model decodes in its square frame (``frame.Placement``). Refinement works in
the *input's* normalised frame, ``(x / W, y / H)`` of the input's pixel grid, and renders at
the input's resolution (inputs larger than ``max_side`` are fitted at a reduced copy), so
``tau`` is measured in input pixels.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F

from .frame import Placement
from .infer import flat_result, model_input, segment_counts, to_vector
from .model.vae import Im2Vec
from .optim import Adam
from .options import PARTS
from .raster import flatten_closed, gaussian_pyramid, polygon_area, pyramid_l2, render_pyramid, segment_controls
from .vector import VectorImage, VectorShape, fill_vector, resolve_overlaps, simplify
from .vector.fit import split_segments
from .vector.outline import Corners, redrawn, traced, untangle
from .vector.trace import background_color, two_tone

CHOICE_TOLERANCE = 0.25  # px: the clean-outline starts are compared fitted this closely


@dataclass(frozen=True)
class RefineSettings:
    """Optimisation settings of ``refine``."""

    latent_steps: int = 10
    point_steps: int = 50
    latent_lr: float = 0.05
    point_lr: float = 1.5e-3  # normalised units per Adam step (0.1 px on a 64 px image)
    color_lr: float = 0.02
    tau_start: float = 0.8  # edge softness in input pixels, annealed during the point stage...
    tau_end: float = 0.3  # ...to about a box filter's slope, which is what cairo and the input show
    levels: int = 1  # the full-resolution L2 only. Coarse levels rendered sharp against a blurred target
    # pulled the outline off the edges (IoU@4x 0.921 with 3 levels vs 0.972 with 1, bench/vectorize.py); the
    # blurred pyramid (render_pyramid's default) neither helps nor hurts (0.9888 vs 0.9891, 12 fonts test glyphs)
    max_side: int = 128  # larger inputs are fitted at this size (then scaled back: the frame is normalised)
    patience: int = 12  # stop when the loss has not improved by min_improvement in this many steps
    min_improvement: float = 2e-3
    margin: float = 0.02  # control points may leave the canvas by this much (normalised) before a penalty
    bounds_weight: float = 10.0
    min_segment_px: float = 0.5  # segments shorter than this are pushed apart (collapsed-segment guard)
    collapse_weight: float = 1e-3
    prune_tol: float = 0.01  # drop a path whose removal raises the loss by less than this fraction
    simplify_tol: float = 0.25  # after fitting, merge segments while the outline moves less than this (input px)
    polish_steps: int = 40  # points-only steps after simplifying
    polish_samples: int = 12  # lines per cubic in the polish: merged segments are long, and too coarse a
    # polygon lets the fit bend the true curve away from the edge (IoU@4x 0.972 with the model's 4)
    tolerance: float = 0.5  # clean outlines: cubics fitted within this many input px of the traced/united ring
    outline_steps: int = 40  # clean outlines: points (and colours) polished against the input...
    outline_tau: float = 0.3  # ...from this edge softness, annealed to tau_end
    split_error: float = 0.01  # then segments along which the render is still this wrong (MSE) are halved and
    # the polish repeated (0: never)
    max_segments: int = 200  # per contour, splitting stops here
    model_start: bool = True  # clean outlines of a two-tone image: also start from the model's paths (redrawn
    # clean), keep the better start. On 40 held-out glyphs and 40 icons it changed IoU@4x by -0.0005 and 0.0000
    # at twice the time (bench/outlines.py), so the fast effort traces the image alone


# Named efforts (`vectorize --effort`; options.EFFORTS names them, torch-free, for the CLI).
# "best" is ``RefineSettings()``; "fast" takes about a third of the steps and a
# coarser polish polygon: on 62 held-out Liberation Sans Narrow glyphs
# at 64 px (fonts model) IoU@4x 0.9855 and MSE 0.00051 in 0.26 s per glyph, against 0.9913,
# 0.00022 and 0.79 s (on all 248 glyphs, `make bench-vectorize`: 0.9867 / 0.00036 in 0.44 s against
# 0.9914 / 0.00018 in 1.01 s; potrace 0.9524 / 0.00283), so that one `vectorize` fits in about 2 s
# with torch's import.
EFFORTS = {  # in the order of options.EFFORTS
    "fast": RefineSettings(latent_steps=5, point_steps=25, polish_steps=15, polish_samples=8, outline_steps=25,
                           model_start=False),
    "best": RefineSettings(split_error=0.005),
}


def _geometry_penalty(points: torch.Tensor, real: torch.Tensor, size: tuple[int, int], s: RefineSettings) -> torch.Tensor:
    """Keep control points near the canvas and segments from collapsing: ``(B,)``, per image.

    Args:
        points: ``(B, P, 3K, 2)`` input-normalised frame; real ``(B, P, 3K)`` false on padding.
    """
    h, w = size
    out = F.relu(-s.margin - points) + F.relu(points - 1 - s.margin)
    bounds = out.square().flatten(1).sum(1)
    seg = segment_controls(points * torch.tensor([w, h], dtype=points.dtype, device=points.device))  # (B, P, K, 4, 2)
    chord = (seg[..., 3, :] - seg[..., 0, :]).norm(dim=-1)  # (B, P, K) px
    collapse = (F.relu(s.min_segment_px - chord).square() * real[..., 0::3]).flatten(1).sum(1)
    return s.bounds_weight * bounds + s.collapse_weight * collapse


def _box3(a: np.ndarray) -> np.ndarray:
    """The mean of each pixel's 3 x 3 neighbourhood, edges mirrored (``scipy.ndimage.uniform_filter(a, 3)``,
    without importing SciPy's 0.3 s of modules for it)."""
    p = np.pad(a, 1, mode="symmetric")
    rows = (p[:-2] + p[1:-1] + p[2:]) / 3
    return (rows[:, :-2] + rows[:, 1:-1] + rows[:, 2:]) / 3


def _converged(history: list[float], s: RefineSettings) -> bool:
    if len(history) <= s.patience:
        return False
    before = min(history[: -s.patience])
    return min(history[-s.patience :]) > before * (1 - s.min_improvement)


@dataclass
class _Paths:
    """Vector images of one size as renderer tensors: every contour one path, padded to the
    longest contour and to the image with most contours and shapes.

    points ``(B, P, 3K, 2)`` input-normalised; real ``(B, P, 3K)`` (false on padding: a
    contour's padding repeats its first anchor, a padding contour sits at the canvas centre);
    counts ``(B, P)`` segments (0: padding contour); colors ``(B, G, 3)``; depth ``(B, G)``;
    shape_index ``(B, P)`` (-1: padding contour). A padding shape has no contour, so it
    renders to nothing (``raster.render_coverage``).
    """

    points: torch.Tensor
    real: torch.Tensor
    counts: torch.Tensor
    colors: torch.Tensor
    depth: torch.Tensor
    shape_index: torch.Tensor
    fill_rule: str

    @classmethod
    def of(cls, vecs: list[VectorImage], device) -> _Paths:
        """``vecs``: images of one size, each with at least one shape, all under one fill rule."""
        conts = [[(gi, torch.as_tensor(c, dtype=torch.float32)) for gi, sh in enumerate(v.shapes) for c in sh.contours]
                 for v in vecs]
        b, p = len(vecs), max(len(cs) for cs in conts)
        big = max(len(c) for cs in conts for _, c in cs)
        g = max(len(v.shapes) for v in vecs)
        pts = torch.full((b, p, big, 2), 0.5)
        counts = torch.zeros(b, p, dtype=torch.long)
        sidx = torch.full((b, p), -1, dtype=torch.long)
        colors = torch.zeros(b, g, 3)
        for i, (v, cs) in enumerate(zip(vecs, conts)):
            scale = torch.tensor([v.width, v.height])
            for j, (gi, c) in enumerate(cs):
                pts[i, j] = torch.cat([c, c[:1].expand(big - len(c), 2)]) / scale
                counts[i, j], sidx[i, j] = len(c) // 3, gi
            colors[i, : len(v.shapes)] = torch.tensor([sh.color for sh in v.shapes], dtype=torch.float32)
        real = torch.arange(big) < 3 * counts.unsqueeze(-1)
        return cls(pts.to(device), real.to(device), counts.to(device), colors.to(device),
                   torch.arange(g, dtype=torch.float32, device=device).expand(b, g), sidx.to(device),
                   _rule([sh for v in vecs for sh in v.shapes]))

    def take(self, rows: torch.Tensor) -> _Paths:
        """The images ``rows`` of the batch (the same padding)."""
        return _Paths(self.points[rows], self.real[rows], self.counts[rows], self.colors[rows], self.depth[rows],
                      self.shape_index[rows], self.fill_rule)

    def effective(self, points: torch.Tensor) -> torch.Tensor:
        """Free points with the padding tied to each path's first anchor."""
        return torch.where(self.real[..., None], points, points[:, :, :1])

    def to_vector(self, i: int, points: torch.Tensor, colors: torch.Tensor, like: VectorImage) -> VectorImage:
        """Image ``i`` of the batch from ``points (P, 3K, 2)`` and ``colors (G, 3)``, shaped like ``like``."""
        px = (points.detach().double().cpu() * torch.tensor([like.width, like.height], dtype=torch.float64)).numpy()
        n = (3 * self.counts[i]).tolist()
        sidx = self.shape_index[i].tolist()
        shapes = []
        for gi, sh in enumerate(like.shapes):
            cs = [px[p, : n[p]] for p in range(len(sidx)) if sidx[p] == gi]
            shapes.append(VectorShape(cs, tuple(float(v) for v in colors[gi].clamp(0, 1).tolist()), sh.fill_rule))
        return VectorImage(like.width, like.height, shapes)


def _rule(shapes: list[VectorShape]) -> str:
    """The fill rule to render ``shapes`` under: theirs when they agree, else nonzero."""
    rules = {sh.fill_rule for sh in shapes}
    return rules.pop() if len(rules) == 1 else "nonzero"


def _by_rule(vecs: list[VectorImage]) -> list[list[int]]:
    """The non-empty images of ``vecs``, grouped by the rule they render under (one batch each)."""
    groups: dict[str, list[int]] = {}
    for i, v in enumerate(vecs):
        if v.shapes:
            groups.setdefault(_rule(v.shapes), []).append(i)
    return [groups[r] for r in ("nonzero", "evenodd") if r in groups]


class _Progress:
    """Per-image loss history of a batched optimisation: each image's best loss and its early
    stop (``_converged``). ``live`` lists the images still optimised, in batch order."""

    def __init__(self, n: int, s: RefineSettings):
        self.s, self.hist, self.best, self.live = s, [[] for _ in range(n)], [float("inf")] * n, list(range(n))

    def record(self, losses: list[float]) -> tuple[list[tuple[int, int]], bool]:
        """``losses``: one per live image. Returns ``(position in live, image)`` of the images
        that improved on their best, and whether any stopped (then ``live`` is updated)."""
        better, stopped = [], []
        for a, k in enumerate(self.live):
            self.hist[k].append(losses[a])
            if losses[a] < self.best[k]:
                self.best[k] = losses[a]
                better.append((a, k))
            if _converged(self.hist[k], self.s):
                stopped.append(k)
        if stopped:
            self.live = [k for k in self.live if k not in stopped]
        return better, bool(stopped)


class _Fitter:
    """The objective (pyramid L2 against each input of a batch, at the fit size) and the
    point/colour stages. Every method takes vector images with ``index``, the batch row of
    each one's target (default: the i-th image is row i)."""

    def __init__(self, target: torch.Tensor, samples: int, s: RefineSettings):
        self.size = tuple(target.shape[-2:])
        self.target = gaussian_pyramid(target, s.levels)  # levels of (B, 3, h, w)
        self.samples, self.s = samples, s

    def loss(self, t: _Paths, points, colors, rows: torch.Tensor, tau: float) -> torch.Tensor:
        """Per-image pyramid L2 ``(A,)`` of the paths ``t`` (drawn with ``points``, ``colors``)
        against the targets ``rows (A,)``."""
        renders = render_pyramid(points, colors, t.depth, size=self.size, levels=self.s.levels, tau=tau,
                                 fill_rule=t.fill_rule, shape_index=t.shape_index, counts=t.counts,
                                 samples=self.samples, composite="over")
        return pyramid_l2(renders, [lvl[rows] for lvl in self.target], reduction="none")

    def vector_loss(self, vecs: list[VectorImage], tau: float, index: list[int] | None = None) -> list[float]:
        """The loss of each image (``inf`` for an empty one), one batched render per fill rule."""
        index = list(range(len(vecs))) if index is None else index
        out = [float("inf")] * len(vecs)
        for todo in _by_rule(vecs):
            t = _Paths.of([vecs[i] for i in todo], self.target[0].device)
            rows = torch.tensor([index[i] for i in todo], device=t.points.device)
            with torch.no_grad():
                got = self.loss(t, t.points, t.colors, rows, tau).tolist()
            for i, v in zip(todo, got):
                out[i] = v
        return out

    def fit_points(self, vecs: list[VectorImage], steps: int, tau_start: float, learn_colors: bool, stage: str,
                   on_step, smooth: list[Corners] | None = None, index: list[int] | None = None
                   ) -> tuple[list[VectorImage], list[int]]:
        """Adam on the control points (and colours) of each of ``vecs``, tau annealed to ``tau_end``.

        One batched render per step (per fill rule), one loss per image: an image's gradient
        and Adam state are its own, so the batch gives each image what it alone would get
        (up to float rounding). Each image stops when its loss converges and is rendered no
        more. ``smooth``: per image the corner flags of ``vector.fit.fit_ring``; after every
        step the two handles of each smooth join are made collinear again (projected gradient
        descent). Returns the best result of each image at the final tau and its steps taken."""
        index = list(range(len(vecs))) if index is None else index
        out, taken = list(vecs), [0] * len(vecs)
        if steps <= 0:
            return out, taken
        for todo in _by_rule(vecs):
            got, n = self._fit_batch([vecs[i] for i in todo], steps, tau_start, learn_colors, stage, on_step,
                                     None if smooth is None else [smooth[i] for i in todo], [index[i] for i in todo])
            for i, v, k in zip(todo, got, n):
                out[i], taken[i] = v, k
        return out, taken

    def _fit_batch(self, vecs, steps, tau_start, learn_colors, stage, on_step, smooth, index):
        s = self.s
        t = _Paths.of(vecs, self.target[0].device)
        dev = t.points.device
        pts = t.points.clone().requires_grad_(True)
        cols = t.colors.clone().requires_grad_(learn_colors)
        groups = [{"params": [pts], "lr": s.point_lr}]
        if learn_colors:
            groups.append({"params": [cols], "lr": s.color_lr})
        opt = Adam(groups)
        joins = None if smooth is None else _smooth_joins(vecs, smooth, dev)
        anneal = int(0.6 * steps) if tau_start != s.tau_end else 0
        rows_all = torch.tensor(index, device=dev)
        progress = _Progress(len(vecs), s)
        best_pts, best_cols = t.effective(pts).detach().clone(), cols.detach().clone()
        taken = [0] * len(vecs)
        sub, sel = t, None  # the live images' paths (all of them until one stops)
        for i in range(steps):
            tau = tau_start + (s.tau_end - tau_start) * min(1.0, i / anneal) if anneal else s.tau_end
            p, c = (pts, cols) if sel is None else (pts[sel], cols[sel])
            eff = sub.effective(p)
            fit = self.loss(sub, eff, c.clamp(0, 1), rows_all if sel is None else rows_all[sel], tau)  # (A,)
            loss = fit + _geometry_penalty(eff, sub.real, self.size, s)
            opt.zero_grad()
            loss.sum().backward()
            opt.step()
            if joins is not None:
                _align(pts, joins, self.size)
            if on_step:
                on_step({"stage": stage, "step": i, "loss": float(fit.detach().mean()), "tau": tau,
                         "images": len(progress.live)})
            for k in progress.live:
                taken[k] = i + 1
            if i < anneal:  # compare losses only at the final tau
                continue
            better, stopped = progress.record(loss.tolist())
            for a, k in better:
                best_pts[k], best_cols[k] = eff[a].detach(), c[a].detach()
            if stopped:
                if not progress.live:
                    break
                sel = torch.tensor(progress.live, device=dev)
                sub = t.take(sel)
        return [t.to_vector(k, best_pts[k], best_cols[k], v) for k, v in enumerate(vecs)], taken

    def prune(self, vec: VectorImage, tol: float, row: int) -> VectorImage:
        """Drop paths one at a time (smallest first) while each removal raises the loss at
        ``tau_end`` by less than ``tol`` (relative): slivers and paths hidden by others.
        Each removal is judged on the result of the last, so this runs one image (target
        ``row``) at a time."""
        if tol <= 0 or not vec.shapes:
            return vec
        current = self.vector_loss([vec], self.s.tau_end, [row])[0]
        order = sorted(((gi, ci) for gi, sh in enumerate(vec.shapes) for ci in range(len(sh.contours))),
                       key=lambda gc: abs(_anchor_area(vec.shapes[gc[0]].contours[gc[1]])))
        removed: set[tuple[int, int]] = set()
        for gc in order:
            trial = _without(vec, removed | {gc})
            if trial.num_paths == 0:
                continue
            loss = self.vector_loss([trial], self.s.tau_end, [row])[0]
            if loss <= current * (1 + tol):
                removed.add(gc)
                current = min(current, loss)
        return _without(vec, removed)


def _smooth_joins(vecs: list[VectorImage], flags: list[Corners], device) -> torch.Tensor:
    """``(5, J)`` indices (image, path, anchor, handle before, handle after) of the smooth
    joins of every contour of ``vecs``, in ``_Paths`` order."""
    rows = []
    for b, (vec, fl_img) in enumerate(zip(vecs, flags)):
        p = 0
        for sh, fl in zip(vec.shapes, fl_img):
            for c, f in zip(sh.contours, fl):
                n = len(c)
                rows += [(b, p, 3 * k, (3 * k - 1) % n, 3 * k + 1) for k in np.nonzero(~np.asarray(f, dtype=bool))[0]]
                p += 1
    return torch.tensor(rows, dtype=torch.long, device=device).reshape(-1, 5).T


def _align(pts: torch.Tensor, joins: torch.Tensor, size: tuple[int, int]) -> None:
    """In place on ``pts (B, P, 3K, 2)`` (input-normalised): each smooth join's handles made
    collinear through its anchor (in pixels), their lengths kept."""
    if not joins.shape[1]:
        return
    with torch.no_grad():
        scale = torch.tensor([size[1], size[0]], dtype=pts.dtype, device=pts.device)
        i, p, a, b, c = joins
        anchor, before, after = pts[i, p, a] * scale, pts[i, p, b] * scale, pts[i, p, c] * scale
        la, lb = (after - anchor).norm(dim=-1, keepdim=True), (anchor - before).norm(dim=-1, keepdim=True)
        t = (after - anchor) / la.clamp_min(1e-9) + (anchor - before) / lb.clamp_min(1e-9)
        t = t / t.norm(dim=-1, keepdim=True).clamp_min(1e-9)
        ok = ((la > 1e-6) & (lb > 1e-6)).expand_as(t)
        pts[i, p, c] = torch.where(ok, anchor + la * t, after) / scale
        pts[i, p, b] = torch.where(ok, anchor - lb * t, before) / scale


def _anchor_area(c) -> float:
    """Area of a contour's anchor polygon (px^2): enough to order paths by size."""
    return float(polygon_area(torch.as_tensor(c[0::3])))


def _without(vec: VectorImage, removed: set[tuple[int, int]]) -> VectorImage:
    shapes = []
    for gi, sh in enumerate(vec.shapes):
        cs = [c for ci, c in enumerate(sh.contours) if (gi, ci) not in removed]
        if cs:
            shapes.append(VectorShape(cs, sh.color, sh.fill_rule))
    return VectorImage(vec.width, vec.height, shapes)


class Refinement:
    """The refinement of a batch of images of one size, stage by stage (``refine_batch``
    runs them in order). Every stage takes and returns one item per image (or per ``index``,
    the images it is given), so that one render per step serves the whole batch.

    Holds the model (frozen while it runs), the fit targets ``(B, 3, h, w)`` at the fit size,
    and two objectives: ``fitter`` with the model's lines per cubic for the latent and point
    stages, ``fine`` with ``polish_samples`` that judges results and fits the polish.
    """

    def __init__(self, model: Im2Vec, images: list[torch.Tensor], settings: RefineSettings,
                 on_step: Callable[[dict], None] | None = None):
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

    def encode(self, index: list[int], segments, quality) -> tuple[torch.Tensor, Placement, int | torch.Tensor | None]:
        """The amortised guess of the images ``index``: ``mu (A, D)``, the placement (one for
        the batch: its images share a size), and the segments to decode with."""
        xs, places = zip(*(model_input(self.model, self.images[i]) for i in index))
        with torch.no_grad():
            mu, _ = self.model.encode(torch.stack(xs).to(self.device))
            return mu, places[0], segment_counts(self.model, mu, segments, quality)

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
            renders = render_pyramid(place.model_to_input(dec.points), dec.colors, dec.depth, size=self.fitter.size,
                                     levels=s.levels, tau=s.tau_start, fill_rule=dec.fill_rule, shape_index=sidx,
                                     counts=dec.counts, samples=self.fitter.samples, composite="over")
            loss = pyramid_l2(renders, [lvl[rows_all[sel]] for lvl in self.fitter.target], reduction="none")
            opt.zero_grad()
            loss.sum().backward()
            opt.step()
            for _, j in progress.record(loss.tolist())[0]:
                best_z[j] = z[j].detach()
            if self.on_step:
                self.on_step({"stage": "latent", "step": i, "loss": float(loss.detach().mean()), "images": len(sel)})
            if not progress.live:
                break
        return best_z, [len(h) for h in progress.hist]

    def decode(self, z: torch.Tensor, k, place: Placement, max_paths: int | None, index: list[int]) -> list[VectorImage]:
        """The paths of each latent in the input's frame, overlaps resolved against its input (once)."""
        with torch.no_grad():
            dec = self.model.decode(z, k)
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

    def polish_outline(self, vecs: list[VectorImage], flags: list[Corners], index: list[int]) -> list[VectorImage]:
        """Clean outlines: points and colours polished for ``outline_steps``, smooth joins kept smooth."""
        return self.fine.fit_points(vecs, self.s.outline_steps, self.s.outline_tau, True, "outline", self.on_step,
                                    smooth=flags, index=index)[0]

    def split_where_wrong(self, vec: VectorImage, flags: Corners, row: int) -> tuple[VectorImage, Corners, int]:
        """Halve every segment along which the render still differs from the input ``row`` by
        more than ``split_error`` (mean squared, over the pixels the segment passes and their
        neighbours, cairo at the input's size; scaled by ``(tolerance / 0.5)^2``): the polish
        then has the points it lacked there.

        Returns the new image, its corner flags and the segments split."""
        image = self.images[row]
        _, h, w = image.shape
        got = fill_vector(vec, w, h)  # (H, W, 3): cairo, as rasterize_svg(vec.to_svg(3)) draws it
        err = _box3(((got - image.permute(1, 2, 0).double().cpu().numpy()) ** 2).sum(-1))
        limit = self.s.split_error * (self.s.tolerance / 0.5) ** 2  # a looser tolerance splits less
        shapes, out_flags, count = [], [], 0
        for sh, fl in zip(vec.shapes, flags):
            cs, fs = [], []
            for c, f in zip(sh.contours, fl):
                pts = flatten_closed(torch.from_numpy(np.asarray(c, dtype=np.float64)), 8).numpy().reshape(-1, 8, 2)
                ix = np.clip(pts[..., 0].astype(int), 0, w - 1)
                iy = np.clip(pts[..., 1].astype(int), 0, h - 1)
                bad = np.nonzero(err[iy, ix].mean(1) > limit)[0]
                if len(bad) and len(c) // 3 + len(bad) <= self.s.max_segments:
                    c, f = split_segments(c, f, bad)
                    count += len(bad)
                cs.append(c)
                fs.append(f)
            shapes.append(VectorShape(cs, sh.color, sh.fill_rule))
            out_flags.append(fs)
        return VectorImage(vec.width, vec.height, shapes), out_flags, count

    def loss(self, vecs: list[VectorImage], index: list[int]) -> list[float]:
        """The judge: pyramid L2 at ``tau_end`` with ``polish_samples`` lines per cubic."""
        return self.fine.vector_loss(vecs, self.s.tau_end, index)


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
