"""Reading pictures (``files.py``): every Pillow mode to ``(3, H, W)`` in [0, 1] over white."""

import numpy as np
import pytest
import torch
from PIL import Image

from im2vec_cli.files import image_to_tensor


def _over_white(img: Image.Image) -> torch.Tensor:
    """The reference: RGBA in float, alpha composited onto white."""
    arr = torch.from_numpy(np.asarray(img.convert("RGBA"), dtype=np.float32) / 255.0)
    return (arr[..., :3] * arr[..., 3:] + (1 - arr[..., 3:])).permute(2, 0, 1)


@pytest.mark.parametrize("mode", ["RGB", "L", "1", "P", "CMYK", "RGBA", "LA"])
def test_every_mode_reads_as_rgb_over_white(mode):
    """Opaque pictures take the 8-bit path (a quarter of the memory) and read exactly as the
    composited path reads them; pictures with alpha are composited onto white."""
    rng = np.random.default_rng(0)
    rgba = Image.fromarray(rng.integers(0, 256, (9, 13, 4), dtype=np.uint8), "RGBA")
    img = rgba.convert(mode) if mode != "P" else rgba.convert("RGB").quantize(16)
    got = image_to_tensor(img)
    assert got.shape == (3, 9, 13) and got.dtype == torch.float32
    assert torch.equal(got, _over_white(img))
