"""The Python API: what the ``im2vec`` command does, as functions.

Pictures go in as Pillow images, NumPy arrays (``(H, W)``, ``(H, W, 3)`` or ``(H, W, 4)``, uint8 or
float in [0, 1]), ``(3, H, W)`` tensors or file paths; vector images come out as ``VectorImage`` (``.to_svg()``
gives the SVG text, in the input's pixel frame). Nothing here prints or exits: errors are ``Im2VecError``
(one line, for users) or ``ValueError`` (for programmers).

    >>> import im2vec_cli as iv
    >>> model = iv.load_model("fonts")
    >>> svg = iv.vectorize("examples/glyph_a.png", model).to_svg()
    >>> svg.startswith("<svg") and 'viewBox="0 0 64 64"' in svg
    True
    >>> z = iv.encode(["examples/glyph_a.png", "examples/glyph_R.png"], model)
    >>> z.shape
    (2, 128)
    >>> frames = iv.interpolate(z[0], z[1], model, steps=4)
    >>> len(frames), type(frames[0]).__name__
    (6, 'VectorImage')

(run by ``tests/test_api.py::test_the_module_example_runs``, from the repository root.)

torch and the model load at their first use: ``vectorize`` of pictures that are traced and not
polished (larger than the polish's size, pixel art, photos, ``effort="draft"``) imports neither.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from .config import DEFAULT_MODEL
from .events import FeatureData, FeatureTest, Skipped
from .files import as_image
from .options import GROW, PARTS, VectorizeOptions
from .vector import VectorImage
from .vectorizing import ModelRef, check_segments, load_model, vectorize, vectorize_each
from .vectorizing import model_of as _model

# Names re-exported from the modules that hold them, imported at first use (most need torch): the
# doors of the CLI (which imports nothing past api.py, options and the ground floor) and of Python users.
_LAZY = {
    "fit_neighbours": "extras", "fit_prior": "extras", "train_aux": "extras",
    "evaluate_model": "report", "sweep_figure": "report", "test_split_note": "report",
    "plan_workers": "parallel", "batch_groups": "parallel", "vectorize_chunks": "parallel", "vectorize_on_ray": "rayengine",
    "list_images": "data.folder", "DEFAULT_CHARS": "data.fonts", "build_fonts": "data.fonts",
    "build_mnist": "data.mnist", "build_svg_set": "data.svgset",
    "from_svg": "vector", "render_vector": "vector", "contact_sheet": "vector", "flipbook_svg": "vector",
    "MAX_SVG_BYTES": "vector.document", "read_svg_bytes": "vector.document",
}
__all__ = ["ModelRef", "VectorizeOptions", "check_segments", "decode", "encode", "export", "interpolate", "load_feature_net", "load_model",
           "prior_latents", "project", "sample", "train", "train_features", "vectorize", "vectorize_each", *_LAZY]


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        where = importlib.import_module(f"{__package__}.{_LAZY[name]}")
        return getattr(where, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def project(images, model=DEFAULT_MODEL, *, fit: bool = True, segments: int | None = None, grow: int = 0):
    """A picture or a list as the model draws them (``project.Projection``: latents and paths),
    fitted to each (``project.project``) or the encoder's guess (``fit=False``); ``grow``: with
    ``fit``, at most this many pieces of each picture grown where its fitted paths miss a part
    (``project.grown_parts``: ``interpolate`` morphs them)."""
    from . import project as projection
    from .raster import compiling

    model, pictures = _model(model), _pictures(images)
    with compiling(False):  # a compile costs tens of seconds, a fit about one
        proj = projection.project(model, pictures, _fitting(fit), segments)
    return projection.grown_parts(model, proj, pictures, grow) if fit and grow else proj


def encode(images, model=DEFAULT_MODEL, *, fit: bool = True) -> np.ndarray:
    """Latents ``(N, D)`` float32 of a picture or a list, in one batch: fitted to each through
    the renderer (``project.LATENT``) or the encoder's posterior means (``fit=False``)."""
    from . import project as projection
    from .raster import compiling

    with compiling(False):
        setting = projection.LATENT if fit else projection.GUESS
        return projection.project(_model(model), _pictures(images), setting).z.float().cpu().numpy()


def _fitting(fit: bool):
    from . import project as projection

    return projection.ProjectSettings() if fit else projection.GUESS


def _pictures(images) -> list:
    return [as_image(x) for x in (images if isinstance(images, (list, tuple)) else [images])]


def _latents(z, model):
    """Latents ``(N, D)`` or ``(D,)`` (array-like) -> float32 tensor ``(N, D)``, checked."""
    import torch

    t = torch.as_tensor(np.asarray(z, dtype=np.float32))
    t = t.view(1, -1) if t.dim() == 1 else t
    if t.dim() != 2 or t.shape[1] != model.config.latent:
        raise ValueError(f"latents must be (N, {model.config.latent}) or ({model.config.latent},), got {tuple(t.shape)}")
    return t


def _parts(parts: str | None, keep_all: bool) -> bool:
    """Whether to draw clean outlines: ``parts`` ``"clean"`` / ``"model"``, default clean unless ``keep_all``."""
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
    from . import infer

    model = _model(model)
    return infer.decode(model, _latents(z, model), segments=segments, keep_all=keep_all,
                        clean=_parts(parts, keep_all))


def prior_latents(n: int, model=DEFAULT_MODEL, *, seed: int = 0, temperature: float | None = None,
                  prior: str = "auto") -> np.ndarray:
    """``n`` latents ``(n, D)`` float32, the same for the same ``seed``.

    ``prior``: ``"fitted"`` draws from the density fitted to the training set's latents that
    the model folder stores (``model.prior``), ``"normal"`` from N(0, I), ``"auto"`` the first when the
    model has one. ``temperature`` scales the std (``None``: the fitted prior's stored one, 1 for N(0, I))."""
    from . import infer

    return infer.prior_latents(_model(model), n, seed=seed, temperature=temperature, prior=prior).numpy()


def sample(n: int, model=DEFAULT_MODEL, *, seed: int = 0, temperature: float | None = None, prior: str = "auto",
           segments: int | None = None, parts: str = "clean") -> list[VectorImage]:
    """``n`` new graphics: ``prior_latents`` decoded (``parts`` as in ``decode``)."""
    model = _model(model)
    z = prior_latents(n, model, seed=seed, temperature=temperature, prior=prior)
    return decode(z, model, segments=segments, parts=parts)


def interpolate(a, b, model=DEFAULT_MODEL, *, steps: int = 4, segments: int | None = None,
                keep_all: bool = False, parts: str | None = None, fit: bool = True,
                grow: int = GROW) -> list[VectorImage]:
    """``steps + 2`` frames from ``a`` to ``b``, ends included, on the model's square canvas.

    Each end is a picture (``project``-ed: fitted unless ``fit=False``), a latent ``(D,)``
    (decoded) or a projection of one (``project(...).take(i)``). The frames interpolate the
    two ends' paths (``Projection.between``), and are drawn as ``decode`` says (``keep_all``:
    the model's own paths, every frame with the same ones). ``grow``: a picture end fitted (not with
    ``keep_all``) gets at most this many pieces grown where its paths miss a part (``project.grown_parts``),
    matched across the ends and morphed with the paths (``vector.morph.frames``); 0: the model's paths alone."""
    from . import project as projection
    from .raster import compiling

    model = _model(model)
    grow = 0 if keep_all or not fit else grow
    with compiling(False):
        pa, pb = (projection.endpoint(model, x, _fitting(fit), segments, grow) for x in (a, b))
    return pa.between(pb, steps).vectors(model.config.image_size, clean=_parts(parts, keep_all), keep_all=keep_all)


# --- models from images: training, fine-tuning, the latent prior and the auxiliary networks ---

def train(data_dir, run_dir="runs/latest", model_config=None, train_config=None, *, init=None,
          device="auto", val_dir=None, resume: bool = False, overwrite: bool = False,
          epochs: float | None = None, minutes: float | None = None, on_event=None) -> Path:
    """Train a model on a folder of images (``train.train``); returns the exported model folder.

    ``model_config`` / ``train_config``: ``ModelConfig`` / ``TrainConfig`` or dicts of their fields. ``init``
    (a model or its name) fine-tunes: its weights and config, but ``options.GROWABLE`` fields (``grow_state``).
    ``resume`` / ``overwrite`` as ``checkpoint.prepare_run_dir`` says (a resumed run keeps its configs, the keys
    given over them: ``checkpoint.resumed_configs``); ``minutes`` bounds a phase (``train.train``). ``on_event``
    hears each progress event, a typed ``events.Event`` (``DataLoaded``, ``TrainStep``, ...; also of ``fit_prior``,
    ``train_aux`` and ``train_features``)."""
    from .checkpoint import resumed_configs
    from .config import ModelConfig, TrainConfig
    from .model.pretrained import grow_state
    from .options import GROWABLE, fixed_on_init
    from .runtime import resolve_device
    from .training.train import train as run_train

    given = model_config.to_dict() if isinstance(model_config, ModelConfig) else dict(model_config or {})
    t_given = train_config.to_dict() if isinstance(train_config, TrainConfig) else dict(train_config or {})
    if init is not None and resume:
        raise ValueError("init starts a new run and resume continues one: give one of them")
    given, t_given = resumed_configs(run_dir, given, t_given) if resume else (given, t_given)  # checkpoint's, given over
    tcfg, init_state = TrainConfig.from_dict(t_given), None
    if init is None:
        mcfg = ModelConfig.from_dict(given)
    else:
        start = _model(init).cpu()
        fixed = fixed_on_init(given, start.config.to_dict())
        if fixed:
            raise ValueError(f"init takes the model's config (but {', '.join(GROWABLE)}); drop {', '.join(fixed)}")
        mcfg = ModelConfig.from_dict({**start.config.to_dict(), **given})
        init_state = grow_state(start.state_dict(), start.config, mcfg, tcfg.seed)
    dev = resolve_device(device) if isinstance(device, str) else device
    return run_train(data_dir, run_dir, mcfg, tcfg, device=dev, val_dir=val_dir, resume=resume,
                     overwrite=overwrite, on_event=on_event, epochs=epochs, init_state=init_state, minutes=minutes)


def export(run_dir, output, *, half: bool = False, overwrite: bool = False) -> tuple[Path, int]:
    """The model of a run's latest checkpoint as a model folder (``pretrained.export_checkpoint``)."""
    from .model.pretrained import export_checkpoint

    return export_checkpoint(run_dir, output, half=half, overwrite=overwrite)


def train_features(data_dir, output, *, size: int = 64, fit: str = "resize", steps: int = 2000, seed: int = 0,
                   on_event=None):
    """Train the feature net of ``eval --features`` on ``data_dir``'s training split and write
    it to ``output``: a classifier when the folder layout names classes (with one more class
    for junk images, outlier exposure), else an autoencoder; its test accuracy (or MSE) on
    ``DATA/test`` is stored in its config. Returns the ``FeatureNet``."""
    import torch

    from .data.folder import folder_labels, load_folder, split_dir
    from .errors import Im2VecError
    from .model.features import FeatureConfig
    from .training.features import JUNK, FeatureSettings, feature_net_score, train_feature_net

    emit = on_event or (lambda e: None)
    skip = lambda m: emit(Skipped(m))  # noqa: E731
    x, names = load_folder(split_dir(data_dir, "train"), size, fit=fit, on_skip=skip)
    labels = folder_labels(names)
    classes = sorted(set(labels[0])) + [JUNK] if labels else []  # JUNK: outlier exposure (train_features.py)
    cfg = FeatureConfig(image_size=size, fit=fit, classes=classes, data=str(data_dir))
    emit(FeatureData(len(x), len(classes) - 1 if labels else 0, labels[1] if labels else None))
    index = {c: i for i, c in enumerate(classes)}
    y = torch.tensor([index[c] for c in labels[0]]) if labels else None
    net = train_feature_net(x, y, cfg, FeatureSettings(steps=steps, seed=seed), on_step=emit)
    tx, tnames = load_folder(split_dir(data_dir, "test"), size, fit=fit, on_skip=skip)
    if classes:
        tlabels = folder_labels(tnames, key=labels[1])[0]
        if any(c not in index for c in tlabels):
            raise Im2VecError(f"{data_dir}: the test split has classes the training split has not")
        net.config = dataclasses.replace(cfg, test_accuracy=feature_net_score(
            net, tx, torch.tensor([index[c] for c in tlabels])))
    else:
        net.config = dataclasses.replace(cfg, test_mse=feature_net_score(net, tx, None))
    emit(FeatureTest(len(tx), net.config.test_accuracy if classes else None,
                     None if classes else net.config.test_mse))
    net.save(output)
    return net


def load_feature_net(folder):
    """A feature net written by ``train_features`` (``model.features.FeatureNet``)."""
    from .model.features import FeatureNet

    return FeatureNet.load(folder)
