"""The options of the pipelines and their choice lists, written down once.

Torch-free, so that the CLI imports them for ``--help`` without starting torch. The
pipelines import their choices from here; ``VectorizeOptions`` is validated once, where it
is made, and passed whole: CLI -> ``api.vectorize`` -> ``parallel`` -> the pipeline.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

PARTS = ("clean", "model")  # `vectorize --parts`: clean outlines (default) or the model's own paths
EFFORTS = ("fast", "best")  # `vectorize --effort`: refine.EFFORTS holds the settings of each
PRIORS = ("auto", "fitted", "normal")  # `sample --prior`: auto is the fitted prior when the model has one
GROUPINGS = ("evenodd", "nonzero", "layers")  # ModelConfig.grouping: how paths make shapes
ARCHS = ("im2vec", "imagevae")  # ModelConfig.arch: the vector model, or the paper's raster baseline
FITS = ("resize", "pad")  # ModelConfig.fit: how an image smaller than the model square meets it
GROWABLE = ("paths", "grouping")  # ModelConfig keys a fine-tune (`train --init`) may change


MEMORY_DEFAULT = 2 * 2**30  # `vectorize --max-memory`: the budget of one vectorize process...
MEMORY_MIN = 768 * 2**20  # ...at least this
BASE_BYTES = 512 * 2**20  # the interpreter, torch and a model
READ_BYTES_PER_PIXEL = 16  # a picture decoded (8-bit, twice while converting) and as float
WORK_BYTES_PER_PIXEL = 256  # tracing and polishing, per pixel of the copy worked on (bench/hardening.py:
# 1.3 GB peak for a 2048^2 gradient of 16 colours)
MAX_WORK_PIXELS = 2048 * 2048  # the largest copy worked on, whatever the budget: 2048 px resolve any outline


@dataclass(frozen=True)
class VectorizeOptions:
    """How ``vectorize`` turns pictures into paths (``api.vectorize`` documents each field).

    Raises ``ValueError`` (one line, naming the field) when made with a value out of range.
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

    def __post_init__(self) -> None:
        if self.effort not in EFFORTS:
            raise ValueError(f"effort must be one of {list(EFFORTS)}, got {self.effort!r}")
        if self.parts not in PARTS:
            raise ValueError(f"parts must be one of {list(PARTS)}, got {self.parts!r}")
        if self.tolerance is not None and not _positive(self.tolerance):
            raise ValueError(f"tolerance must be a positive number of pixels, got {self.tolerance!r}")
        if self.colors is not None and not (_integer(self.colors) and 1 <= self.colors <= 64):
            raise ValueError(f"colors must be an integer in [1, 64], got {self.colors!r}")
        if self.max_paths is not None and not (_integer(self.max_paths) and self.max_paths >= 1):
            raise ValueError(f"max_paths must be an integer >= 1, got {self.max_paths!r}")
        if self.segments is not None and self.segments != "auto" and not (_integer(self.segments)
                                                                          and self.segments >= 1):
            raise ValueError(f"segments must be an integer >= 1 or 'auto', got {self.segments!r}")
        if self.quality is not None and not _positive(self.quality):
            raise ValueError(f"quality must be a positive number, got {self.quality!r}")
        if self.simplify_px is not None and not (_number(self.simplify_px) and self.simplify_px >= 0):
            raise ValueError(f"simplify_px must be a number of pixels >= 0, got {self.simplify_px!r}")
        if self.max_memory is not None and not (_integer(self.max_memory) and self.max_memory >= MEMORY_MIN):
            raise ValueError(f"max_memory must be a number of bytes >= {MEMORY_MIN // 2**20} MiB, got {self.max_memory!r}")

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
