"""Image folders for training: every PNG/JPG under a root, loaded into memory.

Images are composited onto white, converted to RGB and fitted to ``size x size``
(``fit_square``: padded with white to a square, then resized), stored as uint8 ``(N, 3, S, S)``.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import torch

from ..errors import DataError, InputError
from ..io import load_image

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")
FITS = ("resize", "pad")  # ModelConfig.fit: how an image smaller than the model square meets it


def list_images(root: str | Path) -> list[Path]:
    root = Path(root)
    if not root.is_dir():
        raise DataError(f"{root}: not a directory")
    return sorted(p for p in root.rglob("*") if p.suffix.lower() in IMAGE_SUFFIXES and p.is_file())


def resize_square(img: torch.Tensor, size: int) -> torch.Tensor:
    """``(C, S, S)`` -> ``(C, size, size)``: area filter down, bilinear up, unchanged at ``size``."""
    import torch.nn.functional as F

    s = img.shape[-1]
    if s == size:
        return img
    down = s > size
    return F.interpolate(img[None], size=(size, size), mode="area" if down else "bilinear",
                         align_corners=None if down else False)[0]


def check_fit(fit: str) -> None:
    """Raise ``ValueError`` unless ``fit`` is one of ``FITS``."""
    if fit not in FITS:
        raise ValueError(f"fit must be one of {FITS}, got {fit!r}")


def square_side(height: int, width: int, size: int, fit: str = "resize") -> int:
    """Side of the white square an image is centred on before it is resized to ``size``:
    ``max(H, W)``, or with ``fit="pad"`` at least ``size``, so that a smaller image (28 x 28
    MNIST in a 32 x 32 model) is padded, never resampled."""
    check_fit(fit)
    return max(height, width, size if fit == "pad" else 0)


def fit_square(img: torch.Tensor, size: int, fit: str = "resize") -> torch.Tensor:
    """``(3, H, W)`` -> ``(3, size, size)``: centre on a white square of side
    ``square_side(H, W, size, fit)``, then resize to ``size``."""
    import torch.nn.functional as F

    _, h, w = img.shape
    s = square_side(h, w, size, fit)
    if (h, w) != (s, s):
        top, left = (s - h) // 2, (s - w) // 2
        img = F.pad(img, (left, s - w - left, top, s - h - top), value=1.0)
    return resize_square(img, size).clamp(0, 1)


def load_folder(
    root: str | Path, size: int, *, fit: str = "resize", workers: int = 2,
    on_skip: Callable[[str], None] | None = None,
) -> tuple[torch.Tensor, list[str]]:
    """Load every image under ``root``, fitted to ``size`` by ``fit_square(..., fit)``.

    Unreadable files are skipped and reported through ``on_skip`` (one line each).

    Returns:
        ``(N, 3, size, size)`` uint8 and the relative file names.
    """
    files = list_images(root)
    if not files:
        raise DataError(f"{root}: no images (.png, .jpg) found")

    def one(p):
        try:
            return fit_square(load_image(p), size, fit)
        except InputError as exc:
            if on_skip:
                on_skip(str(exc))
            return None

    with ThreadPoolExecutor(max_workers=max(1, workers)) as pool:
        imgs = list(pool.map(one, files))
    keep = [(f, i) for f, i in zip(files, imgs) if i is not None]
    if not keep:
        raise DataError(f"{root}: none of the {len(files)} image files could be read")
    data = torch.stack([(i * 255).round().to(torch.uint8) for _, i in keep])
    return data, [str(f.relative_to(root)) for f, _ in keep]


def split_indices(names: list[str], val_fraction: float) -> tuple[list[int], list[int]]:
    """Deterministic train/val split by a hash of each file's folder (so one font family or
    class folder stays on one side); single-folder sets are split by file name."""
    keys = [str(Path(n).parent) for n in names]
    if len(set(keys)) < 10:
        keys = names
    val = [i for i, k in enumerate(keys) if int(hashlib.sha256(k.encode()).hexdigest()[:8], 16) / 0xFFFFFFFF < val_fraction]
    if not val and len(names) > 1:
        val = [len(names) - 1]
    vs = set(val)
    return [i for i in range(len(names)) if i not in vs], val
