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
from .raster import flatten_closed, gaussian_pyramid, polygon_area, pyramid_l2, render_pyramid, segment_controls
from .vector import VectorImage, VectorShape, rasterize_svg, resolve_overlaps, simplify
from .vector.fit import split_segments
from .vector.outline import Corners, redrawn, traced, untangle
from .vector.trace import background_color, two_tone

PARTS = ("clean", "model")  # `vectorize --parts`: clean outlines (default) or the model's own paths
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


# Named efforts (`vectorize --effort`, whose choices cli.py spells out to keep torch out of
# `--help`). "best" is ``RefineSettings()``; "fast" takes about a third of the steps and a
# coarser polish polygon: on 62 held-out Liberation Sans Narrow glyphs
# at 64 px (fonts model) IoU@4x 0.9855 and MSE 0.00051 in 0.26 s per glyph, against 0.9913,
# 0.00022 and 0.79 s (on all 248 glyphs, `make bench-vectorize`: 0.9867 / 0.00036 in 0.44 s against
# 0.9914 / 0.00018 in 1.01 s; potrace 0.9524 / 0.00283), so that one `vectorize` fits in about 2 s
# with torch's import.
EFFORTS = {
    "fast": RefineSettings(latent_steps=5, point_steps=25, polish_steps=15, polish_samples=8, outline_steps=25,
                           model_start=False),
    "best": RefineSettings(split_error=0.005),
}


def _geometry_penalty(points: torch.Tensor, real: torch.Tensor, size: tuple[int, int], s: RefineSettings) -> torch.Tensor:
    """Keep control points near the canvas and segments from collapsing.

    Args:
        points: ``(1, P, 3K, 2)`` input-normalised frame; real ``(1, P, 3K)`` false on padding.
    """
    h, w = size
    out = F.relu(-s.margin - points) + F.relu(points - 1 - s.margin)
    bounds = out.square().sum()
    seg = segment_controls(points * torch.tensor([w, h], dtype=points.dtype, device=points.device))  # (1, P, K, 4, 2)
    chord = (seg[..., 3, :] - seg[..., 0, :]).norm(dim=-1)  # (1, P, K) px
    collapse = (F.relu(s.min_segment_px - chord).square() * real[..., 0::3]).sum()
    return s.bounds_weight * bounds + s.collapse_weight * collapse


def _converged(history: list[float], s: RefineSettings) -> bool:
    if len(history) <= s.patience:
        return False
    before = min(history[: -s.patience])
    return min(history[-s.patience :]) > before * (1 - s.min_improvement)


@dataclass
class _Paths:
    """A ``VectorImage`` as renderer tensors: every contour one path, padded to the longest.

    points ``(1, P, 3K, 2)`` input-normalised; real ``(1, P, 3K)`` (false on padding, which
    repeats the path's first anchor); colors ``(1, G, 3)``; depth ``(1, G)``; shape_index ``(P,)``.
    """

    points: torch.Tensor
    real: torch.Tensor
    colors: torch.Tensor
    depth: torch.Tensor
    shape_index: torch.Tensor
    fill_rule: str

    @classmethod
    def of(cls, vec: VectorImage, device) -> _Paths:
        conts = [(gi, torch.as_tensor(c, dtype=torch.float32)) for gi, sh in enumerate(vec.shapes) for c in sh.contours]
        big = max(len(c) for _, c in conts)
        scale = torch.tensor([vec.width, vec.height])
        pts = torch.stack([torch.cat([c, c[:1].expand(big - len(c), 2)]) / scale for _, c in conts])
        real = torch.stack([torch.arange(big) < len(c) for _, c in conts])
        rules = {sh.fill_rule for sh in vec.shapes}
        return cls(pts[None].to(device), real[None].to(device),
                   torch.tensor([sh.color for sh in vec.shapes], dtype=torch.float32, device=device)[None],
                   torch.arange(len(vec.shapes), dtype=torch.float32, device=device)[None],
                   torch.tensor([gi for gi, _ in conts], device=device), rules.pop() if len(rules) == 1 else "nonzero")

    def effective(self, points: torch.Tensor) -> torch.Tensor:
        """Free points with the padding tied to each path's first anchor."""
        return torch.where(self.real[..., None], points, points[:, :, :1])

    def to_vector(self, points: torch.Tensor, colors: torch.Tensor, like: VectorImage) -> VectorImage:
        px = (points[0].detach().double().cpu() * torch.tensor([like.width, like.height], dtype=torch.float64)).numpy()
        real = self.real[0].cpu()
        sidx = self.shape_index.tolist()
        shapes = []
        for gi, sh in enumerate(like.shapes):
            cs = [px[p][real[p].numpy()] for p in range(len(sidx)) if sidx[p] == gi]
            shapes.append(VectorShape(cs, tuple(float(v) for v in colors[0, gi].clamp(0, 1).tolist()), sh.fill_rule))
        return VectorImage(like.width, like.height, shapes)


class _Fitter:
    """The objective (pyramid L2 against the input at the fit size) and the point/colour stages."""

    def __init__(self, target: torch.Tensor, samples: int, s: RefineSettings):
        self.size = tuple(target.shape[-2:])
        self.target = gaussian_pyramid(target, s.levels)
        self.samples, self.s = samples, s

    def loss(self, points, colors, depth, shape_index, fill_rule: str, tau: float) -> torch.Tensor:
        renders = render_pyramid(points, colors, depth, size=self.size, levels=self.s.levels, tau=tau,
                                 fill_rule=fill_rule, shape_index=shape_index, samples=self.samples, composite="over")
        return pyramid_l2(renders, self.target)

    def vector_loss(self, vec: VectorImage, tau: float) -> float:
        if not vec.shapes:
            return float("inf")
        t = _Paths.of(vec, self.target[0].device)
        with torch.no_grad():
            return float(self.loss(t.points, t.colors, t.depth, t.shape_index, t.fill_rule, tau))

    def fit_points(self, vec: VectorImage, steps: int, tau_start: float, learn_colors: bool, stage: str,
                   on_step, smooth: Corners | None = None) -> tuple[VectorImage, int]:
        """Adam on the control points (and colours) of ``vec``, annealing tau to ``tau_end``.

        ``smooth``: per contour the corner flags of ``vector.fit.fit_ring``; after every step
        the two handles of each smooth join are made collinear again (projected gradient
        descent), so the fit keeps the joins' smoothness. Returns the best result at the
        final tau and the steps taken."""
        s = self.s
        if not vec.shapes or steps <= 0:
            return vec, 0
        t = _Paths.of(vec, self.target[0].device)
        pts = t.points.clone().requires_grad_(True)
        cols = t.colors.clone().requires_grad_(learn_colors)
        groups = [{"params": [pts], "lr": s.point_lr}]
        if learn_colors:
            groups.append({"params": [cols], "lr": s.color_lr})
        opt = Adam(groups)
        joins = None if smooth is None else _smooth_joins(vec, smooth, pts.device)
        anneal = int(0.6 * steps) if tau_start != s.tau_end else 0
        hist: list[float] = []
        best, best_pts, best_cols = float("inf"), pts.detach().clone(), cols.detach().clone()
        i = -1
        for i in range(steps):
            tau = tau_start + (s.tau_end - tau_start) * min(1.0, i / anneal) if anneal else s.tau_end
            eff = t.effective(pts)
            fit = self.loss(eff, cols.clamp(0, 1), t.depth, t.shape_index, t.fill_rule, tau)
            loss = fit + _geometry_penalty(eff, t.real, self.size, s)
            opt.zero_grad()
            loss.backward()
            opt.step()
            if joins is not None:
                _align(pts, joins, self.size)
            if on_step:
                on_step({"stage": stage, "step": i, "loss": fit.item(), "tau": tau})
            if i >= anneal:  # compare losses only at the final tau
                hist.append(loss.item())
                if hist[-1] < best:
                    best, best_pts, best_cols = hist[-1], eff.detach().clone(), cols.detach().clone()
                if _converged(hist, s):
                    break
        return t.to_vector(best_pts, best_cols, vec), i + 1

    def prune(self, vec: VectorImage, tol: float) -> VectorImage:
        """Drop paths one at a time (smallest first) while each removal raises the loss at
        ``tau_end`` by less than ``tol`` (relative): slivers and paths hidden by others."""
        if tol <= 0:
            return vec
        current = self.vector_loss(vec, self.s.tau_end)
        order = sorted(((gi, ci) for gi, sh in enumerate(vec.shapes) for ci in range(len(sh.contours))),
                       key=lambda gc: abs(_anchor_area(vec.shapes[gc[0]].contours[gc[1]])))
        removed: set[tuple[int, int]] = set()
        for gc in order:
            trial = _without(vec, removed | {gc})
            if trial.num_paths == 0:
                continue
            loss = self.vector_loss(trial, self.s.tau_end)
            if loss <= current * (1 + tol):
                removed.add(gc)
                current = min(current, loss)
        return _without(vec, removed)


def _smooth_joins(vec: VectorImage, flags: Corners, device) -> torch.Tensor:
    """``(4, J)`` indices (path, anchor, handle before, handle after) of the smooth joins of
    ``vec``'s contours, in ``_Paths`` order."""
    rows, p = [], 0
    for sh, fl in zip(vec.shapes, flags):
        for c, f in zip(sh.contours, fl):
            n = len(c)
            rows += [(p, 3 * k, (3 * k - 1) % n, 3 * k + 1) for k in np.nonzero(~np.asarray(f, dtype=bool))[0]]
            p += 1
    return torch.tensor(rows, dtype=torch.long, device=device).reshape(-1, 4).T


def _align(pts: torch.Tensor, joins: torch.Tensor, size: tuple[int, int]) -> None:
    """In place on ``pts (1, P, 3K, 2)`` (input-normalised): each smooth join's handles made
    collinear through its anchor (in pixels), their lengths kept."""
    if not joins.shape[1]:
        return
    with torch.no_grad():
        scale = torch.tensor([size[1], size[0]], dtype=pts.dtype, device=pts.device)
        p, a, b, c = joins
        anchor, before, after = pts[0, p, a] * scale, pts[0, p, b] * scale, pts[0, p, c] * scale
        la, lb = (after - anchor).norm(dim=-1, keepdim=True), (anchor - before).norm(dim=-1, keepdim=True)
        t = (after - anchor) / la.clamp_min(1e-9) + (anchor - before) / lb.clamp_min(1e-9)
        t = t / t.norm(dim=-1, keepdim=True).clamp_min(1e-9)
        ok = ((la > 1e-6) & (lb > 1e-6)).expand_as(t)
        pts[0, p, c] = torch.where(ok, anchor + la * t, after) / scale
        pts[0, p, b] = torch.where(ok, anchor - lb * t, before) / scale


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
    """One image's refinement, stage by stage (``refine`` runs them in order).

    Holds the model (frozen while it runs), the fit target at the fit size, and two
    objectives: ``fitter`` with the model's lines per cubic for the latent and point stages,
    ``fine`` with ``polish_samples`` that judges results and fits the polish.
    """

    def __init__(self, model: Im2Vec, image: torch.Tensor, settings: RefineSettings,
                 on_step: Callable[[dict], None] | None = None):
        s = self.s = settings
        self.model, self.image, self.on_step = model, image, on_step
        self.device = next(model.parameters()).device
        _, h, w = image.shape
        target = image[None].to(self.device)
        if max(h, w) > s.max_side:
            f = s.max_side / max(h, w)
            target = F.interpolate(target, size=(max(4, round(h * f)), max(4, round(w * f))), mode="area")
        self.fitter = _Fitter(target, model.config.samples, s)
        self.fine = _Fitter(target, max(s.polish_samples, model.config.samples), s)

    def encode(self, segments, quality) -> tuple[torch.Tensor, Placement, int | torch.Tensor | None]:
        """The amortised guess: ``mu (1, D)``, the placement, and the segments to decode with."""
        x, place = model_input(self.model, self.image)
        with torch.no_grad():
            mu, _ = self.model.encode(x[None].to(self.device))
            return mu, place, segment_counts(self.model, mu, segments, quality)

    def fit_latent(self, mu: torch.Tensor, k, place: Placement) -> tuple[torch.Tensor, int]:
        """Stage 1: Adam on the latent (the shapes stay on the model's manifold), at ``tau_start``.

        Returns the best latent (``mu`` itself when no step improves on it) and the steps taken."""
        s = self.s
        z = mu.clone().requires_grad_(True)
        opt = Adam([{"params": [z], "lr": s.latent_lr}])
        hist: list[float] = []
        best_z, best = z.detach().clone(), float("inf")
        for i in range(s.latent_steps):
            dec = self.model.decode(z, k)
            loss = self.fitter.loss(place.model_to_input(dec.points), dec.colors, dec.depth, dec.shape_index,
                                    dec.fill_rule, s.tau_start)
            opt.zero_grad()
            loss.backward()
            opt.step()
            hist.append(loss.item())
            if hist[-1] < best:
                best, best_z = hist[-1], z.detach().clone()
            if self.on_step:
                self.on_step({"stage": "latent", "step": i, "loss": hist[-1]})
            if _converged(hist, s):
                break
        return best_z, len(hist)

    def decode(self, z: torch.Tensor, k, place: Placement, max_paths: int | None) -> VectorImage:
        """The paths of ``z`` in the input's frame, overlaps resolved against the input (once)."""
        with torch.no_grad():
            return resolve_overlaps(to_vector(self.model.decode(z, k), 0, place, max_paths=max_paths), self.image)

    def fit_points(self, vec: VectorImage) -> tuple[VectorImage, int]:
        """Stage 2: control points and colours (learned-colour models only), tau annealed."""
        learn_colors = not self.model.palette.numel()
        return self.fitter.fit_points(vec, self.s.point_steps, self.s.tau_start, learn_colors, "points", self.on_step)

    def prune(self, vec: VectorImage) -> VectorImage:
        """Drop paths that do not change the result (``_Fitter.prune``)."""
        return self.fitter.prune(vec, self.s.prune_tol)

    def simplify_and_polish(self, vec: VectorImage) -> tuple[VectorImage, int]:
        """Stage 3: merge segments within ``simplify_tol`` px, then a short points-only polish."""
        if self.s.simplify_tol <= 0:
            return vec, 0
        return self.fine.fit_points(simplify(vec, self.s.simplify_tol), self.s.polish_steps, self.s.tau_end, False,
                                    "polish", self.on_step)

    def polish_outline(self, vec: VectorImage, flags: Corners) -> VectorImage:
        """Clean outlines: points and colours polished for ``outline_steps``, smooth joins kept smooth."""
        return self.fine.fit_points(vec, self.s.outline_steps, self.s.outline_tau, True, "outline", self.on_step,
                                    smooth=flags)[0]

    def split_where_wrong(self, vec: VectorImage, flags: Corners) -> tuple[VectorImage, Corners, int]:
        """Halve every segment along which the render still differs from the input by more
        than ``split_error`` (mean squared, over the pixels the segment passes, cairo at the
        input's size; scaled by ``(tolerance / 0.5)^2``): the polish then has the points it
        lacked there.

        Returns the new image, its corner flags and the segments split."""
        from scipy.ndimage import uniform_filter

        _, h, w = self.image.shape
        got = rasterize_svg(vec.to_svg(3), w, h)  # (H, W, 3)
        err = ((got - self.image.permute(1, 2, 0).double().cpu().numpy()) ** 2).sum(-1)
        err = uniform_filter(err, 3)
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

    def loss(self, vec: VectorImage) -> float:
        """The judge: pyramid L2 at ``tau_end`` with ``polish_samples`` lines per cubic."""
        return self.fine.vector_loss(vec, self.s.tau_end)


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
    if parts not in PARTS:
        raise ValueError(f"parts must be one of {PARTS}, got {parts!r}")
    flat = flat_result(image)
    if flat is not None:  # nothing to fit: the same answer as amortised vectorisation
        return flat, {"loss_start": 0.0, "loss_end": 0.0, "latent_steps": 0, "point_steps": 0}
    run = Refinement(model, image, settings, on_step)
    req = [p.requires_grad for p in model.parameters()]
    for p in model.parameters():
        p.requires_grad_(False)
    try:
        with torch.enable_grad():
            if parts == "model":
                vec, info = _model_paths(run, segments, quality, max_paths)
            else:
                vec, info = _clean(run, segments, quality, colors, max_paths)
    finally:
        for p, r in zip(model.parameters(), req):
            p.requires_grad_(r)
    return vec, info


def _model_paths(run: Refinement, segments, quality, max_paths, outline: bool = False) -> tuple[VectorImage, dict]:
    """The model's paths refined (``parts="model"``); never worse than the model's guess.

    ``outline``: stop after the point stage (the paths are then united and refitted)."""
    mu, place, k = run.encode(segments, quality)
    z, latent_steps = run.fit_latent(mu, k, place)
    guess = run.decode(z, k, place, max_paths)
    start = run.loss(guess)
    vec, point_steps = run.fit_points(guess)
    if outline:
        return vec, {"loss_start": start, "latent_steps": latent_steps, "point_steps": point_steps}
    vec = run.prune(vec)
    fitted_segments = vec.num_segments
    vec, polish_steps = run.simplify_and_polish(vec)
    end = run.loss(vec)
    if end > start:  # refinement never makes the result worse than the model's guess
        vec, end = simplify(guess, run.s.simplify_tol), start
    return vec, {"loss_start": start, "loss_end": end, "latent_steps": latent_steps, "point_steps": point_steps,
                 "polish_steps": polish_steps, "segments_fitted": fitted_segments, "segments": vec.num_segments}


def _clean(run: Refinement, segments, quality, colors: int | None, max_paths: int | None) -> tuple[VectorImage, dict]:
    """Clean outlines from the image's regions and, for a two-tone image, from the model's
    refined paths; the start nearer the image is polished (and split where still wrong)."""
    picture = run.image.permute(1, 2, 0).double().cpu().numpy()  # (H, W, 3)
    # The contours of a clean shape do not overlap, so even-odd renders them as nonzero does,
    # without the renderer's boundary search (seconds on a picture of many regions); written nonzero.
    starts = {"image": lambda tol: _evenodd(*traced(picture, tol, colors, max_paths))}
    info: dict = {}
    if run.s.model_start and colors in (None, 1) and two_tone(picture, background_color(picture)) is not None:
        # Multi-colour pictures: the shipped emoji model's paths lost to the image's own regions on
        # every OpenMoji face tried (bench/outlines.py) and cost seconds, so only the image is traced.
        model_vec, info = _model_paths(run, segments, quality, max_paths, outline=True)
        if model_vec.shapes:
            starts["model"] = lambda tol: _evenodd(*redrawn(model_vec, tol, picture))
    if len(starts) > 1:  # chosen at one tolerance for all, so that a looser one never changes the choice
        scored = sorted((run.loss(make(CHOICE_TOLERANCE)[0]), name) for name, make in starts.items())
        name = scored[0][1]  # the polish moves points by a fraction of a pixel: it does not reorder the starts
    else:
        name = "image"
    vec, flags = starts[name](run.s.tolerance)
    if not vec.shapes:  # nothing to draw
        return vec, {**info, "loss_end": run.loss(vec), "start": name, "segments": 0}
    vec = run.polish_outline(vec, flags)
    loss = run.loss(vec)
    if run.s.split_error > 0:
        more, flags, n = run.split_where_wrong(vec, flags)
        if n:
            more = run.polish_outline(more, flags)
            more_loss = run.loss(more)
            if more_loss < loss:
                vec, loss = more, more_loss
    out = untangle(_with_rule(vec, "nonzero"))
    return out, {**info, "loss_end": loss, "start": name, "segments": out.num_segments}


def _with_rule(vec: VectorImage, rule: str) -> VectorImage:
    return VectorImage(vec.width, vec.height, [VectorShape(sh.contours, sh.color, rule) for sh in vec.shapes])


def _evenodd(vec: VectorImage, flags: Corners) -> tuple[VectorImage, Corners]:
    return _with_rule(vec, "evenodd"), flags
