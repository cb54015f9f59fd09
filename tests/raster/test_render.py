import math

import numpy as np
import pytest
import torch

from im2vec_cli.data.glyphs import glyph_image
from im2vec_cli.raster import (
    Rasterizer,
    composite_over,
    composite_soft,
    gaussian_pyramid,
    pyramid_l2,
    render_coverage,
    render_paths,
    render_pyramid,
    render_supersampled,
)
from im2vec_cli.raster.coverage import nearest_edge_search
from im2vec_cli.vector import VectorImage, VectorShape, rasterize_svg, to_svg, to_tensors
from tests.helpers import circle, polyline_as_cubic, star

SIZE = 64


def ours(image: VectorImage, tau=0.15, samples=16):
    """Render a VectorImage with our rasterizer (over compositing), as a (H, W) grey array."""
    pts, cols, sidx = to_tensors(image)
    rule = image.shapes[0].fill_rule
    img = render_paths(
        pts[None], cols[None], size=(int(image.height), int(image.width)), tau=tau,
        fill_rule=rule, shape_index=sidx if len(image.shapes) == 1 else None, samples=samples,
    )
    return img[0].mean(0).numpy()


def cairo(image: VectorImage, supersample=1):
    h, w = int(image.height), int(image.width)
    big = rasterize_svg(to_svg(image, decimals=4), w * supersample, h * supersample).mean(-1)
    return big.reshape(h, supersample, w, supersample).mean((1, 3))


def check_agreement(image):
    a = ours(image)
    # MAD against cairo's own 64^2 render; area against cairo at 4x box-filtered down, since
    # cairo's 8-bit coverage at 1x is itself ~1% low on small shapes (a circle of r = 8.3 px:
    # 214.0 px^2 at 1x, 216.3 at 4x, pi r^2 = 216.4).
    mad = np.abs(a - cairo(image)).mean()
    b = cairo(image, supersample=4)
    area_a, area_b = (1 - a).sum(), (1 - b).sum()
    assert mad <= 0.02, f"mean abs diff {mad:.4f}"
    assert abs(area_a - area_b) <= 0.01 * area_b, f"area {area_a:.1f} vs cairo {area_b:.1f}"
    return mad


def shape_image(contours_px, rule="nonzero"):
    return VectorImage(SIZE, SIZE, [VectorShape([c.numpy() for c in contours_px], (0, 0, 0), rule)])


@pytest.mark.parametrize("seed", range(4))
def test_stars_agree_with_cairo(seed):
    g = torch.Generator().manual_seed(seed)
    s = star(32 + 3 * seed, 30, 26, 11, 5 + seed, generator=g)
    check_agreement(shape_image([s]))


@pytest.mark.parametrize("r", [8.3, 12.7, 27.0])
def test_circles_agree_with_cairo(r):
    check_agreement(shape_image([circle(31.2, 32.9, r, segments=6)]))


@pytest.mark.parametrize("char", list("aBgo8&@%Q"))
def test_glyphs_agree_with_cairo(dejavu, char):
    check_agreement(glyph_image(dejavu, char, size=SIZE, margin=4))


@pytest.mark.parametrize("rule", ["nonzero", "evenodd"])
def test_glyph_hole_matches_cairo(dejavu, rule):
    # 'o' has two contours wound in opposite directions: a hole under both rules
    img = glyph_image(dejavu, "o", size=SIZE, margin=4)
    img.shapes[0].fill_rule = rule
    check_agreement(img)
    # centre pixel is background (a true hole, not paint)
    assert ours(img)[32, 32] > 0.95


@pytest.mark.parametrize("rule", ["nonzero", "evenodd"])
def test_self_intersecting_pentagram_matches_cairo(rule):
    verts = [(32 + 28 * math.cos(-math.pi / 2 + 4 * math.pi * i / 5), 34 + 28 * math.sin(-math.pi / 2 + 4 * math.pi * i / 5)) for i in range(5)]
    img = shape_image([polyline_as_cubic(verts)], rule)
    check_agreement(img)
    centre = ours(img)[34, 32]
    assert (centre < 0.05) if rule == "nonzero" else (centre > 0.95)


@pytest.mark.parametrize("char", list("aB8&"))
def test_supersampled_render_matches_cairo_antialiasing(dejavu, char):
    """At a model's 32^2, a soft edge (sigmoid, tau 0.3 px) is visibly not the box-filtered
    edge of cairo's antialiased render; 4x4 sub-pixels with tau 0.25 sub-px match it."""
    img = glyph_image(dejavu, char, size=32, margin=2)
    pts, cols, sidx = to_tensors(img)
    kw = dict(size=32, fill_rule=img.shapes[0].fill_rule, shape_index=sidx, samples=16)
    ref = cairo(img, supersample=8)
    plain = render_paths(pts[None], cols[None], tau=0.3, **kw)[0].mean(0).numpy()
    boxed = render_supersampled(pts[None], cols[None], factor=4, tau=0.25, **kw)[0].mean(0).numpy()
    err_plain, err_boxed = ((plain - ref) ** 2).mean(), ((boxed - ref) ** 2).mean()
    assert err_boxed <= 1e-4 and err_boxed <= 0.05 * err_plain, (err_boxed, err_plain)


def test_pyramid_levels_blur_the_finest_render_or_render_again():
    pts = circle(14.3, 17.1, 9.0, segments=6, dtype=torch.float32)[None, None] / 32
    cols = torch.zeros(1, 1, 3)
    finest = render_supersampled(pts, cols, size=32, factor=4, tau=0.3)
    blur = render_pyramid(pts, cols, size=32, levels=3, tau=0.3, supersample=4)
    assert [r.shape[-1] for r in blur] == [32, 16, 8]
    for a, b in zip(blur, gaussian_pyramid(finest, 3)):
        assert torch.equal(a, b)
    # "render": the finest level alone is supersampled, the coarser ones are fresh renders
    plain = render_pyramid(pts, cols, size=32, levels=3, tau=0.3, coarse="render")
    boxed = render_pyramid(pts, cols, size=32, levels=3, tau=0.3, supersample=4, coarse="render")
    assert torch.equal(boxed[0], finest)
    assert not torch.allclose(boxed[0], plain[0], atol=1e-2)
    for a, b in zip(plain[1:], boxed[1:]):
        assert torch.equal(a, b)
    with pytest.raises(ValueError, match="factor"):
        render_supersampled(pts, cols, size=32, factor=0)
    with pytest.raises(ValueError, match="coarse"):
        render_pyramid(pts, cols, size=32, coarse="nearest")


@pytest.mark.parametrize("char", list("a8"))
def test_blurred_pyramid_matches_the_pyramid_of_cairos_render(dejavu, char):
    """The loss compares the render's pyramid with ``gaussian_pyramid`` of the image. Built
    from cairo's antialiased render of the same SVG, the blurred levels agree at every level;
    renders made directly at the coarse sizes are far off there (they are sharp where the
    target is blurred), so they would pull a perfect fit away from the image."""
    img = glyph_image(dejavu, char, size=32, margin=2)
    pts, cols, sidx = to_tensors(img)
    kw = dict(size=32, levels=3, supersample=4, tau=0.25, fill_rule=img.shapes[0].fill_rule, shape_index=sidx,
              samples=16)
    ref = torch.from_numpy(cairo(img, supersample=8)).float()[None, None].expand(1, 3, 32, 32)
    target = gaussian_pyramid(ref, 3)
    blur = [((r - t) ** 2).mean().item() for r, t in zip(render_pyramid(pts[None], cols[None], **kw), target)]
    direct = [((r - t) ** 2).mean().item()
              for r, t in zip(render_pyramid(pts[None], cols[None], coarse="render", **kw), target)]
    assert max(blur) <= 1e-4, blur
    assert direct[0] == pytest.approx(blur[0])
    assert min(direct[1:]) >= 20 * max(blur[1:]), (direct, blur)


def test_same_contours_evenodd_overlap_is_hole():
    # two overlapping circles with the same orientation in one shape
    a, b = circle(26, 32, 14), circle(38, 32, 14)
    for rule, expect_hole in (("nonzero", False), ("evenodd", True)):
        out = ours(shape_image([a, b], rule))
        assert (out[32, 32] > 0.95) == expect_hole
        check_agreement(shape_image([a, b], rule))


@pytest.mark.parametrize("impl", ["sparse", "dense"])
def test_winding_scanline_matches_bruteforce(impl):
    # the eager per-crossing count and the compiled kernel's dense one, on edges that leave the
    # raster on every side, and a horizontal one (which crosses no row)
    from im2vec_cli.raster.winding import _winding, _winding_sparse

    g = torch.Generator().manual_seed(3)
    verts = torch.rand(3, 17, 2, generator=g, dtype=torch.float64) * 30 - 5
    verts[0, 4, 1] = verts[0, 5, 1]
    a, b = verts, torch.roll(verts, -1, 1)
    wind = (_winding_sparse if impl == "sparse" else _winding.eager)(a, b, 20, 20)
    ys, xs = torch.meshgrid(torch.arange(20) + 0.5, torch.arange(20) + 0.5, indexing="ij")
    ref = torch.zeros(3, 20, 20, dtype=torch.float64)
    for e in range(17):
        ax, ay, bx, by = a[:, e, 0, None, None], a[:, e, 1, None, None], b[:, e, 0, None, None], b[:, e, 1, None, None]
        up = (ay <= ys) & (by > ys)
        down = (by <= ys) & (ay > ys)
        xi = ax + (ys - ay) * (bx - ax) / torch.where(by == ay, torch.ones_like(by), by - ay)
        ref += torch.where(up & (xi > xs), 1.0, 0.0) - torch.where(down & (xi > xs), 1.0, 0.0)
    assert torch.equal(wind, ref)


@pytest.mark.parametrize("grouped", [False, True])
def test_culled_nearest_edge_matches_dense(monkeypatch, grouped):
    import im2vec_cli.raster.coverage as coverage

    if grouped:  # tiles searched in groups by candidate count, as in large batches
        monkeypatch.setattr(coverage, "_SMALL_SEARCH", 0)
    g = torch.Generator().manual_seed(0)
    pts = torch.stack([star(20 + 5 * i, 22, 15, 6, 6, generator=g) for i in range(3)]) / 40  # (3, 36, 2)
    from im2vec_cli.raster.bezier import flatten_closed

    a = flatten_closed(pts * 40, 4)
    b = torch.roll(a, -1, 1)
    # brute force: every pixel against every edge
    c = torch.arange(40, dtype=a.dtype) + 0.5
    py, px = torch.meshgrid(c, c, indexing="ij")
    r = torch.stack([px, py], -1).view(1, 40, 40, 1, 2) - a.view(3, 1, 1, -1, 2)
    d = (b - a).view(3, 1, 1, -1, 2)
    t = ((r * d).sum(-1) / (d * d).sum(-1)).clamp(0, 1)
    brute = (r - t.unsqueeze(-1) * d).norm(dim=-1).min(-1).values  # (3, 40, 40)
    dense = nearest_edge_search(a, b, 40, 40, radius=math.inf)[1]
    culled = nearest_edge_search(a, b, 40, 40, radius=3.0)[1]
    near = brute <= 3.0
    assert torch.allclose(dense, brute, atol=1e-6)
    assert torch.allclose(culled[near], brute[near], atol=1e-6)
    assert (culled[~near] > 3.0).all()


@pytest.mark.parametrize("batch", [1, 2])
def test_shapes_and_module(batch):
    pts = torch.stack([torch.stack([circle(0.5, 0.5, 0.3), circle(0.4, 0.6, 0.2)])] * batch).float()
    cols = torch.rand(batch, 2, 3)
    depth = torch.randn(batch, 2)
    img = render_paths(pts, cols, depth, size=(16, 24), composite="soft")
    assert img.shape == (batch, 3, 16, 24)
    mod = Rasterizer((16, 24))
    assert torch.allclose(mod(pts, cols, depth), img)
    cov = render_coverage(pts, size=12, shape_index=[0, 0])
    assert cov.shape == (batch, 1, 12, 12)


def test_errors_name_the_argument():
    with pytest.raises(ValueError, match="points"):
        render_coverage(torch.zeros(1, 2, 5, 2), size=8)
    with pytest.raises(ValueError, match="tau"):
        render_coverage(torch.zeros(1, 1, 6, 2), size=8, tau=0)
    with pytest.raises(ValueError, match="fill_rule"):
        render_coverage(torch.rand(1, 1, 6, 2), size=8, fill_rule="winding")
    with pytest.raises(ValueError, match="colors"):
        composite_over(torch.rand(1, 2, 4, 4), torch.rand(1, 3, 3), torch.rand(1, 2))


def test_gradcheck_float64():
    torch.manual_seed(0)
    pts = (circle(0.5, 0.5, 0.3, segments=3) + 0.03 * torch.randn(9, 2, dtype=torch.float64))[None, None]
    pts.requires_grad_(True)
    col = torch.tensor([[[0.2, 0.5, 0.9]]], dtype=torch.float64, requires_grad=True)

    def f(p, c):
        return render_paths(p, c, size=12, tau=1.0, samples=3)

    assert torch.autograd.gradcheck(f, (pts, col), eps=1e-6, atol=1e-5)


def test_gradcheck_supersampled_float64():
    torch.manual_seed(3)
    pts = (circle(0.5, 0.5, 0.3, segments=3) + 0.03 * torch.randn(9, 2, dtype=torch.float64))[None, None]
    pts.requires_grad_(True)
    col = torch.tensor([[[0.2, 0.5, 0.9]]], dtype=torch.float64)

    def f(p):
        return render_supersampled(p, col, size=6, factor=2, tau=1.0, samples=3)

    assert f(pts).shape == (1, 3, 6, 6)
    assert torch.autograd.gradcheck(f, (pts,), eps=1e-6, atol=1e-5)


def test_gradcheck_grouped_shapes_evenodd():
    # unequal shapes (2 contours + 1) take the gathered-rows branch, under even-odd
    torch.manual_seed(1)
    base = torch.stack([circle(0.45, 0.5, 0.3, 3), circle(0.5, 0.5, 0.12, 3), circle(0.7, 0.3, 0.15, 3)])
    pts = (base + 0.02 * torch.randn_like(base))[None].requires_grad_(True)

    def f(p):
        return render_coverage(p, size=12, tau=1.0, samples=3, fill_rule="evenodd", shape_index=[0, 0, 1])

    assert torch.autograd.gradcheck(f, (pts,), eps=1e-6, atol=1e-5)


def test_gradcheck_soft_composite():
    torch.manual_seed(0)
    cov = torch.rand(1, 3, 4, 4, dtype=torch.float64, requires_grad=True)
    col = torch.rand(1, 3, 3, dtype=torch.float64, requires_grad=True)
    dep = torch.randn(1, 3, dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(lambda a, b, c: composite_soft(a, b, c, 0.5), (cov, col, dep))


def test_float32_gradients_reach_every_control_point():
    pts = circle(0.5, 0.5, 0.3, segments=5).float()[None, None].requires_grad_(True)
    target = torch.ones(1, 3, 32, 32)
    img = render_paths(pts, torch.zeros(1, 1, 3), size=32, tau=0.5)
    ((img - target) ** 2).sum().backward()
    g = pts.grad.norm(dim=-1)
    assert torch.isfinite(pts.grad).all() and (g > 0).all()


def test_composite_is_convex():
    cov = torch.full((1, 1, 2, 2), 0.5)
    col = torch.tensor([[[0.0, 0.2, 0.4]]])
    for out in (composite_soft(cov, col, torch.zeros(1, 1)), composite_over(cov, col, torch.zeros(1, 1))):
        assert torch.allclose(out[0, :, 0, 0], torch.tensor([0.5, 0.6, 0.7]))
    g = torch.Generator().manual_seed(0)
    cov = torch.rand(2, 4, 5, 5, generator=g)
    col = torch.rand(2, 4, 3, generator=g)
    out = composite_soft(cov, col, torch.randn(2, 4, generator=g), 0.3)
    lo = torch.minimum(col.min(1).values, torch.ones(3)).view(2, 3, 1, 1)
    assert (out >= lo - 1e-6).all() and (out <= 1 + 1e-6).all()


def test_soft_composite_tends_to_over():
    g = torch.Generator().manual_seed(1)
    cov = torch.rand(2, 4, 6, 6, generator=g, dtype=torch.float64)
    col = torch.rand(2, 4, 3, generator=g, dtype=torch.float64)
    dep = torch.randn(2, 4, generator=g, dtype=torch.float64)
    hard = composite_over(cov, col, dep)
    errs = [(composite_soft(cov, col, dep, t) - hard).abs().max().item() for t in (1.0, 0.1, 0.01, 1e-4)]
    assert errs[-1] < 1e-6
    assert all(x >= y for x, y in zip(errs, errs[1:]))


def fit(target_img, levels, coarse, steps=300):
    pts = circle(0.5, 0.5, 0.3, segments=8).float()[None, None].clone().requires_grad_(True)
    black = torch.zeros(1, 1, 3)
    opt = torch.optim.Adam([pts], lr=0.01)
    targets = gaussian_pyramid(target_img, levels)
    full = gaussian_pyramid(target_img, 4)

    def full_loss():
        with torch.no_grad():
            return pyramid_l2(render_pyramid(pts, black, size=32, levels=4, tau=0.5, coarse=coarse), full).item()

    start = full_loss()
    for _ in range(steps):
        opt.zero_grad()
        loss = pyramid_l2(render_pyramid(pts, black, size=32, levels=levels, tau=0.5, coarse=coarse), targets)
        loss.backward()
        opt.step()
    return start, full_loss()


@pytest.mark.parametrize("coarse", ["blur", "render"])
def test_gradient_descent_fits_a_glyph(dejavu, coarse):
    img = glyph_image(dejavu, "D", size=32, margin=3)
    pts, cols, sidx = to_tensors(img)
    target = render_paths(pts[None].float(), cols[None].float(), size=32, tau=0.5, shape_index=sidx)
    # the 'D' has a counter; one circle can only approximate the outer contour
    start, end_pyr = fit(target, levels=4, coarse=coarse)
    assert end_pyr <= start / 10, (start, end_pyr)
    if coarse == "render":
        # sharp coarse renders reach far: from this circle they fit better than one level.
        # (The blurred pyramid, which the training loss uses, does not beat one level here.)
        _, end_single = fit(target, levels=1, coarse=coarse)
        assert end_pyr <= end_single * 1.05, (end_pyr, end_single)


def test_unequal_shape_groups_match_separate_renders():
    pts = torch.stack([circle(0.3, 0.5, 0.2), circle(0.3, 0.5, 0.1), circle(0.7, 0.5, 0.15)])[None].float()
    both = render_coverage(pts, size=24, fill_rule="evenodd", shape_index=[0, 0, 1])
    first = render_coverage(pts[:, :2], size=24, fill_rule="evenodd", shape_index=[0, 0])
    second = render_coverage(pts[:, 2:], size=24, fill_rule="evenodd")
    assert torch.allclose(both, torch.cat([first, second], 1), atol=1e-6)


@pytest.mark.parametrize("rule", ["evenodd", "nonzero"])
def test_ragged_batch_renders_each_image_as_alone(rule):
    # Two images of different path counts, shape counts and segment counts in one batch:
    # (B, P) shape maps with -1 for padding paths, counts for padding segments (which start at
    # the path's first anchor, then junk that must not draw), and a padding shape, which must
    # render to nothing.
    ring = [circle(0.35, 0.5, 0.25, 4), torch.roll(circle(0.35, 0.5, 0.1, 4).flip(0), 1, 0)]  # outer + hole
    spike = star(0.75, 0.35, 0.2, 0.08, 5)  # 10 segments
    img1 = [*ring, spike]  # shape 0: ring, shape 1: star
    img2 = [star(0.5, 0.5, 0.4, 0.15, 4)]  # 8 segments, one shape
    big = 11
    pts = torch.rand(2, 3, 3 * big, 2, dtype=torch.float64, generator=torch.Generator().manual_seed(3))  # junk padding
    counts = torch.zeros(2, 3, dtype=torch.long)
    for b, paths in enumerate([img1, img2]):
        for p, c in enumerate(paths):
            pts[b, p, : len(c)] = c
            pts[b, p, len(c)] = c[0]
            counts[b, p] = len(c) // 3
    sidx = torch.tensor([[0, 0, 1], [0, -1, -1]])
    got = render_coverage(pts, size=(40, 48), tau=0.4, fill_rule=rule, shape_index=sidx, counts=counts, num_shapes=2)
    alone1 = torch.cat([render_coverage(torch.stack(ring)[None], size=(40, 48), tau=0.4, fill_rule=rule,
                                        shape_index=[0, 0]),
                        render_coverage(spike[None, None], size=(40, 48), tau=0.4, fill_rule=rule)], 1)
    alone2 = render_coverage(img2[0][None, None], size=(40, 48), tau=0.4, fill_rule=rule)
    assert torch.allclose(got[0], alone1[0], atol=1e-9)
    assert torch.allclose(got[1, :1], alone2[0], atol=1e-9)
    assert got[1, 1].abs().max() == 0  # the padding shape draws nothing at all
    assert (alone1[0, 0] > 0.5).sum() < (alone1[0, 0] > -1).sum()  # the ring has a hole, so the test can fail
