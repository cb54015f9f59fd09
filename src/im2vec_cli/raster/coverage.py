"""Soft coverage of closed polylines: winding number for the sign (``winding.py``), distance for the edge.

Frame: everything in this module is in *pixel* units, ``(x, y)`` with y down and pixel
centres at ``(j + 0.5, i + 0.5)``. ``render.py`` converts from the normalised frame.

Coverage of a shape at a pixel is ``sigmoid(sign * min(d, radius) / tau)``, where ``sign`` is
+1 inside (by the fill rule) and -1 outside, and ``d`` the distance to the nearest edge.

Speed and memory (issue "Foundation"):
- the nearest edge is searched without autograd by fused ``torch.compile`` kernels over
  tiles, where only edges whose box comes within ``radius`` of the tile are tested; tiles
  are grouped by candidate count so that crowded tiles do not pad the others;
- backward is closed form (``_SoftCoverage``): only the pixels within
  ``radius`` of an edge have a gradient, and each passes it to its one nearest edge, so
  autograd memory is O(N*H*W) and backward costs O(pixels in the band).
"""

from __future__ import annotations

import math

import torch

from ._compile import compile_enabled, maybe_compile
from .winding import _EPS, _FAR

_SMALL_SEARCH = 2**20  # pixel x edge pairs below which the nearest-edge search is one group


@maybe_compile(dynamic={0: (0, 2), 1: (0, 1), 2: (0,), 3: (0,)})
def _nearest_kernel(cand, sel, px, py, num_edges, r2):
    """Nearest of a tile's K candidate edges for each of its pixels, for a run of tiles.

    Args:
        cand: ``(A, 1, K, 5)`` candidate edges ``[ax, ay, dx, dy, 1/|d|^2]``.
        sel: ``(A, K)`` their edge indices (``num_edges``: a padding edge parked far away).
        px, py: ``(A, M, 1)`` centres of the tile's pixels.
        r2: 0-d squared culling radius.

    Returns:
        ``idx (A, M)`` (0 where no edge is within reach) and ``dist`` (``inf`` there).
    """
    ax, ay, dx, dy, inv = cand.unbind(-1)  # each (A, 1, K)
    rx, ry = px - ax, py - ay  # (A, M, K); then in place: eager runs 1.5x faster with 3 temporaries, not 9
    t = (rx * dx).addcmul_(ry, dy).mul_(inv).clamp_(0.0, 1.0)
    qx, qy = rx.addcmul_(t, dx, value=-1.0), ry.addcmul_(t, dy, value=-1.0)
    d2, slot = torch.min(qx.mul_(qx).addcmul_(qy, qy), dim=-1)  # (A, M)
    idx = torch.gather(sel, 1, slot)
    none = (idx >= num_edges) | (d2 > r2)
    return idx.masked_fill(none, 0), torch.sqrt(d2 + _EPS).masked_fill(none, math.inf)


def nearest_edge_search(
    a: torch.Tensor,
    b: torch.Tensor,
    height: int,
    width: int,
    *,
    radius: float = math.inf,
    tile: int = 8,
    active: torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Nearest edge to every pixel centre and its distance (no autograd).

    The raster is cut into ``tile x tile`` tiles; an edge is a candidate for a tile when its
    box grown by ``radius`` meets it (``_tile_masks``). Tiles with no candidate are skipped;
    the others are grouped by candidate count (rounded up to a multiple of 8) and each group
    is searched by one fused kernel, so a few crowded tiles do not pad the others.

    Args:
        a, b: ``(N, E, 2)`` edge end points, pixel frame; height, width: the raster size.
        radius: culling radius in pixels (``math.inf``: every edge is a candidate everywhere).
        tile: tile side in pixels; active: optional ``(N, E)`` bool, inactive edges never chosen.

    Returns:
        ``idx (N, H, W)`` long and ``dist (N, H, W)``; ``inf`` and 0 where no active edge is near.
    """
    n, e, _ = a.shape
    dev, dt = a.device, a.dtype
    ny, nx = -(-height // tile), -(-width // tile)
    with torch.no_grad():
        grow = radius if math.isfinite(radius) else float(height + width) * 4  # every tile meets it
        mx, my, counts = _tile_masks(a, b, height, width, tile, grow, active)
        tiles = torch.nonzero(counts).view(-1)  # (A,) active (path, tile row, tile col)
        # per tile, its row in out_i / out_d; row A is the answer for tiles without candidates
        pos = torch.full((n * ny * nx,), tiles.numel(), dtype=torch.long, device=dev)
        out_i = torch.zeros(tiles.numel() + 1, tile * tile, dtype=torch.long, device=dev)
        out_d = torch.full((tiles.numel() + 1, tile * tile), math.inf, dtype=dt, device=dev)
        if tiles.numel():
            cnt, perm = torch.sort(counts[tiles].long(), stable=True)  # tiles of one group: a contiguous run
            tiles = tiles[perm]
            tn, tr, tc = tiles // (ny * nx), tiles // nx % ny, tiles % nx
            cap = ((cnt + 7) // 8 * 8).clamp_(max=e)  # (A,) candidate slots, ascending
            order = _candidates_first(my[tn, tr] & mx[tn, tc], int(cap[-1]))  # (A, K+1)
            groups = _groups(cap, tiles.numel() * tile * tile * e)
            local = torch.arange(tile * tile, device=dev)
            py = ((tr * tile).unsqueeze(1) + local // tile).to(dt).add_(0.5).unsqueeze(-1)  # (A, tile^2, 1)
            px = ((tc * tile).unsqueeze(1) + local % tile).to(dt).add_(0.5).unsqueeze(-1)
            table = _edge_table(a, b)
            r2 = torch.tensor(grow * grow, dtype=dt, device=dev)
            num_e = torch.tensor(e, device=dev)  # a tensor: a new segment count must not recompile
            start = 0
            for k, run in groups:
                chunk = _chunk_rows(run, tile * tile * k)
                for s in range(start, start + run, chunk):
                    sl = slice(s, min(s + chunk, start + run))
                    sel = torch.where(torch.arange(k, device=dev) < cnt[sl, None], order[sl, :k], e)  # (A', K)
                    cand = table[(tn[sl] * (e + 1)).unsqueeze(1) + sel].unsqueeze(1)  # (A', 1, K, 5)
                    out_i[sl], out_d[sl] = _nearest_kernel(cand, sel, px[sl], py[sl], num_e, r2)
                start += run
            pos[tiles] = torch.arange(tiles.numel(), device=dev)
        return _untile(out_i, out_d, pos.view(n, ny, nx), tile, height, width)


def _groups(cap: torch.Tensor, pairs: int) -> list[tuple[int, int]]:
    """``(candidate slots K, tiles)`` runs of the ascending ``cap``: one group when the search
    is small (``pairs`` pixel x edge tests; fewer calls beat less padding)."""
    if pairs <= _SMALL_SEARCH:
        return [(int(cap[-1]), cap.numel())]
    caps, runs = torch.unique_consecutive(cap, return_counts=True)
    return list(zip(caps.tolist(), runs.tolist()))


def _tile_masks(a, b, height: int, width: int, tile: int, grow: float, active):
    """Which edges' boxes, grown by ``grow``, meet each tile column and row: ``mx (N, nx, E)``,
    ``my (N, ny, E)`` (inactive edges left out), and the candidates of every tile,
    ``counts (N*ny*nx,)``, as one batched matmul of the two (the test is separable)."""
    dev, dt = a.device, a.dtype
    ny, nx = -(-height // tile), -(-width // tile)
    lo = torch.minimum(a, b) - grow  # (N, E, 2)
    hi = torch.maximum(a, b) + grow
    xs0 = torch.arange(nx, device=dev).to(dt) * tile + 0.5  # first and last pixel centre of a tile
    ys0 = torch.arange(ny, device=dev).to(dt) * tile + 0.5
    xs1, ys1 = (xs0 + tile - 1).clamp(max=width - 0.5), (ys0 + tile - 1).clamp(max=height - 0.5)
    mx = (hi[:, None, :, 0] >= xs0[None, :, None]) & (lo[:, None, :, 0] <= xs1[None, :, None])  # (N, nx, E)
    my = (hi[:, None, :, 1] >= ys0[None, :, None]) & (lo[:, None, :, 1] <= ys1[None, :, None])  # (N, ny, E)
    if active is not None:
        my &= active[:, None, :]
    counts = torch.bmm(my.to(dt), mx.to(dt).transpose(1, 2)).round_().view(-1)  # (N*ny*nx,)
    return mx, my, counts


def _candidates_first(m: torch.Tensor, kmax: int) -> torch.Tensor:
    """Each tile's candidate edges first, in edge order (a compaction, so that every group
    takes its first K slots): ``m (A, E)`` bool -> ``(A, kmax + 1)`` edge ids, ``E`` past them."""
    e = m.shape[1]
    slot_of = torch.where(m, m.cumsum(1) - 1, kmax)  # column kmax takes the non-candidates
    order = torch.full((m.shape[0], kmax + 1), e, dtype=torch.long, device=m.device)
    return order.scatter_(1, slot_of, torch.arange(e, device=m.device).expand_as(slot_of))


def _edge_table(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """``(N*(E+1), 5)`` rows ``(ax, ay, dx, dy, 1/|d|^2)`` per edge, row ``E`` of each set an
    edge parked far away (what a padding slot reads)."""
    n, dt = a.shape[0], a.dtype
    d = b - a
    len2 = (d * d).sum(-1)
    inv = torch.where(len2 > 0, 1.0 / len2.clamp_min(_EPS), torch.zeros_like(len2))
    table = torch.stack([a[..., 0], a[..., 1], d[..., 0], d[..., 1], inv], -1)  # (N, E, 5)
    pad = torch.tensor([_FAR, _FAR, 0.0, 0.0, 0.0], dtype=dt, device=a.device).expand(n, 1, 5)
    return torch.cat([table, pad], 1).view(-1, 5)


@maybe_compile(dynamic={0: (0,), 1: (0,), 2: (0,)})
def _untile(out_i, out_d, pos, tile: int, height: int, width: int):
    """``(A+1, tile*tile)`` per-tile results -> ``(N, H, W)`` rasters, in one gather.

    ``pos (N, ny, nx)`` is the row of each tile in ``out_i`` / ``out_d``.
    """
    n, ny, nx = pos.shape

    def place(out):  # (A+1, tile^2) -> tiles (N, ny, nx, tile, tile) -> raster (N, ny*tile, nx*tile), cropped
        tiles = out.index_select(0, pos.reshape(-1)).view(n, ny, nx, tile, tile)
        return tiles.permute(0, 1, 3, 2, 4).reshape(n, ny * tile, nx * tile)[:, :height, :width]

    return place(out_i), place(out_d)


def _chunk_rows(rows: int, pairs_per_row: int) -> int:
    """Rows per kernel call: the compiled kernel fuses the reduction, eager does not."""
    if compile_enabled():
        return rows
    budget = 2**24  # pair elements per eager call (~64 MB per float32 temporary)
    return max(1, budget // max(1, pairs_per_row))


def _sum_into_edges(a, edge, grads):
    """``(dL/da, dL/db)``, each ``(N, E, 2)``, from per-pixel ``grads (M, 4)`` on ``edge (M,)``
    (rows of ``a.view(N*E, 2)``)."""
    n, e, _ = a.shape
    out = torch.zeros(n * e, 4, dtype=a.dtype, device=a.device).index_add_(0, edge, grads).view(n, e, 4)
    return out[..., :2], out[..., 2:]


class _SoftCoverage(torch.autograd.Function):
    """``sigmoid(sign * min(d, radius) / tau)`` with ``d`` the distance to the nearest edge.

    One function from edges to coverage, so that backward touches only the band of pixels
    within ``radius`` of an edge (elsewhere the clamp makes the gradient exactly 0):
    ``dL/dd = dL/dc * c (1 - c) * sign / tau`` there, then ``_band_grads_cov``.
    """

    @staticmethod
    def forward(ctx, a, b, wind, height, width, radius, tau, evenodd, active):
        idx, dist = nearest_edge_search(a, b, height, width, radius=radius, active=active)
        r = torch.tensor(radius, dtype=a.dtype, device=a.device)
        t = torch.tensor(tau, dtype=a.dtype, device=a.device)
        cov = shade(dist, wind, r, t, evenodd)
        ctx.save_for_backward(a, b, idx, dist, wind, cov)
        ctx.tau, ctx.radius, ctx.evenodd = tau, radius, evenodd
        return cov

    @staticmethod
    def backward(ctx, grad_cov):
        a, b, idx, dist, wind, cov = ctx.saved_tensors
        sel = torch.nonzero(dist.reshape(-1) < ctx.radius).view(-1)  # (M,) the band
        h, w = idx.shape[1:]
        inv_tau = torch.tensor(1.0 / ctx.tau, dtype=a.dtype, device=a.device)
        edge, grads = _band_grads_cov(a.reshape(-1, 2), b.reshape(-1, 2), idx.reshape(-1), sel, grad_cov.reshape(-1),
                                      cov.reshape(-1), wind.reshape(-1), h * w, w,
                                      torch.tensor(a.shape[1], device=a.device), inv_tau, ctx.evenodd)
        ga, gb = _sum_into_edges(a, edge, grads)
        return ga, gb, None, None, None, None, None, None, None


def soft_coverage(
    a: torch.Tensor,
    b: torch.Tensor,
    wind: torch.Tensor,
    height: int,
    width: int,
    *,
    radius: float,
    tau: float,
    fill_rule: str = "nonzero",
    active: torch.Tensor | None = None,
) -> torch.Tensor:
    """Soft coverage ``(N, H, W)`` of closed polylines, differentiable in ``a`` and ``b``.

    Args:
        a, b: ``(N, E, 2)`` edges, pixel frame; wind: ``(N, H, W)`` their winding numbers.
        radius: distance clamp and culling radius in pixels; tau: softness in pixels.
        fill_rule, active: as in ``signed_coverage`` and ``nearest_edge_search``.
    """
    inside_from_winding(wind[:0], fill_rule)  # validates fill_rule
    return _SoftCoverage.apply(a, b, wind, height, width, float(radius), float(tau), fill_rule == "evenodd", active)


def _closed_form(ea, eb, pix, width, g):
    """Per-pixel ``(dL/da, dL/db)`` ``(M, 4)`` of ``d = |p - a - t (b - a)|``, t clamped to [0, 1].

    ``t`` is the minimiser, so ``dd/dt = 0`` inside and ``t`` is constant where clamped:
    ``dd/da = -(1 - t) q / d``, ``dd/db = -t q / d`` with ``q = p - a - t (b - a)``.
    ``ea, eb (M, 2)`` the edge of each pixel, ``pix (M,)`` its index in a row-major raster.
    """
    px = (pix % width).to(ea.dtype) + 0.5
    py = torch.div(pix, width, rounding_mode="floor").to(ea.dtype) + 0.5
    dx, dy = eb[:, 0] - ea[:, 0], eb[:, 1] - ea[:, 1]
    rx, ry = px - ea[:, 0], py - ea[:, 1]
    len2 = dx * dx + dy * dy
    t = torch.where(len2 > 0, (rx * dx + ry * dy) / len2.clamp_min(_EPS), torch.zeros_like(len2)).clamp(0.0, 1.0)
    qx, qy = rx - t * dx, ry - t * dy
    s = g / torch.sqrt(qx * qx + qy * qy + _EPS)
    ux, uy = qx * s, qy * s
    return torch.stack([-(1 - t) * ux, -(1 - t) * uy, -t * ux, -t * uy], -1)


def _gather_closed_form(a2, b2, idx, sel, hw: int, width: int, num_edges, g_sel):
    """``edge (M,)`` rows of ``a2`` nearest to the flat pixels ``sel (M,)`` and their
    ``_closed_form`` gradients ``(M, 4)`` for ``g_sel (M,)`` = dL/d(distance) there."""
    edge = idx[sel] + torch.div(sel, hw, rounding_mode="floor") * num_edges
    return edge, _closed_form(a2[edge], b2[edge], sel % hw, width, g_sel)


@maybe_compile(dynamic={0: (0,), 1: (0,), 2: (0,), 3: (0,), 4: (0,), 5: (0,), 6: (0,)})
def _band_grads_cov(a2, b2, idx, sel, grad_cov, cov, wind, hw: int, width: int, num_edges, inv_tau,
                    evenodd: bool):
    """Closed-form gradients of the pixels ``sel (M,)`` of a flat ``(N*H*W,)`` raster, from
    dL/d(coverage): ``dL/dd = dL/dc * c (1 - c) * sign / tau``.

    Args: a2, b2 ``(N*E, 2)``; idx ``(N*H*W,)`` nearest edge.
    Returns ``edge (M,)`` rows of ``a2`` and ``grads (M, 4)``.
    """
    c = cov[sel]
    inside = inside_from_winding(wind[sel], "evenodd" if evenodd else "nonzero")
    g = grad_cov[sel] * c * (1 - c) * torch.where(inside, inv_tau, -inv_tau)
    return _gather_closed_form(a2, b2, idx, sel, hw, width, num_edges, g)


@maybe_compile(dynamic={0: (0,), 1: (0,)})
def shade(dist, wind, radius, tau, evenodd: bool):
    """Soft coverage ``sigmoid(sign * min(dist, radius) / tau)`` of ``(N, H, W)`` pixels, fused.

    Args:
        dist, wind: ``(N, H, W)`` distance to the nearest edge and winding number.
        radius, tau: 0-d tensors (tensors, so that annealing them does not recompile).
        evenodd: fill rule (else nonzero).
    """
    return signed_coverage(dist, wind, radius, tau, "evenodd" if evenodd else "nonzero")


def signed_coverage(dist, wind, radius, tau, fill_rule: str) -> torch.Tensor:
    """``sigmoid(sign * min(dist, radius) / tau)``, the sign from ``wind`` under ``fill_rule``."""
    dist = dist.clamp(max=radius)
    return torch.sigmoid(torch.where(inside_from_winding(wind, fill_rule), dist, -dist) / tau)


def inside_from_winding(wind: torch.Tensor, fill_rule: str) -> torch.Tensor:
    """Boolean inside mask from winding numbers under ``"nonzero"`` or ``"evenodd"``."""
    if fill_rule == "nonzero":
        return wind != 0
    if fill_rule == "evenodd":
        return torch.remainder(wind, 2) != 0
    raise ValueError(f"fill_rule must be 'nonzero' or 'evenodd', got {fill_rule!r}")
