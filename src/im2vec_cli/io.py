"""File input and output shared by the CLI and the library: atomic writes, image loading.

Images are returned as ``(C, H, W)`` float tensors in [0, 1] on a white background.
"""

from __future__ import annotations

import io
import os
import tempfile
import warnings
from pathlib import Path

import numpy as np
import torch
from PIL import Image, UnidentifiedImageError

from .errors import InputError

MAX_PIXELS = 64_000_000  # larger images are refused (decompression bombs)


def atomic_write(path: str | os.PathLike, data: bytes | str, *, durable: bool = True) -> None:
    """Write ``data`` to ``path`` through a temporary file and a rename, so that a crash
    never leaves a partial file behind. ``durable=False`` skips the fsync (bulk datasets)."""
    path = Path(path)
    raw = data.encode("utf-8") if isinstance(data, str) else data
    directory = path.parent if str(path.parent) else Path(".")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=directory)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(raw)
            if durable:
                f.flush()
                os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def open_image(data: bytes, name: str = "<image>") -> Image.Image:
    """Decode image bytes with Pillow, turning every failure into a one-line ``InputError``."""
    if not data:
        raise InputError(f"{name}: empty file")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", Image.DecompressionBombWarning)
            img = Image.open(io.BytesIO(data))
            if img.width * img.height > MAX_PIXELS:
                raise InputError(f"{name}: image too large ({img.width}x{img.height} pixels)")
            img.load()
    except InputError:
        raise
    except (Image.DecompressionBombError, Image.DecompressionBombWarning) as exc:
        raise InputError(f"{name}: image too large (decompression bomb): {exc}") from None
    except (UnidentifiedImageError, OSError, SyntaxError, ValueError) as exc:
        raise InputError(f"{name}: not a readable image ({exc})") from None
    return img


def image_to_tensor(img: Image.Image) -> torch.Tensor:
    """Any Pillow mode -> ``(3, H, W)`` float in [0, 1], alpha composited onto white."""
    if img.mode in ("I;16", "I;16B", "I;16L", "I"):
        arr = np.asarray(img, dtype=np.float64)
        top = 65535.0 if arr.max() > 255 else 255.0
        g = torch.from_numpy(arr / top).float().clamp(0, 1)
        return g.unsqueeze(0).expand(3, -1, -1).contiguous()
    if img.mode == "F":
        g = torch.from_numpy(np.asarray(img, dtype=np.float32)).clamp(0, 1)
        return g.unsqueeze(0).expand(3, -1, -1).contiguous()
    rgba = img.convert("RGBA")
    arr = torch.from_numpy(np.asarray(rgba, dtype=np.float32) / 255.0)  # (H, W, 4)
    rgb, a = arr[..., :3], arr[..., 3:]
    out = rgb * a + (1 - a)  # white background
    return out.permute(2, 0, 1).contiguous()  # (3, H, W)


def load_image(path: str | os.PathLike, data: bytes | None = None) -> torch.Tensor:
    """Read an image file (or given bytes) as ``(3, H, W)`` in [0, 1] over white."""
    name = str(path)
    if data is None:
        try:
            data = Path(path).read_bytes()
        except FileNotFoundError:
            raise InputError(f"{name}: no such file") from None
        except IsADirectoryError:
            raise InputError(f"{name}: is a directory") from None
        except OSError as exc:
            raise InputError(f"{name}: cannot read ({exc.strerror})") from None
    return image_to_tensor(open_image(data, name))


def tensor_to_png(img: torch.Tensor) -> bytes:
    """``(3, H, W)`` or ``(1, H, W)`` in [0, 1] -> PNG bytes."""
    arr = (img.detach().float().clamp(0, 1) * 255).round().to(torch.uint8).cpu()
    if arr.shape[0] == 1:
        pil = Image.fromarray(arr[0].numpy(), "L")
    else:
        pil = Image.fromarray(arr.permute(1, 2, 0).numpy(), "RGB")
    buf = io.BytesIO()
    pil.save(buf, format="PNG")
    return buf.getvalue()
