"""Training-batch augmentation (``TrainConfig.augment``): mirrored, scaled and shifted copies of
the training pictures, drawn per picture from the run's generator so that a resumed run draws alike.

Frame: ``x (B, C, S, S)`` in [0, 1], the batch ``train_step`` draws; the result has its shape.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F

from ..options import parse_augment

SCALE = 1 / 8  # ``scale``: each picture magnified by a factor drawn uniformly in [1 - SCALE, 1 + SCALE]


def augment_batch(x: torch.Tensor, spec: str, gen: torch.Generator) -> torch.Tensor:
    """``flip``: each picture mirrored left-right with probability 1/2. ``scale``: each magnified
    about its centre by a factor in [1 - SCALE, 1 + SCALE] (bilinear; what it uncovers takes the
    border's pixels). ``shift``: each moved by a whole number of pixels in x and y, up to S/32
    each way (2 px at 64), its border pixels repeated into what it uncovers. Applied in that
    order; returns ``x`` itself when ``spec`` is empty."""
    kinds = parse_augment(spec)
    b, _, s, _ = x.shape
    if "flip" in kinds:
        mirror = (torch.rand(b, generator=gen) < 0.5).to(x.device).view(b, 1, 1, 1)
        x = torch.where(mirror, x.flip(-1), x)
    if "scale" in kinds:
        zoom = 1 + (torch.rand(b, generator=gen) * 2 - 1) * SCALE  # (B,)
        theta = torch.zeros(b, 2, 3)
        theta[:, 0, 0] = theta[:, 1, 1] = 1 / zoom  # output point p samples the input at p / zoom
        grid = F.affine_grid(theta.to(x), list(x.shape), align_corners=False)
        x = F.grid_sample(x, grid, mode="bilinear", padding_mode="border", align_corners=False)
    m = s // 32
    if "shift" in kinds and m:
        dy, dx = (torch.randint(-m, m + 1, (2, b), generator=gen) + m).to(x.device)  # (B,) each, in [0, 2m]
        padded = torch.nn.functional.pad(x, (m, m, m, m), mode="replicate")  # (B, C, S + 2m, S + 2m)
        ar = torch.arange(s, device=x.device)
        rows, cols = (dy[:, None] + ar)[:, :, None], (dx[:, None] + ar)[:, None, :]  # (B, S, 1), (B, 1, S)
        x = padded[torch.arange(b, device=x.device)[:, None, None], :, rows, cols].permute(0, 3, 1, 2)
    return x
