"""Compositing P coloured coverage layers over a background.

Depth convention: a *larger* depth is nearer the viewer, so it is drawn later ("over").
"""

from __future__ import annotations

import torch

from ._compile import maybe_compile


def _check(coverage: torch.Tensor, colors: torch.Tensor, depth: torch.Tensor) -> None:
    if coverage.dim() != 4:
        raise ValueError(f"coverage must be (B, G, H, W), got {tuple(coverage.shape)}")
    b, g = coverage.shape[:2]
    if colors.shape != (b, g, 3):
        raise ValueError(f"colors must be (B, G, 3) = {(b, g, 3)}, got {tuple(colors.shape)}")
    if depth.shape != (b, g):
        raise ValueError(f"depth must be (B, G) = {(b, g)}, got {tuple(depth.shape)}")


def composite_over(
    coverage: torch.Tensor, colors: torch.Tensor, depth: torch.Tensor, background: float = 1.0
) -> torch.Tensor:
    """Exact back-to-front "over" compositing in depth order.

    Args:
        coverage: ``(B, G, H, W)`` alpha of each layer in [0, 1].
        colors: ``(B, G, 3)`` RGB in [0, 1].
        depth: ``(B, G)``; larger is in front.
        background: grey level of the background.

    Returns:
        ``(B, 3, H, W)`` image.
    """
    _check(coverage, colors, depth)
    b, g, h, w = coverage.shape
    order = torch.argsort(depth, dim=1)  # (B, G): back to front
    cov = torch.gather(coverage, 1, order.view(b, g, 1, 1).expand(b, g, h, w))
    col = torch.gather(colors, 1, order.unsqueeze(-1).expand(b, g, 3))
    out = torch.full((b, 3, h, w), float(background), dtype=coverage.dtype, device=coverage.device)
    for i in range(g):
        a = cov[:, i : i + 1]  # (B, 1, H, W)
        out = out * (1 - a) + col[:, i].view(b, 3, 1, 1) * a
    return out


def composite_soft(
    coverage: torch.Tensor,
    colors: torch.Tensor,
    depth: torch.Tensor,
    temperature: float = 0.1,
    background: float = 1.0,
) -> torch.Tensor:
    """Differentiable soft compositing by depth (in the spirit of DiffComp, Reddy et al. 2020).

    Layer ``i`` gets weight ``a_i * prod_{j != i} (1 - a_j * sigmoid((d_j - d_i) / T))``: it is
    hidden by the layers softly in front of it. The background gets ``prod_j (1 - a_j)``.
    The weights are normalised, so the result is a convex combination of the layer colours
    and the background; as ``T -> 0`` the weights become exactly those of ``composite_over``.

    Args:
        coverage: ``(B, G, H, W)`` alpha of each layer in [0, 1].
        colors: ``(B, G, 3)``.
        depth: ``(B, G)``; larger is in front.
        temperature: softness of the depth order (> 0).
        background: grey level of the background.

    Returns:
        ``(B, 3, H, W)`` image.
    """
    _check(coverage, colors, depth)
    if temperature <= 0:
        raise ValueError(f"temperature must be > 0, got {temperature}")
    return _soft(coverage, colors, depth, temperature, background)


@maybe_compile(dynamic={0: (0,), 1: (0,), 2: (0,)})
def _soft(coverage, colors, depth, temperature, background):
    # Unrolled over the (few) layers so that the compiled graph is one fused loop per pixel;
    # a batched (B, G, G, H, W) product costs far more, mostly in prod's backward.
    g = coverage.shape[1]
    alpha = [coverage[:, i : i + 1] for i in range(g)]  # each (B, 1, H, W)
    z = depth.unsqueeze(-1).unsqueeze(-1)  # (B, G, 1, 1)
    bg = torch.ones_like(alpha[0])
    for a in alpha:
        bg = bg * (1 - a)
    total = bg
    rgb = bg * background
    for i in range(g):
        w = alpha[i]
        for j in range(g):
            if j != i:
                w = w * (1 - alpha[j] * torch.sigmoid((z[:, j : j + 1] - z[:, i : i + 1]) / temperature))
        total = total + w
        rgb = rgb + w * colors[:, i].view(-1, 3, 1, 1)
    return rgb / total.clamp_min(1e-12)  # (B, 3, H, W)


def solve_colors(
    coverage: torch.Tensor, depth: torch.Tensor, target: torch.Tensor, prior: torch.Tensor,
    ridge: float = 1e-3, background: float = 1.0,
) -> torch.Tensor:
    """The layer colours whose ``composite_over`` is closest to ``target``: a least-squares solve.

    With the coverages and the order fixed, ``composite_over`` is linear in the colours: pixel
    ``x`` is ``background * t(x) + sum_i c_i w_i(x)``, where ``w_i`` is layer ``i``'s alpha times
    the transparency of the layers in front of it and ``t`` that of them all. The normal equations
    of ``min sum_x |that - target(x)|^2 + ridge * N * sum_i |c_i - prior_i|^2`` (N pixels) are
    solved per picture; the ridge keeps a hidden layer at its prior colour. Results are clamped to
    [0, 1]. Differentiable in the coverages (``TrainConfig.solved`` trains through it); inference
    runs it under ``no_grad``.

    Args:
        coverage: ``(B, G, H, W)`` alpha of each layer in [0, 1].
        depth: ``(B, G)``; larger is in front.
        target: ``(B, 3, H, W)`` in [0, 1].
        prior: ``(B, G, 3)`` colours a layer keeps where the picture says nothing of it.
        ridge: weight of the prior per pixel (> 0).
        background: grey level of the background.

    Returns:
        ``(B, G, 3)`` colours.
    """
    _check_problem(coverage, depth, target, prior, ridge)
    gram, cross, _ = _normal_equations(coverage, depth, target, background)
    return _solved(gram, cross, prior, ridge * coverage[0, 0].numel()).to(prior.dtype)


def _check_problem(coverage, depth, target, prior, ridge) -> None:
    """The shapes and ridge ``solve_colors`` and ``solve_order`` take (a ``ValueError`` naming what is wrong)."""
    _check(coverage, prior, depth)
    if target.shape != (coverage.shape[0], 3, *coverage.shape[2:]):
        raise ValueError(f"target must be (B, 3, H, W) = {(coverage.shape[0], 3, *coverage.shape[2:])}, "
                         f"got {tuple(target.shape)}")
    if ridge <= 0:
        raise ValueError(f"ridge must be > 0, got {ridge}")


def _normal_equations(coverage: torch.Tensor, depth: torch.Tensor, target: torch.Tensor, background: float
                      ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """The least-squares problem of ``solve_colors``: with ``w (B, G, N)`` the layers' weights and
    ``r (B, 3, N)`` the target less the background's share, ``w w^T (B, G, G)``, ``w r^T (B, G, 3)``
    and ``|r|^2 (B,)``, so that a colouring ``c`` is ``sum_x |w^T c - r|^2 = c.(w w^T c) - 2 c.(w r^T) + |r|^2`` off."""
    b, g, h, w = coverage.shape
    front = torch.argsort(depth, dim=1, descending=True).view(b, g, 1, 1).expand(b, g, h, w)  # front to back
    a = torch.gather(coverage, 1, front)
    clear = torch.cumprod(torch.cat([torch.ones_like(a[:, :1]), 1 - a], 1), 1)  # (B, G+1, H, W)
    wf = torch.empty_like(a).scatter(1, front, a * clear[:, :-1]).flatten(2)  # (B, G, N), layers in their own order
    rest = (target - background * clear[:, -1:]).flatten(2)  # (B, 3, N)
    return wf @ wf.transpose(1, 2), wf @ rest.transpose(1, 2), rest.square().sum((1, 2))


def _solved(gram: torch.Tensor, cross: torch.Tensor, prior: torch.Tensor, lam: float) -> torch.Tensor:
    """The ridge solution of ``_normal_equations``' problem, pulled to ``prior`` with weight ``lam``, clamped to [0, 1]."""
    eye = torch.eye(gram.shape[-1], dtype=gram.dtype, device=gram.device)
    return torch.linalg.solve(gram + lam * eye, cross + lam * prior.to(gram.dtype)).clamp(0, 1)


@torch.no_grad()
def solve_order(
    coverage: torch.Tensor, depth: torch.Tensor, target: torch.Tensor, prior: torch.Tensor,
    ridge: float = 1e-3, background: float = 1.0, rounds: int = 3,
) -> torch.Tensor:
    """The layer order whose composite, its colours solved (``solve_colors``), is closest to ``target``.

    A greedy search from ``depth``'s order: each round tries, one after another, moving the layer
    at every position to every other (the layers between shift by one), and keeps a move for
    each picture whose squared error it lowers; it stops after ``rounds`` rounds or one without a
    kept move. A layer the network put behind the one it should be in front of (an eye behind the
    face) comes forward. The result never draws farther from ``target`` than ``depth``'s order.

    Args as ``solve_colors``.

    Returns:
        ``(B, G)`` depths: ``depth``'s own values, reassigned to the layers in the order found
        (tied values set a few ulps apart).
    """
    _check_problem(coverage, depth, target, prior, ridge)
    g = depth.shape[1]
    values = depth.sort(1).values  # (B, G), back to front
    rank = torch.argsort(torch.argsort(depth, 1), 1)  # (B, G): each layer's position, 0 = back
    best = _solved_error(coverage, rank.to(coverage.dtype), target, prior, ridge, background)
    for _ in range(rounds):
        kept = False
        for i in range(g):
            for j in range(g):
                if i == j:
                    continue
                lo, hi = min(i, j), max(i, j)
                between = (rank >= lo) & (rank <= hi) & (rank != i)
                moved = torch.where(rank == i, j, torch.where(between, rank + (1 if j < i else -1), rank))
                err = _solved_error(coverage, moved.to(coverage.dtype), target, prior, ridge, background)
                better = err < best * (1 - 1e-4)  # by more than float32's rounding of the expansion
                if better.any():
                    kept = True
                    rank, best = torch.where(better[:, None], moved, rank), torch.where(better, err, best)
        if not kept:
            break
    return torch.gather(_distinct(values), 1, rank)


def _distinct(values: torch.Tensor) -> torch.Tensor:
    """Sorted depths ``(B, G)`` made strictly increasing where they tie (a few ulps apart), so
    the order found is the order drawn; distinct values are kept as they are."""
    out = values.clone()
    step = 4 * torch.finfo(values.dtype).eps * values.abs().amax(1).clamp_min(1)  # (B,)
    for i in range(1, values.shape[1]):
        out[:, i] = torch.maximum(out[:, i], out[:, i - 1] + step)
    return out


def _solved_error(coverage, depth, target, prior, ridge, background) -> torch.Tensor:
    """``(B,)`` mean squared error to ``target`` of the composite with its colours solved, from the
    normal equations (no composite drawn)."""
    gram, cross, rr = _normal_equations(coverage, depth, target, background)
    c = _solved(gram, cross, prior, ridge * coverage[0, 0].numel())  # (B, G, 3)
    return ((c * (gram @ c)).sum((1, 2)) - 2 * (c * cross).sum((1, 2)) + rr) / target[0].numel()
