"""The picture's own regions as polygons: the image-side start of ``vectorize``.

A picture is split into flat-colour *regions* drawn back to front, each a set of closed
polygons (outer boundaries and holes) that the curve fitter (``fit.py``) turns into cubics:

- **Two-tone pictures** (glyphs, digits, icons: every pixel lies between one background and
  one ink colour) give one region, the 0.5 level of the ink's coverage ``alpha`` traced with
  sub-pixel accuracy (marching squares, ``contourpy``). Holes are holes: the background
  shows through them.
- **Multi-colour pictures** (emoji) are quantised to a palette (k-means on the pixels that are
  not on an edge; edge pixels go to the nearest colour found beside them). Each connected
  piece of one colour is a region; regions are stacked by the area they enclose, largest at
  the back, and a region is extended under the regions stacked on it (its holes filled where
  upper regions cover them, and one pixel under every upper neighbour), so that no background
  shows between neighbours at any zoom.

White connected to the picture's border is the background (the canvas: transparent in the
SVG; inputs with alpha were composited over white when read). Any other background colour
becomes a full-canvas region at the back.

Frame: pixel coordinates of the input, ``x`` right and ``y`` down, pixel ``(row i, col j)`` covering ``[j, j+1] x
[i, i+1]``. Outer boundaries run clockwise on screen, holes counter-clockwise: nonzero and even-odd agree.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from ..errors import TraceError
from ..raster.curves import ring_area
from .ndops import norm3
from .palette import FLAT_BY_LEVELS, _flat_pixels, hard_palette, posterize, quantize
from .pixels import ExactOutlines

MAX_REGIONS = 10_000  # regions (or rings of a two-tone picture) traced at most: a few ms each...
MAX_PIECES = 100_000  # ...and pieces at most when --max-paths keeps only the largest of them
WHITE_TOL = 0.06  # a colour within this (max channel distance) of white is white
TWO_TONE_TOL = 0.08  # pixels this far (RGB distance) from the background-ink line break two-tone...
TWO_TONE_SHARE = 0.005  # ...when more than this share of the pixels do
GRID_KEPT = 1024  # px: contourpy's grid is kept for fields this small (a photo's pieces), 256 sizes at most (5 MB)


@dataclass
class Region:
    """One flat-colour region: ``polygons`` are closed ``(N, 2)`` pixel-frame rings (first point not repeated), outer
    boundaries clockwise, holes counter-clockwise. ``exact``: along pixel edges, the outline itself (nothing to fit)."""

    color: tuple[float, float, float]
    polygons: list[np.ndarray]
    exact: bool = False


def level_polygons(field: np.ndarray, level: float = 0.5, min_area: float = 0.5, max_rings: int | None = None
                   ) -> list[np.ndarray]:
    """Closed rings around ``field >= level`` (``(H, W)``, values at pixel centres), sub-pixel.

    The field is padded with zeros, so regions touching the border close along it. Rings
    enclosing less than ``min_area`` px^2 (specks, pin holes) are dropped. More than
    ``MAX_REGIONS`` rings (``max_rings`` given: ``MAX_PIECES``) is a ``TraceError``.
    """
    import contourpy

    h, w = field.shape
    padded = np.zeros((h + 2, w + 2))
    padded[1:-1, 1:-1] = field
    if not np.isfinite(padded).all():
        raise ValueError("level_polygons: the field must be finite")
    x, y = _grid(h + 2, w + 2) if h * w <= GRID_KEPT else _grid.__wrapped__(h + 2, w + 2)
    # contour_generator(x, y, padded, fill_type="OuterOffset") without its NaN check (0.7 s of a photo's 6,000 calls)
    gen = contourpy.SerialContourGenerator(x, y, padded, None, corner_mask=True, quad_as_tri=False,
                                           line_type=contourpy.LineType.SeparateCode,
                                           fill_type=contourpy.FillType.OuterOffset, z_interp=contourpy.ZInterp.Linear)
    polys, offsets_all = gen.filled(level, np.inf)
    _check_pieces(sum(len(o) - 1 for o in offsets_all), "outlines", max_rings, lift=False)
    rings = []
    for poly, offsets in zip(polys, offsets_all):
        for a, b in zip(offsets[:-1], offsets[1:]):
            ring = np.minimum(np.maximum(poly[a : b - 1], 0), (w, h))  # np.clip's; the last point repeats the first
            if len(ring) >= 3 and abs(float(ring_area(ring))) >= min_area:
                rings.append(ring)
    return rings


@functools.lru_cache(maxsize=256)
def _grid(h: int, w: int) -> tuple[np.ndarray, np.ndarray]:
    """The pixel centres of an ``(h, w)`` field padded by one, as contourpy takes them (shared, read-only)."""
    x, y = np.meshgrid(np.arange(w) - 0.5, np.arange(h) - 0.5)
    x.flags.writeable = y.flags.writeable = False
    return x, y


def background_color(image: np.ndarray) -> np.ndarray:
    """The most common colour of the border pixels of ``image (H, W, 3)``: ``(3,)``."""
    border = np.concatenate([image[0], image[-1], image[:, 0], image[:, -1]])  # (B, 3)
    keys = np.round(border * 31).astype(np.int64) @ np.array([1024, 32, 1])
    values, counts = np.unique(keys, return_counts=True)
    near = border[keys == values[np.argmax(counts)]]
    return near.mean(0)


def _ink_line(image: np.ndarray, bg: np.ndarray, extreme: float, d: np.ndarray | None = None
              ) -> tuple[np.ndarray, np.ndarray]:
    """The ink (mean of the pixels at least ``extreme`` of the farthest from ``bg``; ``d (H, W)``:
    each pixel's distance from ``bg``, where known) and each pixel's position ``t (H, W)`` along
    the background-ink line (0: background, 1: ink; unclipped)."""
    d = norm3(image - bg) if d is None else d  # (H, W)
    ink = image[d >= extreme * max(d.max(), 1e-6)].mean(0)
    axis = ink - bg
    return ink, ((image - bg) @ axis) / max(float(axis @ axis), 1e-12)


def _off_line(image: np.ndarray, bg: np.ndarray, ink: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Each pixel's distance from its point on the background-ink line."""
    return norm3(image - (bg + t[..., None] * (ink - bg)))


def two_tone(image: np.ndarray, bg: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """``(ink (3,), alpha (H, W))`` when every pixel mixes ``bg`` and one ink colour, else ``None``.
    (A picture of more than ``FLAT_BY_LEVELS`` pixels is tested in float32: half the memory.)"""
    if image.shape[0] * image.shape[1] > FLAT_BY_LEVELS:
        image, bg = image.astype(np.float32), bg.astype(np.float32)
    d = norm3(image - bg)
    if d.max() < 0.1:
        return None
    ink, t = _ink_line(image, bg, 0.9, d)
    limit = TWO_TONE_SHARE * t.size  # more pixels off the line than this: not two-tone. A colour picture
    if (_off_line(image[::4], bg, ink, t[::4]) > TWO_TONE_TOL).sum() > limit:  # shows it in a quarter of its rows
        return None
    off = _off_line(image, bg, ink, t)  # off the background-ink line
    alpha = np.clip(t, 0, 1).astype(np.float64)
    if (off > TWO_TONE_TOL).mean() > TWO_TONE_SHARE:
        return None
    if ((alpha > 0.15) & (alpha < 0.85) & _flat_pixels(image)).mean() > TWO_TONE_SHARE:
        return None  # flat areas of an in-between shade (a grey fill): colours of their own, not edges
    return ink, alpha


def trace(image: np.ndarray, colors: int | None = None, max_regions: int | None = None,
          seed: int = 0, kind: str = "", tone: tuple[np.ndarray, np.ndarray] | None = None,
          speck: int = 0, marks: float = 0.0, palette: bool = False) -> list[Region]:
    """The regions of ``image (H, W, 3)`` in [0, 1], back to front.

    Args:
        colors: palette size for a multi-colour picture (``None``: the fewest colours that reproduce the flat
            areas, at most 16). ``colors == 1`` treats any picture as two-tone (the ink is its darkest extreme).
        max_regions: keep this many regions at most (the largest).
        kind: what ``read.read`` read the picture as. ``"pixel"``: its exact colours traced
            along its pixel edges, whatever their number (at most ``MAX_HARD_COLORS``) or
            mixes; ``"photo"``: its pieces of one fine colour step, none under ``speck`` px but marks standing
            out by ``marks`` (``photo.pieces``), or with ``colors`` posterised to that many (``palette.posterize``).
        tone: ``two_tone(image, background_color(image))`` where it is known (``read.read``); ``palette``: none
            is sought (the picture was read as colours though it looks two-tone: ``photo.tints_agree_better``).
    """
    image = np.asarray(image, dtype=np.float64)
    bg = background_color(image)
    white = (1 - bg).max() <= WHITE_TOL  # the canvas is white: white around the picture is left to it
    pixel = kind == "pixel"
    hard = hard_palette(image, pixel) if pixel or (colors is None and kind in ("", "logo")) else None
    if hard is not None:  # exact colours: along the pixel edges, or, read as a logo (a drawing), with curves
        exact = kind != "logo"
        if max_regions is None:  # the back layer covers the canvas, unless white shows around the picture
            return _layers(*hard, white_around=white, exact=exact)
        return _with_background(bg, _stacked_regions(image, *hard, max_regions, white, exact=exact), image.shape,
                                exact=exact)
    photo = kind == "photo" and colors is None  # read as a photo: its pieces, though its blur may look two-tone
    sought = colors in (None, 1) and not (photo or palette)
    tone = None if not sought else two_tone(image, bg) if tone is None else tone
    if tone is None and colors == 1:
        ink, t = _ink_line(image, bg, 0.8)
        tone = ink, np.clip(t, 0, 1)
    if tone is not None:
        ink, alpha = tone
        alpha, faint = faint_marks(alpha, ink, bg) if kind == "logo" and colors is None else (alpha, [])
        return _with_background(bg, [Region(tuple(ink.tolist()), level_polygons(alpha)), *faint], image.shape)
    if photo:
        from .photo import pieces

        palette, labels = pieces(image, max(speck, 1), marks)
        return _with_background(bg, _stacked_regions(image, palette, labels, max_regions, white, each_one=True),
                                image.shape)
    palette, labels = posterize(image, colors, seed) if kind == "photo" else quantize(image, colors, seed)
    return _with_background(bg, _stacked_regions(image, palette, labels, max_regions, white), image.shape)


FAINT_ALPHA, FAINT_PX, FAINT_MOST = 0.1, 3, 1000  # a mark: this much ink on this many px; more faint ones: noise
FAINT_PEAK, FAINT_LEVEL = 0.75, 0.3  # a faint mark peaks under this and is traced out to this share of its peak


def faint_marks(alpha: np.ndarray, ink: np.ndarray, bg: np.ndarray) -> tuple[np.ndarray, list[Region]]:
    """The marks of a two-tone drawing whose ink coverage ``alpha (H, W)`` peaks under ``FAINT_PEAK``, of which its
    0.5 level traces a sliver or nothing (a logo's grey credit line was lost: bench/wild.py's LinuxLogo, edge F1
    0.896), each drawn in its own tone (``ink`` over ``bg`` at its peak coverage) out to ``FAINT_LEVEL`` of its
    peak: a mark a pixel thin spreads its ink thinly (out to half its peak that line came out as specks, F1 0.948;
    at 0.3, 0.999). The marks of one tone (to 0.1) are one region. Returns ``alpha`` without them, and them."""
    from .ndops import label

    lab, n = label(alpha > FAINT_ALPHA, eight=True)
    inside = lab > 0
    peak, size = np.zeros(n + 1), np.bincount(lab[inside], minlength=n + 1)  # (size[0] = 0: not a mark)
    np.maximum.at(peak, lab[inside], alpha[inside])
    faint = (peak < FAINT_PEAK) & (size >= FAINT_PX)
    if not faint.any() or faint.sum() > FAINT_MOST:  # (grain, not marks: drawn as before, and the bound kept)
        return alpha, []
    tone, out = np.round(peak * 10), []
    for t in np.unique(tone[faint]):
        keep = faint & (tone == t)
        field = np.where(keep[lab], alpha / np.maximum(2 * FAINT_LEVEL * peak[lab], FAINT_ALPHA), 0.0)
        out.append(Region(tuple((bg + peak[keep].mean() * (ink - bg)).tolist()), level_polygons(field)))
    return np.where(faint[lab], 0.0, alpha), out


ALIAS_SIGMA = 0.7  # px: the blur of a hard-edged drawing's layer masks whose 0.5 level is the curve its staircase draws
TUCK = 2  # px: how far a layer of such a drawing stays inside the outline it shares with the layers over it


def _layers(palette: np.ndarray, labels: np.ndarray, white_around: bool, exact: bool = True) -> list[Region]:
    """A hard-edged picture as one shape a colour, along its pixel edges: the colours stacked
    by area, largest at the back, each shape the union of its own pixels and those of every
    colour above it (so no background shows between neighbours at any zoom, and each colour is
    one path however many pieces it has). ``white_around``: the white around the picture
    (touching its border) is the canvas. ``exact=False`` (a drawing of curves whose edges were
    not anti-aliased): each shape is the 0.5 level of its mask blurred by ``ALIAS_SIGMA``, the
    curve its staircase stands for, to be fitted and polished."""
    from .ndops import dilate, gaussian, label

    _check_pieces(sum(label_count(labels == k) for k in range(len(palette))), f"pieces of {len(palette)} colours",
                  None)
    white = _white(palette)
    around = np.zeros(labels.shape, dtype=bool)
    if white >= 0 and white_around:
        lab, _ = label(labels == white)
        edge = np.unique(np.concatenate([lab[0], lab[-1], lab[:, 0], lab[:, -1]]))
        around = np.isin(lab, edge[edge > 0])
    areas = np.bincount(labels[~around], minlength=len(palette))
    order = [k for k in np.argsort(-areas, kind="stable") if areas[k] > 0]
    regions, covered = [], ~around
    outline = ExactOutlines()
    for k in order:
        if exact:
            rings = outline(covered)
        else:  # the colours above pulled in from the outline they share with it: no sliver of this one shows there
            tucked = covered & ~(covered & (labels != k) & dilate(~covered, iterations=TUCK))
            rings = level_polygons(gaussian(tucked * 1.0, ALIAS_SIGMA))
        regions.append(Region(tuple(palette[k].tolist()), rings, exact=exact))
        covered = covered & (labels != k)
        if not covered.any():
            break
    return regions


def label_count(mask: np.ndarray) -> int:
    """The connected pieces (8-connected) of ``mask``."""
    from .ndops import label

    return label(mask, eight=True)[1]


def _with_background(bg: np.ndarray, regions: list[Region], shape, exact: bool = False) -> list[Region]:
    regions = [r for r in regions if r.polygons]
    if (1 - bg).max() <= WHITE_TOL:
        return regions
    h, w = shape[:2]
    canvas = np.array([[0, 0], [w, 0], [w, h], [0, h]], dtype=np.float64)
    return [Region(tuple(bg.tolist()), [canvas], exact)] + regions


def _check_pieces(n: int, what: str, max_regions: int | None, lift: bool = True) -> None:
    """``TraceError`` when a picture falls into more than ``MAX_REGIONS`` pieces (``n``; with
    ``max_regions``, ``MAX_PIECES``): each costs milliseconds to trace, fit and polish, and
    that many are noise or a photo's grain, nothing a designer would keep."""
    limit = MAX_REGIONS if max_regions is None else MAX_PIECES
    if n > limit:
        hint = "; --max-paths N keeps the N largest" if lift and max_regions is None else ""
        raise TraceError(f"the picture falls into {n:,} {what} (noise, or a photo's grain?), more than the "
                         f"{limit:,} im2vec traces{hint}")


BOX_MARGIN = 6  # px around a piece in which its region is worked out: its edge field reaches 5 px


def _grown_box(box: tuple[slice, slice], margin: int, shape) -> tuple[slice, slice]:
    ys, xs = box
    return (slice(max(ys.start - margin, 0), min(ys.stop + margin, shape[0])),
            slice(max(xs.start - margin, 0), min(xs.stop + margin, shape[1])))


def _pieces(palette: np.ndarray, labels: np.ndarray, max_regions: int | None, white_canvas: bool,
            each_one: bool = False) -> list[tuple[int, int, tuple, np.ndarray, np.ndarray]]:
    """Connected pieces of each colour (but, on a ``white_canvas``, the white around the picture):
    ``(enclosed area, colour, box, mask, filled)``, the masks within the piece's box (``BOX_MARGIN``
    px wider). ``each_one``: every label is one connected piece already (``photo.pieces``)."""
    from .ndops import boxes, fill_holes, pieces

    if each_one:  # (label map, its number in it, box) of each label k
        found = [[(labels, k, box)] for k, box in enumerate(boxes(labels, len(palette)))]
    else:
        found = [[(lab, p, box) for p, box in enumerate(colour_boxes, 1)]
                 for lab, colour_boxes in (pieces(labels == k, eight=True) for k in range(len(palette)))]
    _check_pieces(sum(map(len, found)), f"pieces of {len(palette)} colours", max_regions)
    out, white = [], _white(palette) if white_canvas else -1  # (once: a photo's palette is a colour a piece)
    for k, each in enumerate(found):
        for lab, p, box in each:
            box = _grown_box(box, BOX_MARGIN, labels.shape)
            mask = lab[box] == p
            if k == white and _touches_border(mask, box, labels.shape):
                continue  # the background: the white canvas shows it (a grey one would not: issue 69)
            filled = fill_holes(mask)
            out.append((int(filled.sum()), k, box, mask, filled))
    return out


def _stacked_regions(image: np.ndarray, palette: np.ndarray, labels: np.ndarray, max_regions: int | None,
                     white_canvas: bool, exact: bool = False, each_one: bool = False) -> list[Region]:
    """Connected pieces of each colour (``_pieces``), stacked largest (by enclosed area) at the back,
    each extended under the pieces above it; neighbouring pieces of one colour share a region.
    Each piece is worked out within its box. ``exact``: outlines along the pixel edges
    (``pixels.ExactOutlines``), else the sub-pixel 0.5 level of each piece's edge field."""
    from .ndops import dilate

    pieces = sorted(_pieces(palette, labels, max_regions, white_canvas, each_one), key=lambda t: -t[0])
    if max_regions is not None:
        pieces = pieces[:max_regions]
    above = np.zeros(labels.shape, dtype=bool)
    extended, outline = [], ExactOutlines()
    for _, k, box, mask, filled in reversed(pieces):  # front to back: `above` is what covers this piece
        over = above[box]
        reach = dilate(mask) & over if exact else _hidden_reach(mask, over)  # exact: never polished
        grown = mask | (filled & over) | reach
        rings = outline(grown) if exact else level_polygons(_edge_field(image[box], palette[k], grown, over))
        extended.append((k, box, grown, [r + (box[1].start, box[0].start) for r in rings]))
        over |= mask
    regions: list[Region] = []
    owner = np.full(labels.shape, -1, dtype=np.int32)  # the region each pixel's grown piece went to
    last_k = None
    for k, box, grown, rings in reversed(extended):  # back to front
        mine = owner[box]
        if regions and last_k == k and not (mine[grown] == len(regions) - 1).any():
            regions[-1].polygons.extend(rings)  # the same colour, not overlapping: one shape
        else:
            regions.append(Region(tuple(palette[k].tolist()), rings, exact))
            last_k = k
        mine[grown] = len(regions) - 1
    return regions


HIDDEN_REACH = 3  # px: how far a piece extends under the pieces above it, towards the middle of what they cover


def _hidden_reach(mask: np.ndarray, over: np.ndarray) -> np.ndarray:
    """The pixels under ``over`` (the pieces in front) that the piece ``mask`` claims: within
    ``HIDDEN_REACH`` px of it and nearer it than anything else beneath (another piece, the
    background), half a pixel more; the parts on either side of a stroke then meet under its
    middle, so that a stroke polished a little thinner or shifted opens no crack."""
    from .ndops import distance

    if not over.any():
        return over
    mine = distance(~mask)
    other = ~mask & ~over
    theirs = distance(~other) if other.any() else np.full(mask.shape, np.inf)
    return over & (mine <= HIDDEN_REACH) & (mine < theirs + 0.5)


def _edge_field(image: np.ndarray, color: np.ndarray, grown: np.ndarray, above: np.ndarray) -> np.ndarray:
    """``(H, W)`` field whose 0.5 level is the region's edge: on edges against what lies below
    (background, lower regions) the pixel's mix of the region's colour and the colour beside
    it (sub-pixel, like a two-tone picture's ``alpha``); elsewhere (edges hidden under upper
    regions) the mask, blurred to the mid-line of its staircase."""
    from .ndops import box_mean, dilate, gaussian

    field = gaussian(grown, 0.6)
    below = ~grown & ~above
    band = dilate(grown) & dilate(~grown) & dilate(below)
    if not band.any():
        return field
    count, near = box_mean(below, 5), box_mean(image * below[..., None], 5)
    ys, xs = np.nonzero(band & ~above & (count > 1e-6))  # (a pixel under a piece above shows that piece)
    other = near[ys, xs] / np.maximum(count[ys, xs], 1e-9)[:, None]  # (M, 3): only where it is used
    axis = color - other
    norm = (axis * axis).sum(-1)
    use = norm > 0.15**2
    field[ys[use], xs[use]] = np.clip(((image[ys, xs] - other) * axis).sum(-1) / np.maximum(norm, 1e-9), 0, 1)[use]
    return field


def _white(palette: np.ndarray) -> int:
    """Index of the palette's white, or -1."""
    gap = (1 - palette).max(-1)
    return int(np.argmin(gap)) if gap.min() <= WHITE_TOL else -1


def _touches_border(mask: np.ndarray, box: tuple[slice, slice], shape) -> bool:
    """Whether ``mask`` (within ``box`` of a picture of ``shape``) touches the picture's border."""
    ys, xs = box
    return bool((ys.start == 0 and mask[0].any()) or (ys.stop == shape[0] and mask[-1].any())
                or (xs.start == 0 and mask[:, 0].any()) or (xs.stop == shape[1] and mask[:, -1].any()))
