"""What a trained model carries beside its weights, fitted to its training images: the latent
priors ``sample`` draws from (``fit_prior``, ``fit_neighbours``) and the segment-count predictor
(``train_aux``). Each writes the model with them to a new folder, or into the model's own with
``overwrite``. Part of the Python API (``im2vec_cli.api`` re-exports them)."""

from __future__ import annotations

from pathlib import Path

import torch

from .config import DEFAULT_COMPONENTS, DEFAULT_NEIGHBOURS, DEFAULT_SHRINK
from .errors import ConfigError, DataError, ModelError
from .events import Encoding, Measuring, Skipped


def load_model(model):
    """A model, or the shipped one or folder it names, on the device ``api.load_model`` picks (``auto``)."""
    from .model.pretrained import from_pretrained
    from .runtime import resolve_device

    return from_pretrained(model, resolve_device("auto")) if isinstance(model, str) else model


def output_is_source(output, overwrite: bool, source) -> bool:
    """Whether ``output`` is the model's own folder ``source`` (updated in place, only with
    ``overwrite``); any other output is made whole, and one that holds files only with
    ``overwrite``. Checked before any work."""
    from .files import check_output_folder

    if source is not None and Path(output).resolve() == Path(source).resolve():
        if not overwrite:
            raise ModelError(f"{output}: is the model's own folder; --overwrite updates it in place")
        return True
    check_output_folder(output, overwrite, *([source] if source is not None else []), error=ModelError)
    return False


def model_folder(model):
    """The folder a model was loaded from (``None`` for a model built in memory)."""
    from .config import resolve_model

    return resolve_model(model) if isinstance(model, str) else getattr(model, "folder", None)


def model_and_images(model, output, overwrite: bool, data_dir, emit):
    """The model's folder, the model, whether ``output`` is that folder (checked first, before
    any work) and ``data_dir``'s training images at the model's size, uint8."""
    from .data.folder import load_folder, split_dir

    source = model_folder(model)
    in_place = output_is_source(output, overwrite, source)
    model = load_model(model)
    data, _ = load_folder(split_dir(data_dir, "train"), model.config.image_size, fit=model.config.fit,
                          on_skip=lambda m: emit(Skipped(m)))
    return source, model, in_place, data


def fit_prior(data_dir, model, output, *, components: int | None = None, seed: int = 0,
              overwrite: bool = False, shrink: float = DEFAULT_SHRINK, neighbours: int | None = None,
              on_event=None):
    """Fit the latent densities ``sample`` draws from to ``data_dir``'s images (``DATA/train`` when it
    exists) and write the model with them to ``output`` (its own folder: only its priors, with
    ``overwrite``): the Gaussian mixture (``components``, ``shrink``: ``model.prior.fit_prior``'s)
    and, unless ``neighbours`` is 0, the neighbour prior (``model.prior.fit_neighbours``; ``None``:
    ``DEFAULT_NEIGHBOURS``, fewer for a small set; 0 drops a stored one, fitted to other weights).
    ``components=None``: ``DEFAULT_COMPONENTS``, fewer for a small set (at most half the images).
    Returns the ``LatentPrior``."""
    from .model.prior import fit_neighbours, posterior_means
    from .model.prior import fit_prior as fit

    emit = on_event or (lambda e: None)
    source, model, in_place, data = model_and_images(model, output, overwrite, data_dir, emit)
    if len(data) < 2:
        raise DataError(f"{data_dir}: a latent prior is fitted to at least 2 readable images, found {len(data)}")
    if components is None:
        components = min(DEFAULT_COMPONENTS, len(data) // 2)
    elif components > max(1, len(data) // 2):
        raise ConfigError(f"components {components}: at most half the {len(data)} images")
    neighbours = _neighbours(neighbours, len(data), fewest=0)
    emit(Encoding(len(data)))
    mu = posterior_means(model, data)
    prior = fit(mu, components, seed=seed, data=str(data_dir), shrink=shrink)
    near = fit_neighbours(mu, neighbours, seed=seed, data=str(data_dir)) if neighbours else None
    model.latent_prior, model.neighbour_prior = prior, near
    _write_priors(model, source, output, in_place)
    return prior


def fit_neighbours(data_dir, model, output, *, neighbours: int | None = None, seed: int = 0,
                   overwrite: bool = False, on_event=None):
    """Fit only the neighbour prior (``model.prior.NeighbourPrior``; the mixture stays as stored) to
    ``data_dir``'s training images and write the model with it to ``output`` as ``fit_prior`` does.
    It encodes only the images the prior keeps (``model.prior.anchor_rows``): the prior ``fit_prior``
    fits with the same ``seed``, in seconds where the mixture's every image takes minutes.
    Returns the ``NeighbourPrior``."""
    from .model.prior import anchor_rows, posterior_means
    from .model.prior import fit_neighbours as fit

    emit = on_event or (lambda e: None)
    source, model, in_place, data = model_and_images(model, output, overwrite, data_dir, emit)
    k = _neighbours(neighbours, len(data), fewest=1)
    rows = anchor_rows(len(data), seed)
    emit(Encoding(len(rows)))
    model.neighbour_prior = fit(posterior_means(model, data[rows]), k, seed=seed, data=str(data_dir), images=len(data))
    _write_priors(model, source, output, in_place)
    return model.neighbour_prior


def _neighbours(asked: int | None, images: int, fewest: int) -> int:
    """k for a neighbour prior of ``images`` images, checked before the work: ``asked``, from
    ``fewest`` (0: none) to ``model.prior.most_neighbours``, or for ``None`` the default, fewer
    for a small set."""
    from .model.prior import most_neighbours

    most = most_neighbours(images)
    if asked is None:
        return min(DEFAULT_NEIGHBOURS, most)
    if not (fewest <= asked and (asked == 0 or asked <= most)):
        raise ConfigError(f"neighbours {asked}: {'at least 1 and ' if fewest else ''}fewer than the "
                          f"{most + 1} images it chooses from")
    return asked


def _write_priors(model, source, output, in_place: bool) -> None:
    """Only the priors into the model's own folder, else the whole model (weights as stored) to ``output``."""
    from .files import replace_folder
    from .model.pretrained import save_pretrained, save_priors, stored_half

    if in_place:
        save_priors(model, output)
    else:
        half = source is not None and stored_half(source)  # the weights stay bit-identical
        replace_folder(output, lambda folder: save_pretrained(model, folder, half=half))


def train_aux(data_dir, model, output, *, images: int = 2048, steps: int = 3000, seed: int = 0,
              overwrite: bool = False, on_event=None) -> dict:
    """Train the segment-count predictor (paper sec. 3.3) of a model on a seeded subset of
    ``images`` of ``data_dir`` and write the model with it to ``output`` (the model's own
    folder only with ``overwrite``), with ``segments.json``. Returns that report."""
    import json

    from .files import atomic_write, replace_folder
    from .model.pretrained import save_pretrained, stored_half
    from .training.aux import AuxSettings, train_segment_predictor

    emit = on_event or (lambda e: None)
    source, model, in_place, data = model_and_images(model, output, overwrite, data_dir, emit)
    x = data[torch.randperm(len(data), generator=torch.Generator().manual_seed(seed))[:images]].float() / 255
    emit(Measuring(len(x), model.config.paths))
    out, report = train_segment_predictor(model, x, AuxSettings(steps=steps, seed=seed), on_step=emit)
    half = source is not None and stored_half(source)  # as stored: the VAE weights stay bit-identical

    def write(folder) -> None:
        save_pretrained(out, folder, half=half)
        atomic_write(Path(folder) / "segments.json", json.dumps(report, indent=1) + "\n")

    write(Path(output)) if in_place else replace_folder(output, write)
    return report
