"""Progress events of the long library calls (``api.train``, ``fit_prior``, ``train_aux``,
``train_features``, refinement): typed and frozen, so that a caller matches on the class, not
on string keys. Torch-free, so the CLI imports them.

Each event has a ``kind`` (the ``"event"`` field of ``RUN/metrics.jsonl``) and ``as_dict()``,
the record written there: ``{"event": kind, **fields}``, with a ``figures`` mapping spread
into the record.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import ClassVar

try:
    from typing import dataclass_transform
except ImportError:  # Python 3.10: only type checkers need it
    def dataclass_transform(**_):
        return lambda cls: cls


@dataclass_transform(frozen_default=True, field_specifiers=(field,))
class Event:
    """A progress event; a subclass names its ``kind`` (``class Done(Event, kind="done")``) and
    is a frozen dataclass of its fields."""

    kind: ClassVar[str] = ""

    def __init_subclass__(cls, kind: str = "", **kwargs):
        super().__init_subclass__(**kwargs)
        cls.kind = kind
        dataclass(frozen=True)(cls)

    def as_dict(self) -> dict:
        """The JSON record: ``{"event": kind, **fields}``, ``figures`` spread in place."""
        out: dict = {"event": self.kind}
        for f in dataclasses.fields(self):
            if f.name == "figures":
                out.update(getattr(self, f.name))
            else:
                out[f.name] = getattr(self, f.name)
        return out


# --- training (api.train) ------------------------------------------------------------------------


class Skipped(Event, kind="skip"):
    """An unreadable image left out of the data."""
    message: str


class DataLoaded(Event, kind="data"):
    """The images loaded for training and validation, and the steps to run."""
    train: int
    val: int
    steps: int


class Resumed(Event, kind="resume"):
    """Training continues from the checkpoint of ``step``."""
    step: int


class TrainStep(Event, kind="train"):
    """A logged training step: ``figures`` (loss, pyramid_l2, kl, k, lr, tau, grad_norm) and the
    throughput since the last one."""
    step: int
    figures: dict[str, float] = field(default_factory=dict)
    img_per_s: float = 0.0
    time: float = 0.0


class NonFinite(Event, kind="nonfinite"):
    """A step whose loss or gradient was not finite: its update was skipped."""
    step: int
    loss: float
    grad_norm: float
    in_a_row: int
    time: float = 0.0


class Validated(Event, kind="val"):
    """The held-out figures (``val_pyramid_l2``, ``val_mse``; ``raw_*`` with an EMA)."""
    step: int
    figures: dict[str, float] = field(default_factory=dict)
    time: float = 0.0


class Teaching(Event, kind="teach"):
    """A distillation phase has fitted the latents of ``done`` of its ``images`` teacher images."""
    done: int
    images: int
    time: float = 0.0


class Tracing(Event, kind="trace"):
    """An outline phase has traced ``done`` of its ``images`` training images (``outline_aux``)."""
    done: int
    images: int
    time: float = 0.0


class TimeUp(Event, kind="time_up"):
    """The phase's time (``train``'s ``minutes``) ran out: ``step`` of ``steps`` is its last."""
    step: int
    steps: int
    time: float = 0.0


class PriorFitting(Event, kind="prior"):
    """The latent prior is being fitted to the latents of ``images`` training images."""
    images: int


class NoPrior(Event, kind="no_prior"):
    """Too few training images for a latent prior: ``sample`` draws from N(0, I)."""
    images: int
    needed: int


# --- fit_prior, train_aux, train_features -------------------------------------------------------


class Encoding(Event, kind="encode"):
    """``fit_prior`` (``fit_neighbours``: the anchors only) encodes ``images`` images."""
    images: int


class Measuring(Event, kind="measure"):
    """``train_aux`` sweeps the segment count of ``paths`` paths of ``images`` images."""
    images: int
    paths: int


class AuxStep(Event, kind="aux_step"):
    """A step of the segment-count predictor (every 250 and the last): its fit, the log MSE of
    the predicted loss(k) curves, on the training and on the held-out path codes."""
    step: int
    fit: float
    val_fit: float


class FeatureData(Event, kind="feature_data"):
    """The feature net's training images: a classifier of ``classes`` (named by file or folder,
    ``by``), or an autoencoder (``classes`` 0)."""
    images: int
    classes: int
    by: str | None


class FeatureStep(Event, kind="feature_step"):
    """A step of the feature net's training."""
    step: int
    loss: float


class FeatureTest(Event, kind="feature_test"):
    """The feature net on the test split: ``accuracy`` (a classifier) or ``mse`` (an autoencoder)."""
    images: int
    accuracy: float | None
    mse: float | None


# --- refinement ------------------------------------------------------------------------------------


class RefineStep(Event, kind="refine_step"):
    """A step of a refinement stage (``latent``, ``points``, ``polish``, ``outline``): the mean
    loss over the ``images`` still optimised, and the edge softness ``tau`` (input px)."""
    stage: str
    step: int
    loss: float
    images: int
    tau: float | None = None


class Stage(Event, kind="stage"):
    """A stage of ``vectorize`` done for a batch of pictures (``STAGES``, in order)."""
    stage: str


STAGES = ("read", "traced", "polished", "finished")  # `Stage.stage`: read, traced and fitted, polished, untangled


# --- worker processes (parallel.vectorize_chunks) ----------------------------------------------------


class WorkerDied(Event, kind="worker_died"):
    """A worker process died (``signal``: the signal that ended it, or 0 when not known) with
    ``pictures`` in its pool's hands; they are vectorized again in a fresh pool, one chunk at a
    time, and a picture whose worker dies again fails."""
    signal: int
    pictures: int
