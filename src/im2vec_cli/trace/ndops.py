"""The image operations the trace uses, on OpenCV: pieces, morphology, filters, distances, k-means.

Each function says which SciPy / scikit-image call it stands for and gives the same result
(tests/trace/test_ndops.py checks every one against that library on random pictures). They are
here, on OpenCV, because importing ``scipy.ndimage`` and ``scipy.cluster.vq`` costs 0.2-0.4 s a
process (SciPy 1.17's array-API layer) and ``skimage.filters`` more, where ``import cv2`` costs
about 0.02 s beyond NumPy: a traced picture's whole call is about that long (issue 70). OpenCV's
kernels are also 5-50x faster per call on the small boxes the trace works in.

Masks are ``(H, W)`` bool, fields ``(H, W)`` float64; 2-D only unless a function says.
"""

from __future__ import annotations

import functools

import cv2
import numpy as np

CROSS = cv2.getStructuringElement(cv2.MORPH_CROSS, (3, 3))  # SciPy's default structure: 4-connected


def _u8(mask: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(mask, dtype=np.uint8)


def label(mask: np.ndarray, eight: bool = False) -> tuple[np.ndarray, int]:
    """``scipy.ndimage.label(mask)`` (``eight``: ``structure=np.ones((3, 3))``): ``(H, W)`` int32
    labels 1..n of the connected pieces, numbered in raster order of their first pixel, and n."""
    n, lab = cv2.connectedComponentsWithAlgorithm(_u8(mask), 8 if eight else 4, cv2.CV_32S, cv2.CCL_WU)
    return lab, n - 1


def pieces(mask: np.ndarray, eight: bool = False) -> tuple[np.ndarray, list[tuple[slice, slice]]]:
    """``label`` and ``scipy.ndimage.find_objects`` of its labels: the labels and each piece's box."""
    n, lab, stats, _ = cv2.connectedComponentsWithStatsWithAlgorithm(_u8(mask), 8 if eight else 4, cv2.CV_32S,
                                                                     cv2.CCL_WU)
    x, y, w, h = (stats[1:, i].tolist() for i in range(4))
    return lab, [(slice(b, b + d), slice(a, a + c)) for a, b, c, d in zip(x, y, w, h)]


def equal_pieces(values: np.ndarray) -> tuple[np.ndarray, int]:
    """The 4-connected pieces of equal value in ``values (H, W)`` (any integers), as
    ``skimage.measure.label(values, background=None, connectivity=1)`` finds them: ``(H, W)``
    ids 0..n-1 and n. Each pixel sits on the even points of a grid twice as fine, whose odd
    points join two neighbours of equal value; one binary labelling of that grid finds them all."""
    h, w = values.shape
    grid = np.zeros((2 * h - 1, 2 * w - 1), dtype=np.uint8)
    grid[::2, ::2] = 1
    grid[::2, 1::2] = values[:, 1:] == values[:, :-1]
    grid[1::2, ::2] = values[1:] == values[:-1]
    n, lab = cv2.connectedComponentsWithAlgorithm(grid, 4, cv2.CV_32S, cv2.CCL_WU)
    return lab[::2, ::2] - 1, n - 1


def fill_holes(mask: np.ndarray) -> np.ndarray:
    """``scipy.ndimage.binary_fill_holes(mask)``: the background pieces (4-connected) that do
    not touch the border filled."""
    lab, _ = label(~mask)
    edge = np.unique(np.concatenate([lab[0], lab[-1], lab[:, 0], lab[:, -1]]))
    outside = np.zeros(int(lab.max()) + 1, dtype=bool)
    outside[edge] = True
    outside[0] = False
    return ~outside[lab]


def _kernel(structure: np.ndarray | None) -> np.ndarray:
    return CROSS if structure is None else _u8(structure)


def dilate(mask: np.ndarray, structure: np.ndarray | None = None, iterations: int = 1, border: int = 0) -> np.ndarray:
    """``scipy.ndimage.binary_dilation(mask, structure, iterations, border_value=border)``
    (``structure`` symmetric, odd-sized; default the cross)."""
    if iterations < 1:
        raise ValueError(f"dilate: iterations must be >= 1, got {iterations}")
    out = cv2.dilate(_u8(mask), _kernel(structure), iterations=iterations, borderType=cv2.BORDER_CONSTANT,
                     borderValue=border)
    return out.astype(bool)


def erode(mask: np.ndarray, structure: np.ndarray | None = None, border: int = 0) -> np.ndarray:
    """``scipy.ndimage.binary_erosion(mask, structure, border_value=border)`` (``structure``
    symmetric, odd-sized; default the cross)."""
    out = cv2.erode(_u8(mask), _kernel(structure), borderType=cv2.BORDER_CONSTANT, borderValue=border)
    return out.astype(bool)


def opening(mask: np.ndarray, structure: np.ndarray, border: int = 0) -> np.ndarray:
    """``scipy.ndimage.binary_opening(mask, structure, border_value=border)``: erosion then
    dilation, the outside ``border`` for both. An even-sized ``structure`` is centred as SciPy
    centres it (its centre at ``size // 2``)."""
    k = _u8(structure)
    anchor = (k.shape[1] // 2, k.shape[0] // 2)
    kw = dict(anchor=anchor, borderType=cv2.BORDER_CONSTANT, borderValue=border)
    eroded = cv2.erode(_u8(mask), k, **kw)
    # SciPy's dilation reflects the structure (its centre moves to the other side for even sizes)
    flipped = k[::-1, ::-1].copy()
    back = ((k.shape[1] - 1) - anchor[0], (k.shape[0] - 1) - anchor[1])
    return cv2.dilate(eroded, flipped, anchor=back, borderType=cv2.BORDER_CONSTANT, borderValue=border).astype(bool)


def grey_closing(field: np.ndarray, footprint: np.ndarray) -> np.ndarray:
    """``scipy.ndimage.grey_closing(field, footprint=footprint)`` (flat, edges mirrored): the
    maximum over the footprint, then the minimum over it reflected."""
    k = _u8(footprint)
    anchor = (k.shape[1] // 2, k.shape[0] // 2)
    flipped = k[::-1, ::-1].copy()
    back = ((k.shape[1] - 1) - anchor[0], (k.shape[0] - 1) - anchor[1])
    a = np.ascontiguousarray(field, dtype=np.float64)
    grown = cv2.dilate(a, flipped, anchor=back, borderType=cv2.BORDER_REFLECT)
    return cv2.erode(grown, k, anchor=anchor, borderType=cv2.BORDER_REFLECT)


def gaussian(field: np.ndarray, sigma: float) -> np.ndarray:
    """``scipy.ndimage.gaussian_filter(field, sigma)`` in each channel of ``(H, W)`` or
    ``(H, W, C)`` (``sigma`` along H and W only), edges mirrored, the kernel cut at 4 sigma
    and normalised as SciPy's; float64 out. A float32 ``field`` is rounded to float32 after
    each axis, as SciPy's float32 output is (then returned as float64)."""
    phi, one = _gaussian_kernel(float(sigma)), np.ones(1)
    if np.asarray(field).dtype == np.float32:
        a = np.ascontiguousarray(field)
        a = cv2.sepFilter2D(a.astype(np.float64), cv2.CV_64F, one, phi, borderType=cv2.BORDER_REFLECT)  # along H
        a = cv2.sepFilter2D(a.astype(np.float32).astype(np.float64), cv2.CV_64F, phi, one,
                            borderType=cv2.BORDER_REFLECT)
        return a.astype(np.float32).astype(np.float64)
    a = np.ascontiguousarray(field, dtype=np.float64)
    return cv2.sepFilter2D(a, cv2.CV_64F, phi, phi, borderType=cv2.BORDER_REFLECT)


@functools.lru_cache(maxsize=16)
def _gaussian_kernel(sigma: float) -> np.ndarray:
    """SciPy's 1-D Gaussian of ``sigma``, cut at 4 sigma and normalised (shared, read-only)."""
    radius = int(4.0 * sigma + 0.5)
    x = np.arange(-radius, radius + 1)
    phi = np.exp(-0.5 / (sigma * sigma) * x**2)
    phi = phi / phi.sum()
    phi.flags.writeable = False
    return phi


def box_mean(field: np.ndarray, size: int) -> np.ndarray:
    """``scipy.ndimage.uniform_filter(field, size)`` (odd ``size``, edges mirrored), float64."""
    a = np.ascontiguousarray(field, dtype=np.float64)
    return cv2.boxFilter(a, cv2.CV_64F, (size, size), normalize=True, borderType=cv2.BORDER_REFLECT)


def convolve(field: np.ndarray, kernel: np.ndarray) -> np.ndarray:
    """``scipy.ndimage.convolve(field, kernel, mode="reflect")`` (odd-sized ``kernel``), float64."""
    a = np.ascontiguousarray(field, dtype=np.float64)
    return cv2.filter2D(a, cv2.CV_64F, np.ascontiguousarray(kernel[::-1, ::-1], dtype=np.float64),
                        borderType=cv2.BORDER_REFLECT)


def median3(field: np.ndarray) -> np.ndarray:
    """``scipy.ndimage.median_filter(field, size=(3, 3[, 1]))`` of a float32 ``(H, W)`` or
    ``(H, W, 3)``: each channel's 3x3 median (edges mirrored: for 3x3 the same as repeated)."""
    return cv2.medianBlur(np.ascontiguousarray(field, dtype=np.float32), 3)


def max_filter(mask: np.ndarray, size: int) -> np.ndarray:
    """``scipy.ndimage.maximum_filter(mask, size)`` of a bool ``(H, W)`` (odd ``size``)."""
    k = np.ones((size, size), dtype=np.uint8)
    return cv2.dilate(_u8(mask), k, borderType=cv2.BORDER_REFLECT).astype(bool)


def mean3(a: np.ndarray) -> np.ndarray:
    """``a.mean(-1)`` of ``(..., 3)``, bit for bit (summed in the same order), on whole channels
    (``norm3``): 4x faster."""
    return (a[..., 0] + a[..., 1] + a[..., 2]) / 3


def spread3(a: np.ndarray) -> np.ndarray:
    """``np.ptp(a, axis=-1)`` of ``(..., 3)`` on whole channels (``norm3``): 7x faster."""
    x, y, z = a[..., 0], a[..., 1], a[..., 2]
    return np.maximum(np.maximum(x, y), z) - np.minimum(np.minimum(x, y), z)


def rgb_keys(q: np.ndarray) -> np.ndarray:
    """One int64 a colour: the 8-bit channels ``q (..., 3)`` (integers 0-255) packed, red highest."""
    return (q[..., 0] << 16) | (q[..., 1] << 8) | q[..., 2]


def rgb_of_keys(keys: np.ndarray) -> np.ndarray:
    """``rgb_keys`` undone: the colours ``(..., 3)`` in [0, 1] of packed 8-bit ``keys``."""
    return np.stack([keys >> 16, (keys >> 8) & 255, keys & 255], -1) / 255


def norm3(a: np.ndarray) -> np.ndarray:
    """``np.linalg.norm(a, axis=-1)`` of ``(..., 3)``, bit for bit (the squares summed in the same
    order), on whole channels: 2-4x faster than NumPy's reduction over a last axis of 3."""
    x, y, z = a[..., 0], a[..., 1], a[..., 2]
    return np.sqrt(x * x + y * y + z * z)


def extreme3(a: np.ndarray, maximum: bool) -> np.ndarray:
    """The 3x3 maximum (or minimum) of ``a (H, W, C)`` in each channel, edges repeated (SciPy's
    ``maximum_filter(a, size=(3, 3, 1), mode="nearest")``); any number of channels; uint8,
    float32 or float64."""
    op = cv2.dilate if maximum else cv2.erode
    k = np.ones((3, 3), dtype=np.uint8)
    chans = [np.ascontiguousarray(a[..., i : i + 4]) for i in range(0, a.shape[-1], 4)]  # OpenCV: <= 4 channels
    out = [op(c, k, borderType=cv2.BORDER_REPLICATE).reshape(c.shape) for c in chans]
    return out[0] if len(out) == 1 else np.concatenate(out, -1)


def distance(mask: np.ndarray) -> np.ndarray:
    """``scipy.ndimage.distance_transform_edt(mask)``: each true pixel's exact Euclidean distance
    to the nearest false one (0 on false pixels), float64; ``mask`` must hold a false pixel."""
    d = cv2.distanceTransform(_u8(mask), cv2.DIST_L2, cv2.DIST_MASK_PRECISE, dstType=cv2.CV_32F)
    return np.sqrt(np.round(d.astype(np.float64) ** 2))  # squared distances are integers: exact in float64


def remove_small(mask: np.ndarray, max_size: int) -> np.ndarray:
    """``skimage.morphology.remove_small_objects(mask, max_size=max_size)``: pieces (4-connected)
    of at most ``max_size`` pixels removed."""
    n, lab, stats, _ = cv2.connectedComponentsWithStats(_u8(mask), connectivity=4, ltype=cv2.CV_32S)
    keep = stats[:, cv2.CC_STAT_AREA] > max_size
    keep[0] = False
    return keep[lab]


def otsu(values: np.ndarray, bins: int = 256) -> float:
    """``skimage.filters.threshold_otsu(values)``: the bin centre (of ``bins`` over the values'
    range) that maximises the between-class variance; a constant input is its own threshold."""
    v = np.asarray(values).ravel()
    if np.all(v == v[0]):
        return v[0]
    counts, edges = np.histogram(v, bins=bins, range=(v.min(), v.max()))
    counts = counts.astype(np.float32)
    centers = (edges[:-1] + edges[1:]) / 2.0
    w1, w2 = np.cumsum(counts), np.cumsum(counts[::-1])[::-1]
    m1 = np.cumsum(counts * centers) / w1
    m2 = (np.cumsum((counts * centers)[::-1]) / w2[::-1])[::-1]
    return centers[np.argmax(w1[:-1] * w2[1:] * (m1[:-1] - m2[1:]) ** 2)]


def kmeans(data: np.ndarray, k: int, rng: np.random.Generator, iterations: int = 20) -> tuple[np.ndarray, np.ndarray]:
    """``scipy.cluster.vq.kmeans2(data, k, minit="++", seed=rng, iter=iterations)``: k-means++
    seeds drawn from ``rng`` as SciPy draws them, then ``iterations`` rounds of Lloyd's (an empty
    cluster keeps its centre). ``data (N, D)`` float64 -> centres ``(k, D)`` and labels ``(N,)``."""
    data = np.asarray(data, dtype=np.float64)
    rows, back = distinct(data)  # what depends on a row's value alone is worked out once a value
    centres = np.empty((k, data.shape[1]))
    near = np.full(len(rows), np.inf)  # (M,) squared distance to the nearest seed so far
    for i in range(k):
        if i == 0:
            j = int(rng.integers(data.shape[0], dtype="int64"))
        else:
            near = np.minimum(near, ((rows - centres[i - 1]) ** 2).sum(-1))
            d2 = near[back]  # (N,)
            j = int(np.searchsorted((d2 / d2.sum()).cumsum(), rng.uniform()))
        centres[i] = data[j]
    labels = np.zeros(len(data), dtype=np.int32)
    cols = [np.ascontiguousarray(data[:, j]) for j in range(data.shape[1])]
    for it in range(iterations):
        last, labels = labels, nearest(rows, centres)[back]
        if it and np.array_equal(labels, last):  # the same labels give the same centres: settled
            break
        counts = np.bincount(labels, minlength=k)
        sums = np.stack([np.bincount(labels, weights=c, minlength=k) for c in cols], 1)  # summed in data order
        centres = np.where((counts > 0)[:, None], sums / np.maximum(counts, 1)[:, None], centres)
    return centres, labels


def distinct(pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distinct colours ``(M, 3)`` of ``pixels (N, 3)`` and each pixel's ``(N,)`` index among
    them: what depends on a pixel's colour alone is worked out once a colour (a logo's 65,536
    sampled pixels hold a few thousand)."""
    order = np.lexsort(pixels.T[::-1])  # rows in lexicographic order (np.unique(axis=0)'s, 6x faster)
    ranked = pixels[order]
    new = np.ones(len(ranked), dtype=bool)
    new[1:] = (ranked[1:] != ranked[:-1]).any(1)
    back = np.empty(len(ranked), dtype=np.int64)
    back[order] = np.cumsum(new) - 1
    return ranked[new], back


def run_places(counts: np.ndarray) -> np.ndarray:
    """For runs of ``counts (R,)`` items laid end to end, each item's place in its run:
    ``(sum(counts),)`` int64, ``arange(c)`` of each run one after another."""
    counts = np.asarray(counts, dtype=np.int64)
    return np.arange(int(counts.sum())) - np.repeat(np.cumsum(counts) - counts, counts)


def nearest(data: np.ndarray, centres: np.ndarray) -> np.ndarray:
    """``scipy.cluster.vq.vq(data, centres)[0]``: each row's nearest centre (squared Euclidean,
    summed over the columns in order; the first on a tie); ``(N,)`` int32."""
    cols = [np.ascontiguousarray(data[:, j]) for j in range(data.shape[1])]
    best = np.full(len(data), np.inf)
    out = np.zeros(len(data), dtype=np.int32)
    for i, c in enumerate(centres):
        d = (cols[0] - c[0]) ** 2
        for j in range(1, len(cols)):
            d += (cols[j] - c[j]) ** 2
        closer = d < best
        best[closer] = d[closer]
        out[closer] = i
    return out


# CIE L*a*b* under D65 (2 degrees), as scikit-image's rgb2lab / lab2rgb compute it
_RGB_XYZ = np.array([[0.412453, 0.357580, 0.180423], [0.212671, 0.715160, 0.072169], [0.019334, 0.119193, 0.950227]])
_XYZ_RGB = np.linalg.inv(_RGB_XYZ)
_WHITE = np.array([0.95047, 1.0, 1.08883])


def rgb2lab(rgb: np.ndarray) -> np.ndarray:
    """``skimage.color.rgb2lab(rgb)`` of ``(..., 3)`` sRGB in [0, 1]."""
    a = np.asarray(rgb, dtype=np.float64)
    lin = np.where(a > 0.04045, ((a + 0.055) / 1.055) ** 2.4, a / 12.92)
    xyz = (lin @ _RGB_XYZ.T) / _WHITE
    f = np.where(xyz > 0.008856, np.cbrt(xyz), 7.787 * xyz + 16.0 / 116.0)
    x, y, z = f[..., 0], f[..., 1], f[..., 2]
    return np.stack([116.0 * y - 16.0, 500.0 * (x - y), 200.0 * (y - z)], -1)


def lab2rgb(lab: np.ndarray) -> np.ndarray:
    """``skimage.color.lab2rgb(lab)`` of ``(..., 3)``: sRGB clipped to [0, 1]."""
    a = np.asarray(lab, dtype=np.float64)
    y = (a[..., 0] + 16.0) / 116.0
    x, z = a[..., 1] / 500.0 + y, y - a[..., 2] / 200.0
    z = np.maximum(z, 0)
    f = np.stack([x, y, z], -1)
    xyz = np.where(f > 0.2068966, f**3, (f - 16.0 / 116.0) / 7.787) * _WHITE
    lin = xyz @ _XYZ_RGB.T
    rgb = np.where(lin > 0.0031308, 1.055 * np.power(np.maximum(lin, 0), 1 / 2.4) - 0.055, 12.92 * lin)
    return np.clip(rgb, 0, 1)


def boxes(labels: np.ndarray, n: int) -> list[tuple[slice, slice]]:
    """The box of each label ``0..n-1`` of ``labels (H, W)`` (each present), as
    ``scipy.ndimage.find_objects(labels + 1)`` gives them."""
    h, w = labels.shape
    flat = labels.ravel()
    rows, cols = np.divmod(np.arange(h * w), w)
    lo_y, lo_x, hi_y, hi_x = np.full(n, h), np.full(n, w), np.zeros(n, dtype=np.int64), np.zeros(n, dtype=np.int64)
    np.minimum.at(lo_y, flat, rows)
    np.minimum.at(lo_x, flat, cols)
    np.maximum.at(hi_y, flat, rows)
    np.maximum.at(hi_x, flat, cols)
    return [(slice(a, b + 1), slice(c, d + 1)) for a, b, c, d in zip(lo_y.tolist(), hi_y.tolist(), lo_x.tolist(),
                                                                       hi_x.tolist())]
