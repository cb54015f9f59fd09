"""``vectorize``: pictures in, closed cubic paths out, and the model it may need, loaded at its
first use (``ModelRef``).

Stages: each picture as an array (``files.as_picture``) -> with clean parts, read
(``trace.read_pictures``) -> the pictures that are not polished (larger than the polish's size,
pixel art, photos, ``effort="draft"``) traced without the renderer (``refine.clean.trace_alone``: NumPy,
no torch, no model) and the others refined through it (``refine.refine_batch``) -> each result
with its notes. ``--parts model`` and ``--no-refine`` always use the model. Re-exported by
``api.py``; nothing here prints or exits.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Callable

import numpy as np

from . import trace
from .config import DEFAULT_MODEL, check_model_folder, resolve_model
from .errors import ModelError, OptionWarning, VectorizeError, describe
from .events import Event, Stage
from .files import as_picture, to_tensor
from .options import Plan, VectorizeOptions
from .runtime import check_device
from .vector import VectorImage


def load_model(name_or_dir: str = DEFAULT_MODEL, device="auto"):
    """A shipped model by name (``fonts``, ``mnist``, ``emoji``, ``icons``) or a model folder written by
    ``im2vec train`` / ``export``, on ``device`` (a ``torch.device`` or ``auto``: CUDA, then MPS, then CPU)."""
    from . import infer, refine  # noqa: F401 - what uses a model, imported with it (the CLI's collector is paused)
    from .model.pretrained import from_pretrained
    from .runtime import resolve_device

    return from_pretrained(name_or_dir, resolve_device(device) if isinstance(device, str) else device)


class ModelRef:
    """A model loaded at its first use, once (``load()`` gives it): ``vectorize`` of pictures that are
    traced and not polished never loads it, nor imports torch. ``ModelRef("fonts")`` checks the name
    and the folder at once (``config.check_model_folder``: all but the weights' values) and the device's
    name (``runtime.check_device``), and loads it with ``load_model`` on ``device``; any other
    ``load`` callable may stand in."""

    def __init__(self, name_or_dir: str = DEFAULT_MODEL, device="auto", load=None):
        if load is None:  # an unknown or broken model is an error now, not at the first picture that needs it
            check_model_folder(resolve_model(name_or_dir))
            check_device(device)
        self._load = load or (lambda: load_model(name_or_dir, device))
        self._model = None

    def load(self):
        if self._model is None:
            self._model = self._load()
        return self._model


def model_of(model):
    """A model given as itself, a ``ModelRef`` or a name -> the model."""
    return model.load() if isinstance(model, ModelRef) else load_model(model) if isinstance(model, str) else model


def vectorize(images, model=DEFAULT_MODEL, options: VectorizeOptions | None = None, *,
              on_event: Callable[[Event], None] | None = None, **fields) -> VectorImage | list[VectorImage]:
    """Vectorize one picture (or a list of them) into closed cubic paths.

    Args:
        images: a picture, or a list of pictures (any size each).
        model: a model from ``load_model``, a ``ModelRef``, or its name (loaded only where a
            picture needs it: one traced and not polished does not).
        options: a ``VectorizeOptions`` (default: its defaults; its docstring describes each
            field); ``fields`` override any of them by name (``vectorize(img, m, parts="model")``).
        on_event: hears the progress of refinement: ``events.Stage`` (read, traced, polished,
            finished) and ``events.RefineStep``.

    Returns:
        One ``VectorImage`` per picture (a list for a list), in each picture's pixel frame.
    """
    o = dataclasses.replace(options or VectorizeOptions(), **fields)  # validated here, once
    warn_idle(o, set(fields) | set_fields(options))
    plan = o.resolve()
    model = ModelRef(model) if isinstance(model, str) else model
    one = not isinstance(images, (list, tuple))
    pictures = [as_picture(x) for x in ([images] if one else images)]
    check_segments(model, plan.segments)
    out = _refined(model, pictures, plan, on_event) if plan.refine else _guessed(model, pictures, plan)
    return out[0] if one else out


def set_fields(options: VectorizeOptions | None) -> set[str]:
    """The fields of ``options`` that differ from their defaults (those the caller set)."""
    if options is None:
        return set()
    default = VectorizeOptions()
    return {f.name for f in dataclasses.fields(options) if getattr(options, f.name) != getattr(default, f.name)}


def warn_idle(options: VectorizeOptions, given: set[str]) -> None:
    """An ``errors.OptionWarning`` for each field of ``given`` that does nothing with these options
    (``VectorizeOptions.idle``): the same notes the CLI prints."""
    for note in options.idle(given):
        warnings.warn(note, OptionWarning, stacklevel=3)


def _guessed(model, pictures: list[np.ndarray], plan: Plan) -> list[VectorImage]:
    """``vectorize`` without refinement: the model's guess, in one batch (torch and the model loaded)."""
    model = model_of(model)
    from . import infer
    from .raster import compiling

    kw = {"segments": plan.segments, "quality": plan.quality, "max_paths": plan.max_paths, "clean": plan.parts == "clean"}
    with compiling(plan.compile):  # compiling the passes cost 6-16 s a process for 0.15 s of work
        out = infer.vectorize(model, [to_tensor(p) for p in pictures], **kw)
    return [trace.simplify(v, plan.simplify_tol) for v in out]


def _refined(model, pictures: list[np.ndarray], plan: Plan, on_event=None) -> list[VectorImage]:
    """``vectorize`` with refinement: each result with its ``notes`` (``_notes``). With clean parts
    the pictures are read first; those that are not polished are traced here without the renderer
    (``refine.clean.trace_alone``), the others refined (``refine.refine_batch``, given their readings)."""
    out: list = [None] * len(pictures)
    rest, readings = list(range(len(pictures))), None
    if plan.parts == "clean":
        readings = trace.read_pictures(pictures, plan)
        needs = trace.needs_renderer(readings, plan)
        rest, alone = [i for i, n in enumerate(needs) if n], [i for i, n in enumerate(needs) if not n]
        if alone:
            if on_event and not rest:
                on_event(Stage("read"))
            from .refine.clean import trace_alone  # (NumPy only: no torch)

            got = trace_alone([readings[i] for i in alone], [pictures[i].shape[:2] for i in alone], plan,
                              on_stage=on_event)
            for i, r in zip(alone, got):
                out[i] = r
    if rest:
        model = model_of(model)  # (torch's import with it)
        from . import refine
        from .raster import compiling

        with compiling(plan.compile):  # off by default: each new image size would compile afresh
            got = refine.refine_batch(model, [to_tensor(pictures[i]) for i in rest], plan, on_step=on_event,
                                      readings=None if readings is None else [readings[i] for i in rest])
        for i, r in zip(rest, got):
            out[i] = r
    return [dataclasses.replace(v, notes=_notes(info)) for v, info in out]


def _notes(info: dict) -> dict:
    """What a result tells beside its paths: the kind of picture it was read as, and how."""
    return {k: info[k] for k in ("kind", "reading", "start", "loss_end") if k in info}


def vectorize_each(images: list, model=DEFAULT_MODEL, options: VectorizeOptions | None = None, *,
                   on_event: Callable[[Event], None] | None = None, **fields) -> list[VectorImage | VectorizeError]:
    """``vectorize`` of a list of pictures in which one picture's failure is its own: each entry
    is the picture's ``VectorImage``, or a ``VectorizeError`` (one line) where its pipeline
    raised anything (a dependency's error, memory running out). The pictures are vectorized
    together; when that fails, each is vectorized alone, to find which. Options and the model
    are checked first: a bad option raises, as in ``vectorize``; ``on_event`` as there."""
    o = dataclasses.replace(options or VectorizeOptions(), **fields)
    model = ModelRef(model) if isinstance(model, str) else model
    check_segments(model, o.segments)
    try:
        return vectorize(list(images), model, o, on_event=on_event)
    except Exception as exc:  # noqa: BLE001 - any failure is one picture's; KeyboardInterrupt is not caught
        if len(images) == 1:
            return [_failed(exc)]
    out: list = []
    for img in images:
        try:
            out.append(vectorize([img], model, o)[0])
        except Exception as exc:  # noqa: BLE001
            out.append(_failed(exc))
    return out


def _failed(exc: Exception) -> VectorizeError:
    return exc if isinstance(exc, VectorizeError) else VectorizeError(f"could not vectorize: {describe(exc)}")


def check_segments(model, segments: int | str | None) -> None:
    """``ModelError`` when ``segments="auto"`` is asked of a model (or ``ModelRef``: then loaded) without
    a segment predictor."""
    if segments == "auto" and model_of(model).segment_predictor is None:
        raise ModelError(f"model {getattr(model_of(model), 'name', '?')!r} has no segment predictor for segments='auto' "
                         "(add one with `im2vec train-aux`)")
