"""How many segments a path needs (paper sec. 3.3).

An auxiliary MLP reads a path code and predicts ``(a, b, c)`` of the path's error curve

    loss(k) ~= a * exp(-b * k) + c,   a, b, c > 0  (softplus),

so the predicted curve decreases monotonically in the segment count ``k`` by construction.
For a quality threshold ``T`` (error per added segment, MSE on [0, 1] coverage), a path gets
the smallest ``k`` where the curve's slope ``a * b * exp(-b * k)`` has fallen below ``T``:

    k = ceil(ln(a * b / T) / b),  clamped to [K_MIN, k_max].
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

K_MIN = 3  # fewest segments a path is given (a closed path needs 2; 3 draws a rounded triangle)
SWEEP = (3, 4, 5, 6, 7, 8, 10, 12, 14, 17, 20, 25)  # k measured when training the predictor


class SegmentPredictor(nn.Module):
    """Path code ``(N, C)`` -> curve parameters ``(N, 3)``: ``a, b, c`` (all > 0)."""

    def __init__(self, code: int, hidden: int):
        super().__init__()
        self.net = nn.Sequential(nn.Linear(code, hidden), nn.ReLU(), nn.Linear(hidden, hidden), nn.ReLU(),
                                 nn.Linear(hidden, 3))

    def forward(self, code: torch.Tensor) -> torch.Tensor:
        return F.softplus(self.net(code)) + 1e-6


def curve(params: torch.Tensor, k: torch.Tensor) -> torch.Tensor:
    """``params (N, 3)``, ``k (K,)`` -> predicted loss ``(N, K)``."""
    a, b, c = params.unbind(-1)
    return a[:, None] * torch.exp(-b[:, None] * k[None].to(params.dtype)) + c[:, None]


def choose_segments(params: torch.Tensor, quality: float, k_max: int) -> torch.Tensor:
    """Smallest ``k`` whose predicted slope is below ``quality``: ``(N, 3) -> (N,)`` long."""
    if not quality > 0:
        raise ValueError(f"quality must be > 0, got {quality}")
    a, b, _ = params.double().unbind(-1)
    k = torch.log((a * b / quality).clamp_min(1.0)) / b
    k = torch.nan_to_num(k, nan=float(k_max), posinf=float(k_max))
    return k.ceil().clamp(K_MIN, max(K_MIN, k_max)).long()


def fit_loss(params: torch.Tensor, ks: torch.Tensor, losses: torch.Tensor, eps: float = 1e-4) -> torch.Tensor:
    """Squared error of the predicted curves in log space: ``losses (N, K)`` measured at ``ks (K,)``.

    ``eps`` (MSE units) keeps paths whose error is already negligible from dominating."""
    return (torch.log(curve(params, ks) + eps) - torch.log(losses + eps)).square().mean()
