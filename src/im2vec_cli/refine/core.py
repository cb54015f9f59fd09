"""The optimiser core of refinement: vector images packed as tensors (``_Paths``), early
stopping (``_Progress``), and batched Adam through the renderer (``_Fitter``), with the
geometry guards (and the projections after each step: ``projections.py``)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F

from ..events import RefineStep
from ..optim import Adam
from ..options import Plan
from ..raster import gaussian_pyramid, polygon_area, pyramid_l2, render_pyramid, segment_controls
from ..trace import Corners
from ..vector import VectorImage, VectorShape, fill_vector
from .projections import align, joins_and_lines, straighten


def _geometry_penalty(points: torch.Tensor, real: torch.Tensor, size: tuple[int, int], s: Plan) -> torch.Tensor:
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


def _converged(history: list[float], s: Plan) -> bool:
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

    def __init__(self, n: int, s: Plan):
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

    def __init__(self, target: torch.Tensor, samples: int, s: Plan):
        self.size = tuple(target.shape[-2:])
        self.target = gaussian_pyramid(target, s.levels)  # levels of (B, 3, h, w)
        self.samples, self.s = samples, s

    def loss(self, points: torch.Tensor, colors: torch.Tensor, depth: torch.Tensor, rows: torch.Tensor, tau: float, *,
             fill_rule: str, shape_index: torch.Tensor | None, counts: torch.Tensor | None) -> torch.Tensor:
        """The one render + loss of refinement (the latent stage and the point stages call it):
        per-image pyramid L2 ``(A,)`` of the paths ``points (A, P, 3K, 2)`` (input-normalised),
        ``colors (A, G, 3)``, ``depth (A, G)`` against the targets ``rows (A,)``."""
        renders = render_pyramid(points, colors, depth, size=self.size, levels=self.s.levels, tau=tau,
                                 fill_rule=fill_rule, shape_index=shape_index, counts=counts,
                                 samples=self.samples, composite="over")
        return pyramid_l2(renders, [lvl[rows] for lvl in self.target], reduction="none")

    def paths_loss(self, t: _Paths, points: torch.Tensor, colors: torch.Tensor, rows: torch.Tensor, tau: float
                   ) -> torch.Tensor:
        """``loss`` of the paths ``t`` drawn with ``points`` and ``colors``."""
        return self.loss(points, colors, t.depth, rows, tau, fill_rule=t.fill_rule, shape_index=t.shape_index,
                         counts=t.counts)

    def vector_loss(self, vecs: list[VectorImage], tau: float, index: list[int] | None = None) -> list[float]:
        """The loss of each image (``inf`` for an empty one), one batched render per fill rule."""
        index = list(range(len(vecs))) if index is None else index
        out = [float("inf")] * len(vecs)
        for todo in _by_rule(vecs):
            t = _Paths.of([vecs[i] for i in todo], self.target[0].device)
            rows = torch.tensor([index[i] for i in todo], device=t.points.device)
            with torch.no_grad():
                got = self.paths_loss(t, t.points, t.colors, rows, tau).tolist()
            for i, v in zip(todo, got):
                out[i] = v
        return out

    def fit_points(self, vecs: list[VectorImage], steps: int, tau_start: float, learn_colors: bool, stage: str,
                   on_step, smooth: list[Corners] | None = None, index: list[int] | None = None,
                   straight: list[bool] | None = None) -> tuple[list[VectorImage], list[int]]:
        """Adam on the control points (and colours) of each of ``vecs``, tau annealed to ``tau_end``.

        One batched render per step (per fill rule), one loss per image: an image's gradient
        and Adam state are its own, so the batch gives each image what it alone would get
        (up to float rounding). Each image stops when its loss converges and is rendered no
        more. ``smooth``: per image the corner flags of ``trace.fit_rings``; after every
        step the two handles of each smooth join are made collinear again and, in the images
        ``straight`` says, each line straight (projected gradient descent: ``projections.py``). Returns the best result of each image at the final tau and its steps taken."""
        index = list(range(len(vecs))) if index is None else index
        out, taken = list(vecs), [0] * len(vecs)
        if steps <= 0:
            return out, taken
        for todo in _by_rule(vecs):
            got, n = self._fit_batch([vecs[i] for i in todo], steps, tau_start, learn_colors, stage, on_step,
                                     None if smooth is None else [smooth[i] for i in todo], [index[i] for i in todo],
                                     [bool(straight and straight[i]) for i in todo])
            for i, v, k in zip(todo, got, n):
                out[i], taken[i] = v, k
        return out, taken

    def _fit_batch(self, vecs, steps, tau_start, learn_colors, stage, on_step, smooth, index, straight):
        s = self.s
        t = _Paths.of(vecs, self.target[0].device)
        dev = t.points.device
        pts = t.points.clone().requires_grad_(True)
        cols = t.colors.clone().requires_grad_(learn_colors)
        groups = [{"params": [pts], "lr": s.point_lr}]
        if learn_colors:
            groups.append({"params": [cols], "lr": s.color_lr})
        opt = Adam(groups)
        joins, lines = (None, None) if smooth is None else joins_and_lines(vecs, smooth, straight, dev)
        hold = None if smooth is None else _hidden(vecs, t.points.shape[:3], dev)  # (B, P, 3K): points held
        hold = hold if hold is not None and bool(hold.any()) else None  # (at their start: t.points)
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
            fit = self.paths_loss(sub, eff, c.clamp(0, 1), rows_all if sel is None else rows_all[sel], tau)  # (A,)
            loss = fit + _geometry_penalty(eff, sub.real, self.size, s)
            opt.zero_grad()
            loss.sum().backward()
            opt.step()
            if joins is not None:
                straighten(pts, lines, t.counts)
                align(pts, joins, self.size)
            if hold is not None:
                with torch.no_grad():
                    pts.copy_(torch.where(hold[..., None], t.points, pts))
            if on_step:
                on_step(RefineStep(stage, i, float(fit.detach().mean()), len(progress.live), tau))
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


HIDDEN_DEPTH = 0.5  # input px: control points this deep under the shapes above their own are held in the polish


def _hidden(vecs: list[VectorImage], shape: tuple[int, int, int], device) -> torch.Tensor:
    """``(B, P, 3K)`` bool, in ``_Paths`` order: the control points of each contour that lie
    more than ``HIDDEN_DEPTH`` px inside the shapes drawn above its own (cairo at 4x). The
    polish sees nothing of a hidden edge but the soft edges of what covers it, and pulled
    such edges out into slivers of background beside the strokes above (OpenMoji faces).
    A picture of one shape has none (and needs no cairo)."""
    out = torch.zeros(shape, dtype=torch.bool)
    for b, vec in enumerate(vecs):
        if len(vec.shapes) < 2:
            continue
        flags = [f for per_shape in _held(vec) for f in per_shape]  # one per contour, in _Paths order
        for p, f in enumerate(flags):
            out[b, p, : len(f)] = torch.from_numpy(f)
    return out.to(device)


HIDDEN_UP = 4  # ``_held`` draws at 4x the picture's size
_R = HIDDEN_DEPTH * HIDDEN_UP  # the depth in pixels of the 4x drawing
_DISK = [(dx, dy) for dx in range(-int(_R), int(_R) + 1) for dy in range(-int(_R), int(_R) + 1)
         if dx * dx + dy * dy <= _R * _R]  # the offsets within it


def _held(vec: VectorImage) -> list[list[np.ndarray]]:
    """Per shape of ``vec``, per contour, ``(3K,)`` bool: its control points ``_deep`` under the
    shapes above it, drawn front to back into one ``(4H, 4W)`` mask (the back shape is not drawn:
    nothing lies under it)."""
    w, h = vec.width, vec.height
    above = np.zeros((round(h * HIDDEN_UP), round(w * HIDDEN_UP)), dtype=bool)
    out = []
    for i, sh in enumerate(reversed(vec.shapes)):  # front to back: ``above`` is what covers this shape
        out.append([_deep(above, np.asarray(c)) for c in sh.contours])
        if i < len(vec.shapes) - 1:
            ink = fill_vector(VectorImage(w, h, [VectorShape(sh.contours, (0.0, 0.0, 0.0), sh.fill_rule)]),
                              above.shape[1], above.shape[0])
            above |= ink[..., 0] < 0.5
    return out[::-1]


def _deep(above: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """``(N,)`` bool: the points ``pts (N, 2)`` (input px) more than ``HIDDEN_DEPTH`` px inside
    ``above``: every pixel of the disk of that radius around the point's pixel covered (the
    Euclidean distance transform's test, at the few points asked instead of every pixel)."""
    h, w = above.shape
    ix = np.clip((pts[:, 0] * HIDDEN_UP).astype(int), 0, w - 1)
    iy = np.clip((pts[:, 1] * HIDDEN_UP).astype(int), 0, h - 1)
    deep = np.ones(len(pts), dtype=bool)
    for dx, dy in _DISK:  # the disk's pixels off the picture are not asked (as the transform does)
        deep &= above[np.clip(iy + dy, 0, h - 1), np.clip(ix + dx, 0, w - 1)]
    return deep


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
