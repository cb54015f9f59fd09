"""The colours of a picture: its palette and each pixel's label.

- ``hard_palette``: a hard-edged picture (pixel art, a mosaic) is its exact colours;
- ``quantize``: any other multi-colour picture is quantised (k-means on its flat pixels, the
  colours of thin features added, edge pixels given the colour they hold more of), and its
  specks absorbed.

Frame: ``(H, W, 3)`` arrays in [0, 1], labels ``(H, W)``.
"""

from __future__ import annotations

import collections

import numpy as np

from .ndops import norm3, rgb_keys, rgb_of_keys

MAX_HARD_COLORS = 64  # a picture of at most this many exact colours (and at least 3)...
MAX_HARD_SIDE = 512  # ...no larger than this is hard-edged: traced along its pixel edges
MAX_SPECK = 24  # px: a piece smaller than 1/2000 of the picture, and than this, is a speck (absorbed)...
CLEAN_SPECK = 4  # ...or than this in a clean render (its flat pixels within CLEAN_FLAT_MSE of their colours):
CLEAN_FLAT_MSE = 1e-4  # a screenshot's small text and an icon's dots are no JPEG specks (issue 69)


def hard_palette(image: np.ndarray, pixel: bool = False) -> tuple[np.ndarray, np.ndarray] | None:
    """``(palette (K, 3), labels (H, W))`` of a hard-edged picture (pixel art, a mosaic, a chart
    without anti-aliasing): at most ``MAX_HARD_SIDE`` px a side, every pixel exactly one of 3 to
    ``MAX_HARD_COLORS`` 8-bit colours, so that no pixel mixes two. Else ``None``. ``pixel``: the
    picture is known to be pixel art (``read.read``): any 1 to ``MAX_HARD_COLORS`` colours,
    mixes or not, any size."""
    if max(image.shape[:2]) > MAX_HARD_SIDE and not pixel:
        return None
    q = np.round(image * 255).astype(np.int64)
    keys = rgb_keys(q).ravel()
    sample = np.unique(keys[:: max(1, len(keys) // 4096)])
    if len(sample) > MAX_HARD_COLORS:  # most pictures: a sample says no
        return None
    inverse = np.minimum(np.searchsorted(sample, keys), len(sample) - 1)
    missed = keys[sample[inverse] != keys]  # np.unique(keys, return_inverse=True), from the sample's colours on
    if len(missed):
        values = np.union1d(sample, missed[:: max(1, len(missed) // 4096)])
        if len(values) > MAX_HARD_COLORS:
            return None
        values = np.union1d(values, missed)
        inverse = np.searchsorted(values, keys)
    else:
        values = sample
    if len(values) > MAX_HARD_COLORS:
        return None
    if not pixel and (len(values) < 3 or _blends(q) > max(2, MAX_BLENDS * len(keys))):
        return None
    return rgb_of_keys(values), inverse.reshape(image.shape[:2])


MAX_BLENDS = 5e-4  # share of pixels that may look anti-aliased in a hard-edged picture


def _blends(q: np.ndarray) -> int:
    """How many pixels of ``q (H, W, 3)`` (8-bit) are a blend of their two neighbours on a row
    or a column (strictly between two different colours, within 2 levels): anti-aliasing,
    which a hard-edged picture has not."""
    count = 0
    for a, c, b in ((q[:, :-2], q[:, 1:-1], q[:, 2:]), (q[:-2], q[1:-1], q[2:])):
        d, e = b - a, c - a  # (H', W', 3)
        dd = (d * d).sum(-1)
        t = (e * d).sum(-1) / np.maximum(dd, 1)
        off = e - t[..., None] * d
        between = (dd > 0) & (t > 0.02) & (t < 0.98) & ((off * off).sum(-1) <= 4)
        count += int(between.sum())
    return count


KEPT = 2  # ``quantize`` keeps its last results: ``read.read`` judges a drawing by its palette (``photo.agrees_better``)
_kept: collections.deque = collections.deque(maxlen=KEPT)  # and the trace then quantises the same picture again
# (0.17 s of a 512 px icon's 0.65)


def quantize(image: np.ndarray, colors: int | None, seed: int = 0, max_colors: int = 16,
             flat_mse: float = 1.5e-3) -> tuple[np.ndarray, np.ndarray]:
    """``_quantize``, its last ``KEPT`` results kept with their pictures and arguments (a picture's
    bytes compared: a twentieth of the time a hash of them took)."""
    image = np.ascontiguousarray(image)
    args = (image.shape, image.dtype.str, colors, seed, max_colors, flat_mse)
    raw = image.reshape(-1).view(np.uint8)
    got = next((r for a, kept, r in _kept if a == args and np.array_equal(kept, raw)), None)
    if got is None:
        got = _quantize(image, colors, seed, max_colors, flat_mse)
        _kept.append((args, raw.copy(), got))  # (the oldest pushed out)
    return got[0].copy(), got[1].copy()


def _quantize(image: np.ndarray, colors: int | None, seed: int = 0, max_colors: int = 16,
              flat_mse: float = 1.5e-3) -> tuple[np.ndarray, np.ndarray]:
    """Palette ``(K, 3)`` and per-pixel labels ``(H, W)`` of a picture.

    The palette is fitted (k-means) to the *flat* pixels, whose 3x3 neighbourhood has one
    colour, so that anti-aliased edges do not get colours of their own; with ``colors=None``
    ``K`` grows until the flat pixels' mean squared error is below ``flat_mse`` and at most
    ``FAR_SHARE`` of them are ``FAR_COLOR`` or farther from their colour (a small area of a
    distinct colour, a grey arc beside a pale blue, keeps a colour of its own), and none of
    those far pixels is one area's colour (``_far_area``: a grey chin between black lines,
    a mix of two palette colours that ``_thin_colors`` cannot tell from an edge). Edge pixels
    take the nearest palette colour among those of the flat pixels within two pixels.
    """
    from .ndops import kmeans, nearest

    h, w, _ = image.shape
    flat = _flat_pixels(image)
    if h * w <= SMALL_FLAT:
        flat |= _flat_blocks(image)
    pool = image[flat] if flat.sum() >= 16 else image.reshape(-1, 3)
    rng = np.random.default_rng(seed)
    if len(pool) > 20000:
        pool = pool[rng.choice(len(pool), 20000, replace=False)]
    keys, counts = np.unique(rgb_keys(np.round(pool * 255).astype(np.int64)), return_counts=True)  # 8-bit colours
    unique = len(keys)
    ks = [min(colors, unique)] if colors else range(1, min(max_colors, unique) + 1)
    for k in ks:
        centres, lab = kmeans(pool, k, rng, 20)
        used = np.unique(lab)
        centres = centres[used]
        err = ((pool - centres[nearest(pool, centres)]) ** 2).sum(-1)
        far = err > FAR_COLOR**2
        if err.mean() <= flat_mse and far.mean() <= FAR_SHARE and not _far_area(pool[far], len(pool)):
            break
    if not colors:
        split = _split_fills(keys, counts, centres, max_colors)
        if len(split) > len(centres):  # the flat pixels' error with the fills' own colours
            centres, err = split, ((pool - split[nearest(pool, split)]) ** 2).sum(-1)
        pixels = image.reshape(-1, 3)
        if len(pixels) > THIN_SAMPLE:  # the colours of thin lines and dots show in a sample too
            pixels = pixels[rng.choice(len(pixels), THIN_SAMPLE, replace=False)]
        centres = _thin_colors(pixels, centres, max_colors)
    clean = err.mean() <= CLEAN_FLAT_MSE  # a clean render: its small pieces and its thin lines are its own
    lines = clean and h * w > MIXES_ON_EDGES
    labels = _assign(image, centres, flat, lines=lines)
    speck = CLEAN_SPECK if clean else MAX_SPECK
    return np.clip(centres, 0, 1), _absorb_specks(labels, max(2, min(h * w // 2000, speck)), eight=lines)


PHOTO_SPECK = 2e-4  # a photo's pieces smaller than this share of its pixels are absorbed (52 px at 512 px)


def posterize(image: np.ndarray, colors: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Palette ``(K, 3)`` and labels ``(H, W)`` of a photo: k-means in CIELAB (distances as the
    eye sees them, so a small patch of a distinct hue keeps a colour of its own) on a sample of
    all its pixels, each pixel given the nearest colour, specks absorbed."""
    from .ndops import kmeans, lab2rgb, nearest, rgb2lab

    h, w, _ = image.shape
    lab = rgb2lab(image).reshape(-1, 3)
    rng = np.random.default_rng(seed)
    pool = lab[rng.choice(len(lab), min(len(lab), 20000), replace=False)]
    centres, _ = kmeans(pool, min(colors, len(np.unique(np.round(pool), axis=0))), rng, 20)
    used, labels = np.unique(nearest(lab, centres), return_inverse=True)
    palette = lab2rgb(centres[used])
    return palette, _absorb_specks(labels.reshape(h, w), max(2, int(PHOTO_SPECK * h * w)))


FAR_COLOR = 0.12  # RGB distance of a flat pixel from its palette colour that is another colour...
FAR_SHARE = 0.005  # ...when more than this share of the flat pixels are that far
FAR_AREA = 3  # flat pixels of one colour (within FAR_TIE of each other) far from the palette are an area of
FAR_AREA_SHARE = 1e-3  # that colour (at least this share of the flat pixels too), not noise
FAR_TIE = 0.04
THIN_SAMPLE = 65_536  # pixels in which ``_thin_colors`` looks for the colours of thin features (a 256 px
# picture's worth: at 512 px, 262,144 took 1.9 s of a logo's 4; bench/realworld.py)


FILL_SHARE = 0.02  # an exact 8-bit colour of at least this share of the flat pixels (and FILL_MIN of them) is a fill...
FILL_MIN = 64
FILL_TIE = 0.03  # ...and fills farther apart than this (RGB distance, chained) are two: a card's (248, 245, 245) on
# white keeps its colour, where k-means met the mean squared error with one colour between the two; a shaded
# ramp of exact greys one level apart stays one colour


def _split_fills(keys: np.ndarray, counts: np.ndarray, centres: np.ndarray, max_colors: int) -> np.ndarray:
    """``centres (K, 3)`` with each colour that stands for two or more fills of the flat pixels (their
    distinct 8-bit colours ``keys``, ``rgb_keys``, each ``counts`` of them; ``FILL_SHARE``, ``FILL_TIE``)
    replaced by those fills, each the mean of its exact colours (at most ``max_colors`` colours in all)."""
    from .ndops import nearest

    fill = counts >= max(FILL_SHARE * counts.sum(), FILL_MIN)
    fills, counts = rgb_of_keys(keys[fill]), counts[fill]
    if len(fills) < 2:
        return centres
    owner = nearest(fills, centres)
    out = []
    for i, centre in enumerate(centres):
        mine, weight = fills[owner == i], counts[owner == i]
        groups = _chained(mine, FILL_TIE)
        n = groups.max(initial=-1) + 1
        if n < 2 or len(out) + n + len(centres) - i - 1 > max_colors:
            out.append(centre)  # one fill (or none): k-means' colour
            continue
        out.extend((mine[groups == g] * weight[groups == g, None]).sum(0) / weight[groups == g].sum()
                   for g in range(n))
    return np.array(out)


def _chained(colours: np.ndarray, tie: float) -> np.ndarray:
    """``(N,)`` group of each of ``colours (N, 3)``, 0.. in order of first member: colours within ``tie`` of
    each other are one group, and so are chains of them (single linkage)."""
    if len(colours) < 2:
        return np.zeros(len(colours), dtype=np.int64)
    link = np.sqrt(((colours[:, None] - colours[None]) ** 2).sum(-1)) <= tie  # (N, N), N <= 1 / FILL_SHARE
    while True:
        wider = (link.astype(np.int64) @ link.astype(np.int64)) > 0
        if np.array_equal(wider, link):
            break
        link = wider
    first = np.argmax(link, 1)  # each colour's group by its first member
    return np.unique(first, return_inverse=True)[1].reshape(-1)


def _far_area(far: np.ndarray, pool: int) -> bool:
    """Whether ``far (N, 3)``, the flat pixels far from every palette colour (at most
    ``FAR_SHARE`` of the ``pool``), hold an area of one colour: ``FAR_AREA`` of them, and
    ``FAR_AREA_SHARE`` of the pool, within ``FAR_TIE`` of one of them."""
    need = max(FAR_AREA, FAR_AREA_SHARE * pool)
    if len(far) < need:
        return False
    d = np.sqrt(((far[:, None] - far[None]) ** 2).sum(-1))  # (N, N), N <= FAR_SHARE * 20,000
    return bool(((d < FAR_TIE).sum(1) >= need).any())


def _assign(image: np.ndarray, palette: np.ndarray, flat: np.ndarray, lines: bool = False) -> np.ndarray:
    """``(H, W)`` labels: each pixel explained as a mix of two palette colours found near it
    (within two pixels: a flat pixel of that colour, or a pixel close to it), and given
    the one it holds more of. An anti-aliased edge between yellow and black is then yellow
    or black, never a red that happens to lie nearer the mix. With ``lines``, a pixel on the crest
    of a line thinner than a pixel takes the line's colour though it holds less of it (``_ridges``)."""
    from .ndops import distinct, max_filter

    h, w, _ = image.shape
    k = len(palette)
    dist = np.stack([norm3(image - c).astype(np.float32) for c in palette], -1)  # (H, W, K)
    flat_lab = np.where(flat, np.argmin(dist, -1), -1)
    support = (flat_lab[..., None] == np.arange(k)) | (dist < 0.15)  # flat pixels of it, or pixels close to it
    near = np.stack([max_filter(support[..., i], 5) for i in range(k)], -1)  # (H, W, K)
    near[~near.any(-1)] = True
    labels = np.argmin(dist, -1)
    todo = ~flat if h * w > MIXES_ON_EDGES else np.ones((h, w), dtype=bool)  # a large picture's flat pixels: their
    colours, back = distinct(image[todo])  # nearest colour (the mixes of every pair cost 10 s at 2048 px)
    near = near[todo]
    best = np.full(len(back), np.inf)
    pair, along = np.zeros((2, len(back)), dtype=np.int64), np.zeros(len(back))
    for i, j, t, r in _mixes(colours, palette):
        t, r = t[back], r[back] + 1e-6 * (i != j)  # ties: one colour
        r[~(near[:, i] & near[:, j])] = np.inf
        better = r < best
        best[better] = r[better]
        pair[:, better], along[better] = [[i], [j]], t[better]
    second = _ridges(image, todo, palette, pair, along, best) if lines else along >= 0.5
    labels[todo] = np.where(second, pair[1], pair[0])
    return labels


RIDGE_T = 0.3  # a pixel at least this far along the mix toward a colour, and no less so than its two
RIDGE_FIT = 0.02  # (and within this of the mix of the two: a JPEG's edge pixels are off it, its ringing too)
RIDGE_STEP = 0.1  # neighbours on a line through it (one of them this much less), is on a line of that colour:
# in a clean render larger than the polish's pictures (``MIXES_ON_EDGES``), whose labels are final. (On the 120
# OpenMoji faces of bench/outlines.py at 64 px, which the polish fits against their soft edges, it cost a third
# image with cracks and 3% of MSE at 4x; a JPEG's ringing has crests of its own.)


def _ridges(image: np.ndarray, todo: np.ndarray, palette: np.ndarray, pair: np.ndarray, t: np.ndarray,
            off: np.ndarray) -> np.ndarray:
    """``(N,)`` bool: whether each pixel of ``todo (H, W)``, a mix ``t`` of the palette colours ``pair (2, N)``
    ``off`` from it, takes the second colour: where it holds more of it, and where it is the crest of a
    line of it thinner than a pixel (``RIDGE_T``): a hairline or an outline drawn across a pixel's edge
    whose every pixel holds less of it than of its surround, and which the larger share would break into
    dashes or drop. Likewise a pixel that holds more of the second colour is the first's where it is the
    trough of a thin line of the first (a thin gap kept open)."""
    h, w, _ = image.shape
    ys, xs = np.nonzero(todo)
    a, d = palette[pair[0]], palette[pair[1]] - palette[pair[0]]  # (N, 3)
    scale = 1 / np.maximum((d * d).sum(-1), 1e-12)
    crest, trough = np.zeros(len(t), dtype=bool), np.zeros(len(t), dtype=bool)
    for dy, dx in ((0, 1), (1, 0), (1, 1), (1, -1)):  # a line through the pixel: row, column, diagonals
        ends = [np.clip(((image[np.clip(ys + s * dy, 0, h - 1), np.clip(xs + s * dx, 0, w - 1)] - a) * d).sum(-1)
                        * scale, 0, 1) for s in (-1, 1)]
        lo, hi = np.minimum(*ends), np.maximum(*ends)
        crest |= (hi <= t) & (lo <= t - RIDGE_STEP)
        trough |= (lo >= t) & (hi >= t + RIDGE_STEP)
    line = (pair[0] != pair[1]) & (off <= RIDGE_FIT)  # an exact mix of the two: drawn, not a JPEG's ringing
    return np.where(t < 0.5, line & crest & (t >= RIDGE_T), ~(line & trough & (t <= 1 - RIDGE_T)))


def _mixes(pixels: np.ndarray, palette: np.ndarray):
    """For every pair ``i <= j`` of palette colours: ``(i, j, t, r)``, each pixel's position ``t``
    along the mix from colour ``i`` to colour ``j`` and its distance ``r`` from that mix."""
    for i in range(len(palette)):
        for j in range(i, len(palette)):
            a, d = palette[i], palette[j] - palette[i]
            t = np.clip((pixels - a) @ d / max(float(d @ d), 1e-12), 0, 1)
            yield i, j, t, norm3(pixels - a - t[..., None] * d)


def _mix_distance(colours: np.ndarray, palette: np.ndarray) -> np.ndarray:
    """``(M,)`` distance of each colour to the nearest mix of two palette colours (an edge pixel's)."""
    return np.min([r for _, _, _, r in _mixes(colours, palette)], axis=0)


def _thin_colors(pixels: np.ndarray, palette: np.ndarray, max_colors: int, tol: float = 0.12) -> np.ndarray:
    """Add the colours of thin features (lines, dots: no flat pixel of their own) to ``palette``:
    while more than 0.2% of the pixels are no mix of two palette colours, the farthest tenth
    of them gives one more colour."""
    from .ndops import distinct

    colours, back = distinct(pixels)
    for _ in range(max_colors - len(palette)):
        off = _mix_distance(colours, palette)[back]
        odd = off > tol
        if odd.sum() < max(3, 0.002 * len(pixels)):
            break
        far = pixels[odd][np.argsort(-off[odd])[: max(1, odd.sum() // 10)]]
        palette = np.vstack([palette, far.mean(0)])
    return palette


def _flat_pixels(image: np.ndarray) -> np.ndarray:
    """``(H, W)`` bool: pixels whose 8 neighbours are within 0.06 of them in every channel (the
    3x3 maximum at most 0.06 above, the minimum at most 0.06 below)."""
    h, w, _ = image.shape
    im, tol = image, 0.06
    if h * w > FLAT_BY_LEVELS:  # on 8-bit levels (0.06 is 15.3 of them): a quarter of the memory traffic
        im, tol = np.round(image * 255).astype(np.uint8), 15
    return ((_extreme3(im, np.maximum) - im <= tol) & (im - _extreme3(im, np.minimum) <= tol)).all(-1)


SMALL_FLAT = 48 * 48  # a picture this small has fills too narrow for a flat 3x3: 2x2 blocks of one colour count


def _flat_blocks(image: np.ndarray, tol: float = 0.06) -> np.ndarray:
    """``(H, W)`` bool: pixels of a 2x2 block whose pixels are within ``tol`` of each other in every channel."""
    blocks = np.stack([image[:-1, :-1], image[1:, :-1], image[:-1, 1:], image[1:, 1:]])
    ok = (np.ptp(blocks, axis=0) <= tol).all(-1)
    out = np.zeros(image.shape[:2], dtype=bool)
    for dy in (0, 1):
        for dx in (0, 1):
            out[dy : dy + ok.shape[0], dx : dx + ok.shape[1]] |= ok
    return out


def _extreme3(a: np.ndarray, op) -> np.ndarray:
    """The 3x3 maximum (``op=np.maximum``) or minimum of ``a (H, W, C)`` per channel, edges repeated
    (``ndops.extreme3``)."""
    from .ndops import extreme3

    return extreme3(a, op is np.maximum)


MIXES_ON_EDGES = 128 * 128  # pictures of more pixels (not polished: options.Plan.max_side) explain only
# their edge pixels as mixes in ``_assign``: 0.73 -> 0.16 s on a 512 px logo of 8 colours, the same SVG at 2048 px
FLAT_BY_LEVELS = 512 * 512  # pictures of more pixels find their flat pixels on 8-bit levels


def _absorb_specks(labels: np.ndarray, min_px: int, eight: bool = False) -> np.ndarray:
    """Connected pieces (4-connected; ``eight``: 8-connected, as regions are, so that a clean render's
    stroke a pixel wide, whose pixels meet at corners, is one piece and not specks) smaller than
    ``min_px`` pixels take the commonest label of the pixels around them (their 4-neighbours of
    another colour). The specks of one colour never touch each other, so all of them are absorbed
    at once, colour by colour."""
    from .ndops import label

    labels = labels.copy()
    h, w = labels.shape
    index = np.arange(h * w).reshape(h, w)
    shifts = [(np.s_[1:, :], np.s_[:-1, :]), (np.s_[:-1, :], np.s_[1:, :]),
              (np.s_[:, 1:], np.s_[:, :-1]), (np.s_[:, :-1], np.s_[:, 1:])]
    for k in np.unique(labels):
        pieces, n = label(labels == k, eight)
        small = np.bincount(pieces.ravel(), minlength=n + 1) < min_px
        small[0] = False
        if not small.any():
            continue
        pairs = []  # (speck, the flat index of a pixel around it)
        for here, there in shifts:
            p, q = pieces[here], labels[there]
            m = small[p] & (q != k)
            pairs.append(p[m].astype(np.int64) * (h * w) + index[there][m])
        pairs = np.unique(np.concatenate(pairs))  # each pixel around a speck counted once
        speck, around = pairs // (h * w), labels.ravel()[pairs % (h * w)]
        votes = np.zeros((n + 1, int(labels.max()) + 1), dtype=np.int64)
        np.add.at(votes, (speck, around), 1)
        absorbed = small & (votes.max(1) > 0)
        take = absorbed[pieces]
        labels[take] = votes.argmax(1)[pieces[take]]
    return labels
