"""Metrics. Reconstruction L2 (paper Table 1): the mean squared error on [0, 1] pixels between
each test image and its vector reconstruction, rendered by cairosvg at the image's own size
(the SVG a user gets, in the input's frame, not the soft training render). MNIST is thus
measured at 28 x 28 although its model works at 32 x 32."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from .data.folder import list_images
from .errors import DataError, InputError
from .infer import vectorize
from .io import load_image
from .model.vae import Im2Vec
from .svg import rasterize_svg, to_svg


def reconstruction_l2(
    model: Im2Vec, files: list[Path], *, segments: int | None = None, batch: int = 64
) -> dict[str, float]:
    """Mean and standard error of the per-image MSE over ``files`` (unreadable files skipped)."""
    errs = []
    for i in range(0, len(files), batch):
        imgs = []
        for f in files[i : i + batch]:
            try:
                imgs.append(load_image(f))  # (3, H, W)
            except InputError:
                continue
        if not imgs:
            continue
        for img, vec in zip(imgs, vectorize(model, imgs, segments=segments)):
            h, w = img.shape[1:]
            rec = rasterize_svg(to_svg(vec, 3), w, h)  # (H, W, 3)
            errs.append(float(((torch.from_numpy(rec).permute(2, 0, 1).float() - img) ** 2).mean()))
    if not errs:
        raise DataError("no readable test images")
    e = np.asarray(errs)
    return {"recon_l2": float(e.mean()), "recon_l2_stderr": float(e.std(ddof=1) / np.sqrt(len(e))) if len(e) > 1 else 0.0,
            "images": len(e)}


def eval_files(folder: str | Path, limit: int | None = None, seed: int = 0) -> list[Path]:
    """Images under ``folder`` (``folder/test`` when present), a seeded subset of ``limit``."""
    folder = Path(folder)
    if (folder / "test").is_dir():
        folder = folder / "test"
    files = list_images(folder)
    if limit is not None and len(files) > limit:
        g = torch.Generator().manual_seed(seed)
        files = [files[i] for i in sorted(torch.randperm(len(files), generator=g)[:limit].tolist())]
    return files
