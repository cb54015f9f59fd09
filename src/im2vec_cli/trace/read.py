"""Read a picture as a person would before tracing it: what kind of picture it is, and the clean picture it shows.

- **pixel**: pixel art: exact colours, blocks of ``block`` px (nearest-neighbour upscaling); the picture is read at
  one pixel a block and traced along its pixel edges;
- **scan**: a scan or phone photo of ink on light paper: its uneven light flattened (a smooth surface fitted to the
  paper, divided out), noise and JPEG ringing smoothed away, read as ink on white paper (black-looking ink black);
- **line**: a two-tone drawing of thin (1-3 px) strokes, traced at half each stroke's own darkness (``half_max``), so
  strokes thinner than a pixel stay whole; a scan's and line art's pieces and holes under ``speckle``^2 px dropped;
- **logo**: flat colours (glyphs, icons, logos, emoji), JPEG ringing smoothed first; a small icon that looks two-tone
  by its palette where its tints are fills of their own (``photo.tints_agree_better``);
- **photo**: a continuous-tone picture, lightly smoothed (``PHOTO_SIGMA``) and cut into pieces of one fine colour
  step (``photo.pieces``), none smaller than ``speckle``^2 px but a render's marks (text, dots).

Pixel art and photos are not polished (exact; too many segments), nor a picture over ``options.Plan.max_side``.
Frame: ``(H, W, 3)`` floats in [0, 1].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..options import PRESETS
from .ndops import gaussian, mean3, norm3, rgb_keys, spread3
from .palette import MAX_HARD_COLORS, hard_palette
from .photo import MARK_GRAINY, MARK_RENDERED, PHOTO_SIGMA, agrees_better, looks_like_a_photo, tints_agree_better
from .regions import background_color, two_tone

KINDS = PRESETS[1:]  # the kinds of picture: options.PRESETS but "auto"
NOISE = 0.012  # noise sigma (``noise_sigma``) above which a picture is read as noisy
UNEVEN = 0.06  # a paper whose fitted brightness varies by more than this is unevenly lit
GRAIN = 0.001  # a scan or a photo of paper has at least this much noise; a rendered picture has none
OFF_LINE = 0.15  # a flattened pixel this far (RGB) from the paper-ink line is another colour...
OFF_SHARE = 0.05  # ...and a picture with more than this share of them is no ink on paper (scans: under 0.3%,
# photographed scribbles 3%, OpenMoji faces with a dark outline 12-24%: bench/realworld.py, bench/hardening.py)
THIN = 3.5  # px: strokes at most this wide (median) make line art
PHOTO_SPECK = 4  # px a side: a photo's smallest piece unless --filter-speckle says (as vtracer's default), but
# marks (``photo.MARK_PX``: text, dots) that stand out of all they touch by more than grain could make them
PIXEL_EDGES = 0.08  # native pixel art (no upscaling found) has at least this share of its pixels on a colour edge (its
# pixels are its features: 0.3-0.9 on sprites); a hard-edged drawing of large shapes, its curves aliased, has far
# fewer (flat circles at 384-512 px: 0.02-0.05) and is traced with smooth curves as a logo
PIXEL_SIDE = 64  # a hard-edged picture this small is pixel art whatever its edges
THICK_SHARE = 0.8  # ...and so is one with a colour (of THIN_MIN pixels or more) that a 3x3 erosion keeps less of:
THIN_MIN = 4  # 1 px lines keep 0-0.06, the Shepp-Logan phantom's 2-4 px ring 0.74, flat circles 0.84-0.96
INK_PERCENTILE = 1  # thin strokes' ink: this percentile of the dark side (``ink_coverage(sharp=True)``)
STROKE_LEVEL = 0.8  # a scanned thin stroke, blurred (sigma s), keeps its width at about 0.8 of its peak p
# (a Gaussian profile: p * exp(-0.78 p^2)); at half its peak, scanned text came out 15-50% bold (issue 69)
FRINGE_CHROMA, FRINGE_STEP, FRINGE_EDGE = 0.1, 0.15, 0.9  # sub-pixel text: colourful pixels (channel spread),
# nearly all of them within 2 px of a change in brightness along the row (``subpixel_grey``)
SHADED = 0.02  # ink on paper has at most this share of in-between shades (``shaded_share``)
BLACK_INK = 0.35  # ink of a scan darker than this (mean channel, after flattening) and ...
NEUTRAL_INK = 0.12  # ... less colourful than this (channel spread) is black ink
PAPER_LIGHT, INK_AT_MOST = (0.15, 0.5), 0.9  # a page as shot: paper's 5th percentile, median; ink's largest share


@dataclass(frozen=True)
class Reading:
    """What a picture is (``kind``, one of ``KINDS``) and the clean ``picture (H', W', 3)`` to
    trace: the input's size, or for pixel art its block (``figures["block"]``) times smaller.
    ``polish``: whether the outline is worth polishing against the picture. ``figures``: what the
    reading measured. ``tone``: a two-tone picture's ink and its coverage (``regions.two_tone``),
    found once. ``speck``: a photo's smallest piece, ``marks`` how much a smaller mark stands out."""

    kind: str
    picture: np.ndarray
    polish: bool = True
    figures: dict | None = None
    tone: tuple[np.ndarray, np.ndarray] | None = None  # a two-tone picture's (ink (3,), coverage (H', W'))
    speck: int = 0  # px (``photo.pieces``)
    marks: float = 0.0  # lightness by which a photo's marks smaller than ``speck`` stand out (``photo.pieces``)
    palette: bool = False  # traced by its palette though it looks two-tone (``photo.tints_agree_better``)


def read(picture: np.ndarray, preset: str | None = None, speckle: int | None = None, colors: int | None = None
         ) -> Reading:
    """The reading of ``picture (H, W, 3)`` in [0, 1]: of the kind ``preset`` (one of ``KINDS``) or, with ``None``, of
    the kind it looks like. ``speckle``: pieces smaller than this many px a side are dropped from scans and line art
    (``None``: 2 px, and 1 px more per 256 px of the longer side) and merged into their neighbours in a photo
    (``None``: that, at least ``PHOTO_SPECK``, but marks down to ``photo.MARK_PX``). ``colors``
    (``--colors``): a drawing is read as a logo of that palette."""
    h, w, _ = picture.shape
    speck = max(2, 2 + max(h, w) // 256) if speckle is None else speckle
    block = pixel_block(picture) if preset in (None, "pixel") else 1
    palette = hard_palette(picture) if preset is None and block == 1 else None
    hard = palette is not None
    if preset == "pixel" or (preset is None and block > 1) or (hard and _native_pixel_art(picture, palette[1])):
        small = picture[::block, ::block] if block > 1 else picture
        return Reading("pixel", small, polish=False, figures={"block": block})
    if hard:  # a large hard-edged drawing: its exact colours, outlined with curves (``regions.trace``)
        return Reading("logo", picture, figures={"aliased": True})
    bg = background_color(picture)
    tone = two_tone(picture, bg) if preset in (None, "line", "logo") else None
    if tone is None and preset in (None, "line", "logo"):  # text drawn with sub-pixel anti-aliasing (a
        grey = subpixel_grey(picture)  # screenshot's): colour fringes on the sides of the strokes, read as grey
        tone = two_tone(grey, bg) if grey is not None else None
        picture = grey if tone is not None else picture
    if preset is None and tone is not None and background_spread(picture, tone[1]) > UNEVEN:
        tone = None  # shaded paper: a scan whose light falls along the ink's colour line, not a clean picture
    tinted = preset is None and tone is not None and tints_agree_better(picture, bg, *tone)  # a small icon's fills
    if preset is None and tone is not None and not tinted:
        width = stroke_width(tone[1] >= 0.5)
        kind = "line" if width <= THIN else "logo"
        return Reading(kind, picture, figures={"stroke": round(width, 2)},
                       tone=(tone[0], half_max(tone[1])) if kind == "line" else tone)
    if preset in ("line", "logo") and tone is not None:
        return Reading(preset, picture, tone=(tone[0], half_max(tone[1])) if preset == "line" else tone)
    noise = noise_sigma(picture) if max(h, w) > PIXEL_SIDE else 0.0  # a small icon's detail is no noise
    figures = {"noise": round(noise, 4)}
    if preset in ("scan", "line") or (preset is None and noise > GRAIN):  # a rendered picture has no paper to flatten
        flat, light = flattened(picture)
        figures["light"] = round(light, 3)
        if preset is not None or noise > NOISE or light > UNEVEN:
            lum = smoothed(mean3(flat), noise)
            ink, alpha = ink_coverage(flat, lum)
            if preset is not None or (_is_two_tone(flat, ink, picture, alpha) and shaded_share(alpha) <= SHADED):
                # read at the darkest ink, where thin strokes keep their weight (not needed for a forced scan)
                thin = None if preset == "scan" else ink_coverage(flat, lum, sharp=True)
                kind = preset or ("line" if stroke_width(thin[1] >= 0.5) <= THIN else "scan")
                if kind == "line":
                    ink, alpha = thin
                alpha, ink = despeckled(alpha, speck), _ink_color(ink)
                clean = 1 - alpha[..., None] * (1 - ink)
                if kind == "line":
                    alpha = half_max(alpha, level=STROKE_LEVEL)
                return Reading(kind, clean, figures=figures, tone=(ink, alpha) if alpha.max() >= 0.1 else None)
    piece = max(speck, PHOTO_SPECK) ** 2 if speckle is None else speckle**2
    mark = (MARK_RENDERED if noise <= GRAIN else MARK_GRAINY) if speckle is None else 0.0  # text, dots
    if preset == "photo" or (preset is None and looks_like_a_photo(picture)):
        return _photo(picture, figures, piece, mark)
    judge = preset is None and colors is None and not hard  # (a large drawing on a window: ``busiest_window``)
    return _logo_or_photo(picture, noise, figures, piece, mark, judge, tinted)


def _logo_or_photo(picture: np.ndarray, noise: float, figures: dict, piece: int, mark: float, judge: bool,
                   tinted: bool = False) -> Reading:
    """A drawing read as a logo or, ``judge``-d so, as a photo where its pieces draw it closer (``photo.agrees_better``,
    on the picture cast through float32 as ``batch.read_pictures`` casts it: the trace finds the palette kept).
    ``tinted``: it looks two-tone, but its tints are fills of their own (``photo.tints_agree_better``)."""
    logo = smoothed(picture, noise) if noise > NOISE else picture
    if judge:
        better, agreement = agrees_better(logo.astype(np.float32).astype(np.float64), piece, mark)
        figures.update(agreement)
        if better:
            return _photo(picture, figures, piece, mark)
    return Reading("logo", logo, figures=figures, palette=tinted)


def _photo(picture: np.ndarray, figures: dict, piece: int, mark: float) -> Reading:  # ``Reading.speck``, ``marks``
    return Reading("photo", gaussian(picture, PHOTO_SIGMA), polish=False, figures=figures, speck=piece, marks=mark)


def shaded_share(alpha: np.ndarray) -> float:
    """The share of pixels of ``alpha (H, W)`` (a reading as ink on paper) neither ink nor paper (0.15-0.85) in a
    steady 3x3 neighbourhood (spread under 0.1): areas of an in-between shade. A scan's in-between pixels are its
    strokes' edges (real scans and pages: at most 0.002); a shaded icon's grey body is one (Oxygen's: 0.07-0.09)."""
    from .ndops import extreme3

    spread = extreme3(alpha[..., None], True)[..., 0] - extreme3(alpha[..., None], False)[..., 0]
    return float(((alpha > 0.15) & (alpha < 0.85) & (spread < 0.1)).mean())


def subpixel_grey(picture: np.ndarray) -> np.ndarray | None:
    """``picture (H, W, 3)`` as grey when its colours are sub-pixel anti-aliasing's (ClearType,
    FreeType's LCD filter: text in a screenshot): colour only on the sides of dark strokes, at
    least ``FRINGE_EDGE`` of its colourful pixels where the brightness changes along the row;
    else ``None`` (a colour picture: colour in its flat areas too)."""
    if max(picture.shape[:2]) <= PIXEL_SIDE:  # a small icon is all edges: its colours are its own
        return None
    chroma = spread3(picture)
    colourful = chroma > FRINGE_CHROMA
    if not colourful.any():
        return None
    lum = mean3(picture)
    p = np.pad(lum, ((0, 0), (2, 2)), mode="edge")
    across = np.maximum(np.abs(p[:, 3:-1] - p[:, 1:-3]), np.abs(p[:, 4:] - p[:, :-4]))  # within 2 px along the row
    if (across[colourful] > FRINGE_STEP).mean() < FRINGE_EDGE:
        return None
    return np.repeat(lum[..., None], 3, -1)


def _native_pixel_art(picture: np.ndarray, labels: np.ndarray) -> bool:
    """Whether a hard-edged picture (``hard_palette``: its colours ``labels (H, W)``) without
    upscaled blocks is pixel art: small, made of pixel-sized features (``PIXEL_EDGES``), or with
    a colour drawn in lines a pixel or two wide (a diagram's outlines, a UI's strokes: drawn as
    curves they would thin to hairlines or vanish), all of which its pixel edges trace exactly.
    A large hard-edged drawing of thick shapes is not: traced along its pixel edges it is a
    staircase of thousands of segments."""
    if max(picture.shape[:2]) <= PIXEL_SIDE or edge_share(picture) >= PIXEL_EDGES:
        return True
    from .ndops import erode

    for k in range(int(labels.max()) + 1):
        mask = labels == k
        n = int(mask.sum())
        if n >= THIN_MIN and erode(mask).sum() < THICK_SHARE * n:
            return True  # most of this colour is within a pixel of another: lines, not shapes
    return False


def edge_share(picture: np.ndarray) -> float:
    """The share of the pixels of ``picture (H, W, 3)`` whose 8-bit colour differs from the one above or left."""
    keys = rgb_keys(np.round(picture * 255).astype(np.int64))
    edge = np.zeros(keys.shape, dtype=bool)
    edge[1:] |= keys[1:] != keys[:-1]
    edge[:, 1:] |= keys[:, 1:] != keys[:, :-1]
    return float(edge.mean())


def background_spread(picture: np.ndarray, alpha: np.ndarray) -> float:
    """How much the brightness of a two-tone picture's background (no coverage: its edges' soft
    pixels left out) varies: the range of its middle 95%. Nil for a clean render; a scan's
    shaded paper, all on the paper-ink line, spreads by a tenth or more where it is brighter
    than its commonest shade at the border (coverage clipped to 0)."""
    step = max(1, max(alpha.shape) // 256)
    lum = mean3(picture[::step, ::step])[alpha[::step, ::step] <= 0.01]
    if len(lum) < 16:
        return 0.0
    lo, hi = np.percentile(lum, [2.5, 97.5])
    return float(hi - lo)


def pixel_block(picture: np.ndarray) -> int:
    """The side of the blocks of one colour a nearest-neighbour upscaled picture is made of
    (aligned with its top-left corner, dividing its sides; 1 when there are none): the
    greatest common divisor of the rows and columns at which the colours change."""
    h, w, _ = picture.shape
    sample = np.round(picture[:: max(1, h // 64), :: max(1, w // 64)] * 255).astype(np.int64)
    if len(np.unique(rgb_keys(sample))) > MAX_HARD_COLORS:
        return 1  # more colours than pixel art has (most pictures: a sample says so)
    q = np.round(picture * 255).astype(np.uint8)
    rows = np.nonzero((q[1:] != q[:-1]).any((1, 2)))[0] + 1
    cols = np.nonzero((q[:, 1:] != q[:, :-1]).any((0, 2)))[0] + 1
    if len(rows) == 0 and len(cols) == 0:
        return 1
    block = int(np.gcd.reduce(np.concatenate([rows, cols, [h, w]])))
    if block < 2 or len(np.unique(rgb_keys(q[::block, ::block].astype(np.int64)))) > MAX_HARD_COLORS:
        return 1
    return block


def noise_sigma(picture: np.ndarray) -> float:
    """The picture's noise (standard deviation, in [0, 1] units), Immerkaer's estimate made
    robust: the median absolute response to the 3x3 mask that cancels smooth shading (edges,
    a few pixels, do not move the median), on a copy of at most 512 px a side."""
    from .ndops import convolve

    h, w, _ = picture.shape
    y0, x0 = (h - min(h, 512)) // 2, (w - min(w, 512)) // 2
    gray = mean3(picture[y0 : y0 + 512, x0 : x0 + 512])
    mask = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], dtype=np.float64)
    r = convolve(gray, mask)[1:-1, 1:-1]
    return float(1.4826 * np.median(np.abs(r)) / 6 * np.sqrt(3))  # grey is the mean of 3 channels


SURFACE_DEGREE = 3  # the paper's light: a polynomial surface of this degree in x and y
SURFACE_SIDE = 96  # fitted on a copy this small


def flattened(picture: np.ndarray) -> tuple[np.ndarray, float]:
    """``(picture with the paper's light divided out, the light's range)``: the paper (the
    brighter side of Otsu's threshold, refined twice against the flattened picture) fitted per
    channel by a smooth polynomial surface; the paper of the result is white."""
    from .ndops import otsu as threshold_otsu

    h, w, _ = picture.shape
    step = max(1, max(h, w) // SURFACE_SIDE)
    sh, sw = h // step, w // step
    small = picture[: sh * step, : sw * step].reshape(sh, step, sw, step, 3).mean((1, 3))  # block means
    ys, xs = (np.arange(sh) + 0.5) * step / h, (np.arange(sw) + 0.5) * step / w
    basis = _basis(np.tile(xs, sh), np.repeat(ys, sw))  # (N, B)
    flat_small = small.reshape(-1, 3)
    lum = mean3(flat_small)
    paper, coef = lum > threshold_otsu(lum), None
    for _ in range(3):
        if paper.sum() < basis.shape[1] * 4:
            break
        a = basis[paper]  # least squares by the normal equations: B x B, B = 10
        coef = np.linalg.solve(a.T @ a + 1e-9 * np.eye(a.shape[1]), a.T @ flat_small[paper])  # (B, 3)
        light = np.clip(basis @ coef, 0.05, None)  # (N, 3)
        flat_lum = mean3(flat_small / light)
        paper = flat_lum > threshold_otsu(flat_lum)
    if coef is None:
        return picture, 0.0  # too little paper to fit its light: as it is
    full = _surface(coef, (np.arange(w) + 0.5) / w, (np.arange(h) + 0.5) / h)  # (H, W, 3)
    spread = float(np.ptp(mean3(light)))
    return np.clip(picture / np.clip(full, 0.05, None), 0, 1), spread


def _basis(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    return np.stack([x**i * y**j for i, j in _POWERS], -1)


_POWERS = [(i, j) for i in range(SURFACE_DEGREE + 1) for j in range(SURFACE_DEGREE + 1 - i)]


def _surface(coef: np.ndarray, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """The polynomials ``coef (B, 3)`` over the grid ``ys x xs``: ``Y C X^T`` per channel, with
    ``C[j, i]`` the coefficient of ``x^i y^j`` (no ``(H*W, B)`` basis)."""
    n = SURFACE_DEGREE + 1
    out = []
    for c in range(coef.shape[1]):
        grid = np.zeros((n, n))
        for (i, j), v in zip(_POWERS, coef[:, c]):
            grid[j, i] = v
        out.append(np.vander(ys, n, increasing=True) @ grid @ np.vander(xs, n, increasing=True).T)
    return np.stack(out, -1)


def smoothed(picture: np.ndarray, noise: float) -> np.ndarray:
    """``picture`` (``(H, W)`` or ``(H, W, 3)``) with noise of ``noise`` sigma and JPEG ringing
    smoothed away, edges kept: a 3x3 median (specks, ringing), then a Gaussian as wide as the
    noise asks."""
    from .ndops import median3

    return gaussian(median3(picture), min(1.5, 0.5 + 25 * noise))


def ink_coverage(picture: np.ndarray, lum: np.ndarray, sharp: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """``(ink colour (3,), coverage (H, W))`` of a picture of ink on white paper, from its
    (smoothed) brightness ``lum (H, W)``: the coverage is each pixel's place between the paper's
    and the ink's typical brightness (the medians of either side of Otsu's threshold), clipped
    to [0, 1]; the ink's colour is the mean of the fully covered pixels of ``picture``. ``sharp``:
    the ink's brightness is the ``INK_PERCENTILE`` of the dark side of ``picture`` (3x3 median)
    instead, for thin strokes, which blurring keeps from ever reaching the ink's median."""
    from .ndops import otsu as threshold_otsu

    step = (max(1, lum.shape[0] // 256), max(1, lum.shape[1] // 256))
    sample = lum[:: step[0], :: step[1]]
    t = threshold_otsu(sample)
    dark, light = sample[sample <= t], sample[sample > t]
    if sharp:  # the ink's level before smoothing thinned the strokes: the darkest of the dark side
        from .ndops import median3

        dark = median3(mean3(picture))[:: step[0], :: step[1]]
        dark = dark[dark <= t]
    ink_l = float(np.percentile(dark, INK_PERCENTILE if sharp else 50)) if len(dark) else 0.0
    paper_l = float(np.median(light)) if len(light) else 1.0
    alpha = np.clip((paper_l - lum) / max(paper_l - ink_l, 1e-3), 0, 1)
    full = alpha >= 0.9
    ink = picture[full].mean(0) if full.any() else np.zeros(3)
    return ink, alpha


def _is_two_tone(flat: np.ndarray, ink: np.ndarray, picture: np.ndarray, alpha: np.ndarray) -> bool:
    """Whether the flattened picture is ink on paper: the ink's colour explains its dark pixels
    (few pixels far from the paper-ink line, each pixel's coverage read from its own, unsmoothed brightness),
    the ink stands out of the paper, and the paper of ``picture`` (where ``alpha``, the coverage, is under 0.5)
    is light and shows (``PAPER_LIGHT``, ``INK_AT_MOST``; a bold scanned icon is 60-70% ink): a dim photo of dark
    lines (a retina's vessels), a night sky or a black-to-white gradient is no page to whiten."""
    paper, grey = alpha[::2, ::2] < 0.5, mean3(picture[::2, ::2])
    if ink.mean() > 0.75 or paper.mean() < 1 - INK_AT_MOST or (np.percentile(grey[paper], [5, 50]) < PAPER_LIGHT).any():
        return False
    sample = flat[::2, ::2]
    _, alpha = ink_coverage(sample, mean3(sample))
    off = norm3(sample - (1 - alpha[..., None] * (1 - ink)))
    return bool((off > OFF_LINE).mean() < OFF_SHARE)


def _ink_color(ink: np.ndarray) -> np.ndarray:
    """The ink as a person reads it: dark and grey is black; any other ink keeps its colour."""
    if ink.mean() < BLACK_INK and np.ptp(ink) < NEUTRAL_INK:
        return np.zeros(3)
    return ink


def half_max(alpha: np.ndarray, floor: float = 0.3, level: float = 0.5) -> np.ndarray:
    """Line art's coverage ``alpha (H, W)`` over ``2 * level`` times its local peak (3x3, at least
    ``floor``; at most 1): the 0.5 level is then at ``level`` times the stroke's own darkness, so
    a stroke thinner than a pixel, whose anti-aliased pixels never reach 0.5, is traced as a line
    about a pixel wide, not as dashes. A blurred stroke (a scan's) keeps its width at about 0.8
    of its peak (``STROKE_LEVEL``); crisp line art is traced at half of it."""
    from .ndops import extreme3

    peak = extreme3(alpha[..., None], True)[..., 0]
    return np.clip(alpha / np.minimum(1.0, 2 * level * np.maximum(peak, floor)), 0, 1)


def despeckled(alpha: np.ndarray, speck: int) -> np.ndarray:
    """``alpha (H, W)`` with ink pieces and paper holes of fewer than ``speck``^2 px removed."""
    from .ndops import remove_small

    if speck <= 1:
        return alpha
    ink = alpha >= 0.5
    keep = remove_small(ink, speck * speck - 1)  # pieces of ink, then holes, of fewer than speck^2 px
    keep = ~remove_small(~keep, speck * speck - 1)
    out = alpha.copy()
    out[ink & ~keep] = 0.0
    out[~ink & keep] = 1.0
    return out


def stroke_width(ink: np.ndarray) -> float:
    """The mean width (px) of the strokes of ``ink (H, W)``: twice its area over its perimeter
    (pixel edges between ink and paper), which is a stroke's width for strokes much longer than
    wide (``inf`` without ink)."""
    edges = int((ink[1:] != ink[:-1]).sum() + (ink[:, 1:] != ink[:, :-1]).sum())
    edges += int(ink[0].sum() + ink[-1].sum() + ink[:, 0].sum() + ink[:, -1].sum())
    return 2 * float(ink.sum()) / edges if edges else float("inf")
