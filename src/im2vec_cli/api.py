"""The Python API: what the ``im2vec`` command does, as functions.

Pictures go in as Pillow images, NumPy arrays (``(H, W)``, ``(H, W, 3)`` or ``(H, W, 4)``,
uint8 or float in [0, 1]), ``(3, H, W)`` tensors or file paths; vector images come out as
``VectorImage`` (``.to_svg()`` gives the SVG text, in the input's pixel frame). Nothing here
prints or exits: errors are ``Im2VecError`` (one line, for users) or ``ValueError`` (for
programmers).

    >>> import im2vec_cli as iv
    >>> model = iv.load_model("fonts")
    >>> svg = iv.vectorize("examples/glyph_a.png", model).to_svg()
    >>> z = iv.encode(["examples/glyph_a.png", "examples/glyph_R.png"], model)   # (2, 128)
    >>> frames = iv.interpolate(z[0], z[1], model, steps=4)                      # 6 VectorImages
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np
import torch

from . import infer
from . import refine as refinement
from .errors import ModelError
from .files import as_image
from .model.pretrained import DEFAULT_MODEL, from_pretrained
from .options import PARTS, VectorizeOptions
from .raster import compiling
from .runtime import resolve_device
from .vector import VectorImage, simplify

__all__ = ["VectorizeOptions", "decode", "encode", "interpolate", "load_model", "prior_latents", "sample", "vectorize"]


def load_model(name_or_dir: str = DEFAULT_MODEL, device: str | torch.device = "auto"):
    """A shipped model by name (``fonts``, ``mnist``, ``emoji``, ``icons``) or a model folder
    written by ``im2vec train`` / ``export``, on ``device`` (``auto``: CUDA, then MPS, then CPU)."""
    dev = device if isinstance(device, torch.device) else resolve_device(device)
    return from_pretrained(name_or_dir, dev)


def _model(model):
    return load_model(model) if isinstance(model, str) else model


def vectorize(images, model=DEFAULT_MODEL, options: VectorizeOptions | None = None,
              **fields) -> VectorImage | list[VectorImage]:
    """Vectorize one picture (or a list of them) into closed cubic paths.

    Args:
        images: a picture, or a list of pictures (any size each).
        model: a model from ``load_model``, or its name.
        options: a ``VectorizeOptions`` (default: its defaults); ``fields`` override any of
            its fields by name (``vectorize(img, m, parts="model")``). The fields:
        refine: fit the paths to each picture through the renderer (``refine.refine``);
            ``False`` gives the model's guess alone, in one batch.
        effort: with ``refine``, ``"fast"`` or ``"best"`` (``options.EFFORTS``).
        parts: with ``refine``, ``"clean"`` (each colour one path of non-overlapping outer
            contours and holes, from the model's paths or the picture's own regions, whichever
            fits better) or ``"model"`` (the model's own paths, the same for every picture of
            its class).
        tolerance: with ``parts="clean"``, how far (input pixels) the cubics may stray from the
            traced outline before another segment is added (default 0.5); larger is more compact.
        colors: with ``parts="clean"``, the palette size of a multi-colour picture (default:
            as many as its flat areas need, at most 16; 1: two-tone).
        segments: cubic segments per path (default: the model's), or ``"auto"`` (the model's
            segment predictor chooses per path at ``quality``).
        max_paths: keep at most this many paths (the largest).
        simplify_px: merge segments while the outline moves less than this many input pixels
            (default 0.25 with ``refine``, else 0).
        compile: run the renderer's kernels through ``torch.compile`` while refining. Each new
            image size compiles afresh (about 20 s per size on 2 CPU cores the first time on a
            machine, seconds from the cache after); on a CPU the eager kernels are nearly as
            fast (bench/folder.py), on a GPU the fused kernels pay for many pictures of one size.

    Returns:
        One ``VectorImage`` per picture (a list for a list), in each picture's pixel frame.
    """
    o = dataclasses.replace(options or VectorizeOptions(), **fields)  # validated here, once
    model = _model(model)
    one = not isinstance(images, (list, tuple))
    pictures = [as_image(x) for x in ([images] if one else images)]
    check_segments(model, o.segments)
    kw = {"segments": o.segments, "quality": o.quality, "max_paths": o.max_paths}
    if o.refine:
        settings = refinement.EFFORTS[o.effort]
        if o.simplify_px is not None:
            settings = dataclasses.replace(settings, simplify_tol=o.simplify_px)
        if o.tolerance is not None:
            settings = dataclasses.replace(settings, tolerance=float(o.tolerance))
        with compiling(o.compile):  # off by default: each new image size would compile afresh
            out = [v for v, _ in refinement.refine_batch(model, pictures, settings=settings, parts=o.parts,
                                                         colors=o.colors, **kw)]
    else:
        out = [simplify(v, o.simplify_px or 0.0) for v in infer.vectorize(model, pictures, **kw)]
    return out[0] if one else out


def check_segments(model, segments: int | str | None) -> None:
    """``ModelError`` when ``segments="auto"`` is asked of a model without a segment predictor."""
    if segments == "auto" and model.segment_predictor is None:
        raise ModelError(f"model {getattr(model, 'name', '?')!r} has no segment predictor for segments='auto' "
                         "(add one with `im2vec train-aux`)")


def encode(images, model=DEFAULT_MODEL) -> np.ndarray:
    """Latents (posterior means) of a picture or a list of pictures: ``(N, D)`` float32."""
    model = _model(model)
    pictures = [as_image(x) for x in (images if isinstance(images, (list, tuple)) else [images])]
    return infer.encode(model, pictures).float().numpy()


def _latents(z, model) -> torch.Tensor:
    """Latents ``(N, D)`` or ``(D,)`` (array-like) -> float32 ``(N, D)``, checked."""
    t = torch.as_tensor(np.asarray(z, dtype=np.float32))
    t = t.view(1, -1) if t.dim() == 1 else t
    if t.dim() != 2 or t.shape[1] != model.config.latent:
        raise ValueError(f"latents must be (N, {model.config.latent}) or ({model.config.latent},), got {tuple(t.shape)}")
    return t


def _parts(parts: str | None, keep_all: bool) -> bool:
    """Whether to draw clean outlines: ``parts`` ``"clean"`` / ``"model"``, default clean
    unless ``keep_all`` (morphs need the model's own paths)."""
    parts = parts or ("model" if keep_all else "clean")
    if parts not in PARTS:
        raise ValueError(f"parts must be one of {list(PARTS)}, got {parts!r}")
    return parts == "clean"


def decode(z, model=DEFAULT_MODEL, *, segments: int | None = None, keep_all: bool = False,
           parts: str | None = None) -> list[VectorImage]:
    """Latents ``(N, D)`` (or one ``(D,)``) -> vector images on the model's square canvas.

    ``parts``: ``"clean"`` (the default) draws each shape as non-overlapping outer contours and
    holes; ``"model"`` keeps the model's overlapping paths (under even-odd for the fonts and
    MNIST models). ``keep_all`` keeps unused paths too, so that every image has the same paths
    (morphs; it implies ``"model"``)."""
    model = _model(model)
    return infer.decode(model, _latents(z, model), segments=segments, keep_all=keep_all,
                        clean=_parts(parts, keep_all))


def prior_latents(n: int, model=DEFAULT_MODEL, *, seed: int = 0, temperature: float = 1.0,
                  prior: str = "auto") -> np.ndarray:
    """``n`` latents ``(n, D)`` float32, the same for the same ``seed``.

    ``prior``: ``"fitted"`` draws from the density fitted to the training set's latents that
    the model folder stores (``model.prior``), ``"normal"`` from N(0, I), ``"auto"`` the
    first when the model has one. ``temperature`` scales the standard deviations."""
    return infer.prior_latents(_model(model), n, seed=seed, temperature=temperature, prior=prior).numpy()


def sample(n: int, model=DEFAULT_MODEL, *, seed: int = 0, temperature: float = 1.0, prior: str = "auto",
           segments: int | None = None, parts: str = "clean") -> list[VectorImage]:
    """``n`` new graphics: ``prior_latents`` decoded (``parts`` as in ``decode``)."""
    model = _model(model)
    z = prior_latents(n, model, seed=seed, temperature=temperature, prior=prior)
    return decode(z, model, segments=segments, parts=parts)


def interpolate(a, b, model=DEFAULT_MODEL, *, steps: int = 4, segments: int | None = None,
                keep_all: bool = False, parts: str | None = None) -> list[VectorImage]:
    """``steps + 2`` frames from ``a`` to ``b`` (endpoints included), each a picture or a latent
    ``(D,)``, decoded from evenly spaced latents. ``keep_all`` and ``parts`` as in ``decode``
    (``keep_all`` for ``vector.animated_svg``)."""
    model = _model(model)
    za, zb = (_endpoint(x, model) for x in (a, b))
    return infer.decode(model, infer.lerp_latents(za, zb, steps), segments=segments, keep_all=keep_all,
                        clean=_parts(parts, keep_all))


def _endpoint(x, model) -> torch.Tensor:
    """A picture or a latent -> ``(D,)``."""
    if isinstance(x, (np.ndarray, torch.Tensor, Sequence)) and not isinstance(x, str) and np.asarray(x).ndim == 1:
        return _latents(x, model)[0]
    return infer.encode(model, [as_image(x)])[0]
