"""trace.ndops against the libraries each function stands for (SciPy, scikit-image), on random pictures."""

import numpy as np
import pytest
import scipy.ndimage as ndi
from scipy.cluster.vq import kmeans2, vq
from skimage.color import lab2rgb, rgb2lab
from skimage.filters import threshold_otsu
from skimage.morphology import remove_small_holes, remove_small_objects

from im2vec_cli.trace import ndops


def masks(seed: int, n: int = 6):
    """Random blobby masks of several sizes (odd, even, thin) and densities."""
    rng = np.random.default_rng(seed)
    for i in range(n):
        h, w = rng.integers(1, 40, 2) if i else (1, 1)
        noise = ndi.gaussian_filter(rng.random((h, w)), rng.uniform(0, 2))
        yield noise > np.quantile(noise, rng.uniform(0.2, 0.8))


@pytest.mark.parametrize("seed", range(8))
def test_pieces_match_scipy(seed):
    for m in masks(seed):
        for eight in (False, True):
            ref, n = ndi.label(m, structure=np.ones((3, 3)) if eight else None)
            lab, got_n = ndops.label(m, eight)
            assert got_n == n and np.array_equal(lab, ref)  # same numbering: raster order
            lab2, boxes = ndops.pieces(m, eight)
            assert np.array_equal(lab2, ref) and boxes == ndi.find_objects(ref)
        assert np.array_equal(ndops.fill_holes(m), ndi.binary_fill_holes(m))


@pytest.mark.parametrize("seed", range(8))
def test_equal_pieces_match_skimage(seed):
    """Pieces of equal value, numbered in raster order, as skimage's multi-valued labelling finds them."""
    from skimage.measure import label

    rng = np.random.default_rng(seed)
    for levels in (2, 3, 6):
        values = rng.integers(0, levels, (int(rng.integers(1, 40)), int(rng.integers(1, 40))))
        ids, n = ndops.equal_pieces(values)
        ref = label(values + 1, background=0, connectivity=1)
        assert n == ref.max() and np.array_equal(ids + 1, ref)


@pytest.mark.parametrize("seed", range(8))
def test_morphology_matches_scipy(seed):
    for m in masks(seed):
        for it in (1, 3):
            assert np.array_equal(ndops.dilate(m, iterations=it), ndi.binary_dilation(m, iterations=it))
        assert np.array_equal(ndops.erode(m), ndi.binary_erosion(m))
        assert np.array_equal(ndops.max_filter(m, 5), ndi.maximum_filter(m, size=5))
        for size in (2, 3, 4):
            k = np.ones((size, size), dtype=bool)
            for border in (0, 1):
                assert np.array_equal(ndops.opening(m, k, border), ndi.binary_opening(m, k, border_value=border))
            field = m * np.random.default_rng(seed).random(m.shape)
            assert np.allclose(ndops.grey_closing(field, k), ndi.grey_closing(field, footprint=k), rtol=0, atol=0)


@pytest.mark.parametrize("seed", range(6))
def test_filters_match_scipy(seed):
    rng = np.random.default_rng(seed)
    a = rng.random((int(rng.integers(3, 50)), int(rng.integers(3, 50))))
    for sigma in (0.6, 0.8, 1.3):
        assert np.allclose(ndops.gaussian(a, sigma), ndi.gaussian_filter(a, sigma), rtol=0, atol=1e-14)
    rgb = rng.random(a.shape + (3,))
    assert np.allclose(ndops.gaussian(rgb, 0.9), ndi.gaussian_filter(rgb, (0.9, 0.9, 0)), rtol=0, atol=1e-14)
    f32 = rgb.astype(np.float32)  # rounded to float32 after each axis, as SciPy's float32 output is
    assert np.allclose(ndops.gaussian(f32, 1.1), ndi.gaussian_filter(f32, (1.1, 1.1, 0)), rtol=0, atol=1e-7)
    assert np.allclose(ndops.box_mean(a, 5), ndi.uniform_filter(a, 5), rtol=0, atol=1e-14)
    mask = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], dtype=np.float64)
    tilt = mask * np.arange(1, 10).reshape(3, 3)  # not symmetric: convolution flips it
    for k in (mask, tilt):
        assert np.allclose(ndops.convolve(a, k), ndi.convolve(a, k, mode="reflect"), rtol=0, atol=1e-12)
    f32 = rgb.astype(np.float32)
    assert np.array_equal(ndops.median3(f32), ndi.median_filter(f32, size=(3, 3, 1)))
    assert np.array_equal(ndops.median3(f32[..., 0]), ndi.median_filter(f32[..., 0], size=3))


@pytest.mark.parametrize("dtype", [np.float64, np.float32, np.uint8])
def test_extreme3_matches_scipy(dtype):
    rng = np.random.default_rng(3)
    for shape in [(1, 1, 1), (7, 5, 1), (20, 31, 3), (4, 9, 6)]:
        a = (rng.random(shape) * 200).astype(dtype)
        for maximum, ref in ((True, ndi.maximum_filter), (False, ndi.minimum_filter)):
            got = ndops.extreme3(a, maximum)
            assert got.dtype == a.dtype and np.array_equal(got, ref(a, size=(3, 3, 1), mode="nearest"))


@pytest.mark.parametrize("seed", range(8))
def test_distance_matches_scipy(seed):
    for m in masks(seed):
        if m.all():
            continue
        assert np.array_equal(ndops.distance(m), ndi.distance_transform_edt(m))


@pytest.mark.parametrize("seed", range(8))
def test_small_pieces_and_otsu_match_scikit_image(seed):
    for m in masks(seed):
        for size in (0, 3, 10):
            assert np.array_equal(ndops.remove_small(m, size), remove_small_objects(m, max_size=size))
            assert np.array_equal(~ndops.remove_small(~m, size), remove_small_holes(m, max_size=size))
    rng = np.random.default_rng(seed)
    v = np.concatenate([rng.normal(0.2, 0.05, 300), rng.normal(0.8, 0.1, 500)])
    assert ndops.otsu(v) == threshold_otsu(v)
    assert ndops.otsu(np.full(7, 0.3)) == threshold_otsu(np.full(7, 0.3))


@pytest.mark.parametrize("seed", range(6))
def test_kmeans_matches_scipy_draw_for_draw(seed):
    rng = np.random.default_rng(seed)
    data = np.concatenate([rng.normal(c, 0.05, (200, 3)) for c in rng.random((5, 3))])
    for k in (1, 3, 7):
        a, b = np.random.default_rng(seed), np.random.default_rng(seed)
        ref_c, ref_l = kmeans2(data, k, minit="++", seed=a, iter=20)
        got_c, got_l = ndops.kmeans(data, k, b, 20)
        assert np.array_equal(got_c, ref_c) and np.array_equal(got_l, ref_l)
        assert a.random() == b.random()  # the generator is left where SciPy leaves it
        assert np.array_equal(ndops.nearest(data, ref_c), vq(data, ref_c)[0])


def test_lab_matches_scikit_image():
    rgb = np.random.default_rng(0).random((40, 30, 3))
    rgb[0, :4] = [[0, 0, 0], [1, 1, 1], [0.01, 0.02, 0.03], [1, 0, 0]]
    assert np.allclose(ndops.rgb2lab(rgb), rgb2lab(rgb), rtol=0, atol=1e-12)
    lab = rgb2lab(rgb)
    assert np.allclose(ndops.lab2rgb(lab), lab2rgb(lab), rtol=0, atol=1e-12)


def test_norm3_is_numpys_norm_bit_for_bit():
    a = np.random.default_rng(5).normal(size=(17, 23, 3))
    assert np.array_equal(ndops.norm3(a), np.linalg.norm(a, axis=-1))
    assert np.array_equal(ndops.norm3(a[:, 0]), np.linalg.norm(a[:, 0], axis=-1))


def test_run_places_counts_within_each_run():
    """``run_places``: each item's place in its run, empty runs and all, as a loop of aranges gives it."""
    from im2vec_cli.trace.ndops import run_places

    counts = [2, 0, 3, 1, 0]
    assert np.array_equal(run_places(counts), np.concatenate([np.arange(c) for c in counts]))
    assert run_places([]).shape == (0,)
