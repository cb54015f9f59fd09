"""Training the feature network of the sample-quality metric (``im2vec train-features``).

A classifier (cross-entropy) when the dataset's layout gives labels (``data.folder_labels``),
else an autoencoder (MSE at 32 x 32). Inputs are shifted by up to ``shift`` pixels each step,
so that features do not hinge on exact placement (samples are drawn, not photographed).

A classifier trained on the data alone maps what is not data anywhere: on MNIST a blank image
fell inside the test digits' k-NN balls (precision 1.0) and uniform noise scored 0.31. So a
classifier also learns a last class, ``JUNK`` (outlier exposure, Hendrycks et al., ICLR 2019):
blank images, noise and regular patterns (``junk_images``), a quarter of every batch.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import torch
import torch.nn.functional as F

from ..events import FeatureStep
from ..model.features import WORK_SIZE, FeatureConfig, FeatureNet


@dataclasses.dataclass(frozen=True)
class FeatureSettings:
    steps: int = 2000
    batch: int = 128
    lr: float = 2e-3
    shift: int = 2  # random translation (pixels of the input frame) each step
    seed: int = 0


JUNK = "(none)"  # the last class of a classifier: not a picture of the data
JUNK_SHARE = 0.25  # of every batch


def junk_images(n: int, size: int, g: torch.Generator) -> torch.Tensor:
    """``n`` images ``(n, 3, size, size)`` in [0, 1] that are no picture of anything: white or
    flat colour with a few specks, uniform or sparse binary noise, checkerboards and stripes
    of random period and phase (the outliers of ``JUNK``)."""
    out = torch.ones(n, 3, size, size)
    kind = torch.randint(0, 5, (n,), generator=g).tolist()
    yy, xx = torch.meshgrid(torch.arange(size), torch.arange(size), indexing="ij")
    for i, k in enumerate(kind):
        if k == 0:  # white or flat colour, a few specks
            out[i] = torch.rand(3, 1, 1, generator=g) if torch.rand((), generator=g) < 0.3 else 1.0
            specks = torch.rand(size, size, generator=g) < 0.01 * float(torch.rand((), generator=g))
            out[i, :, specks] = 0.0
        elif k == 1:  # uniform noise, grey or colour
            grey = torch.rand((), generator=g) < 0.5
            out[i] = torch.rand(1 if grey else 3, size, size, generator=g).expand(3, -1, -1)
        elif k == 2:  # sparse binary noise
            dense = 0.02 + 0.5 * float(torch.rand((), generator=g))
            out[i] = (torch.rand(size, size, generator=g) >= dense).float()
        else:  # checkerboard (3) or stripes (4)
            period = int(torch.randint(2, size // 2, (), generator=g))
            dx, dy = torch.randint(0, period, (2,), generator=g).tolist()
            cells = ((xx + dx) // period + ((yy + dy) // period if k == 3 else 0)) % 2
            out[i] = cells.float().expand(3, -1, -1) if k == 3 else (cells if torch.rand((), generator=g) < 0.5
                                                                     else cells.T).float().expand(3, -1, -1)
    return out


def _shifted(x: torch.Tensor, shift: int, g: torch.Generator) -> torch.Tensor:
    """Each image of ``(B, 3, S, S)`` moved by up to ``shift`` px, the border filled with white."""
    if shift <= 0:
        return x
    b, _, s, _ = x.shape
    pad = F.pad(x, (shift,) * 4, value=1.0)  # (B, 3, S + 2 shift, S + 2 shift)
    dx, dy = torch.randint(0, 2 * shift + 1, (2, b), generator=g).tolist()
    return torch.stack([pad[i, :, dy[i] : dy[i] + s, dx[i] : dx[i] + s] for i in range(b)])


def train_feature_net(
    images: torch.Tensor,
    labels: torch.Tensor | None,
    config: FeatureConfig,
    settings: FeatureSettings = FeatureSettings(),
    on_step: Callable[[FeatureStep], None] | None = None,
) -> FeatureNet:
    """A feature net trained on ``images (N, 3, S, S)`` uint8 (``labels (N,)`` for a classifier,
    whose ``config.classes`` names them; ``None`` with no classes for an autoencoder)."""
    if (labels is None) == bool(config.classes):
        raise ValueError("labels are needed exactly when config.classes names them")
    if config.classes and config.classes[-1] != JUNK:
        raise ValueError(f"a classifier's last class must be {JUNK!r} (outlier exposure)")
    s = settings
    torch.manual_seed(s.seed)
    g = torch.Generator().manual_seed(s.seed)
    net = FeatureNet(config)
    opt = torch.optim.AdamW(net.parameters(), lr=s.lr, weight_decay=1e-4)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, s.lr, total_steps=s.steps, pct_start=0.1)
    net.train()
    for step in range(s.steps):
        idx = torch.randint(len(images), (s.batch,), generator=g)
        x = _shifted(images[idx].float() / 255, s.shift, g)  # (B, 3, S, S)
        if labels is not None:
            junk = int(s.batch * JUNK_SHARE)
            x = torch.cat([x, junk_images(junk, x.shape[-1], g)])  # (B + J, 3, S, S)
            y = torch.cat([labels[idx], torch.full((junk,), len(config.classes) - 1)])
            loss = F.cross_entropy(net.logits(x), y)
        else:
            loss = F.mse_loss(net.reconstruct(x), F.adaptive_avg_pool2d(x, WORK_SIZE))
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        sched.step()
        if on_step and (step % 100 == 0 or step == s.steps - 1):
            on_step(FeatureStep(step, loss.item()))
    return net.eval()


@torch.no_grad()
def feature_net_score(net: FeatureNet, images: torch.Tensor, labels: torch.Tensor | None,
                      batch: int = 512) -> float:
    """Accuracy on ``images (N, 3, S, S)`` uint8 with ``labels`` (classifier), or the mean
    reconstruction MSE at 32 x 32 (autoencoder)."""
    hits, errs = 0, 0.0
    for i in range(0, len(images), batch):
        x = images[i : i + batch].float() / 255
        if net.is_classifier:
            hits += int((net.logits(x).argmax(1) == labels[i : i + batch]).sum())
        else:
            errs += float(F.mse_loss(net.reconstruct(x), F.adaptive_avg_pool2d(x, WORK_SIZE), reduction="sum"))
    return hits / len(images) if net.is_classifier else errs / (len(images) * 3 * WORK_SIZE**2)
