"""Inference: vectorize, encode, decode, sample and interpolate with a trained model.

Frames: the model sees its square frame (``frame.py``); ``to_vector`` maps decoded paths to
the *input's* pixel frame with the image's ``Placement``, so an SVG overlays its input.
"""

from __future__ import annotations

import dataclasses

import torch

from .errors import ConfigError, ModelError
from .frame import Placement, resize_square, to_model_frame
from .model.vae import Decoded, Im2Vec
from .options import MAX_TEMPERATURE, PRIORS
from .trace import cleaned
from .trace import flat_result as trace_flat_result
from .vector import VectorImage, from_tensors, resolve_overlaps

MIN_AREA = 1e-4  # paths below this area (normalised units) are unused and not exported


def model_input(model: Im2Vec, image: torch.Tensor) -> tuple[torch.Tensor, Placement]:
    """``(3, H, W)`` in [0, 1] -> model input ``(3, S, S)`` and its placement."""
    return to_model_frame(image, model.config.image_size, model.config.fit)


def to_vector(dec: Decoded, i: int, place: Placement, *, max_paths: int | None = None, keep_all: bool = False) -> VectorImage:
    """Decoded item ``i`` -> ``VectorImage`` in the input's pixel frame.

    Degenerate (unused) paths are dropped unless ``keep_all``; ``max_paths`` keeps the largest.
    """
    pts = dec.points[i].detach().double().cpu()  # (P, 3k, 2) normalised (model square)
    counts = None if dec.counts is None else dec.counts[i].tolist()  # (P,) segments before padding
    area = Im2Vec.path_areas(pts)  # (P,)
    keep = torch.ones(len(pts), dtype=torch.bool) if keep_all else area >= MIN_AREA
    if max_paths is not None and int(keep.sum()) > max_paths:
        order = torch.argsort(torch.where(keep, area, torch.full_like(area, -1.0)), descending=True)
        keep = torch.zeros_like(keep)
        keep[order[:max_paths]] = True
    sidx = None if dec.shape_index is None else dec.shape_index.cpu()[keep]
    norm = place.model_to_input(pts)  # (P, 3k, 2) input-normalised
    if counts is None:
        norm = norm[keep]
    else:  # ragged: trim the padding of each path
        norm = [norm[p, : 3 * counts[p]] for p in range(len(norm)) if keep[p]]
    cols = dec.colors[i].detach().cpu()
    depth = dec.depth[i].detach().cpu()
    if sidx is None:
        cols, depth = cols[keep], depth[keep]
    return from_tensors(norm, cols, size=(place.height, place.width), shape_index=sidx, depth=depth,
                        fill_rule=dec.fill_rule)


def flat_result(image: torch.Tensor) -> VectorImage | None:
    """The vector image of a flat ``(3, H, W)`` image (one colour: nothing to fit), else ``None``."""
    return trace_flat_result(image.detach().permute(1, 2, 0).cpu().numpy())


DEFAULT_QUALITY = 5e-4  # --segments auto: error per added segment (MSE on coverage) worth paying for


def segment_counts(model: Im2Vec, code: torch.Tensor, segments: int | str | None,
                   quality: float | None = None) -> int | torch.Tensor | None:
    """``segments`` as ``Im2Vec.decode`` takes it: ``"auto"`` becomes per-path counts ``(B, P)``
    chosen by the model's segment predictor at ``quality`` (default ``DEFAULT_QUALITY``) for the
    paths of the codes ``(B, P, C)`` (``Im2Vec.path_state``)."""
    if segments == "auto":
        return model.code_segments(code, quality or DEFAULT_QUALITY)
    return segments


@torch.no_grad()
def vectorize(model: Im2Vec, images: list[torch.Tensor], *, segments: int | str | None = None,
              quality: float | None = None, max_paths: int | None = None, clean: bool = False) -> list[VectorImage]:
    """Amortised vectorisation (``z = mu``) of images ``(3, H_i, W_i)``, in one batch.

    ``segments``: per path, default the model's; ``"auto"`` picks each path's count for
    ``quality`` (``segment_counts``).
    Overlapping paths of an even-odd shape are filled rather than cut out where that is
    nearer the image (``overlaps.resolve_overlaps``: no white seams where two strokes meet).
    ``clean``: each result drawn as non-overlapping outer contours and holes, its hairline
    seams, cracks and slivers mended (``clean_guess``), not as the model's overlapping paths.
    Flat images (one colour, e.g. blank) skip the model: white gives an empty SVG, any
    other colour one canvas-sized square.
    """
    dev = next(model.parameters()).device
    out = [flat_result(im) for im in images]
    todo = [i for i, v in enumerate(out) if v is None]
    if todo:
        xs, places = zip(*(model_input(model, images[i]) for i in todo))
        x = torch.stack(xs).to(dev)
        code, depth, color = model.path_state(model.encode(x)[0], x)  # the path passes run once
        dec = model.draw(code, depth, color, segment_counts(model, code, segments, quality), x)
        for j, (i, p) in enumerate(zip(todo, places)):
            vec = resolve_overlaps(to_vector(dec, j, p, max_paths=max_paths), images[i])
            out[i] = clean_guess(vec, p, model.config.image_size) if clean else vec
    kind = "the model's guess, mended" if clean else "the model's paths"  # what `vectorize -v` says
    return [dataclasses.replace(v, notes={"kind": kind}) for v in out]  # type: ignore[arg-type]


def clean_guess(vec: VectorImage, place: Placement, size: int) -> VectorImage:
    """A decoded image in its input's pixel frame drawn clean (``outline.cleaned``) at the
    scale the model drew it, a ``size`` px square over the input's ``place``, and mapped back:
    the seams it mends and the specks it drops are measured in model pixels, and the work is
    bounded by the model's size whatever the input's."""
    k = size / place.side
    w, h = max(1, round(place.width * k)), max(1, round(place.height * k))
    return cleaned(vec.rescaled(w, h)).rescaled(vec.width, vec.height)


@torch.no_grad()
def reconstruct_raster(model, images: list[torch.Tensor]) -> list[torch.Tensor]:
    """The ImageVAE baseline's reconstructions (``z = mu``) of images ``(3, H_i, W_i)``, each
    mapped back to its input's frame (the model square resized to ``max(H, W)`` and cropped)."""
    dev = next(model.parameters()).device
    xs, places = zip(*(model_input(model, im) for im in images))
    out = model.decode(model.encode(torch.stack(xs).to(dev))[0]).cpu()  # (N, 3, S, S)
    recs = []
    for img, p in zip(out, places):
        img = resize_square(img, p.side)
        left, top = p.offset
        recs.append(img[:, top : top + p.height, left : left + p.width].clamp(0, 1))
    return recs


@torch.no_grad()
def encode(model: Im2Vec, images: list[torch.Tensor]) -> torch.Tensor:
    """Posterior means ``(N, D)`` of images ``(3, H_i, W_i)``."""
    dev = next(model.parameters()).device
    xs = torch.stack([model_input(model, im)[0] for im in images]).to(dev)
    return model.encode(xs)[0].cpu()


@torch.no_grad()
def decode(model: Im2Vec, z: torch.Tensor, *, segments: int | None = None, keep_all: bool = False,
           clean: bool = False) -> list[VectorImage]:
    """Latents ``(N, D)`` -> vector images on the model's square canvas; ``clean``: each drawn
    as non-overlapping outer contours and holes (``outline.cleaned``), not as the model's
    overlapping paths (which ``keep_all`` keeps, for morphs)."""
    if clean and keep_all:
        raise ValueError("clean outlines do not keep the model's paths: keep_all needs clean=False")
    if z.dim() != 2 or z.shape[1] != model.config.latent:
        raise ValueError(f"z must be (N, {model.config.latent}), got {tuple(z.shape)}")
    if not torch.isfinite(z).all():
        raise ValueError("z contains NaN or infinite values")
    dev = next(model.parameters()).device
    dec = model.decode(z.to(dev).float(), segments)
    s = model.config.image_size
    out = [to_vector(dec, i, Placement(s, s), keep_all=keep_all) for i in range(len(z))]
    return [cleaned(v) for v in out] if clean else out


def resolve_prior(model, prior: str = "auto") -> str:
    """``"neighbours"``, ``"fitted"`` or ``"normal"``: the prior ``prior_latents`` draws from for
    ``prior`` (``"auto"``: the first of them the model has; ``ModelError`` when asked for one it lacks)."""
    if prior not in PRIORS:
        raise ValueError(f"prior must be one of {PRIORS}, got {prior!r}")
    if prior == "auto":
        return next((p for p in STORED_PRIORS if stored_prior(model, p) is not None), "normal")
    if prior != "normal" and stored_prior(model, prior) is None:
        how = "`im2vec fit-prior --neighbours K`" if prior == "neighbours" else "`im2vec fit-prior`"
        what = "neighbour prior" if prior == "neighbours" else "fitted latent prior"
        raise ModelError(f"model {getattr(model, 'name', '?')!r} has no {what} "
                         f"(add one with {how}, or use prior='normal')")
    return prior


STORED_PRIORS = ("neighbours", "fitted")  # what a model folder may store, in the order "auto" prefers them


def stored_prior(model, which: str):
    """``model.neighbour_prior`` (``model.prior.NeighbourPrior``) or ``model.latent_prior`` (``LatentPrior``), or ``None``."""
    return getattr(model, "neighbour_prior" if which == "neighbours" else "latent_prior", None)


def prior_latents(model, n: int, *, seed: int = 0, temperature: float | None = None,
                  prior: str = "auto") -> torch.Tensor:
    """``n`` latents ``(n, D)`` float32 drawn with their own generator seeded by ``seed``: from
    the prior ``resolve_prior`` names (``model.neighbour_prior``, ``model.latent_prior``) or N(0, I),
    at ``temperature`` (``None``: the stored prior's own, 1 for N(0, I); ``sample_temperature``)."""
    if n < 1:
        raise ValueError(f"n must be >= 1, got {n}")
    t = sample_temperature(model, prior, temperature)
    which = resolve_prior(model, prior)
    if which != "normal":
        return stored_prior(model, which).sample(n, seed=seed, temperature=t)
    return torch.randn(n, model.config.latent, generator=torch.Generator().manual_seed(seed)) * t


def sample_temperature(model, prior: str = "auto", temperature: float | None = None) -> float:
    """The temperature ``prior_latents`` draws with: ``temperature``, or when ``None`` the one the
    stored prior keeps (``LatentPriorConfig.temperature``, ``NeighbourPriorConfig.temperature``), 1 for N(0, I)."""
    if temperature is not None:
        if not 0 <= float(temperature) <= MAX_TEMPERATURE:  # NaN too: 1e300 made every latent infinite
            raise ConfigError(f"temperature must be in [0, {MAX_TEMPERATURE:g}], got {temperature}")
        return float(temperature)
    which = resolve_prior(model, prior)
    return stored_prior(model, which).config.temperature if which != "normal" else 1.0


def lerp_latents(za: torch.Tensor, zb: torch.Tensor, steps: int) -> torch.Tensor:
    """Endpoints and ``steps`` evenly spaced latents between them: ``(steps + 2, D)``."""
    t = torch.linspace(0, 1, steps + 2, dtype=za.dtype).view(-1, 1)
    return za.view(1, -1) * (1 - t) + zb.view(1, -1) * t
