"""Soft coverage of closed polylines: winding number for the sign, distance for the edge.

Frame: everything in this module is in *pixel* units, ``(x, y)`` with y down and pixel
centres at ``(j + 0.5, i + 0.5)``. ``render.py`` converts from the normalised frame.

Coverage of a shape at a pixel is ``sigmoid(sign * min(d, radius) / tau)``, where ``sign`` is
+1 inside (by the fill rule) and -1 outside, and ``d`` the distance to the nearest edge.

Speed and memory (issue "Foundation"):
- the winding number is a scanline count: per row, each edge's crossing is binned and a
  reverse cumulative sum gives every pixel's count, O(N*H*E + N*H*W) instead of O(N*H*W*E);
- the nearest edge is searched without autograd in a fused ``torch.compile`` kernel over
  row bands, where only edges whose y-extent comes within ``radius`` of the band are tested;
- the distance is then recomputed *with* autograd from the one nearest edge per pixel, so
  autograd memory is O(N*H*W) and the gradient is the closed-form one of that edge.
"""

from __future__ import annotations

import math

import torch

from ._compile import compile_enabled, maybe_compile

_FAR = 1.0e6  # padding edges are parked this far away (pixel units)
_EPS = 1e-12


@maybe_compile
def _nearest_kernel(ax, ay, dx, dy, inv, px, py):
    """Squared distance to the nearest of K edges, and its slot.

    Shapes broadcast to ``(N, nb, M, K)``; the reduction is over K.
    """
    rx = px - ax
    ry = py - ay
    t = ((rx * dx + ry * dy) * inv).clamp(0.0, 1.0)
    qx = rx - t * dx
    qy = ry - t * dy
    d2 = qx * qx + qy * qy
    return torch.min(d2, dim=-1)


def winding_number(a: torch.Tensor, b: torch.Tensor, height: int, width: int) -> torch.Tensor:
    """Winding number of closed polylines at every pixel centre (scanline count).

    Args:
        a: ``(N, E, 2)`` edge starts, pixel frame.
        b: ``(N, E, 2)`` edge ends.
        height, width: raster size.

    Returns:
        ``(N, H, W)`` winding numbers (float, integral values).
    """
    with torch.no_grad():
        return _winding(a, b, height, width)


@maybe_compile
def _winding(a, b, height, width):
    ax, ay, bx, by = a[..., 0], a[..., 1], b[..., 0], b[..., 1]
    y = torch.arange(height, dtype=a.dtype, device=a.device).add_(0.5).view(1, -1, 1)  # (1, H, 1)
    ay_, by_ = ay.unsqueeze(1), by.unsqueeze(1)  # (N, 1, E)
    up = (ay_ <= y) & (by_ > y)  # (N, H, E)
    down = (by_ <= y) & (ay_ > y)
    direction = up.to(a.dtype) - down.to(a.dtype)
    dy = by_ - ay_
    safe = torch.where(dy == 0, torch.ones_like(dy), dy)
    xi = ax.unsqueeze(1) + (y - ay_) * (bx - ax).unsqueeze(1) / safe  # (N, H, E)
    # pixel j counts the crossing when xi > j + 0.5, i.e. j <= ceil(xi - 0.5) - 1.
    last = torch.ceil(xi - 0.5).clamp_(0, width).to(torch.long)  # (N, H, E): bins 0..W
    bins = torch.zeros(a.shape[0], height, width + 1, dtype=a.dtype, device=a.device)
    bins.scatter_add_(2, last, direction)
    # pixel j sums the bins m >= j + 1
    return bins.flip(-1).cumsum(-1).flip(-1)[..., 1:]  # (N, H, W)


def point_winding(pts: torch.Tensor, a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Winding number of closed polylines around arbitrary points (brute force over edges).

    Args:
        pts: ``(N, M, 2)`` query points, pixel frame.
        a, b: ``(N, E, 2)`` edges.

    Returns:
        ``(N, M)`` winding numbers (float).
    """
    py, px = pts[..., 1].unsqueeze(-1), pts[..., 0].unsqueeze(-1)  # (N, M, 1)
    ax, ay = a[..., 0].unsqueeze(1), a[..., 1].unsqueeze(1)  # (N, 1, E)
    bx, by = b[..., 0].unsqueeze(1), b[..., 1].unsqueeze(1)
    up = (ay <= py) & (by > py)
    down = (by <= py) & (ay > py)
    dy = by - ay
    xi = ax + (py - ay) * (bx - ax) / torch.where(dy == 0, torch.ones_like(dy), dy)
    right = xi > px
    return ((up & right).to(a.dtype) - (down & right).to(a.dtype)).sum(-1)


def boundary_edges(verts: torch.Tensor, shape_index: torch.Tensor | None) -> torch.Tensor:
    """Which edges separate inside from outside under the nonzero rule.

    Under "nonzero" an edge between winding 1 and 2 (a self-intersecting star, two
    overlapping contours of one shape) is not part of the filled region's boundary, and
    its distance must not soften the interior. Each edge is tested at its midpoint, a hair
    to either side. Under "evenodd" every edge is a boundary, so this is not needed.

    Args:
        verts: ``(B, P, E, 2)`` polyline vertices, pixel frame (edge i: vertex i -> i+1).
        shape_index: ``(P,)`` path -> shape, or ``None`` (each path its own shape).

    Returns:
        ``(B, P, E)`` bool.
    """
    with torch.no_grad():
        bsz, p, e, _ = verts.shape
        a, b = verts, torch.roll(verts, -1, 2)
        d = b - a
        normal = torch.stack([-d[..., 1], d[..., 0]], -1)
        normal = normal / normal.norm(dim=-1, keepdim=True).clamp_min(_EPS) * 1e-3
        mid = (a + b) / 2
        probes = torch.cat([mid + normal, mid - normal], 2)  # (B, P, 2E, 2)
        if shape_index is None:
            w = point_winding(probes.flatten(0, 1), a.flatten(0, 1), b.flatten(0, 1)).view(bsz, p, 2 * e)
        else:
            # every path's probes against every path's edges, then summed within each shape
            q = probes.reshape(bsz, 1, p * 2 * e, 2).expand(bsz, p, p * 2 * e, 2)
            w_src = point_winding(q.flatten(0, 1), a.flatten(0, 1), b.flatten(0, 1)).view(bsz, p, p, 2 * e)
            same = (shape_index.view(-1, 1) == shape_index.view(1, -1)).to(w_src.dtype)  # (src, dst)
            w = torch.einsum("bsdm,sd->bdm", w_src, same)  # (B, P, 2E)
        inside = w != 0
        return inside[..., :e] != inside[..., e:]


def _bucket(k: int) -> int:
    """Round a candidate count up to a multiple of 8 (the kernel is compiled dynamic)."""
    return max(8, -(-k // 8) * 8)


def nearest_edge(
    a: torch.Tensor,
    b: torch.Tensor,
    height: int,
    width: int,
    *,
    radius: float = math.inf,
    tile: int = 8,
    active: torch.Tensor | None = None,
) -> torch.Tensor:
    """Index of the nearest edge to every pixel centre (no autograd).

    The raster is cut into ``tile x tile`` tiles. An edge is a candidate for a tile when its
    bounding box grown by ``radius`` meets the tile; tiles with no candidate are skipped, and
    the others are packed together with their candidates padded to a common count K.
    Pixels farther than ``radius`` from every edge get an arbitrary edge, so the caller must
    clamp their distance to ``radius``.

    Args:
        a, b: ``(N, E, 2)`` edge end points, pixel frame.
        height, width: raster size.
        radius: culling radius in pixels (``math.inf``: every edge is a candidate everywhere).
        tile: tile side in pixels.
        active: optional ``(N, E)`` bool; inactive edges are never chosen.

    Returns:
        ``(N, H, W)`` long edge indices.
    """
    n, e, _ = a.shape
    dev, dt = a.device, a.dtype
    with torch.no_grad():
        ny, nx = -(-height // tile), -(-width // tile)
        ty, tx = torch.meshgrid(torch.arange(ny, device=dev), torch.arange(nx, device=dev), indexing="ij")
        ty, tx = ty.reshape(-1), tx.reshape(-1)  # (T,) tile rows / cols
        nt = ty.numel()
        if not math.isfinite(radius):
            radius = float(height + width) * 4  # a box that every tile meets
        lo_y = (ty * tile).to(dt) + 0.5  # pixel-centre extent of each tile
        lo_x = (tx * tile).to(dt) + 0.5
        box = torch.stack([lo_x, (lo_x + tile - 1).clamp(max=width - 0.5),
                           lo_y, (lo_y + tile - 1).clamp(max=height - 0.5)], -1)  # (T, 4)
        act = active if active is not None else torch.ones(n, e, dtype=torch.bool, device=dev)
        table, mask, counts = _candidates(a, b, act, box, torch.tensor(radius, dtype=dt, device=dev))
        tiles = torch.nonzero(counts.view(-1)).view(-1)  # (A,) active (path, tile) pairs
        idx = torch.zeros(n * nt, tile * tile, dtype=torch.long, device=dev)
        if tiles.numel() and e:
            k = min(_bucket(int(counts.max().item())), e)
            act_n, act_t = tiles // nt, tiles % nt
            m = mask.view(n * nt, e)[tiles]  # (A, E)
            if k < e:
                sel = torch.topk(m.to(torch.uint8), k, dim=-1, sorted=False).indices  # (A, K)
                valid = torch.gather(m, 1, sel)
            else:
                sel, valid = torch.arange(e, device=dev).expand(tiles.numel(), e), m
            sel = torch.where(valid, sel, e)  # slot e of each path is the far-away padding edge
            cand = table.view(-1, 5)[act_n.view(-1, 1) * (e + 1) + sel]  # (A, K, 5)
            local = torch.arange(tile, device=dev)
            py = ((ty[act_t] * tile).view(-1, 1, 1) + local.view(1, tile, 1)).expand(-1, tile, tile)
            px = ((tx[act_t] * tile).view(-1, 1, 1) + local.view(1, 1, tile)).expand(-1, tile, tile)
            py = (py.reshape(-1, tile * tile, 1).to(dt) + 0.5)  # (A, tile*tile, 1)
            px = (px.reshape(-1, tile * tile, 1).to(dt) + 0.5)
            c = cand.unsqueeze(1)  # (A, 1, K, 5)
            total = tiles.numel()
            chunk = _chunk_rows(total, tile * tile * k)
            slots = []
            for s in range(0, total, chunk):
                sl = slice(s, s + chunk)
                _, slot = _nearest_kernel(c[sl, ..., 0], c[sl, ..., 1], c[sl, ..., 2], c[sl, ..., 3], c[sl, ..., 4],
                                          px[sl], py[sl])  # (A', tile*tile)
                slots.append(slot)
            best = torch.gather(sel, 1, torch.cat(slots, 0)).clamp_(max=e - 1)  # (A, tile*tile)
            idx[tiles] = best
        idx = idx.view(n, ny, nx, tile, tile).permute(0, 1, 3, 2, 4).reshape(n, ny * tile, nx * tile)
        return idx[:, :height, :width]  # (N, H, W)


@maybe_compile
def _candidates(a, b, active, box, radius):
    """Edge table with a padding row, and which edges are candidates for which tile.

    Returns ``table (N, E+1, 5)`` = ``[ax, ay, dx, dy, 1/|d|^2]`` (row E: an edge parked far
    away), ``mask (N, T, E)`` and ``counts (N, T)``.
    """
    d = b - a
    len2 = (d * d).sum(-1)
    inv = torch.where(len2 > 0, 1.0 / len2.clamp_min(_EPS), torch.zeros_like(len2))
    table = torch.stack([a[..., 0], a[..., 1], d[..., 0], d[..., 1], inv], -1)  # (N, E, 5)
    pad = torch.tensor([_FAR, _FAR, 0.0, 0.0, 0.0], dtype=a.dtype, device=a.device).expand(a.shape[0], 1, 5)
    table = torch.cat([table, pad], 1)
    lo = torch.minimum(a, b) - radius  # (N, E, 2)
    hi = torch.maximum(a, b) + radius
    mask = (
        (hi[:, None, :, 0] >= box[None, :, None, 0]) & (lo[:, None, :, 0] <= box[None, :, None, 1])
        & (hi[:, None, :, 1] >= box[None, :, None, 2]) & (lo[:, None, :, 1] <= box[None, :, None, 3])
        & active[:, None, :]
    )  # (N, T, E)
    return table, mask, mask.sum(-1)


def _chunk_rows(rows: int, pairs_per_row: int) -> int:
    """Rows per kernel call: the compiled kernel fuses the reduction, eager does not."""
    if compile_enabled():
        return rows
    budget = 2**24  # pair elements per eager call (~64 MB per float32 temporary)
    return max(1, budget // max(1, pairs_per_row))


def edge_distance(a: torch.Tensor, b: torch.Tensor, idx: torch.Tensor) -> torch.Tensor:
    """Distance from every pixel centre to one chosen edge, differentiable in ``a`` and ``b``.

    Args:
        a, b: ``(N, E, 2)`` edge end points, pixel frame.
        idx: ``(N, H, W)`` chosen edge per pixel.

    Returns:
        ``(N, H, W)`` distances in pixels.
    """
    return _edge_distance(a, b, idx)


@maybe_compile
def _edge_distance(a, b, idx):
    n, h, w = idx.shape
    flat = idx.reshape(n, h * w, 1).expand(n, h * w, 2)
    ea = torch.gather(a, 1, flat)  # (N, HW, 2)
    eb = torch.gather(b, 1, flat)
    ys = torch.arange(h, dtype=a.dtype, device=a.device).add(0.5)
    xs = torch.arange(w, dtype=a.dtype, device=a.device).add(0.5)
    grid = torch.stack(torch.meshgrid(xs, ys, indexing="xy"), -1).reshape(1, h * w, 2)  # (1, HW, 2)
    d = eb - ea
    r = grid - ea
    len2 = (d * d).sum(-1)
    t = ((r * d).sum(-1) / len2.clamp_min(_EPS)).clamp(0.0, 1.0)  # (N, HW)
    q = r - t.unsqueeze(-1) * d
    dist = torch.sqrt((q * q).sum(-1) + _EPS)
    return dist.reshape(n, h, w)


@maybe_compile
def shade(a, b, idx, wind, radius, tau, evenodd: bool):
    """Soft coverage ``sigmoid(sign * min(d, radius) / tau)`` of ``(N, H, W)`` pixels.

    Args:
        a, b: ``(N, E, 2)`` edges; idx ``(N, H, W)`` nearest edge; wind ``(N, H, W)``.
        radius, tau: 0-d tensors (tensors, so that annealing them does not recompile).
        evenodd: fill rule (else nonzero).
    """
    return signed_coverage(_edge_distance(a, b, idx), wind, radius, tau, "evenodd" if evenodd else "nonzero")


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
