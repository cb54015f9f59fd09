"""Projection: the model's paths fitted to pictures (semi-amortised inference, Kim et al. 2018).

The encoder's guess ``z = mu`` is only where a fit starts: on held-out glyphs its paths have
12x the raster baseline's error (docs/results/fonts-ablation.md). ``project`` fits a batch of
pictures through our renderer, with Adam on the L2 of the soft render against each picture
at the model's size, one loss per picture (a picture's fit is its own), in three stages:

1. the latent ``z`` (``latent_steps``): the shapes stay on the model's manifold;
2. the per-path codes (``code_steps``): the LSTM bypassed, the path decoder kept;
3. the control points (``point_steps``): offsets from the decoded paths (moved by the model's
   point passes, ``ModelConfig.point_passes``, where it has them), and the colours of a
   learned-colour model.

Each stage keeps each picture's best step. On the 24 glyphs of held-out faces of
``bench/morphs.py`` the IoU@4x of their clean outlines against the true outlines is 0.913
from the guess, 0.937 with the latent fitted, 0.944 with the codes too and 0.977 with the
points.

A ``Projection`` is ``z`` with its paths (``Decoded``: points ``(N, P, 3k, 2)`` in the model's
square, normalised). Every projection of one model has the same ``P`` paths of ``k``
segments in the same order, so ``between`` morphs path ``i`` of one into path ``i`` of the
other: frames are the linear interpolation of their points, colours and depths.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch

from .files import as_image
from .frame import Placement
from .infer import model_input, to_vector
from .model.vae import Decoded, Im2Vec
from .optim import Adam
from .raster import gaussian_pyramid, pyramid_l2, render_pyramid
from .trace import cleaned
from .vector import VectorImage, VectorShape, picture_array, resolve_overlaps


@dataclass(frozen=True)
class ProjectSettings:
    """The stages of ``project`` (steps 0: the stage is skipped; all 0: the encoder's guess).

    The defaults fit two 64 px glyphs in about 1 s on 2 CPU cores (``im2vec interpolate`` of
    two glyphs: 3.3-4.2 s wall with the process start). On the 12 pairs of
    ``bench/morphs.py`` 20/20/30 steps kept 93% of frames with the character's pieces and
    holes where 30/30/60 kept 99% (both with the first version of ``trace.outline.mended``).
    """

    latent_steps: int = 30
    code_steps: int = 30
    point_steps: int = 60
    latent_lr: float = 0.05
    code_lr: float = 0.02
    point_lr: float = 1.5e-3  # normalised units per step: 0.1 px on a 64 px canvas
    color_lr: float = 0.02
    tau: float | None = None  # edge softness of the render in model pixels; None: 0.5 at 64 px, scaled with the
    # model's size (MNIST's 32 px model: 0.25, its training softness; at 0.5 its 64 test digits fitted to 0.00140,
    # from the guess's 0.00064, at 0.25 to 0.00049: fitted to a softer edge than the SVG draws, the paths were drawn off it)


GUESS = ProjectSettings(latent_steps=0, code_steps=0, point_steps=0)
LATENT = ProjectSettings(code_steps=0, point_steps=0)  # what a latent can hold (``encode``)


@dataclass
class Projection:
    """Pictures (or latents) as the model draws them: ``z (N, D)`` and its paths ``decoded``
    (points ``(N, P, 3k, 2)``, colours ``(N, G, 3)``, depth ``(N, G)``), on the model's square;
    ``parts``: per item the pieces grown on top where its fitted paths miss a part (``grown_parts``;
    ``VectorShape`` s in the square's normalised frame), or ``None``."""

    z: torch.Tensor
    decoded: Decoded
    parts: list[list[VectorShape]] | None = None

    def __len__(self) -> int:
        return len(self.z)

    def take(self, i: int) -> Projection:
        """Item ``i`` as a projection of one."""
        d = self.decoded
        return Projection(self.z[i : i + 1], Decoded(d.points[i : i + 1], d.colors[i : i + 1], d.depth[i : i + 1],
                                                     d.shape_index, d.fill_rule), self.parts and self.parts[i : i + 1])

    def between(self, other: Projection, steps: int) -> Projection:
        """``steps + 2`` frames from this projection of one to ``other`` (one), ends included:
        points, colours, depths and ``z`` linearly interpolated; grown parts matched across the
        ends and interpolated (``vector.morph.frames``)."""
        if len(self) != 1 or len(other) != 1:
            raise ValueError("between takes two projections of one picture each")
        a, b = self.decoded, other.decoded
        if a.points.shape != b.points.shape:
            raise ValueError(f"the two projections differ in paths: {tuple(a.points.shape)} and {tuple(b.points.shape)}")
        t = torch.linspace(0, 1, steps + 2, dtype=a.points.dtype, device=a.points.device)  # (T,)

        def lerp(x: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
            w = t.view(-1, *([1] * (x.dim() - 1)))
            return x * (1 - w) + y * w

        dec = Decoded(lerp(a.points, b.points), lerp(a.colors, b.colors), lerp(a.depth, b.depth), a.shape_index,
                      a.fill_rule)
        parts = None
        if self.parts or other.parts:
            from .vector.morph import frames

            parts = frames((self.parts or [[]])[0], (other.parts or [[]])[0], t.tolist())
        return Projection(lerp(self.z, other.z), dec, parts)

    def vectors(self, size: int, *, clean: bool = True, keep_all: bool = False) -> list[VectorImage]:
        """Each item on a ``size`` px square canvas: clean outlines (``trace.cleaned``) or the
        model's own paths (``keep_all``: the unused ones too, as ``infer.to_vector``)."""
        if clean and keep_all:
            raise ValueError("clean outlines do not keep the model's paths: keep_all needs clean=False")
        out = [to_vector(self.decoded, i, Placement(size, size), keep_all=keep_all) for i in range(len(self))]
        if self.parts:
            out = [dataclasses.replace(v, shapes=list(v.shapes) + VectorImage(1, 1, parts).rescaled(size, size).shapes)
                   for v, parts in zip(out, self.parts)]
        return [cleaned(v) for v in out] if clean else out

    def in_pictures(self, model: Im2Vec, images: list[torch.Tensor]) -> list[VectorImage]:
        """Each item in its picture's pixel frame (placed as ``infer.model_input`` places it), the
        overlaps of its even-odd shapes resolved against the picture as ``infer.vectorize`` does."""
        places = [model_input(model, im)[1] for im in images]
        return [resolve_overlaps(to_vector(self.decoded, i, p), im) for i, (p, im) in enumerate(zip(places, images))]


def grown_parts(model: Im2Vec, proj: Projection, images: list[torch.Tensor], grow: int) -> Projection:
    """``proj`` of ``images (3, H_i, W_i)`` with at most ``grow`` pieces of each picture's own regions
    grown on its fitted paths where they miss a part (``refine.grow.grown``, at the model's size)."""
    from .options import Plan
    from .refine.grow import grown
    from .trace import read_pictures

    size, plan = model.config.image_size, Plan(grow=grow)
    pics = [picture_array(model_input(model, im)[0]) for im in images]
    parts = []
    for i, (pic, reading) in enumerate(zip(pics, read_pictures(pics, plan))):
        vec, n = grown(to_vector(proj.decoded, i, Placement(size, size)), pic, reading, plan)
        parts.append(VectorImage(size, size, vec.shapes[len(vec.shapes) - n :]).rescaled(1, 1).shapes)
    return dataclasses.replace(proj, parts=parts)


def from_latents(model: Im2Vec, z: torch.Tensor, segments: int | None = None) -> Projection:
    """Latents ``(N, D)`` as a ``Projection`` (decoded with ``segments`` per path)."""
    dev = next(model.parameters()).device
    with torch.no_grad():
        return Projection(z.to(dev).float(), model.decode(z.to(dev).float(), segments))


def endpoint(model: Im2Vec, x, settings: ProjectSettings = ProjectSettings(), segments: int | None = None,
             grow: int = 0) -> Projection:
    """An end of a morph as a projection of one: ``x`` a projection of one (as it is), a latent
    ``(D,)`` (array-like: decoded) or a picture (anything ``files.as_image`` takes: projected, with at
    most ``grow`` parts grown, ``grown_parts``)."""
    if isinstance(x, Projection):
        if len(x) != 1:
            raise ValueError(f"an endpoint is a projection of one picture, got {len(x)}")
        return x
    if isinstance(x, (np.ndarray, torch.Tensor, Sequence)) and not isinstance(x, str) and np.asarray(x).ndim == 1:
        z = torch.as_tensor(np.asarray(x, dtype=np.float32))
        if len(z) != model.config.latent or not torch.isfinite(z).all():
            raise ValueError(f"a latent endpoint must be ({model.config.latent},) and finite, got {tuple(z.shape)}")
        return from_latents(model, z[None], segments)
    image = as_image(x)
    proj = project(model, [image], settings, segments)
    return grown_parts(model, proj, [image], grow) if grow else proj


def project(model: Im2Vec, images: list[torch.Tensor], settings: ProjectSettings = ProjectSettings(),
            segments: int | None = None) -> Projection:
    """Pictures ``(3, H_i, W_i)`` in [0, 1] fitted as the module says, in one batch (each
    placed in the model's square as the model was trained: ``infer.model_input``)."""
    dev = next(model.parameters()).device
    return project_frames(model, torch.stack([model_input(model, im)[0] for im in images]).to(dev), settings,
                          segments)


def project_frames(model: Im2Vec, x: torch.Tensor, settings: ProjectSettings = ProjectSettings(),
                   segments: int | None = None) -> Projection:
    """``project`` of pictures already in the model's square, ``x (N, 3, S, S)`` in [0, 1] on
    the model's device (training images: ``distill.fit_teacher``). The weights are left as
    they were, ``requires_grad`` included."""
    req = [p.requires_grad for p in model.parameters()]
    for p in model.parameters():
        p.requires_grad_(False)
    try:
        with torch.enable_grad():
            return _fit(model, x, settings, segments)
    finally:
        for p, r in zip(model.parameters(), req):
            p.requires_grad_(r)


def _fit(model: Im2Vec, x: torch.Tensor, s: ProjectSettings, segments: int | None) -> Projection:
    target = gaussian_pyramid(x, 1)
    k = segments or model.config.segments
    tau = s.tau if s.tau is not None else 0.5 * model.config.image_size / 64
    with torch.no_grad():
        z = model.encode(x)[0]
    if s.latent_steps:
        z = _adam(model, target, [z], [s.latent_lr], lambda z: model.decode(z, k), s.latent_steps, tau)[0]
    with torch.no_grad():
        # from the encoder's guess, the model's path passes (if any) correct the codes; not a fitted latent's
        code, depth, color = model.path_state(z, None if s.latent_steps else x)  # (N, P, C), (N, P), (N, P, 3)
        base = model.draw(code, depth, color, k)
    if s.code_steps:
        code = _adam(model, target, [code], [s.code_lr], lambda c: _with_points(base, model.path_points(c, k)),
                     s.code_steps, tau)[0]
    with torch.no_grad():
        points = model.draw(code, depth, color, k, x).points  # (N, P, 3k, 2), moved by the model's point passes if any
    colors = base.colors
    if s.point_steps:
        learn = not model.palette.numel()
        params, lrs = [torch.zeros_like(points)] + ([colors] if learn else []), [s.point_lr, s.color_lr]
        got = _adam(model, target, params, lrs[: len(params)],
                    lambda off, *c: _with_points(base, points + off, c[0].clamp(0, 1) if c else None),
                    s.point_steps, tau)
        points, colors = points + got[0], got[1].clamp(0, 1) if learn else colors
    return Projection(z, _with_points(base, points, colors))


def _with_points(d: Decoded, points: torch.Tensor, colors: torch.Tensor | None = None) -> Decoded:
    return Decoded(points, d.colors if colors is None else colors, d.depth, d.shape_index, d.fill_rule)


def _adam(model: Im2Vec, target: list[torch.Tensor], start: list[torch.Tensor], lrs: list[float], draw,
          steps: int, tau: float) -> list[torch.Tensor]:
    """``steps`` of Adam from ``start`` on the per-picture ``_loss`` of ``draw(*params)``; each
    picture's best parameters (its rows of every tensor in ``start``) over the steps."""
    params = [t.detach().clone().requires_grad_(True) for t in start]
    opt = Adam([{"params": [p], "lr": lr} for p, lr in zip(params, lrs)])
    best = [t.detach().clone() for t in start]
    best_loss = torch.full((len(start[0]),), float("inf"), device=start[0].device)
    for _ in range(steps):
        loss = _loss(model, draw(*params), target, tau)  # (N,)
        better = loss.detach() < best_loss
        best_loss = torch.where(better, loss.detach(), best_loss)
        for b, p in zip(best, params):
            b[better] = p.detach()[better]
        opt.zero_grad()
        loss.sum().backward()
        opt.step()
    return best


def _loss(model: Im2Vec, dec: Decoded, target: list[torch.Tensor], tau: float) -> torch.Tensor:
    """Per-picture L2 ``(N,)`` of the soft render of ``dec`` against ``target`` (a one-level pyramid)."""
    sidx = None if dec.shape_index is None else dec.shape_index.expand(len(dec.points), -1)
    renders = render_pyramid(dec.points, dec.colors, dec.depth, size=model.config.image_size, levels=1, tau=tau,
                             fill_rule=dec.fill_rule, shape_index=sidx, samples=model.config.samples,
                             composite="over")
    return pyramid_l2(renders, target, reduction="none")
