"""The options of the pipelines and their choice lists, written down once.

Torch-free, so that the CLI imports them for ``--help`` without starting torch. The
pipelines import their choices from here; ``VectorizeOptions`` is validated once, where it
is made, and passed whole: CLI -> ``api.vectorize`` -> ``parallel`` -> the pipeline.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

from .errors import ConfigError

PARTS = ("clean", "model")  # `vectorize --parts`: clean outlines (default) or the model's own paths
EFFORTS = ("draft", "fast", "best")  # `vectorize --effort`: refine.EFFORTS holds the settings of each
PRESETS = ("auto", "scan", "logo", "line", "pixel", "photo")  # `vectorize --preset`: the kinds of trace.read
PRIORS = ("auto", "neighbours", "fitted", "normal")  # `sample --prior`: auto is the first of the others the model has
GROUPINGS = ("evenodd", "nonzero", "layers")  # ModelConfig.grouping: how paths make shapes
ARCHS = ("im2vec", "imagevae")  # ModelConfig.arch: the vector model, or the paper's raster baseline
FITS = ("resize", "pad")  # ModelConfig.fit: how an image smaller than the model square meets it
AUGMENTS = ("flip", "scale", "shift")  # TrainConfig.augment: the kinds it may name, comma-separated (data.augment)
GROWABLE = ("paths", "grouping", "palette", "feedback", "feedback_paths", "feedback_select", "path_passes",
            "path_pass_width", "point_passes", "point_pass_width", "point_smooth", "solve_colors",
            "solve_order")  # ModelConfig keys a fine-tune (`train --init`) may change


def parse_augment(spec: str) -> tuple[str, ...]:
    """``TrainConfig.augment`` ``"flip,shift"`` -> ``("flip", "shift")``; an unknown kind raises ``ValueError``."""
    kinds = tuple(k.strip() for k in spec.split(",") if k.strip())
    bad = [k for k in kinds if k not in AUGMENTS]
    if bad:
        raise ValueError(f"unknown augment {', '.join(bad)} (known: {', '.join(AUGMENTS)})")
    return kinds


MEMORY_DEFAULT = 2 * 2**30  # `vectorize --max-memory`: the budget of one vectorize process...
MEMORY_MIN = 768 * 2**20  # ...at least this
MAX_TEMPERATURE = 100.0  # `sample --temperature`: a latent's spread this many times the prior's is far past any picture
BASE_BYTES = 512 * 2**20  # the interpreter, torch and a model
READ_BYTES_PER_PIXEL = 16  # a picture decoded (8-bit, twice while converting) and as float
WORK_BYTES_PER_PIXEL = 256  # tracing and polishing, per pixel of the copy worked on (bench/hardening.py:
# 1.3 GB peak for a 2048^2 gradient of 16 colours)
MAX_SPECKLE = 1000  # `vectorize --filter-speckle`: px a side at most
MAX_WORK_PIXELS = 2048 * 2048  # the largest copy worked on, whatever the budget: 2048 px resolve any outline


@dataclass(frozen=True)
class VectorizeOptions:
    """How ``vectorize`` (``api.vectorize``) turns pictures into paths.

    refine: fit the paths to each picture through the renderer (``refine.refine``);
        ``False`` gives the model's guess alone, in one batch.
    effort: with ``refine``, ``"draft"`` (clean outlines traced and fitted, nothing
        polished: the quickest), ``"fast"`` or ``"best"`` (``options.EFFORTS``).
    preset: with ``parts="clean"``, what kind of picture it is (``options.PRESETS``:
        ``"scan"``, ``"logo"``, ``"line"``, ``"pixel"``, ``"photo"``; ``"auto"``, the default:
        the kind it looks like, ``trace.read``). The result's ``notes["kind"]`` says which.
    speckle: with ``parts="clean"``, pieces and holes smaller than this many px a side are
        dropped from scans and line art (default: 2 px, and 1 more per 256 px of the
        picture's longer side).
    parts: ``"clean"`` (each colour one path of non-overlapping outer contours and holes:
        with ``refine`` from the model's paths or the picture's own regions, whichever fits
        better; without, the model's guess with its seams, cracks and slivers mended,
        ``infer.clean_guess``) or ``"model"`` (the model's own overlapping paths, the same for
        every picture of its class).
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
    max_memory: the memory budget in bytes (default 2 GiB): a picture larger than it allows
        is vectorized at an area-averaged copy (``VectorizeOptions.work_pixels``, at most
        2048^2) and scaled back; the CLI refuses to read a picture it cannot hold.

    Raises ``errors.ConfigError`` (an ``Im2VecError`` and a ``ValueError``: one line, naming the field)
    when made with a value out of range.
    """

    refine: bool = True
    effort: str = "fast"
    parts: str = "clean"
    tolerance: float | None = None
    colors: int | None = None
    segments: int | str | None = None
    quality: float | None = None
    max_paths: int | None = None
    simplify_px: float | None = None
    compile: bool = False
    max_memory: int | None = None  # bytes (None: MEMORY_DEFAULT)
    preset: str = "auto"
    speckle: int | None = None  # px (None: by the picture's size, trace.read)

    def __post_init__(self) -> None:
        if self.effort not in EFFORTS:
            raise ConfigError(f"effort must be one of {list(EFFORTS)}, got {self.effort!r}")
        if self.preset not in PRESETS:
            raise ConfigError(f"preset must be one of {list(PRESETS)}, got {self.preset!r}")
        if self.speckle is not None and not (_integer(self.speckle) and 0 <= self.speckle <= MAX_SPECKLE):
            raise ConfigError(f"speckle must be an integer number of pixels in [0, {MAX_SPECKLE}], got {self.speckle!r}")
        if self.parts not in PARTS:
            raise ConfigError(f"parts must be one of {list(PARTS)}, got {self.parts!r}")
        if self.tolerance is not None and not _positive(self.tolerance):
            raise ConfigError(f"tolerance must be a positive number of pixels, got {self.tolerance!r}")
        if self.colors is not None and not (_integer(self.colors) and 1 <= self.colors <= 64):
            raise ConfigError(f"colors must be an integer in [1, 64], got {self.colors!r}")
        if self.max_paths is not None and not (_integer(self.max_paths) and self.max_paths >= 1):
            raise ConfigError(f"max_paths must be an integer >= 1, got {self.max_paths!r}")
        if self.segments is not None and self.segments != "auto" and not (_integer(self.segments)
                                                                          and self.segments >= 1):
            raise ConfigError(f"segments must be an integer >= 1 or 'auto', got {self.segments!r}")
        if self.quality is not None and not _positive(self.quality):
            raise ConfigError(f"quality must be a positive number, got {self.quality!r}")
        if self.simplify_px is not None and not (_number(self.simplify_px) and self.simplify_px >= 0):
            raise ConfigError(f"simplify_px must be a number of pixels >= 0, got {self.simplify_px!r}")
        if self.max_memory is not None and not (_integer(self.max_memory) and self.max_memory >= MEMORY_MIN):
            raise ConfigError(f"max_memory must be a number of bytes >= {MEMORY_MIN // 2**20} MiB, got {self.max_memory!r}")

    def work_pixels(self) -> int:
        """The most pixels of a picture worked on within the memory budget: a larger picture is
        vectorized at an area-averaged copy this large, then scaled back."""
        budget = (self.max_memory or MEMORY_DEFAULT) - BASE_BYTES
        return min(MAX_WORK_PIXELS, budget // WORK_BYTES_PER_PIXEL)

    def max_input_pixels(self) -> int:
        """The most pixels a picture may have to be read within the memory budget."""
        return ((self.max_memory or MEMORY_DEFAULT) - BASE_BYTES) // READ_BYTES_PER_PIXEL


def _integer(x) -> bool:
    return isinstance(x, numbers.Integral) and not isinstance(x, bool)  # numpy integers too


def _number(x) -> bool:
    return isinstance(x, numbers.Real) and not isinstance(x, bool) and math.isfinite(x)


def _positive(x) -> bool:
    return _number(x) and x > 0
