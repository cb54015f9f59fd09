"""The options of the pipelines and their choice lists, written down once.

Torch-free, so that the CLI imports them for ``--help`` without starting torch. The
pipelines import their choices from here. ``VectorizeOptions`` (what the user chose) is
validated once, where it is made; ``VectorizeOptions.resolve()`` turns it into one ``Plan``
(every setting of the run, each default written once, here) that every stage reads from:
CLI -> ``VectorizeOptions`` -> ``Plan`` -> ``trace`` / ``refine`` -> the function that acts.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

from .errors import ConfigError

PARTS = ("clean", "model")  # `vectorize --parts`: clean outlines (default) or the model's own paths
EFFORTS = ("draft", "fast", "best")  # `vectorize --effort`: EFFORT_SETTINGS holds the settings of each
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
MAX_GROW = 256  # `vectorize --grow`: paths at most (each one more shape in every step of the polish)
GROW = 32  # paths grown at most by default (``refine.grow``): a face's parts and a flag's stars, not a photo's pieces
MAX_WORK_PIXELS = 2048 * 2048  # the largest copy worked on, whatever the budget: 2048 px resolve any outline...
MAX_BILEVEL_PIXELS = 4096 * 4096  # ...but a picture of exactly two colours (a 1-bit scan: a 300 dpi page is 2550 x 3300)
# is traced whole up to this: an averaged copy blurs its pixel edges (issue 69: a typewritten page's MSE 0.0053 at
# the copy, 0.0013 whole; potrace 0.0029), and it is never polished (options.Plan.max_side)
BILEVEL_BYTES_PER_PIXEL = 128  # tracing a two-colour picture, per pixel (bench/hardening.py's 1-bit page: 911-959 MiB
# peak at 8.4 MP, the process included)


@dataclass(frozen=True)
class Plan:
    """Every setting of one ``vectorize`` run, resolved (``VectorizeOptions.resolve``): the user's
    choices, and the settings of the effort they chose (``EFFORT_SETTINGS``; ``Plan()`` itself is the
    most thorough refinement). The stages read what they need from it: ``trace`` the outline
    fields, ``refine`` the optimisation's."""

    # what to make (``VectorizeOptions`` describes each)
    refine: bool = True
    parts: str = "clean"
    colors: int | None = None  # a multi-colour picture's palette size (None: as its flat areas need, <= 16)
    max_paths: int | None = None
    segments: int | str | None = None  # per path (None: the model's; "auto": its segment predictor)
    quality: float | None = None
    compile: bool = False
    preset: str | None = None  # the kind of picture (None: the kind it looks like, ``trace.read``)
    speckle: int | None = None  # px (None: by the picture's size, ``trace.read``)
    work_pixels: int = MAX_WORK_PIXELS  # a larger picture is vectorized at an area-averaged copy this large...
    bilevel_pixels: int = min(MAX_BILEVEL_PIXELS, (MEMORY_DEFAULT - BASE_BYTES) // BILEVEL_BYTES_PER_PIXEL)  # ...and
    # one of exactly two colours at a copy this large
    # the optimisation (``refine``)
    passes: bool | None = None  # refinement's start drawn through the model's picture door (``Im2Vec.decode``
    # with the picture: its path and point passes, colours solved: what --no-refine draws) rather than from the
    # latent alone (the latent door), once the latent stage has run. None: the picture door for a model of one
    # shape (fonts, mnist, icons: --parts model on 620 held-out glyphs IoU@4x 0.9854 -> 0.9863, cracks 3.1% ->
    # 1.5%; 120 Font Awesome icons 0.9715 -> 0.9818, cracks 33.3% -> 11.7%, bench/outlines.py), the latent door
    # for a model of layers (emoji: 120 OpenMoji faces MSE 0.01867 -> 0.01435 but cracks 25% -> 45%)
    latent_steps: int = 10
    point_steps: int = 50
    latent_lr: float = 0.05
    point_lr: float = 1.5e-3  # normalised units per Adam step (0.1 px on a 64 px image)
    color_lr: float = 0.02
    tau_start: float = 0.8  # edge softness in input pixels, annealed during the point stage...
    tau_end: float = 0.3  # ...to about a box filter's slope, which is what cairo and the input show
    levels: int = 1  # the full-resolution L2 only. Coarse levels rendered sharp against a blurred target
    # pulled the outline off the edges (IoU@4x 0.921 with 3 levels vs 0.972 with 1, bench/vectorize.py); the
    # blurred pyramid (render_pyramid's default) neither helps nor hurts (0.9888 vs 0.9891, 12 fonts test glyphs)
    max_side: int = 128  # larger inputs are fitted at this size (then scaled back: the frame is normalised);
    # a clean outline of a larger picture is not polished: fitted within tolerance of the full-size picture,
    # it is finer than a pixel at this size (on 400-600 px pictures polishing made things worse: MSE 0.00056
    # polished against 0.00036 not on logos, 0.00131 against 0.00071 on scans, bench/realworld.py)
    patience: int = 12  # stop when the loss has not improved by min_improvement in this many steps
    min_improvement: float = 2e-3
    margin: float = 0.02  # control points may leave the canvas by this much (normalised) before a penalty
    bounds_weight: float = 10.0
    min_segment_px: float = 0.5  # segments shorter than this are pushed apart (collapsed-segment guard)
    collapse_weight: float = 1e-3
    grow: int = GROW  # (<= MAX_GROW) --parts model: at most this many paths of the picture's own pieces added
    # where the fitted paths miss them (``refine.grow``; 0: none)
    prune_tol: float = 0.01  # drop a path whose removal raises the loss by less than this fraction
    simplify_tol: float = 0.25  # after fitting, merge segments while the outline moves less than this (input px)
    polish_steps: int = 40  # points-only steps after simplifying
    polish_samples: int = 12  # lines per cubic in the polish: merged segments are long, and too coarse a
    # polygon lets the fit bend the true curve away from the edge (IoU@4x 0.972 with the model's 4)
    # clean outlines (``refine.clean.clean_outlines``)
    tolerance: float = 0.5  # cubics fitted within this many input px of the traced/united ring
    outline_steps: int = 40  # points and colours polished against the input, colours then solved (0: none)...
    outline_tau: float = 0.3  # ...from this edge softness, annealed to tau_end
    split_error: float = 0.01  # then segments along which the render is still this wrong (MSE) are halved and
    # the polish repeated (0: never)
    max_segments: int = 200  # per contour, splitting stops here
    polish_segments: int = 4000  # an outline of more segments is not polished: each step would render them all,
    # at the fit size (128 px) where a picture of that many is finer than a pixel; it is fitted within tolerance
    model_start: bool = True  # clean outlines of a two-tone image: also start from the model's paths (redrawn
    # clean), keep the better start. On 40 held-out glyphs and 40 icons it changed IoU@4x by -0.0005 and 0.0000
    # at twice the time (bench/outlines.py), so the fast effort traces the image alone

    @property
    def polish(self) -> bool:
        """Whether clean outlines are polished through the renderer at all (not ``--effort draft``)."""
        return self.outline_steps > 0


# Named efforts (`vectorize --effort`): each ``Plan``'s fields that differ from ``Plan()``.
# "best" is ``Plan()`` with a finer split; "fast" takes about a third of the steps and a coarser
# polish polygon: on 62 held-out Liberation Sans Narrow glyphs at 64 px (fonts model) IoU@4x
# 0.9855 and MSE 0.00051 in 0.26 s per glyph, against 0.9913, 0.00022 and 0.79 s (on all 248
# glyphs, `make bench-vectorize`: 0.9867 / 0.00036 in 0.44 s against 0.9914 / 0.00018 in 1.01 s;
# potrace 0.9524 / 0.00283), so that one `vectorize` fits in about 2 s with torch's import.
EFFORT_SETTINGS = {  # in the order of EFFORTS
    "draft": {"latent_steps": 0, "point_steps": 0, "polish_steps": 0, "outline_steps": 0, "split_error": 0.0,
              "model_start": False},  # clean outlines traced and fitted, not polished
    "fast": {"latent_steps": 5, "point_steps": 25, "polish_steps": 15, "polish_samples": 8, "outline_steps": 25,
             "model_start": False},
    "best": {"split_error": 0.005},
}


def effort_plan(effort: str, **fields) -> Plan:
    """The ``Plan`` of a named effort (``EFFORTS``), with ``fields`` set too."""
    return Plan(**{**EFFORT_SETTINGS[effort], **fields})


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
    grow: with ``parts="model"`` and ``refine``, at most this many paths added on top of the model's where its
        fitted paths miss a part of the picture (an eye, a dot, a hole), each one piece of the picture's own regions
        (``refine.grow``; default 32; 0: the model's paths alone).
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
    grow: int | None = None  # paths (None: Plan.grow)
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
        if self.grow is not None and not (_integer(self.grow) and 0 <= self.grow <= MAX_GROW):
            raise ConfigError(f"grow must be an integer number of paths in [0, {MAX_GROW}], got {self.grow!r}")
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
        return min(MAX_WORK_PIXELS, self._budget() // WORK_BYTES_PER_PIXEL)

    def bilevel_pixels(self) -> int:
        """``work_pixels`` of a picture of exactly two colours (traced, never polished: cheaper by the pixel)."""
        return max(self.work_pixels(), min(MAX_BILEVEL_PIXELS, self._budget() // BILEVEL_BYTES_PER_PIXEL))

    def max_input_pixels(self) -> int:
        """The most pixels a picture may have to be read within the memory budget."""
        return self._budget() // READ_BYTES_PER_PIXEL

    def _budget(self) -> int:
        """Bytes of the memory budget left for pictures: ``max_memory`` less the interpreter, torch and a model."""
        return (self.max_memory or MEMORY_DEFAULT) - BASE_BYTES

    def resolve(self) -> Plan:
        """The run's ``Plan``: the effort's settings with these choices applied (a ``tolerance`` or
        ``simplify_px`` given replaces the effort's; without refinement nothing is simplified
        unless ``simplify_px`` says so)."""
        fields = dict(EFFORT_SETTINGS[self.effort])
        if self.tolerance is not None:
            fields["tolerance"] = float(self.tolerance)
        if self.simplify_px is not None or not self.refine:
            fields["simplify_tol"] = float(self.simplify_px or 0.0)
        if self.grow is not None:
            fields["grow"] = int(self.grow)
        return Plan(refine=self.refine, parts=self.parts, colors=self.colors, max_paths=self.max_paths,
                    segments=self.segments, quality=self.quality, compile=self.compile,
                    preset=None if self.preset == "auto" else self.preset, speckle=self.speckle,
                    work_pixels=self.work_pixels(), bilevel_pixels=self.bilevel_pixels(), **fields)

    def idle(self, given: set[str]) -> list[str]:
        """Of the fields named in ``given`` (those the user set), a note for each that does nothing
        in the mode chosen (``IDLE``): ``"tolerance does nothing here: ..."``."""
        return [f"{name} does nothing here: {why}" for name, (acts, why) in IDLE.items()
                if name in given and not acts(self)]


# field -> (when it acts, given the options; when it does not, why): a field set that does nothing in
# the mode chosen gets a note (the API warns, the CLI prints it), not silence
_CLEAN_REFINED = (lambda o: o.refine and o.parts == "clean", "it shapes clean parts with refinement")
IDLE = {
    "tolerance": _CLEAN_REFINED, "colors": _CLEAN_REFINED, "preset": _CLEAN_REFINED, "speckle": _CLEAN_REFINED,
    "effort": (lambda o: o.refine, "it sets how hard refinement works, and without refinement there is none"),
    "compile": (lambda o: o.refine, "it compiles the refinement, and without refinement there is none"),
    "quality": (lambda o: o.segments == "auto", "it sets segments='auto''s choice"),
    "grow": (lambda o: o.refine and o.parts == "model", "it adds paths to the model's fitted ones (--parts model)"),
}


def fixed_on_init(given: dict, start: dict) -> list[str]:
    """The model fields of ``given`` that a fine-tune (``train --init``) cannot change: those not
    ``GROWABLE`` whose value differs from the starting model's config ``start`` (sorted)."""
    return sorted(k for k in given if k not in GROWABLE and given[k] != start.get(k))


def _integer(x) -> bool:
    return isinstance(x, numbers.Integral) and not isinstance(x, bool)  # numpy integers too


def _number(x) -> bool:
    return isinstance(x, numbers.Real) and not isinstance(x, bool) and math.isfinite(x)


def _positive(x) -> bool:
    return _number(x) and x > 0
