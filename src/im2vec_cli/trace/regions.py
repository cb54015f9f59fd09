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

Frame: pixel coordinates of the input, ``x`` right and ``y`` down, pixel ``(row i, col j)``
covering ``[j, j+1] x [i, i+1]``. Outer boundaries run clockwise on screen, holes counter-
clockwise, so the nonzero and even-odd rules agree on every region.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from ..raster.bezier import polygon_area

WHITE_TOL = 0.06  # a colour within this (max channel distance) of white is white
TWO_TONE_TOL = 0.08  # pixels this far (RGB distance) from the background-ink line break two-tone...
TWO_TONE_SHARE = 0.005  # ...when more than this share of the pixels do


@dataclass
class Region:
    """One flat-colour region: ``polygons`` are closed ``(N, 2)`` pixel-frame rings (first
    point not repeated), outer boundaries clockwise on screen and holes counter-clockwise."""

    color: tuple[float, float, float]
    polygons: list[np.ndarray]


def level_polygons(field: np.ndarray, level: float = 0.5, min_area: float = 0.5) -> list[np.ndarray]:
    """Closed rings around ``field >= level`` (``(H, W)``, values at pixel centres), sub-pixel.

    The field is padded with zeros, so regions touching the border close along it. Rings
    enclosing less than ``min_area`` px^2 (specks, pin holes) are dropped.
    """
    import contourpy

    h, w = field.shape
    padded = np.pad(np.asarray(field, dtype=np.float64), 1)
    gen = contourpy.contour_generator(np.arange(w + 2) - 0.5, np.arange(h + 2) - 0.5, padded,
                                      fill_type="OuterOffset", quad_as_tri=False)
    rings = []
    for poly, offsets in zip(*gen.filled(level, np.inf)):
        for a, b in zip(offsets[:-1], offsets[1:]):
            ring = np.clip(poly[a : b - 1], 0, [w, h])  # the last point repeats the first
            if len(ring) >= 3 and abs(float(polygon_area(torch.from_numpy(ring)))) >= min_area:
                rings.append(ring)
    return rings


def background_color(image: np.ndarray) -> np.ndarray:
    """The most common colour of the border pixels of ``image (H, W, 3)``: ``(3,)``."""
    border = np.concatenate([image[0], image[-1], image[:, 0], image[:, -1]])  # (B, 3)
    keys = np.round(border * 31).astype(np.int64) @ np.array([1024, 32, 1])
    values, counts = np.unique(keys, return_counts=True)
    near = border[keys == values[np.argmax(counts)]]
    return near.mean(0)


def _ink_line(image: np.ndarray, bg: np.ndarray, extreme: float) -> tuple[np.ndarray, np.ndarray]:
    """The ink (mean of the pixels at least ``extreme`` of the farthest from ``bg``) and each
    pixel's position ``t (H, W)`` along the background-ink line (0: background, 1: ink; unclipped)."""
    d = np.linalg.norm(image - bg, axis=-1)  # (H, W)
    ink = image[d >= extreme * max(d.max(), 1e-6)].mean(0)
    axis = ink - bg
    return ink, ((image - bg) @ axis) / max(float(axis @ axis), 1e-12)


def two_tone(image: np.ndarray, bg: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """``(ink (3,), alpha (H, W))`` when every pixel mixes ``bg`` and one ink colour, else ``None``."""
    if np.linalg.norm(image - bg, axis=-1).max() < 0.1:
        return None
    ink, t = _ink_line(image, bg, 0.9)
    off = np.linalg.norm(image - (bg + t[..., None] * (ink - bg)), axis=-1)  # off the background-ink line
    alpha = np.clip(t, 0, 1)
    if (off > TWO_TONE_TOL).mean() > TWO_TONE_SHARE:
        return None
    if ((alpha > 0.15) & (alpha < 0.85) & _flat_pixels(image)).mean() > TWO_TONE_SHARE:
        return None  # flat areas of an in-between shade (a grey fill): colours of their own, not edges
    return ink, alpha


def trace(image: np.ndarray, colors: int | None = None, max_regions: int | None = None,
          seed: int = 0) -> list[Region]:
    """The regions of ``image (H, W, 3)`` in [0, 1], back to front.

    Args:
        colors: palette size for a multi-colour picture (``None``: the fewest colours that
            reproduce the flat areas, at most 16). ``colors == 1`` treats any picture as
            two-tone (the ink is its darkest extreme).
        max_regions: keep this many regions at most (the largest).
    """
    image = np.asarray(image, dtype=np.float64)
    bg = background_color(image)
    tone = two_tone(image, bg) if colors in (None, 1) else None
    if tone is None and colors == 1:
        ink, t = _ink_line(image, bg, 0.8)
        tone = ink, np.clip(t, 0, 1)
    if tone is not None:
        ink, alpha = tone
        return _with_background(bg, [Region(tuple(ink.tolist()), level_polygons(alpha))], image.shape)
    palette, labels = quantize(image, colors, seed)
    return _with_background(bg, _stacked_regions(image, palette, labels, max_regions), image.shape)


def _with_background(bg: np.ndarray, regions: list[Region], shape) -> list[Region]:
    regions = [r for r in regions if r.polygons]
    if (1 - bg).max() <= WHITE_TOL:
        return regions
    h, w = shape[:2]
    canvas = np.array([[0, 0], [w, 0], [w, h], [0, h]], dtype=np.float64)
    return [Region(tuple(bg.tolist()), [canvas])] + regions


# --- multi-colour pictures ---------------------------------------------------------------------


def quantize(image: np.ndarray, colors: int | None, seed: int = 0, max_colors: int = 16,
             flat_mse: float = 1.5e-3) -> tuple[np.ndarray, np.ndarray]:
    """Palette ``(K, 3)`` and per-pixel labels ``(H, W)`` of a picture.

    The palette is fitted (k-means) to the *flat* pixels, whose 3x3 neighbourhood has one
    colour, so that anti-aliased edges do not get colours of their own; with ``colors=None``
    ``K`` grows until the flat pixels' mean squared error is below ``flat_mse``. Edge pixels
    take the nearest palette colour among those of the flat pixels within two pixels.
    """
    from scipy.cluster.vq import kmeans2

    h, w, _ = image.shape
    flat = _flat_pixels(image)
    pool = image[flat] if flat.sum() >= 16 else image.reshape(-1, 3)
    rng = np.random.default_rng(seed)
    if len(pool) > 20000:
        pool = pool[rng.choice(len(pool), 20000, replace=False)]
    unique = np.unique(np.round(pool * 255), axis=0)
    ks = [min(colors, len(unique))] if colors else range(1, min(max_colors, len(unique)) + 1)
    for k in ks:
        centres, lab = kmeans2(pool, k, minit="++", seed=rng, iter=20)
        used = np.unique(lab)
        centres = centres[used]
        err = ((pool - centres[np.argmin(((pool[:, None] - centres[None]) ** 2).sum(-1), 1)]) ** 2).sum(-1).mean()
        if err <= flat_mse:
            break
    if not colors:
        centres = _thin_colors(image.reshape(-1, 3), centres, max_colors)
    labels = _assign(image, centres, flat)
    return np.clip(centres, 0, 1), _absorb_specks(labels, max(2, h * w // 2000))


def _assign(image: np.ndarray, palette: np.ndarray, flat: np.ndarray) -> np.ndarray:
    """``(H, W)`` labels: each pixel explained as a mix of two palette colours found near it
    (within two pixels: a flat pixel of that colour, or a pixel close to it), and given
    the one it holds more of. An anti-aliased edge between yellow and black is then yellow
    or black, never a red that happens to lie nearer the mix."""
    from scipy.ndimage import maximum_filter

    h, w, _ = image.shape
    k = len(palette)
    dist = np.linalg.norm(image[:, :, None] - palette, axis=-1)  # (H, W, K)
    flat_lab = np.where(flat, np.argmin(dist, -1), -1)
    support = (flat_lab[..., None] == np.arange(k)) | (dist < 0.15)  # flat pixels of it, or pixels close to it
    near = np.stack([maximum_filter(support[..., i], size=5) for i in range(k)], -1)  # (H, W, K)
    near[~near.any(-1)] = True
    best = np.full((h, w), np.inf)
    labels = np.zeros((h, w), dtype=np.int64)
    for i, j, t, r in _mixes(image, palette):
        r = r + 1e-6 * (i != j)  # ties: one colour
        r[~(near[..., i] & near[..., j])] = np.inf
        better = r < best
        best[better] = r[better]
        labels[better] = np.where(t[better] < 0.5, i, j)
    return labels


def _mixes(pixels: np.ndarray, palette: np.ndarray):
    """For every pair ``i <= j`` of palette colours: ``(i, j, t, r)``, each pixel's position ``t``
    along the mix from colour ``i`` to colour ``j`` and its distance ``r`` from that mix."""
    for i in range(len(palette)):
        for j in range(i, len(palette)):
            a, d = palette[i], palette[j] - palette[i]
            t = np.clip((pixels - a) @ d / max(float(d @ d), 1e-12), 0, 1)
            yield i, j, t, np.linalg.norm(pixels - a - t[..., None] * d, axis=-1)


def _mix_distance(pixels: np.ndarray, palette: np.ndarray) -> np.ndarray:
    """``(N,)`` distance of each pixel to the nearest mix of two palette colours (an edge pixel)."""
    return np.min([r for _, _, _, r in _mixes(pixels, palette)], axis=0)


def _thin_colors(pixels: np.ndarray, palette: np.ndarray, max_colors: int, tol: float = 0.12) -> np.ndarray:
    """Add the colours of thin features (lines, dots: no flat pixel of their own) to ``palette``:
    while more than 0.2% of the pixels are no mix of two palette colours, the farthest tenth
    of them gives one more colour."""
    for _ in range(max_colors - len(palette)):
        off = _mix_distance(pixels, palette)
        odd = off > tol
        if odd.sum() < max(3, 0.002 * len(pixels)):
            break
        far = pixels[odd][np.argsort(-off[odd])[: max(1, odd.sum() // 10)]]
        palette = np.vstack([palette, far.mean(0)])
    return palette


def _flat_pixels(image: np.ndarray) -> np.ndarray:
    """``(H, W)`` bool: pixels whose 8 neighbours are within 0.06 of them in every channel."""
    pad = np.pad(image, ((1, 1), (1, 1), (0, 0)), mode="edge")
    h, w, _ = image.shape
    worst = np.zeros((h, w))
    for dy in (0, 1, 2):
        for dx in (0, 1, 2):
            worst = np.maximum(worst, np.abs(pad[dy : dy + h, dx : dx + w] - image).max(-1))
    return worst <= 0.06


def _absorb_specks(labels: np.ndarray, min_px: int) -> np.ndarray:
    """Connected pieces smaller than ``min_px`` pixels take the commonest label around them."""
    from scipy.ndimage import binary_dilation, label

    labels = labels.copy()
    for k in np.unique(labels):
        pieces, n = label(labels == k)
        sizes = np.bincount(pieces.ravel())
        for p in np.nonzero(sizes[1:] < min_px)[0] + 1:
            piece = pieces == p
            ring = binary_dilation(piece) & ~piece
            around = labels[ring]
            around = around[around != k]
            if len(around):
                labels[piece] = np.bincount(around).argmax()
    return labels


def _stacked_regions(image: np.ndarray, palette: np.ndarray, labels: np.ndarray, max_regions: int | None) -> list[Region]:
    """Connected pieces of each colour, stacked largest (by enclosed area) at the back, each
    extended under the pieces above it; neighbouring pieces of one colour share a region."""
    from scipy.ndimage import binary_dilation, binary_fill_holes, label

    pieces = []  # (enclosed area, colour index, mask)
    for k in range(len(palette)):
        lab, n = label(labels == k, structure=np.ones((3, 3)))
        for p in range(1, n + 1):
            mask = lab == p
            filled = binary_fill_holes(mask)
            if k == _white(palette) and _touches_border(mask):
                continue  # the background: the canvas shows it
            pieces.append((int(filled.sum()), k, mask, filled))
    pieces.sort(key=lambda t: -t[0])
    if max_regions is not None:
        pieces = pieces[:max_regions]
    above = np.zeros(labels.shape, dtype=bool)
    extended = []
    for _, k, mask, filled in reversed(pieces):  # front to back: `above` is what covers this piece
        grown = mask | (filled & above) | (binary_dilation(mask) & above)
        extended.append((k, grown, _edge_field(image, palette[k], grown, above)))
        above |= mask
    regions: list[Region] = []
    last = None
    for k, grown, field in reversed(extended):  # back to front
        rings = level_polygons(field)
        if regions and last is not None and last[0] == k and not (last[1] & grown).any():
            regions[-1].polygons.extend(rings)  # the same colour, not overlapping: one shape
            last = (k, last[1] | grown)
        else:
            regions.append(Region(tuple(palette[k].tolist()), rings))
            last = (k, grown)
    return regions


def _edge_field(image: np.ndarray, color: np.ndarray, grown: np.ndarray, above: np.ndarray) -> np.ndarray:
    """``(H, W)`` field whose 0.5 level is the region's edge: on edges against what lies below
    (background, lower regions) the pixel's mix of the region's colour and the colour beside
    it (sub-pixel, like a two-tone picture's ``alpha``); elsewhere (edges hidden under upper
    regions) the mask, blurred to the mid-line of its staircase."""
    from scipy.ndimage import binary_dilation, gaussian_filter, uniform_filter

    field = gaussian_filter(grown.astype(np.float64), 0.6)
    below = ~grown & ~above
    band = binary_dilation(grown) & binary_dilation(~grown) & binary_dilation(below)
    if not band.any():
        return field
    count = uniform_filter(below.astype(np.float64), 5)
    other = np.stack([uniform_filter(image[..., c] * below, 5) for c in range(3)], -1) / np.maximum(count, 1e-9)[..., None]
    axis = color - other  # (H, W, 3)
    norm = (axis * axis).sum(-1)
    mix = np.clip(((image - other) * axis).sum(-1) / np.maximum(norm, 1e-9), 0, 1)
    use = band & (count > 1e-6) & (norm > 0.15**2)
    field[use] = mix[use]
    return field


def _white(palette: np.ndarray) -> int:
    """Index of the palette's white, or -1."""
    gap = (1 - palette).max(-1)
    return int(np.argmin(gap)) if gap.min() <= WHITE_TOL else -1


def _touches_border(mask: np.ndarray) -> bool:
    return bool(mask[0].any() or mask[-1].any() or mask[:, 0].any() or mask[:, -1].any())
