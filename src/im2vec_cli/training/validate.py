"""What a training run shows of its model: ``evaluate_l2`` (the ``val`` figures) and
``preview_grid`` (the ``RUN/preview_<step>.png`` sheets)."""

from __future__ import annotations

import torch

from ..files import encode_png
from ..model.losses import reconstruction_loss
from ..model.pretrained import unwrap_model
from ..model.vae import Im2Vec

__all__ = ["evaluate_l2", "preview_grid"]


@torch.no_grad()
def evaluate_l2(model: Im2Vec, images: torch.Tensor, segments: int, tau: float, batch: int = 128,
                supersample: int = 1, pyramid: str = "blur", solved: bool = False) -> dict[str, float]:
    """Validation: pyramid L2 and plain MSE (paper Table 1) with ``z = mu``.

    ``images`` uint8 ``(N, 3, S, S)``; the MSE render uses exact "over" compositing, and
    ``supersample``, ``pyramid`` and ``solved`` as the loss does.
    """
    m = unwrap_model(model)
    was = m.training
    m.eval()
    dev = next(m.parameters()).device
    pyr, mse, n = 0.0, 0.0, 0
    for i in range(0, len(images), batch):
        x = images[i : i + batch].to(dev).float() / 255
        loss, _, dec, _ = reconstruction_loss(m, x, segments, tau, sample=False, supersample=supersample,
                                           pyramid=pyramid, solved=solved)
        img = dec if m.raster_output else m.render(dec, tau=tau, composite="over", supersample=supersample)
        pyr += float(loss) * len(x)
        mse += float(((img - x) ** 2).mean()) * len(x)
        n += len(x)
    m.train(was)
    return {"val_pyramid_l2": pyr / n, "val_mse": mse / n}


def preview_grid(model: Im2Vec, images: torch.Tensor, segments: int, tau: float, scale: int = 2) -> bytes:
    """PNG rows of input | reconstruction | reconstruction with control points (anchors red;
    the ImageVAE baseline has none)."""
    from PIL import Image, ImageDraw

    m = unwrap_model(model)
    with torch.no_grad():
        x = images.float() / 255
        dec, _, _ = m(x.to(next(m.parameters()).device), segments, sample=False)
        rec = (dec if m.raster_output else m.render(dec, tau=tau, composite="over")).cpu()
    s = m.config.image_size * scale
    sheet = Image.new("RGB", (3 * s, len(x) * s), "white")
    for r in range(len(x)):
        for c, img in enumerate((x[r], rec[r], rec[r])):
            tile = Image.fromarray((img.permute(1, 2, 0).clamp(0, 1) * 255).byte().numpy()).resize((s, s), Image.NEAREST)
            if c == 2 and not m.raster_output:
                draw = ImageDraw.Draw(tile)
                for path in dec.points[r].cpu():
                    for j, (px, py) in enumerate(path.tolist()):
                        col = (220, 30, 30) if j % 3 == 0 else (30, 90, 220)
                        draw.ellipse([px * s - 1.5, py * s - 1.5, px * s + 1.5, py * s + 1.5], fill=col)
            sheet.paste(tile, (c * s, r * s))
    return encode_png(sheet)
