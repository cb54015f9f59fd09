"""Renderer benchmark (issue "Foundation"): ours vs a naive dense autograd reference.

Workload: B=64 images, P=4 paths, S=12 cubic segments, at 64^2 and 128^2, soft compositing.
Each measurement runs in its own process so that peak memory is its own.
Run: ``python bench/raster.py`` (``make bench``).
"""

from __future__ import annotations

import json
import os
import sys
import time

import torch

sys.path.insert(0, os.path.dirname(__file__))
from common import maxrss_bytes, run_child, star_paths, timeit  # noqa: E402
from im2vec_cli.raster import render_paths, render_pyramid  # noqa: E402
from im2vec_cli.raster.bezier import flatten_closed  # noqa: E402
from im2vec_cli.raster.composite import composite_soft  # noqa: E402

P, S, SAMPLES, TAU = 4, 12, 4, 0.5


def naive_render(points, colors, depth, size):
    """Every pixel x every edge, all in autograd: the reference the issue asks for."""
    b, p = points.shape[:2]
    verts = flatten_closed(points * size, SAMPLES).flatten(0, 1)  # (N, E, 2)
    a, bb = verts, torch.roll(verts, -1, 1)
    c = torch.arange(size, dtype=points.dtype) + 0.5
    py, px = torch.meshgrid(c, c, indexing="ij")
    pix = torch.stack([px, py], -1).view(1, -1, 1, 2)  # (1, HW, 1, 2)
    a_, b_ = a.unsqueeze(1), bb.unsqueeze(1)  # (N, 1, E, 2)
    d = b_ - a_
    r = pix - a_
    t = ((r * d).sum(-1) / (d * d).sum(-1).clamp_min(1e-12)).clamp(0, 1)
    q = r - t.unsqueeze(-1) * d
    dist = torch.sqrt((q * q).sum(-1) + 1e-12).min(-1).values  # (N, HW)
    y = pix[..., 1]
    up = (a_[..., 1] <= y) & (b_[..., 1] > y)
    down = (b_[..., 1] <= y) & (a_[..., 1] > y)
    xi = a_[..., 0] + (y - a_[..., 1]) * d[..., 0] / torch.where(d[..., 1] == 0, torch.ones_like(d[..., 1]), d[..., 1])
    right = xi > pix[..., 0]
    wind = ((up & right).float() - (down & right).float()).sum(-1)
    cov = torch.sigmoid(torch.where(wind != 0, dist, -dist) / TAU).view(b, p, size, size)
    return composite_soft(cov, colors, depth, 0.1)


def child(impl: str, size: int, batch: int) -> dict:
    torch.manual_seed(0)
    pts = star_paths(batch, P, S).requires_grad_(True)
    cols = torch.rand(batch, P, 3, requires_grad=True)
    dep = torch.randn(batch, P, requires_grad=True)
    if impl == "ours":
        fwd = lambda: render_paths(pts, cols, dep, size=size, tau=TAU, samples=SAMPLES, composite="soft")
    elif impl == "pyramid":  # the training workload: every level of a 3-level pyramid rendered directly
        fwd = lambda: torch.cat([r.flatten() for r in render_pyramid(
            pts, cols, dep, size=size, levels=3, tau=TAU, samples=SAMPLES, composite="soft")])
    else:
        fwd = lambda: naive_render(pts, cols, dep, size)
    base = maxrss_bytes()
    t0 = time.perf_counter()
    fwd().sum().backward()
    first = time.perf_counter() - t0
    with torch.no_grad():
        t_fwd = timeit(fwd, 3 if impl == "naive" else 20)

    def step():
        pts.grad = None
        fwd().sum().backward()

    t_fb = timeit(step, 3 if impl == "naive" else 20)
    peak = maxrss_bytes() - base
    return {"first_call_s": first, "fwd_ms": t_fwd * 1e3, "fwdbwd_ms": t_fb * 1e3, "batch": batch,
            "img_per_s": batch / t_fb, "peak_mib": peak / 2**20}


def main():
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        print(json.dumps(child(sys.argv[2], int(sys.argv[3]), int(sys.argv[4]))))
        return
    print(f"torch {torch.__version__}, {torch.get_num_threads()} threads, compile={os.environ.get('IM2VEC_COMPILE', '1')}")
    print(f"workload: B=64, P={P}, S={S} cubic segments, {SAMPLES} lines per cubic, tau={TAU}px, soft composite")
    hdr = f"{'impl':<7}{'size':>6}{'B':>5}{'compile s':>14}{'fwd ms':>9}{'fwd+bwd ms':>12}{'ms/img':>8}{'img/s':>8}{'peak MiB':>10}"
    print("compile s: the first forward+backward of a fresh process with an empty inductor cache")
    print(hdr)
    rows = {}
    for size in (64, 128):
        for impl in ("ours", "naive"):
            batch = 64 if (impl == "ours" or size == 64) else 16  # dense 128^2 at B=64 needs > 24 GiB
            r = run_child(__file__, "--child", impl, str(size), str(batch), cold_compile=True)
            rows[(impl, size)] = r
            if "error" in r:
                print(f"{impl:<7}{size:>6}{batch:>5}  failed: {r['error']}")
                continue
            print(f"{impl:<7}{size:>6}{batch:>5}{r['first_call_s']:>14.1f}{r['fwd_ms']:>9.1f}{r['fwdbwd_ms']:>12.1f}"
                  f"{r['fwdbwd_ms'] / batch:>8.2f}{r['img_per_s']:>8.0f}{r['peak_mib']:>10.0f}")
    r = run_child(__file__, "--child", "pyramid", "64", "64", cold_compile=True)
    if "error" in r:
        print(f"pyramid 64/32/16 failed: {r['error']}")
    else:
        print(f"{'ours, 3-level pyramid 64/32/16':<18}{r['first_call_s']:>14.1f}{r['fwd_ms']:>9.1f}{r['fwdbwd_ms']:>12.1f}"
              f"{r['fwdbwd_ms'] / 64:>8.2f}{r['img_per_s']:>8.0f}{r['peak_mib']:>10.0f}")
    for size in (64, 128):
        o, n = rows[("ours", size)], rows[("naive", size)]
        if "error" not in o and "error" not in n:
            ratio = (n["fwdbwd_ms"] / n["batch"]) / (o["fwdbwd_ms"] / o["batch"])
            print(f"{size}^2: ours is {ratio:.0f}x faster than the naive dense reference per image (fwd+bwd)")
    o = rows[("ours", 64)]
    if "error" not in o:
        per = o["fwdbwd_ms"] / 64
        print(f"64^2 vs diffvg on CPU (issue figures, fwd+bwd per image): 2x2 spp 28 ms -> {28 / per:.0f}x; "
              f"1x1 spp 8.5 ms -> {8.5 / per:.0f}x")


if __name__ == "__main__":
    main()
