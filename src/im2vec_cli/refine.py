"""Test-time refinement: fit the decoded paths of one image to that image.

The amortised encoder gives a first guess; refinement then minimises the pyramid L2
(sec. 3.4, eq. 1) against the input itself, first over the latent ``z`` (the shapes stay
on the model's manifold), then over the control points and colours directly.

Frames: the model decodes in its square frame (``infer.Placement``). Refinement works in
the *input's* normalised frame, ``(x / W, y / H)`` of the input's pixel grid, and renders at
the input's resolution (inputs larger than ``max_side`` are fitted at a reduced copy), so
``tau`` is measured in input pixels.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass

import torch
import torch.nn.functional as F

from .infer import Placement, flat_vector, model_input, to_vector, uniform_color
from .model.vae import Decoded, Im2Vec
from .raster import gaussian_pyramid, pyramid_l2, render_pyramid
from .raster.bezier import segment_controls
from .svg import VectorImage


@dataclass(frozen=True)
class RefineSettings:
    """Optimisation settings of ``refine``."""

    latent_steps: int = 30
    point_steps: int = 80
    latent_lr: float = 0.05
    point_lr: float = 1.5e-3  # normalised units per Adam step (0.1 px on a 64 px image)
    color_lr: float = 0.02
    tau_start: float = 0.8  # edge softness in input pixels, annealed during the point stage...
    tau_end: float = 0.3  # ...to about a box filter's slope, which is what cairo and the input show
    levels: int = 3
    max_side: int = 128  # larger inputs are fitted at this size (then scaled back: the frame is normalised)
    patience: int = 12  # stop when the loss has not improved by min_improvement in this many steps
    min_improvement: float = 2e-3
    margin: float = 0.02  # control points may leave the canvas by this much (normalised) before a penalty
    bounds_weight: float = 10.0
    min_segment_px: float = 0.5  # segments shorter than this are pushed apart (collapsed-segment guard)
    collapse_weight: float = 1e-3


def _geometry_penalty(points: torch.Tensor, size: tuple[int, int], s: RefineSettings) -> torch.Tensor:
    """Keep control points near the canvas and segments from collapsing.

    Args:
        points: ``(1, P, 3k, 2)`` input-normalised frame.
    """
    h, w = size
    out = F.relu(-s.margin - points) + F.relu(points - 1 - s.margin)
    bounds = out.square().sum()
    seg = segment_controls(points * torch.tensor([w, h], dtype=points.dtype, device=points.device))  # (1, P, k, 4, 2)
    chord = (seg[..., 3, :] - seg[..., 0, :]).norm(dim=-1)  # (1, P, k) px
    collapse = F.relu(s.min_segment_px - chord).square().sum()
    return s.bounds_weight * bounds + s.collapse_weight * collapse


def _converged(history: list[float], s: RefineSettings) -> bool:
    if len(history) <= s.patience:
        return False
    before = min(history[: -s.patience])
    return min(history[-s.patience :]) > before * (1 - s.min_improvement)


def refine(
    model: Im2Vec,
    image: torch.Tensor,
    *,
    segments: int | None = None,
    max_paths: int | None = None,
    settings: RefineSettings = RefineSettings(),
    on_step: Callable[[dict], None] | None = None,
) -> tuple[VectorImage, dict]:
    """Vectorise one image ``(3, H, W)`` in [0, 1] and refine the result against it.

    Returns:
        The vector image (input pixel frame) and a summary: the pyramid L2 before and after
        (at ``tau_end``), and the steps taken in each stage.
    """
    s = settings
    if image.dim() != 3 or image.shape[0] != 3:
        raise ValueError(f"image must be (3, H, W), got {tuple(image.shape)}")
    dev = next(model.parameters()).device
    _, h, w = image.shape
    place = Placement(w, h)
    flat = uniform_color(image)
    if flat is not None:  # nothing to fit: the same answer as amortised vectorisation
        return flat_vector(place, flat), {"loss_start": 0.0, "loss_end": 0.0, "latent_steps": 0, "point_steps": 0}
    x, _ = model_input(model, image)
    fit_h, fit_w = h, w
    if max(h, w) > s.max_side:
        f = s.max_side / max(h, w)
        fit_h, fit_w = max(4, round(h * f)), max(4, round(w * f))
    target_img = image[None].to(dev)
    if (fit_h, fit_w) != (h, w):
        target_img = F.interpolate(target_img, size=(fit_h, fit_w), mode="area")
    target = gaussian_pyramid(target_img, s.levels)
    side = place.side
    left, top = place.offset
    scale = torch.tensor([side / w, side / h], device=dev)  # model-normalised -> input-normalised
    shift = torch.tensor([left / w, top / h], device=dev)
    cfg = model.config

    def loss_of(points, colors, dec: Decoded, tau: float) -> torch.Tensor:
        renders = render_pyramid(points, colors, dec.depth, size=(fit_h, fit_w), levels=s.levels, tau=tau,
                                 fill_rule=dec.fill_rule, shape_index=dec.shape_index, samples=cfg.samples,
                                 composite="over")
        return pyramid_l2(renders, target)

    req = [p.requires_grad for p in model.parameters()]
    for p in model.parameters():
        p.requires_grad_(False)
    try:
        with torch.enable_grad():
            mu, _ = model.encode(x[None].to(dev))
            z = mu.detach().clone().requires_grad_(True)
            with torch.no_grad():
                dec0 = model.decode(z, segments)
                start = float(loss_of(dec0.points * scale - shift, dec0.colors, dec0, s.tau_end))
            # stage 1: the latent
            opt = torch.optim.Adam([z], lr=s.latent_lr)
            hist: list[float] = []
            best_z, best = z.detach().clone(), float("inf")
            for i in range(s.latent_steps):
                dec = model.decode(z, segments)
                loss = loss_of(dec.points * scale - shift, dec.colors, dec, s.tau_start)
                opt.zero_grad()
                loss.backward()
                opt.step()
                hist.append(loss.item())
                if hist[-1] < best:
                    best, best_z = hist[-1], z.detach().clone()
                if on_step:
                    on_step({"stage": "latent", "step": i, "loss": hist[-1]})
                if _converged(hist, s):
                    break
            latent_steps = len(hist)
            with torch.no_grad():
                dec = model.decode(best_z, segments)
            # stage 2: control points and colours
            pts = (dec.points * scale - shift).detach().clone().requires_grad_(True)
            learn_colors = not model.palette.numel()
            cols = dec.colors.detach().clone().requires_grad_(learn_colors)
            groups = [{"params": [pts], "lr": s.point_lr}]
            if learn_colors:
                groups.append({"params": [cols], "lr": s.color_lr})
            opt = torch.optim.Adam(groups)
            anneal = max(1, int(0.6 * s.point_steps))
            hist = []
            best_pts, best_cols, best = pts.detach().clone(), cols.detach().clone(), float("inf")
            for i in range(s.point_steps):
                tau = s.tau_start + (s.tau_end - s.tau_start) * min(1.0, i / anneal)
                fit = loss_of(pts, cols.clamp(0, 1), dec, tau)
                loss = fit + _geometry_penalty(pts, (fit_h, fit_w), s)
                opt.zero_grad()
                loss.backward()
                opt.step()
                if on_step:
                    on_step({"stage": "points", "step": i, "loss": fit.item(), "tau": tau})
                if i >= anneal:  # compare losses only at the final tau
                    hist.append(loss.item())
                    if hist[-1] < best:
                        best, best_pts, best_cols = hist[-1], pts.detach().clone(), cols.detach().clone()
                    if _converged(hist, s):
                        break
            point_steps = i + 1
            if best == float("inf"):
                best_pts, best_cols = pts.detach().clone(), cols.detach().clone()
            with torch.no_grad():
                end = float(loss_of(best_pts, best_cols.clamp(0, 1), dec, s.tau_end))
    finally:
        for p, r in zip(model.parameters(), req):
            p.requires_grad_(r)
    if end > start:  # refinement never makes the result worse than the amortised guess
        best_pts, best_cols, end = dec0.points * scale - shift, dec0.colors, start
        dec = dec0
    out = dataclasses.replace(dec, points=((best_pts + shift) / scale).detach(), colors=best_cols.clamp(0, 1).detach())
    vec = to_vector(out, 0, place, max_paths=max_paths)
    return vec, {"loss_start": start, "loss_end": end, "latent_steps": latent_steps, "point_steps": point_steps}
