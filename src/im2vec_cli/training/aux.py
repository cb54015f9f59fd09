"""Training the segment-count predictor (paper sec. 3.3, ``im2vec train-aux``).

For each path of each training image, the frozen model decodes the path with every k of
``SWEEP`` and renders it alone (coverage at the model size). The path's error at k is the
MSE between that coverage and the coverage at the largest k, the decoder's most detailed
version of the same path. The predictor is then fitted to these curves (``fit_loss``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import torch

from ..events import AuxStep
from ..model.segments import SWEEP, SegmentPredictor, curve, fit_loss
from ..model.vae import Im2Vec
from ..raster import render_coverage


@torch.no_grad()
def measure_segment_losses(model: Im2Vec, images: torch.Tensor, ks=SWEEP, batch: int = 64,
                           tau: float = 0.4) -> tuple[torch.Tensor, torch.Tensor]:
    """Path codes and their error curves.

    Args:
        images: ``(N, 3, S, S)`` in [0, 1] at the model size.

    Returns:
        codes ``(N * P, C)`` and losses ``(N * P, len(ks))``.
    """
    cfg = model.config
    dev = next(model.parameters()).device
    codes, losses = [], []
    for i in range(0, len(images), batch):
        x = images[i : i + batch].to(dev)
        mu, _ = model.encode(x)
        code = model.path_state(mu, x, colors=False)[0].flatten(0, 1)  # (B*P, C), the path passes' codes
        centre = model.centres.expand(len(x), -1, -1).flatten(0, 1)  # (B*P, 2)
        covs = []
        for k in ks:
            pts = model.decoder(code, k, centre)  # (B*P, 3k, 2)
            covs.append(render_coverage(pts[:, None], size=cfg.image_size, tau=tau, samples=cfg.samples)[:, 0])
        ref = covs[-1]
        losses.append(torch.stack([(c - ref).square().mean((1, 2)) for c in covs], 1).cpu())  # (B*P, K)
        codes.append(code.cpu())
    return torch.cat(codes), torch.cat(losses)


@dataclasses.dataclass(frozen=True)
class AuxSettings:
    hidden: int = 64
    steps: int = 3000
    lr: float = 2e-3
    val_fraction: float = 0.1
    seed: int = 0


def train_segment_predictor(
    model: Im2Vec,
    images: torch.Tensor,
    settings: AuxSettings = AuxSettings(),
    on_step: Callable[[AuxStep], None] | None = None,
) -> tuple[Im2Vec, dict]:
    """A copy of ``model`` with a fitted segment predictor, and a report.

    The report gives the fit loss (log space) on held-out paths, and the measured and
    predicted mean error at each k of the sweep.
    """
    s = settings
    codes, losses = measure_segment_losses(model, images)
    ks = torch.tensor(SWEEP, dtype=torch.float32)
    g = torch.Generator().manual_seed(s.seed)
    order = torch.randperm(len(codes), generator=g)
    n_val = max(1, int(len(codes) * s.val_fraction))
    val, tr = order[:n_val], order[n_val:]
    pred = SegmentPredictor(codes.shape[1], s.hidden)
    torch.manual_seed(s.seed)
    opt = torch.optim.Adam(pred.parameters(), lr=s.lr)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, s.steps)
    for step in range(s.steps):
        loss = fit_loss(pred(codes[tr]), ks, losses[tr])
        opt.zero_grad()
        loss.backward()
        opt.step()
        sched.step()
        if on_step and (step % 250 == 0 or step == s.steps - 1):
            with torch.no_grad():
                on_step(AuxStep(step, loss.item(), fit_loss(pred(codes[val]), ks, losses[val]).item()))
    with torch.no_grad():
        pv = pred(codes[val])
        report = {
            "paths": len(codes), "val_paths": n_val, "ks": list(SWEEP),
            "val_fit_log_mse": fit_loss(pv, ks, losses[val]).item(),
            "measured_mean": losses[val].mean(0).tolist(),
            "predicted_mean": curve(pv, ks).mean(0).tolist(),
        }
    cfg = dataclasses.replace(model.config, segment_predictor=s.hidden)
    out = Im2Vec(cfg).to(next(model.parameters()).device)
    vae = {k: v for k, v in model.state_dict().items() if not k.startswith("segment_predictor.")}
    out.load_state_dict(vae, strict=False)  # everything but the new predictor
    out.segment_predictor.load_state_dict(pred.state_dict())
    for prior in ("latent_prior", "neighbour_prior"):  # the latents are the same: so are their priors
        setattr(out, prior, getattr(model, prior, None))
    return out.eval(), report
