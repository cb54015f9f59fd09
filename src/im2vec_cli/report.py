"""What ``im2vec eval`` measures of a model on a dataset, in one call (``evaluate_model``): the
paper's Table 1 and 2 figures, the segments ablation of Fig. 5 and the sample quality, each from
``evaluate.py``'s metrics, as one JSON-ready dict. Re-exported by ``api.py``; nothing here prints.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from .errors import Im2VecError


def evaluate_model(model, data_dir, *, limit: int | None = None, train_dir=None, samples: int = 1000,
                   pairs: int = 250, segments=None, fit: bool = False, sweep: list[int] | None = None,
                   features_dir=None, prior: str = "auto", seed: int = 0,
                   on_skip: Callable[[str], None] | None = None) -> dict:
    """The figures of ``model`` on ``data_dir``'s test split (a seeded subset of ``limit`` images):
    reconstruction L2 (``fit``: of the paths fitted to each image), with ``train_dir`` generation,
    held-out and interpolation L2, with ``sweep`` (segment counts) the ablation, with
    ``features_dir`` (a feature net) the sample quality. ``on_skip`` hears each unreadable image."""
    from .data.folder import load_folder, split_dir
    from .evaluate import eval_files, generation_l2, held_out_l2, interpolation_l2, reconstruction_l2

    res = {"model": getattr(model, "name", str(model)), "arch": model.config.arch}
    files = eval_files(data_dir, limit, seed, on_skip=on_skip)
    res.update(reconstruction_l2(model, files, segments=segments, on_skip=on_skip, fit=fit), **({"fit": True} if fit else {}))
    if train_dir:
        train, _ = load_folder(split_dir(train_dir, "train"), model.config.image_size, fit=model.config.fit,
                               on_skip=on_skip)
        res["train_images"] = len(train)
        res.update(generation_l2(model, train, samples=samples, seed=seed, segments=segments, prior=prior))
        res.update(held_out_l2(files, train, model.config.image_size, model.config.fit))
        res.update(interpolation_l2(model, train, pairs=pairs, seed=seed, segments=segments))
    if sweep:
        res.update(_sweeps(model, files, sweep))
    if features_dir:
        res.update(_sample_quality(model, features_dir, data_dir, samples, seed, prior, segments))
    return res


def sweep_figure(res: dict) -> bytes:
    """The segments ablation of an ``evaluate_model`` result with ``sweep``, as a PNG plot (matplotlib)."""
    from .evaluate import sweep_plot

    series = {"sample deformation": res["segments_sweep"]}
    if "segments_sweep_deform_off" in res:
        series["deformation off at inference"] = res["segments_sweep_deform_off"]
    return sweep_plot(series, f"{res['model']}: {res['images']} test images")


def test_split_note(data_dir) -> str | None:
    """``evaluate_model`` scores a dataset's test split: a dataset with train/ but no test/ is refused
    (``Im2VecError``); a plain folder of images is scored whole, and this says so (else ``None``)."""
    if (Path(data_dir) / "test").is_dir():
        return None
    if (Path(data_dir) / "train").is_dir():
        raise Im2VecError(f"{data_dir}: has train/ but no test/; eval scores the test split (give a folder with test/)")
    return f"{data_dir} has no test/ folder: every image in it is scored, any the model trained on included"


def _sweeps(model, files, ks) -> dict:
    from .evaluate import segments_sweep

    out = {"segments_sweep": segments_sweep(model, files, ks)}
    if model.decoder.deform is not None:
        out["segments_sweep_deform_off"] = segments_sweep(model, files, ks, deform=False)
    return out


def _sample_quality(model, features_dir, data_dir, samples, seed, prior, segments) -> dict:
    """``evaluate.sample_quality`` against a seeded subset of as many test images as samples
    (apart from ``limit``), with the feature net's provenance."""
    from .evaluate import eval_files, sample_quality
    from .files import load_image
    from .model.features import FeatureNet

    net = FeatureNet.load(features_dir)
    pictures = [load_image(f) for f in eval_files(data_dir, samples, seed)]
    try:
        out = sample_quality(model, net, pictures, samples=samples, seed=seed, prior=prior, segments=segments)
    except Im2VecError as exc:
        raise Im2VecError(f"{features_dir}: {exc}") from None
    return {**out, "features": str(features_dir), "features_test_accuracy": net.config.test_accuracy}
