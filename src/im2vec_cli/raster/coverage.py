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
        d = b - a
        len2 = (d * d).sum(-1)
        inv = torch.where(len2 > 0, 1.0 / len2.clamp_min(_EPS), torch.zeros_like(len2))
        ny, nx = -(-height // tile), -(-width // tile)
        ty, tx = torch.meshgrid(torch.arange(ny, device=dev), torch.arange(nx, device=dev), indexing="ij")
        ty, tx = ty.reshape(-1), tx.reshape(-1)  # (T,) tile rows / cols
        if active is not None and not math.isfinite(radius):
            radius = float(height + width) * 4  # a box that every tile meets, to apply the mask
        if math.isfinite(radius):
            lo_y = (ty * tile).to(dt) + 0.5  # pixel-centre extent of each tile
            hi_y = (lo_y + tile - 1).clamp(max=height - 0.5)
            lo_x = (tx * tile).to(dt) + 0.5
            hi_x = (lo_x + tile - 1).clamp(max=width - 0.5)
            ymin = (torch.minimum(a[..., 1], b[..., 1]) - radius).unsqueeze(1)  # (N, 1, E)
            ymax = (torch.maximum(a[..., 1], b[..., 1]) + radius).unsqueeze(1)
            xmin = (torch.minimum(a[..., 0], b[..., 0]) - radius).unsqueeze(1)
            xmax = (torch.maximum(a[..., 0], b[..., 0]) + radius).unsqueeze(1)
            mask = (ymax >= lo_y.view(1, -1, 1)) & (ymin <= hi_y.view(1, -1, 1))
            mask &= (xmax >= lo_x.view(1, -1, 1)) & (xmin <= hi_x.view(1, -1, 1))  # (N, T, E)
            if active is not None:
                mask &= active.unsqueeze(1)
            counts = mask.sum(-1)  # (N, T)
            act_n, act_t = torch.nonzero(counts, as_tuple=True)  # (A,), (A,)
            k = int(counts.max().item()) if counts.numel() else 0
        else:
            act_n = torch.arange(n, device=dev).repeat_interleave(ty.numel())
            act_t = torch.arange(ty.numel(), device=dev).repeat(n)
            mask = None
            k = e
        idx = torch.zeros(n, ny * tile, nx * tile, dtype=torch.long, device=dev)
        if act_n.numel() == 0 or e == 0:
            return idx[:, :height, :width]
        k = min(_bucket(k), e)
        if mask is not None and k < e:
            m = mask[act_n, act_t]  # (A, E)
            sel = torch.topk(m.to(torch.uint8), k, dim=-1, sorted=False).indices  # (A, K)
            valid = torch.gather(m, 1, sel)
        else:
            sel = torch.arange(e, device=dev).expand(act_n.numel(), e)
            valid = mask[act_n, act_t] if mask is not None else torch.ones_like(sel, dtype=torch.bool)

        def pick(v, pad):
            g = torch.gather(v[act_n], 1, sel)  # (A, K)
            return torch.where(valid, g, torch.full_like(g, pad)).unsqueeze(1)  # (A, 1, K)

        ax, ay = pick(a[..., 0], _FAR), pick(a[..., 1], _FAR)
        dx, dy, iv = pick(d[..., 0], 0.0), pick(d[..., 1], 0.0), pick(inv, 0.0)
        local = torch.arange(tile, device=dev)
        oy = local.view(tile, 1).expand(tile, tile).reshape(1, -1)  # (1, tile*tile)
        ox = local.view(1, tile).expand(tile, tile).reshape(1, -1)
        gy = ty[act_t].view(-1, 1) * tile + oy  # (A, tile*tile) pixel rows
        gx = tx[act_t].view(-1, 1) * tile + ox
        py = (gy.to(dt) + 0.5).unsqueeze(-1)  # (A, tile*tile, 1)
        px = (gx.to(dt) + 0.5).unsqueeze(-1)
        total = act_n.numel()
        chunk = _chunk_rows(total, tile * tile * k)
        slots = []
        for s in range(0, total, chunk):
            sl = slice(s, s + chunk)
            _, slot = _nearest_kernel(ax[sl], ay[sl], dx[sl], dy[sl], iv[sl], px[sl], py[sl])  # (A', tile*tile)
            slots.append(slot)
        best = torch.gather(sel, 1, torch.cat(slots, 0))  # (A, tile*tile)
        idx[act_n.view(-1, 1), gy, gx] = best
        return idx[:, :height, :width]  # (N, H, W)


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


def inside_from_winding(wind: torch.Tensor, fill_rule: str) -> torch.Tensor:
    """Boolean inside mask from winding numbers under ``"nonzero"`` or ``"evenodd"``."""
    if fill_rule == "nonzero":
        return wind != 0
    if fill_rule == "evenodd":
        return torch.remainder(wind, 2) != 0
    raise ValueError(f"fill_rule must be 'nonzero' or 'evenodd', got {fill_rule!r}")
