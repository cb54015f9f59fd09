"""The model's square frame and the input's pixel frame, in one place.

The model sees a ``S x S`` square (``S = config.image_size``) made from an input ``(3, H, W)``
by centring it on a white square of side ``square_side(H, W, S, fit)`` and resizing that to
``S``. ``Placement`` records where that square sits in the input's pixel grid, and maps
points from the model's normalised frame to the input's (``model_to_input``), so an SVG
overlays its input.

Frames (shared/STYLE.md): normalised coordinates ``(x, y)`` in [0, 1], y down, of the model
square (``model``) or of the input's ``W x H`` grid (``input``: ``(x_px / W, y_px / H)``).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
import torch.nn.functional as F

from .options import FITS  # ModelConfig.fit: how an image smaller than the model square meets it


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


def resize_square(img: torch.Tensor, size: int) -> torch.Tensor:
    """``(C, S, S)`` -> ``(C, size, size)``: area filter down, bilinear up, unchanged at ``size``."""
    s = img.shape[-1]
    if s == size:
        return img
    down = s > size
    return F.interpolate(img[None], size=(size, size), mode="area" if down else "bilinear",
                         align_corners=None if down else False)[0]


def fit_square(img: torch.Tensor, size: int, fit: str = "resize") -> torch.Tensor:
    """``(3, H, W)`` -> ``(3, size, size)``: centre on a white square of side
    ``square_side(H, W, size, fit)``, then resize to ``size``."""
    _, h, w = img.shape
    s = square_side(h, w, size, fit)
    if (h, w) != (s, s):
        top, left = (s - h) // 2, (s - w) // 2
        img = F.pad(img, (left, s - w - left, top, s - h - top), value=1.0)
    return resize_square(img, size).clamp(0, 1)


@dataclass(frozen=True)
class Placement:
    """Input ``width x height``; the model square of side ``square_side(H, W, size, fit)``
    sits at ``(-left, -top)`` in the input's pixel frame (``size`` 0: side ``max(H, W)``)."""

    width: int
    height: int
    size: int = 0
    fit: str = "resize"

    @property
    def side(self) -> int:
        return square_side(self.height, self.width, self.size, self.fit)

    @property
    def offset(self) -> tuple[int, int]:
        """``(left, top)``: input pixels between the square's corner and the input's."""
        return (self.side - self.width) // 2, (self.side - self.height) // 2

    def model_to_input(self, points: torch.Tensor) -> torch.Tensor:
        """Points ``(..., 2)`` in the model's normalised frame -> the input's normalised frame
        (same dtype and device)."""
        left, top = self.offset
        scale = points.new_tensor([self.side / self.width, self.side / self.height])
        shift = points.new_tensor([left / self.width, top / self.height])
        return points * scale - shift


def to_model_frame(image: torch.Tensor, size: int, fit: str = "resize") -> tuple[torch.Tensor, Placement]:
    """``(3, H, W)`` in [0, 1] -> the model input ``(3, size, size)`` and its placement."""
    if image.dim() != 3 or image.shape[0] != 3:
        raise ValueError(f"image must be (3, H, W), got {tuple(image.shape)}")
    _, h, w = image.shape
    return fit_square(image, size, fit), Placement(w, h, size, fit)
