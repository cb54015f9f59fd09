"""A photo's pieces: its colours in fine steps, each piece of one step its own region.

A palette of a dozen colours (``palette.posterize``) cuts a photo's smooth shading into bands
whose steps show as edges the photo does not have, and merges neighbours of near colours
whose edge it does have. Here the photo's CIELAB values are cut into steps of ``STEP_L`` in
lightness and ``STEP_AB`` in a and b (about 15 grey levels: under the step an edge detector
sees), each 4-connected piece of one step is a piece, and pieces smaller than ``min_px`` are
merged into the neighbour nearest in colour until none is left (and no more than ``MAX_PIECES``), but marks
(``marks``: a stroke of text, a dot, darker or lighter than all around them). Each piece keeps the mean
colour of its pixels, so shading comes out as fine bands and edges stay where they are.

``looks_like_a_photo`` tells a photo (continuous tone) from a drawing (flat colours), grey ones too;
``agrees_better`` whether a drawing with shading (a gradient-filled icon, a shaded fish) is drawn
closer by a photo's pieces than by its palette's regions.

Frame: ``(H, W, 3)`` arrays in [0, 1], piece ids ``(H, W)``.
"""

from __future__ import annotations

import numpy as np

from ..options import Plan

STEP_L = 6.0  # CIELAB lightness of one step (of 100): about 15 levels of 255
STEP_AB = 12.0  # a and b of one step: hue and saturation change less where the eye looks
MARK_PX = 4  # a piece this small (2x2 px) that stands out of all it touches (``marks``) is kept: text, a dot...
MARK_RENDERED, MARK_GRAINY = STEP_L / 2, 2 * STEP_L  # ...by this lightness in a picture without grain, and with
MERGE_ROUNDS = 16  # rounds of merging small pieces (each merges all of them at once; 4-8 are usual)
PHOTO_SHARE = 0.6  # a picture whose 16 commonest colours (4 bits a channel) cover less than this share is a photo
GREY_PHOTO_SHARE = 0.35  # a grey picture whose 16 commonest 8-bit grey levels cover less than this is a photo (4 bits
# a channel leave a grey picture 16 colours in all): grey photos 0.16-0.24, grey drawings, icons and diagrams
# 0.44-1.0 in bench/wild.py's pictures (a rendered clock's shading 0.44)
GREY_SPREAD = 0.04  # a pixel whose channels are within this of each other is grey
PHOTO_SIGMA = 0.3  # px: a photo's blur before it is cut into pieces (bench/wild.py's 17 tuned photos, at most 9000
# pieces: 15 of 17 at or above both peers at 0.3 px, 14 with none (an apple's skin cut into specks), 13 at 0.5 px)
AGREE_MARGIN = 0.03  # edge F1 by which a drawing's pieces must agree better with it than its palette's regions
# (bench/wild.py's tuned drawings: 0.04-0.33 better where the pieces' trace was at or above both peers and the
# palette's was not; a 100 px star 0.30 better where the palette's trace was already exact)...
POLISHED_MARGIN = 0.05  # ...and a drawing the logo reading polishes (``options.Plan.max_side`` px a side at most)
# by this: its palette's raster draws hard the edges the polish fits (an OpenMoji FaceTime logo at 64 px, its pieces
# 0.043 better, was read as a photo: MSE@1x 0.0069, as a logo 0.0005; a 48 px Adwaita calculator, 0.033: 0.0070
# and 0.0043, edge F1 0.998 and 0.992)
TINT_PIXELS, TINT_MARGIN = 64 * 64, 0.7  # a two-tone-looking picture this small is read as colours where
# its palette's pixel error is under this share of its ink's (``tints_agree_better``)
AGREE_PIXELS = 1024 * 1024  # a larger drawing is judged on its window of this many pixels with the most edges (a
# quantise and a cut: about 1 s a megapixel, 6 s on a 2100 px diagram; an area-averaged copy blurs thin lines)
WINDOW_STEPS = 8  # the window is sought at this many steps across and down
GRAIN_PIECES = 0.75  # pieces of one step per pixel above which a picture is noise (RGB noise 0.99; the most
GRAIN_SIGMA = 2.0  # px: textured of bench/wild.py's photos, fur and a painting, 0.49): cut after this blur
MAX_PIECES = 9000  # a photo of more pieces (grain, noise) has its smallest merged until it has no more: the 17
# tuned photos of bench/wild.py have 500-7,500 at 4 px (fur and a circuit board lost their detail at 6,000); vtracer
# draws 300-6,100 paths on them. At most regions.MAX_REGIONS


def pieces(image: np.ndarray, min_px: int, mark_by: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """``(colours (K, 3), ids (H, W))``: the photo ``image`` cut into pieces of one colour step,
    none smaller than ``min_px`` px (but where a piece has no neighbour, or, with ``mark_by``, is a mark:
    ``merged``) and at most ``MAX_PIECES`` of them (the smallest size raised until so), each of the
    mean colour of its pixels."""
    from .ndops import equal_pieces, gaussian, rgb2lab

    lab = rgb2lab(image)
    ids, n = equal_pieces(_steps(lab))
    if n > GRAIN_PIECES * ids.size:  # noise, not a photo: its pieces from a blurred copy, fewer and rounder
        lab = rgb2lab(gaussian(image, GRAIN_SIGMA))
        ids, n = equal_pieces(_steps(lab))
    ids, n = merged(ids, n, lab, min_px, mark_by)
    while n > MAX_PIECES:  # the bound holds over marks: no mark is kept past it
        min_px = min_px * n // MAX_PIECES + 1
        ids, n = merged(ids, n, lab, min_px)
    return _means(ids, n, image), ids


def _steps(lab: np.ndarray) -> np.ndarray:
    """``(H, W)`` the number of each pixel's colour step (``STEP_L``, ``STEP_AB``) of CIELAB ``lab``."""
    steps = np.floor(lab / np.array([STEP_L, STEP_AB, STEP_AB])).astype(np.int64)
    steps -= steps.reshape(-1, 3).min(0)
    span = steps.reshape(-1, 3).max(0) + 1
    return (steps[..., 0] * span[1] + steps[..., 1]) * span[2] + steps[..., 2]


def _means(ids: np.ndarray, n: int, values: np.ndarray) -> np.ndarray:
    """``(n, C)`` the mean of ``values (H, W, C)`` over each piece of ``ids``."""
    flat = ids.ravel()
    area = np.maximum(np.bincount(flat, minlength=n), 1)
    return np.stack([np.bincount(flat, values[..., c].ravel(), minlength=n) for c in range(values.shape[-1])],
                    -1) / area[:, None]


def merged(ids: np.ndarray, n: int, values: np.ndarray, min_px: int, mark_by: float = 0.0) -> tuple[np.ndarray, int]:
    """Pieces ``ids (H, W)`` (0..n-1) with those smaller than ``min_px`` merged, round by round,
    into the 4-neighbour whose mean of ``values (H, W, C)`` is nearest theirs: ``(ids, n)``. With ``mark_by``, a
    piece of at least ``MARK_PX`` px that is a mark by that much lightness (``marks``: text, a dot) is kept.
    A piece and the one it picks may pick each other: the larger takes the smaller. No other
    loop is possible (each pick is the nearest, so the distances along a loop could not
    all fall), and chains are followed to their end."""
    for _ in range(MERGE_ROUNDS):
        area = np.bincount(ids.ravel(), minlength=n)
        small = area < min_px
        if not small.any():
            break
        mean = _means(ids, n, values)
        across, down = ids[:, 1:] != ids[:, :-1], ids[1:] != ids[:-1]  # where two pieces touch
        a = np.concatenate([ids[:, 1:][across], ids[1:][down]])
        b = np.concatenate([ids[:, :-1][across], ids[:-1][down]])
        a, b = np.concatenate([a, b]), np.concatenate([b, a])  # each touching pair both ways
        if mark_by:
            small &= ~(marks(mean[:, 0], a, b, mark_by) & (area >= MARK_PX))
        keep = small[a]
        if not keep.any():
            break
        a, b = a[keep], b[keep]
        order = np.lexsort((b, ((mean[a] - mean[b]) ** 2).sum(-1), a))  # per small piece, nearest first
        a, b = a[order], b[order]
        first = np.r_[True, a[1:] != a[:-1]]
        parent = np.arange(n)
        parent[a[first]] = b[first]
        me = np.arange(n)
        mutual = (parent != me) & (parent[parent] == me)
        stays = mutual & ((area > area[parent]) | ((area == area[parent]) & (me < parent)))
        parent[stays] = me[stays]
        while True:
            up = parent[parent]
            if (up == parent).all():
                break
            parent = up
        roots, parent = np.unique(parent, return_inverse=True)
        ids, n = parent[ids], len(roots)
    return ids, n


def marks(lum: np.ndarray, a: np.ndarray, b: np.ndarray, by: float) -> np.ndarray:
    """``(n,)`` bool: the pieces whose lightness ``lum (n,)`` is darker, or lighter, than that of every piece they
    touch (the pairs ``a``-``b``, both ways) by more than ``by``: marks of their own (a stroke of text, a dot), not the
    mix along an edge between two colours, which lies between its neighbours."""
    lo, hi = np.full(len(lum), np.inf), np.full(len(lum), -np.inf)
    np.minimum.at(lo, a, lum[b])
    np.maximum.at(hi, a, lum[b])
    return (lum < lo - by) | (lum > hi + by)


def looks_like_a_photo(picture: np.ndarray) -> bool:
    """Whether ``picture (H, W, 3)`` is continuous tone: its 16 commonest colours cover less than
    ``PHOTO_SHARE`` of it, or, grey, its 16 commonest grey levels less than ``GREY_PHOTO_SHARE``."""
    return color_share(picture, 16) < PHOTO_SHARE or grey_share(picture) < GREY_PHOTO_SHARE


def color_share(picture: np.ndarray, k: int) -> float:
    """The share of the pixels that the ``k`` commonest colours (4 bits a channel) cover: near 1
    for flat colours, JPEG'd or not; about half or less for a photo."""
    q = (picture[:: max(1, picture.shape[0] // 256), :: max(1, picture.shape[1] // 256)] * 15.999).astype(np.int64)
    counts = np.bincount(((q[..., 0] << 8) | (q[..., 1] << 4) | q[..., 2]).ravel(), minlength=4096)
    return float(np.sort(counts)[::-1][:k].sum() / counts.sum())


def grey_share(picture: np.ndarray, k: int = 16) -> float:
    """For a grey picture (all its pixels grey within ``GREY_SPREAD``), the share of its pixels
    that its ``k`` commonest 8-bit grey levels cover; 1 for a picture in colour."""
    from .ndops import mean3, spread3

    sample = picture[:: max(1, picture.shape[0] // 256), :: max(1, picture.shape[1] // 256)]
    if (spread3(sample) > GREY_SPREAD).any():
        return 1.0
    counts = np.bincount((mean3(sample) * 255.999).astype(np.int64).ravel(), minlength=256)
    return float(np.sort(counts)[::-1][:k].sum() / counts.sum())


def agrees_better(picture: np.ndarray, min_px: int, mark_by: float = 0.0, seed: int = 0) -> tuple[bool, dict]:
    """Whether the drawing ``picture (H, W, 3)`` (multi-colour, not hard-edged) agrees better with
    itself cut into a photo's ``pieces`` (as ``read.read`` cuts a photo) than quantised to its
    palette (``palette.quantize``, as a logo is): each drawn as a raster of its labels' colours,
    the pieces' edges agree by at least ``AGREE_MARGIN`` (where the logo is polished, ``POLISHED_MARGIN``) more
    (``edge_agreement``) and their pixel error is no larger (never where the palette's agree within the margin of 1: the
    pieces are not cut). With the agreements worked out, for ``-v``."""
    from .ndops import gaussian
    from .palette import quantize

    margin = POLISHED_MARGIN if max(picture.shape[:2]) <= Plan.max_side else AGREE_MARGIN
    picture = busiest_window(picture)
    palette, labels = quantize(picture, None, seed)
    logo = palette[labels]
    edges = {"logo_edges": edge_agreement(picture, logo)}
    if edges["logo_edges"] + margin > 1:  # no cut can agree by the margin more (a flat logo): not cut
        return False, {k: round(v, 3) for k, v in edges.items()}
    colours, ids = pieces(gaussian(picture, PHOTO_SIGMA), min_px, mark_by)
    photo = colours[ids]
    edges["photo_edges"] = edge_agreement(picture, photo)
    better = edges["photo_edges"] >= edges["logo_edges"] + margin and (
        ((photo - picture) ** 2).mean() <= ((logo - picture) ** 2).mean())
    return bool(better), {k: round(v, 3) for k, v in edges.items()}


def tints_agree_better(picture: np.ndarray, bg: np.ndarray, ink: np.ndarray, alpha: np.ndarray) -> bool:
    """Whether a picture ``(H, W, 3)`` of at most ``TINT_PIXELS`` px that looks two-tone (``ink (3,)`` at coverage
    ``alpha (H, W)`` over ``bg``) is drawn nearer by its palette's regions (``palette.quantize``, as a logo is)
    than by its ink where ``alpha`` is half or more (as it is traced), by ``TINT_MARGIN`` of the pixel error: its
    in-between shades are flat tints of their own, not edges (a 22-32 px icon's light fill inside its 1 px
    outline, a key's grey face; 2 of the 201 two-tone pictures of tests/assets' test sets, where 27 of 110 Tango
    22-32 px icons outside bench/wild.py's)."""
    from .palette import quantize

    if picture.shape[0] * picture.shape[1] > TINT_PIXELS:
        return False
    palette, labels = quantize(picture, None)
    two = bg + (alpha >= 0.5)[..., None] * (ink - bg)
    return bool(((palette[labels] - picture) ** 2).mean() < TINT_MARGIN * ((two - picture) ** 2).mean())


def busiest_window(picture: np.ndarray) -> np.ndarray:
    """``picture (H, W, 3)`` itself where it has at most ``AGREE_PIXELS`` pixels, else its square
    window of that many (or a band as wide as a narrow picture), at one of ``WINDOW_STEPS`` + 1
    places each way, with the most Canny edges (``edge_agreement``'s): a screenshot's text, a plot's
    marks, where a cut and a palette differ."""
    h, w, _ = picture.shape
    if h * w <= AGREE_PIXELS:
        return picture
    side = int(AGREE_PIXELS**0.5)
    sh, sw = min(h, max(side, AGREE_PIXELS // w)), min(w, max(side, AGREE_PIXELS // h))
    sums = np.pad(_edges(picture).cumsum(0, dtype=np.int64).cumsum(1), ((1, 0), (1, 0)))
    ys = np.unique(np.linspace(0, h - sh, WINDOW_STEPS + 1).round().astype(int))
    xs = np.unique(np.linspace(0, w - sw, WINDOW_STEPS + 1).round().astype(int))
    y, x = ys[:, None], xs[None, :]
    counts = sums[y + sh, x + sw] - sums[y, x + sw] - sums[y + sh, x] + sums[y, x]
    i, j = np.unravel_index(np.argmax(counts), counts.shape)
    return picture[ys[i] : ys[i] + sh, xs[j] : xs[j] + sw]


def _edges(rgb: np.ndarray) -> np.ndarray:
    """Canny's edges of ``rgb (H, W, 3)`` in [0, 1] on grey blurred by a Gaussian of 1 px, thresholds 50 and 150 of
    255 (bench/wild.py's)."""
    import cv2

    grey = cv2.cvtColor((np.clip(rgb, 0, 1) * 255).round().astype(np.uint8), cv2.COLOR_RGB2GRAY)
    return cv2.Canny(cv2.GaussianBlur(grey, (0, 0), 1.0), 50, 150) > 0


def edge_agreement(picture: np.ndarray, drawn: np.ndarray, within: float = 1.5) -> float:
    """F1 of the edges of ``drawn`` against those of ``picture`` (both ``(H, W, 3)`` in [0, 1]):
    Canny's (on grey blurred by a Gaussian of 1 px, thresholds 50 and 150 of 255), an edge found
    where the other has one within ``within`` px; 1 where neither has any (bench/wild.py's score)."""
    import cv2

    a, b = _edges(picture), _edges(drawn)
    if not a.any() or not b.any():
        return float(a.any() == b.any())
    near_a = cv2.distanceTransform((~a).astype(np.uint8), cv2.DIST_L2, 5) <= within
    near_b = cv2.distanceTransform((~b).astype(np.uint8), cv2.DIST_L2, 5) <= within
    precision, recall = (b & near_a).sum() / b.sum(), (a & near_b).sum() / a.sum()
    return float(2 * precision * recall / max(precision + recall, 1e-12))
