"""Configuration dataclasses: ``ModelConfig`` (architecture) and ``TrainConfig`` (optimisation).

Both are frozen; ``from_dict`` rejects unknown keys and wrong types.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, get_type_hints

from .errors import ConfigError, Im2VecError, ModelError
from .options import ARCHS, FITS, GROUPINGS, parse_augment

FORMAT_VERSION = 1
# ModelConfig.grouping: how the P paths make shapes. "evenodd": one shape under the even-odd rule (every
# overlap of two paths is a hole); "nonzero": one shape under the nonzero rule (overlaps stay filled, a
# path wound the other way inside another cuts a hole, as in font outlines); "layers": one coloured shape
# per path, composited by depth.
PYRAMID_MODES = ("blur", "render")  # TrainConfig.pyramid: the coarse levels of the loss (raster.render_pyramid)
TRAIN_ONLY = ("", "encoder", "path_pass", "point_pass")  # TrainConfig.train_only: every weight, or one module's alone (the rest frozen)
DEFAULT_COMPONENTS = 10  # Gaussians of a fitted latent prior (model.prior): chosen by the samples' precision/recall on MNIST
DEFAULT_NEIGHBOURS = 8  # nearest training latents a neighbour prior steps towards (model.prior.NeighbourPrior)
DEFAULT_SHRINK = 1e-4  # added to each of its covariances' diagonal, in units of the latents' mean variance
# ModelConfig.feedback: a bound on cost (each pass renders the batch once more), not on quality: how many
# passes help is a property of each model's weights, measured (bench/ship_phase.py --feedback N)
MAX_FEEDBACK = 8


# ModelConfig's bounds, checked before a model is built: far above any model trained here (image_size 64,
# paths 8, widths 128), and the largest model they allow has 121 M parameters (0.5 GB; tests/test_config.py),
# where a crafted config.json asked for 7 GB
MODEL_AT_MOST = {"image_size": 256, "channels": 4, "latent": 1024, "paths": 64, "enc_width": 64, "lstm_hidden": 512,
                 "code": 512, "dec_width": 512, "dec_layers": 16, "deform_width": 512, "segments": 200,
                 "min_segments": 200, "max_segments": 200, "samples": 32, "levels": 6, "segment_predictor": 1024,
                 "path_pass_width": 128, "point_pass_width": 512, "point_smooth": 16}
MAX_RENDER_WORK = 2**26  # paths x segments x samples x pixels of one picture's render (shipped models: 1.6-3.3 M)
MAX_BATCH = 256  # TrainConfig.batch: four times the shipped runs' 64
MAX_CONFIG_BYTES = 2**20  # a config file larger than this is refused unread (a 3 GB sparse one was read whole)


class JsonConfig:
    """A frozen dataclass stored as JSON (class name and format version beside the fields)."""

    @classmethod
    def from_dict(cls, data: dict[str, Any]):
        if not isinstance(data, dict):
            raise Im2VecError(f"{cls.__name__}: expected a mapping, got {type(data).__name__}")
        data = {k: v for k, v in data.items() if k not in ("class_name", "format_version")}
        hints = get_type_hints(cls)
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - names)
        if unknown:
            raise Im2VecError(f"{cls.__name__}: unknown keys {unknown}")
        for key, value in data.items():
            want = hints[key]
            ok = {
                int: isinstance(value, int) and not isinstance(value, bool),
                float: isinstance(value, (int, float)) and not isinstance(value, bool),
                bool: isinstance(value, bool),
                str: isinstance(value, str),
            }.get(want, True)
            if want == "int | None" or str(want) == "int | None":
                ok = value is None or isinstance(value, int)
            if not ok:
                raise Im2VecError(f"{cls.__name__}.{key}: expected {getattr(want, '__name__', want)}, got {value!r}")
            if want is float:
                data[key] = float(value)
        return cls(**data)

    def to_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d["class_name"] = type(self).__name__
        d["format_version"] = FORMAT_VERSION
        return d

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2, sort_keys=True) + "\n"

    @classmethod
    def load(cls, path: str | Path):
        data = read_json(path)
        if not isinstance(data, dict):
            raise Im2VecError(f"{path}: expected a JSON object, got {type(data).__name__}")
        if data.get("format_version", FORMAT_VERSION) != FORMAT_VERSION:
            raise Im2VecError(f"{path}: config format version {data.get('format_version')} is not {FORMAT_VERSION}")
        try:
            return cls.from_dict(data)
        except Im2VecError as exc:
            raise Im2VecError(f"{path}: {exc}") from None


def read_json(path: str | Path, limit: int = MAX_CONFIG_BYTES) -> Any:
    """The JSON of a regular file of at most ``limit`` bytes (``files.read_regular``: a FIFO,
    a device or a larger file is refused unread); anything else is one ``Im2VecError`` line."""
    from .files import read_regular

    raw = read_regular(path, limit, what="config file")
    try:
        return json.loads(raw.decode("utf-8"))
    except UnicodeDecodeError:
        raise Im2VecError(f"{path}: not valid JSON (not UTF-8 text)") from None
    except (json.JSONDecodeError, RecursionError) as exc:
        raise Im2VecError(f"{path}: not valid JSON ({str(exc)[:120]})") from None


@dataclass(frozen=True)
class ModelConfig(JsonConfig):
    """Architecture of the Im2Vec VAE (paper sec. 3)."""

    arch: str = "im2vec"  # "im2vec" (paths, sec. 3) or "imagevae" (the raster baseline of sec. 4)
    image_size: int = 64
    fit: str = "resize"  # inputs smaller than image_size: "resize" (upscaled) or "pad" (centred unscaled, see fit_square)
    channels: int = 3
    latent: int = 128
    paths: int = 4
    enc_width: int = 32  # first conv width; doubles per stride-2 stage, capped at 8x
    lstm_hidden: int = 128
    code: int = 64  # per-path code
    dec_width: int = 128  # path decoder channels (authors: 264)
    dec_layers: int = 4  # path decoder conv layers (authors: 6)
    deform: bool = True  # sample deformation subnetwork (sec. 3.1.2)
    deform_width: int = 64
    grouping: str = "evenodd"  # GROUPINGS: one even-odd shape (fonts, digits), one nonzero shape (icons), or layers
    palette: str = ""  # fixed colours "#rrggbb,#rrggbb,..." (empty: learned colours)
    segments: int = 12  # default k at inference
    min_segments: int = 7  # training range of k (sec. 3.5)
    max_segments: int = 25
    samples: int = 4  # lines per cubic when rasterising
    levels: int = 3  # Gaussian pyramid levels of the loss (eq. 1)
    feedback: int = 0  # render-and-compare passes correcting the encoder's latent (model.encoder.Feedback), 0 to MAX_FEEDBACK
    feedback_paths: bool = False  # the feedback pass also sees each path's own coverage (P more input channels)
    feedback_select: bool = False  # at inference, keep per picture the pass whose render is closest to it (one render more)
    path_passes: int = 0  # render-and-compare passes correcting each path's code and colour (model.encoder.PathPass), 0 to MAX_FEEDBACK
    path_pass_width: int = 16  # first conv width of the path pass (a multiple of 8)
    point_passes: int = 0  # render-and-compare passes moving each path's outline across and along itself (model.points), 0 to MAX_FEEDBACK
    point_pass_width: int = 64  # channels of the point pass's circular convolutions
    point_smooth: int = 0  # [1, 2, 1] / 4 filters the point pass's moves go through along the outline (model.points)
    solve_colors: bool = False  # at inference, given the picture, the layers' colours by least squares (raster.solve_colors)
    solve_order: bool = False  # ...and before that their order, searched by the solved render's error (raster.solve_order)
    segment_predictor: int = 0  # hidden width of the segment-count MLP (sec. 3.3); 0: none (`im2vec train-aux` adds it)

    def __post_init__(self):
        """Values no model can be built with are refused here (one line naming the key)."""
        at_least = {"image_size": 8, "channels": 1, "latent": 1, "paths": 1, "enc_width": 8, "lstm_hidden": 1,
                    "code": 1, "dec_width": 1, "dec_layers": 1, "deform_width": 1, "segments": 1, "min_segments": 1,
                    "max_segments": 1, "samples": 1, "levels": 1, "segment_predictor": 0, "feedback": 0,
                    "path_passes": 0, "path_pass_width": 8, "point_passes": 0, "point_pass_width": 1,
                    "point_smooth": 0}
        for key, low in at_least.items():
            if getattr(self, key) < low:
                raise ConfigError(f"ModelConfig.{key} must be >= {low}, got {getattr(self, key)}")
        for key, high in MODEL_AT_MOST.items():  # before anything is built from it: a crafted config costs nothing
            if getattr(self, key) > high:
                raise ConfigError(f"ModelConfig.{key} must be <= {high}, got {getattr(self, key)}")
        work = self.paths * self.max_segments * self.samples * self.image_size**2
        if work > MAX_RENDER_WORK:
            raise ConfigError(f"ModelConfig: paths x max_segments x samples x image_size^2 is {work:,}, over the "
                              f"{MAX_RENDER_WORK:,} (line x pixel pairs) one render may cost")
        if self.feedback > MAX_FEEDBACK:
            raise ConfigError(f"ModelConfig.feedback must be <= {MAX_FEEDBACK} (each pass renders the batch once), "
                              f"got {self.feedback}")
        if self.path_passes > MAX_FEEDBACK or self.path_pass_width % 8:
            raise ConfigError(f"ModelConfig.path_passes must be <= {MAX_FEEDBACK} and path_pass_width a multiple of 8, "
                              f"got {self.path_passes} and {self.path_pass_width}")
        if self.point_passes > MAX_FEEDBACK:
            raise ConfigError(f"ModelConfig.point_passes must be <= {MAX_FEEDBACK}, got {self.point_passes}")
        if self.feedback_paths and not self.feedback:
            raise ConfigError("ModelConfig.feedback_paths needs feedback >= 1 (it adds inputs to the feedback pass)")
        if self.feedback_select and not self.feedback:
            raise ConfigError("ModelConfig.feedback_select needs feedback >= 1 (it chooses among the passes)")
        if self.solve_colors and (self.grouping != "layers" or self.palette):
            raise ConfigError("ModelConfig.solve_colors needs grouping 'layers' and learned colours (no palette)")
        if self.solve_order and not self.solve_colors:
            raise ConfigError("ModelConfig.solve_order needs solve_colors (each order is scored with its colours solved)")
        if self.min_segments > self.max_segments:
            raise ConfigError(f"ModelConfig.min_segments ({self.min_segments}) is above max_segments ({self.max_segments})")
        for key, allowed in (("arch", ARCHS), ("fit", FITS),
                             ("grouping", GROUPINGS)):
            if getattr(self, key) not in allowed:
                raise ConfigError(f"ModelConfig.{key} must be one of {allowed}, got {getattr(self, key)!r}")


@dataclass(frozen=True)
class TrainConfig(JsonConfig):
    """Optimisation settings of ``im2vec train``."""

    steps: int = 5000
    batch: int = 64
    lr: float = 5e-4
    beta: float = 1e-5  # KL weight (on the sum over latent dims)
    beta_warmup: int = 2000  # steps of linear KL warm-up
    grad_clip: float = 1.0
    lookahead_k: int = 6
    lookahead_alpha: float = 0.5
    tau_start: float = 1.0  # edge softness (pixels), annealed linearly...
    tau_end: float = 0.4  # ...to this value at the last step
    supersample: int = 1  # > 1: the finest loss level is box-filtered from sub-pixels, like the SVG's antialiased render
    pyramid: str = "blur"  # coarser loss levels: "blur" (pyramid of the render, as the target's) or "render" (see render_pyramid)
    lr_final: float = 0.1  # cosine decay to lr * lr_final
    ema: float = 0.0  # > 0: keep an exponential moving average of the weights with this decay; val and export use it
    distill: float = 0.0  # > 0: weight of the encoder's squared distance to the fitted latents (distill.Teacher)
    distill_images: int = 4096  # training images whose latents the teacher fits (when distill > 0)
    outline: float = 0.0  # > 0: weight of the mean squared distance (px^2) of the traced outlines to the paths (outline_aux)
    detail: float = 0.0  # > 0: the finest loss level weighs pixels by their picture's detail (raster.detail_weights)
    solved: bool = False  # the loss sees the colours solved (ModelConfig.solve_colors), composited "over" as the SVG is
    augment: str = ""  # any of "flip", "scale", "shift", comma-separated: mirrored / scaled / shifted pictures (data.augment)
    train_only: str = ""  # TRAIN_ONLY: "encoder" freezes the rest (the decoder the teacher's latents were fitted to)
    prior_components: int = DEFAULT_COMPONENTS  # Gaussians of the latent prior fitted at the end (fonts: 62)
    prior_shrink: float = DEFAULT_SHRINK  # its covariance shrinkage (model.prior.fit_prior; emoji: 0.05)
    prior_neighbours: int = DEFAULT_NEIGHBOURS  # k of the neighbour prior fitted beside it (0: none; model.prior.fit_neighbours)
    seed: int = 0
    val_fraction: float = 0.05
    val_every: int = 250
    ckpt_every: int = 250
    preview_every: int = 500
    workers: int = 2
    log_every: int = 25

    def __post_init__(self):
        """Values a run cannot use are refused here, before any data loads."""
        if self.batch > MAX_BATCH:  # memory grows with it before any step runs (a huge one reached 6.2 GB on 3 images)
            raise ConfigError(f"TrainConfig.batch must be <= {MAX_BATCH}, got {self.batch}")
        for key in ("steps", "batch", "beta_warmup", "distill_images", "lookahead_k", "val_every", "ckpt_every", "preview_every",
                    "workers", "log_every", "prior_components"):
            if getattr(self, key) < 1:
                raise ConfigError(f"TrainConfig.{key} must be >= 1, got {getattr(self, key)}")
        for key in ("lr", "beta", "grad_clip", "lookahead_alpha", "tau_start", "tau_end", "lr_final", "val_fraction",
                    "distill", "outline", "prior_shrink", "detail"):
            v = getattr(self, key)
            if not (math.isfinite(v) and v >= 0):
                raise ConfigError(f"TrainConfig.{key} must be a finite number >= 0, got {v}")
        if not 0 <= self.seed < 2**32:
            raise ConfigError(f"TrainConfig.seed must be in [0, 2^32), got {self.seed}")
        if self.supersample < 1:
            raise ConfigError(f"TrainConfig.supersample must be >= 1, got {self.supersample}")
        if self.prior_neighbours < 0:
            raise ConfigError(f"TrainConfig.prior_neighbours must be >= 0, got {self.prior_neighbours}")
        if self.pyramid not in PYRAMID_MODES:
            raise ConfigError(f"TrainConfig.pyramid must be one of {PYRAMID_MODES}, got {self.pyramid!r}")
        if not 0.0 <= self.ema < 1.0:
            raise ConfigError(f"TrainConfig.ema must be in [0, 1), got {self.ema}")
        try:
            augments = parse_augment(self.augment)
        except ValueError as e:
            raise ConfigError(f"TrainConfig.augment: {e}") from None
        if augments and self.outline:
            raise ConfigError("TrainConfig.augment: augment moves the pictures away from the outlines the outline "
                              "loss traced")
        if self.train_only not in TRAIN_ONLY:
            raise ConfigError(f"TrainConfig.train_only must be one of {TRAIN_ONLY}, got {self.train_only!r}")


# --- model folders: where a model named on the command line is found ---

REPO_MODELS = Path(__file__).resolve().parents[2] / "models"
PACKAGE_MODELS = Path(__file__).resolve().parents[0] / "models"
DEFAULT_MODEL = "fonts"


def resolve_model(name_or_dir: str | os.PathLike) -> Path:
    """A model folder, looked up in this order:

    1. a path (it names a folder: ``runs/x/model``, ``./fonts``, ``/abs``): that folder;
    2. a bare name (``fonts``): a folder of that name here only when it holds ``config.json``,
       then ``$IM2VEC_MODELS/NAME``, the repository's ``models/NAME``, the package's
       bundled ``models/NAME``; so a folder here that is not a model never hides a shipped one.
    """
    p = Path(name_or_dir)
    name = str(name_or_dir)
    bare = os.sep not in name and (os.altsep or os.sep) not in name and name not in (".", "..")
    if p.is_dir() and (not bare or (p / "config.json").is_file()):
        return p
    candidates = []
    if os.environ.get("IM2VEC_MODELS"):
        env = Path(os.environ["IM2VEC_MODELS"])
        if not env.is_dir():  # a typo here would silently fall back to the shipped models
            raise ModelError(f"IM2VEC_MODELS={env} is not a folder")
        candidates.append(env / name)
    candidates += [REPO_MODELS / name, PACKAGE_MODELS / name]
    for c in candidates:
        if (c / "config.json").is_file():
            return c
    if p.is_dir():
        return p  # not a model: its missing config.json is the error to show
    known = sorted({d.name for base in (REPO_MODELS, PACKAGE_MODELS) if base.is_dir() for d in base.iterdir()
                    if (d / "config.json").is_file()})
    if not known:  # an install without its models (a wheel built without them, a copied package)
        raise ModelError(f"unknown model {name!r}: no models are installed; give --model a model folder, or set "
                         "IM2VEC_MODELS to a folder of them (a checkout's models/)")
    raise ModelError(f"unknown model {name!r} (not a directory; shipped models: {', '.join(known)})")


STORED_TYPES = {"F32", "F16", "BF16", "I64", "I32", "BOOL"}  # a weight's (pretrained.STORED_FLOATS) or a buffer's


def check_model_folder(folder: Path) -> ModelConfig:
    """What can be told of a model folder without torch, before it is needed: its config (every
    bound), and its weights file present, whole (every tensor's bytes inside the file) and of
    stored types the loader takes. The values (NaN, shapes against the config) are checked when
    it loads (``pretrained.from_pretrained``). Returns the config."""
    cfg = ModelConfig.load(folder / "config.json")
    weights = folder / "model.safetensors"
    if not weights.is_file():
        raise ModelError(f"{folder}: model.safetensors is missing")
    size = weights.stat().st_size
    try:
        with open(weights, "rb") as f:
            n = int.from_bytes(f.read(8), "little")
            if size < 8 or n > min(size - 8, MAX_CONFIG_BYTES * 16):
                raise ValueError("its header runs past the file")
            header = json.loads(f.read(n))
        ends = [int(v["data_offsets"][1]) for k, v in header.items() if k != "__metadata__"]
        kinds = {k: v["dtype"] for k, v in header.items() if k != "__metadata__"}
    except (OSError, ValueError, KeyError, TypeError, IndexError, AttributeError) as exc:
        raise ModelError(f"{weights}: unreadable weights ({exc})") from None
    if max(ends, default=0) > size - 8 - n:
        raise ModelError(f"{weights}: unreadable weights (truncated: its tensors end past the file)")
    odd = sorted(k for k, t in kinds.items() if t not in STORED_TYPES)  # int8: a quantised float weight
    if odd:
        raise ModelError(f"{weights}: {odd[0]} is stored as {kinds[odd[0]]}, a type no model holds")
    return cfg
